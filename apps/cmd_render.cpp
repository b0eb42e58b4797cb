// denoisebench render SCENE [--spp N] [--size WxH] [--seed S] [--threads T] [--max-depth D]
//                          [--reflection-levels K] [--scenes-dir DIR] [--frames A:B] -o FRAME.exr
// Renders every AOV layer of docs/design.md, "AOV frame file" (plus the edge file FRAME.edges.exr)
// with the shared tracer.
#include "apps/args.h"
#include "apps/commands.h"
#include "tracer/jobs.h"

namespace dnb::app {

void add_render(CLI::App& app, Action& action) {
  struct RenderArgs {
    RenderJob job;
    std::string size = "1024x768";
    std::string frames;
  };
  auto args = std::make_shared<RenderArgs>();
  auto* cmd = app.add_subcommand("render", "Render an AOV frame of a scene with the shared path tracer");
  cmd->add_option("scene", args->job.scene, "built-in scene name or scene TOML file")->required();
  cmd->add_option("-o,--output", args->job.output, "output frame (OpenEXR)")->required();
  cmd->add_option("--spp", args->job.settings.spp, "samples per pixel")->check(in_bounds(bounds::kSpp));
  cmd->add_option("--size", args->size, "image size WIDTHxHEIGHT");
  cmd->add_option("--seed", args->job.settings.seed, "random seed")->check(in_bounds(bounds::kSeed));
  add_threads_option(*cmd, args->job.settings.threads, "worker threads (0: all cores)");
  cmd->add_option("--max-depth", args->job.settings.max_depth, "path length in segments")
      ->check(in_bounds(bounds::kMaxDepth));
  cmd->add_option("--reflection-levels", args->job.settings.reflection_levels, "decomposed reflection levels (refl1..reflK)")
      ->check(CLI::Range(0, 8));
  cmd->add_option("--frames", args->frames,
                  "an animated scene's frames FIRST:END (frames FIRST .. END - 1), written as OUTPUT_0000.exr ...");
  cmd->add_option("--scenes-dir", args->job.load.scenes_dir, "folder of the McGuire scenes (else $DENOISEBENCH_SCENES, ../shared/scenes)");
  cmd->callback([&action, args] {
    action = [args] {
      RenderJob job = args->job;
      std::tie(job.settings.width, job.settings.height) = parse_size(args->size);
      if (!args->frames.empty()) job.frames = parse_frame_range(args->frames, "--frames");
      render_frame_file(job);
      return 0;
    };
  });
}

}  // namespace dnb::app
