// A loaded scene (tracer/scene_loader.h) as one glTF 2.0 file, so that renderers that read glTF
// (Blender Cycles: renderers/cycles) render what the tracer renders:
//
//   denoisebench export-gltf cornell-box -o cornell-box.gltf --size 256x192
//
// One .gltf text file with its buffer embedded (base64): one mesh per (mesh, material) pair,
// 3 vertices per triangle as the tracer stores corners, in world coordinates; NORMAL where the
// mesh has shading normals, TEXCOORD_0 (u, 1 - v: glTF's v runs down) where it has texture
// coordinates. The camera is a perspective camera node (yfov, the film's aspect ratio).
//
// Materials: the glTF metallic-roughness material nearest to the tracer's (diffuse: a non-metal
// with KHR_materials_specular's specularFactor 0, which this project's glTF import reads back as
// diffuse; mirror and conductor: metals of roughness sqrt(alpha); dielectric:
// KHR_materials_transmission with KHR_materials_ior, KHR_materials_volume where it absorbs; plastic
// and coated: non-metals with their index), and the tracer's own parameters, exactly, in the
// material's extras as {"denoisebench": {"type", "albedo", "tint", "ior", "alpha", ...}}: a
// back-end that reads them (renderers/cycles) builds the same BSDF instead of the nearest glTF one.
// Emission: emissiveFactor (normalised) x KHR_materials_emissive_strength. A constant sky is the
// scene's extras {"denoisebench": {"sky": [r, g, b]}}, a gradient sky {"sky_gradient": {"zenith",
// "horizon", "ground", "up"}} (configs/scenes/README.md's [sky]); a sun a KHR_lights_punctual directional light
// (irradiance as intensity) with its angular radius in the light's extras.
//
// Refused with an InputError naming the scene and the feature (nothing is dropped silently):
// opacity, normal and roughness maps (not exported yet), a thin lens, motion
// blur, anisotropic roughness. Colour textures are baked into 1024 x 1024 16-bit sRGB PNGs.
#pragma once

#include <string>

namespace dnb {

class Scene;  // tracer/scene.h

struct GltfExportSettings {
  int width = 256;  // the film's aspect ratio is the camera's aspectRatio
  int height = 192;
};

// Writes the scene to `path` (.gltf) atomically; returns the path. InputError for what is
// refused (above) or when `path` exists.
std::string export_gltf(const Scene& scene, const GltfExportSettings& settings, const std::string& path);

}  // namespace dnb
