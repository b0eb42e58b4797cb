// Fuzz target: glTF 2.0 scenes (tracer/gltf_import.h) loaded as scenes of their own.
//
// One input is one file: a binary glTF when it starts with the GLB magic "glTF", else the text of
// a .gltf (buffers and images in data URIs: a file's external URIs name files that do not exist
// in the private folder, which must be refused cleanly too). It is written as scene.glb or
// scene.gltf, then load_scene() reads it: the JSON check, tinygltf's decoding, the accessors'
// reading and OpenImageIO's decoding of embedded images all run; an animated file's last frame is
// loaded too (its animations evaluated there). fuzz/gltf.dict has the keys.
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

#include "fuzz_input.h"
#include "tracer/scene.h"
#include "tracer/scene_loader.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace dnb::fuzz;
  const std::string_view bytes(reinterpret_cast<const char*>(data), size);
  const bool binary = bytes.substr(0, 4) == "glTF";
  remove_input(binary ? "scene.gltf" : "scene.glb");
  const std::string path = write_input(binary ? "scene.glb" : "scene.gltf", bytes);
  run_guarded([&] {
    auto scene = dnb::load_scene(path);
    (void)dnb::scene_content_hash(*scene);
    // An animated file: its last frame too, where the animations are evaluated between keys or
    // past them (frame 0 is at 0 s, often a key).
    if (scene->animated() && scene->frames > 1) {
      dnb::SceneLoadOptions o;
      o.frame = scene->frames - 1;
      (void)dnb::load_scene(path, o);
    }
  });
  return 0;
}
