// Textures of the diffuse albedo: image files read through OpenImageIO, and procedural ones
// generated in code (checker, wood, brick, noise) so that built-in scenes need no files.
// All textures are looked up by surface (u, v); procedural ones repeat with period 1 in u and v
// after multiplying by `scale`.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "tracer/math.h"

namespace dnb {
class ConfigTable;
}

namespace dnb::rt {

class Texture {
 public:
  virtual ~Texture() = default;
  // Linear RGB reflectance at (u, v).
  virtual Vec3 eval(float u, float v) const = 0;
  // The texture as an alpha cut-out (Material::opacity): coverage in [0, 1] at (u, v). A
  // procedural texture's first channel (a checker of white and black makes holes), a `leaf`'s
  // blade, an image's alpha (RGBA) or its grey value (one channel), never sRGB-decoded.
  virtual float opacity(float u, float v) const { return eval(u, v).x; }
  // Why this texture cannot be an opacity (an image with 2 or 3 channels: which one would be
  // coverage is a guess), or empty.
  virtual std::string opacity_problem() const { return {}; }
  // Why this texture cannot hold data (a normal map, a roughness map) rather than a colour: an
  // 8-bit or 16-bit image decoded from sRGB (its `linear` key turns that off), or, with
  // `min_channels`, an image of fewer channels; empty when it can. Procedural textures can.
  virtual std::string data_problem(int /*min_channels*/) const { return {}; }
  // The channels an image holds (4: RGBA, whose alpha a glTF cut-out reads); 3 for procedural ones.
  virtual int channels() const { return 3; }
};

// An image file (any format OpenImageIO reads). 8-bit images are taken as sRGB-encoded and
// converted to linear; float images are used as they are. Bilinear lookup, repeating edges,
// v = 0 at the bottom row (the OBJ convention). Throws InputError naming the file when it
// cannot be read, is not a regular file, or is larger than an Image may be (core/bounds.h).
// linear: take 8- and 16-bit values as they are (data such as normal maps), not as sRGB.
std::unique_ptr<Texture> load_image_texture(const std::string& path, bool linear = false);

// An image held in memory (a glTF file's embedded image): as load_image_texture, with `name`
// (the image's place in its scene file, ending in the format's extension) in messages.
std::unique_ptr<Texture> load_image_texture(const std::string& name, const unsigned char* data, std::size_t size,
                                            bool linear = false);

// A view of `source` (which must outlive it) as grey data: its channel `channel` (0, 1, 2),
// clamped at 0 and raised to `power`. glTF's roughness is the green channel of its
// metallic-roughness image, and GGX's alpha is roughness squared.
std::unique_ptr<Texture> channel_texture(const Texture& source, int channel, float power = 1);

// The mean colour of a texture over the unit square of (u, v).
Vec3 texture_mean(const Texture& t);

// InputError "CONTEXT: WHAT 'PATH' not found" or "... is not a regular file" (a folder, a
// device such as /dev/zero, a pipe): the files a scene reads as meshes and textures.
void require_regular_file(const std::string& path, const std::string& context, const std::string& what);

// A texture described by a [textures.NAME] table of a scene file:
//   type = "image"   file = "path" (relative to the scene file's folder), linear = false (true:
//                    8- and 16-bit values are data, not sRGB: normal and roughness maps)
//   type = "checker" scale, color_a, color_b
//   type = "wood"    scale, color_a (light wood), color_b (dark rings), rings (rings per unit)
//   type = "brick"   scale, color_a (brick), color_b (mortar), rows, mortar (fraction), variation
//   type = "noise"   scale, color_a, color_b, octaves
// `resolve` turns a file name of the scene into a path. The file paths read are appended to
// `files` (for the scene's content hash).
std::unique_ptr<Texture> make_texture(ConfigTable& t, const std::string& scene_dir,
                                      std::vector<std::string>& files);

// Value noise in [0, 1] with `octaves` octaves (fractional Brownian motion), periodic with
// period `period` lattice cells; exposed for the wood and brick patterns and for tests.
float fbm_noise(float x, float y, int octaves, int period);

}  // namespace dnb::rt
