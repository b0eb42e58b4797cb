// The tracer against a real renderer: each hard material and the thin lens rendered by the tracer
// and by Mitsuba 3 (scalar_rgb, the project's .venv) from the same scene, exported by
// tracer/mitsuba_export.h, and compared block by block; and the exporter's refusals.
//
// Statistics. Each frame is 32 x 24 pixels, cut into 12 blocks of 8 x 8. Per block and channel,
// both renderers give a mean and the variance of that mean, each from 8 independent estimates
// per pixel (the tracer's 8 sample groups; 8 Mitsuba renders of different seeds,
// python/mitsuba_render.py), summed over the block's 64 independent pixels: about 448 degrees of
// freedom per side, so the difference over its combined standard error is normal to within a few
// percent in the tails. A block passes when
//     |tracer - mitsuba| <= 5 sigma + bias + 1e-5 max(tracer, mitsuba)
// 5 sigma: a two-sided normal tail of 5.7e-7 per comparison; 9 cases x 12 blocks x 3 channels
// = 324 comparisons make a false alarm about 2e-4 per run (Bonferroni). 1e-5 relative: float
// rounding where both sides are exact (sky-only blocks have zero variance in both). `bias` is the
// known model difference of the case, derived below; zero where both renderers have the same model.
//
// Known model differences (tracer/mitsuba_export.h), bounded, not tolerated by looser sigmas:
// the rough cases use a layout in which every path meets the material at most once: a single
// quad of it as the floor, lit by a constant sky and by one quad light of albedo 0 (a path ends
// on it), nothing else. A pixel's radiance is then the integral of f(wo, wi) L_in(wi) |cos| over
// wi at the first hit, with L_in at most Lmax (the larger of sky and light, per channel), so the
// two renderers differ by at most
//     Lmax * Delta(wo),  Delta(wo) = int |f_tracer(wo, wi) - f_mitsuba(wo, wi)| |cos_i| dwi,
// and a block by the largest Delta over the camera rays through its pixels' corners (Delta is
// smooth in wo; the corners include the block's most grazing rays, where it is largest), times
// 1.1 for the quadrature and that interpolation. Delta is computed here by quadrature from the
// tracer's own Ggx and Fresnel functions:
//   - microfacet lobes: f_mitsuba = f_tracer * G1(wo) G1(wi) / G2(wo, wi) (Mitsuba's separable
//     masking, include/mitsuba/render/microfacet.h G()), so with visible normals m of wo,
//     Delta_spec = E_m[F (G2 / G1(wo) - G1(wr))] + E_m[(1 - F) (G2 / G1(wo) - G1(wt)) / eta^2] T,
//     every term non-negative (G2 >= G1 G1);
//   - plastic base: Mitsuba's is a t(ci) t(co) / (pi eta^2 (1 - a R)) with, for roughplastic,
//     t(c) = E_m[(1 - F) G1(wt)] (microfacet.h eval_transmittance) and R = 2 mean_mu(mu E_m[F
//     G1(wr)]) at 1 / eta over 64 cosines (src/bsdfs/roughplastic.cpp), for plastic t = 1 - F and
//     R = Mitsuba's fitted Fdr (render/fresnel.h); the tracer's has 1 - F and its quadrature Fdr.
//     Checked during development against Mitsuba 3.5.2's own roughplastic eval of the diffuse
//     component (ior 1.5; Mitsuba / this quadrature): alpha 0.15: R 0.5208 / 0.5207, t(1)
//     0.9587 / 0.9589, t(0.5) / t(1) 0.9420 / 0.9421; alpha 0.3: R 0.4148 / 0.4150, t(1) 0.9532 /
//     0.9537 (the smooth coat's 1 - F(1) is 0.96 and Fdr 0.596: at alpha 0.15 and albedo 0.3 the
//     two bases differ by a few percent, which is why RoughPlastic's bound is the largest).
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <map>
#include <string>
#include <thread>
#include <vector>

#include <fmt/format.h>

#include "core/errors.h"
#include "core/json_file.h"
#include "test_util.h"
#include "tracer/bsdf.h"
#include "tracer/integrator.h"
#include "tracer/mitsuba_export.h"
#include "tracer/render.h"
#include "tracer/scene.h"
#include "tracer/scene_loader.h"
#include "tracer_scenes.h"

namespace dnb {
namespace {

using rt::Vec3;

constexpr int kWidth = 32, kHeight = 24, kBlock = 8, kSpp = 256, kSeeds = 8;
constexpr double kSigmas = 5.0;

// ---- Scenes ----------------------------------------------------------------------------------
// The camera looks down at the floor from the front right; the light is off-centre, so a
// mirrored or flipped image fails.
const char* kCamera = "[camera]\neye = [0.3, 1.4, 2.6]\nlook_at = [0, 0.1, 0]\nvfov = 40\n";
const char* kSky = "[sky]\ntype = \"constant\"\ncolor = [0.4, 0.5, 0.6]\n";
const char* kLight =
    "[[lights]]\ntype = \"quad\"\nsize = [1, 1]\nrotate = [180, 0, 0]\ntranslate = [0.6, 1.6, -0.4]\n"
    "emission = [3.0, 2.4, 1.8]\n";
const Vec3 kLmax{3.0f, 2.4f, 1.8f};  // the larger of sky and light per channel

// The single-hit layout: a floor of material `m` (the lines of [materials.m]), sky and light.
std::string floor_scene(const std::string& m) {
  return std::string(kCamera) + kSky + "[materials.m]\n" + m +
         "\n[[objects]]\ntype = \"quad\"\nmaterial = \"m\"\nsize = [3, 3]\n" + kLight;
}

// A diffuse floor and back wall with `objects` (their own materials) on it: multiple bounces.
std::string room_scene(const std::string& materials, const std::string& objects, const std::string& camera = kCamera) {
  return camera + kSky + "[materials.floor]\nalbedo = [0.6, 0.5, 0.4]\n[materials.wall]\nalbedo = [0.3, 0.5, 0.7]\n" +
         materials +
         "\n[[objects]]\ntype = \"quad\"\nmaterial = \"floor\"\nsize = [3, 3]\n"
         "[[objects]]\ntype = \"quad\"\nmaterial = \"wall\"\nsize = [3, 1.5]\nrotate = [90, 0, 0]\n"
         "translate = [0, 0.75, -1.5]\n" +
         objects + kLight;
}

enum class Bias { kNone, kFirstHit };

struct Case {
  const char* name;
  std::string toml;
  int max_depth;
  Bias bias;
};

std::vector<Case> cases() {
  return {
      {"RoughConductor", floor_scene("type = \"conductor\"\nmetal = \"Au\"\nroughness = 0.3"), 4, Bias::kFirstHit},
      {"AnisotropicRoughConductor",
       floor_scene("type = \"conductor\"\nmetal = \"Cu\"\nroughness_x = 0.4\nroughness_y = 0.1"), 4, Bias::kFirstHit},
      {"SmoothConductor",
       room_scene("[materials.metal]\ntype = \"conductor\"\neta = [0.2, 0.9, 1.1]\nk = [3.9, 2.4, 2.1]\n"
                  "tint = [1, 0.9, 0.8]\n",
                  "[[objects]]\ntype = \"box\"\nmaterial = \"metal\"\nsize = [0.8, 0.8, 0.8]\nrotate = [0, 30, 0]\n"
                  "translate = [-0.2, 0.4, 0]\n"),
       6, Bias::kNone},
      // The glass box stands 5 mm above the floor: resting on it, its bottom face and the floor
      // would be one plane, and a ray inside the glass would meet one or the other by each
      // renderer's own tie-break (about 12% in a band of pixels whose refracted rays reach the
      // bottom), a difference of ray-tracing kernels, not of the materials compared here.
      {"SmoothDielectric",
       room_scene("[materials.glass]\ntype = \"dielectric\"\nior = 1.5\ntransmittance = [0.9, 0.95, 1.0]\n",
                  "[[objects]]\ntype = \"box\"\nmaterial = \"glass\"\nsize = [0.8, 0.6, 0.8]\nrotate = [0, 25, 0]\n"
                  "translate = [-0.1, 0.305, 0.2]\n"),
       8, Bias::kNone},
      {"RoughDielectric",
       floor_scene("type = \"dielectric\"\nior = 1.5\nroughness = 0.3\ntransmittance = [0.8, 0.9, 1.0]"), 4,
       Bias::kFirstHit},
      {"ThinSheet",
       room_scene("[materials.pane]\ntype = \"dielectric\"\nthin = true\nior = 1.5\ntint = [1, 0.9, 0.8]\n"
                  "transmittance = [0.7, 0.9, 1.0]\n",
                  "[[objects]]\ntype = \"quad\"\nmaterial = \"pane\"\nsize = [1.2, 0.9]\nrotate = [90, 20, 0]\n"
                  "translate = [0.1, 0.45, 0.4]\n"),
       6, Bias::kNone},
      {"SmoothPlastic", floor_scene("type = \"plastic\"\nalbedo = [0.5, 0.3, 0.1]\nior = 1.5"), 4, Bias::kFirstHit},
      {"RoughPlastic", floor_scene("type = \"plastic\"\nalbedo = [0.3, 0.2, 0.1]\nior = 1.5\nroughness = 0.15"), 4,
       Bias::kFirstHit},
      {"ThinLens",
       room_scene("[materials.a]\nalbedo = [0.8, 0.2, 0.2]\n[materials.b]\nalbedo = [0.2, 0.8, 0.3]\n",
                  "[[objects]]\ntype = \"box\"\nmaterial = \"a\"\nsize = [0.4, 0.4, 0.4]\ntranslate = [-0.6, 0.2, 0.8]\n"
                  "[[objects]]\ntype = \"box\"\nmaterial = \"b\"\nsize = [0.4, 0.8, 0.4]\ntranslate = [0.5, 0.4, -0.9]\n",
                  "[camera]\neye = [0.3, 1.4, 2.6]\nlook_at = [0, 0.1, 0]\nvfov = 40\naperture_radius = 0.15\n"
                  "focus_distance = 2.0\n"),
       4, Bias::kNone},
  };
}

// ---- Model differences (see the top) -----------------------------------------------------------
// Mitsuba 3.5.2's fresnel_diffuse_reflectance for eta < 1 (Egan and Hilgeman's fit, the branch a
// plastic's internal Fdr takes: include/mitsuba/render/fresnel.h).
double mitsuba_fdr_below_one(double eta) { return 0.0636 / eta + eta * (eta * -1.4399 + 0.7099) + 0.6681; }

// Smith's masking from the tracer's Lambda, written out here rather than taken from Ggx::G1/G2, so
// that a break of the tracer's G2 moves its image but not the bound it is judged by.
double g1(const rt::Ggx& g, Vec3 w) { return 1.0 / (1.0 + g.lambda(w)); }
double g2(const rt::Ggx& g, Vec3 wo, Vec3 wi) { return 1.0 / (1.0 + g.lambda(wo) + g.lambda(wi)); }

constexpr int kQuad = 64;  // visible-normal quadrature: kQuad^2 midpoint nodes over (u1, u2)

// E_m[F G1(wr)] (reflect) or E_m[(1 - F) G1(wt)] (transmit) over the visible normals of w.
double rough_interface(const rt::Ggx& g, Vec3 w, float eta, bool transmit) {
  double sum = 0;
  for (int i = 0; i < kQuad; ++i)
    for (int j = 0; j < kQuad; ++j) {
      const Vec3 m = g.sample_visible(w, (i + 0.5f) / kQuad, (j + 0.5f) / kQuad);
      const float wm = dot(w, m);
      if (wm <= 0) continue;
      float cos_t = 0;
      const float f = rt::fresnel_dielectric(wm, eta, &cos_t);
      if (!transmit) {
        const Vec3 wr = rt::reflect(w, m);
        if (wr.z > 0) sum += f * g1(g, wr);
      } else if (f < 1) {
        const Vec3 wt = rt::refract_dir(w, m, eta, cos_t);
        if (wt.z < 0) sum += (1 - f) * g1(g, wt);
      }
    }
  return sum / (kQuad * kQuad);
}

Vec3 dir_of_cos(double c) { return {float(std::sqrt(std::max(0.0, 1 - c * c))), 0.0f, float(c)}; }

constexpr int kBaseNodes = 128;  // midpoint nodes of the base's integral over the light's cosine

// Mitsuba's plastic base terms: t(c) and R (see the top); t at the base integral's nodes once.
struct PlasticBase {
  bool rough = false;
  rt::Ggx g;
  float ior = 1.5f;
  double R = 0;
  std::vector<double> t_nodes;
  double t(double c) const {
    return rough ? rough_interface(g, dir_of_cos(std::max(c, 1e-6)), ior, true) : 1 - rt::fresnel_dielectric(float(c), ior);
  }
};
PlasticBase mitsuba_plastic_base(const rt::Material& m) {
  PlasticBase b;
  b.rough = m.alpha_x >= 1e-3f;
  b.g = rt::Ggx{m.alpha_x, m.alpha_y};
  b.ior = m.ior;
  if (!b.rough) {
    b.R = mitsuba_fdr_below_one(1.0 / m.ior);
  } else {
    constexpr int n = 64;  // MI_ROUGH_TRANSMITTANCE_RES cosines, linspace(0, 1) floored at 1e-6
    double s = 0;
    for (int i = 0; i < n; ++i) {
      const double mu = std::max(1e-6, double(i) / (n - 1));
      s += mu * rough_interface(b.g, dir_of_cos(mu), 1.0f / m.ior, false);
    }
    b.R = 2 * s / n;
  }
  for (int i = 0; i < kBaseNodes; ++i) b.t_nodes.push_back(b.t((i + 0.5) / kBaseNodes));
  return b;
}

// Delta(wo) per channel for a front-side hit of material m (see the top).
Vec3 model_difference(const rt::Material& m, const PlasticBase* base, Vec3 wo) {
  double d[3] = {0, 0, 0};
  const rt::Ggx g{m.alpha_x, m.alpha_y};
  const float eta = m.ior;
  if (!g.smooth()) {
    const double g1o = g1(g, wo);
    for (int i = 0; i < kQuad; ++i)
      for (int j = 0; j < kQuad; ++j) {
        const Vec3 h = g.sample_visible(wo, (i + 0.5f) / kQuad, (j + 0.5f) / kQuad);
        const float om = dot(wo, h);
        if (om <= 0) continue;
        const Vec3 wr = rt::reflect(wo, h);
        Vec3 fr;
        float cos_t = 0, f = 1;
        if (m.type == rt::MaterialType::kConductor) {
          fr = rt::conductor_fresnel(om, m.eta_c, m.k_c, m.schlick, m.tint);
        } else {
          f = rt::fresnel_dielectric(om, eta, &cos_t);
          fr = m.tint * f;
        }
        if (wr.z > 0) {
          const double w = g2(g, wo, wr) / g1o - g1(g, wr);
          for (int c = 0; c < 3; ++c) d[c] += fr[c] * w;
        }
        if (m.type == rt::MaterialType::kDielectric && f < 1) {
          const Vec3 wt = rt::refract_dir(wo, h, eta, cos_t);
          if (wt.z < 0) {
            const double w = (1 - f) * (g2(g, wo, wt) / g1o - g1(g, wt)) / (eta * eta);
            for (int c = 0; c < 3; ++c) d[c] += m.transmittance[c] * w;
          }
        }
      }
    for (double& x : d) x /= kQuad * kQuad;
  }
  if (m.type == rt::MaterialType::kPlastic) {
    // 2 pi int_0^1 |base_tracer - base_mitsuba| c dc, the bases' azimuth-free product forms.
    constexpr int n = kBaseNodes;
    const double co = wo.z, to_t = 1 - rt::fresnel_dielectric(float(co), eta), to_m = base->t(co);
    for (int i = 0; i < n; ++i) {
      const double c = (i + 0.5) / n;
      const double ti_t = 1 - rt::fresnel_dielectric(float(c), eta), ti_m = base->t_nodes[std::size_t(i)];
      for (int ch = 0; ch < 3; ++ch) {
        const double a = m.albedo[ch];
        const double bt = a * ti_t * to_t / (1 - a * m.base_inner_reflectance);
        const double bm = a * ti_m * to_m / (1 - a * base->R);
        d[ch] += 2 * std::fabs(bt - bm) * c / (n * double(eta * eta));  // (1 / pi) x 2 pi
      }
    }
  }
  return {float(d[0]), float(d[1]), float(d[2])};
}

// Per block and channel, 1.1 Lmax x the largest Delta over the camera rays through the corners
// of the block's pixels that hit the material (pinhole camera: the single-hit layouts have no lens).
std::vector<Vec3> first_hit_bias(const Scene& scene) {
  const int bx = kWidth / kBlock, by = kHeight / kBlock;
  std::vector<Vec3> bias(std::size_t(bx * by), Vec3(0.0f));
  std::map<const rt::Material*, PlasticBase> bases;
  for (int y = 0; y <= kHeight; ++y)
    for (int x = 0; x <= kWidth; ++x) {
      rt::SurfaceHit hit;
      if (!scene.intersect(scene.camera.generate_ray(float(x), float(y), kWidth, kHeight), hit)) continue;
      const rt::Material& m = *hit.material;
      if (!m.is_hard()) continue;
      const PlasticBase* base = nullptr;
      if (m.type == rt::MaterialType::kPlastic) {
        auto it = bases.find(&m);
        if (it == bases.end()) it = bases.emplace(&m, mitsuba_plastic_base(m)).first;
        base = &it->second;
      }
      const rt::Frame f(hit.ns);
      const Vec3 delta = model_difference(m, base, f.to_local(-scene.camera.generate_ray(float(x), float(y), kWidth, kHeight).dir));
      // A corner belongs to up to four blocks.
      for (int yy : {y - 1, y})
        for (int xx : {x - 1, x}) {
          if (xx < 0 || yy < 0 || xx >= kWidth || yy >= kHeight) continue;
          Vec3& b = bias[std::size_t((yy / kBlock) * bx + xx / kBlock)];
          for (int c = 0; c < 3; ++c) b[c] = std::max(b[c], 1.1f * kLmax[c] * delta[c]);
        }
    }
  return bias;
}

// ---- Frames ------------------------------------------------------------------------------------
struct Frame {
  std::vector<double> mean, var;  // W * H * 3, row-major from the top
};

struct BlockStat {
  double mean[3] = {0, 0, 0}, var[3] = {0, 0, 0};
};
std::vector<BlockStat> blocks(const Frame& f) {
  const int bx = kWidth / kBlock;
  std::vector<BlockStat> out(std::size_t(bx * (kHeight / kBlock)));
  const double n = kBlock * kBlock;
  for (int y = 0; y < kHeight; ++y)
    for (int x = 0; x < kWidth; ++x)
      for (int c = 0; c < 3; ++c) {
        BlockStat& b = out[std::size_t((y / kBlock) * bx + x / kBlock)];
        const std::size_t i = std::size_t((y * kWidth + x) * 3 + c);
        b.mean[c] += f.mean[i] / n;
        b.var[c] += f.var[i] / (n * n);  // independent pixels
      }
  return out;
}

std::string python() { return test::source_dir() + "/.venv/bin/python"; }

// Every case exported and rendered by Mitsuba once for the suite (one Python start-up, one import).
class MitsubaAgreement : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    if (test::run_command(python() + " -c 'import mitsuba' 2>&1").exit_code != 0) {
      skip_reason_ = "Mitsuba is not in " + python() + " (scripts/setup installs it from PyPI)";
      return;
    }
    dir_ = new test::TempDir;
    std::string xmls;
    for (const Case& c : cases()) {
      auto scene = load_scene(test::write_text(dir_->file(std::string(c.name) + ".toml"), c.toml));
      MitsubaExportSettings s{kWidth, kHeight, kSpp / kSeeds, c.max_depth, 1};
      xmls += ' ';
      xmls += export_mitsuba(*scene, s, dir_->file(c.name));
    }
    const unsigned threads = std::max(1u, std::thread::hardware_concurrency());
    const auto r = test::run_command(fmt::format("{} {}/python/mitsuba_render.py{} -o {} --seeds {} --threads {} 2>&1",
                                                 python(), test::source_dir(), xmls, dir_->file("mitsuba.json"),
                                                 kSeeds, threads));
    if (r.exit_code != 0) {
      error_ = "python/mitsuba_render.py failed: " + r.output;
      return;
    }
    const nlohmann::json j = json_file::read(dir_->file("mitsuba.json"));
    for (const auto& fr : j.at("frames")) {
      const std::string name = std::filesystem::path(fr.at("scene").get<std::string>()).parent_path().filename();
      frames_[name] = Frame{fr.at("mean").get<std::vector<double>>(), fr.at("variance_of_mean").get<std::vector<double>>()};
    }
  }
  static void TearDownTestSuite() {
    delete dir_;
    dir_ = nullptr;
  }

  // Renders case `name` with the tracer and compares it with Mitsuba's frame block by block.
  void check(const char* name) {
    if (!skip_reason_.empty()) GTEST_SKIP() << skip_reason_;
    ASSERT_TRUE(error_.empty()) << error_;
    const Case* cs = nullptr;
    for (const Case& c : cases_)
      if (std::string(c.name) == name) cs = &c;
    ASSERT_NE(cs, nullptr);
    ASSERT_TRUE(frames_.count(name)) << name;
    const Frame& mf = frames_.at(name);
    ASSERT_EQ(mf.mean.size(), std::size_t(kWidth * kHeight * 3));

    auto scene = load_scene(dir_->file(std::string(name) + ".toml"));
    RenderSettings s;
    s.width = kWidth;
    s.height = kHeight;
    s.spp = kSpp;
    s.seed = 7;
    s.max_depth = cs->max_depth;
    s.reflection_levels = 0;
    s.edge_subpixels = false;
    const AovFrame af = render_frame(*scene, s);
    Frame tf;
    const Image& col = af.layer(layer::kColor);
    const Image& var = af.layer(layer::kVariance);
    for (int y = 0; y < kHeight; ++y)
      for (int x = 0; x < kWidth; ++x)
        for (int c = 0; c < 3; ++c) {
          tf.mean.push_back(col.at(x, y, c));
          tf.var.push_back(var.at(x, y, c));
        }
    const std::vector<Vec3> bias =
        cs->bias == Bias::kFirstHit ? first_hit_bias(*scene) : std::vector<Vec3>(12, Vec3(0.0f));

    const auto bt = blocks(tf), bm = blocks(mf);
    double worst_z = 0, worst_bias_share = 0, rel_se = 0;
    for (std::size_t b = 0; b < bt.size(); ++b)
      for (int c = 0; c < 3; ++c) {
        const double diff = bt[b].mean[c] - bm[b].mean[c];
        const double sigma = std::sqrt(bt[b].var[c] + bm[b].var[c]);
        const double floor = 1e-5 * std::max(bt[b].mean[c], bm[b].mean[c]);
        const double allowed = kSigmas * sigma + bias[b][c] + floor;
        if (sigma > 0) worst_z = std::max(worst_z, std::fabs(diff) / sigma);
        worst_bias_share = std::max(worst_bias_share, bias[b][c] / std::max(1e-12, bm[b].mean[c]));
        rel_se = std::max(rel_se, sigma / std::max(1e-12, bm[b].mean[c]));
        EXPECT_LE(std::fabs(diff), allowed)
            << name << " block " << b % 4 << "," << b / 4 << " channel " << c << ": tracer " << bt[b].mean[c]
            << " mitsuba " << bm[b].mean[c] << ", " << diff / std::max(sigma, 1e-300) << " sigma (sigma " << sigma
            << "), model bound " << bias[b][c];
      }
    // The line the report quotes: the largest difference in standard errors (bias not subtracted).
    std::printf("[ %s ] max |tracer - mitsuba| / sigma = %.2f over 12 blocks x 3 channels; largest model bound %.4f "
                "of the block mean; largest sigma %.4f of the block mean\n",
                name, worst_z, worst_bias_share, rel_se);
  }

  static inline test::TempDir* dir_ = nullptr;
  static inline std::string skip_reason_, error_;
  static inline std::map<std::string, Frame> frames_;
  const std::vector<Case> cases_ = cases();
};

TEST_F(MitsubaAgreement, RoughConductor) { check("RoughConductor"); }
TEST_F(MitsubaAgreement, AnisotropicRoughConductor) { check("AnisotropicRoughConductor"); }
TEST_F(MitsubaAgreement, SmoothConductor) { check("SmoothConductor"); }
TEST_F(MitsubaAgreement, SmoothDielectric) { check("SmoothDielectric"); }
TEST_F(MitsubaAgreement, RoughDielectric) { check("RoughDielectric"); }
TEST_F(MitsubaAgreement, ThinSheet) { check("ThinSheet"); }
TEST_F(MitsubaAgreement, SmoothPlastic) { check("SmoothPlastic"); }
TEST_F(MitsubaAgreement, RoughPlastic) { check("RoughPlastic"); }
TEST_F(MitsubaAgreement, ThinLens) { check("ThinLens"); }

// ---- The exporter without Mitsuba ----------------------------------------------------------------
std::string export_error(const std::string& toml) {
  test::TempDir dir;
  auto scene = load_scene(test::write_text(dir.file("s.toml"), toml));
  return test::error_of<InputError>([&] { export_mitsuba(*scene, {}, dir.file("out")); });
}

TEST(MitsubaExport, RefusesWhatMitsubaCannotRepresent) {
  const std::string sky = std::string(kCamera) + kSky;
  const std::string obj = "\n[[objects]]\ntype = \"quad\"\nmaterial = \"m\"\n";
  struct Refusal {
    std::string toml, says;
  };
  const Refusal refusals[] = {
      {sky + "[materials.m]\ntype = \"coated\"" + obj, "coated"},
      {sky + "[materials.m]\ntype = \"conductor\"\nschlick = true" + obj, "Schlick conductor"},
      {sky + "[sun]\ndirection = [0, 1, 0]\nirradiance = [1, 1, 1]\n[materials.m]\n" + obj, "the sun"},
      {std::string(kCamera) + "[sky]\ntype = \"gradient\"\nzenith = [1, 1, 1]\nhorizon = [1, 1, 1]\n[materials.m]\n" + obj,
       "gradient sky"},
      {sky + "[materials.m]\ntype = \"dielectric\"\nabsorption = [1, 1, 1]" + obj, "absorption"},
      {sky + "[materials.m]\ntype = \"plastic\"\nroughness_x = 0.2\nroughness_y = 0.1" + obj, "roughplastic is isotropic"},
      {sky + "[textures.t]\ntype = \"checker\"\n[materials.m]\ntexture = \"t\"" + obj, "textures"},
      {sky + "[materials.m]\nemission = [1, 1, 1]\ntwo_sided = true" + obj, "two-sided emitter"},
      {sky + "[textures.t]\ntype = \"leaf\"\n[materials.m]\nopacity = \"t\"" + obj, "opacity"},
      {sky + "[materials.m]\n" + obj + "translate_end = [1, 0, 0]\n", "moves"},
      {std::string(kCamera) + "shutter = [0, 1]\n" + kSky + "[materials.m]\n" + obj, "shutter"},
      {sky + "[materials.m]\ntype = \"conductor\"\nroughness_x = 0.2\nroughness_y = 0.1\n"
             "[[objects]]\ntype = \"sphere\"\nmaterial = \"m\"\nradius = 1\n",
       "interpolated normals"},
  };
  for (const Refusal& r : refusals) {
    const std::string e = export_error(r.toml);
    EXPECT_NE(e.find(r.says), std::string::npos) << e;
    EXPECT_NE(e.find("cannot export to Mitsuba 3"), std::string::npos) << e;
  }
  // An unused refused material is no reason to refuse the scene.
  EXPECT_EQ(export_error(sky + "[materials.unused]\ntype = \"coated\"\n[materials.m]\n" + obj), "(no error)");
}

TEST(MitsubaExport, WritesOneShapePerMeshAndMaterialAndNeverIntoAFullFolder) {
  test::TempDir dir;
  auto scene = load_scene(test::write_text(dir.file("s.toml"), room_scene("[materials.glass]\ntype = \"dielectric\"\n",
                                                                           "[[objects]]\ntype = \"box\"\nmaterial = "
                                                                           "\"glass\"\n")));
  const std::string xml_path = export_mitsuba(*scene, {.width = 8, .height = 6, .spp = 4, .max_depth = 3}, dir.file("out"));
  const std::string xml = test::slurp(xml_path);
  EXPECT_NE(xml.find("<scene version=\"3.0.0\">"), std::string::npos);
  EXPECT_NE(xml.find("<integer name=\"max_depth\" value=\"3\"/>"), std::string::npos);
  // Roulette from the tracer's vertex, not Mitsuba's default 5 (a speed comparison's equal work).
  EXPECT_NE(xml.find(fmt::format("<integer name=\"rr_depth\" value=\"{}\"/>", rt::PathTracer::Options{}.rr_depth)),
            std::string::npos);
  EXPECT_NE(xml.find("<bsdf type=\"dielectric\" id="), std::string::npos) << "glass is not wrapped in twosided";
  std::size_t shapes = 0;
  for (std::size_t p = xml.find("<shape"); p != std::string::npos; p = xml.find("<shape", p + 1)) ++shapes;
  EXPECT_EQ(shapes, scene->meshes.size());  // floor, wall, box, light: one material each
  std::size_t plys = 0, boxes = 0;
  for (const auto& e : std::filesystem::directory_iterator(dir.file("out/meshes"))) {
    ++plys;
    // The box: 12 triangles, 3 corners each, flat (no normals), and its uvs.
    const std::string ply = test::slurp(e.path());
    if (ply.find("element vertex 36\n") != std::string::npos) {
      ++boxes;
      EXPECT_EQ(ply.find("property float nx"), std::string::npos);
      EXPECT_NE(ply.find("element face 12\n"), std::string::npos);
    }
  }
  EXPECT_EQ(plys, shapes);
  EXPECT_EQ(boxes, 1u);
  // A second export into the same folder is refused and leaves it as it was.
  const std::string again = test::error_of<InputError>([&] { export_mitsuba(*scene, {}, dir.file("out")); });
  EXPECT_NE(again.find("exists and is not an empty folder"), std::string::npos) << again;
  EXPECT_EQ(test::slurp(xml_path), xml);
  // The command: bad input is exit 2 with the reason, and nothing is written.
  const auto r = test::run_denoisebench("export-mitsuba " + dir.file("s.toml") + " -o " + dir.file("cmd") +
                                        " --size 16x12 --spp 4 --max-depth 5 --seed 3");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(test::slurp(dir.file("cmd/scene.xml")).find("<integer name=\"seed\" value=\"3\"/>"), std::string::npos);
  const auto bad = test::run_denoisebench("export-mitsuba " + dir.file("s.toml") + " -o " + dir.file("cmd"));
  EXPECT_EQ(bad.exit_code, 2) << bad.output;
  const std::string sun_toml = std::string(kCamera) + "[sun]\ndirection = [0, 1, 0]\nirradiance = [1, 1, 1]\n"
                               "[materials.m]\n[[objects]]\ntype = \"quad\"\nmaterial = \"m\"\n";
  const auto refused =
      test::run_denoisebench("export-mitsuba " + test::write_text(dir.file("sun.toml"), sun_toml) + " -o " + dir.file("sun"));
  EXPECT_EQ(refused.exit_code, 2) << refused.output;
  EXPECT_NE(refused.output.find("the sun"), std::string::npos) << refused.output;
  EXPECT_FALSE(std::filesystem::exists(dir.file("sun")));
}

}  // namespace
}  // namespace dnb
