// denoisebench export-mitsuba SCENE -o DIR [--size WxH] [--spp N] [--max-depth D] [--seed S]
//                                          [--scenes-dir DIR]
// Writes the scene as a Mitsuba 3 scene (DIR/scene.xml and DIR/meshes/*.ply) for the same frame
// the tracer would render with these settings (tracer/mitsuba_export.h: the mapping, and what is
// refused with exit status 2). Render it with python/mitsuba_render.py.
#include <fmt/format.h>

#include "apps/args.h"
#include "apps/commands.h"
#include "tracer/mitsuba_export.h"
#include "tracer/scene_loader.h"

namespace dnb::app {

void add_export_mitsuba(CLI::App& app, Action& action) {
  struct ExportArgs {
    std::string scene, output, size = "256x192";
    MitsubaExportSettings settings;
    SceneLoadOptions load;
  };
  auto args = std::make_shared<ExportArgs>();
  auto* cmd = app.add_subcommand("export-mitsuba", "Write a scene as a Mitsuba 3 scene (XML and PLY meshes)");
  cmd->add_option("scene", args->scene, "built-in scene name or scene TOML file")->required();
  cmd->add_option("-o,--output", args->output, "output folder (must not exist, or be empty)")->required();
  cmd->add_option("--size", args->size, "film size WIDTHxHEIGHT");
  cmd->add_option("--spp", args->settings.spp, "samples per pixel of the sampler")->check(in_bounds(bounds::kSpp));
  cmd->add_option("--max-depth", args->settings.max_depth, "path length in segments, as render's")
      ->check(in_bounds(bounds::kMaxDepth));
  cmd->add_option("--seed", args->settings.seed, "the sampler's seed (below 2^32)")->check(in_bounds(bounds::kSeed));
  cmd->add_option("--scenes-dir", args->load.scenes_dir, "folder of the McGuire scenes (else $DENOISEBENCH_SCENES, ../shared/scenes)");
  cmd->callback([&action, args] {
    action = [args] {
      MitsubaExportSettings s = args->settings;
      std::tie(s.width, s.height) = parse_size(args->size);
      const auto scene = load_scene(args->scene, args->load);
      fmt::print("{}\n", export_mitsuba(*scene, s, args->output));
      return 0;
    };
  });
}

}  // namespace dnb::app
