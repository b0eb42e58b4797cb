// denoisebench render SCENE [--spp N] [--size WxH] [--seed S] [--threads T] [--max-depth D]
//                          [--reflection-levels K] [--scenes-dir DIR] -o FRAME.exr
// Renders every AOV layer of DESIGN.md (plus the edge file FRAME.edges.exr) with the shared tracer.
#include <cstdio>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "apps/commands.h"
#include "core/errors.h"
#include "core/exr_io.h"
#include "core/progress.h"
#include "tracer/render.h"
#include "tracer/scene_loader.h"

namespace dnb::app {

namespace {

struct RenderArgs {
  std::string scene, output, size = "1024x768", scenes_dir;
  RenderSettings settings;
};

void parse_size(const std::string& s, int& w, int& h) {
  unsigned ww = 0, hh = 0;
  char x = 0, extra = 0;
  if (std::sscanf(s.c_str(), "%u%c%u%c", &ww, &x, &hh, &extra) != 3 || (x != 'x' && x != 'X') || ww == 0 || hh == 0)
    throw InputError(fmt::format("--size '{}': expected WIDTHxHEIGHT, e.g. 1024x768", s));
  w = int(ww);
  h = int(hh);
}

}  // namespace

void add_render(CLI::App& app, Action& action) {
  auto args = std::make_shared<RenderArgs>();
  auto* cmd = app.add_subcommand("render", "Render an AOV frame of a scene with the shared path tracer");
  cmd->add_option("scene", args->scene, "built-in scene name or scene TOML file")->required();
  cmd->add_option("-o,--output", args->output, "output frame (OpenEXR)")->required();
  cmd->add_option("--spp", args->settings.spp, "samples per pixel")->check(CLI::PositiveNumber);
  cmd->add_option("--size", args->size, "image size WIDTHxHEIGHT");
  cmd->add_option("--seed", args->settings.seed, "random seed");
  cmd->add_option("--threads", args->settings.threads, "worker threads (0: all cores)")->check(CLI::NonNegativeNumber);
  cmd->add_option("--max-depth", args->settings.max_depth, "path length in segments")->check(CLI::PositiveNumber);
  cmd->add_option("--reflection-levels", args->settings.reflection_levels, "decomposed reflection levels (refl1..reflK)")
      ->check(CLI::Range(0, 8));
  cmd->add_option("--scenes-dir", args->scenes_dir, "folder of the McGuire scenes (else $DENOISEBENCH_SCENES, ../shared/scenes)");
  cmd->callback([&action, args] {
    action = [args] {
      RenderSettings s = args->settings;
      parse_size(args->size, s.width, s.height);
      SceneLoadOptions lo;
      lo.scenes_dir = args->scenes_dir;
      auto scene = load_scene(args->scene, lo);
      Progress progress(fmt::format("render {} {}x{} {} spp", scene_name(*scene), s.width, s.height, s.spp),
                        std::int64_t(s.width) * s.height * s.spp, "samples", 5.0);
      s.on_progress = [&progress](std::int64_t n) { progress.add(n); };
      AovFrame frame = render_frame(*scene, s);
      progress.finish();
      write_frame(frame, args->output);
      spdlog::info("wrote {} ({} layers, {} edge pixels, {} dropped samples, {:.2f} s)", args->output,
                   frame.layers().size(), frame.edges ? frame.edges->size() : 0, frame.meta.dropped_samples,
                   frame.meta.render_seconds);
      return 0;
    };
  });
}

}  // namespace dnb::app
