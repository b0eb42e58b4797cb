// The adaptive-manifold core (see adaptive_manifold.h for the algorithm and its choices).
//
// Why hand-written and not OpenCV's ximgproc::AdaptiveManifoldFilter: OpenCV's version cannot
// answer slice queries with another guide value (paper 3.1 needs that for edge sub-pixels), its
// power iteration restarts from the random vector every step, and it is about 3x slower here
// (bench/am_bench.cpp): it splits every image into planes with a separate full-resolution pass
// per operation. Here every full-resolution pass is fused (distance, weight, splat, covariance
// in one; slice, split, child splat in the other), rows are planar so the loops vectorise (the
// children's reduced splats are pixel-interleaved instead, for their low-pass: see Interleaved),
// and the exponentials go through OpenCV's vectorised cv::hal::exp32f.
#include "denoisers/adaptive_manifold.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <mutex>
#include <random>
#include <type_traits>

#include <opencv2/core/hal/hal.hpp>
#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include "core/errors.h"

namespace dnb {

int am_tree_height(double sigma_s, double sigma_r) {
  const double hs = std::floor(std::log2(sigma_s)) - 1.0;
  const double lr = 1.0 - sigma_r;
  return std::max(2, int(std::ceil(hs * lr)));
}

int am_downsample_factor(double sigma_s, double sigma_r) {
  const double df = std::min(sigma_s / 4.0, 256.0 * sigma_r);
  int p = 1;
  while (p * 2 <= df) p *= 2;
  return p;
}

Image make_guide(const std::vector<GuideGroup>& groups, float sigma_r) {
  if (groups.empty()) throw WorkError("make_guide: no guide group");
  const int w = groups[0].image.width, h = groups[0].image.height;
  int d = 0;
  for (const auto& g : groups) {
    if (g.image.width != w || g.image.height != h) throw WorkError("make_guide: guide groups differ in size");
    if (!(g.sigma > 0)) throw WorkError("make_guide: a guide group's sigma must be positive");
    d += g.image.channels;
  }
  Image out(w, h, d);
  tbb::parallel_for(0, h, [&](int y) {
    float* o = out.pixel(0, y);
    for (int x = 0; x < w; ++x) {
      for (const auto& g : groups) {
        const float s = sigma_r / g.sigma;
        const float* p = g.image.pixel(x, y);
        for (int c = 0; c < g.image.channels; ++c) *o++ = s * p[c];
      }
    }
  });
  return out;
}

namespace {

// Independent partial sums of a dot product: float sums only vectorise when their order is
// fixed by the code (no -ffast-math), and a fixed order also keeps the result bit-identical.
constexpr int kLanes = 16;

// Planar float images: channel c of pixel (x, y) at data[(c * h + y) * w + x].
// Full-resolution buffers are recycled between runs: a fresh 100 MB per call (1024x768 with a
// 10-channel guide) costs more in page faults than a pass over it. At most kPoolBytes are kept.
class BufferPool {
 public:
  static BufferPool& get() {
    static BufferPool pool;
    return pool;
  }
  std::vector<float> take(std::size_t n) {
    std::lock_guard<std::mutex> lock(m_);
    std::size_t best = free_.size();
    for (std::size_t i = 0; i < free_.size(); ++i)
      if (free_[i].capacity() >= n && (best == free_.size() || free_[i].capacity() < free_[best].capacity())) best = i;
    if (best == free_.size()) return {};
    std::vector<float> v = std::move(free_[best]);
    free_.erase(free_.begin() + std::ptrdiff_t(best));
    bytes_ -= v.capacity() * sizeof(float);
    return v;
  }
  void give(std::vector<float>&& v) {
    const std::size_t b = v.capacity() * sizeof(float);
    if (b < (std::size_t(1) << 20)) return;  // small buffers: malloc recycles them anyway
    std::lock_guard<std::mutex> lock(m_);
    if (bytes_ + b > kPoolBytes) return;
    bytes_ += b;
    free_.push_back(std::move(v));
  }

 private:
  static constexpr std::size_t kPoolBytes = std::size_t(512) << 20;
  std::mutex m_;
  std::vector<std::vector<float>> free_;
  std::size_t bytes_ = 0;
};

std::vector<float> pooled(std::size_t n, float fill) {
  std::vector<float> v = BufferPool::get().take(n);
  v.assign(n, fill);
  return v;
}
// For a buffer its user overwrites whole: a recycled one keeps its stale values (shrinking a
// vector writes nothing; only growth beyond its size value-initialises the tail).
std::vector<float> pooled_uninitialised(std::size_t n) {
  std::vector<float> v = BufferPool::get().take(n);
  v.resize(n);
  return v;
}

struct Planes {
  int w = 0, h = 0, n = 0;
  std::vector<float> data;
  Planes() = default;
  Planes(int w_, int h_, int n_) : w(w_), h(h_), n(n_), data(pooled(std::size_t(w_) * h_ * n_, 0.0f)) {}
  // Contents unspecified: for planes the caller writes in full before reading.
  struct Overwritten {};
  Planes(int w_, int h_, int n_, Overwritten) : w(w_), h(h_), n(n_), data(pooled_uninitialised(std::size_t(w_) * h_ * n_)) {}
  Planes(const Planes& o) : w(o.w), h(o.h), n(o.n), data(BufferPool::get().take(o.data.size())) {
    data.assign(o.data.begin(), o.data.end());
  }
  Planes(Planes&&) = default;
  Planes& operator=(Planes&& o) {
    BufferPool::get().give(std::move(data));
    w = o.w, h = o.h, n = o.n, data = std::move(o.data);
    return *this;
  }
  Planes& operator=(const Planes&) = delete;
  ~Planes() { BufferPool::get().give(std::move(data)); }
  float* plane(int c) { return data.data() + std::size_t(c) * w * h; }
  const float* plane(int c) const { return data.data() + std::size_t(c) * w * h; }
  float* row(int c, int y) { return plane(c) + std::size_t(y) * w; }
  const float* row(int c, int y) const { return plane(c) + std::size_t(y) * w; }
};

// The vertical half of recursive_filter: columns are independent, split into 64-wide chunks.
template <typename WV>
void recursive_filter_vertical(Planes& p, int first, int count, WV wv) {
  const int w = p.w, h = p.h;
  constexpr int kChunk = 64;
  tbb::parallel_for(0, (w + kChunk - 1) / kChunk, [&](int chunk) {
    const int x0 = chunk * kChunk, x1 = std::min(w, x0 + kChunk);
    for (int c = first; c < first + count; ++c) {
      for (int y = 1; y < h; ++y) {
        const float* a = wv(y - 1);
        float* r = p.row(c, y);
        const float* q = p.row(c, y - 1);
        for (int x = x0; x < x1; ++x) r[x] += a[x] * (q[x] - r[x]);
      }
      for (int y = h - 2; y >= 0; --y) {
        const float* a = wv(y);
        float* r = p.row(c, y);
        const float* q = p.row(c, y + 1);
        for (int x = x0; x < x1; ++x) r[x] += a[x] * (q[x] - r[x]);
      }
    }
  });
}

// The horizontal recursion runs along x, so in planar rows it is a scalar dependency chain per
// channel, latency-bound. Here rows are pixel-interleaved (channels padded to blocks of 8): the
// 8 channels of a block are one SIMD vector, and R rows x NB blocks independent chains hide
// the latency. GCC/Clang vector extensions keep it portable; each element sees the same
// operations, in the same order, as in the planar loop. a[r] holds row r's w-1 edge weights.
using Vec8 = float __attribute__((vector_size(32)));
inline Vec8 load8(const float* p) {
  Vec8 v;
  std::memcpy(&v, p, sizeof v);
  return v;
}
inline void store8(float* p, Vec8 v) { std::memcpy(p, &v, sizeof v); }

template <int NB, int R>
void recursive_interleaved(float* const* rows, const float* const* a, int w) {
  constexpr int DP = 8 * NB;
  Vec8 prev[R][NB];
  auto start = [&](int x) {
    for (int r = 0; r < R; ++r)
      for (int b = 0; b < NB; ++b) prev[r][b] = load8(rows[r] + std::size_t(x) * DP + 8 * b);
  };
  // Pixel x of row r moves towards the previous one along the pass by the edge weight k.
  auto step = [&](int r, int x, float k) {
    for (int b = 0; b < NB; ++b) {
      float* q = rows[r] + std::size_t(x) * DP + 8 * b;
      Vec8 v = load8(q);
      v += k * (prev[r][b] - v);
      store8(q, v);
      prev[r][b] = v;
    }
  };
  start(0);
  for (int x = 1; x < w; ++x)
    for (int r = 0; r < R; ++r) step(r, x, a[r][x - 1]);
  start(w - 1);
  for (int x = w - 2; x >= 0; --x)
    for (int r = 0; r < R; ++r) step(r, x, a[r][x]);
}

// Rows of `nb` blocks, in groups of kRowGroup (the last group may be smaller).
constexpr int kRowGroup = 4;
template <int R>
void recursive_interleaved(float* const* rows, const float* const* a, int w, int nb) {
  switch (nb) {
    case 1: return recursive_interleaved<1, R>(rows, a, w);
    case 2: return recursive_interleaved<2, R>(rows, a, w);
    case 3: return recursive_interleaved<3, R>(rows, a, w);
    case 4: return recursive_interleaved<4, R>(rows, a, w);
    default: break;
  }
  // Wider (guides of more than 32 channels, rare): block by block through a copy.
  std::vector<float> tmp(std::size_t(w) * 8);
  for (int r = 0; r < R; ++r)
    for (int b = 0; b < nb; ++b) {
      for (int x = 0; x < w; ++x) std::memcpy(&tmp[std::size_t(x) * 8], rows[r] + std::size_t(x) * nb * 8 + 8 * b, 32);
      float* one = tmp.data();
      recursive_interleaved<1, 1>(&one, a + r, w);
      for (int x = 0; x < w; ++x) std::memcpy(rows[r] + std::size_t(x) * nb * 8 + 8 * b, &tmp[std::size_t(x) * 8], 32);
    }
}
inline void recursive_interleaved(float* const* rows, const float* const* a, int w, int nb, int n) {
  switch (n) {
    case 4: return recursive_interleaved<4>(rows, a, w, nb);
    case 3: return recursive_interleaved<3>(rows, a, w, nb);
    case 2: return recursive_interleaved<2>(rows, a, w, nb);
    default: return recursive_interleaved<1>(rows, a, w, nb);
  }
}

// Moves row y of planes [first, first + count) to the pixel-interleaved row `il` (stride dp),
// or back when kBack, in blocks of 8 pixels so the transposes stay in registers.
template <bool kBack>
void interleave(Planes& p, int first, int count, int y, float* il, int dp) {
  float* rows[32];
  for (int c0 = 0; c0 < count; c0 += 32) {
    const int m = std::min(32, count - c0);
    for (int c = 0; c < m; ++c) rows[c] = p.row(first + c0 + c, y);
    for (int x0 = 0; x0 < p.w; x0 += 8) {
      const int xn = std::min(8, p.w - x0);
      for (int c = 0; c < m; ++c)
        for (int k = 0; k < xn; ++k) {
          float& v = il[std::size_t(x0 + k) * dp + c0 + c];
          if constexpr (kBack) rows[c][x0 + k] = v;
          else v = rows[c][x0 + k];
        }
    }
  }
}

// Recursive filter, one causal and one anti-causal pass per direction (Gastal and Oliveira
// 2011, domain transform RF): out[x] += a_x (out[x-1] - out[x]) with a per-edge feedback a_x.
// `wh(y)` returns the w-1 horizontal edge weights of row y, `wv(y)` the w vertical weights
// between rows y and y+1. Rows are independent in the horizontal pass and columns in the
// vertical one, so the parallel split does not change the result.
template <typename WH, typename WV>
void recursive_filter(Planes& p, int first, int count, WH wh, WV wv) {
  const int w = p.w, h = p.h;
  // Horizontal: groups of rows gathered into interleaved buffers (recursive_interleaved).
  const int nb = (count + 7) / 8, dp = 8 * nb;
  const int groups = (h + kRowGroup - 1) / kRowGroup;
  tbb::parallel_for(tbb::blocked_range<int>(0, groups), [&](const tbb::blocked_range<int>& range) {
    std::vector<float> buf(std::size_t(kRowGroup) * w * dp, 0.0f);
    float* rows[kRowGroup];
    const float* a[kRowGroup];
    for (int r = 0; r < kRowGroup; ++r) rows[r] = buf.data() + std::size_t(r) * w * dp;
    for (int g = range.begin(); g != range.end(); ++g) {
      const int y0 = g * kRowGroup, n = std::min(kRowGroup, h - y0);
      for (int r = 0; r < n; ++r) {
        a[r] = wh(y0 + r);
        interleave<false>(p, first, count, y0 + r, rows[r], dp);
      }
      recursive_interleaved(rows, a, w, nb, n);
      for (int r = 0; r < n; ++r) interleave<true>(p, first, count, y0 + r, rows[r], dp);
    }
  });
  recursive_filter_vertical(p, first, count, wv);
}

// Their h_filter's edge weights: the constant feedback exp(-sqrt 2 / sigma), for rows of n pixels.
std::vector<float> low_pass_weights(int n, double sigma) {
  return std::vector<float>(std::max(n, 1), float(std::exp(-std::sqrt(2.0) / sigma)));
}

// Pixel-interleaved float image: row y holds w pixels of dp floats (n channels, then zeros up
// to dp, a multiple of 8), so that both halves of a constant-feedback recursive filter run in
// place: the horizontal one as recursive_interleaved over the rows themselves, the vertical one
// as one vector loop along each row (no per-column weights). Planar planes had to be
// transposed to interleaved rows and back for the horizontal half: that transpose cost more
// than the filtering.
struct Interleaved {
  int w = 0, h = 0, n = 0, dp = 8;
  Planes storage;  // one plane of w * dp floats by h rows (the pool's buffers, as planes use)
  Interleaved() = default;
  Interleaved(int w_, int h_, int n_)
      : w(w_), h(h_), n(n_), dp(8 * ((n_ + 7) / 8)), storage(w_ * dp, h_, 1, Planes::Overwritten{}) {}
  float* row(int y) { return storage.row(0, y); }
  const float* row(int y) const { return storage.row(0, y); }
};

// Their h_filter: the recursive filter with a constant feedback, on an interleaved image (every
// element sees the operations recursive_filter() would apply to its plane, in the same order).
void low_pass(Interleaved& p, double sigma) {
  const std::vector<float> a = low_pass_weights(p.w, sigma);
  const int w = p.w, h = p.h, nb = p.dp / 8;
  const int groups = (h + kRowGroup - 1) / kRowGroup;
  tbb::parallel_for(0, groups, [&](int g) {
    const int y0 = g * kRowGroup, n = std::min(kRowGroup, h - y0);
    float* rows[kRowGroup];
    const float* ar[kRowGroup];
    for (int r = 0; r < n; ++r) rows[r] = p.row(y0 + r), ar[r] = a.data();
    recursive_interleaved(rows, ar, w, nb, n);
  });
  const float k = a[0];
  const std::size_t len = std::size_t(w) * p.dp;
  constexpr std::size_t kChunk = 512;
  tbb::parallel_for(std::size_t(0), (len + kChunk - 1) / kChunk, [&](std::size_t chunk) {
    const std::size_t i0 = chunk * kChunk, i1 = std::min(len, i0 + kChunk);
    for (int y = 1; y < h; ++y) {
      float* __restrict r = p.row(y);
      const float* __restrict q = p.row(y - 1);
      for (std::size_t i = i0; i < i1; ++i) r[i] += k * (q[i] - r[i]);
    }
    for (int y = h - 2; y >= 0; --y) {
      float* __restrict r = p.row(y);
      const float* __restrict q = p.row(y + 1);
      for (std::size_t i = i0; i < i1; ++i) r[i] += k * (q[i] - r[i]);
    }
  });
}

std::uint64_t hash_guide(ConstImageView g) {
  std::uint64_t h = 1469598103934665603ull;
  auto mix = [&](std::uint64_t v) {
    h ^= v;
    h *= 1099511628211ull;
  };
  mix(std::uint64_t(g.width));
  mix(std::uint64_t(g.height));
  mix(std::uint64_t(g.channels));
  const std::size_t n = std::size_t(g.width) * g.height * g.channels;
  for (std::size_t k = 0; k < n; k += 61) {
    const std::size_t px = k / g.channels, c = k % g.channels;
    const float v = g.pixel(int(px % g.width), int(px / g.width))[c];
    std::uint32_t bits;
    std::memcpy(&bits, &v, 4);
    mix(bits);
  }
  return h;
}

class AmRun {
 public:
  AmRun(ConstImageView src, ConstImageView guide, const AmSettings& s, const std::vector<AmQuery>& queries)
      : s_(s), W_(src.width), H_(src.height), C_(src.channels), D_(guide.channels), queries_(queries) {
    if (guide.width != W_ || guide.height != H_)
      throw WorkError("am_filter: guide and source differ in size");
    if (!(s.sigma_s >= 1.0) || !(s.sigma_r > 0.0)) throw WorkError("am_filter: needs sigma_s >= 1 and sigma_r > 0");
    height_ = s.tree_height > 0 ? std::min(s.tree_height, 12) : std::min(am_tree_height(s.sigma_s, s.sigma_r), 12);
    df_ = s.downsample > 0 ? s.downsample : am_downsample_factor(s.sigma_s, s.sigma_r);
    sw_ = (W_ + df_ - 1) / df_;
    sh_ = (H_ + df_ - 1) / df_;
    inv_sr2_ = float(1.0 / (s.sigma_r * s.sigma_r));
    seed_ = am_detail::guide_seed(guide);

    guide_ = Planes(W_, H_, D_);
    src_ = Planes(W_, H_, C_);
    // The first manifold, the guide low-passed at full resolution: one pass over the
    // interleaved input makes planar copies of the guide and source and runs the horizontal
    // low-pass on the interleaved rows (recursive_interleaved), in pairs of rows; then the
    // vertical half.
    eta_full_ = Planes(W_, H_, D_);
    const int nb = (D_ + 7) / 8, dp = 8 * nb;
    const std::vector<float> a_first = low_pass_weights(W_, s.sigma_s);
    tbb::parallel_for(tbb::blocked_range<int>(0, (H_ + 1) / 2), [&](const tbb::blocked_range<int>& range) {
      std::vector<float> buf(std::size_t(2) * W_ * dp, 0.0f);
      float* rows[2] = {buf.data(), buf.data() + std::size_t(W_) * dp};
      for (int t = range.begin(); t != range.end(); ++t) {
        const int y0 = 2 * t, n = std::min(2, H_ - y0);
        for (int r = 0; r < n; ++r) {
          const int y = y0 + r;
          for (int x = 0; x < W_; ++x) {
            const float* g = guide.pixel(x, y);
            float* b = rows[r] + std::size_t(x) * dp;
            for (int c = 0; c < D_; ++c) {
              guide_.row(c, y)[x] = g[c];
              b[c] = g[c];
            }
            const float* f = src.pixel(x, y);
            for (int c = 0; c < C_; ++c) src_.row(c, y)[x] = f[c];
          }
        }
        const float* a[2] = {a_first.data(), a_first.data()};
        recursive_interleaved(rows, a, W_, nb, n);
        for (int r = 0; r < n; ++r)
          for (int x = 0; x < W_; ++x) {
            const float* b = rows[r] + std::size_t(x) * dp;
            for (int c = 0; c < D_; ++c) eta_full_.row(c, y0 + r)[x] = b[c];
          }
      }
    });
    recursive_filter_vertical(eta_full_, 0, D_, [&](int) { return a_first.data(); });
    acc_ = Planes(W_, H_, C_ + 1);
    label_.assign(std::size_t(W_) * H_, 1);
    if (s.adjust_outliers) min_d2_ = pooled(std::size_t(W_) * H_, INFINITY);

    // Bilinear upsampling from the reduced grid, pixel centres aligned: full-resolution x
    // sits at (x + 0.5) / df - 0.5 on the reduced grid.
    auto table = [&](int n, int small, std::vector<int>& i0, std::vector<int>& i1, std::vector<float>& f) {
      i0.resize(n), i1.resize(n), f.resize(n);
      for (int x = 0; x < n; ++x) {
        const float u = std::clamp((x + 0.5f) / df_ - 0.5f, 0.0f, float(small - 1));
        i0[x] = std::min(int(u), small - 1);
        i1[x] = std::min(i0[x] + 1, small - 1);
        f[x] = u - float(i0[x]);
      }
    };
    table(W_, sw_, x0_, x1_, fx_);
    table(H_, sh_, y0_, y1_, fy_);
    frac_.resize(df_);
    // Output pixel df sx + df/2 + k sits at sx + (df/2 + k + 0.5) / df - 0.5 on the reduced grid.
    for (int k = 0; k < df_; ++k) frac_[k] = (df_ / 2 + k + 0.5f) / df_ - 0.5f;
    nq_ = queries_.size();
    // Query buffers from the pool (tens of megabytes at 1024x768: fresh ones cost more in page
    // faults than the queries' arithmetic).
    qacc_ = pooled(nq_ * (C_ + 1), 0.0f);
    qmin_ = pooled(nq_, INFINITY);
    // The queries' guides by channel (planar), so that the distances of a run of queries
    // vectorise across the queries.
    qg_ = pooled_uninitialised(nq_ * D_);
    tbb::parallel_for(std::size_t(0), nq_, [&](std::size_t q) {
      for (int c = 0; c < D_; ++c) qg_[std::size_t(c) * nq_ + q] = queries_[q].guide[c];
    });
    for (std::size_t q = 0; q < queries_.size(); ++q) {
      if (q == 0 || queries_[q].x != queries_[q - 1].x || queries_[q].y != queries_[q - 1].y) qrun_.push_back(q);
    }
    qrun_.push_back(queries_.size());
    // Runs by image row (any query order works), for the slice pass that walks rows.
    row_runs_.assign(std::size_t(H_) + 1, 0);
    for (std::size_t k = 0; k + 1 < qrun_.size(); ++k) ++row_runs_[std::size_t(queries_[qrun_[k]].y) + 1];
    for (int y = 0; y < H_; ++y) row_runs_[std::size_t(y) + 1] += row_runs_[std::size_t(y)];
    runs_by_row_.resize(qrun_.size() - 1);
    {
      std::vector<std::size_t> fill(row_runs_.begin(), row_runs_.end() - 1);
      for (std::size_t k = 0; k + 1 < qrun_.size(); ++k) runs_by_row_[fill[std::size_t(queries_[qrun_[k]].y)]++] = k;
    }
  }

  ~AmRun() {
    BufferPool::get().give(std::move(min_d2_));
    for (auto* v : {&qacc_, &qmin_, &qg_}) BufferPool::get().give(std::move(*v));
  }
  AmRun(const AmRun&) = delete;
  AmRun& operator=(const AmRun&) = delete;

  Image run(std::vector<float>* query_out) {
    tree();
    eta_full_ = Planes();

    Image out(W_, H_, C_);
    const float alpha_k = float(-0.5 * s_.outlier_scale / (s_.sigma_r * s_.sigma_r));
    tbb::parallel_for(0, H_, [&](int y) {
      for (int x = 0; x < W_; ++x) {
        const std::size_t i = std::size_t(y) * W_ + x;
        const float den = acc_.row(C_, y)[x];
        const float alpha = s_.adjust_outliers ? std::exp(alpha_k * min_d2_[i]) : 1.0f;
        float* o = out.pixel(x, y);
        for (int c = 0; c < C_; ++c) {
          const float f = src_.row(c, y)[x];
          // No manifold reached this pixel (all weights underflowed): it is its own estimate.
          const float g = den > kAmMinWeight ? acc_.row(c, y)[x] / den : f;
          o[c] = f + alpha * (g - f);
        }
      }
    });
    if (query_out) {
      query_out->assign(queries_.size() * C_, 0.0f);
      for (std::size_t q = 0; q < queries_.size(); ++q) {
        const float den = qacc_[std::size_t(C_) * nq_ + q];
        const float alpha = queries_[q].adjust_outliers ? std::exp(alpha_k * qmin_[q]) : 1.0f;
        for (int c = 0; c < C_; ++c) {
          const float f = queries_[q].src ? queries_[q].src[c]
                                           : src_.row(c, queries_[q].y)[queries_[q].x];
          const float g = den > kAmMinWeight ? qacc_[std::size_t(c) * nq_ + q] / den : f;
          (*query_out)[q * C_ + c] = f + alpha * (g - f);
        }
      }
    }
    return out;
  }

 private:
  struct Scratch {
    std::vector<float> eta, x, d2, w, tmp, blur;
    std::vector<float> qeta, qarg, qw;  // one pixel's manifold value and its queries' weights
    std::vector<float> qrow;            // a reduced eta row blended vertically (D x sw)
    std::vector<float> colsum;  // per-column sums over the rows of one reduced-grid row
    std::vector<float> cov;     // lane-split covariance sums (kLanes per entry)
  };

  // Fills rows [0, D) of `eta` (D x W) with manifold eta at full-resolution row y.
  void eta_row(const Planes* eta_full, const Planes& eta_small, int y, float* eta, float* tmp) const {
    if (eta_full) {
      for (int c = 0; c < D_; ++c) std::memcpy(eta + std::size_t(c) * W_, eta_full->row(c, y), sizeof(float) * W_);
      return;
    }
    upsample_rows(eta_small, 0, D_, y, eta, tmp);
  }

  // The vertical half of bilinear upsampling: plane c's two reduced rows around full row y,
  // blended into one reduced row (sw floats).
  void blend_rows(const Planes& p, int c, int y, float* out) const {
    const float* r0 = p.row(c, y0_[y]);
    const float* r1 = p.row(c, y1_[y]);
    const float fy = fy_[y];
    for (int x = 0; x < sw_; ++x) out[x] = r0[x] + fy * (r1[x] - r0[x]);
  }

  void upsample_rows(const Planes& p, int first, int count, int y, float* out, float* tmp) const {
    for (int c = 0; c < count; ++c) {
      blend_rows(p, first + c, y, tmp);
      float* o = out + std::size_t(c) * W_;
      upsample_x(tmp, o);
    }
  }

  // Calls f with std::integral_constant<int, W> for the W among Widths equal to df, else with
  // the constant 0 (the loop then reads df_): the block width as a compile-time constant, so
  // that the loops over a block unroll into vector code.
  template <int... Widths, typename F>
  static void with_block_width(int df, F&& f) {
    const bool done = ((df == Widths ? (f(std::integral_constant<int, Widths>{}), true) : false) || ...);
    if (!done) f(std::integral_constant<int, 0>{});
  }

  // Horizontal bilinear upsampling of one reduced row. Inside the image, output pixel
  // df sx + df/2 + k lies between reduced pixels sx and sx + 1 at fraction
  // (df/2 + k + 0.5) / df - 0.5 for every sx ((k + 0.5) / df for even df, 0 for df = 1), so the interior needs no index tables (and vectorises); the borders use them.
  void upsample_x(const float* tmp, float* o) const {
    with_block_width<2, 4, 8, 16>(df_, [&](auto df) { upsample_x<decltype(df)::value>(tmp, o); });
  }
  template <int DF>
  void upsample_x(const float* tmp, float* o) const {
    const int df = DF > 0 ? DF : df_;
    const int lead = std::min(W_, df / 2);
    for (int x = 0; x < lead; ++x) o[x] = tmp[x0_[x]] + fx_[x] * (tmp[x1_[x]] - tmp[x0_[x]]);
    int x = lead;
    float frac[DF > 0 ? DF : 1];
    if constexpr (DF > 0)
      for (int k = 0; k < DF; ++k) frac[k] = (DF / 2 + k + 0.5f) / DF - 0.5f;
    const int n = std::min(sw_ - 1, (W_ - lead) / df);
    for (int sx = 0; sx < n; ++sx, x += df) {
      const float a = tmp[sx], b = tmp[sx + 1] - tmp[sx];
      if constexpr (DF > 0) {
        for (int k = 0; k < DF; ++k) o[x + k] = a + frac[k] * b;
      } else {
        for (int k = 0; k < df; ++k) o[x + k] = a + frac_[k] * b;
      }
    }
    for (; x < W_; ++x) o[x] = tmp[x0_[x]] + fx_[x] * (tmp[x1_[x]] - tmp[x0_[x]]);
  }

  // Adds the df-wide blocks of `col` (W floats) to the reduced row `out`, scaled by inv_rows.
  void reduce_columns(const float* col, float* out, float inv_rows) const {
    with_block_width<1, 2, 4, 8>(df_, [&](auto df) { reduce_columns<decltype(df)::value>(col, out, inv_rows); });
  }
  template <int DF>
  void reduce_columns(const float* col, float* out, float inv_rows) const {
    const int df = DF > 0 ? DF : df_;
    const int full = W_ / df;  // blocks of df columns; a partial one may follow
    const float scale = inv_rows / float(df);
    for (int sx = 0; sx < full; ++sx) {
      float s = 0;
      for (int k = 0; k < df; ++k) s += col[sx * df + k];
      out[sx] = s * scale;
    }
    if (full < sw_) {
      float s = 0;
      for (int x = full * df; x < W_; ++x) s += col[x];
      out[full] = s * inv_rows / float(W_ - full * df);
    }
  }

  // One manifold: splat, blur, slice, and (above the leaves) split into two children.
  // One manifold of the tree: its id (children 2 id and 2 id + 1), its eta on the reduced grid
  // (the root's also at full resolution), and what its level's passes make of it.
  struct Node {
    int id = 1;
    const Planes* eta_full = nullptr;
    Planes eta_small;
    Planes splat;                  // C + 1 planes on the reduced grid: the splat, then blurred
    std::vector<double> cov_rows;  // per reduced row, the D x D covariance sums (split levels)
    std::vector<float> v;          // the split direction
    Planes veta;                   // v . eta on the reduced grid (split levels below the root)
    std::vector<float> w;          // every pixel's weight for this manifold, full resolution
    Interleaved kids[2];           // the children's (1 - w)-weighted guide splats and weights
  };
  // Manifolds of one level processed together: the full-resolution passes are bound by
  // reading the guide, the source and the accumulators from memory, so each pass reads them
  // once for up to kGroup manifolds instead of once per manifold (15 manifolds: 4 reads of the
  // guide per pass instead of 15). The group's weights are kept at full resolution meanwhile.
  static constexpr int kGroup = 8;

  // Builds and slices the whole tree, level by level (the same manifolds as their recursive
  // algorithm 1; only the order in which slices are summed differs).
  void tree() {
    std::vector<Node> nodes(1);
    nodes[0].eta_full = &eta_full_;
    for (int level = 1; !nodes.empty(); ++level) {
      std::vector<Node> next;
      for (std::size_t first = 0; first < nodes.size(); first += kGroup) {
        const std::size_t last = std::min(nodes.size(), first + kGroup);
        group(nodes.data() + first, int(last - first), level, next);
      }
      nodes = std::move(next);
    }
  }

  // The scratch of this thread with column sums and covariance lanes for m manifolds. Only
  // ever grown: resizing down and up again would zero them on every call (the passes clear
  // what they use).
  Scratch& scratch(int m) {
    Scratch& s = scratch_.local();
    s.eta.resize(std::size_t(D_) * W_);
    s.x.resize(std::size_t(D_) * W_);
    s.d2.resize(W_);
    s.w.resize(W_);
    s.tmp.resize(sw_);
    s.blur.resize(std::size_t(C_ + 1) * W_);
    s.qeta.resize(std::size_t(D_));
    const std::size_t cols = std::size_t(m) * std::max(C_ + 1, 2 * (D_ + 1)) * W_;
    const std::size_t lanes = std::size_t(m) * D_ * D_ * kLanes;
    if (s.colsum.size() < cols) s.colsum.resize(cols);
    if (s.cov.size() < lanes) s.cov.resize(lanes);
    return s;
  }

  // Splat, blur, slice and (above the leaves) split the m manifolds nodes[0 .. m); their
  // children go to `next`.
  void group(Node* nodes, int m, int level, std::vector<Node>& next) {
    const bool split = level < height_;
    const int DD = D_ * D_;
    for (int k = 0; k < m; ++k) {
      nodes[k].splat = Planes(sw_, sh_, C_ + 1, Planes::Overwritten{});  // every reduced row by pass 1
      nodes[k].cov_rows.assign(split ? std::size_t(sh_) * DD : 0, 0.0);
      nodes[k].w = BufferPool::get().take(std::size_t(W_) * H_);
      nodes[k].w.resize(std::size_t(W_) * H_);
    }
    const std::size_t splat_cols = std::size_t(C_ + 1) * W_;

    // Pass 1 (full resolution): distance to each manifold, weight, splat, covariance. One task
    // per reduced-grid row: its df full rows are summed per column first (vectorised), then
    // per block.
    tbb::parallel_for(0, sh_, [&](int sy) {
      Scratch& sc = scratch(m);
      const int ya = sy * df_, yb = std::min(H_, ya + df_);
      std::fill(sc.colsum.begin(), sc.colsum.begin() + std::ptrdiff_t(m * splat_cols), 0.0f);
      if (split) std::fill(sc.cov.begin(), sc.cov.begin() + std::ptrdiff_t(std::size_t(m) * DD * kLanes), 0.0f);
      for (int y = ya; y < yb; ++y) {
        const std::int32_t* lab = label_.data() + std::size_t(y) * W_;
        for (int k = 0; k < m; ++k) {
          const Node& n = nodes[k];
          float* col = sc.colsum.data() + std::size_t(k) * splat_cols;
          eta_row(n.eta_full, n.eta_small, y, sc.eta.data(), sc.tmp.data());
          std::fill(sc.d2.begin(), sc.d2.end(), 0.0f);
          for (int c = 0; c < D_; ++c) {
            const float* g = guide_.row(c, y);
            const float* e = sc.eta.data() + std::size_t(c) * W_;
            float* X = sc.x.data() + std::size_t(c) * W_;
            float* d2 = sc.d2.data();
            for (int x = 0; x < W_; ++x) {
              X[x] = g[x] - e[x];
              d2[x] += X[x] * X[x];
            }
          }
          float* wrow = nodes[k].w.data() + std::size_t(y) * W_;
          for (int x = 0; x < W_; ++x) sc.w[x] = -sc.d2[x] * inv_sr2_;
          cv::hal::exp32f(sc.w.data(), wrow, W_);
          if (s_.adjust_outliers) {
            float* md = min_d2_.data() + std::size_t(y) * W_;
            for (int x = 0; x < W_; ++x) md[x] = std::min(md[x], sc.d2[x]);
          }
          for (int c = 0; c < C_; ++c) {
            float* o = col + std::size_t(c) * W_;
            const float* f = src_.row(c, y);
            for (int x = 0; x < W_; ++x) o[x] += wrow[x] * f[x];
          }
          float* o = col + std::size_t(C_) * W_;
          for (int x = 0; x < W_; ++x) o[x] += wrow[x];
          if (!split) continue;
          // Uncentred covariance of (g - eta) over the node's cluster: X is relative to the
          // manifold, itself the cluster's weighted mean (their algorithm 1, step 2). Pixels
          // outside the cluster get X = 0.
          for (int c = 0; c < D_; ++c) {
            float* X = sc.x.data() + std::size_t(c) * W_;
            for (int x = 0; x < W_; ++x) X[x] = lab[x] == n.id ? X[x] : 0.0f;
          }
          const int body = W_ / kLanes * kLanes;
          float* cov = sc.cov.data() + std::size_t(k) * DD * kLanes;
          for (int i = 0; i < D_; ++i) {
            const float* Xi = sc.x.data() + std::size_t(i) * W_;
            for (int j = i; j < D_; ++j) {
              const float* Xj = sc.x.data() + std::size_t(j) * W_;
              // A local accumulator: through `lanes` the compiler must assume aliasing with
              // Xi and Xj and would store all 16 lanes every step (a third of this pass).
              float acc[kLanes] = {};
              for (int x = 0; x < body; x += kLanes)
                for (int l = 0; l < kLanes; ++l) acc[l] += Xi[x + l] * Xj[x + l];
              for (int x = body; x < W_; ++x) acc[x - body] += Xi[x] * Xj[x];
              float* lanes = cov + std::size_t(i * D_ + j) * kLanes;
              for (int l = 0; l < kLanes; ++l) lanes[l] += acc[l];
            }
          }
        }
      }
      const float inv_rows = 1.0f / float(yb - ya);
      for (int k = 0; k < m; ++k) {
        const float* col = sc.colsum.data() + std::size_t(k) * splat_cols;
        for (int c = 0; c <= C_; ++c) reduce_columns(col + std::size_t(c) * W_, nodes[k].splat.row(c, sy), inv_rows);
        if (!split) continue;
        const float* cov = sc.cov.data() + std::size_t(k) * DD * kLanes;
        for (int e = 0; e < DD; ++e) {
          double t = 0;
          for (int l = 0; l < kLanes; ++l) t += cov[std::size_t(e) * kLanes + l];
          nodes[k].cov_rows[std::size_t(sy) * DD + e] = t;
        }
      }
    });

    for (int k = 0; k < m; ++k) {
      Node& n = nodes[k];
      if (n.eta_full) n.eta_small = downsample(*n.eta_full, D_);
      // Blur along the manifold: domain-transform recursive filter at the reduced resolution.
      blur(n.splat, n.eta_small);
      if (!split) continue;
      // The split direction: leading eigenvector of the cluster's covariance (power iteration).
      std::vector<double> cov(DD, 0.0);
      for (int sy = 0; sy < sh_; ++sy)
        for (int e = 0; e < DD; ++e) cov[e] += n.cov_rows[std::size_t(sy) * DD + e];
      for (int i = 0; i < D_; ++i)
        for (int j = 0; j < i; ++j) cov[i * D_ + j] = cov[j * D_ + i];
      n.v = am_detail::split_direction(cov, D_, seed_, n.id, s_.pca_iterations);
      if (!n.eta_full) {
        n.veta = Planes(sw_, sh_, 1, Planes::Overwritten{});
        tbb::parallel_for(0, sh_, [&](int sy) {
          float* o = n.veta.row(0, sy);
          std::fill(o, o + sw_, 0.0f);
          for (int c = 0; c < D_; ++c) {
            const float* e = n.eta_small.row(c, sy);
            const float vc = n.v[c];
            for (int x = 0; x < sw_; ++x) o[x] += vc * e[x];
          }
        });
      }
      n.kids[0] = Interleaved(sw_, sh_, D_ + 1);  // every reduced row by pass 2
      n.kids[1] = Interleaved(sw_, sh_, D_ + 1);
    }

    // Pass 2 (full resolution): slice; above the leaves also split each cluster and splat the
    // children's (1 - w)-weighted guide (their eqs. 7-8).
    const std::size_t kid_cols = std::size_t(2 * (D_ + 1)) * W_;  // left child, then right
    tbb::parallel_for(0, sh_, [&](int sy) {
      Scratch& sc = scratch(m);
      const int ya = sy * df_, yb = std::min(H_, ya + df_);
      if (split) std::fill(sc.colsum.begin(), sc.colsum.begin() + std::ptrdiff_t(m * kid_cols), 0.0f);
      for (int y = ya; y < yb; ++y) {
        std::int32_t* lab = label_.data() + std::size_t(y) * W_;
        for (int k = 0; k < m; ++k) {
          const Node& n = nodes[k];
          upsample_rows(n.splat, 0, C_ + 1, y, sc.blur.data(), sc.tmp.data());
          const float* wrow = n.w.data() + std::size_t(y) * W_;
          for (int c = 0; c <= C_; ++c) {
            float* a = acc_.row(c, y);
            const float* b = sc.blur.data() + std::size_t(c) * W_;
            for (int x = 0; x < W_; ++x) a[x] += wrow[x] * b[x];
          }
          if (!split) {
            answer_queries(n, y, nullptr, sc.blur.data(), sc);
            continue;
          }
          float* dot = sc.d2.data();
          if (n.eta_full) {
            eta_row(n.eta_full, n.eta_small, y, sc.eta.data(), sc.tmp.data());
            answer_queries(n, y, sc.eta.data(), sc.blur.data(), sc);
            std::fill(sc.d2.begin(), sc.d2.end(), 0.0f);
            for (int c = 0; c < D_; ++c) {
              const float* g = guide_.row(c, y);
              const float* e = sc.eta.data() + std::size_t(c) * W_;
              const float vc = n.v[c];
              for (int x = 0; x < W_; ++x) dot[x] += vc * (g[x] - e[x]);
            }
          } else {
            // v . (g - eta) = v . g - v . eta, and v . eta is linear in eta, so it is
            // upsampled as one plane (n.veta) instead of upsampling the D planes of eta.
            answer_queries(n, y, nullptr, sc.blur.data(), sc);
            upsample_rows(n.veta, 0, 1, y, dot, sc.tmp.data());
            for (int x = 0; x < W_; ++x) dot[x] = -dot[x];
            for (int c = 0; c < D_; ++c) {
              const float* g = guide_.row(c, y);
              const float vc = n.v[c];
              for (int x = 0; x < W_; ++x) dot[x] += vc * g[x];
            }
          }
          float* tl = sc.w.data();  // (1 - w) for pixels going left, else 0
          float* tr = sc.x.data();  // the same for pixels going right
          const std::int32_t id = n.id, left = 2 * id, right = 2 * id + 1;
          // Branch-free, one element width (32-bit labels) and restrict-qualified: written with
          // plain pointers GCC had to assume tl, tr or lab alias dot and wrow, and compiled a
          // scalar loop with two data-dependent branches per pixel (a quarter of this pass).
          // The children's ids belong to the next level, so no other node of this group sees them.
          split_row(lab, dot, wrow, tl, tr, id, left, right);
          float* col = sc.colsum.data() + std::size_t(k) * kid_cols;
          for (int c = 0; c <= D_; ++c) {
            float* ol = col + std::size_t(c) * W_;
            float* orr = col + std::size_t(D_ + 1 + c) * W_;
            if (c < D_) {
              const float* g = guide_.row(c, y);
              for (int x = 0; x < W_; ++x) {
                ol[x] += tl[x] * g[x];
                orr[x] += tr[x] * g[x];
              }
            } else {
              for (int x = 0; x < W_; ++x) {
                ol[x] += tl[x];
                orr[x] += tr[x];
              }
            }
          }
        }
      }
      if (!split) return;
      const float inv_rows = 1.0f / float(yb - ya);
      for (int k = 0; k < m; ++k) {
        const float* col = sc.colsum.data() + std::size_t(k) * kid_cols;
        for (int side = 0; side < 2; ++side) {
          Interleaved& kid = nodes[k].kids[side];
          float* out = kid.row(sy);
          for (int c = 0; c <= D_; ++c) {
            reduce_columns(col + std::size_t(side * (D_ + 1) + c) * W_, sc.tmp.data(), inv_rows);
            for (int sx = 0; sx < sw_; ++sx) out[std::size_t(sx) * kid.dp + c] = sc.tmp[std::size_t(sx)];
          }
          for (int sx = 0; sx < sw_; ++sx)
            for (int c = D_ + 1; c < kid.dp; ++c) out[std::size_t(sx) * kid.dp + c] = 0.0f;
        }
      }
    });

    for (int k = 0; k < m; ++k) {
      Node& n = nodes[k];
      BufferPool::get().give(std::move(n.w));
      n.splat = Planes();
      if (!split) continue;
      for (int c2 = 0; c2 < 2; ++c2) {
        Interleaved& p = n.kids[c2];
        low_pass(p, s_.sigma_s / df_);
        Node child;
        child.id = 2 * n.id + c2;
        child.eta_small = Planes(sw_, sh_, D_, Planes::Overwritten{});
        tbb::parallel_for(0, sh_, [&](int sy) {
          const float* px = p.row(sy);
          const int dp = p.dp;
          for (int c = 0; c < D_; ++c) {
            const float* parent = n.eta_small.row(c, sy);
            float* e = child.eta_small.row(c, sy);
            // Where the child's cluster left no weight, it keeps its parent's manifold.
            for (int i = 0; i < sw_; ++i) {
              const float num = px[std::size_t(i) * dp + c], dn = px[std::size_t(i) * dp + D_];
              e[i] = dn > 1e-20f ? num / dn : parent[i];
            }
          }
        });
        p = Interleaved();
        next.push_back(std::move(child));
      }
      n.eta_small = Planes();
      n.veta = Planes();
    }
  }

  // One row of a cluster split: pixels of cluster `id` go left (dot < 0) or right; tl and tr
  // get their (1 - w) on their side and 0 elsewhere; lab is relabelled.
  void split_row(std::int32_t* __restrict lab, const float* __restrict dot, const float* __restrict wrow,
                 float* __restrict tl, float* __restrict tr, std::int32_t id, std::int32_t left,
                 std::int32_t right) const {
    for (int x = 0; x < W_; ++x) {
      const std::int32_t l = lab[x];
      const bool mine = l == id;
      const bool go_left = dot[x] < 0.0f;
      const float theta = mine ? 1.0f - wrow[x] : 0.0f;
      tl[x] = go_left ? theta : 0.0f;
      tr[x] = go_left ? 0.0f : theta;
      lab[x] = mine ? (go_left ? left : right) : l;
    }
  }

  // Point queries: the same slice with the query's guide value, answered in the slice pass
  // for the queries of row y: the splat there is `blur` (the upsampled row the pixels get), the
  // manifold `eta` (its full-resolution row, or null: sampled from the reduced grid). Each
  // query keeps its own sums, added manifold by manifold in tree order, so the thread count does
  // not change them. Consecutive queries at one pixel (an edge pixel's 16 sub-pixels) share
  // the manifold's value there; only the guide distance is per query.
  void answer_queries(const Node& n, int y, const float* eta, const float* blur, Scratch& sc) {
    const std::size_t r0 = row_runs_[std::size_t(y)], r1 = row_runs_[std::size_t(y) + 1];
    if (r0 == r1) return;
    // Without a full-resolution eta row: the reduced grid's two rows, blended vertically once
    // per row (read in order), then sampled horizontally per run (random reads of the grid at
    // every run were cache misses: 14 per run and manifold).
    const float* vrow = nullptr;
    if (!eta && !n.eta_full) {
      sc.qrow.resize(std::size_t(D_) * sw_);
      for (int c = 0; c < D_; ++c) blend_rows(n.eta_small, c, y, sc.qrow.data() + std::size_t(c) * sw_);
      vrow = sc.qrow.data();
    }
    for (std::size_t i = r0; i < r1; ++i) {
      const std::size_t k = runs_by_row_[i];
      const std::size_t first = qrun_[k], end = qrun_[k + 1], len = end - first;
      const int x = queries_[first].x;
      float* e = sc.qeta.data();
      for (int c = 0; c < D_; ++c) {
        if (eta) {
          e[c] = eta[std::size_t(c) * W_ + x];
        } else if (n.eta_full) {
          e[c] = n.eta_full->row(c, y)[x];
        } else {
          const float* v = vrow + std::size_t(c) * sw_;
          e[c] = v[x0_[x]] + fx_[x] * (v[x1_[x]] - v[x0_[x]]);
        }
      }
      sc.qarg.resize(len);
      sc.qw.resize(len);
      float* d2 = sc.qarg.data();
      std::fill(d2, d2 + len, 0.0f);
      for (int c = 0; c < D_; ++c) {
        const float ec = e[c];
        const float* g = qg_.data() + std::size_t(c) * nq_ + first;
        for (std::size_t q = 0; q < len; ++q) d2[q] += (g[q] - ec) * (g[q] - ec);
      }
      float* mn = qmin_.data() + first;
      for (std::size_t q = 0; q < len; ++q) {
        mn[q] = std::min(mn[q], d2[q]);
        d2[q] = -d2[q] * inv_sr2_;  // now the exponent, as the pixels' (pass 1)
      }
      // Weights and sums in float, as the image's pixels get them (exp32f; acc_).
      cv::hal::exp32f(d2, sc.qw.data(), int(len));
      for (int c = 0; c <= C_; ++c) {
        const float b = blur[std::size_t(c) * W_ + x];
        float* acc = qacc_.data() + std::size_t(c) * nq_ + first;
        for (std::size_t q = 0; q < len; ++q) acc[q] += sc.qw[q] * b;
      }
    }
  }

  Planes downsample(const Planes& full, int n) const {
    Planes out(sw_, sh_, n);
    tbb::parallel_for(0, sh_, [&](int sy) {
      const int ya = sy * df_, yb = std::min(H_, ya + df_);
      for (int c = 0; c < n; ++c) {
        float* o = out.row(c, sy);
        for (int y = ya; y < yb; ++y) add_blocks(full.row(c, y), o);
        for (int sx = 0; sx < sw_; ++sx) o[sx] /= float((yb - ya) * (std::min(W_, (sx + 1) * df_) - sx * df_));
      }
    });
    return out;
  }
  // Adds the sums of row r's df-wide blocks to o (a partial block may end the row).
  void add_blocks(const float* r, float* o) const {
    with_block_width<2, 4>(df_, [&](auto df) { add_blocks<decltype(df)::value>(r, o); });
  }
  template <int DF>
  void add_blocks(const float* r, float* o) const {
    const int df = DF > 0 ? DF : df_;
    const int full = W_ / df;
    for (int sx = 0; sx < full; ++sx) {
      float s = 0;
      for (int k = 0; k < df; ++k) s += r[sx * df + k];
      o[sx] += s;
    }
    if (full < sw_) {
      float s = 0;
      for (int x = full * df; x < W_; ++x) s += r[x];
      o[full] += s;
    }
  }

  void blur(Planes& splat, const Planes& eta) const {
    const double ss = s_.sigma_s / df_;
    const double sr = s_.sigma_r / std::sqrt(2.0);
    const float ratio2 = float((ss / sr) * (ss / sr));
    const float ln_a = float(-std::sqrt(2.0) / ss);
    // Edge feedbacks a^(geodesic distance), L2 over the guide channels.
    std::vector<float> ah(std::size_t(sh_) * std::max(sw_ - 1, 1), 0.0f), av(std::size_t(std::max(sh_ - 1, 1)) * sw_, 0.0f);
    tbb::parallel_for(0, sh_, [&](int y) {
      std::vector<float> d(sw_, 0.0f);
      for (int c = 0; c < D_; ++c) {
        const float* e = eta.row(c, y);
        for (int x = 0; x + 1 < sw_; ++x) d[x] += (e[x + 1] - e[x]) * (e[x + 1] - e[x]);
      }
      float* a = ah.data() + std::size_t(y) * std::max(sw_ - 1, 1);
      for (int x = 0; x + 1 < sw_; ++x) a[x] = ln_a * std::sqrt(1.0f + ratio2 * d[x]);
      cv::hal::exp32f(a, a, std::max(sw_ - 1, 0));
      if (y + 1 < sh_) {
        std::fill(d.begin(), d.end(), 0.0f);
        for (int c = 0; c < D_; ++c) {
          const float* e0 = eta.row(c, y);
          const float* e1 = eta.row(c, y + 1);
          for (int x = 0; x < sw_; ++x) d[x] += (e1[x] - e0[x]) * (e1[x] - e0[x]);
        }
        float* b = av.data() + std::size_t(y) * sw_;
        for (int x = 0; x < sw_; ++x) b[x] = ln_a * std::sqrt(1.0f + ratio2 * d[x]);
        cv::hal::exp32f(b, b, sw_);
      }
    });
    const int hstride = std::max(sw_ - 1, 1);
    recursive_filter(
        splat, 0, C_ + 1, [&](int y) { return ah.data() + std::size_t(y) * hstride; },
        [&](int y) { return av.data() + std::size_t(y) * sw_; });
  }

  AmSettings s_;
  int W_, H_, C_, D_;
  const std::vector<AmQuery>& queries_;
  int height_ = 2, df_ = 1, sw_ = 1, sh_ = 1;
  float inv_sr2_ = 1;
  std::uint64_t seed_ = 0;
  Planes guide_, src_, acc_, eta_full_;  // eta_full_: the first manifold, full resolution
  std::vector<float> min_d2_;
  std::vector<std::int32_t> label_;
  std::vector<int> x0_, x1_, y0_, y1_;
  std::vector<float> fx_, fy_, frac_;
  std::size_t nq_ = 0;
  std::vector<float> qacc_;  // planar: channel c of query q at c * nq_ + q (C sums, then the weight)
  std::vector<float> qg_;     // planar: the queries' guides
  std::vector<float> qmin_;
  std::vector<std::size_t> qrun_;  // first query of each run of queries at one pixel, then the count
  std::vector<std::size_t> row_runs_, runs_by_row_;  // runs_by_row_[row_runs_[y] ..) are row y's
  tbb::enumerable_thread_specific<Scratch> scratch_;
};

}  // namespace

namespace am_detail {

std::uint64_t guide_seed(ConstImageView guide) { return hash_guide(guide); }

std::vector<float> split_direction(const std::vector<double>& cov, int D, std::uint64_t seed, int id, int iterations) {
  std::mt19937_64 rng(seed ^ (0x9E3779B97F4A7C15ull * std::uint64_t(id)));
  std::uniform_real_distribution<double> uni(-0.5, 0.5);
  std::vector<double> vd(D), u(D);
  for (auto& e : vd) e = uni(rng);
  for (int it = 0; it < std::max(1, iterations); ++it) {
    double n = 0;
    for (int i = 0; i < D; ++i) {
      u[i] = 0;
      for (int j = 0; j < D; ++j) u[i] += cov[i * D + j] * vd[j];
      n += u[i] * u[i];
    }
    if (!(n > 1e-300)) break;  // the cluster is flat: any direction splits it
    n = std::sqrt(n);
    for (int i = 0; i < D; ++i) vd[i] = u[i] / n;
  }
  std::vector<float> v(D);
  for (int i = 0; i < D; ++i) v[i] = float(vd[i]);
  return v;
}

}  // namespace am_detail

Image am_filter(ConstImageView src, ConstImageView guide, const AmSettings& settings,
                const std::vector<AmQuery>& queries, std::vector<float>* query_out) {
  if (src.empty()) return Image(src.width, src.height, src.channels);
  AmRun run(src, guide, settings, queries);
  return run.run(query_out);
}

}  // namespace dnb
