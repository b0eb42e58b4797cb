// The adaptive-manifold tree (adaptive_manifold.h: their algorithm 1 with the recursive tree of
// section 4.2), built level by level; am/run.h says why the full-resolution passes are fused.
// A group of manifolds runs four named passes:
//   1. splat (full resolution, one task per reduced row): each pixel's distance to each manifold,
//      its weight, the weighted source summed into the reduced grid, and above the leaves the
//      cluster's covariance sums;
//   2. blur and orient (reduced grid): the domain-transform blur along each manifold, and the
//      split direction (power iteration on the covariance);
//   3. slice and split (full resolution, one task per reduced row): each pixel gathers its
//      weighted blurred value; above the leaves the cluster is split and the children's
//      (1 - w)-weighted guide summed into the reduced grid;
//   4. children (reduced grid): the children's manifolds, low-passed.
#include <algorithm>
#include <cmath>
#include <cstring>
#include <memory>

#include <opencv2/core/hal/hal.hpp>
#include <tbb/parallel_for.h>

#include "denoisers/am/run.h"
#include "denoisers/am/transpose8.h"

namespace dnb::am_detail {

using domain_transform::Interleaved;

void AmRun::tree() {
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

void AmRun::group(Node* nodes, int m, int level, std::vector<Node>& next) {
  const bool split = level < height_;
  start_group(nodes, m, split);
  tbb::parallel_for(0, sh_, [&](int sy) { splat_block(nodes, m, split, sy); });
  for (int k = 0; k < m; ++k) blur_and_orient(nodes[k], split);
  tbb::parallel_for(0, sh_, [&](int sy) { slice_block(nodes, m, split, sy); });
  for (int k = 0; k < m; ++k) {
    Node& n = nodes[k];
    BufferPool::get().give(std::move(n.w));
    n.splat = Planes();
    if (split) make_children(n, next);
  }
}

void AmRun::start_group(Node* nodes, int m, bool split) {
  for (int k = 0; k < m; ++k) {
    nodes[k].splat = Planes(sw_, sh_, C_ + 1, Planes::Overwritten{});  // every reduced row by pass 1
    nodes[k].cov_rows.assign(split ? std::size_t(sh_) * D_ * D_ : 0, 0.0);
    nodes[k].w = BufferPool::get().take(std::size_t(W_) * H_);
    nodes[k].w.resize(std::size_t(W_) * H_);
  }
}

// The scratch of this thread with column sums and covariance lanes for m manifolds. Only ever
// grown: resizing down and up again would zero them on every call (the passes clear what they use).
AmRun::Scratch& AmRun::scratch(int m) {
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

void AmRun::eta_row(const Planes* eta_full, const Planes& eta_small, int y, float* eta, float* tmp) const {
  if (eta_full) {
    for (int c = 0; c < D_; ++c) std::memcpy(eta + std::size_t(c) * W_, eta_full->row(c, y), sizeof(float) * W_);
    return;
  }
  grid_.upsample_rows(eta_small, 0, D_, y, eta, tmp);
}

// ---- Pass 1: splat. The df full rows of reduced row sy are summed per column first
// (vectorised), then per block.
void AmRun::splat_block(Node* nodes, int m, bool split, int sy) {
  const int DD = D_ * D_;
  const std::size_t splat_cols = std::size_t(C_ + 1) * W_;
  Scratch& sc = scratch(m);
  const int ya = sy * df_, yb = std::min(H_, ya + df_);
  std::fill(sc.colsum.begin(), sc.colsum.begin() + std::ptrdiff_t(m * splat_cols), 0.0f);
  if (split) std::fill(sc.cov.begin(), sc.cov.begin() + std::ptrdiff_t(std::size_t(m) * DD * kLanes), 0.0f);
  for (int y = ya; y < yb; ++y) {
    const std::int32_t* lab = label_.data() + std::size_t(y) * W_;
    for (int k = 0; k < m; ++k) {
      weigh_and_splat_row(nodes[k], y, sc, sc.colsum.data() + std::size_t(k) * splat_cols);
      if (split) add_covariance_row(nodes[k], lab, sc, sc.cov.data() + std::size_t(k) * DD * kLanes);
    }
  }
  const float inv_rows = 1.0f / float(yb - ya);
  for (int k = 0; k < m; ++k) {
    const float* col = sc.colsum.data() + std::size_t(k) * splat_cols;
    for (int c = 0; c <= C_; ++c) grid_.reduce_columns(col + std::size_t(c) * W_, nodes[k].splat.row(c, sy), inv_rows);
    if (!split) continue;
    const float* cov = sc.cov.data() + std::size_t(k) * DD * kLanes;
    for (int e = 0; e < DD; ++e) {
      double t = 0;
      for (int l = 0; l < kLanes; ++l) t += cov[std::size_t(e) * kLanes + l];
      nodes[k].cov_rows[std::size_t(sy) * DD + e] = t;
    }
  }
}

// Row y against manifold n: X = g - eta (into sc.x), d2 = |X|^2, the weight exp(-d2 / sigma_r^2)
// (into n.w), the nearest distance so far, and (w src, w) added to the column sums `col`.
void AmRun::weigh_and_splat_row(Node& n, int y, Scratch& sc, float* col) {
  eta_row(n.eta_full, n.eta_small, y, sc.eta.data(), sc.tmp.data());
  // The first channel sets d2 (X^2 is what 0 + X^2 rounds to, fused or not), the others add.
  for (int c = 0; c < D_; ++c) {
    const float* g = guide_.row(c, y);
    const float* e = sc.eta.data() + std::size_t(c) * W_;
    float* X = sc.x.data() + std::size_t(c) * W_;
    float* d2 = sc.d2.data();
    if (c == 0) {
      for (int x = 0; x < W_; ++x) {
        X[x] = g[x] - e[x];
        d2[x] = X[x] * X[x];
      }
    } else {
      for (int x = 0; x < W_; ++x) {
        X[x] = g[x] - e[x];
        d2[x] += X[x] * X[x];
      }
    }
  }
  float* wrow = n.w.data() + std::size_t(y) * W_;
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
}

// Uncentred covariance of (g - eta) over the node's cluster, added to the lane sums `cov`: X (in
// sc.x, from weigh_and_splat_row) is relative to the manifold, itself the cluster's weighted
// mean (their algorithm 1, step 2). Pixels outside the cluster get X = 0.
void AmRun::add_covariance_row(const Node& n, const std::int32_t* lab, Scratch& sc, float* cov) const {
  for (int c = 0; c < D_; ++c) {
    float* X = sc.x.data() + std::size_t(c) * W_;
    for (int x = 0; x < W_; ++x) X[x] = lab[x] == n.id ? X[x] : 0.0f;
  }
  const int body = W_ / kLanes * kLanes;
  for (int i = 0; i < D_; ++i) {
    const float* Xi = sc.x.data() + std::size_t(i) * W_;
    for (int j = i; j < D_; ++j) {
      const float* Xj = sc.x.data() + std::size_t(j) * W_;
      // A local accumulator: through `lanes` the compiler must assume aliasing with Xi and Xj
      // and would store all 16 lanes every step (a third of this pass).
      float acc[kLanes] = {};
      for (int x = 0; x < body; x += kLanes)
        for (int l = 0; l < kLanes; ++l) acc[l] += Xi[x + l] * Xj[x + l];
      for (int x = body; x < W_; ++x) acc[x - body] += Xi[x] * Xj[x];
      float* lanes = cov + std::size_t(i * D_ + j) * kLanes;
      for (int l = 0; l < kLanes; ++l) lanes[l] += acc[l];
    }
  }
}

// ---- Pass 2: blur along the manifold (domain-transform recursive filter at the reduced
// resolution) and, above the leaves, the split direction: the leading eigenvector of the
// cluster's covariance (power iteration), with v . eta on the reduced grid for pass 3.
void AmRun::blur_and_orient(Node& n, bool split) {
  const int DD = D_ * D_;
  if (n.eta_full) n.eta_small = downsample(*n.eta_full, D_);
  blur(n.splat, n.eta_small);
  if (!split) return;
  std::vector<double> cov(DD, 0.0);
  for (int sy = 0; sy < sh_; ++sy)
    for (int e = 0; e < DD; ++e) cov[e] += n.cov_rows[std::size_t(sy) * DD + e];
  for (int i = 0; i < D_; ++i)
    for (int j = 0; j < i; ++j) cov[i * D_ + j] = cov[j * D_ + i];
  n.v = split_direction(cov, D_, seed_, n.id, s_.pca_iterations);
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
  n.kids[0] = Interleaved(sw_, sh_, D_ + 1);  // every reduced row by pass 3
  n.kids[1] = Interleaved(sw_, sh_, D_ + 1);
}

Planes AmRun::downsample(const Planes& full, int n) const {
  Planes out(sw_, sh_, n);
  tbb::parallel_for(0, sh_, [&](int sy) {
    const int ya = sy * df_, yb = std::min(H_, ya + df_);
    for (int c = 0; c < n; ++c) {
      float* o = out.row(c, sy);
      for (int y = ya; y < yb; ++y) grid_.add_blocks(full.row(c, y), o);
      for (int sx = 0; sx < sw_; ++sx) o[sx] /= float((yb - ya) * (std::min(W_, (sx + 1) * df_) - sx * df_));
    }
  });
  return out;
}

void AmRun::blur(Planes& splat, const Planes& eta) const {
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
  domain_transform::recursive_filter(
      splat, 0, C_ + 1, [&](int y) { return ah.data() + std::size_t(y) * hstride; },
      [&](int y) { return av.data() + std::size_t(y) * sw_; });
}

// ---- Pass 3: slice; above the leaves also split each cluster and splat the children's
// (1 - w)-weighted guide (their eqs. 7-8).
void AmRun::slice_block(Node* nodes, int m, bool split, int sy) {
  const std::size_t kid_cols = std::size_t(2 * (D_ + 1)) * W_;  // left child, then right
  Scratch& sc = scratch(m);
  const int ya = sy * df_, yb = std::min(H_, ya + df_);
  if (split) std::fill(sc.colsum.begin(), sc.colsum.begin() + std::ptrdiff_t(m * kid_cols), 0.0f);
  for (int y = ya; y < yb; ++y) {
    std::int32_t* lab = label_.data() + std::size_t(y) * W_;
    for (int k = 0; k < m; ++k) {
      const Node& n = nodes[k];
      slice_row(n, y, sc);
      if (!split) {
        answer_queries(n, y, nullptr, sc.blur.data(), sc);
        continue;
      }
      float* dot = sc.d2.data();
      split_side_row(n, y, sc, dot);
      float* tl = sc.w.data();  // (1 - w) for pixels going left, else 0
      float* tr = sc.x.data();  // the same for pixels going right
      const std::int32_t id = n.id, left = 2 * id, right = 2 * id + 1;
      // Branch-free, one element width (32-bit labels) and restrict-qualified: written with
      // plain pointers GCC had to assume tl, tr or lab alias dot and wrow, and compiled a
      // scalar loop with two data-dependent branches per pixel (a quarter of this pass).
      // The children's ids belong to the next level, so no other node of this group sees them.
      split_row(lab, dot, n.w.data() + std::size_t(y) * W_, tl, tr, id, left, right);
      splat_children_row(y, tl, tr, sc.colsum.data() + std::size_t(k) * kid_cols);
    }
  }
  if (split) store_children_block(nodes, m, sy, sc, 1.0f / float(yb - ya));
}

// Row y of manifold n's blurred splat, upsampled into sc.blur, added w-weighted to acc_.
void AmRun::slice_row(const Node& n, int y, Scratch& sc) {
  grid_.upsample_rows(n.splat, 0, C_ + 1, y, sc.blur.data(), sc.tmp.data());
  const float* wrow = n.w.data() + std::size_t(y) * W_;
  for (int c = 0; c <= C_; ++c) {
    float* a = acc_.row(c, y);
    const float* b = sc.blur.data() + std::size_t(c) * W_;
    for (int x = 0; x < W_; ++x) a[x] += wrow[x] * b[x];
  }
}

// v . (g - eta) along row y into `dot` (its sign is the pixel's side), and row y's queries
// answered (they need eta's row, which the root has at full resolution).
void AmRun::split_side_row(const Node& n, int y, Scratch& sc, float* dot) {
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
    return;
  }
  // v . (g - eta) = v . g - v . eta, and v . eta is linear in eta, so it is upsampled as one
  // plane (n.veta) instead of upsampling the D planes of eta.
  answer_queries(n, y, nullptr, sc.blur.data(), sc);
  grid_.upsample_rows(n.veta, 0, 1, y, dot, sc.tmp.data());
  for (int x = 0; x < W_; ++x) dot[x] = -dot[x];
  for (int c = 0; c < D_; ++c) {
    const float* g = guide_.row(c, y);
    const float vc = n.v[c];
    for (int x = 0; x < W_; ++x) dot[x] += vc * g[x];
  }
}

// The children's (1 - w)-weighted guide and weight of row y (tl left, tr right) added to the
// column sums `col` (D + 1 rows for the left child, then D + 1 for the right).
void AmRun::splat_children_row(int y, const float* tl, const float* tr, float* col) const {
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

// The children's column sums of reduced row sy, reduced per block into planar rows, then moved
// to their interleaved rows (transpose8.h; the padding channels get zeros).
void AmRun::store_children_block(Node* nodes, int m, int sy, Scratch& sc, float inv_rows) const {
  const std::size_t kid_cols = std::size_t(2 * (D_ + 1)) * W_;
  sc.kid.resize(std::size_t(D_ + 1) * sw_);
  sc.ptrs.resize(std::size_t(D_ + 1));
  for (int c = 0; c <= D_; ++c) sc.ptrs[std::size_t(c)] = sc.kid.data() + std::size_t(c) * sw_;
  for (int k = 0; k < m; ++k) {
    const float* col = sc.colsum.data() + std::size_t(k) * kid_cols;
    for (int side = 0; side < 2; ++side) {
      Interleaved& kid = nodes[k].kids[side];
      for (int c = 0; c <= D_; ++c)
        grid_.reduce_columns(col + std::size_t(side * (D_ + 1) + c) * W_, sc.ptrs[std::size_t(c)], inv_rows);
      to_interleaved(sc.ptrs.data(), D_ + 1, sw_, kid.row(sy), kid.dp);
    }
  }
}

// ---- Pass 4: the children. Each child's splat is low-passed (their h_filter) and normalised
// into its manifold; where its cluster left no weight, it keeps its parent's manifold.
void AmRun::make_children(Node& n, std::vector<Node>& next) const {
  for (int c2 = 0; c2 < 2; ++c2) {
    Interleaved& p = n.kids[c2];
    domain_transform::low_pass(p, s_.sigma_s / df_);
    Node child;
    child.id = 2 * n.id + c2;
    child.eta_small = Planes(sw_, sh_, D_, Planes::Overwritten{});
    // Each reduced row's sums moved to planar rows first (transpose8.h), so that the divisions
    // run along rows in vector code.
    tbb::parallel_for(tbb::blocked_range<int>(0, sh_), [&](const tbb::blocked_range<int>& range) {
      std::unique_ptr<float[]> planar(new float[std::size_t(D_ + 1) * sw_]);  // overwritten row by row
      std::vector<float*> rows(std::size_t(D_ + 1));
      for (int c = 0; c <= D_; ++c) rows[std::size_t(c)] = planar.get() + std::size_t(c) * sw_;
      const float* dn = rows[std::size_t(D_)];
      for (int sy = range.begin(); sy != range.end(); ++sy) {
        from_interleaved(p.row(sy), p.dp, sw_, rows.data(), D_ + 1);
        for (int c = 0; c < D_; ++c) {
          const float* parent = n.eta_small.row(c, sy);
          const float* num = rows[std::size_t(c)];
          float* e = child.eta_small.row(c, sy);
          for (int i = 0; i < sw_; ++i) e[i] = dn[i] > 1e-20f ? num[i] / dn[i] : parent[i];
        }
      }
    });
    p = Interleaved();
    next.push_back(std::move(child));
  }
  n.eta_small = Planes();
  n.veta = Planes();
}

}  // namespace dnb::am_detail
