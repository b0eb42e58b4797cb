// Loading scenes: the built-in scene names and the search paths of scene and mesh files, the
// scene file schema (TOML, documented in configs/scenes/README.md), and the content hash that
// keys every cached render of a scene (tracer/render_cache.h).
//
//   auto scene = load_scene("cornell-box");                 // configs/scenes/cornell-box.toml
//   auto mine = load_scene("my/room.toml", {.scenes_dir = "/data/mcguire"});
//   CacheKey key("frame");
//   key.add("scene", scene_content_hash(*scene));
#pragma once

#include <memory>
#include <string>
#include <vector>

namespace dnb {

class Scene;  // tracer/scene.h

struct SceneLoadOptions {
  // Folder holding the McGuire scenes (--scenes-dir, else $DENOISEBENCH_SCENES, else
  // ../shared/scenes when present). Empty: use that search order.
  std::string scenes_dir = {};
  // An animated scene's frame ([animation] frames = N; docs/sequences.md): its keys evaluated
  // there. -1: frame 0 of an animated scene, and a still scene as it is (a still refuses any
  // other frame).
  int frame = -1;
};

// `name_or_path`: a built-in scene name (cornell-box, conference, bedroom, sponza, ...) found in
// configs/scenes/, or a path to a scene TOML file. InputError naming the file/key on bad input.
std::shared_ptr<const Scene> load_scene(const std::string& name_or_path, const SceneLoadOptions& options = {});
// Names of the built-in scenes.
std::vector<std::string> builtin_scene_names();
// Content hash of everything that determines a render of the scene: the scene file and every
// file it references (meshes, textures). Used by the reference and input caches.
std::string scene_content_hash(const Scene& scene);
const std::string& scene_name(const Scene& scene);

}  // namespace dnb
