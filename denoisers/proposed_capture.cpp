#include "denoisers/proposed_capture.h"

#include <cstdint>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <vector>

#include "core/errors.h"

namespace dnb {
namespace {

constexpr char kMagic[8] = {'D', 'N', 'B', 'P', 'C', 'A', 'P', '1'};

// What the pipeline reads: every level's split, normal, depth and tint, the colour and variance
// (the detail guard).
std::vector<std::string> captured_layers(const AovFrame& f, int levels) {
  std::vector<std::string> out;
  for (int k = 0; k <= levels; ++k)
    for (const char* base : {layer::kDirect, layer::kIndirect, layer::kAlbedo, layer::kReflection, layer::kEmission,
                             layer::kNormal, layer::kDepth, layer::kTint}) {
      const std::string name = layer::at_level(k, base);
      if (f.has(name)) out.push_back(name);
    }
  for (const char* name : {layer::kColor, layer::kVariance})
    if (f.has(name)) out.push_back(name);
  return out;
}

class Writer {
 public:
  explicit Writer(std::ofstream& o) : o_(o) {}
  template <typename T>
  void pod(const T& v) {
    o_.write(reinterpret_cast<const char*>(&v), sizeof v);
  }
  void floats(const float* p, std::size_t n) { o_.write(reinterpret_cast<const char*>(p), std::streamsize(n * sizeof(float))); }
  void str(const std::string& s) {
    pod(std::uint32_t(s.size()));
    o_.write(s.data(), std::streamsize(s.size()));
  }

 private:
  std::ofstream& o_;
};

class Reader {
 public:
  Reader(std::ifstream& i, const std::string& path) : i_(i), path_(path) {}
  template <typename T>
  T pod(const char* what) {
    T v{};
    i_.read(reinterpret_cast<char*>(&v), sizeof v);
    if (!i_) fail(what);
    return v;
  }
  void floats(float* p, std::size_t n, const char* what) {
    i_.read(reinterpret_cast<char*>(p), std::streamsize(n * sizeof(float)));
    if (!i_) fail(what);
  }
  std::string str(const char* what) {
    const auto n = pod<std::uint32_t>(what);
    if (n > 256) fail(what);
    std::string s(n, '\0');
    i_.read(s.data(), n);
    if (!i_) fail(what);
    return s;
  }
  [[noreturn]] void fail(const char* what) const {
    throw InputError("proposed capture '" + path_ + "': truncated or malformed at " + what +
                     " (expected a file written by DENOISEBENCH_PROPOSED_CAPTURE, denoisers/proposed_capture.h)");
  }

 private:
  std::ifstream& i_;
  const std::string& path_;
};

// The plan's fields, in one order for both directions.
template <typename F>
void plan_fields(ProposedDevicePlan& p, F&& f) {
  for (AmSettings* a : {&p.am, &p.reflection_am}) {
    f(a->sigma_s), f(a->sigma_r), f(a->tree_height), f(a->pca_iterations), f(a->adjust_outliers), f(a->outlier_scale),
        f(a->downsample);
  }
  f(p.nlm.radius), f(p.nlm.patch_sigma), f(p.nlm.dims), f(p.nlm.samples);
  f(p.sigma_nlm), f(p.sigma_direct), f(p.sigma_normal), f(p.sigma_depth), f(p.firefly_ratio), f(p.levels), f(p.edges),
      f(p.reflection_sum), f(p.smooth_tints), f(p.tint_radius), f(p.tint_band), f(p.tint_normal_distance),
      f(p.tint_depth_distance), f(p.detail_guard);
}

}  // namespace

void write_proposed_capture(const std::string& path, const AovFrame& frame, const ProposedDevicePlan& plan,
                            const Image& cpu_output) {
  const std::string tmp = path + ".tmp";
  {
    std::ofstream o(tmp, std::ios::binary | std::ios::trunc);
    if (!o) throw WorkError("proposed capture: cannot write '" + tmp + "'");
    Writer w(o);
    o.write(kMagic, sizeof kMagic);
    ProposedDevicePlan p = plan;
    plan_fields(p, [&](auto& v) { w.pod(v); });
    w.pod(std::int32_t(frame.width())), w.pod(std::int32_t(frame.height())), w.pod(std::int32_t(frame.meta.spp));
    const std::vector<std::string> names = captured_layers(frame, plan.levels);
    w.pod(std::uint32_t(names.size()));
    for (const std::string& n : names) {
      const Image& im = frame.layer(n);
      w.str(n);
      w.pod(std::int32_t(im.channels()));
      w.floats(im.data(), im.size());
    }
    const std::size_t ne = frame.edges ? frame.edges->size() : 0;
    w.pod(std::uint64_t(ne));
    for (std::size_t e = 0; e < ne; ++e) w.pod(std::int32_t(frame.edges->pixels[e]));
    for (std::size_t s = 0; s < ne * EdgeSubpixels::kPerPixel; ++s) {
      const EdgeSample& x = frame.edges->samples[s];
      w.floats(x.normal, 3), w.floats(&x.depth, 1), w.floats(x.albedo, 3), w.floats(x.direct, 3), w.floats(x.indirect, 3);
    }
    w.floats(cpu_output.data(), cpu_output.size());
    if (!o) throw WorkError("proposed capture: writing '" + tmp + "' failed");
  }
  if (std::rename(tmp.c_str(), path.c_str()) != 0) throw WorkError("proposed capture: cannot rename '" + tmp + "' to '" + path + "'");
}

ProposedCapture read_proposed_capture(const std::string& path) {
  std::ifstream i(path, std::ios::binary);
  if (!i) throw InputError("proposed capture '" + path + "': no such file");
  Reader r(i, path);
  char magic[8];
  i.read(magic, sizeof magic);
  if (!i || std::memcmp(magic, kMagic, sizeof kMagic) != 0) r.fail("the header (DNBPCAP1)");
  ProposedCapture c;
  plan_fields(c.plan, [&](auto& v) { v = r.pod<std::remove_reference_t<decltype(v)>>("the plan"); });
  const auto w = r.pod<std::int32_t>("the width"), h = r.pod<std::int32_t>("the height"), spp = r.pod<std::int32_t>("spp");
  if (w < 1 || h < 1 || w > 16384 || h > 16384) r.fail("the size (1 to 16384 a side)");
  c.frame = AovFrame(w, h);
  c.frame.meta.spp = spp;
  const auto nl = r.pod<std::uint32_t>("the layer count");
  if (nl > 256) r.fail("the layer count");
  for (std::uint32_t k = 0; k < nl; ++k) {
    const std::string name = r.str("a layer's name");
    const auto ch = r.pod<std::int32_t>("a layer's channels");
    if (ch < 1 || ch > 4) r.fail("a layer's channels (1 to 4)");
    Image& im = c.frame.add(name, ch);
    r.floats(im.data(), im.size(), "a layer's values");
  }
  const auto ne = r.pod<std::uint64_t>("the edge pixel count");
  if (ne > std::uint64_t(w) * std::uint64_t(h)) r.fail("the edge pixel count");
  if (ne > 0) {
    EdgeSubpixels g;
    g.pixels.resize(ne);
    for (auto& p : g.pixels) {
      p = r.pod<std::int32_t>("an edge pixel");
      if (p < 0 || p >= w * h) r.fail("an edge pixel (inside the frame)");
    }
    g.samples.resize(ne * EdgeSubpixels::kPerPixel);
    for (EdgeSample& x : g.samples) {
      r.floats(x.normal, 3, "an edge sample"), r.floats(&x.depth, 1, "an edge sample");
      r.floats(x.albedo, 3, "an edge sample"), r.floats(x.direct, 3, "an edge sample");
      r.floats(x.indirect, 3, "an edge sample");
    }
    c.frame.edges = std::move(g);
  }
  c.cpu_output = Image(w, h, 3);
  r.floats(c.cpu_output.data(), c.cpu_output.size(), "the CPU output");
  return c;
}

}  // namespace dnb
