// The adaptive-manifold core's public functions and one run's set-up, queries and output (see
// adaptive_manifold.h for the algorithm and its choices, am/run.h for how a run is laid out,
// am/tree.cpp for the tree's passes).
//
// Why hand-written and not OpenCV's ximgproc::AdaptiveManifoldFilter: OpenCV's version cannot
// answer slice queries with another guide value (paper 3.1 needs that for edge sub-pixels), its
// power iteration restarts from the random vector every step, and it is about 3x slower here
// (bench/am_bench.cpp): it splits every image into planes with a separate full-resolution pass
// per operation, where this core fuses them (am/run.h).
#include "denoisers/am/adaptive_manifold.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <random>

#include <fmt/format.h>
#include <opencv2/core/hal/hal.hpp>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "core/errors.h"
#include "denoisers/am/capture.h"
#include "denoisers/am/run.h"
#include "denoisers/am/transpose8.h"

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
  // Group by group along each row (a group's scale and channel count fixed for the row's loop).
  tbb::parallel_for(0, h, [&](int y) {
    float* const row = out.pixel(0, y);
    int off = 0;
    for (const auto& g : groups) {
      const float s = sigma_r / g.sigma;
      const float* p = g.image.pixel(0, y);
      const int n = g.image.channels;
      float* o = row + off;
      for (int x = 0; x < w; ++x)
        for (int c = 0; c < n; ++c) o[std::size_t(x) * d + c] = s * p[std::size_t(x) * n + c];
      off += n;
    }
  });
  return out;
}

namespace am_detail {

std::uint64_t guide_seed(ConstImageView g) {
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

AmRunShape::AmRunShape(int width, int height, int src_channels, int guide_channels, std::uint64_t seed, const AmSettings& s,
                       const std::vector<AmQuery>& queries)
    : s_(s), W_(width), H_(height), C_(src_channels), D_(guide_channels), queries_(queries) {
  height_ = std::min(s.tree_height > 0 ? s.tree_height : am_tree_height(s.sigma_s, s.sigma_r), 12);
  df_ = s.downsample > 0 ? s.downsample : am_downsample_factor(s.sigma_s, s.sigma_r);
  sw_ = (W_ + df_ - 1) / df_;
  sh_ = (H_ + df_ - 1) / df_;
  inv_sr2_ = float(1.0 / (s.sigma_r * s.sigma_r));
  seed_ = seed;
}

AmRunShape::AmRunShape(ConstImageView src, ConstImageView guide, const AmSettings& s, const std::vector<AmQuery>& queries)
    : AmRunShape(src.width, src.height, src.channels, guide.channels, guide_seed(guide), s, queries) {
  // Both paths index their buffers by the queries' pixels.
  for (std::size_t q = 0; q < queries.size(); ++q)
    if (queries[q].x < 0 || queries[q].x >= W_ || queries[q].y < 0 || queries[q].y >= H_)
      throw WorkError(fmt::format("adaptive-manifold filter: slice query {} at pixel ({}, {}) lies outside the {}x{} image", q,
                                  queries[q].x, queries[q].y, W_, H_));
}

AmRun::AmRun(ConstImageView src, ConstImageView guide, const AmSettings& s, const std::vector<AmQuery>& queries)
    : AmRunShape(src, guide, s, queries), grid_(W_, H_, df_) {
  copy_and_low_pass_guide(src, guide);
  acc_ = Planes(W_, H_, C_ + 1);
  label_.assign(std::size_t(W_) * H_, 1);
  if (s.adjust_outliers) min_d2_ = pooled(std::size_t(W_) * H_, INFINITY);
  index_queries();
}

// Planar copies of the guide and the source, and the first manifold: the guide low-passed at
// full resolution. One pass over the interleaved input makes the copies and runs the
// horizontal low-pass on the interleaved rows (recursive_interleaved), in pairs of rows; then
// the vertical half.
void AmRun::copy_and_low_pass_guide(ConstImageView src, ConstImageView guide) {
  // Every element of the three is written below.
  guide_ = Planes(W_, H_, D_, Planes::Overwritten{});
  src_ = Planes(W_, H_, C_, Planes::Overwritten{});
  eta_full_ = Planes(W_, H_, D_, Planes::Overwritten{});
  const int nb = (D_ + 7) / 8, dp = 8 * nb;
  const std::vector<float> a_first = domain_transform::low_pass_weights(W_, s_.sigma_s);
  tbb::parallel_for(tbb::blocked_range<int>(0, (H_ + 1) / 2), [&](const tbb::blocked_range<int>& range) {
    std::vector<float> buf(std::size_t(2) * W_ * dp);
    std::vector<float*> gp(static_cast<std::size_t>(D_)), sp(static_cast<std::size_t>(C_));
    float* rows[2] = {buf.data(), buf.data() + std::size_t(W_) * dp};
    for (int t = range.begin(); t != range.end(); ++t) {
      const int y0 = 2 * t, n = std::min(2, H_ - y0);
      // The layout moves by 8 x 8 transposes (transpose8.h): the input's pixels to the planar
      // copies, the guide's planes to the interleaved rows, and those back to eta's planes.
      for (int r = 0; r < n; ++r) {
        const int y = y0 + r;
        for (int c = 0; c < D_; ++c) gp[std::size_t(c)] = guide_.row(c, y);
        for (int c = 0; c < C_; ++c) sp[std::size_t(c)] = src_.row(c, y);
        from_interleaved(guide.pixel(0, y), D_, W_, gp.data(), D_);
        from_interleaved(src.pixel(0, y), C_, W_, sp.data(), C_);
        to_interleaved(gp.data(), D_, W_, rows[r], dp);
      }
      const float* a[2] = {a_first.data(), a_first.data()};
      domain_transform::recursive_interleaved(rows, a, W_, nb, n);
      for (int r = 0; r < n; ++r) {
        for (int c = 0; c < D_; ++c) gp[std::size_t(c)] = eta_full_.row(c, y0 + r);
        from_interleaved(rows[r], dp, W_, gp.data(), D_);
      }
    }
  });
  domain_transform::recursive_filter_vertical(eta_full_, 0, D_, [&](int) { return a_first.data(); });
}

// The queries' buffers and indices: sums, nearest distances and guides by channel (planar, so
// that the distances of a run of queries vectorise across the queries), runs of consecutive
// queries at one pixel, and the runs by image row (any query order works), for the slice pass
// that walks rows. The buffers come from the pool (tens of megabytes at 1024x768: fresh ones
// cost more in page faults than the queries' arithmetic).
void AmRun::index_queries() {
  nq_ = queries_.size();
  qacc_ = pooled(nq_ * (C_ + 1), 0.0f);
  qmin_ = pooled(nq_, INFINITY);
  qg_ = pooled_uninitialised(nq_ * D_);
  tbb::parallel_for(std::size_t(0), nq_, [&](std::size_t q) {
    for (int c = 0; c < D_; ++c) qg_[std::size_t(c) * nq_ + q] = queries_[q].guide[c];
  });
  for (std::size_t q = 0; q < queries_.size(); ++q) {
    if (q == 0 || queries_[q].x != queries_[q - 1].x || queries_[q].y != queries_[q - 1].y) qrun_.push_back(q);
  }
  qrun_.push_back(queries_.size());
  row_runs_.assign(std::size_t(H_) + 1, 0);
  for (std::size_t k = 0; k + 1 < qrun_.size(); ++k) ++row_runs_[std::size_t(queries_[qrun_[k]].y) + 1];
  for (int y = 0; y < H_; ++y) row_runs_[std::size_t(y) + 1] += row_runs_[std::size_t(y)];
  runs_by_row_.resize(qrun_.size() - 1);
  std::vector<std::size_t> fill(row_runs_.begin(), row_runs_.end() - 1);
  for (std::size_t k = 0; k + 1 < qrun_.size(); ++k) runs_by_row_[fill[std::size_t(queries_[qrun_[k]].y)]++] = k;
}

AmRun::~AmRun() {
  BufferPool::get().give(std::move(min_d2_));
  for (auto* v : {&qacc_, &qmin_, &qg_}) BufferPool::get().give(std::move(*v));
}

Image AmRun::run(std::vector<float>* query_out) {
  tree();
  eta_full_ = Planes();
  Image out = normalised_output();
  if (query_out) {
    const float alpha_k = float(-0.5 * s_.outlier_scale / (s_.sigma_r * s_.sigma_r));
    query_out->assign(queries_.size() * C_, 0.0f);
    for (std::size_t q = 0; q < queries_.size(); ++q) {
      const float den = qacc_[std::size_t(C_) * nq_ + q];
      const float alpha = queries_[q].adjust_outliers ? std::exp(alpha_k * qmin_[q]) : 1.0f;
      for (int c = 0; c < C_; ++c) {
        const float f = queries_[q].src ? queries_[q].src[c] : src_.row(c, queries_[q].y)[queries_[q].x];
        const float g = den > kAmMinWeight ? qacc_[std::size_t(c) * nq_ + q] / den : f;
        (*query_out)[q * C_ + c] = f + alpha * (g - f);
      }
    }
  }
  return out;
}

// sum(w blur) / sum(w blur_0) per pixel, with the outlier adjustment (eq. 11) when asked.
Image AmRun::normalised_output() const {
  Image out(W_, H_, C_);
  const float alpha_k = float(-0.5 * s_.outlier_scale / (s_.sigma_r * s_.sigma_r));
  // Row by row: the adjustment's weights first (libm's exp, one call a pixel), then each channel
  // in a loop of its own, which vectorises.
  tbb::parallel_for(tbb::blocked_range<int>(0, H_), [&](const tbb::blocked_range<int>& range) {
    std::vector<float> alpha(std::size_t(W_), 1.0f);
    for (int y = range.begin(); y != range.end(); ++y) {
      if (s_.adjust_outliers) {
        const float* md = min_d2_.data() + std::size_t(y) * W_;
        for (int x = 0; x < W_; ++x) alpha[std::size_t(x)] = std::exp(alpha_k * md[x]);
      }
      const float* __restrict den = acc_.row(C_, y);
      const float* __restrict al = alpha.data();
      float* __restrict o = out.pixel(0, y);
      for (int c = 0; c < C_; ++c) {
        const float* __restrict f = src_.row(c, y);
        const float* __restrict a = acc_.row(c, y);
        for (int x = 0; x < W_; ++x) {
          // No manifold reached this pixel (all weights underflowed): it is its own estimate.
          const float g = den[x] > kAmMinWeight ? a[x] / den[x] : f[x];
          o[std::size_t(x) * C_ + c] = f[x] + al[x] * (g - f[x]);
        }
      }
    }
  });
  return out;
}

// Point queries: the same slice with the query's guide value, answered in the slice pass
// for the queries of row y: the splat there is `blur` (the upsampled row the pixels get), the
// manifold `eta` (its full-resolution row, or null: sampled from the reduced grid). Each
// query keeps its own sums, added manifold by manifold in tree order, so the thread count does
// not change them. Consecutive queries at one pixel (an edge pixel's 16 sub-pixels) share
// the manifold's value there; only the guide distance is per query.
void AmRun::answer_queries(const Node& n, int y, const float* eta, const float* blur, Scratch& sc) {
  const std::size_t r0 = row_runs_[std::size_t(y)], r1 = row_runs_[std::size_t(y) + 1];
  if (r0 == r1) return;
  // Without a full-resolution eta row: the reduced grid's two rows, blended vertically once
  // per row (read in order), then sampled horizontally per run (random reads of the grid at
  // every run were cache misses: 14 per run and manifold).
  const float* vrow = nullptr;
  if (!eta && !n.eta_full) {
    sc.qrow.resize(std::size_t(D_) * sw_);
    for (int c = 0; c < D_; ++c) grid_.blend_rows(n.eta_small, c, y, sc.qrow.data() + std::size_t(c) * sw_);
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
        e[c] = v[grid_.x0[x]] + grid_.fx[x] * (v[grid_.x1[x]] - v[grid_.x0[x]]);
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

std::vector<double> split_start(int D, std::uint64_t seed, int id) {
  std::mt19937_64 rng(seed ^ (0x9E3779B97F4A7C15ull * std::uint64_t(id)));
  std::uniform_real_distribution<double> uni(-0.5, 0.5);
  std::vector<double> vd(D);
  for (auto& e : vd) e = uni(rng);
  return vd;
}

std::vector<float> split_direction(const std::vector<double>& cov, int D, std::uint64_t seed, int id, int iterations) {
  std::vector<double> vd = split_start(D, seed, id), u(D);
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
  if (guide.width != src.width || guide.height != src.height)
    throw WorkError("am_filter: guide and source differ in size");
  if (!(settings.sigma_s >= 1.0) || !(settings.sigma_r > 0.0))
    throw WorkError("am_filter: needs sigma_s >= 1 and sigma_r > 0");
  am_detail::AmRun run(src, guide, settings, queries);
  am_capture_if_asked(src, guide, settings, queries);
  return run.run(query_out);
}

}  // namespace dnb
