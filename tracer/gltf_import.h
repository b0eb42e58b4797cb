// glTF 2.0 scenes (.gltf text with embedded or external buffers, or .glb) appended to a Scene:
// an [[objects]] entry of type "gltf" in a scene file, or a .gltf/.glb file given where a scene
// is expected (configs/scenes/README.md). tinygltf (Debian's libtinygltf-dev) decodes the file;
// this file checks it (every error names the file and the JSON pointer of what is wrong) and
// maps its content onto the tracer's meshes, materials, textures, camera and lights.
//
// Mapping (metallic-roughness materials -> tracer/scene.h; docs/gltf.md has the table and why):
//  - metallicFactor >= 0.5: a conductor with Schlick's curve from F0 = base colour;
//  - else transmission (KHR_materials_transmission) >= 0.5: a dielectric of KHR_materials_ior's
//    index (1.5), thin unless KHR_materials_volume gives it a thickness (then a solid with Beer
//    absorption from attenuationColor and attenuationDistance);
//  - else a plastic (the glTF dielectric BRDF: a diffuse base of the base colour under a GGX
//    coat of index 1.5, or KHR_materials_ior's);
//  - roughness r -> GGX alpha r^2, the metallic-roughness texture's green channel squared as the
//    roughness map; normalTexture -> the normal map; emissiveFactor x KHR_materials_emissive_
//    strength -> emission; alphaMode MASK -> the base colour's alpha as a cut-out.
// Lights (KHR_lights_punctual): directional -> the sun, point -> a small sphere light of the same
// intensity; the first perspective camera -> the scene camera when the scene file has none.
// What the tracer cannot represent (spot lights, textures on metals and glass, emissive
// textures, vertex colours, skins, morph targets, KHR_texture_transform, unknown extensions,
// ...) is approximated or left out with a warning naming the property (GltfImport::warnings):
// never silently.
// Animations: the channels on nodes' translation, rotation and scale are evaluated at the time
// import_gltf is given (tracer/gltf_animation.h), and place the meshes and the camera there; all
// of the file's animations play together (one that targets a property an earlier animation
// drives is an alternative clip, left out with a warning). Morph target weights and skins are not
// animated (warnings). Lights do not move: a light on an animated node is an error, and so is an
// emissive mesh on one.
#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "tracer/scene.h"
#include "tracer/shapes.h"

namespace dnb::rt {

struct GltfImport {
  std::optional<Camera> camera;        // the default scene's first perspective camera (x applied)
  std::vector<std::string> warnings;   // "FILE: /POINTER: what was approximated or left out"
  // Whether an animation of the file moves a node (a translation, rotation or scale channel it
  // plays), and the time of its last key over those channels, in seconds.
  bool animated = false;
  double duration = 0;
};

// Appends the default scene (or scene 0) of the glTF file at `path` to `scene`, every vertex
// transformed by its node's matrix and then by x: one mesh of its triangles (named after the
// file's stem), the materials and textures they use, and its lights. `material`: when set, every
// triangle gets this scene material instead of its own. The glTF file and every external buffer
// and image file it names are appended to scene.files. InputError "FILE: /JSON/POINTER: what is
// wrong and what was expected" on a malformed file, a missing external file, a reference out of
// range, data past its buffer, a non-finite vertex, a vertex index out of range, or an
// extension the file requires that is not supported; and for animations, a malformed sampler
// (accessor types, counts, key times that do not rise: naming the animation and the channel), an
// animated node with a matrix, a light or an emissive mesh that an animation moves.
// `time`: the instant in seconds at which the animations place the nodes (0: a still's; before
// a channel's first key it holds its first value, after its last key its last).
GltfImport import_gltf(Scene& scene, const std::filesystem::path& path, const Transform& x,
                       std::optional<unsigned> material, double time = 0);

// Whether `path` names a glTF file by its extension (.gltf or .glb, any case).
bool is_gltf_path(const std::filesystem::path& path);

}  // namespace dnb::rt
