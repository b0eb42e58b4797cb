#include "denoisers/am/capture.h"
#include "core/env.h"

#include <unistd.h>

#include <atomic>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>

#include "core/errors.h"

namespace dnb {
namespace {

// File layout (little-endian, the machines it travels between): magic, version, then
//   int32 W, H, C (source channels), D (guide channels)
//   double sigma_s, sigma_r, outlier_scale; int32 tree_height, pca_iterations, adjust_outliers, downsample
//   int64 query count; per query: int32 x, y, adjust_outliers, has_src; D floats; C floats if has_src
//   the source's W x H x C floats, then the guide's W x H x D floats, row by row.
constexpr char kMagic[8] = {'D', 'N', 'B', 'A', 'M', 'C', 'A', 'P'};
constexpr std::int32_t kVersion = 1;

struct Writer {
  std::ofstream out;
  template <typename T>
  void put(const T& v) {
    out.write(reinterpret_cast<const char*>(&v), sizeof(T));
  }
  void put_floats(const float* p, std::size_t n) { out.write(reinterpret_cast<const char*>(p), std::streamsize(n * sizeof(float))); }
  void put_view(ConstImageView v) {
    for (int y = 0; y < v.height; ++y) put_floats(v.row(y), std::size_t(v.width) * v.channels);
  }
};

struct Reader {
  std::ifstream in;
  const std::string& path;
  template <typename T>
  T get() {
    T v{};
    in.read(reinterpret_cast<char*>(&v), sizeof(T));
    if (!in) throw InputError(path + ": truncated adaptive-manifold capture");
    return v;
  }
  void get_floats(float* p, std::size_t n) {
    in.read(reinterpret_cast<char*>(p), std::streamsize(n * sizeof(float)));
    if (!in) throw InputError(path + ": truncated adaptive-manifold capture");
  }
};

}  // namespace

void am_capture_if_asked(ConstImageView src, ConstImageView guide, const AmSettings& s,
                         const std::vector<AmQuery>& queries) {
  const char* dir = env::get("AM_CAPTURE");
  if (!dir || !*dir) return;
  static std::atomic<int> calls{0};
  const int n = ++calls;
  if (const char* max = env::get("AM_CAPTURE_MAX"); max && n > std::atoi(max)) return;
  const std::string path = (std::filesystem::path(dir) / ("am-" + std::to_string(::getpid()) + "-" + std::to_string(n) + ".bin")).string();
  const std::string tmp = path + ".tmp";
  {
    Writer w{std::ofstream(tmp, std::ios::binary | std::ios::trunc)};
    if (!w.out) throw WorkError("DENOISEBENCH_AM_CAPTURE: cannot write " + tmp);
    w.out.write(kMagic, sizeof kMagic);
    w.put(kVersion);
    w.put(std::int32_t(src.width));
    w.put(std::int32_t(src.height));
    w.put(std::int32_t(src.channels));
    w.put(std::int32_t(guide.channels));
    w.put(s.sigma_s);
    w.put(s.sigma_r);
    w.put(s.outlier_scale);
    w.put(std::int32_t(s.tree_height));
    w.put(std::int32_t(s.pca_iterations));
    w.put(std::int32_t(s.adjust_outliers));
    w.put(std::int32_t(s.downsample));
    w.put(std::int64_t(queries.size()));
    for (const AmQuery& q : queries) {
      w.put(std::int32_t(q.x));
      w.put(std::int32_t(q.y));
      w.put(std::int32_t(q.adjust_outliers));
      w.put(std::int32_t(q.src != nullptr));
      w.put_floats(q.guide, std::size_t(guide.channels));
      if (q.src) w.put_floats(q.src, std::size_t(src.channels));
    }
    w.put_view(src);
    w.put_view(guide);
    w.out.close();
    if (!w.out) {
      std::remove(tmp.c_str());
      throw WorkError("DENOISEBENCH_AM_CAPTURE: writing " + tmp + " failed");
    }
  }
  std::error_code ec;
  std::filesystem::rename(tmp, path, ec);
  if (ec) {
    std::remove(tmp.c_str());
    throw WorkError("DENOISEBENCH_AM_CAPTURE: cannot rename " + tmp + " to " + path + ": " + ec.message());
  }
}

AmCapture read_am_capture(const std::string& path) {
  Reader r{std::ifstream(path, std::ios::binary), path};
  if (!r.in) throw InputError(path + ": cannot open");
  char magic[sizeof kMagic];
  r.in.read(magic, sizeof magic);
  if (!r.in || std::memcmp(magic, kMagic, sizeof kMagic) != 0)
    throw InputError(path + ": not an adaptive-manifold capture (written with DENOISEBENCH_AM_CAPTURE)");
  const auto version = r.get<std::int32_t>();
  if (version != kVersion)
    throw InputError(path + ": capture version " + std::to_string(version) + ", expected " + std::to_string(kVersion));
  const auto W = r.get<std::int32_t>(), H = r.get<std::int32_t>(), C = r.get<std::int32_t>(), D = r.get<std::int32_t>();
  if (W < 1 || H < 1 || W > Image::kMaxSide || H > Image::kMaxSide || std::int64_t(W) * H > Image::kMaxPixels ||
      C < 1 || C > 64 || D < 1 || D > 64)
    throw InputError(path + ": image " + std::to_string(W) + "x" + std::to_string(H) + " with " + std::to_string(C) +
                     " source and " + std::to_string(D) + " guide channels is out of range");
  AmCapture c;
  c.settings.sigma_s = r.get<double>();
  c.settings.sigma_r = r.get<double>();
  c.settings.outlier_scale = r.get<double>();
  c.settings.tree_height = r.get<std::int32_t>();
  c.settings.pca_iterations = r.get<std::int32_t>();
  c.settings.adjust_outliers = r.get<std::int32_t>() != 0;
  c.settings.downsample = r.get<std::int32_t>();
  const auto nq = r.get<std::int64_t>();
  if (nq < 0 || nq > std::int64_t(W) * H * 64) throw InputError(path + ": " + std::to_string(nq) + " queries is out of range");
  c.query_guide.resize(std::size_t(nq) * D);
  c.query_src.resize(std::size_t(nq) * C);
  c.queries.resize(std::size_t(nq));
  for (std::int64_t i = 0; i < nq; ++i) {
    AmQuery& q = c.queries[std::size_t(i)];
    q.x = r.get<std::int32_t>();
    q.y = r.get<std::int32_t>();
    q.adjust_outliers = r.get<std::int32_t>() != 0;
    const bool has_src = r.get<std::int32_t>() != 0;
    q.guide = c.query_guide.data() + std::size_t(i) * D;
    r.get_floats(c.query_guide.data() + std::size_t(i) * D, std::size_t(D));
    if (has_src) {
      q.src = c.query_src.data() + std::size_t(i) * C;
      r.get_floats(c.query_src.data() + std::size_t(i) * C, std::size_t(C));
    }
  }
  c.src = Image(W, H, C);
  c.guide = Image(W, H, D);
  r.get_floats(c.src.data(), c.src.size());
  r.get_floats(c.guide.data(), c.guide.size());
  return c;
}

}  // namespace dnb
