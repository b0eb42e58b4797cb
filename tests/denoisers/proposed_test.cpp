// The paper's method `proposed` (denoisers/proposed.cpp) on synthetic frames whose noise-free
// answer is known: texture kept, edge sub-pixel resolve, reflection levels, ablation switches.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <functional>
#include <random>

#include "denoisers/method.h"
#include "test_util.h"
#include "denoisers/synthetic_frame.h"
#include "tracer/render.h"
#include "tracer/scene_loader.h"

namespace dnb {
namespace {

// Measured figures for the test report, in scientific notation.
std::string sci(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%.3g", v);
  return b;
}

// A textured plane under smooth illumination: albedo a fine pattern (stripes of 3 pixels times
// an 8-pixel checkerboard, values 0.1 .. 0.9), direct light a smooth gradient, indirect light
// constant; 30% relative Gaussian noise on direct and indirect (about a 16-spp render). Level 1
// (a mirror seen nowhere: tint 0) is present but contributes nothing. `clean` gets the
// noise-free colour.
AovFrame textured_plane(int w, int h, float noise, Image* clean, std::uint64_t seed = 3) {
  AovFrame f = test::constant_frame(w, h);
  std::mt19937_64 rng(seed);
  std::normal_distribution<float> g(0.0f, 1.0f);
  Image& color = f.layer(layer::kColor);
  Image& d = f.layer(layer::kDirect);
  Image& i = f.layer(layer::kIndirect);
  Image& t = f.layer(layer::kAlbedo);
  Image& z = f.layer(layer::kDepth);
  Image& r = f.layer(layer::kReflection);
  Image& tint = f.layer(layer::at_level(1, layer::kTint));
  if (clean) *clean = Image(w, h, 3);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const float stripe = (x / 3) % 2 ? 1.0f : 0.35f;
      const float check = ((x / 8 + y / 8) % 2) ? 0.9f : 0.4f;
      z.at(x, y, 0) = 2.0f + 0.5f * float(y) / h;
      for (int c = 0; c < 3; ++c) {
        const float albedo = stripe * check * (c == 1 ? 0.8f : 1.0f);
        const float dl = 0.5f + 0.5f * float(x) / w + 0.2f * float(y) / h;
        const float il = 0.25f;
        t.at(x, y, c) = albedo;
        d.at(x, y, c) = std::max(0.0f, dl * (1 + noise * g(rng)));
        i.at(x, y, c) = std::max(0.0f, il * (1 + noise * g(rng)));
        r.at(x, y, c) = 0;
        tint.at(x, y, c) = 0;
        color.at(x, y, c) = (d.at(x, y, c) + i.at(x, y, c)) * albedo;
        // The variance of the pixel's mean, as the tracer's layer says it (the detail guard
        // reads it): the two layers' Gaussian noise through the albedo.
        f.layer(layer::kVariance).at(x, y, c) = albedo * albedo * noise * noise * (dl * dl + il * il);
        if (clean) clean->at(x, y, c) = (dl + il) * albedo;
      }
    }
  return f;
}

Image run(const std::string& method, const AovFrame& f, const std::map<std::string, std::string>& set = {}) {
  auto m = MethodRegistry::global().create(method, set);
  return run_method(*m, {.frame = &f}).image;
}

// The texture survives: the error of `proposed` against the noise-free image is at most 0.1x
// that of `am` on the colour (am blurs the 3-pixel stripes with the noise or keeps both,
// proposed never sees them since it filters the untextured illumination), and at most 0.03x the
// input's (measured 2026-12-03: 0.0198x with the detail guard off, 0.0202x with it on, 19 of
// 36864 samples clamped; the comment of 2026-11 said 0.010x, the filter has changed since).
TEST(Proposed, KeepsTextureWhileRemovingNoise) {
  Image clean;
  const AovFrame f = textured_plane(128, 96, 0.3f, &clean);
  const double input = test::mse(f.layer(layer::kColor), clean);
  const double am = test::mse(run("am", f), clean);
  const double ours = test::mse(run("proposed", f), clean);
  RecordProperty("mse_input", sci(input));
  RecordProperty("mse_am", sci(am));
  RecordProperty("mse_proposed", sci(ours));
  EXPECT_LT(ours, 0.1 * am) << "input " << input << " am " << am;
  EXPECT_LT(ours, 0.03 * input) << "input " << input << " am " << am;
}

// A high-contrast edge (paper 3.1): a bright, light-coloured surface (left) and a dark, dim one
// (right) meeting along a slanted line, so edge pixels are covered partly by each. The tracer's
// convention for edge pixels: T is the mean sub-pixel albedo, D and I are albedo-weighted means
// (so (D + I) T is the mean of the sub-pixels' (D_s + I_s) T_s), normal and depth are means.
// The 16 sub-pixels carry each side's own values; D and I carry noise, sub-pixel values more
// (a sixteenth of the samples each).
AovFrame edge_frame(int w, int h, float noise, Image* clean, std::vector<char>* is_edge, std::uint64_t seed = 11) {
  AovFrame f = test::constant_frame(w, h);
  std::mt19937_64 rng(seed);
  std::normal_distribution<float> g(0.0f, 1.0f);
  Image& color = f.layer(layer::kColor);
  Image& d = f.layer(layer::kDirect);
  Image& i = f.layer(layer::kIndirect);
  Image& t = f.layer(layer::kAlbedo);
  Image& n = f.layer(layer::kNormal);
  Image& z = f.layer(layer::kDepth);
  Image& r = f.layer(layer::kReflection);
  Image& e = f.layer(layer::kEdge);
  for (int c = 0; c < 3; ++c) f.layer(layer::at_level(1, layer::kTint)).data()[c] = 0;
  for (std::size_t k = 0; k < r.size(); ++k) r.data()[k] = 0, f.layer(layer::at_level(1, layer::kTint)).data()[k] = 0;
  *clean = Image(w, h, 3);
  is_edge->assign(std::size_t(w) * h, 0);
  EdgeSubpixels edges;
  struct Side {
    float n[3], depth, albedo[3], direct, indirect;
  };
  const Side left{{0, 0, 1}, 2.0f, {0.9f, 0.8f, 0.7f}, 1.0f, 0.3f};
  const Side right{{1, 0, 0}, 4.0f, {0.1f, 0.15f, 0.1f}, 0.1f, 0.05f};
  // The boundary: x = 0.45 w + 0.15 y (in pixels), a slope that gives every coverage.
  auto side_of = [&](float px, float py) { return px < 0.45f * w + 0.15f * py ? &left : &right; };
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      EdgeSample sub[16];
      int on_left = 0;
      for (int s = 0; s < 16; ++s) {
        const Side* sd = side_of(x + (s % 4 + 0.5f) / 4, y + (s / 4 + 0.5f) / 4);
        on_left += sd == &left;
        EdgeSample& es = sub[s];
        for (int c = 0; c < 3; ++c) {
          es.normal[c] = sd->n[c];
          es.albedo[c] = sd->albedo[c];
          es.direct[c] = std::max(0.0f, sd->direct * (1 + 4 * noise * g(rng)));
          es.indirect[c] = std::max(0.0f, sd->indirect * (1 + 4 * noise * g(rng)));
        }
        es.depth = sd->depth;
      }
      const bool edge = on_left != 0 && on_left != 16;
      (*is_edge)[std::size_t(y) * w + x] = edge;
      e.at(x, y, 0) = edge;
      for (int c = 0; c < 3; ++c) {
        float ts = 0, dts = 0, its = 0, ns = 0, truth = 0;
        for (int s = 0; s < 16; ++s) {
          const Side* sd = side_of(x + (s % 4 + 0.5f) / 4, y + (s / 4 + 0.5f) / 4);
          ts += sub[s].albedo[c];
          ns += sub[s].normal[c];
          truth += (sd->direct + sd->indirect) * sd->albedo[c];
        }
        const Side* mid = side_of(x + 0.5f, y + 0.5f);
        if (edge) {
          // Pixel means from the (noisy) sub-pixels, as a tracer accumulates them.
          for (int s = 0; s < 16; ++s) dts += sub[s].direct[c] * sub[s].albedo[c], its += sub[s].indirect[c] * sub[s].albedo[c];
          d.at(x, y, c) = dts / ts;
          i.at(x, y, c) = its / ts;
        } else {
          d.at(x, y, c) = std::max(0.0f, mid->direct * (1 + noise * g(rng)));
          i.at(x, y, c) = std::max(0.0f, mid->indirect * (1 + noise * g(rng)));
        }
        t.at(x, y, c) = ts / 16;
        n.at(x, y, c) = ns / 16;
        color.at(x, y, c) = (d.at(x, y, c) + i.at(x, y, c)) * t.at(x, y, c);
        clean->at(x, y, c) = truth / 16;
      }
      float zs = 0;
      for (int s = 0; s < 16; ++s) zs += sub[s].depth;
      z.at(x, y, 0) = zs / 16;
      if (edge) {
        edges.pixels.push_back(y * w + x);
        for (int s = 0; s < 16; ++s) edges.samples.push_back(sub[s]);
      }
    }
  f.edges = edges;
  return f;
}

double mse_on(const Image& a, const Image& b, const std::vector<char>& mask) {
  double s = 0;
  std::size_t n = 0;
  for (std::size_t p = 0; p < mask.size(); ++p)
    if (mask[p])
      for (int c = 0; c < 3; ++c) {
        const double d = double(a.data()[p * 3 + c]) - b.data()[p * 3 + c];
        s += d * d, ++n;
      }
  return s / double(std::max<std::size_t>(n, 1));
}

// The sub-pixel resolve lowers the error on the pixels of G (the mixed pixels' blended guide
// pulls in both sides' illumination, and the product of pixel means is not the mean of
// products). Sub-pixel slices far from every manifold fall back towards the sub-pixel's own
// value (eq. 11), which carries 4x the noise of the pixel here, so the gain is about 0.6x, not
// more. One frame is not enough to say so: the tree's split directions start from a random
// vector seeded by the guide, and over 16 noise seeds one frame's ratio ranged 0.49-0.92 (two
// above 0.8; a rounding change in the NLM vectors moved seed 11 from 0.49 to 0.87). Pooled over
// 8 frames it was 0.58-0.63 across those code versions, so the bound 0.8 is far from both.
TEST(Proposed, EdgeSubpixelResolveLowersErrorOnEdgePixels) {
  double with = 0, without = 0;
  for (std::uint64_t seed = 1; seed <= 8; ++seed) {
    Image clean;
    std::vector<char> g;
    const AovFrame f = edge_frame(96, 64, 0.2f, &clean, &g, seed);
    ASSERT_GT(f.edges->size(), 50u);
    with += mse_on(run("proposed", f), clean, g);
    without += mse_on(run("proposed", f, {{"edge_subpixels", "false"}}), clean, g);
  }
  RecordProperty("mse_edge_with_resolve", sci(with / 8));
  RecordProperty("mse_edge_without_resolve", sci(without / 8));
  EXPECT_LT(with, 0.8 * without) << "with " << with / 8 << " without " << without / 8;
}

// On a rendered scene the resolve must not raise the error on G. Before the outlier adjustment
// applied to sub-pixel slices, a sub-pixel guide far from every manifold (a sliver of a second
// surface inside a silhouette pixel) took the value of whichever manifold was least far: the
// 8-bit MSE on G of conference at 256x192, 256 spp went from 8.7 without the resolve to 99 with
// it (now 8.0). Here: conference at 128x96, 64 spp, against 512 spp. Bound 1.3x of the error
// without the resolve: where sub-pixels fall back to their own values (a sixteenth of the
// samples) the resolve can cost a little; the failure it guards against cost 11x.
TEST(Proposed, EdgeResolveDoesNotRaiseTheErrorOnARenderedScene) {
  auto scene = load_scene("conference");
  RenderSettings s;
  s.width = 128, s.height = 96, s.spp = 64, s.seed = 1;
  const AovFrame f = render_frame(*scene, s);
  s.spp = 512, s.seed = 77, s.edge_subpixels = false, s.reflection_levels = 0;
  const Image reference = render_frame(*scene, s).layer(layer::kColor);
  ASSERT_TRUE(f.edges && f.edges->size() > 200u);
  std::vector<char> g(std::size_t(f.width()) * f.height(), 0);
  for (int p : f.edges->pixels) g[std::size_t(p)] = 1;
  const double with = mse_on(run("proposed", f), reference, g);
  const double without = mse_on(run("proposed", f, {{"edge_subpixels", "false"}}), reference, g);
  RecordProperty("mse_edge_with_resolve", sci(with));
  RecordProperty("mse_edge_without_resolve", sci(without));
  EXPECT_LT(with, 1.3 * without) << "with " << with << " without " << without;
}

// Rough glossy and refracting surfaces (tracer 7's hard materials) have light in R that no
// reflection level explains: a rough lobe has no level behind it (refl1.tint is 0 there). That
// part passes through as the deepest level's R does; composed from the levels alone a rough gold
// ball, frosted glass and a rough coat are black (still-life's mse 1614 against the input's 3.2). On a
// frame of both kinds, rough metal beside clear glass: the error against a 16x render is below
// the input's, and the rough ball's mean stays the input's within 2% (only noise is removed).
TEST(Proposed, RoughGlossyLightWithoutALevelBehindItIsKept) {
  test::TempDir dir;
  const std::string text =
      "[camera]\neye = [0, 0.6, 3]\nlook_at = [0, 0.4, 0]\nvfov = 40\n"
      "[sky]\ntype = \"constant\"\ncolor = [0.6, 0.65, 0.7]\n"
      "[materials.gold]\ntype = \"conductor\"\nmetal = \"Au\"\nroughness = 0.2\n"
      "[materials.glass]\ntype = \"dielectric\"\nior = 1.5\n"
      "[materials.floor]\nalbedo = [0.5, 0.5, 0.5]\n"
      "[[objects]]\ntype = \"sphere\"\nmaterial = \"gold\"\ncenter = [-0.55, 0.5, 0]\nradius = 0.5\n"
      "[[objects]]\ntype = \"sphere\"\nmaterial = \"glass\"\ncenter = [0.55, 0.5, 0]\nradius = 0.5\n"
      "[[objects]]\ntype = \"quad\"\nmaterial = \"floor\"\nsize = [10, 10]\n"
      "[[lights]]\ntype = \"quad\"\nsize = [1, 1]\nrotate = [180, 0, 0]\ntranslate = [0, 3, 1]\nemission = [8, 8, 8]\n";
  std::ofstream(dir.file("hard.toml")) << text;
  auto scene = load_scene(dir.file("hard.toml"));
  RenderSettings s;
  s.width = 64, s.height = 48, s.spp = 16, s.seed = 1;
  const AovFrame f = render_frame(*scene, s);
  s.spp = 256, s.seed = 99, s.edge_subpixels = false, s.reflection_levels = 0;
  const Image reference = render_frame(*scene, s).layer(layer::kColor);
  const Image out = run("proposed", f);
  std::vector<char> all(std::size_t(f.width()) * f.height(), 1), ball(all.size(), 0);
  double in_ball = 0, out_ball = 0;
  for (int y = 0; y < f.height(); ++y)
    for (int x = 0; x < f.width() / 2; ++x) {
      const std::size_t p = std::size_t(y) * f.width() + x;
      // The gold ball's pixels: reflection and no diffuse albedo, no level behind (tint 0).
      if (f.layer(layer::kAlbedo).at(x, y, 1) > 0 || f.layer(layer::kReflection).at(x, y, 1) <= 0) continue;
      if (f.layer(layer::at_level(1, layer::kTint)).at(x, y, 1) > 0) continue;
      ball[p] = 1;
      in_ball += f.layer(layer::kColor).at(x, y, 1);
      out_ball += out.at(x, y, 1);
    }
  ASSERT_GT(in_ball, 0);
  EXPECT_NEAR(out_ball / in_ball, 1.0, 0.02);
  const double e_out = mse_on(out, reference, all), e_in = mse_on(f.layer(layer::kColor), reference, all);
  RecordProperty("mse_out", sci(e_out));
  RecordProperty("mse_in", sci(e_in));
  EXPECT_LT(e_out, e_in);
}

// Reflection level (paper 3.2): the right half is a mirror (T = D = I = 0 at level 0, tint 0.9)
// showing a noisy lit surface at level 1; filtering level 1 and composing it through the tint
// beats passing the noisy R through: measured MSE 4.2e-4 against 1.1e-2 on the mirror pixels.
TEST(Proposed, ReflectionLevelIsFiltered) {
  Image clean;
  AovFrame f = textured_plane(96, 64, 0.3f, &clean);
  std::mt19937_64 rng(5);
  std::normal_distribution<float> g(0.0f, 1.0f);
  const int w = f.width(), h = f.height();
  std::vector<char> mirror(std::size_t(w) * h, 0);
  for (int y = 0; y < h; ++y)
    for (int x = w / 2; x < w; ++x) {
      mirror[std::size_t(y) * w + x] = 1;
      for (int c = 0; c < 3; ++c) {
        const float d1 = 0.6f + 0.3f * float(y) / h, i1 = 0.2f, t1 = 0.5f, tint = 0.9f;
        const float dn = std::max(0.0f, d1 * (1 + 0.3f * g(rng))), in = std::max(0.0f, i1 * (1 + 0.3f * g(rng)));
        f.layer(layer::at_level(1, layer::kDirect)).at(x, y, c) = dn;
        f.layer(layer::at_level(1, layer::kIndirect)).at(x, y, c) = in;
        f.layer(layer::at_level(1, layer::kAlbedo)).at(x, y, c) = t1;
        f.layer(layer::at_level(1, layer::kReflection)).at(x, y, c) = 0;
        f.layer(layer::at_level(1, layer::kTint)).at(x, y, c) = tint;
        f.layer(layer::kDirect).at(x, y, c) = 0;
        f.layer(layer::kIndirect).at(x, y, c) = 0;
        f.layer(layer::kAlbedo).at(x, y, c) = 0;
        f.layer(layer::kReflection).at(x, y, c) = tint * (dn + in) * t1;
        f.layer(layer::kColor).at(x, y, c) = tint * (dn + in) * t1;
        clean.at(x, y, c) = tint * (d1 + i1) * t1;
      }
      f.layer(layer::kNormal).at(x, y, 0) = 1;
      f.layer(layer::kNormal).at(x, y, 2) = 0;
    }
  const Image split = run("proposed", f);
  const double with = mse_on(split, clean, mirror);
  const double without = mse_on(run("proposed", f, {{"reflections", "false"}}), clean, mirror);
  RecordProperty("mse_mirror_with_levels", sci(with));
  RecordProperty("mse_mirror_without_levels", sci(without));
  EXPECT_LT(with, 0.3 * without) << "with " << with << " without " << without;
  // The speed option reflection_sum filters the level's D + I as one layer: the mirror is as
  // well filtered (same bound), and nothing but the mirror changes (below).
  const Image summed = run("proposed", f, {{"reflection_sum", "true"}});
  const double with_sum = mse_on(summed, clean, mirror);
  RecordProperty("mse_mirror_reflection_sum", sci(with_sum));
  EXPECT_LT(with_sum, 0.3 * without) << "summed " << with_sum << " without " << without;
  // Off the mirror, the detail guard's calibration (a median over the whole image of each
  // pixel's change over its noise) sees the mirror's pixels too, so there the option may move a
  // clamped pixel by the calibration's change (measured: 1 ulp at one pixel under -O1, none at
  // -O3); without the guard nothing but the mirror changes, to the bit.
  const Image split_unguarded = run("proposed", f, {{"detail_guard", "0"}});
  const Image summed_unguarded = run("proposed", f, {{"reflection_sum", "true"}, {"detail_guard", "0"}});
  bool mirror_changed = false;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      for (int c = 0; c < 3; ++c) {
        if (mirror[std::size_t(y) * w + x]) {
          mirror_changed |= split.at(x, y, c) != summed.at(x, y, c);
        } else {
          ASSERT_EQ(split_unguarded.at(x, y, c), summed_unguarded.at(x, y, c)) << x << "," << y;
          ASSERT_NEAR(split.at(x, y, c), summed.at(x, y, c), 1e-6f * std::abs(split.at(x, y, c))) << x << "," << y;
        }
      }
  EXPECT_TRUE(mirror_changed) << "reflection_sum did not change the level at all";
}

// A coated surface (paper 3.2 with the tracer's coat, tracer/integrator.cpp): the right half
// reflects a bright, noise-free level 1 (F1 = 1) through a tint whose expectation is 0.08 but
// which each pixel estimates from its 256 samples' lobe choices (pc 0.2: binomial, 12.5%
// relative noise). The filtered level is multiplied by that tint, so its noise stays in the
// image unless the tint is smoothed: with tint_radius 2 the error on the coated half must be at
// most 0.5x that with the raw tint (measured 0.24x: 3.2e-5 against 1.35e-4).
TEST(Proposed, CoatedSurfaceTintNoiseIsSmoothed) {
  Image clean;
  AovFrame f = textured_plane(96, 64, 0.05f, &clean);
  f.meta.spp = 256;
  std::mt19937_64 rng(21);
  std::binomial_distribution<int> picks(256, 0.2);
  const int w = f.width(), h = f.height();
  std::vector<char> coated(std::size_t(w) * h, 0);
  const float expected = 0.08f, f1 = 1.0f;
  for (int y = 0; y < h; ++y)
    for (int x = w / 2; x < w; ++x) {
      coated[std::size_t(y) * w + x] = 1;
      const float tint = expected / 0.2f * float(picks(rng)) / 256.0f;
      for (int c = 0; c < 3; ++c) {
        f.layer(layer::at_level(1, layer::kDirect)).at(x, y, c) = 2.0f;
        f.layer(layer::at_level(1, layer::kIndirect)).at(x, y, c) = 0;
        f.layer(layer::at_level(1, layer::kAlbedo)).at(x, y, c) = 0.5f;
        f.layer(layer::at_level(1, layer::kTint)).at(x, y, c) = tint;
        f.layer(layer::kReflection).at(x, y, c) = tint * f1;
        f.layer(layer::kColor).at(x, y, c) += tint * f1;
        clean.at(x, y, c) += expected * f1;
      }
      f.layer(layer::at_level(1, layer::kNormal)).at(x, y, 1) = 1;
      f.layer(layer::at_level(1, layer::kDepth)).at(x, y, 0) = 3.0f;
    }
  const double smoothed = mse_on(run("proposed", f), clean, coated);
  const double raw = mse_on(run("proposed", f, {{"tint_radius", "0"}}), clean, coated);
  RecordProperty("mse_coated_smoothed_tint", sci(smoothed));
  RecordProperty("mse_coated_raw_tint", sci(raw));
  EXPECT_LT(smoothed, 0.5 * raw) << "smoothed " << smoothed << " raw " << raw;
}

// A reflection level is filtered only over the box where its tint is non-zero, plus a margin
// of 6 sigma_s (24 pixels at the default sigma_s 4): the level's layers outside it do not
// change the output by a single bit, the box is the expected size, and a level whose tint is
// zero everywhere is not filtered at all.
TEST(Proposed, ReflectionLevelFilteredOnlyWhereVisible) {
  AovFrame f = textured_plane(128, 96, 0.3f, nullptr);
  const int w = f.width(), h = f.height();
  const int mx0 = 40, my0 = 20, side = 24;  // the mirror: x 40..63, y 20..43
  std::mt19937_64 rng(11);
  std::normal_distribution<float> g(0.0f, 1.0f);
  for (int y = my0; y < my0 + side; ++y)
    for (int x = mx0; x < mx0 + side; ++x) {
      for (int c = 0; c < 3; ++c) {
        f.layer(layer::at_level(1, layer::kDirect)).at(x, y, c) = std::max(0.0f, 0.7f * (1 + 0.3f * g(rng)));
        f.layer(layer::at_level(1, layer::kIndirect)).at(x, y, c) = std::max(0.0f, 0.2f * (1 + 0.3f * g(rng)));
        f.layer(layer::at_level(1, layer::kAlbedo)).at(x, y, c) = 0.5f;
        f.layer(layer::at_level(1, layer::kTint)).at(x, y, c) = 0.9f;
        for (const char* base : {layer::kDirect, layer::kIndirect, layer::kAlbedo}) f.layer(base).at(x, y, c) = 0;
        // The colour is the mirror's (tint times level 1), its variance that of the level's noise.
        f.layer(layer::kColor).at(x, y, c) = 0.9f * 0.5f * (f.layer(layer::at_level(1, layer::kDirect)).at(x, y, c) +
                                                           f.layer(layer::at_level(1, layer::kIndirect)).at(x, y, c));
        f.layer(layer::kVariance).at(x, y, c) = 0.45f * 0.45f * 0.09f * (0.7f * 0.7f + 0.2f * 0.2f);
        // R is that colour too: the frame's split holds (R = tint x level 1's colour), as the
        // tracer's frames' does, so no part of R is left unexplained by the level.
        f.layer(layer::kReflection).at(x, y, c) = f.layer(layer::kColor).at(x, y, c);
      }
      f.layer(layer::at_level(1, layer::kNormal)).at(x, y, 1) = 1;
      f.layer(layer::at_level(1, layer::kDepth)).at(x, y, 0) = 3.0f;
    }
  // Level 2 present, its tint zero everywhere, its layers noise.
  for (const char* base : {layer::kDirect, layer::kIndirect, layer::kAlbedo, layer::kReflection, layer::kEmission,
                           layer::kNormal, layer::kTint})
    f.add(layer::at_level(2, base), 3);
  f.add(layer::at_level(2, layer::kDepth), 1);
  AovFrame noisy = f;
  for (const char* base : {layer::kDirect, layer::kIndirect, layer::kNormal, layer::kDepth}) {
    for (int k = 1; k <= 2; ++k) {
      Image& im = noisy.layer(layer::at_level(k, base));
      for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
          const bool in_box = x >= mx0 - 24 && x < mx0 + side + 24 && y >= my0 - 24 && y < my0 + side + 24;
          if (k == 1 && in_box) continue;
          for (int c = 0; c < im.channels(); ++c) im.at(x, y, c) = 5.0f + 3.0f * g(rng);
        }
    }
  }
  auto m = MethodRegistry::global().create("proposed", {});
  const MethodResult a = run_method(*m, {.frame = &f});
  const MethodResult b = run_method(*m, {.frame = &noisy});
  EXPECT_TRUE(a.image == b.image) << "level-1/2 layers outside the visible box changed the output";
  // Box x 16..87, y 0..67 (clipped at the top): 72 x 68 of 128 x 96.
  EXPECT_DOUBLE_EQ(a.stats.counters.at("level1_filtered_fraction"), 72.0 * 68.0 / (128.0 * 96.0));
  EXPECT_DOUBLE_EQ(a.stats.counters.at("level2_filtered_fraction"), 0.0);
  // And level 1 was filtered inside the box: the mirror's output is smoother than its input.
  double in_var = 0, out_var = 0, in_mean = 0, out_mean = 0;
  const int n = side * side;
  std::vector<double> iv, ov;
  for (int y = my0; y < my0 + side; ++y)
    for (int x = mx0; x < mx0 + side; ++x) {
      const double t = 0.9 * 0.5;
      iv.push_back(t * (f.layer(layer::at_level(1, layer::kDirect)).at(x, y, 1) + f.layer(layer::at_level(1, layer::kIndirect)).at(x, y, 1)));
      ov.push_back(a.image.at(x, y, 1));
    }
  for (int k = 0; k < n; ++k) in_mean += iv[k] / n, out_mean += ov[k] / n;
  for (int k = 0; k < n; ++k) in_var += (iv[k] - in_mean) * (iv[k] - in_mean) / n, out_var += (ov[k] - out_mean) * (ov[k] - out_mean) / n;
  EXPECT_LT(out_var, 0.3 * in_var) << "in " << in_var << " out " << out_var;
  EXPECT_NEAR(out_mean, in_mean, 0.05 * in_mean);
}

// sigma_nlm, the direct layer's sigma_nlm_direct and the outlier adjustment's strength are the
// values at 256 spp and follow the frame's sample count (its metadata): sigma_nlm as
// (256 / spp)^nlm_spp_exponent, sigma_nlm_direct as (256 / spp)^nlm_direct_spp_exponent, eq.
// 11's strength as (spp / 256)^outlier_spp_exponent. A 16-spp frame is filtered exactly as a
// 256-spp frame with the sigmas scaled by hand (the outlier scaling off in both), exponents 0
// turn the scalings off, and a frame without a sample count (spp 0, a hand-made frame) is
// filtered with the parameters as given.
TEST(Proposed, ParametersFollowTheFrameSampleCount) {
  Image clean;
  AovFrame f16 = textured_plane(48, 40, 0.3f, &clean);
  f16.meta.spp = 16;
  AovFrame f256 = f16;
  f256.meta.spp = 256;
  AovFrame f0 = f16;
  f0.meta.spp = 0;
  const std::map<std::string, std::string> no_outlier{{"outlier_spp_exponent", "0"}};
  // Defaults: sigma_nlm 0.05 x 16 = 0.8; sigma_nlm_direct 0.0075 x 16^0.25 = 0.015.
  EXPECT_EQ(test::mse(run("proposed", f16, no_outlier),
                      run("proposed", f256, {{"sigma_nlm", "0.8"}, {"sigma_nlm_direct", "0.015"}, {"outlier_spp_exponent", "0"}})),
            0.0);
  const Image fixed = run("proposed", f16, {{"nlm_spp_exponent", "0"}, {"nlm_direct_spp_exponent", "0"}, {"outlier_spp_exponent", "0"}});
  EXPECT_EQ(test::mse(fixed, run("proposed", f256)), 0.0);
  EXPECT_EQ(test::mse(fixed, run("proposed", f0)), 0.0);
  const Image scaled = run("proposed", f16);
  EXPECT_GT(test::mse(scaled, run("proposed", f16, no_outlier)), 1e-10) << "the outlier scaling changed nothing";
  EXPECT_GT(test::mse(scaled, fixed), 1e-8) << "the scalings changed nothing";
  // At this noise (30% relative, about 16 spp) the scaled parameters also lower the error
  // against the noise-free image (measured in the record); one noise draw, so only "not
  // higher" is asserted.
  const double e_scaled = test::mse(scaled, clean), e_fixed = test::mse(fixed, clean);
  RecordProperty("mse_scaled", sci(e_scaled));
  RecordProperty("mse_fixed", sci(e_fixed));
  EXPECT_LE(e_scaled, e_fixed) << "scaled " << e_scaled << " fixed " << e_fixed;
}

// Rare bright paths (fireflies): the textured plane at 256-spp-like noise (5%) with 40 isolated
// pixels whose indirect light is 200x its mean (one sample of a bright caustic path among 256,
// the way sponza's sun caustics look). Their expected light is 200 / 256 of a pixel's indirect
// light per firefly, spread thinly; the filter keeping them smears each into a blotch of its
// kernel's size. With the cut (firefly_ratio 3) the error against the noise-free image must
// be at most a third of the error without it (measured in the record); and the pixels around
// each firefly (its 9x9 window but the firefly) must not be raised on average by more than a
// tenth of what the filter without the cut raises them.
TEST(Proposed, FirefliesAreCutNotSmeared) {
  Image clean;
  AovFrame f = textured_plane(128, 96, 0.05f, &clean);
  std::mt19937_64 rng(5);
  std::vector<std::pair<int, int>> spots;
  while (spots.size() < 40) {
    const int x = 6 + int(rng() % 116), y = 6 + int(rng() % 84);
    bool near = false;
    for (auto [sx, sy] : spots) near = near || (std::abs(sx - x) < 10 && std::abs(sy - y) < 10);
    if (near) continue;
    spots.push_back({x, y});
    for (int c = 0; c < 3; ++c) {
      const float before = f.layer(layer::kColor).at(x, y, c);
      f.layer(layer::kIndirect).at(x, y, c) *= 200.0f;
      f.layer(layer::kColor).at(x, y, c) =
          (f.layer(layer::kDirect).at(x, y, c) + f.layer(layer::kIndirect).at(x, y, c)) * f.layer(layer::kAlbedo).at(x, y, c);
      // A firefly is one sample's excess: the pairs' variance of the mean is about its square.
      const float excess = f.layer(layer::kColor).at(x, y, c) - before;
      f.layer(layer::kVariance).at(x, y, c) = excess * excess;
    }
  }
  const Image cut = run("proposed", f, {{"firefly_ratio", "3"}});
  const Image kept = run("proposed", f, {{"firefly_ratio", "0"}});
  const double e_cut = test::mse(cut, clean), e_kept = test::mse(kept, clean);
  // Mean excess over the clean image around the fireflies (not at them), relative to clean.
  auto halo = [&](const Image& im) {
    double sum = 0;
    int n = 0;
    for (auto [x, y] : spots)
      for (int dy = -4; dy <= 4; ++dy)
        for (int dx = -4; dx <= 4; ++dx)
          if (dx || dy)
            for (int c = 0; c < 3; ++c, ++n) sum += im.at(x + dx, y + dy, c) / clean.at(x + dx, y + dy, c) - 1.0;
    return sum / n;
  };
  const double h_cut = halo(cut), h_kept = halo(kept);
  RecordProperty("mse_cut", sci(e_cut));
  RecordProperty("mse_kept", sci(e_kept));
  RecordProperty("halo_cut", sci(h_cut));
  RecordProperty("halo_kept", sci(h_kept));
  EXPECT_LT(e_cut, e_kept / 3) << "cut " << e_cut << " kept " << e_kept;
  EXPECT_GT(h_kept, 0.0) << "no halo without the cut: the test frame does not show the effect";
  EXPECT_LT(std::abs(h_cut), 0.1 * h_kept) << "halo with the cut " << h_cut << ", without " << h_kept;
}

// Every ablation switch changes the output (each part is wired in).
TEST(Proposed, AblationSwitchesChangeTheOutput) {
  Image clean;
  std::vector<char> g;
  AovFrame f = edge_frame(64, 48, 0.2f, &clean, &g);
  for (int y = 0; y < 48; ++y)  // some reflection, so that the reflection switch matters
    for (int x = 0; x < 64; ++x)
      for (int c = 0; c < 3; ++c) {
        f.layer(layer::at_level(1, layer::kTint)).at(x, y, c) = 0.2f;
        f.layer(layer::at_level(1, layer::kDirect)).at(x, y, c) = 0.5f + 0.1f * float((x * 7 + y * 3) % 5);
      }
  const Image base = run("proposed", f);
  for (const auto& [key, value] : std::vector<std::pair<std::string, std::string>>{
           {"nlm_space", "false"}, {"geometry", "false"}, {"edge_subpixels", "false"},
           {"reflections", "false"}, {"filter_color", "true"}}) {
    const Image other = run("proposed", f, {{key, value}});
    EXPECT_GT(test::mse(base, other), 1e-8) << key << "=" << value << " changed nothing";
  }
}

// A flat plane (one normal, one depth), albedo 0.5 unless given, lit by `light(x)` = {direct,
// indirect} with `noise` relative Gaussian noise on both; its colour, and the variance of the
// pixel's mean as the tracer writes it (the detail guard reads it). `clean` gets the noise-free
// colour.
template <class Light>
AovFrame lit_plane(int w, int h, float noise, Image* clean, std::uint64_t seed, Light light, float albedo = 0.5f) {
  AovFrame f = test::constant_frame(w, h);
  std::mt19937_64 rng(seed);
  std::normal_distribution<float> g(0.0f, 1.0f);
  *clean = Image(w, h, 3);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      for (int c = 0; c < 3; ++c) {
        const auto [dl, il] = light(x);
        const float dn = std::max(0.0f, dl * (1 + noise * g(rng))), in = std::max(0.0f, il * (1 + noise * g(rng)));
        f.layer(layer::kDirect).at(x, y, c) = dn;
        f.layer(layer::kIndirect).at(x, y, c) = in;
        f.layer(layer::kAlbedo).at(x, y, c) = albedo;
        f.layer(layer::kReflection).at(x, y, c) = 0;
        f.layer(layer::at_level(1, layer::kTint)).at(x, y, c) = 0;
        f.layer(layer::kColor).at(x, y, c) = (dn + in) * albedo;
        f.layer(layer::kVariance).at(x, y, c) = albedo * albedo * noise * noise * (dl * dl + il * il);
        clean->at(x, y, c) = (dl + il) * albedo;
      }
  return f;
}

// A shadow edge at x = w / 2: direct light 1.0 on the left, 0.1 on the right, indirect 0.2.
// Only the illumination shows the edge: the geometry guides cannot.
AovFrame shadow_frame(int w, int h, float noise, Image* clean, std::uint64_t seed) {
  return lit_plane(w, h, noise, clean, seed, [w](int x) { return std::pair{x < w / 2 ? 1.0f : 0.1f, 0.2f}; });
}

AovFrame crease_frame(int w, int h, Image* clean, std::uint64_t seed) {
  AovFrame f = test::constant_frame(w, h);
  f.meta.spp = 1;
  const float noise = 0.6f;
  std::mt19937_64 rng(seed);
  std::normal_distribution<float> g(0.0f, 1.0f);
  *clean = Image(w, h, 3);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const bool left = x < w / 2;
      f.layer(layer::kNormal).at(x, y, 0) = left ? 0.0f : 1.0f;
      f.layer(layer::kNormal).at(x, y, 1) = 0.0f;
      f.layer(layer::kNormal).at(x, y, 2) = left ? 1.0f : 0.0f;
      f.layer(layer::kDepth).at(x, y, 0) = left ? 2.0f : 4.0f;
      for (int c = 0; c < 3; ++c) {
        const float dl = left ? 0.5f : 0.2f, il = 0.2f, albedo = 0.5f;
        const float dn = std::max(0.0f, dl * (1 + noise * g(rng))), in = std::max(0.0f, il * (1 + noise * g(rng)));
        f.layer(layer::kDirect).at(x, y, c) = dn;
        f.layer(layer::kIndirect).at(x, y, c) = in;
        f.layer(layer::kAlbedo).at(x, y, c) = albedo;
        f.layer(layer::kReflection).at(x, y, c) = 0;
        f.layer(layer::at_level(1, layer::kTint)).at(x, y, c) = 0;
        f.layer(layer::kColor).at(x, y, c) = (dn + in) * albedo;
        clean->at(x, y, c) = (dl + il) * albedo;
      }
    }
  return f;
}

// Each ablation switch turns off a part that lowers the error where that part matters (issue
// 28, point 7), not only one that changes the output: the MSE against the noise-free colour,
// summed over three noise seeds, is at most half with the part on (measured: nlm_space 1/30,
// geometry 1/3, filter_color 1/130, each seed alike; half leaves room for other noise draws
// while a part that did nothing, ratio 1, fails).
//   nlm_space    a shadow edge that only the illumination shows (shadow_frame), whole frame
//   geometry     a crease the geometry shows and the noisy 1-spp illumination hardly does
//                (crease_frame), on the 12 columns around it: away from the crease both sides
//                are flat and the geometry has nothing to add (whole frame: measured 1/1.4)
//   filter_color (true turns off filtering the untextured illumination) on the textured plane
TEST(Proposed, EachAblatedPartLowersTheErrorWhereItMatters) {
  constexpr int w = 64, h = 48;
  std::vector<char> everywhere(std::size_t(w) * h, 1), crease(std::size_t(w) * h, 0);
  for (int y = 0; y < h; ++y)
    for (int x = w / 2 - 6; x < w / 2 + 6; ++x) crease[std::size_t(y) * w + x] = 1;  // +-1.5 sigma_s
  struct Case {
    const char* key;
    const char* off;
    std::function<AovFrame(Image*, std::uint64_t)> frame;
    const std::vector<char>& where;
  };
  const std::vector<Case> cases = {
      {"nlm_space", "false", [](Image* clean, std::uint64_t seed) { return shadow_frame(w, h, 0.3f, clean, seed); }, everywhere},
      {"geometry", "false", [](Image* clean, std::uint64_t seed) { return crease_frame(w, h, clean, seed); }, crease},
      {"filter_color", "true", [](Image* clean, std::uint64_t seed) { return textured_plane(w, h, 0.3f, clean, seed); }, everywhere},
  };
  for (const auto& c : cases) {
    double on = 0, off = 0, input = 0;
    for (std::uint64_t seed : {21, 22, 23}) {
      Image clean;
      const AovFrame f = c.frame(&clean, seed);
      on += mse_on(run("proposed", f), clean, c.where);
      off += mse_on(run("proposed", f, {{c.key, c.off}}), clean, c.where);
      input += mse_on(f.layer(layer::kColor), clean, c.where);
    }
    RecordProperty(std::string("mse_with_") + c.key, sci(on / 3));
    RecordProperty(std::string("mse_without_") + c.key, sci(off / 3));
    EXPECT_GT(on, 0.0) << c.key;
    // With every part on, most of the noise goes (measured 1/30 of the input's error or less).
    EXPECT_LT(on, 0.1 * input) << c.key << ": the filter with every part does not denoise the frame";
    EXPECT_LT(on, 0.5 * off) << c.key << " on: " << on / 3 << ", off: " << off / 3;
  }
}

// The detail guard (it keeps thin dark features): a one-pixel dark groove across a noisy lit wall
// (its light 12x lower: occluded; the same normal and depth, so the guide barely sees it) is
// filled with the wall's light by the filter alone; with the guard, each pixel's change is
// held within 3 standard deviations of its mean (the variance layer, honest here as the
// tracer's), so the groove stays darker, and the wall around it is as smooth as without it.
TEST(Proposed, DetailGuardKeepsAOnePixelGroove) {
  const int w = 96, h = 64, gx = 47;
  Image clean;
  const AovFrame f = lit_plane(w, h, 0.15f, &clean, 21, [](int x) {
    return x == gx ? std::pair{0.05f, 0.03f} : std::pair{0.6f, 0.2f};
  }, 0.7f);
  auto groove = [&](const Image& im) {  // the groove's mean over its clean value
    double s = 0;
    for (int y = 4; y < h - 4; ++y) s += im.at(gx, y, 1) / clean.at(gx, y, 1);
    return s / (h - 8);
  };
  auto wall_mse = [&](const Image& im) {  // the wall away from the groove and the borders
    double s = 0;
    int n = 0;
    for (int y = 4; y < h - 4; ++y)
      for (int x = 4; x < w - 4; ++x)
        if (std::abs(x - gx) > 6) s += std::pow(im.at(x, y, 1) - clean.at(x, y, 1), 2), ++n;
    return s / n;
  };
  const Image on = run("proposed", f, {{"detail_guard", "3"}});
  const Image off = run("proposed", f, {{"detail_guard", "0"}});
  RecordProperty("groove_on", sci(groove(on)));
  RecordProperty("groove_off", sci(groove(off)));
  RecordProperty("wall_mse_on", sci(wall_mse(on)));
  RecordProperty("wall_mse_off", sci(wall_mse(off)));
  RecordProperty("wall_mse_input", sci(wall_mse(f.layer(layer::kColor))));
  // Measured: the groove at 2.83x its clean value without the guard, 2.17x with it (its band is
  // widened by the relative-variance floor, which scales the neighbours' relative variance by
  // the filtered value, too bright here; without that floor the training scenes lose 5-8% at
  // 16 spp: docs/method-defaults.md, "Detail guard"); the wall's mse 4.18e-5 and 4.23e-5.
  EXPECT_GT(groove(off), 2.0) << "the filter alone did not fill the groove: the frame does not show the effect";
  EXPECT_LT(groove(on) - 1.0, 0.75 * (groove(off) - 1.0)) << "on " << groove(on) << " off " << groove(off);
  EXPECT_GT(groove(on), 0.9);
  EXPECT_LT(wall_mse(on), 1.05 * wall_mse(off));
}

}  // namespace
}  // namespace dnb
