#include "tracer/texture.h"

#include <filesystem>

#include <OpenImageIO/imagebuf.h>
#include <OpenImageIO/imagebufalgo.h>
#include <OpenImageIO/imageio.h>
#include <OpenImageIO/filesystem.h>
#include <fmt/format.h>

#include "core/config.h"
#include "core/errors.h"
#include "core/exr_io.h"
#include "core/memory_budget.h"

namespace dnb::rt {
namespace {

float srgb_to_linear(float c) {
  return c <= 0.04045f ? c / 12.92f : std::pow((c + 0.055f) / 1.055f, 2.4f);
}

float fract(float x) { return x - std::floor(x); }

class ImageTexture final : public Texture {
 public:
  // coverage: the alpha (4 channels) or the grey value (1 channel) as stored, or empty.
  ImageTexture(std::string path, int w, int h, int channels, bool decoded, std::vector<float> rgb,
               std::vector<float> coverage)
      : path_(std::move(path)), w_(w), h_(h), channels_(channels), decoded_(decoded), rgb_(std::move(rgb)),
        coverage_(std::move(coverage)) {}
  // Bilinear between texel centres, wrapping around (textures of the scenes tile).
  template <typename F>
  auto bilinear(float u, float v, F&& texel) const -> std::decay_t<decltype(texel(std::size_t(0)))> {
    float x = fract(u) * w_ - 0.5f;
    float y = (1.0f - fract(v)) * h_ - 0.5f;
    int x0 = int(std::floor(x)), y0 = int(std::floor(y));
    float fx = x - x0, fy = y - y0;
    auto at = [&](int xi, int yi) {
      xi = ((xi % w_) + w_) % w_;
      yi = ((yi % h_) + h_) % h_;
      return texel(std::size_t(yi) * w_ + xi);
    };
    return (at(x0, y0) * (1 - fx) + at(x0 + 1, y0) * fx) * (1 - fy) +
           (at(x0, y0 + 1) * (1 - fx) + at(x0 + 1, y0 + 1) * fx) * fy;
  }
  Vec3 eval(float u, float v) const override {
    return bilinear(u, v, [&](std::size_t i) {
      const float* p = &rgb_[i * 3];
      return Vec3(p[0], p[1], p[2]);
    });
  }
  float opacity(float u, float v) const override {
    return bilinear(u, v, [&](std::size_t i) { return coverage_[i]; });
  }
  std::string opacity_problem() const override {
    if (!coverage_.empty()) return {};
    return fmt::format("image '{}' has {} channels; an opacity needs 1 (grey coverage) or 4 (RGBA: the alpha)", path_,
                       channels_);
  }
  int channels() const override { return channels_; }
  std::string data_problem(int min_channels) const override {
    if (decoded_)
      return fmt::format("image '{}' is read as sRGB colour (8 or 16 bits); a map of data needs its texture's "
                         "`linear = true`",
                         path_);
    if (channels_ < min_channels)
      return fmt::format("image '{}' has {} channel{}; this map needs {}", path_, channels_, channels_ == 1 ? "" : "s",
                         min_channels);
    return {};
  }

 private:
  std::string path_;
  int w_, h_, channels_;
  bool decoded_;  // the values were sRGB-decoded
  std::vector<float> rgb_;
  std::vector<float> coverage_;
};

class Checker final : public Texture {
 public:
  Checker(float scale, Vec3 a, Vec3 b) : scale_(scale), a_(a), b_(b) {}
  Vec3 eval(float u, float v) const override {
    int i = int(std::floor(u * scale_)) + int(std::floor(v * scale_));
    return (i & 1) ? b_ : a_;
  }

 private:
  float scale_;
  Vec3 a_, b_;
};

// Planks along v with growth rings: the ring phase is distorted by noise so rings wobble.
class Wood final : public Texture {
 public:
  Wood(float scale, Vec3 light, Vec3 dark, float rings) : scale_(scale), a_(light), b_(dark), rings_(rings) {}
  Vec3 eval(float u, float v) const override {
    float x = u * scale_, y = v * scale_;
    float plank = std::floor(x);  // each plank its own ring offset
    float offset = float(mix64(std::uint64_t(std::int64_t(plank)) + 17) >> 40) / 16777216.0f;
    float n = fbm_noise(x * 4.0f, y * 0.5f, 3, 1 << 20);
    float r = fract((fract(x) + offset + 0.6f * n) * rings_);
    float w = std::pow(0.5f + 0.5f * std::cos(2 * kPi * r), 3.0f);
    float seam = fract(x) < 0.02f ? 0.6f : 1.0f;  // dark gap between planks: a sharp texture edge
    return (a_ * (1 - w) + b_ * w) * seam;
  }

 private:
  float scale_;
  Vec3 a_, b_;
  float rings_;
};

class Brick final : public Texture {
 public:
  Brick(float scale, Vec3 brick, Vec3 mortar, float rows, float mortar_w, float variation)
      : scale_(scale), a_(brick), b_(mortar), rows_(rows), mortar_(mortar_w), var_(variation) {}
  Vec3 eval(float u, float v) const override {
    float y = v * scale_ * rows_;
    float row = std::floor(y);
    float x = u * scale_ * rows_ * 0.5f + ((int(row) & 1) ? 0.5f : 0.0f);  // bricks twice as wide as tall
    float col = std::floor(x);
    float fx = x - col, fy = y - row;
    if (fx < mortar_ * 0.5f || fy < mortar_) return b_;
    std::uint64_t h = mix64(std::uint64_t(std::int64_t(row)) * 73856093ULL ^ std::uint64_t(std::int64_t(col)) * 19349663ULL);
    float k = 1.0f + var_ * (float(h >> 40) / 16777216.0f - 0.5f);
    return a_ * k;
  }

 private:
  float scale_;
  Vec3 a_, b_;
  float rows_, mortar_, var_;
};

class Noise final : public Texture {
 public:
  Noise(float scale, Vec3 a, Vec3 b, int octaves) : scale_(scale), a_(a), b_(b), octaves_(octaves) {}
  Vec3 eval(float u, float v) const override {
    int period = std::max(1, int(std::lround(scale_)));
    float n = fbm_noise(fract(u) * period, fract(v) * period, octaves_, period);
    return a_ * (1 - n) + b_ * n;
  }

 private:
  float scale_;
  Vec3 a_, b_;
  int octaves_;
};

// Leaves for alpha cut-outs (a plant's foliage on quads): one leaf per cell of the (u, v)
// lattice, `scale` cells per unit, its blade along v, pointed at both ends (half-width
// 0.42 sin(pi v)^0.7 of the cell), a midrib and paired side veins in color_b over color_a. The
// blade is opaque, the rest of the cell a hole (opacity()); the colour there is never seen.
class Leaf final : public Texture {
 public:
  Leaf(float scale, Vec3 leaf, Vec3 vein) : scale_(scale), a_(leaf), b_(vein) {}
  Vec3 eval(float u, float v) const override {
    const float x = fract(u * scale_) - 0.5f, y = fract(v * scale_);
    const float ax = std::fabs(x);
    if (ax < 0.012f) return b_;  // midrib
    // Side veins: lines leaving the midrib towards the tip, 7 pairs.
    const float phase = fract((y - 1.2f * ax) * 7.0f);
    if (phase < 0.06f && ax < 0.9f * half_width(y)) return a_ * 0.35f + b_ * 0.65f;
    return a_ * (0.85f + 0.15f * fbm_noise(u * scale_ * 24, v * scale_ * 24, 2, 1 << 20));
  }
  float opacity(float u, float v) const override {
    const float x = fract(u * scale_) - 0.5f, y = fract(v * scale_);
    return std::fabs(x) < half_width(y) ? 1.0f : 0.0f;
  }

 private:
  static float half_width(float y) { return 0.42f * std::pow(std::max(0.0f, std::sin(kPi * y)), 0.7f); }
  float scale_;
  Vec3 a_, b_;
};

Vec3 vec3(const std::array<double, 3>& a) { return {float(a[0]), float(a[1]), float(a[2])}; }

}  // namespace

float fbm_noise(float x, float y, int octaves, int period) {
  auto lattice = [](int i, int j, int p) {
    i = ((i % p) + p) % p;
    j = ((j % p) + p) % p;
    return float(mix64(std::uint64_t(i) * 0x9E3779B1ULL + std::uint64_t(j) * 0x85EBCA77ULL + 1) >> 40) / 16777216.0f;
  };
  float sum = 0, amp = 0.5f, norm = 0;
  for (int o = 0; o < octaves; ++o) {
    int i = int(std::floor(x)), j = int(std::floor(y));
    float fx = x - i, fy = y - j;
    fx = fx * fx * (3 - 2 * fx);
    fy = fy * fy * (3 - 2 * fy);
    float v = (lattice(i, j, period) * (1 - fx) + lattice(i + 1, j, period) * fx) * (1 - fy) +
              (lattice(i, j + 1, period) * (1 - fx) + lattice(i + 1, j + 1, period) * fx) * fy;
    sum += amp * v;
    norm += amp;
    amp *= 0.5f;
    x *= 2;
    y *= 2;
    period = period < (1 << 20) ? period * 2 : period;
  }
  return norm > 0 ? sum / norm : 0;
}

void require_regular_file(const std::string& path, const std::string& context, const std::string& what) {
  std::error_code ec;
  const auto st = std::filesystem::status(path, ec);
  if (!std::filesystem::exists(st))
    throw InputError(fmt::format("{}: {} '{}' not found", context, what, path));
  if (!std::filesystem::is_regular_file(st))
    throw InputError(fmt::format("{}: {} '{}' is not a regular file", context, what, path));
}

namespace {

// The size check before any pixel is decoded: a huge image must not be allocated before it is
// refused. `name` is the file, or what an embedded image is called in its scene file.
void check_image_spec(const std::string& name, const OIIO::ImageSpec& s) {
  if (!within(s.width, bounds::kSide) || !within(s.height, bounds::kSide) ||
      std::int64_t(s.width) * s.height > bounds::kMaxTexels || s.nchannels < 1 || s.nchannels > 64)
    throw InputError(fmt::format("texture '{}': {}x{} with {} channels is not accepted (each side 1..{}, at most "
                                 "{} texels: they are held as float RGB, 768 MB at the bound)",
                                 name, s.width, s.height, s.nchannels, bounds::kSide.max, bounds::kMaxTexels));
  // Within the bound, 64 channels of 8192 x 8192 still decode to 16 GiB: refused when it does
  // not fit the memory this process may use (the frame readers' rule).
  check_decode_memory(name, s.width, s.height, s.nchannels, memory_budget_bytes());
}

// The texture of decoded float pixels (w x h x c, interleaved). encoded: 8- or 16-bit values
// that are sRGB colour, decoded to linear here.
std::unique_ptr<Texture> image_texture(const std::string& name, int w, int h, int c, bool encoded,
                                       const std::vector<float>& px) {
  std::vector<float> rgb(std::size_t(w) * h * 3);
  for (std::size_t i = 0; i < std::size_t(w) * h; ++i)
    for (int k = 0; k < 3; ++k) {
      float v = px[i * c + std::min(k, c - 1)];
      rgb[i * 3 + k] = encoded ? srgb_to_linear(v) : v;
    }
  // Coverage for cut-outs: alpha and grey masks are linear data, never sRGB-decoded.
  std::vector<float> coverage;
  if (c == 1 || c == 4) {
    coverage.resize(std::size_t(w) * h);
    for (std::size_t i = 0; i < coverage.size(); ++i) coverage[i] = px[i * c + (c - 1)];
  }
  return std::make_unique<ImageTexture>(name, w, h, c, encoded, std::move(rgb), std::move(coverage));
}

bool integer_format(OIIO::TypeDesc t) {
  return t.basetype == OIIO::TypeDesc::UINT8 || t.basetype == OIIO::TypeDesc::UINT16;
}

// A texture's first channel raised to a power, or another channel of it (tracer/texture.h).
class ChannelView final : public Texture {
 public:
  ChannelView(const Texture& source, int channel, float power) : source_(source), channel_(channel), power_(power) {}
  Vec3 eval(float u, float v) const override {
    const float c = std::max(0.0f, source_.eval(u, v)[channel_]);
    return Vec3(power_ == 1 ? c : std::pow(c, power_));
  }
  std::string data_problem(int min_channels) const override { return source_.data_problem(std::max(min_channels, channel_ + 1)); }
  std::string opacity_problem() const override { return "a channel of another texture is not an opacity"; }

 private:
  const Texture& source_;
  int channel_;
  float power_;
};

}  // namespace

std::unique_ptr<Texture> load_image_texture(const std::string& path, bool linear) {
  require_regular_file(path, "texture", "image file");
  OIIO::ImageBuf in(path);
  if (!in.init_spec(path, 0, 0))
    throw InputError(fmt::format("texture '{}': cannot read image: {}", path, in.geterror()));
  check_image_spec(path, in.spec());
  if (!in.read(0, 0, true, OIIO::TypeDesc::FLOAT))
    throw InputError(fmt::format("texture '{}': cannot read image: {}", path, in.geterror()));
  const OIIO::ImageSpec& spec = in.spec();
  const bool encoded = !linear && (spec.format.basetype == OIIO::TypeDesc::UINT8 || integer_format(in.nativespec().format));
  const int w = spec.width, h = spec.height, c = spec.nchannels;
  std::vector<float> px(std::size_t(w) * h * c);
  in.get_pixels(OIIO::ROI(0, w, 0, h, 0, 1, 0, c), OIIO::TypeDesc::FLOAT, px.data());
  return image_texture(path, w, h, c, encoded, px);
}

std::unique_ptr<Texture> load_image_texture(const std::string& name, const unsigned char* data, std::size_t size,
                                            bool linear) {
  // OIIO reads from memory through an IOProxy; the format comes from the name's extension, or
  // from trying every reader when it has none that OIIO knows.
  OIIO::Filesystem::IOMemReader mem(data, size);
  auto in = OIIO::ImageInput::open(name, nullptr, &mem);
  if (!in) throw InputError(fmt::format("texture '{}': cannot read image: {}", name, OIIO::geterror()));
  const OIIO::ImageSpec spec = in->spec();
  check_image_spec(name, spec);
  const int w = spec.width, h = spec.height, c = spec.nchannels;
  std::vector<float> px(std::size_t(w) * h * c);
  if (!in->read_image(0, 0, 0, c, OIIO::TypeDesc::FLOAT, px.data()))
    throw InputError(fmt::format("texture '{}': cannot read image: {}", name, in->geterror()));
  return image_texture(name, w, h, c, !linear && integer_format(spec.format), px);
}

std::unique_ptr<Texture> channel_texture(const Texture& source, int channel, float power) {
  return std::make_unique<ChannelView>(source, channel, power);
}

Vec3 texture_mean(const Texture& t) {
  // A 256 x 256 grid of texel-centre lookups: the mean of a bilinear image to well under 1% for
  // images up to 4K, and the one answer for procedural textures too.
  constexpr int n = 256;
  Vec3 sum(0.0f);
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) sum += t.eval((i + 0.5f) / n, (j + 0.5f) / n);
  return sum / float(n * n);
}

// Pattern scales and counts: finite, positive, and small enough that u * scale keeps float precision.
constexpr RealBound kTextureScale{0, 1e6, "pattern repeats per unit of u and v", true};
constexpr RealBound kTexturePattern{0, 1e6, "pattern repeats per unit", true};

std::unique_ptr<Texture> make_texture(ConfigTable& t, const std::string& scene_dir,
                                      std::vector<std::string>& files) {
  const std::string type = t.require_string("type");
  std::unique_ptr<Texture> tex;
  if (type == "image") {
    std::string file = t.require_string("file");
    std::filesystem::path p(file);
    if (p.is_relative()) p = std::filesystem::path(scene_dir) / p;
    require_regular_file(p.string(), t.where("file"), "texture file");
    files.push_back(p.string());
    tex = load_image_texture(p.string(), t.get("linear", false));
  } else if (type == "checker") {
    float scale = float(t.get("scale", 8.0, kTextureScale));
    Vec3 a = vec3(t.get("color_a", std::array<double, 3>{0.8, 0.8, 0.8}, bounds::kReflectance));
    Vec3 b = vec3(t.get("color_b", std::array<double, 3>{0.2, 0.2, 0.2}, bounds::kReflectance));
    tex = std::make_unique<Checker>(scale, a, b);
  } else if (type == "wood") {
    float scale = float(t.get("scale", 4.0, kTextureScale));
    Vec3 a = vec3(t.get("color_a", std::array<double, 3>{0.62, 0.42, 0.24}, bounds::kReflectance));
    Vec3 b = vec3(t.get("color_b", std::array<double, 3>{0.36, 0.21, 0.10}, bounds::kReflectance));
    tex = std::make_unique<Wood>(scale, a, b, float(t.get("rings", 6.0, kTexturePattern)));
  } else if (type == "brick") {
    float scale = float(t.get("scale", 1.0, kTextureScale));
    Vec3 a = vec3(t.get("color_a", std::array<double, 3>{0.55, 0.25, 0.18}, bounds::kReflectance));
    Vec3 b = vec3(t.get("color_b", std::array<double, 3>{0.75, 0.73, 0.70}, bounds::kReflectance));
    float rows = float(t.get("rows", 12.0, kTexturePattern));
    float mortar = float(t.get("mortar", 0.08, RealBound{0, 1, "a fraction of a brick"}));
    float variation = float(t.get("variation", 0.3, RealBound{0, 1, "a fraction of the brick colour"}));
    tex = std::make_unique<Brick>(scale, a, b, rows, mortar, variation);
  } else if (type == "noise") {
    float scale = float(t.get("scale", 8.0, kTextureScale));
    Vec3 a = vec3(t.get("color_a", std::array<double, 3>{0.3, 0.3, 0.3}, bounds::kReflectance));
    Vec3 b = vec3(t.get("color_b", std::array<double, 3>{0.7, 0.7, 0.7}, bounds::kReflectance));
    tex = std::make_unique<Noise>(scale, a, b, t.get("octaves", 4, bounds::kTextureOctaves));
  } else if (type == "leaf") {
    float scale = float(t.get("scale", 1.0, kTextureScale));
    Vec3 a = vec3(t.get("color_a", std::array<double, 3>{0.16, 0.36, 0.08}, bounds::kReflectance));
    Vec3 b = vec3(t.get("color_b", std::array<double, 3>{0.45, 0.55, 0.2}, bounds::kReflectance));
    tex = std::make_unique<Leaf>(scale, a, b);
  } else {
    throw InputError(fmt::format("{}: unknown texture type '{}' (expected image, checker, wood, brick, noise or leaf)",
                                 t.where("type"), type));
  }
  t.finish();
  return tex;
}

}  // namespace dnb::rt
