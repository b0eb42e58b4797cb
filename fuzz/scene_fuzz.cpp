// Fuzz target: the scene loader (tracer/scene_loader.h) with the OBJ/MTL files a scene names
// (tracer/obj_import.h).
//
// One input is up to three files, split at separator lines:
//
//   <scene.toml>
//   #@@ mesh.obj
//   <mesh.obj>
//   #@@ mesh.mtl
//   <mesh.mtl>
//
// written into the private folder as scene.toml, mesh.obj and mesh.mtl (a part that is absent
// leaves no file), then load_scene("<folder>/scene.toml"). The seeds' scenes name
// `file = "mesh.obj"`, and their OBJ part says `mtllib mesh.mtl`. fuzz/scene.dict has the keys.
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

#include "fuzz_input.h"
#include "tracer/scene.h"
#include "tracer/scene_loader.h"

namespace {

constexpr std::string_view kObjSeparator = "\n#@@ mesh.obj\n";
constexpr std::string_view kMtlSeparator = "\n#@@ mesh.mtl\n";

// Cuts `rest` at `separator`: the part before it is returned, `rest` keeps what follows (or
// becomes empty and `found` false when there is no separator).
std::string_view cut(std::string_view& rest, std::string_view separator, bool& found) {
  const std::size_t at = rest.find(separator);
  found = at != std::string_view::npos;
  const std::string_view head = found ? rest.substr(0, at) : rest;
  rest = found ? rest.substr(at + separator.size()) : std::string_view{};
  return head;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace dnb::fuzz;
  std::string_view rest(reinterpret_cast<const char*>(data), size);
  bool has_obj = false, has_mtl = false;
  const std::string_view toml = cut(rest, kObjSeparator, has_obj);
  const std::string_view obj = cut(rest, kMtlSeparator, has_mtl);
  const std::string_view mtl = rest;

  const std::string scene_path = write_input("scene.toml", toml);
  if (has_obj) write_input("mesh.obj", obj); else remove_input("mesh.obj");
  if (has_mtl) write_input("mesh.mtl", mtl); else remove_input("mesh.mtl");

  run_guarded([&] {
    auto scene = dnb::load_scene(scene_path);
    (void)dnb::scene_content_hash(*scene);
    // An animated scene's keys are evaluated per frame: its middle and last frames too.
    if (scene->animated())
      for (int frame : {scene->frames / 2, scene->frames - 1}) {
        dnb::SceneLoadOptions o;
        o.frame = frame;
        (void)dnb::scene_content_hash(*dnb::load_scene(scene_path, o));
      }
  });
  return 0;
}
