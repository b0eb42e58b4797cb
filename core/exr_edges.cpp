#include "core/exr_edges.h"

#include <cerrno>
#include <cstdint>
#include <cstring>

#include <OpenImageIO/deepdata.h>
#include <OpenImageIO/imageio.h>
#include <fmt/format.h>

#include "core/errors.h"
#include "core/exr_header.h"
#include "core/hash.h"

namespace dnb::exr {
using OIIO::TypeDesc;

namespace {

const char* kDeepChannels[] = {"normal.X", "normal.Y", "normal.Z", "Z",          "albedo.R",
                               "albedo.G", "albedo.B", "direct.R", "direct.G",   "direct.B",
                               "indirect.R", "indirect.G", "indirect.B"};
constexpr int kDeepCount = 13;

void pack(const EdgeSample& s, float* v) {
  v[0] = s.normal[0]; v[1] = s.normal[1]; v[2] = s.normal[2]; v[3] = s.depth;
  for (int c = 0; c < 3; ++c) { v[4 + c] = s.albedo[c]; v[7 + c] = s.direct[c]; v[10 + c] = s.indirect[c]; }
}
void unpack(const float* v, EdgeSample& s) {
  s.normal[0] = v[0]; s.normal[1] = v[1]; s.normal[2] = v[2]; s.depth = v[3];
  for (int c = 0; c < 3; ++c) { s.albedo[c] = v[4 + c]; s.direct[c] = v[7 + c]; s.indirect[c] = v[10 + c]; }
}

}  // namespace

std::unique_ptr<AtomicOutput> stage_edges(const EdgeSubpixels& e, int width, int height, const std::string& path,
                                          std::string& digest) {
  OIIO::ImageSpec spec(width, height, kDeepCount, TypeDesc::FLOAT);
  spec.deep = true;
  spec.channelnames.assign(std::begin(kDeepChannels), std::end(kDeepChannels));
  spec.z_channel = 3;
  spec.attribute("compression", "zips");
  OIIO::DeepData dd;
  dd.init(spec);
  for (std::size_t i = 0; i < e.size(); ++i) dd.set_samples(e.pixels[i], EdgeSubpixels::kPerPixel);
  float v[kDeepCount];
  for (std::size_t i = 0; i < e.size(); ++i)
    for (int s = 0; s < EdgeSubpixels::kPerPixel; ++s) {
      pack(e.of(i)[s], v);
      for (int c = 0; c < kDeepCount; ++c) dd.set_deep_value(e.pixels[i], c, s, v[c]);
    }
  // OpenImageIO's OpenEXR writer encodes deep images to files only (through an IOProxy it writes
  // nothing and reports success), and it does not notice a full disk: the file is read back
  // before it may be committed.
  auto out = std::make_unique<AtomicOutput>(path);
  errno = 0;
  auto o = OIIO::ImageOutput::create(out->temp_path());
  if (!o || !o->open(out->temp_path(), spec) || !o->write_deep_image(dd) || !o->close()) {
    const int err = errno;  // the system's reason, when the writer's file calls failed
    // The writer's message names the temporary file; the user gave `path`.
    std::string why = o ? o->geterror() : OIIO::geterror();
    for (auto at = why.find(out->temp_path()); at != std::string::npos; at = why.find(out->temp_path()))
      why.replace(at, out->temp_path().size(), path);
    throw WorkError(
        fmt::format("cannot write '{}': {}{}", path, why, err ? fmt::format(" ({})", std::strerror(err)) : ""));
  }
  o.reset();
  auto in = OIIO::ImageInput::open(out->temp_path());
  OIIO::DeepData back;
  if (!in || !in->read_native_deep_image(0, 0, back) || back.pixels() != dd.pixels() ||
      back.all_samples().size() != dd.all_samples().size())
    throw WorkError(fmt::format("cannot write '{}': the file did not read back ({})", path,
                                in ? in->geterror() : OIIO::geterror()));
  in.reset();
  digest = sha256_file(out->temp_path());
  return out;
}

EdgeSubpixels read_edges(const std::string& path, int width, int height) {
  auto in = open_input(path);
  const auto& spec = in->spec();
  if (!spec.deep || spec.width != width || spec.height != height)
    throw InputError(fmt::format("'{}': expected a deep {}x{} image of edge sub-pixels", path, width, height));
  int idx[kDeepCount];
  for (int c = 0; c < kDeepCount; ++c) {
    idx[c] = spec.channelindex(kDeepChannels[c]);
    if (idx[c] < 0)
      throw InputError(fmt::format("'{}': missing deep channel '{}'", path, kDeepChannels[c]));
  }
  OIIO::DeepData dd;
  if (!in->read_native_deep_image(0, 0, dd))
    throw InputError(fmt::format("'{}': cannot read deep data: {}", path, in->geterror()));
  EdgeSubpixels e;
  float v[kDeepCount];
  for (std::int64_t p = 0; p < std::int64_t(width) * height; ++p) {
    int n = dd.samples(p);
    if (n == 0) continue;
    if (n != EdgeSubpixels::kPerPixel)
      throw InputError(fmt::format("'{}': pixel ({}, {}) has {} sub-pixel samples, expected {}", path,
                                   p % width, p / width, n, EdgeSubpixels::kPerPixel));
    e.pixels.push_back(std::int32_t(p));
    for (int s = 0; s < n; ++s) {
      for (int c = 0; c < kDeepCount; ++c) v[c] = dd.deep_value(p, idx[c], s);
      EdgeSample es;
      unpack(v, es);
      e.samples.push_back(es);
    }
  }
  return e;
}

}  // namespace dnb::exr
