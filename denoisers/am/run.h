// One run of the adaptive-manifold filter on the CPU (adaptive_manifold.h: the algorithm and
// its determinism): a private header of the core, shared by its two halves.
//   - adaptive_manifold.cpp: the run's set-up (planar copies, the first manifold, the queries'
//     bookkeeping), the point queries and the final normalisation;
//   - am/tree.cpp: the manifold tree, level by level, in groups of up to kGroup manifolds, each
//     group in named passes: splat (full resolution), blur (reduced grid), slice and split
//     (full resolution), children (reduced grid).
//
// Why every full-resolution pass is fused (distance, weight, splat and covariance in one; slice,
// split and the children's splat in the other): the passes are bound by reading the guide, the
// source and the accumulators from memory, not by arithmetic, so each reads them once per row.
// Rows are planar so the loops vectorise; the children's reduced splats are pixel-interleaved
// instead, for their low-pass (domain_transform.h: Interleaved); the exponentials go through
// OpenCV's vectorised cv::hal::exp32f. Compiled with -fno-trapping-math -fno-math-errno
// (denoisers/CMakeLists.txt).
#pragma once

#include <cstdint>
#include <vector>

#include <tbb/enumerable_thread_specific.h>

#include "core/image.h"
#include "denoisers/am/adaptive_manifold.h"
#include "denoisers/am/grid.h"
#include "denoisers/buffer_pool.h"
#include "denoisers/am/domain_transform.h"

namespace dnb::am_detail {

// Independent partial sums of a dot product: float sums only vectorise when their order is
// fixed by the code (no -ffast-math), and a fixed order also keeps the result bit-identical.
inline constexpr int kLanes = 16;

class AmRun : private AmRunShape {
 public:
  AmRun(ConstImageView src, ConstImageView guide, const AmSettings& s, const std::vector<AmQuery>& queries);
  ~AmRun();
  AmRun(const AmRun&) = delete;
  AmRun& operator=(const AmRun&) = delete;

  // Builds and slices the tree; the filtered image, and the queries' answers into query_out.
  Image run(std::vector<float>* query_out);

 private:
  struct Scratch {
    std::vector<float> eta, x, d2, w, tmp, blur;
    std::vector<float> qeta, qarg, qw;  // one pixel's manifold value and its queries' weights
    std::vector<float> qrow;            // a reduced eta row blended vertically (D x sw)
    std::vector<float> colsum;  // per-column sums over the rows of one reduced-grid row
    std::vector<float> cov;     // lane-split covariance sums (kLanes per entry)
    std::vector<float> kid;         // a child's reduced row, planar (D + 1 rows)
    std::vector<float*> ptrs;       // kid's rows
  };

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
    domain_transform::Interleaved kids[2];  // the children's (1 - w)-weighted guide splats and weights
  };
  // Manifolds of one level processed together: the full-resolution passes are bound by
  // reading the guide, the source and the accumulators from memory, so each pass reads them
  // once for up to kGroup manifolds instead of once per manifold (15 manifolds: 4 reads of the
  // guide per pass instead of 15). The group's weights are kept at full resolution meanwhile.
  static constexpr int kGroup = 8;

  // --- set-up and output (adaptive_manifold.cpp)
  void copy_and_low_pass_guide(ConstImageView src, ConstImageView guide);
  void index_queries();
  Image normalised_output() const;
  void answer_queries(const Node& n, int y, const float* eta, const float* blur, Scratch& sc);

  // --- the tree (am/tree.cpp)
  // Builds and slices the whole tree, level by level (the same manifolds as their recursive
  // algorithm 1; only the order in which slices are summed differs).
  void tree();
  // Splat, blur, slice and (above the leaves) split the m manifolds nodes[0 .. m); their
  // children go to `next`.
  void group(Node* nodes, int m, int level, std::vector<Node>& next);
  void start_group(Node* nodes, int m, bool split);
  // Pass 1 (full resolution) for reduced row sy: weights, splats and covariance sums.
  void splat_block(Node* nodes, int m, bool split, int sy);
  void weigh_and_splat_row(Node& n, int y, Scratch& sc, float* col);
  void add_covariance_row(const Node& n, const std::int32_t* lab, Scratch& sc, float* cov) const;
  // Pass 2 (reduced grid): blur, and above the leaves the split direction.
  void blur_and_orient(Node& n, bool split);
  // Pass 3 (full resolution) for reduced row sy: slice, split, the children's splats.
  void slice_block(Node* nodes, int m, bool split, int sy);
  void slice_row(const Node& n, int y, Scratch& sc);
  void split_side_row(const Node& n, int y, Scratch& sc, float* dot);
  void splat_children_row(int y, const float* tl, const float* tr, float* col) const;
  void store_children_block(Node* nodes, int m, int sy, Scratch& sc, float inv_rows) const;
  // Pass 4 (reduced grid): the children's manifolds, low-passed, into `next`.
  void make_children(Node& n, std::vector<Node>& next) const;

  Scratch& scratch(int m);
  // Fills rows [0, D) of `eta` (D x W) with manifold eta at full-resolution row y.
  void eta_row(const Planes* eta_full, const Planes& eta_small, int y, float* eta, float* tmp) const;
  Planes downsample(const Planes& full, int n) const;
  void blur(Planes& splat, const Planes& eta) const;

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

  ReducedGrid grid_;
  Planes guide_, src_, acc_, eta_full_;  // eta_full_: the first manifold, full resolution
  std::vector<float> min_d2_;
  std::vector<std::int32_t> label_;
  std::size_t nq_ = 0;
  std::vector<float> qacc_;  // planar: channel c of query q at c * nq_ + q (C sums, then the weight)
  std::vector<float> qg_;     // planar: the queries' guides
  std::vector<float> qmin_;
  std::vector<std::size_t> qrun_;  // first query of each run of queries at one pixel, then the count
  std::vector<std::size_t> row_runs_, runs_by_row_;  // runs_by_row_[row_runs_[y] ..) are row y's
  tbb::enumerable_thread_specific<Scratch> scratch_;
};

}  // namespace dnb::am_detail
