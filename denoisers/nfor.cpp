// nfor: Nonlinearly weighted First-Order Regression (Bitterli, Rousselle, Moon, Iglesias-Guitian,
// Adler, Mitchell, Jarosz and Novak 2016, "Nonlinearly Weighted First-order Regression for
// Denoising Monte Carlo Renderings", EGSR), on the frame's colour F, with the half buffers of the
// tracer (half0.*, half1.*: the even and the odd samples, core/aov_frame.h) as its two
// independent half-sample estimates A and B. The steps are the paper's section 5:
//
//  1. Feature cross-prefiltering (5.1): each feature half (albedo, normal, depth) is filtered by
//     NL-means with patch distances on the *other* half, patch radius 3, search radius 5, k = 0.5,
//     variance 2 Var(f) (a half's variance).
//  2. Collaborative first-order regression (5.2): for every pixel p, the colour of its
//     (2 radius + 1)^2 window is fitted as an affine function of the features by least squares
//     weighted with NL-means weights w(p, q) (on the half being filtered, patch radius `patch`,
//     bandwidth k); the fit is evaluated at every pixel q of the window and each q takes the
//     w-weighted mean of the fits of all windows that hold it. Half A is regressed on the
//     prefiltered features of half B and vice versa, for each of the two candidate bandwidths
//     k = `k_small`, `k_large`.
//  3. Selection (5.3): each candidate's per-pixel MSE is estimated from the halves' cross error,
//     ((B - A')^2 - 2 Var + (A - B')^2 - 2 Var) / 2 - (B' - A')^2 / 4, filtered by NL-means on the
//     colour (patch radius 1, search radius 9, k = 1); the candidate with the lower estimate wins
//     per pixel and channel, and the binary selection maps are filtered the same way and used as
//     blend weights.
//  4. Second pass (5.4): the selected halves' mean is regressed once more (k = 1) on the mean of
//     the prefiltered feature halves, themselves NL-means filtered (patch radius 3, search
//     radius 2, k = 0.5, variance (A_f - B_f)^2 / 4), with the variance (B - A)^2 / 4.
//
// NL-means weights are those of Rousselle, Manzi and Zwicker (2013): over the patch and the
// channels, d^2 = mean of ((u_p - u_q)^2 - (V_p + min(V_p, V_q))) / (1e-10 + k^2 (V_p + V_q)),
// w = exp(-max(0, d^2)); patch pixels outside the image are left out.
//
// Departures, from what the frame holds: the tracer writes no visibility feature (the paper's
// fourth), so the features are albedo, normal and depth (7 values and the constant); and it
// writes no variance of the features, so Var(f) of the combined feature is estimated from the
// halves, (f_A - f_B)^2 / 4 averaged over a 3x3 box. Var(F) is the frame's `variance` layer (from
// the spread of the tracer's independent sample groups, tracer/render.cpp). The regression's normal matrix
// gets a ridge of 1e-7 of its own diagonal (and 1e-12) on the feature terms, so that a window
// whose features are constant or collinear (a flat wall; grey albedo) still solves; the
// constant term is never damped.
//
// Linear algebra: Eigen's LDLT of the (1 + 7)^2 normal matrix per pixel. Written by hand
// otherwise: no library implements NFOR (OIDN, OpenCV and OIIO do not). Parallel over 32x32 tiles
// with TBB; a tile's regression writes into its own buffer, and the buffers are added into the
// image in tile order afterwards, so the output does not depend on the thread count.
//
// Parameters: the ParamSpec list at the end of this file; how the defaults were chosen:
// docs/method-defaults.md.
#include <algorithm>
#include <cmath>
#include <vector>

#include <Eigen/Dense>
#include <tbb/parallel_for.h>

#include "denoisers/buffer_pool.h"
#include "denoisers/fast_exp.h"
#include "denoisers/illumination.h"
#include "denoisers/method.h"

namespace dnb {
namespace {

constexpr int kTile = 32;
constexpr int kFeatures = 7;  // albedo RGB, normal XYZ, depth
constexpr int kDims = kFeatures + 1;

// Pixel (x, y) of channel c of the shared planar images (denoisers/buffer_pool.h).
inline float& at(Planes& p, int c, int x, int y) { return p.row(c, y)[x]; }
inline float at(const Planes& p, int c, int x, int y) { return p.row(c, y)[x]; }

Planes planes_of(const Image& img) {
  Planes out(img.width(), img.height(), img.channels(), Planes::Overwritten{});
  const std::size_t n = img.pixel_count();
  for (int c = 0; c < out.n; ++c)
    for (std::size_t px = 0; px < n; ++px) out.plane(c)[px] = img.data()[px * out.n + c];
  return out;
}

Image image_of(const Planes& p) {
  Image out(p.w, p.h, p.n);
  const std::size_t n = out.pixel_count();
  for (int c = 0; c < p.n; ++c)
    for (std::size_t px = 0; px < n; ++px) out.data()[px * p.n + c] = p.plane(c)[px];
  return out;
}

Planes scaled(const Planes& a, float s) {
  Planes out = a;
  for (float& v : out.data) v *= s;
  return out;
}

Planes combine(const Planes& a, const Planes& b, float wa, float wb) {
  Planes out(a.w, a.h, a.n);
  for (std::size_t k = 0; k < a.data.size(); ++k) out.data[k] = wa * a.data[k] + wb * b.data[k];
  return out;
}

// (a - b)^2 / 4 per value: the variance of (a + b) / 2 from one pair of independent halves.
Planes pair_variance(const Planes& a, const Planes& b) {
  Planes out(a.w, a.h, a.n);
  for (std::size_t k = 0; k < a.data.size(); ++k) out.data[k] = 0.25f * (a.data[k] - b.data[k]) * (a.data[k] - b.data[k]);
  return out;
}

// The mean over the in-image pixels of each 3x3 box.
Planes box3(const Planes& in) {
  Planes out(in.w, in.h, in.n);
  tbb::parallel_for(0, in.h, [&](int y) {
    for (int c = 0; c < in.n; ++c)
      for (int x = 0; x < in.w; ++x) {
        float s = 0;
        int n = 0;
        for (int yy = std::max(0, y - 1); yy <= std::min(in.h - 1, y + 1); ++yy)
          for (int xx = std::max(0, x - 1); xx <= std::min(in.w - 1, x + 1); ++xx) s += at(in, c, xx, yy), ++n;
        at(out, c, x, y) = s / float(n);
      }
  });
  return out;
}

struct TileRect {
  int x0, y0, x1, y1;
  int w() const { return x1 - x0; }
  int h() const { return y1 - y0; }
};

std::vector<TileRect> tiles_of(int w, int h) {
  std::vector<TileRect> t;
  for (int y = 0; y < h; y += kTile)
    for (int x = 0; x < w; x += kTile) t.push_back({x, y, std::min(w, x + kTile), std::min(h, y + kTile)});
  return t;
}

// NL-means weights from each pixel p of a tile to every q = p + (dx, dy), |dx|, |dy| <= R:
// w[o][(y - y0) * tile width + (x - x0)], o = (dy + R)(2R + 1) + dx + R; 0 where q is outside.
struct TileWeights {
  int R = 0;
  TileRect t{};
  std::vector<float> w;
  float at(int o, int x, int y) const { return w[(std::size_t(o) * t.h() + (y - t.y0)) * t.w() + (x - t.x0)]; }
};

TileWeights nlm_weights(const Planes& g, const Planes& var, int F, int R, float k, const TileRect& t) {
  TileWeights tw;
  tw.R = R;
  tw.t = t;
  const int side = 2 * R + 1;
  tw.w.assign(std::size_t(side) * side * t.w() * t.h(), 0.0f);
  // The per-pixel distance terms over the tile grown by F, clipped to the image.
  const int ex0 = std::max(0, t.x0 - F), ey0 = std::max(0, t.y0 - F);
  const int ex1 = std::min(g.w, t.x1 + F), ey1 = std::min(g.h, t.y1 + F);
  const int ew = ex1 - ex0, eh = ey1 - ey0;
  std::vector<float> term(std::size_t(ew) * eh), valid(std::size_t(ew) * eh), hs(std::size_t(ew) * eh),
      hv(std::size_t(ew) * eh);
  const float k2 = k * k, inv_c = 1.0f / float(g.n);
  for (int dy = -R; dy <= R; ++dy)
    for (int dx = -R; dx <= R; ++dx) {
      for (int y = ey0; y < ey1; ++y)
        for (int x = ex0; x < ex1; ++x) {
          const std::size_t e = std::size_t(y - ey0) * ew + (x - ex0);
          const int qx = x + dx, qy = y + dy;
          if (qx < 0 || qy < 0 || qx >= g.w || qy >= g.h) {
            term[e] = 0, valid[e] = 0;
            continue;
          }
          float s = 0;
          for (int c = 0; c < g.n; ++c) {
            const float vp = at(var, c, x, y), vq = at(var, c, qx, qy);
            const float diff = at(g, c, x, y) - at(g, c, qx, qy);
            s += (diff * diff - (vp + std::min(vp, vq))) / (1e-10f + k2 * (vp + vq));
          }
          term[e] = s * inv_c, valid[e] = 1;
        }
      // Box sums over the patch: rows, then columns.
      for (int y = 0; y < eh; ++y)
        for (int x = 0; x < ew; ++x) {
          float s = 0, v = 0;
          for (int xx = std::max(0, x - F); xx <= std::min(ew - 1, x + F); ++xx)
            s += term[std::size_t(y) * ew + xx], v += valid[std::size_t(y) * ew + xx];
          hs[std::size_t(y) * ew + x] = s, hv[std::size_t(y) * ew + x] = v;
        }
      const int o = (dy + R) * side + (dx + R);
      for (int y = t.y0; y < t.y1; ++y)
        for (int x = t.x0; x < t.x1; ++x) {
          const int qx = x + dx, qy = y + dy;
          if (qx < 0 || qy < 0 || qx >= g.w || qy >= g.h) continue;
          float s = 0, v = 0;
          for (int yy = std::max(ey0, y - F); yy <= std::min(ey1 - 1, y + F); ++yy) {
            const std::size_t e = std::size_t(yy - ey0) * ew + (x - ex0);
            s += hs[e], v += hv[e];
          }
          // v >= 1: the patch centre itself is valid (q is inside).
          tw.w[(std::size_t(o) * t.h() + (y - t.y0)) * t.w() + (x - t.x0)] = exp_nonpositive(-std::max(0.0f, s / v));
        }
    }
  return tw;
}

// NL-means of `img` with weights from `guide` (and its per-channel variance).
Planes nlmeans(const Planes& img, const Planes& guide, const Planes& var, int F, int R, float k) {
  Planes out(img.w, img.h, img.n);
  const auto tiles = tiles_of(img.w, img.h);
  tbb::parallel_for(std::size_t(0), tiles.size(), [&](std::size_t i) {
    const TileRect& t = tiles[i];
    const TileWeights tw = nlm_weights(guide, var, F, R, k, t);
    const int side = 2 * R + 1;
    for (int y = t.y0; y < t.y1; ++y)
      for (int x = t.x0; x < t.x1; ++x) {
        float s[8] = {0, 0, 0, 0, 0, 0, 0, 0}, ws = 0;
        for (int dy = -R; dy <= R; ++dy)
          for (int dx = -R; dx <= R; ++dx) {
            const float w = tw.at((dy + R) * side + dx + R, x, y);
            if (w == 0) continue;
            for (int c = 0; c < img.n; ++c) s[c] += w * at(img, c, x + dx, y + dy);
            ws += w;
          }
        for (int c = 0; c < img.n; ++c) at(out, c, x, y) = s[c] / ws;  // ws >= 1 (the centre)
      }
  });
  return out;
}

// One half's features: albedo (3), normal (3), depth (1) as planes.
struct Features {
  Planes albedo, normal, depth;
  float value(int j, int x, int y) const {
    return j < 3 ? at(albedo, j, x, y) : j < 6 ? at(normal, j - 3, x, y) : at(depth, 0, x, y);
  }
};

// The collaborative regression of the colour `img` (3 channels) on `f`, with NL-means weights
// on `img` itself (variance `var`, bandwidth k, patch radius F, window radius R).
Planes collaborative_regression(const Planes& img, const Features& f, const Planes& var, float k, int F, int R) {
  const int W = img.w, H = img.h, side = 2 * R + 1;
  const auto tiles = tiles_of(W, H);
  // Each tile's sums over the tile grown by R: colour (3) and weight, row-major.
  std::vector<std::vector<float>> sums(tiles.size());
  tbb::parallel_for(std::size_t(0), tiles.size(), [&](std::size_t i) {
    const TileRect& t = tiles[i];
    const TileWeights tw = nlm_weights(img, var, F, R, k, t);
    const int gx0 = std::max(0, t.x0 - R), gy0 = std::max(0, t.y0 - R);
    const int gw = std::min(W, t.x1 + R) - gx0, gh = std::min(H, t.y1 + R) - gy0;
    std::vector<float>& acc = sums[i];
    acc.assign(std::size_t(gw) * gh * 4, 0.0f);
    std::vector<float> xs(std::size_t(side) * side * kFeatures), ws(std::size_t(side) * side);
    for (int y = t.y0; y < t.y1; ++y)
      for (int x = t.x0; x < t.x1; ++x) {
        Eigen::Matrix<double, kDims, kDims> A = Eigen::Matrix<double, kDims, kDims>::Zero();
        Eigen::Matrix<double, kDims, 3> B = Eigen::Matrix<double, kDims, 3>::Zero();
        double fp[kFeatures];
        for (int j = 0; j < kFeatures; ++j) fp[j] = f.value(j, x, y);
        for (int dy = -R; dy <= R; ++dy)
          for (int dx = -R; dx <= R; ++dx) {
            const int o = (dy + R) * side + dx + R;
            const float w = tw.at(o, x, y);
            ws[o] = w;
            if (w == 0) continue;
            double v[kDims];
            v[0] = 1.0;
            for (int j = 0; j < kFeatures; ++j) v[j + 1] = xs[std::size_t(o) * kFeatures + j] = float(f.value(j, x + dx, y + dy) - fp[j]);
            for (int a = 0; a < kDims; ++a) {
              const double wa = w * v[a];
              for (int b = a; b < kDims; ++b) A(a, b) += wa * v[b];
              for (int c = 0; c < 3; ++c) B(a, c) += wa * at(img, c, x + dx, y + dy);
            }
          }
        for (int a = 0; a < kDims; ++a)
          for (int b = 0; b < a; ++b) A(a, b) = A(b, a);
        for (int a = 1; a < kDims; ++a) A(a, a) += 1e-7 * A(a, a) + 1e-12;
        Eigen::Matrix<double, kDims, 3> beta = A.ldlt().solve(B);
        if (!beta.allFinite()) {  // cannot happen with the ridge, but never write NaN: the weighted mean
          beta.setZero();
          for (int c = 0; c < 3; ++c) beta(0, c) = B(0, c) / A(0, 0);
        }
        for (int dy = -R; dy <= R; ++dy)
          for (int dx = -R; dx <= R; ++dx) {
            const int o = (dy + R) * side + dx + R;
            const float w = ws[o];
            if (w == 0) continue;
            float* a = &acc[(std::size_t(y + dy - gy0) * gw + (x + dx - gx0)) * 4];
            for (int c = 0; c < 3; ++c) {
              double r = beta(0, c);
              for (int j = 0; j < kFeatures; ++j) r += beta(j + 1, c) * xs[std::size_t(o) * kFeatures + j];
              a[c] += w * float(r);
            }
            a[3] += w;
          }
      }
  });
  // Add the tiles' sums in tile order (deterministic whatever the threads).
  std::vector<float> total(std::size_t(W) * H * 4, 0.0f);
  for (std::size_t i = 0; i < tiles.size(); ++i) {
    const TileRect& t = tiles[i];
    const int gx0 = std::max(0, t.x0 - R), gy0 = std::max(0, t.y0 - R);
    const int gw = std::min(W, t.x1 + R) - gx0, gh = std::min(H, t.y1 + R) - gy0;
    for (int y = 0; y < gh; ++y)
      for (int x = 0; x < gw; ++x)
        for (int c = 0; c < 4; ++c)
          total[(std::size_t(gy0 + y) * W + gx0 + x) * 4 + c] += sums[i][(std::size_t(y) * gw + x) * 4 + c];
  }
  Planes out(W, H, 3);
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) {
      const float* s = &total[(std::size_t(y) * W + x) * 4];
      for (int c = 0; c < 3; ++c) at(out, c, x, y) = s[c] / s[3];  // s[3] >= 1: p's own window
    }
  return out;
}

Features half_features(const AovFrame& f, int h) {
  return {planes_of(f.layer(layer::at_half(h, layer::kAlbedo))), planes_of(f.layer(layer::at_half(h, layer::kNormal))),
          planes_of(f.layer(layer::at_half(h, layer::kDepth)))};
}

class Nfor final : public Method {
 public:
  explicit Nfor(const Params& p)
      : radius_(p.i("radius")),
        patch_(p.i("patch_radius")),
        k_small_(float(p.f("k_small"))),
        k_large_(float(p.f("k_large"))),
        second_pass_(p.b("second_pass")),
        firefly_ratio_(float(p.f("firefly_ratio"))) {}

  std::vector<std::string> required_layers() const override {
    std::vector<std::string> l = {layer::kColor, layer::kVariance};
    for (int h = 0; h < 2; ++h)
      for (const char* b : {layer::kColor, layer::kAlbedo, layer::kNormal, layer::kDepth})
        l.push_back(layer::at_half(h, b));
    return l;
  }

  MethodResult execute(const MethodInput& in) override {
    MethodResult r;
    const AovFrame& f = *in.frame;
    // Each half's fireflies cut first (the harness's rule, as atrous, guided and proposed cut
    // theirs; not in the paper): a first-order regression on a window holding a pixel thousands
    // of times brighter than the rest extrapolates it into negative and saturated blotches
    // (McGuire's Sponza at 16 spp: 22% of the output negative, mse 7475 against the input's 941).
    auto half_colour = [&](int h) {
      Image c = f.layer(layer::at_half(h, layer::kColor));
      if (firefly_ratio_ > 0) c = split_fireflies(std::move(c), firefly_ratio_, false).kept;
      return planes_of(c);
    };
    const Planes colA = half_colour(0);
    const Planes colB = half_colour(1);
    const Planes color = combine(colA, colB, 0.5f, 0.5f);
    const Planes var = planes_of(f.layer(layer::kVariance));
    const Planes var_half = scaled(var, 2.0f);  // a half's variance
    Features fa = half_features(f, 0), fb = half_features(f, 1);
    Features pa, pb;  // cross-prefiltered
    {
      ScopedPhase p(r.stats, "prefilter_features");
      auto cross = [](const Planes& a, const Planes& b, Planes& out_a, Planes& out_b) {
        const Planes v = scaled(box3(pair_variance(a, b)), 2.0f);  // a half's variance
        out_a = nlmeans(a, b, v, 3, 5, 0.5f);
        out_b = nlmeans(b, a, v, 3, 5, 0.5f);
      };
      cross(fa.albedo, fb.albedo, pa.albedo, pb.albedo);
      cross(fa.normal, fb.normal, pa.normal, pb.normal);
      cross(fa.depth, fb.depth, pa.depth, pb.depth);
    }
    Planes resA, resB;
    {
      ScopedPhase p(r.stats, "regression");
      const float ks[2] = {k_small_, k_large_};
      Planes filtA[2], filtB[2], mse[2];
      for (int i = 0; i < 2; ++i) {
        filtA[i] = collaborative_regression(colA, pb, var_half, ks[i], patch_, radius_);
        filtB[i] = collaborative_regression(colB, pa, var_half, ks[i], patch_, radius_);
        Planes noisy(color.w, color.h, 3);
        for (std::size_t k = 0; k < noisy.data.size(); ++k) {
          const float ea = (colB.data[k] - filtA[i].data[k]) * (colB.data[k] - filtA[i].data[k]) - var_half.data[k];
          const float eb = (colA.data[k] - filtB[i].data[k]) * (colA.data[k] - filtB[i].data[k]) - var_half.data[k];
          const float resid = 0.25f * (filtB[i].data[k] - filtA[i].data[k]) * (filtB[i].data[k] - filtA[i].data[k]);
          noisy.data[k] = 0.5f * (ea + eb) - resid;
        }
        mse[i] = nlmeans(noisy, color, var, 1, 9, 1.0f);
      }
      Planes sel(color.w, color.h, 3);  // 1 where the first candidate wins
      for (std::size_t k = 0; k < sel.data.size(); ++k) sel.data[k] = mse[0].data[k] <= mse[1].data[k] ? 1.0f : 0.0f;
      sel = nlmeans(sel, color, var, 1, 9, 1.0f);
      resA = Planes(color.w, color.h, 3);
      resB = Planes(color.w, color.h, 3);
      for (std::size_t k = 0; k < sel.data.size(); ++k) {
        resA.data[k] = sel.data[k] * filtA[0].data[k] + (1 - sel.data[k]) * filtA[1].data[k];
        resB.data[k] = sel.data[k] * filtB[0].data[k] + (1 - sel.data[k]) * filtB[1].data[k];
      }
    }
    Planes result = combine(resA, resB, 0.5f, 0.5f);
    if (second_pass_) {
      ScopedPhase p(r.stats, "second_pass");
      auto final_feature = [](const Planes& a, const Planes& b) {
        const Planes m = combine(a, b, 0.5f, 0.5f);
        return nlmeans(m, m, pair_variance(a, b), 3, 2, 0.5f);
      };
      const Features fin{final_feature(pa.albedo, pb.albedo), final_feature(pa.normal, pb.normal),
                         final_feature(pa.depth, pb.depth)};
      result = collaborative_regression(result, fin, pair_variance(resA, resB), 1.0f, patch_, radius_);
    }
    // Light is not negative: a regression's extrapolation below zero is clamped.
    for (float& v : result.data) v = std::max(v, 0.0f);
    r.image = image_of(result);
    return r;
  }

 private:
  int radius_, patch_;
  float k_small_, k_large_;
  bool second_pass_;
  float firefly_ratio_;
};

}  // namespace

MethodInfo nfor_method() {
  return {
      .name = "nfor",
      .description = "NFOR (Bitterli et al. 2016): collaborative first-order regression on albedo/normal/depth with NL-means weights, half-buffer selection",
      .kind = MethodKind::Filter,
      .params =
          {
              {"radius", ParamType::Int, "9", "regression window radius (the paper's 19x19 window: 9)", 1.0, 20.0},
              {"patch_radius", ParamType::Int, "1", "NL-means patch radius of the regression weights", 0.0, 5.0},
              {"k_small", ParamType::Float, "0.75", "NL-means bandwidth of the first candidate filter", 1e-3, 100.0},
              {"k_large", ParamType::Float, "2", "NL-means bandwidth of the second candidate filter", 1e-3, 100.0},
              {"second_pass", ParamType::Bool, "false", "regress the selected result once more (paper 5.4)"},
              firefly_ratio_param(),
          },
      .create = [](const Params& p) { return std::make_unique<Nfor>(p); },
  };
}

}  // namespace dnb
