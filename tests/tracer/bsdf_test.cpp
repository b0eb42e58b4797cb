// The hard materials' BSDFs (tracer/bsdf.h) on their own: Fresnel against closed forms,
// reciprocity, the sampler against the evaluator (one estimate of the directional albedo from
// the sampler's weights, another from eval() on uniformly spread directions, independent code
// paths), the sampler's density against pdf(), and the energy each lobe keeps (furnace).
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "tracer/bsdf.h"

namespace dnb::rt {
namespace {

Vec3 dir_from(float cos_theta, float phi) {
  const float s = std::sqrt(std::max(0.0f, 1 - cos_theta * cos_theta));
  return {s * std::cos(phi), s * std::sin(phi), cos_theta};
}

struct Albedo {
  double mean = 0, se = 0;
};
// The mean of n values and its standard error.
struct Accumulator {
  double s = 0, s2 = 0;
  void add(double w) {
    s += w;
    s2 += w * w;
  }
  Albedo result(int n) const {
    const double m = s / n;
    return {m, std::sqrt(std::max(0.0, s2 / n - m * m) / n)};
  }
};
struct Case {
  std::string name;
  HardBsdf bsdf;
};

HardBsdf conductor(float ax, float ay, bool schlick) {
  HardBsdf b;
  b.type = HardType::kConductor;
  b.ggx = {ax, ay};
  b.schlick = schlick;
  if (!schlick) {
    conductor_preset("Au", b.eta_c, b.k_c);
  } else {
    b.tint = Vec3(1.0f);
  }
  return b;
}
HardBsdf dielectric(float alpha, float eta) {
  HardBsdf b;
  b.type = HardType::kDielectric;
  b.ggx = {alpha, alpha};
  b.eta = eta;
  return b;
}
HardBsdf plastic(float alpha, float ior, Vec3 albedo) {
  HardBsdf b;
  b.type = HardType::kPlastic;
  b.ggx = {alpha, alpha};
  b.eta = ior;
  b.albedo = albedo;
  b.base_inner_reflectance = fresnel_diffuse_reflectance(1.0f / ior);
  b.base_inv_eta2 = 1.0f / (ior * ior);
  return b;
}

std::vector<Case> rough_cases() {
  return {{"conductor_iso_0.3", conductor(0.3f, 0.3f, false)},
          {"conductor_aniso_0.1_0.5", conductor(0.1f, 0.5f, false)},
          {"conductor_schlick_0.8", conductor(0.8f, 0.8f, true)},
          {"glass_in_0.2", dielectric(0.2f, 1.5f)},
          {"glass_out_0.4", dielectric(0.4f, 1.0f / 1.5f)},
          {"plastic_0.25", plastic(0.25f, 1.5f, Vec3(0.6f, 0.3f, 0.9f))}};
}

TEST(Fresnel, DielectricMatchesClosedFormsAndTotalInternalReflection) {
  // Normal incidence: ((eta - 1) / (eta + 1))^2 exactly.
  EXPECT_NEAR(fresnel_dielectric(1.0f, 1.5f), 0.04f, 1e-6f);
  EXPECT_NEAR(fresnel_dielectric(1.0f, 1.0f / 1.5f), 0.04f, 1e-6f);
  // Grazing: 1. Beyond the critical angle from inside (sin > 1 / 1.5): 1.
  EXPECT_NEAR(fresnel_dielectric(1e-6f, 1.5f), 1.0f, 1e-4f);
  EXPECT_EQ(fresnel_dielectric(0.5f, 1.0f / 1.5f), 1.0f);  // sin = 0.866 > 0.667
  // Brewster's angle, tan = eta: the p component vanishes, so F = rs^2 / 2.
  const float cb = std::cos(std::atan(1.5f));
  float ct = 0;
  const float f = fresnel_dielectric(cb, 1.5f, &ct);
  const float rs = (cb - 1.5f * ct) / (cb + 1.5f * ct);
  EXPECT_NEAR(f, 0.5f * rs * rs, 1e-6f);
  // Snell: sin_t = sin_i / eta.
  EXPECT_NEAR(std::sqrt(1 - ct * ct), std::sqrt(1 - cb * cb) / 1.5f, 1e-6f);
  // Hemispherical average: the known values 0.0918 (eta 1.5, outside) and 1 - (1 - 0.0918) / 1.5^2
  // = 0.5963 from inside (the two are tied by reciprocity: (1 - Fdr_in) eta^2 = 1 - Fdr_out).
  EXPECT_NEAR(fresnel_diffuse_reflectance(1.5f), 0.0918f, 2e-3f);
  EXPECT_NEAR(1 - fresnel_diffuse_reflectance(1 / 1.5f), (1 - fresnel_diffuse_reflectance(1.5f)) / 2.25f, 1e-3f);
}

TEST(Fresnel, ConductorMatchesTheDielectricWhenKIsZeroAndTheClosedFormAtNormalIncidence) {
  for (float c : {1.0f, 0.7f, 0.3f, 0.05f}) {
    const Vec3 f = fresnel_conductor(c, Vec3(1.5f), Vec3(0.0f));
    EXPECT_NEAR(f.x, fresnel_dielectric(c, 1.5f), 1e-5f) << c;
  }
  // ((n - 1)^2 + k^2) / ((n + 1)^2 + k^2) at normal incidence.
  Vec3 eta, k;
  ASSERT_TRUE(conductor_preset("Au", eta, k));
  const Vec3 f = fresnel_conductor(1.0f, eta, k);
  for (int c = 0; c < 3; ++c) {
    const float e = eta[c], kk = k[c];
    EXPECT_NEAR(f[c], ((e - 1) * (e - 1) + kk * kk) / ((e + 1) * (e + 1) + kk * kk), 1e-5f);
  }
  // Gold is yellow: red reflects more than blue.
  EXPECT_GT(f.x, f.z + 0.3f);
  EXPECT_FALSE(conductor_preset("Unobtainium", eta, k));
}

TEST(Ggx, DistributionIsNormalisedAndItsVisibleNormalsProjectToTheDirection) {
  // int D(m) cos_m dm = 1 (the microsurface projects onto the macrosurface), and
  // int G1(wo) max(0, wo.m) D(m) dm = cos_o (Heitz 2014, eq. 2 and 17: the visible microsurface
  // projects onto the plane orthogonal to wo); estimated over uniform directions, 5 standard errors.
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(0, 1);
  for (Ggx g : {Ggx{0.2f, 0.2f}, Ggx{0.5f, 0.5f}, Ggx{0.15f, 0.6f}, Ggx{1.0f, 1.0f}}) {
    const Vec3 wo = dir_from(0.6f, 1.1f);
    const int n = 400000;
    Accumulator projected, visible;
    for (int i = 0; i < n; ++i) {
      const Vec3 m = sample_sphere(u(rng), u(rng));
      projected.add(g.D(m) * std::max(0.0f, m.z) * 4 * kPi);
      visible.add(g.G1(wo) * std::max(0.0f, dot(wo, m)) * g.D(m) * 4 * kPi);
    }
    const Albedo a = projected.result(n), b = visible.result(n);
    EXPECT_NEAR(a.mean, 1.0, 5 * a.se) << g.ax << " " << g.ay;
    EXPECT_NEAR(b.mean, wo.z, 5 * b.se) << g.ax << " " << g.ay;
  }
}

TEST(Bsdf, IsReciprocal) {
  // Reflection: f(wo, wi) = f(wi, wo). Transmission (Veach 1997, 5.2.2 ff.): seen from the
  // other side the normal flips and eta becomes 1 / eta, and f(wi -> wo) / n_o^2 = f(wo -> wi) / n_i^2,
  // i.e. f(wo, wi) = f'(wi', wo') / eta^2 with ' the flipped frame. Relative tolerance 1e-3:
  // float rounding of half vectors and of Smith's square roots near grazing directions.
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(0, 1);
  for (const Case& c : rough_cases()) {
    int checked_r = 0, checked_t = 0;
    for (int i = 0; i < 4000; ++i) {
      const Vec3 wo = dir_from(0.05f + 0.95f * u(rng), 2 * kPi * u(rng));
      const Vec3 wi = dir_from((u(rng) * 2 - 1), 2 * kPi * u(rng));
      if (std::fabs(wi.z) < 0.05f) continue;
      const BsdfValue a = c.bsdf.eval(wo, wi);
      const Vec3 fa = a.diffuse_white * c.bsdf.albedo + a.glossy;
      if (wi.z > 0) {
        const BsdfValue b = c.bsdf.eval(wi, wo);
        const Vec3 fb = b.diffuse_white * c.bsdf.albedo + b.glossy;
        for (int ch = 0; ch < 3; ++ch) EXPECT_NEAR(fa[ch], fb[ch], 1e-3f * std::max(1.0f, fa[ch])) << c.name;
        checked_r += fa.x > 0;
      } else {
        HardBsdf flipped = c.bsdf;
        flipped.eta = 1.0f / c.bsdf.eta;
        const Vec3 fb = flipped.eval(Vec3(wi.x, wi.y, -wi.z), Vec3(wo.x, wo.y, -wo.z)).glossy;
        const float e2 = c.bsdf.eta * c.bsdf.eta;
        for (int ch = 0; ch < 3; ++ch)
          EXPECT_NEAR(fa[ch], fb[ch] / e2, 1e-3f * std::max(1.0f, fa[ch])) << c.name << " wo.z " << wo.z << " wi.z " << wi.z;
        checked_t += fa.x > 0;
      }
    }
    EXPECT_GT(checked_r, 500) << c.name;  // the test saw non-zero values
    if (c.bsdf.type == HardType::kDielectric) {
      EXPECT_GT(checked_t, 200) << c.name;
    }
  }
}

// The directional albedo sum_lobes int f |cos| dwi for wo, two ways: (sampled) the mean of
// sample() weights; (quadrature) eval() |cos| / (1 / 4pi) over uniform directions on the sphere.
Albedo sampled_albedo(const HardBsdf& b, Vec3 wo, int n, int channel, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(0, 1);
  Accumulator acc;
  for (int i = 0; i < n; ++i) {
    BsdfSample bs;
    double w = 0;
    if (b.sample(wo, u(rng), u(rng), u(rng), bs)) {
      w = bs.weight_diffuse_white[channel] * b.albedo[channel] + bs.weight_glossy[channel];
      if (!bs.delta) {
        // The sampler's density is pdf()'s, and its weight is eval() cos / pdf.
        EXPECT_NEAR(bs.pdf, b.pdf(wo, bs.wi), 2e-3f * bs.pdf + 1e-6f);
        const BsdfValue v = b.eval(wo, bs.wi);
        const double f = v.diffuse_white[channel] * b.albedo[channel] + v.glossy[channel];
        EXPECT_NEAR(w, f * std::fabs(bs.wi.z) / bs.pdf, 2e-3 * w + 1e-6);
      }
    }
    acc.add(w);
  }
  return acc.result(n);
}
Albedo quadrature_albedo(const HardBsdf& b, Vec3 wo, int n, int channel, unsigned seed, double* pdf_integral) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(0, 1);
  Accumulator acc;
  double p = 0;
  for (int i = 0; i < n; ++i) {
    const Vec3 wi = sample_sphere(u(rng), u(rng));
    const BsdfValue v = b.eval(wo, wi);
    acc.add((v.diffuse_white[channel] * b.albedo[channel] + v.glossy[channel]) * std::fabs(wi.z) * 4 * kPi);
    p += b.pdf(wo, wi) * 4 * kPi;
  }
  if (pdf_integral) *pdf_integral = p / n;
  return acc.result(n);
}

TEST(Bsdf, SamplerAgreesWithTheEvaluator) {
  // Both are unbiased estimates of one integral: they must agree within 5 combined standard
  // errors (a false alarm once in ~1.7 million comparisons). Broad lobes only: a narrow lobe
  // makes the uniform quadrature's variance explode.
  for (const Case& c : rough_cases()) {
    for (float cos_o : {0.9f, 0.5f, 0.2f}) {
      const Vec3 wo = dir_from(cos_o, 0.7f);
      for (int ch = 0; ch < 3; ch += 2) {
        const Albedo a = sampled_albedo(c.bsdf, wo, 100000, ch, 11);
        double pdf_integral = 0;
        const Albedo q = quadrature_albedo(c.bsdf, wo, 400000, ch, 12, &pdf_integral);
        EXPECT_NEAR(a.mean, q.mean, 5 * std::hypot(a.se, q.se)) << c.name << " cos_o " << cos_o << " ch " << ch;
        // The density integrates to at most 1 (samples may be lost below the surface).
        EXPECT_LT(pdf_integral, 1.02) << c.name;
        EXPECT_GT(pdf_integral, 0.5) << c.name;
      }
    }
  }
}

TEST(Bsdf, FurnaceKeepsWhatEachLobeMayKeep) {
  // A white conductor (Schlick tint 1: F = 1): the single-scattering albedo is E[G2 / G1],
  // exactly 1 when smooth, close to 1 when nearly smooth, and below 1 when rough, by the
  // share of light the microfacets send into each other (GGX single scattering loses it).
  const Vec3 wo = dir_from(0.8f, 0.3f);
  BsdfSample bs;
  {
    const HardBsdf smooth = conductor(0, 0, true);
    ASSERT_TRUE(smooth.sample(wo, 0.5f, 0.5f, 0.5f, bs));
    EXPECT_TRUE(bs.delta);
    EXPECT_EQ(bs.weight_glossy.x, 1.0f);
  }
  const double a01 = sampled_albedo(conductor(0.05f, 0.05f, true), wo, 20000, 0, 3).mean;
  const double a05 = sampled_albedo(conductor(0.5f, 0.5f, true), wo, 20000, 0, 3).mean;
  const double a10 = sampled_albedo(conductor(1.0f, 1.0f, true), wo, 20000, 0, 3).mean;
  EXPECT_GT(a01, 0.995);
  EXPECT_LE(a01, 1.0 + 1e-6);
  EXPECT_LT(a05, a01);
  EXPECT_LT(a10, a05);
  EXPECT_GT(a10, 0.2);  // GGX at alpha 1 loses up to ~60% in one bounce (Kulla and Conty 2017); here 0.35
  // A smooth dielectric: R + T = 1, counted without the radiance scaling 1 / eta^2 of refraction.
  for (float eta : {1.5f, 1.0f / 1.5f}) {
    const HardBsdf glass = dielectric(0, eta);
    double sum = 0;
    const int n = 20000;
    std::mt19937 rng(5);
    std::uniform_real_distribution<float> u(0, 1);
    for (int i = 0; i < n; ++i) {
      ASSERT_TRUE(glass.sample(wo, u(rng), u(rng), u(rng), bs));
      sum += bs.weight_glossy.x * (bs.transmitted ? eta * eta : 1.0f);
    }
    EXPECT_NEAR(sum / n, 1.0, 1e-6) << eta;
  }
  // A rough dielectric loses only what its microfacets shadow: between 0.9 and 1 at alpha 0.2.
  {
    const HardBsdf glass = dielectric(0.2f, 1.5f);
    double sum = 0;
    const int n = 40000;
    std::mt19937 rng(6);
    std::uniform_real_distribution<float> u(0, 1);
    for (int i = 0; i < n; ++i)
      if (glass.sample(wo, u(rng), u(rng), u(rng), bs)) sum += bs.weight_glossy.x * (bs.transmitted ? 2.25f : 1.0f);
    EXPECT_GT(sum / n, 0.9);
    EXPECT_LT(sum / n, 1.0 + 1e-3);
  }
  // Plastic, its two lobes apart. The base alone (albedo 1, coat tint 0): light enters through
  // 1 - F(cos_i), is reflected inside with 1 / (1 - Fdr_in) summing the internal bounces, leaves
  // through 1 - F(cos_o) and is spread by 1 / eta^2; with (1 - Fdr_in) eta^2 = 1 - Fdr_out the
  // base returns exactly 1 - F(cos_o), whatever the coat's roughness (the base's model is the
  // smooth coat's). The coat alone (albedo 0, tint 1): F(cos_o) when smooth; rough, below it by
  // what its microfacets shadow and by F(wo.m) < F(wo) averaged, most facets it sees face wo more
  // squarely than the surface does; measured 46% of F at alpha 0.4 and cos 0.4: bound at 35% (so the material as a whole keeps 1 - F(cos_o) + that, not 1).
  for (float alpha : {0.0f, 0.1f, 0.4f}) {
    for (float cos_o : {0.9f, 0.4f}) {
      const Vec3 wo2 = dir_from(cos_o, 0.1f);
      HardBsdf base = plastic(alpha, 1.5f, Vec3(1.0f));
      base.tint = Vec3(0.0f);
      const Albedo b = sampled_albedo(base, wo2, 100000, 0, 9);
      const double f = fresnel_dielectric(cos_o, 1.5f);
      EXPECT_NEAR(b.mean, 1.0 - f, 2e-3 + 5 * b.se) << "base, alpha " << alpha << " cos " << cos_o;
      const Albedo c = sampled_albedo(plastic(alpha, 1.5f, Vec3(0.0f)), wo2, 100000, 0, 10);
      if (alpha == 0) {
        EXPECT_NEAR(c.mean, f, 5 * c.se) << "smooth coat, cos " << cos_o;
      }
      EXPECT_LT(c.mean, f + 5 * c.se) << "coat, alpha " << alpha << " cos " << cos_o;
      EXPECT_GT(c.mean, 0.35 * f) << "coat, alpha " << alpha << " cos " << cos_o;
    }
  }
}

TEST(Bsdf, ThinSheetTransmitsStraightThroughAndSumsItsInterreflections) {
  HardBsdf sheet = dielectric(0, 1.5f);
  sheet.thin = true;
  const Vec3 wo = dir_from(1.0f, 0);
  // At normal incidence R = 0.04 per face; the sheet reflects 2R / (1 + R) = 0.0769.
  int reflected = 0;
  const int n = 100000;
  std::mt19937 rng(2);
  std::uniform_real_distribution<float> u(0, 1);
  for (int i = 0; i < n; ++i) {
    BsdfSample bs;
    ASSERT_TRUE(sheet.sample(wo, u(rng), u(rng), u(rng), bs));
    if (bs.transmitted) {
      EXPECT_NEAR(bs.wi.z, -1.0f, 1e-6f);
      EXPECT_EQ(bs.weight_glossy.x, 1.0f);
    } else {
      ++reflected;
    }
  }
  // Binomial: standard error sqrt(p (1 - p) / n) = 8.4e-4; 5 of them.
  EXPECT_NEAR(double(reflected) / n, 2 * 0.04 / 1.04, 5 * 8.4e-4);
}

}  // namespace
}  // namespace dnb::rt
