// denoisebench export-gltf SCENE -o FILE.gltf [--size WxH] [--scenes-dir DIR]
// Writes the scene as one glTF 2.0 file (tracer/gltf_export.h: the mapping, the exact material
// in each material's extras, and what is refused with exit status 2), for renderers that read
// glTF: the Cycles back-end (renderers/cycles) renders it as the tracer's scene.
#include <fmt/format.h>

#include "apps/args.h"
#include "apps/commands.h"
#include "tracer/gltf_export.h"
#include "tracer/scene_loader.h"

namespace dnb::app {

void add_export_gltf(CLI::App& app, Action& action) {
  struct ExportArgs {
    std::string scene, output, size = "256x192";
    SceneLoadOptions load;
  };
  auto args = std::make_shared<ExportArgs>();
  auto* cmd = app.add_subcommand("export-gltf", "Write a scene as one glTF 2.0 file (the tracer's materials in extras)");
  cmd->add_option("scene", args->scene, "built-in scene name or scene file (TOML, glTF)")->required();
  cmd->add_option("-o,--output", args->output, "the .gltf file to write (must not exist)")->required();
  cmd->add_option("--size", args->size, "film size WIDTHxHEIGHT (the camera's aspect ratio)");
  cmd->add_option("--scenes-dir", args->load.scenes_dir, "folder of the McGuire scenes (else $DENOISEBENCH_SCENES, ../shared/scenes)");
  cmd->callback([&action, args] {
    action = [args] {
      GltfExportSettings s;
      std::tie(s.width, s.height) = parse_size(args->size);
      const auto scene = load_scene(args->scene, args->load);
      fmt::print("{}\n", export_gltf(*scene, s, args->output));
      return 0;
    };
  });
}

}  // namespace dnb::app
