// guided: the guided image filter (He, Sun and Tang 2010, "Guided Image Filtering", ECCV; the
// multi-channel guide of their section 3.5) applied to the untextured illumination L = D + I,
// with the albedo, the shading normal and the depth as the guide, as Bauszat, Eisemann and Magnor
// (2011, "Guided Image Filtering for Interactive High-quality Global Illumination") do for Monte
// Carlo renders. The result is composed as F' = L' * T + R + E (denoisers/illumination.h), R
// filtered the same way when filter_reflection is set.
//
// In every (2 radius + 1)^2 window w_k the filter fits L = a_k^T g + b_k by ridge regression on
// the m-channel guide g (m = 7: albedo RGB, normal XYZ, depth), one fit per colour channel:
//     a_k = (Sigma_k + eps U)^-1 cov_k(g, L),   b_k = mean_k(L) - a_k^T mean_k(g)
// and averages the fits of the windows covering a pixel: L'_i = mean(a)^T g_i + mean(b).
// Where the guide is flat the fit is a plain box mean (noise is averaged away); across a guide
// edge (a crease, a silhouette, a texture boundary) the linear model follows the edge.
//
// Each guide group is multiplied by its weight before the fit. Since eps regularises every
// channel alike, a larger weight lets that group explain more of the illumination (its edges are
// kept more); weight 0 drops the group. Depth is divided by its median first, so weights do not
// depend on the scene's scale. Each group is clamped to the range where its values mean
// something (albedo [0, 1], normal [-1, 1], relative depth [0, 1e3]): the fit sums squares of
// the guide in float, and one extreme but finite value (1e30) would overflow them.
//
// Why not OpenCV: ximgproc::guidedFilter takes at most 3 guide channels, and this guide has 7.
// The means are OpenCV box filters (cv::boxFilter); only the per-pixel m x m solve is written
// here. The image is processed in fixed bands of rows (with a halo of 2 radius rows), in parallel
// over bands: memory stays small and the result does not depend on the thread count.
//
// Parameters: the ParamSpec list at the end of this file, the only place they are documented
// (`denoisebench list methods` prints it); how the defaults were chosen: docs/method-defaults.md.
#include <algorithm>
#include <cmath>

#include <opencv2/imgproc.hpp>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include "denoisers/illumination.h"
#include "denoisers/method.h"

namespace dnb {
namespace {

constexpr int kBandRows = 64;  // output rows per band: fixed, so bands never depend on threads
constexpr float kMaxRelativeDepth = 1e3f;  // depth / median beyond this is as far as "background"
constexpr int kMaxGuide = 7;

// Per-thread buffers of one band, reused from band to band (a fresh 20 MB per band costs more
// in page faults than the box filters themselves).
struct Workspace {
  cv::Mat stats, means, fit, mean_fit;
};

// Solves A x = rhs for a symmetric positive definite m x m A (row-major) by Cholesky, in place
// of rhs, for `nrhs` right-hand sides stored one after the other. A is overwritten.
void cholesky_solve(double* A, int m, double* rhs, int nrhs) {
  double inv_diag[kMaxGuide];
  for (int j = 0; j < m; ++j) {
    double d = A[j * m + j];
    for (int k = 0; k < j; ++k) d -= A[j * m + k] * A[j * m + k];
    inv_diag[j] = 1.0 / std::sqrt(std::max(d, 1e-300));
    for (int i = j + 1; i < m; ++i) {
      double s = A[i * m + j];
      for (int k = 0; k < j; ++k) s -= A[i * m + k] * A[j * m + k];
      A[i * m + j] = s * inv_diag[j];
    }
  }
  for (int r = 0; r < nrhs; ++r) {
    double* x = rhs + r * m;
    for (int i = 0; i < m; ++i) {  // L y = b
      double s = x[i];
      for (int k = 0; k < i; ++k) s -= A[i * m + k] * x[k];
      x[i] = s * inv_diag[i];
    }
    for (int i = m - 1; i >= 0; --i) {  // L^T x = y
      double s = x[i];
      for (int k = i + 1; k < m; ++k) s -= A[k * m + i] * x[k];
      x[i] = s * inv_diag[i];
    }
  }
}

class Guided final : public Method {
 public:
  explicit Guided(const Params& p)
      : radius_(p.i("radius")),
        eps_(p.f("eps")),
        albedo_weight_(float(p.f("albedo_weight"))),
        normal_weight_(float(p.f("normal_weight"))),
        depth_weight_(float(p.f("depth_weight"))),
        filter_reflection_(p.b("filter_reflection")),
        firefly_ratio_(float(p.f("firefly_ratio"))) {}

  std::vector<std::string> required_layers() const override { return illumination_filter_layers(filter_reflection_); }

  MethodResult execute(const MethodInput& in) override {
    MethodResult r;
    const AovFrame& f = *in.frame;
    Image guide, light;
    {
      ScopedPhase p(r.stats, "prepare");
      guide = make_guide(f, 0);
      light = illumination(f);
      if (firefly_ratio_ > 0) light = split_fireflies(std::move(light), firefly_ratio_, false).kept;  // as proposed's
    }
    Image filtered, reflection;
    {
      ScopedPhase p(r.stats, "guided_filter");
      filtered = filter(guide, light);
    }
    if (filter_reflection_) {
      ScopedPhase p(r.stats, "guided_filter_reflection");
      reflection = filter(make_guide(f, 1), f.layer(layer::kReflection));
    }
    {
      ScopedPhase p(r.stats, "compose");
      r.image = filter_reflection_ ? compose(filtered, f, reflection) : compose(filtered, f);
    }
    r.stats.counters["guide_channels"] = guide.empty() ? 0 : guide.channels();
    return r;
  }

 private:
  Image filter(const Image& guide, const Image& src) const {
    Image out(src.width(), src.height(), 3);
    const int bands = (src.height() + kBandRows - 1) / kBandRows;
    tbb::enumerable_thread_specific<Workspace> workspaces;
    tbb::parallel_for(0, bands, [&](int b) {
      filter_band(guide, src, out, b * kBandRows, std::min(src.height(), (b + 1) * kBandRows), workspaces.local());
    });
    return out;
  }

  // The weighted guide of reflection level `level` (0: the first hit; 1: the hit seen in a
  // mirror): only the groups with a non-zero weight. Empty when there is none.
  Image make_guide(const AovFrame& f, int level) const {
    struct Group {
      const Image* img;
      float weight;
      float lo, hi;  // the values clamped to this range (see the top of the file)
    };
    Image depth = normalized_depth(f, level);
    std::vector<Group> groups;
    if (albedo_weight_ > 0)
      groups.push_back({&f.layer(layer::at_level(level, layer::kAlbedo)), albedo_weight_, 0.0f, 1.0f});
    if (normal_weight_ > 0)
      groups.push_back({&f.layer(layer::at_level(level, layer::kNormal)), normal_weight_, -1.0f, 1.0f});
    if (depth_weight_ > 0) groups.push_back({&depth, depth_weight_, 0.0f, kMaxRelativeDepth});
    int m = 0;
    for (auto& g : groups) m += g.img->channels();
    if (m == 0) return {};
    Image guide(f.width(), f.height(), m);
    for (std::size_t px = 0; px < guide.pixel_count(); ++px) {
      int c = 0;
      for (auto& g : groups)
        for (int k = 0; k < g.img->channels(); ++k)
          guide.data()[px * m + c++] = g.weight * std::clamp(g.img->data()[px * g.img->channels() + k], g.lo, g.hi);
    }
    return guide;
  }

  // Filters output rows [y0, y1). Means over rows need a halo of 2 radius rows: one radius for
  // the window statistics, one for the averaging of the fits.
  void filter_band(const Image& guide, const Image& light, Image& out, int y0, int y1, Workspace& ws) const {
    const int w = light.width(), h = light.height(), r = radius_;
    const int m = guide.empty() ? 0 : guide.channels();
    const int ya = std::max(0, y0 - 2 * r), yb = std::min(h, y1 + 2 * r);  // statistics rows
    const int yc = std::max(0, y0 - r), yd = std::min(h, y1 + r);          // fit rows
    const int npair = m * (m + 1) / 2;
    const int nstat = m + 3 + npair + 3 * m;
    const cv::Size ksize(2 * r + 1, 2 * r + 1);

    // Products whose window means give the fit: g (m), L (3), g_i g_j (i <= j), g_i L_c.
    cv::Mat& stats = ws.stats;
    stats.create(yb - ya, w, CV_32FC(nstat));
    for (int y = ya; y < yb; ++y) {
      float* s = stats.ptr<float>(y - ya);
      for (int x = 0; x < w; ++x, s += nstat) {
        const float* g = m ? guide.pixel(x, y) : nullptr;
        const float* l = light.pixel(x, y);
        int k = 0;
        for (int i = 0; i < m; ++i) s[k++] = g[i];
        for (int c = 0; c < 3; ++c) s[k++] = l[c];
        for (int i = 0; i < m; ++i)
          for (int j = i; j < m; ++j) s[k++] = g[i] * g[j];
        for (int i = 0; i < m; ++i)
          for (int c = 0; c < 3; ++c) s[k++] = g[i] * l[c];
      }
    }
    cv::Mat& means = ws.means;
    cv::boxFilter(stats, means, CV_32F, ksize, cv::Point(-1, -1), true, cv::BORDER_REFLECT);

    // The fit of each window: a (3 x m) and b (3), for rows [yc, yd).
    const int nfit = 3 * m + 3;
    cv::Mat& fit = ws.fit;
    fit.create(yd - yc, w, CV_32FC(nfit));
    double A[kMaxGuide * kMaxGuide], rhs[3 * kMaxGuide];
    for (int y = yc; y < yd; ++y) {
      const float* s = means.ptr<float>(y - ya);
      float* o = fit.ptr<float>(y - yc);
      for (int x = 0; x < w; ++x, s += nstat, o += nfit) {
        const float* mg = s;
        const float* ml = s + m;
        const float* mgg = s + m + 3;
        const float* mgl = mgg + npair;
        if (m > 0) {
          for (int i = 0, k = 0; i < m; ++i)
            for (int j = i; j < m; ++j, ++k) {
              const double v = double(mgg[k]) - double(mg[i]) * mg[j];
              A[i * m + j] = A[j * m + i] = v + (i == j ? eps_ : 0.0);
            }
          for (int c = 0; c < 3; ++c)
            for (int i = 0; i < m; ++i) rhs[c * m + i] = double(mgl[i * 3 + c]) - double(mg[i]) * ml[c];
          cholesky_solve(A, m, rhs, 3);
        }
        for (int c = 0; c < 3; ++c) {
          double b = ml[c];
          for (int i = 0; i < m; ++i) {
            o[c * m + i] = float(rhs[c * m + i]);
            b -= rhs[c * m + i] * mg[i];
          }
          o[3 * m + c] = float(b);
        }
      }
    }
    cv::Mat& mean_fit = ws.mean_fit;
    cv::boxFilter(fit, mean_fit, CV_32F, ksize, cv::Point(-1, -1), true, cv::BORDER_REFLECT);

    for (int y = y0; y < y1; ++y) {
      const float* a = mean_fit.ptr<float>(y - yc);
      for (int x = 0; x < w; ++x, a += nfit) {
        const float* g = m ? guide.pixel(x, y) : nullptr;
        float* q = out.pixel(x, y);
        for (int c = 0; c < 3; ++c) {
          float v = a[3 * m + c];
          for (int i = 0; i < m; ++i) v += a[c * m + i] * g[i];
          // A fit can extrapolate below zero next to a strong edge; radiance cannot be negative.
          q[c] = std::max(v, 0.0f);
        }
      }
    }
  }

  int radius_;
  double eps_;
  float albedo_weight_, normal_weight_, depth_weight_;
  bool filter_reflection_;
  float firefly_ratio_;
};

}  // namespace

MethodInfo guided_method() {
  return {
      .name = "guided",
      .description = "guided filter (He et al. 2010) on the illumination D+I, guided by albedo, normal and depth (Bauszat et al. 2011)",
      .kind = MethodKind::Filter,
      .params =
          {
              {"radius", ParamType::Int, "4", "window radius in pixels", 1.0, 64.0},
              {"eps", ParamType::Float, "0.0003", "regularisation of the per-window fit, squared guide units", 1e-6, 1e6},
              {"albedo_weight", ParamType::Float, "0.3", "scale of the albedo guide channels (0: unused)", 0.0, 1e3},
              {"normal_weight", ParamType::Float, "1", "scale of the normal guide channels (0: unused)", 0.0, 1e3},
              {"depth_weight", ParamType::Float, "3", "scale of the median-normalised depth guide (0: unused)", 0.0, 1e3},
              {"filter_reflection", ParamType::Bool, "false", "also filter R, guided by the refl1 albedo/normal/depth"},
              firefly_ratio_param(),
          },
      .create = [](const Params& p) { return std::make_unique<Guided>(p); },
  };
}

}  // namespace dnb
