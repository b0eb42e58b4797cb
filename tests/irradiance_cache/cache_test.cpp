// The irradiance cache without the tracer: gathers through analytic radiance callbacks, records,
// gradients against closed forms, the octree against brute force, the error weight's angle.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <set>

#include "core/errors.h"
#include "irradiance_cache/cache.h"

namespace dnb::ic {
namespace {

constexpr float kPi = rt::kPi;

// A constant radiance L from every direction, everything at distance d.
IncomingFn constant(Vec3 L, float d) {
  return [=](Vec3, int) { return GatherSample{L, d}; };
}

TEST(Gather, WhiteFurnaceGivesExactIrradiance) {
  // Every cell carries 1 / (MN) of the cosine-weighted hemisphere, so a constant L gives
  // E = pi L exactly, whatever M, N and the jitter; radiance differences are exactly 0, so the
  // translational gradient is 0; the rotational one sums tan(theta) v_k over a full circle of
  // azimuths, 0 up to float rounding (1e-4 of E: M N terms of size up to tan(theta_max) E).
  const Vec3 L(0.7f, 0.5f, 0.3f);
  std::mt19937 gen(3);
  std::uniform_real_distribution<float> u01(0.0f, 0.999f);
  for (auto [M, N] : {std::pair{1, 1}, std::pair{4, 12}, std::pair{16, 48}}) {
    GatherResult g = gather(rt::normalize(Vec3(0.3f, 0.8f, -0.2f)), M, N, constant(L, 2.0f),
                            [&](int) { return std::array<float, 2>{u01(gen), u01(gen)}; });
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(g.irradiance[c], kPi * L[c], 1e-6f * kPi * L[c]) << M << "x" << N;
    for (int a = 0; a < 3; ++a)
      for (int c = 0; c < 3; ++c) {
        EXPECT_EQ(g.trans_grad[a][c], 0.0f);
        if (N > 1) {  // one azimuth cannot cancel
          EXPECT_NEAR(g.rot_grad[a][c], 0.0f, 1e-4f * kPi * L[c]);
        }
      }
    EXPECT_NEAR(g.harmonic_mean_distance, 2.0f, 1e-5f);
    EXPECT_EQ(g.min_distance, 2.0f);
  }
}

// The gather clamp (a rare bright path caught by one cell). 16 x 32 cells of radiance 1, one
// of 1e5: unclamped E = pi (511 + 1e5) / 512, 196x the rest's. With clamp_ratio 10 the bound
// is taken three times from the mean (196.3 -> 4.83 -> 1.09), so the cell ends at 10.9 and E
// at pi (511 + 10.9) / 512 = 1.019 pi; the one cell is reported. A constant gather (white
// furnace) and a broad bright region (a tenth of the cells at 20x: a caustic seen by many
// cells) are not touched at ratio 300.
TEST(Gather, ClampCutsOneBrightCellButNotBroadLight) {
  const Vec3 n(0.0f, 0.0f, 1.0f);
  auto one_bright = [](Vec3, int cell) { return GatherSample{Vec3(cell == 77 ? 1e5f : 1.0f), 3.0f}; };
  int cut = -1;
  const GatherResult raw = gather(n, 16, 32, one_bright, nullptr, 0.0f, &cut);
  EXPECT_EQ(cut, 0);
  EXPECT_NEAR(raw.irradiance[0], kPi * (511.0f + 1e5f) / 512.0f, 1e-3f * raw.irradiance[0]);
  const GatherResult clamped = gather(n, 16, 32, one_bright, nullptr, 10.0f, &cut);
  EXPECT_EQ(cut, 1);
  const double m1 = (511.0 + 1e5) / 512, b1 = 10 * m1, m2 = (511 + b1) / 512, b2 = 10 * m2, m3 = (511 + b2) / 512;
  const double expected = kPi * (511 + 10 * m3) / 512;
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(clamped.irradiance[c], expected, 1e-5 * expected);

  const GatherResult furnace = gather(n, 16, 32, constant(Vec3(0.7f, 0.5f, 0.3f), 2.0f), nullptr, 300.0f, &cut);
  EXPECT_EQ(cut, 0);
  EXPECT_NEAR(furnace.irradiance[0], kPi * 0.7f, 1e-6f * kPi);
  auto broad = [](Vec3, int cell) { return GatherSample{Vec3(cell % 10 == 0 ? 20.0f : 1.0f), 3.0f}; };
  const GatherResult b0 = gather(n, 16, 32, broad, nullptr, 0.0f, nullptr);
  const GatherResult b1g = gather(n, 16, 32, broad, nullptr, 300.0f, &cut);
  EXPECT_EQ(cut, 0);
  EXPECT_EQ(b0.irradiance[0], b1g.irradiance[0]);
}

TEST(Cache, WhiteFurnaceInterpolatesExactly) {
  // Records of a constant environment interpolate to the same constant anywhere they apply:
  // sum w E / sum w with equal E (gradient terms ~1e-6 of E, see above).
  const Vec3 L(1.0f, 2.0f, 0.5f);
  IrradianceCache cache(Vec3(-1.0f), Vec3(1.0f), {});
  const Vec3 n(0, 0, 1);
  for (int i = 0; i < 5; ++i)
    cache.insert(Vec3(0.1f * i, 0.05f * i, 0), n, gather(n, 8, 24, constant(L, 0.3f)), {0.0f, 1e30f});
  int hits = 0;
  for (float x = -0.2f; x < 0.7f; x += 0.05f) {
    Vec3 e;
    if (!cache.interpolate(Vec3(x, 0.02f, 0), rt::normalize(Vec3(0.05f, 0, 1)), e)) continue;
    ++hits;
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(e[c], kPi * L[c], 1e-5f * kPi * L[c]);
  }
  EXPECT_GT(hits, 10);
}

// A receiver at (x, 0, 0) with normal +z under an infinite ceiling at height h whose radiance is
// L1 for x' > 0 and L0 for x' < 0. By Nusselt's analogue the half-plane beyond an edge subtends
// a projected solid angle pi / 2 (1 + s), s = x / sqrt(x^2 + h^2), hence
//   E(x) = pi L0 + (L1 - L0) pi / 2 (1 + x / sqrt(x^2 + h^2)),
//   dE/dx = (L1 - L0) pi / 2 h^2 / (x^2 + h^2)^(3/2),  dE/dy = 0.
struct HalfBrightCeiling {
  float h = 1.0f, L0 = 0.2f, L1 = 1.0f;
  IncomingFn at(float x) const {
    return [=, *this](Vec3 d, int) {
      float t = h / d.z;
      return GatherSample{Vec3(x + t * d.x > 0 ? L1 : L0), t};
    };
  }
  float E(float x) const { return kPi * L0 + (L1 - L0) * kPi / 2 * (1 + x / std::sqrt(x * x + h * h)); }
  float dEdx(float x) const { return (L1 - L0) * kPi / 2 * h * h / std::pow(x * x + h * h, 1.5f); }
};

TEST(Gradients, TranslationalMatchesTheClosedFormDerivative) {
  HalfBrightCeiling c;
  for (float x : {-0.8f, -0.3f, 0.0f, 0.4f, 1.2f}) {
    GatherResult g = gather(Vec3(0, 0, 1), 32, 96, c.at(x));
    // The stratified estimate of E itself: cells straddling the edge are resolved to 1/(MN).
    EXPECT_NEAR(g.irradiance.x, c.E(x), 0.01f * c.E(x)) << x;
    // Ward-Heckbert / Krivanek's estimator resolves the edge's motion to the cell size:
    // 32 x 96 cells give a few per cent; 8% of the peak derivative covers it.
    const float peak = c.dEdx(0.0f);
    EXPECT_NEAR(g.trans_grad[0].x, c.dEdx(x), 0.08f * peak) << "x = " << x;
    EXPECT_NEAR(g.trans_grad[1].x, 0.0f, 0.08f * peak) << "x = " << x;
    // And against a central finite difference of the closed-form irradiance.
    const float eps = 1e-3f;
    EXPECT_NEAR(g.trans_grad[0].x, (c.E(x + eps) - c.E(x - eps)) / (2 * eps), 0.08f * peak) << "x = " << x;
  }
}

TEST(Gradients, TranslationalMatchesFiniteDifferencesOfGatheredIrradiance) {
  // The same configuration seen by the cache itself: extrapolating a record by its gradient
  // predicts a second gather's irradiance a small step away better than the constant does.
  HalfBrightCeiling c;
  const float x = -0.25f, step = 0.05f;
  GatherResult g0 = gather(Vec3(0, 0, 1), 32, 96, c.at(x));
  GatherResult g1 = gather(Vec3(0, 0, 1), 32, 96, c.at(x + step));
  const float fd = (g1.irradiance.x - g0.irradiance.x) / step;
  // The finite difference of two estimates carries their stratification error (1% of E each,
  // over the step): 15% of the derivative.
  EXPECT_NEAR(g0.trans_grad[0].x, fd, 0.15f * std::abs(fd));
}

TEST(Gradients, RotationalMatchesTheClosedFormDerivative) {
  // An environment of radiance L1 where x > 0 and L0 elsewhere, normal n = (sin a, 0, cos a):
  //   E(a) = pi L0 + (L1 - L0) pi / 2 (1 + sin a),  dE/da (0) = (L1 - L0) pi / 2.
  // Rotating n from z towards x by a gives n_i x n = (0, sin a, 0), so the rotational gradient's
  // y component must equal dE/da.
  const float L0 = 0.3f, L1 = 1.5f;
  IncomingFn env = [=](Vec3 d, int) { return GatherSample{Vec3(d.x > 0 ? L1 : L0), 1e30f}; };
  auto E = [=](float a) { return kPi * L0 + (L1 - L0) * kPi / 2 * (1 + std::sin(a)); };
  GatherResult g = gather(Vec3(0, 0, 1), 32, 96, env);
  const float expected = (L1 - L0) * kPi / 2;
  // Strata aligned with the environment's edge (96 azimuths put one boundary on phi = pi / 2)
  // and per-stratum tangent means: the only error is the cell-centre azimuth, 1 - sinc(pi/96)
  // ~ 2e-4; 1% leaves room for float sums.
  EXPECT_NEAR(g.rot_grad[1].x, expected, 0.01f * expected);
  EXPECT_NEAR(g.rot_grad[0].x, 0.0f, 0.01f * expected);
  EXPECT_NEAR(g.rot_grad[2].x, 0.0f, 1e-5f);  // no rotation about the normal itself
  const float eps = 1e-3f;
  EXPECT_NEAR(g.rot_grad[1].x, (E(eps) - E(-eps)) / (2 * eps), 0.01f * expected);
  // Nothing escapes to a finite distance: no radius information, no translational gradient.
  EXPECT_EQ(g.harmonic_mean_distance, 1e30f);
  EXPECT_EQ(g.trans_grad[0].x, 0.0f);
}

TEST(Cache, ExtrapolationIsClampedToNonNegative) {
  IrradianceCache cache(Vec3(-2.0f), Vec3(2.0f), {});
  GatherResult g;
  g.irradiance = Vec3(1.0f);
  g.trans_grad[0] = Vec3(-100.0f);  // would drive E far below 0 a short step along +x
  g.harmonic_mean_distance = 1.0f;
  CacheSettings s;
  s.use_gradients = true;
  // No pixel bounds (which would scale the gradient down, see below): the radius is the
  // gradient limit 0.01 and the point 0.1 away would get 1 - 10 = -9.
  std::size_t i = cache.insert(Vec3(0.0f), Vec3(0, 0, 1), g, {0.0f, 1e30f});
  Vec3 e = cache.extrapolate(cache.records()[i], Vec3(0.1f, 0, 0), Vec3(0, 0, 1));
  EXPECT_EQ(e.x, 0.0f);
  EXPECT_GE(e.y, 0.0f);
}

TEST(Cache, RadiusIsLimitedByGradientPixelBoundsAndNeighbours) {
  IrradianceCache cache(Vec3(-2.0f), Vec3(2.0f), {});
  GatherResult g;
  g.irradiance = Vec3(2.0f);
  g.harmonic_mean_distance = 1.0f;
  g.trans_grad[0] = Vec3(10.0f);  // E / |grad| = 0.2
  std::size_t a = cache.insert(Vec3(0.0f), Vec3(0, 0, 1), g, {0.0f, 1e30f});
  EXPECT_NEAR(cache.records()[a].radius, 0.2f, 1e-6f);
  // Pixel bounds clamp the radius both ways.
  g.trans_grad[0] = Vec3(0.0f);
  std::size_t b = cache.insert(Vec3(1.5f, 0, 0), Vec3(0, 0, 1), g, {0.0f, 0.3f});
  EXPECT_NEAR(cache.records()[b].radius, 0.3f, 1e-6f);
  // Neighbour clamping: a record 0.1 from `a` gets at most R_a + 0.1 = 0.3 instead of 1.
  std::size_t c = cache.insert(Vec3(0.1f, 0, 0), Vec3(0, 0, 1), g, {0.0f, 1e30f});
  EXPECT_NEAR(cache.records()[c].radius, 0.3f, 1e-6f);
  // ... and a small new record shrinks an existing large neighbour: R_c <= R_d + |p_c - p_d|.
  g.harmonic_mean_distance = 0.02f;
  cache.insert(Vec3(0.2f, 0, 0), Vec3(0, 0, 1), g, {0.0f, 1e30f});
  EXPECT_NEAR(cache.records()[c].radius, 0.12f, 1e-6f);
}

// The pixel-footprint minimum can raise a radius above the gradient limit E / |grad_t E|; the
// gradient is then scaled so that the extrapolation changes E by at most E over the radius.
// E = 2, gradient 10 along x (limit 0.2), minimum radius 1: the gradient becomes 2, so E
// extrapolates to 4 at +1 and 0 at -1 (unscaled: 12 and -8).
TEST(Cache, GradientScaledWhenThePixelBoundRaisesTheRadius) {
  IrradianceCache cache(Vec3(-4.0f), Vec3(4.0f), {});
  GatherResult g;
  g.irradiance = Vec3(2.0f);
  g.harmonic_mean_distance = 5.0f;
  g.trans_grad[0] = Vec3(10.0f);
  const std::size_t i = cache.insert(Vec3(0.0f), Vec3(0, 0, 1), g, {1.0f, 1e30f});
  const Record& r = cache.records()[i];
  EXPECT_NEAR(r.radius, 1.0f, 1e-6f);
  EXPECT_NEAR(r.trans_grad[0].x, 2.0f, 1e-5f);
  EXPECT_NEAR(cache.extrapolate(r, Vec3(1.0f, 0, 0), Vec3(0, 0, 1)).x, 4.0f, 1e-5f);
  EXPECT_NEAR(cache.extrapolate(r, Vec3(-1.0f, 0, 0), Vec3(0, 0, 1)).x, 0.0f, 1e-5f);
  // Within its own limit (no raise) the gradient is kept as gathered.
  const std::size_t j = cache.insert(Vec3(3.0f, 0, 0), Vec3(0, 0, 1), g, {0.0f, 1e30f});
  EXPECT_NEAR(cache.records()[j].radius, 0.2f, 1e-6f);
  EXPECT_EQ(cache.records()[j].trans_grad[0].x, 10.0f);
}

TEST(Cache, AngleThresholdIsInRadians) {
  // With kappa = 1 a record applies at its own position up to max_angle_degrees of normal
  // deviation. pbrt-v2 passed degrees where radians were meant (cos(Degrees(10))), which would
  // make this threshold meaningless; 9 degrees must pass and 11 must not.
  CacheSettings s;
  s.kappa = 1.0f;
  s.max_angle_degrees = 10.0f;
  IrradianceCache cache(Vec3(-1.0f), Vec3(1.0f), s);
  GatherResult g;
  g.irradiance = Vec3(1.0f);
  g.harmonic_mean_distance = 0.5f;
  cache.insert(Vec3(0.0f), Vec3(0, 0, 1), g, {0.0f, 1e30f});
  auto tilted = [](float deg) {
    float a = deg * kPi / 180.0f;
    return Vec3(std::sin(a), 0, std::cos(a));
  };
  EXPECT_GT(cache.weight(cache.records()[0], Vec3(0.0f), tilted(9.0f)), 0.0f);
  EXPECT_EQ(cache.weight(cache.records()[0], Vec3(0.0f), tilted(11.0f)), 0.0f);
  // And the position term: kappa * d / R < 1.
  EXPECT_GT(cache.weight(cache.records()[0], Vec3(0.49f, 0, 0), Vec3(0, 0, 1)), 0.0f);
  EXPECT_EQ(cache.weight(cache.records()[0], Vec3(0.51f, 0, 0), Vec3(0, 0, 1)), 0.0f);
}

TEST(Octree, LookupEqualsBruteForce) {
  // Random records of radii from 1e-3 to 0.5 in a unit box (some reaching outside it, some
  // clamped later by neighbours), queried at random points inside and around the box.
  for (auto [kappa, clamp] : {std::pair{0.5f, true}, std::pair{1.0f, false}, std::pair{2.5f, true}}) {
    CacheSettings s;
    s.kappa = kappa;
    s.neighbor_clamp = clamp;
    IrradianceCache cache(Vec3(0.0f), Vec3(1.0f), s);
    std::mt19937 gen(11);
    std::uniform_real_distribution<float> u(0.0f, 1.0f);
    for (int i = 0; i < 3000; ++i) {
      GatherResult g;
      g.irradiance = Vec3(1.0f);
      g.harmonic_mean_distance = std::exp(std::log(1e-3f) + u(gen) * std::log(500.0f));
      Vec3 p(u(gen), u(gen), u(gen));
      if (i % 3 == 0) p = p * 0.05f + Vec3(0.3f);  // a dense cluster
      cache.insert(p, Vec3(0, 0, 1), g, {0.0f, 1e30f});
    }
    std::size_t total = 0;
    for (int q = 0; q < 3000; ++q) {
      Vec3 p(u(gen) * 1.4f - 0.2f, u(gen) * 1.4f - 0.2f, u(gen) * 1.4f - 0.2f);
      if (q % 3 == 0) p = p * 0.05f + Vec3(0.3f);
      auto fast = cache.lookup(p);
      ASSERT_EQ(fast, cache.lookup_brute_force(p)) << "query " << q << " kappa " << kappa;
      total += fast.size();
    }
    EXPECT_GT(total, 300u);  // the test exercises non-empty answers
  }
}

// Light-sample strata: with n = 16 every one of the 16 strata of u0 and every cell of the 4 x 4
// grid of (u1, u2) is hit exactly once per shading point, the pairing changes between points;
// with n = 5 (not a square) u1 takes each of 5 strata once.
TEST(LightStrata, EveryStratumOnceAndPairingsVary) {
  std::mt19937 gen(7);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  auto rng = [&] { return u(gen); };
  LightStrata s16(16);
  std::set<std::vector<int>> pairings;
  for (int point = 0; point < 20; ++point) {
    std::set<int> s0, cells;
    std::vector<int> pairing(16);
    for (int d = 0; d < 16; ++d) {
      const LightStrata::Numbers n = s16.next(d, rng);
      ASSERT_TRUE(n.u0 >= 0 && n.u0 < 1 && n.u1 >= 0 && n.u1 < 1 && n.u2 >= 0 && n.u2 < 1);
      s0.insert(int(n.u0 * 16));
      const int cell = int(n.u1 * 4) + 4 * int(n.u2 * 4);
      cells.insert(cell);
      pairing[std::size_t(int(n.u0 * 16))] = cell;
    }
    EXPECT_EQ(s0.size(), 16u);
    EXPECT_EQ(cells.size(), 16u);
    pairings.insert(pairing);
  }
  EXPECT_GT(pairings.size(), 15u);  // 20 random permutations of 16: repeats are vanishingly rare
  LightStrata s5(5);
  std::set<int> s1;
  for (int d = 0; d < 5; ++d) s1.insert(int(s5.next(d, rng).u1 * 5));
  EXPECT_EQ(s1.size(), 5u);
}

// The point of the strata: a light half hidden behind an edge (visible for u1 < 0.37) is
// estimated from 16 samples with far less variance than from 16 independent ones. Expected
// variances: independent p (1 - p) / 16 = 0.0146; stratified, only the grid column across the
// edge varies: 4 x 0.48 x 0.52 / 256 = 0.0039 (ratio 0.27). With 4000 trials the estimated
// variances are within a few per cent, so the bound 0.5 has a wide margin.
TEST(LightStrata, LowerVarianceAcrossAPenumbra) {
  std::mt19937 gen(11);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  auto rng = [&] { return u(gen); };
  auto var = [](const std::vector<double>& v) {
    double m = 0, q = 0;
    for (double x : v) m += x / double(v.size());
    for (double x : v) q += (x - m) * (x - m) / double(v.size() - 1);
    return q;
  };
  LightStrata strata(16);
  std::vector<double> strat, indep;
  for (int t = 0; t < 4000; ++t) {
    double a = 0, b = 0;
    for (int d = 0; d < 16; ++d) {
      a += strata.next(d, rng).u1 < 0.37f ? 1.0 / 16 : 0.0;
      b += rng() < 0.37f ? 1.0 / 16 : 0.0;
    }
    strat.push_back(a);
    indep.push_back(b);
  }
  RecordProperty("variance_ratio", std::to_string(var(strat) / var(indep)));
  EXPECT_LT(var(strat), 0.5 * var(indep)) << var(strat) << " vs " << var(indep);
}

TEST(Settings, BadValuesAreRefusedNamingTheParameter) {
  CacheSettings s;
  s.kappa = 0;
  try {
    s.validate();
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("kappa"), std::string::npos);
  }
  s = {};
  s.max_angle_degrees = -3;
  EXPECT_THROW(s.validate(), InputError);
  EXPECT_THROW(gather(Vec3(0, 0, 1), 0, 4, constant(Vec3(1.0f), 1.0f)), InputError);
}

}  // namespace
}  // namespace dnb::ic
