// The adaptive-manifold filter (Gastal and Oliveira 2012, "Adaptive Manifolds for Real-Time
// High-Dimensional Filtering", SIGGRAPH): a linear-time approximation of a high-dimensional
// Gaussian filter of `src` whose weights depend on pixel distance (sigma_s, pixels) and on
// distance in a guide space (sigma_r, guide units). The reusable core of `am` (colour filtered
// by colour), `proposed` (illumination filtered in NLM/normal/depth space) and the OpenCL path.
//
// What runs (their algorithm 1, with the recursive tree of section 4.2):
//   - tree of manifolds of height H = max(2, ceil((floor(log2 sigma_s) - 1) * (1 - sigma_r)))
//     (their eq. 10, the formula of their reference code), K = 2^H - 1 manifolds;
//   - the first manifold eta_1 is the guide low-passed at full resolution (recursive filter);
//   - splat: every pixel adds w = exp(-|g - eta_k|^2 / sigma_r^2) * (src, 1) to the manifold,
//     which is stored at a resolution reduced by df = max(1, pow2floor(min(sigma_s/4, 256 sigma_r)))
//     (box average of each df x df block);
//   - blur: the domain-transform recursive filter (Gastal and Oliveira 2011) along the manifold,
//     at the reduced resolution, one horizontal and one vertical pass, its geodesic distance
//     sqrt(1 + (sigma_s/df / (sigma_r/sqrt 2))^2 |d eta|^2) (L2 over the guide channels);
//   - slice: each pixel gathers w * blurred (bilinear upsampling), summed over manifolds, and
//     the output is sum(w blur) / sum(w blur_0);
//   - split: the pixels of the node's cluster are divided by the sign of (g - eta_k) . v1, v1
//     the leading eigenvector of their (uncentred) covariance, found by a real power iteration
//     (pca_iterations steps of v <- C v / |C v| on the D x D matrix; OpenCV's implementation
//     restarts every step from its random vector, so its extra iterations change nothing);
//     the children eta_- and eta_+ are low-passed (1 - w)-weighted means of their clusters;
//   - optional outlier adjustment (their eq. 11): out = f + alpha (out - f) with
//     alpha = exp(-0.5 min_k |g - eta_k|^2 / sigma_r^2).
//
// Determinism: the power iteration's start vector comes from a std::mt19937_64 seeded with a
// hash of the guide's samples (every 61st float) and the tree node's index, so the same input
// gives the same output; all parallel loops write disjoint outputs (splat and split accumulate
// per reduced-resolution row, covariance sums per row are added in row order), so the result
// does not depend on the thread count. The tree is built level by level, the full-resolution
// passes of up to 8 manifolds of a level sharing one read of the guide (the passes are bound
// by memory, not arithmetic); slices are summed in level order.
//
// Multi-source guides: each group of guide channels is divided by its own sigma (make_guide),
// so a unit of distance means "one sigma of that group", as Gastal and Oliveira do for their
// multi-source examples; the filter then runs with sigma_r applied to the combined guide.
//
// Point queries (paper 3.1, edge sub-pixels): the slice at one pixel depends on that pixel's
// guide value only through w_k. Queries give a pixel and a guide value (and optionally the
// source value, for the outlier adjustment); the filter returns the slice there with that guide
// value, computed from the same blurred manifolds, without running the filter again.
#pragma once

#include <cstdint>
#include <vector>

#include "core/image.h"

namespace dnb {

struct AmSettings {
  double sigma_s = 16.0;      // spatial standard deviation, pixels
  double sigma_r = 0.2;       // range standard deviation, guide units (after make_guide)
  int tree_height = 0;        // manifold tree height; 0: from sigma_s and sigma_r (eq. 10)
  int pca_iterations = 1;     // power-iteration steps for each split (1 as the reference code)
  bool adjust_outliers = false;  // eq. 11
  // Strength of eq. 11: alpha = exp(-outlier_scale * d^2 / (2 sigma_r^2)), d the distance to the
  // nearest manifold; 1 is Gastal and Oliveira's, below 1 a pixel must be further from every
  // manifold before it falls back to its own value (also applies to the queries).
  double outlier_scale = 1.0;
  int downsample = 0;         // reduced-grid factor (a power of 2); 0: from sigma_s and sigma_r
};

// One slice query: the filtered value at pixel (x, y) as if that pixel's guide were `guide`
// (D floats, in the same scaled units as the guide image); `src` (C floats, or null) is the
// source value used by the outlier adjustment.
struct AmQuery {
  int x = 0, y = 0;
  const float* guide = nullptr;
  const float* src = nullptr;
  bool adjust_outliers = true;  // eq. 11 for this query, whatever the settings say for the image
};

// A group of guide channels with its own range standard deviation.
struct GuideGroup {
  ConstImageView image;
  float sigma = 1.0f;
};
// The combined guide: each group's channels multiplied by sigma_r / group sigma, so that
// |g - g'|^2 / sigma_r^2 = sum over groups of |g_group - g'_group|^2 / sigma_group^2.
Image make_guide(const std::vector<GuideGroup>& groups, float sigma_r);

int am_tree_height(double sigma_s, double sigma_r);
int am_downsample_factor(double sigma_s, double sigma_r);

// Filters src (C channels) with the guide (D channels, same size). `queries` are answered into
// query_out (C floats each, in order) when given.
Image am_filter(ConstImageView src, ConstImageView guide, const AmSettings& settings,
                const std::vector<AmQuery>& queries = {}, std::vector<float>* query_out = nullptr);

// A pixel whose summed slice weight is below this is treated as reached by no manifold (it
// keeps its own value). Not 0: whether a weight of 1e-40 survives depends on the processor's
// denormal mode (flush-to-zero is on in threads that render), and both paths must agree.
inline constexpr float kAmMinWeight = 1e-30f;

// Pieces shared by the CPU and OpenCL paths, so both split the same way.
namespace am_detail {
// Hash of the guide's samples (every 61st float) and shape: the seed of the split vectors.
std::uint64_t guide_seed(ConstImageView guide);
// The power iteration's start vector of tree node `id` (D values in [-0.5, 0.5) from seed and id).
std::vector<double> split_start(int D, std::uint64_t seed, int id);
// Leading eigenvector of the D x D covariance `cov` (row-major, symmetric) by `iterations`
// power-iteration steps from split_start(D, seed, id). (The OpenCL path runs the same steps on
// the device: adaptive_manifold.cl's split_dirs.)
std::vector<float> split_direction(const std::vector<double>& cov, int D, std::uint64_t seed, int id, int iterations);

// What a run on either path derives from its input and settings before it starts: sizes, the
// tree height, the reduced grid's factor and size, 1 / sigma_r^2 and the split vectors' seed.
// The base of the CPU run (am/run.h) and the OpenCL one (am/opencl.cpp).
struct AmRunShape {
  AmRunShape(ConstImageView src, ConstImageView guide, const AmSettings& s, const std::vector<AmQuery>& queries);
  // Without the images (proposed's OpenCL pipeline, whose images stay on the device): their sizes
  // and the split vectors' seed given (and host queries, if any).
  AmRunShape(int width, int height, int src_channels, int guide_channels, std::uint64_t seed, const AmSettings& s,
             const std::vector<AmQuery>& queries);
  AmSettings s_;
  int W_, H_, C_, D_;
  const std::vector<AmQuery>& queries_;
  int height_ = 2, df_ = 1, sw_ = 1, sh_ = 1;
  float inv_sr2_ = 1;
  std::uint64_t seed_ = 0;
};
}  // namespace am_detail

}  // namespace dnb
