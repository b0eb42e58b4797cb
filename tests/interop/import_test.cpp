// Importing other renderers' frames (interop/import.h): each preset on a small synthetic file with
// that renderer's exact channel names, the composition check, the mapping files' refusals, and
// format detection.
#include <algorithm>
#include <cmath>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "core/errors.h"
#include "core/exr_io.h"
#include "denoisers/method.h"
#include "interop/import.h"
#include "methods/denoise.h"
#include <nlohmann/json.hpp>

#include "test_util.h"

namespace dnb {
namespace {
using ::testing::HasSubstr;

constexpr int kW = 12, kH = 9;
constexpr std::size_t kN = std::size_t(kW) * kH;

// A deterministic plane: values in [lo, hi) varying per pixel and per seed.
std::vector<float> plane(unsigned seed, float lo = 0.0f, float hi = 1.0f) {
  std::vector<float> p(kN);
  for (std::size_t i = 0; i < kN; ++i) {
    const unsigned h = (unsigned(i) * 2654435761u) ^ (seed * 40503u + 977u);
    p[i] = lo + (hi - lo) * float((h >> 8) % 1000) / 1000.0f;
  }
  return p;
}

// A Cycles multilayer EXR as Blender writes one: every pass under the view layer's name, RGB
// passes as .R/.G/.B, Combined with .A, vectors as .X/.Y/.Z, Depth.Z, the sample count in the
// header. Combined is composed exactly as Cycles does, in float.
test::Channels cycles_channels(const std::string& vl, bool transmission, unsigned first_seed = 1) {
  test::Channels ch;
  std::map<std::string, std::vector<float>> p;
  const char* rgb[] = {"R", "G", "B"};
  unsigned seed = first_seed;
  std::vector<std::string> passes = {"DiffDir", "DiffInd", "DiffCol", "GlossDir", "GlossInd", "GlossCol", "Emit"};
  if (transmission) passes.insert(passes.end(), {"TransDir", "TransInd", "TransCol"});
  for (const auto& pass : passes)
    for (const char* c : rgb) p[pass + "." + c] = plane(seed++, 0.0f, pass == "Emit" ? 0.2f : 1.0f);
  for (const char* c : rgb) {
    std::vector<float> comb(kN);
    const std::string s = std::string(".") + c;
    for (std::size_t i = 0; i < kN; ++i) {
      float v = (p["DiffDir" + s][i] + p["DiffInd" + s][i]) * p["DiffCol" + s][i] +
                (p["GlossDir" + s][i] + p["GlossInd" + s][i]) * p["GlossCol" + s][i] + p["Emit" + s][i];
      if (transmission) v += (p["TransDir" + s][i] + p["TransInd" + s][i]) * p["TransCol" + s][i];
      comb[i] = v;
    }
    ch.emplace_back(vl + ".Combined." + c, comb);
  }
  ch.emplace_back(vl + ".Combined.A", std::vector<float>(kN, 1.0f));
  for (const auto& [name, values] : p) ch.emplace_back(vl + "." + name, values);
  for (const char* c : {"X", "Y", "Z"}) ch.emplace_back(vl + ".Normal." + c, plane(seed++, -1.0f, 1.0f));
  std::vector<float> depth = plane(seed++, 1.0f, 5.0f);
  depth[3] = 1e10f;  // a miss, as Cycles writes it
  ch.emplace_back(vl + ".Depth.Z", depth);
  return ch;
}

const std::vector<float>& channel(const test::Channels& ch, const std::string& name) {
  for (const auto& [n, v] : ch)
    if (n == name) return v;
  throw std::runtime_error("no " + name);
}

TEST(CyclesImport, ComposedColourEqualsCombinedAndEveryPassMaps) {
  for (bool transmission : {false, true}) {
    test::TempDir dir;
    const auto ch = cycles_channels("My View Layer", transmission);  // any view-layer name, spaces too
    test::write_exr(dir.file("c.exr"), kW, kH, ch, {{"cycles.My View Layer.samples", "128"}});
    const interop::Imported im = interop::import_frame(dir.file("c.exr"), interop::preset("cycles"));
    const AovFrame& f = im.frame;
    EXPECT_EQ(im.report.prefix, "My View Layer.");
    EXPECT_EQ(f.meta.spp, 128);
    EXPECT_EQ(im.report.spp_source, "cycles.My View Layer.samples");
    for (const char* l : {"color", "direct", "indirect", "albedo", "reflection", "emission", "normal", "depth"})
      EXPECT_TRUE(f.has(l)) << l;
    // Only the transmission layers may be left out, and only where the file has no such passes.
    std::vector<std::string> left;
    for (const auto& [l, why] : im.report.left_out) left.push_back(l);
    if (transmission) EXPECT_TRUE(left.empty()) << ::testing::PrintToString(left);
    else EXPECT_THAT(left, ::testing::ElementsAre("trans_color", "trans_direct", "trans_indirect"));
    EXPECT_TRUE(im.report.unmapped.empty()) << ::testing::PrintToString(im.report.unmapped);
    // The colour is Combined itself, bit for bit; D, I, T are DiffDir, DiffInd, DiffCol.
    for (std::size_t i = 0; i < kN; ++i) {
      EXPECT_EQ(f.layer("color").data()[3 * i + 1], channel(ch, "My View Layer.Combined.G")[i]);
      EXPECT_EQ(f.layer("direct").data()[3 * i], channel(ch, "My View Layer.DiffDir.R")[i]);
      EXPECT_EQ(f.layer("albedo").data()[3 * i + 2], channel(ch, "My View Layer.DiffCol.B")[i]);
      // R's parts are Cycles' own passes, as the tracer defines its gloss_* and trans_* layers.
      EXPECT_EQ(f.layer("gloss_direct").data()[3 * i], channel(ch, "My View Layer.GlossDir.R")[i]);
      EXPECT_EQ(f.layer("gloss_color").data()[3 * i + 1], channel(ch, "My View Layer.GlossCol.G")[i]);
      if (transmission) {
        EXPECT_EQ(f.layer("trans_indirect").data()[3 * i + 2], channel(ch, "My View Layer.TransInd.B")[i]);
      }
    }
    EXPECT_EQ(f.has("trans_color"), transmission);
    // (D + I) * T + R + E equals Combined to float rounding: R holds gloss and transmission. The
    // sums are formed in a different order than the file's (double, then rounded once), so
    // they agree to a few float ulps of values near 1: 1e-6 relative.
    ASSERT_TRUE(im.report.composition_rel_rms.has_value());
    EXPECT_LT(*im.report.composition_rel_rms, 1e-6) << (transmission ? "with" : "without") << " transmission";
    // Depth.Z's miss (1e10) is the harness's miss, 0; the rest is kept.
    EXPECT_EQ(f.layer("depth").data()[3], 0.0f);
    EXPECT_EQ(f.layer("depth").data()[4], channel(ch, "My View Layer.Depth.Z")[4]);
    EXPECT_EQ(f.meta.extra.at("import.format"), "cycles");
    EXPECT_EQ(f.meta.extra.at("import.normal_space"), "world");
  }
}

TEST(CyclesImport, WithoutGlossTheSplitDoesNotAddUpAndSaysSo) {
  test::TempDir dir;
  test::Channels ch;
  for (const auto& [n, v] : cycles_channels("ViewLayer", false))
    if (n.find("Gloss") == std::string::npos) ch.emplace_back(n, v);
  test::write_exr(dir.file("c.exr"), kW, kH, ch);
  const interop::Imported im = interop::import_frame(dir.file("c.exr"), interop::preset("cycles"), {.spp = 64});
  EXPECT_FALSE(im.frame.has("reflection"));
  // reflection and R's parts (gloss_*, and trans_*: this file has no transmission passes).
  ASSERT_EQ(im.report.left_out.size(), 7u);
  const auto r = std::find_if(im.report.left_out.begin(), im.report.left_out.end(),
                              [](const auto& p) { return p.first == "reflection"; });
  ASSERT_NE(r, im.report.left_out.end());
  EXPECT_THAT(r->second, HasSubstr("ViewLayer.GlossDir"));
  EXPECT_EQ(im.frame.meta.spp, 64);  // --spp, the file records none
  // Combined holds the gloss light that no mapped pass carries: the check says how much.
  ASSERT_TRUE(im.report.composition_rel_rms.has_value());
  EXPECT_GT(*im.report.composition_rel_rms, 0.05);
  ASSERT_FALSE(im.report.warnings.empty());
  EXPECT_THAT(im.report.warnings[0], HasSubstr("differs from the colour"));
}

// A Cycles file without light passes but with the denoising data: Combined, and the denoiser's
// albedo, camera-space normal and mean depth stand in.
TEST(CyclesImport, WithoutLightPassesTheDenoisingDataServe) {
  test::TempDir dir;
  test::Channels ch;
  for (const char* c : {"R", "G", "B"}) ch.emplace_back(std::string("ViewLayer.Combined.") + c, plane(7));
  for (const char* c : {"R", "G", "B"}) ch.emplace_back(std::string("ViewLayer.Denoising Albedo.") + c, plane(8));
  for (const char* c : {"X", "Y", "Z"}) ch.emplace_back(std::string("ViewLayer.Denoising Normal.") + c, plane(9, -1, 1));
  ch.emplace_back("ViewLayer.Denoising Depth.Z", plane(10, 1, 3));
  test::write_exr(dir.file("c.exr"), kW, kH, ch);
  const auto im = interop::import_frame(dir.file("c.exr"), interop::preset("cycles"), {.spp = 16});
  EXPECT_EQ(im.frame.layer("albedo").data()[4], channel(ch, "ViewLayer.Denoising Albedo.G")[1]);
  EXPECT_EQ(im.frame.meta.extra.at("import.normal_space"), "camera");
  EXPECT_EQ(im.frame.layer("depth").data()[2], channel(ch, "ViewLayer.Denoising Depth.Z")[2]);
  std::vector<std::string> left;
  for (const auto& [l, why] : im.report.left_out) left.push_back(l);
  EXPECT_THAT(left, ::testing::ElementsAre("direct", "emission", "gloss_color", "gloss_direct", "gloss_indirect",
                                           "indirect", "reflection", "trans_color", "trans_direct", "trans_indirect"));
}

// Two renders of one view with different seeds (import --second): their layers are the frame's
// half buffers, every layer their mean, the colour's and illumination's variances (a - b)^2 / 4,
// the spp their sum; then nfor, svgf and kpcn (plug-in manifests aside: the built-ins) can run.
TEST(PairImport, TwoSeedsBecomeHalfBuffersAndVariances) {
  test::TempDir dir;
  const auto a = cycles_channels("ViewLayer", false, 1), b = cycles_channels("ViewLayer", false, 500);
  test::write_exr(dir.file("a.exr"), kW, kH, a, {{"cycles.ViewLayer.samples", "64"}});
  test::write_exr(dir.file("b.exr"), kW, kH, b, {{"cycles.ViewLayer.samples", "64"}});
  const interop::Imported im =
      interop::import_frame_pair(dir.file("a.exr"), dir.file("b.exr"), interop::preset("cycles"));
  const AovFrame& f = im.frame;
  EXPECT_EQ(f.meta.spp, 128);
  const auto& ca = channel(a, "ViewLayer.Combined.G");
  const auto& cb = channel(b, "ViewLayer.Combined.G");
  const auto& da = channel(a, "ViewLayer.DiffDir.R");
  const auto& db = channel(b, "ViewLayer.DiffDir.R");
  for (std::size_t i = 0; i < kN; ++i) {
    EXPECT_EQ(f.layer("half0.color").data()[3 * i + 1], ca[i]);
    EXPECT_EQ(f.layer("half1.color").data()[3 * i + 1], cb[i]);
    EXPECT_FLOAT_EQ(f.layer("color").data()[3 * i + 1], (ca[i] + cb[i]) / 2);
    EXPECT_FLOAT_EQ(f.layer("variance").data()[3 * i + 1], (ca[i] - cb[i]) * (ca[i] - cb[i]) / 4);
    EXPECT_FLOAT_EQ(f.layer("direct_variance").data()[3 * i], (da[i] - db[i]) * (da[i] - db[i]) / 4);
    EXPECT_EQ(f.layer("half1.direct").data()[3 * i], db[i]);
  }
  for (const char* l : {"half0.albedo", "half1.normal", "half0.depth", "indirect_variance"}) EXPECT_TRUE(f.has(l)) << l;
  EXPECT_EQ(f.meta.extra.at("import.second"), dir.file("b.exr"));
  const std::vector<std::string> methods = methods_for_frame(f);
  for (const char* m : {"nfor", "svgf", "proposed"})
    EXPECT_NE(std::find(methods.begin(), methods.end(), m), methods.end()) << m << ": " << ::testing::PrintToString(methods);
  // One file alone: no halves, no variance, so neither nfor nor svgf.
  const std::vector<std::string> single =
      methods_for_frame(interop::import_frame(dir.file("a.exr"), interop::preset("cycles")).frame);
  EXPECT_EQ(std::find(single.begin(), single.end(), "nfor"), single.end());
  EXPECT_EQ(std::find(single.begin(), single.end(), "svgf"), single.end());
}

TEST(PairImport, HalvesThatCannotBeOneFrameAreRefusedNamingTheFiles) {
  test::TempDir dir;
  const auto a = cycles_channels("ViewLayer", false, 1);
  test::write_exr(dir.file("a.exr"), kW, kH, a);
  test::write_exr(dir.file("same.exr"), kW, kH, a);
  auto refusal = [&](const std::string& second) {
    return test::error_of<InputError>(
        [&] { interop::import_frame_pair(dir.file("a.exr"), dir.file(second), interop::preset("cycles")); });
  };
  EXPECT_THAT(refusal("same.exr"), HasSubstr("another seed"));
  // Another size.
  test::Channels small;
  for (const auto& [n, v] : cycles_channels("ViewLayer", false, 9))
    small.emplace_back(n, std::vector<float>(v.begin(), v.begin() + (kW - 1) * kH));
  test::write_exr(dir.file("small.exr"), kW - 1, kH, small);
  EXPECT_THAT(refusal("small.exr"), HasSubstr("small.exr' is 11x9"));
  // Other passes: the second without the gloss passes has no reflection layer.
  test::Channels nogloss;
  for (const auto& [n, v] : cycles_channels("ViewLayer", false, 9))
    if (n.find("Gloss") == std::string::npos) nogloss.emplace_back(n, v);
  test::write_exr(dir.file("nogloss.exr"), kW, kH, nogloss);
  EXPECT_THAT(refusal("nogloss.exr"), HasSubstr("no layer"));
}

TEST(CyclesImport, TwoViewLayersNeedAChoice) {
  test::TempDir dir;
  auto ch = cycles_channels("A", false);
  for (const auto& [n, v] : cycles_channels("B", false)) ch.emplace_back(n, v);
  test::write_exr(dir.file("c.exr"), kW, kH, ch);
  const std::string e = test::error_of<InputError>([&] { interop::import_frame(dir.file("c.exr"), interop::preset("cycles")); });
  EXPECT_THAT(e, HasSubstr("A., B."));
  EXPECT_THAT(e, HasSubstr("--layer"));
  const auto im = interop::import_frame(dir.file("c.exr"), interop::preset("cycles"), {.prefix = "B"});
  EXPECT_EQ(im.frame.layer("direct").data()[0], channel(ch, "B.DiffDir.R")[0]);
}

// pbrt-v4's GBufferFilm, in both of its spellings.
test::Channels pbrt_channels(bool old_names) {
  test::Channels ch;
  unsigned seed = 50;
  for (const char* c : {"R", "G", "B"}) ch.emplace_back(c, plane(seed++));
  for (const char* c : {"R", "G", "B"}) ch.emplace_back(std::string("Albedo.") + c, plane(seed++));
  const char* xyz[] = {"X", "Y", "Z"};
  const char* lxyz[] = {"x", "y", "z"};
  for (const char* g : {"P", "N", "Ns"})
    for (int k = 0; k < 3; ++k)
      ch.emplace_back(old_names ? std::string(g) + lxyz[k] : std::string(g) + "." + xyz[k],
                      plane(seed++, std::string(g) == "P" ? -3.0f : -1.0f, std::string(g) == "P" ? 3.0f : 1.0f));
  ch.emplace_back("dzdx", plane(seed++));
  ch.emplace_back("dzdy", plane(seed++));
  ch.emplace_back("u", plane(seed++));
  ch.emplace_back("v", plane(seed++));
  for (const char* c : {"R", "G", "B"}) ch.emplace_back(std::string("Variance.") + c, plane(seed++));
  for (const char* c : {"R", "G", "B"}) ch.emplace_back(std::string("RelativeVariance.") + c, plane(seed++));
  return ch;
}

TEST(PbrtImport, BothSpellingsGiveTheColourNormalsDepthAndVarianceOfTheMean) {
  for (bool old_names : {false, true}) {
    test::TempDir dir;
    const auto ch = pbrt_channels(old_names);
    test::write_exr(dir.file("p.exr"), kW, kH, ch);
    EXPECT_EQ(interop::detect_format(dir.file("p.exr")).format, "pbrt") << old_names;
    const auto im = interop::import_frame(dir.file("p.exr"), interop::preset("pbrt"), {.spp = 16});
    const AovFrame& f = im.frame;
    const std::string px = old_names ? "Px" : "P.X", py = old_names ? "Py" : "P.Y", pz = old_names ? "Pz" : "P.Z";
    for (std::size_t i = 0; i < kN; ++i) {
      EXPECT_EQ(f.layer("color").data()[3 * i], channel(ch, "R")[i]);
      EXPECT_EQ(f.layer("normal").data()[3 * i + 2], channel(ch, old_names ? "Nsz" : "Ns.Z")[i]);
      const double len = std::sqrt(double(channel(ch, px)[i]) * channel(ch, px)[i] +
                                   double(channel(ch, py)[i]) * channel(ch, py)[i] + double(channel(ch, pz)[i]) * channel(ch, pz)[i]);
      EXPECT_FLOAT_EQ(f.layer("depth").data()[i], float(len));
      // GBufferFilm's Variance is per sample: the variance of the mean is it over the spp.
      EXPECT_FLOAT_EQ(f.layer("variance").data()[3 * i + 1], channel(ch, "Variance.G")[i] / 16.0f);
    }
    EXPECT_FALSE(f.has("direct"));
    EXPECT_EQ(f.meta.extra.at("import.normal_space"), "camera");
    EXPECT_FALSE(im.report.composition_rel_rms.has_value());  // no split to check
  }
}

TEST(PbrtImport, APerSampleVarianceNeedsTheSampleCount) {
  test::TempDir dir;
  test::write_exr(dir.file("p.exr"), kW, kH, pbrt_channels(false));
  // Without it the (optional) variance layer is left out, saying why; required, it is an error.
  const auto im = interop::import_frame(dir.file("p.exr"), interop::preset("pbrt"));
  EXPECT_FALSE(im.frame.has("variance"));
  ASSERT_EQ(im.report.left_out.size(), 1u);
  EXPECT_EQ(im.report.left_out[0].first, "variance");
  EXPECT_THAT(im.report.left_out[0].second, HasSubstr("--spp"));
  const auto m = interop::parse_mapping(
      "[import]\nname='v'\n[layers]\ncolor={channels=['R','G','B']}\nvariance={terms=['Variance'], divide_by_spp=true}\n", "v.toml");
  EXPECT_THAT(test::error_of<InputError>([&] { interop::import_frame(dir.file("p.exr"), m); }), HasSubstr("--spp"));
  // The sample count from the header, where pbrt wrote one.
  test::write_exr(dir.file("q.exr"), kW, kH, pbrt_channels(false), {{"samplesPerPixel", "4"}});
  EXPECT_EQ(interop::import_frame(dir.file("q.exr"), interop::preset("pbrt")).frame.meta.spp, 4);
}

TEST(MitsubaImport, AovIntegratorOutputWithTheDocumentedNames) {
  test::TempDir dir;
  test::Channels ch;
  unsigned seed = 90;
  for (const char* c : {"R", "G", "B"}) ch.emplace_back(c, plane(seed++));
  for (const char* c : {"R", "G", "B", "A"}) ch.emplace_back(std::string("inner.") + c, plane(seed++));
  for (const char* c : {"R", "G", "B"}) ch.emplace_back(std::string("albedo.") + c, plane(seed++));
  for (const char* c : {"X", "Y", "Z"}) ch.emplace_back(std::string("nn.") + c, plane(seed++, -1, 1));
  ch.emplace_back("dd.T", plane(seed++, 1, 4));
  test::write_exr(dir.file("m.exr"), kW, kH, ch, {{"generatedBy", "Mitsuba version 3.5.2"}});
  const auto d = interop::detect_format(dir.file("m.exr"));
  EXPECT_EQ(d.format, "mitsuba");
  EXPECT_THAT(d.reason, HasSubstr("generatedBy"));
  const auto im = interop::import_frame(dir.file("m.exr"), interop::preset("mitsuba"));
  EXPECT_EQ(im.frame.layer("depth").data()[5], channel(ch, "dd.T")[5]);
  EXPECT_EQ(im.frame.layer("albedo").data()[3 * 5 + 1], channel(ch, "albedo.G")[5]);
  EXPECT_EQ(im.frame.meta.spp, 0);  // Mitsuba records none
  EXPECT_EQ(im.report.spp_source, "unknown");
  EXPECT_TRUE(im.report.unmapped.empty()) << ::testing::PrintToString(im.report.unmapped);
}

TEST(ImportMapping, RefusesUnknownKeysLayersAndMissingChannelsNamingThem) {
  const auto parse_error = [](const std::string& text) {
    return test::error_of<InputError>([&] { interop::parse_mapping(text, "m.toml"); });
  };
  EXPECT_THAT(parse_error("[import]\nname='x'\ncolour_space='srgb'\n[layers]\ncolor='C'\n"), HasSubstr("colour_space"));
  EXPECT_THAT(parse_error("[import]\nname='x'\n[layers]\ncolor='C'\ndiffuse='D'\n"), HasSubstr("unknown layer 'diffuse'"));
  EXPECT_THAT(parse_error("[import]\nname='x'\n[layers]\ncolor='C'\n[layers.depth]\nterms=['Z']\nmiss='1'\n"),
              HasSubstr("miss"));
  EXPECT_THAT(parse_error("[import]\nname='x'\n[layers]\ndirect='D'\n"), HasSubstr("must map `color`"));
  // A mapped pass the file lacks: the error names the layer, the mapping's key and the channels.
  test::TempDir dir;
  test::write_exr(dir.file("f.exr"), kW, kH, {{"beauty.R", plane(1)}, {"beauty.G", plane(2)}, {"beauty.B", plane(3)}});
  const auto m = interop::parse_mapping("[import]\nname='mine'\n[layers]\ncolor='beauty'\ndirect='MyLayer.Diffuse'\n", "mine.toml");
  const std::string e = test::error_of<InputError>([&] { interop::import_frame(dir.file("f.exr"), m); });
  EXPECT_THAT(e, HasSubstr("layer 'direct'"));
  EXPECT_THAT(e, HasSubstr("mine.toml:"));
  EXPECT_THAT(e, HasSubstr("MyLayer.Diffuse.R/G/B"));
  // Made optional, it is left out and said so.
  const auto opt = interop::parse_mapping(
      "[import]\nname='mine'\noptional=['direct']\n[layers]\ncolor='beauty'\ndirect='MyLayer.Diffuse'\n", "mine.toml");
  const auto im = interop::import_frame(dir.file("f.exr"), opt);
  ASSERT_EQ(im.report.left_out.size(), 1u);
  EXPECT_EQ(im.report.left_out[0].first, "direct");
}

TEST(ImportFormats, AutoReadsTheHarnessesOwnFramesNatively) {
  test::TempDir dir;
  AovFrame f(kW, kH);
  f.add("color", 3);
  f.add("albedo", 3);  // an albedo.R/G/B channel must not make it look like pbrt's Albedo
  f.meta.spp = 8;
  write_frame(f, dir.file("n.exr"));
  EXPECT_EQ(interop::detect_format(dir.file("n.exr")).format, "native");
  EXPECT_EQ(interop::read_frame_as(dir.file("n.exr"), "auto").meta.spp, 8);
  test::write_exr(dir.file("c.exr"), kW, kH, cycles_channels("ViewLayer", false));
  EXPECT_EQ(interop::detect_format(dir.file("c.exr")).format, "cycles");
  EXPECT_THAT(test::error_of<InputError>([&] { interop::mapping_for("blender"); }), HasSubstr("cycles, mitsuba, pbrt"));
}

}  // namespace
}  // namespace dnb

namespace dnb {
namespace {

// The commands on imported frames: import, then denoise and metrics; or each reading the
// foreign file directly.
TEST(ImportCommand, CyclesFrameImportsAndTheMethodsRunOnItOrOnTheFileItself) {
  test::TempDir dir;
  test::write_exr(dir.file("c.exr"), kW, kH, cycles_channels("ViewLayer", false), {{"cycles.ViewLayer.samples", "256"}});
  auto r = test::run_denoisebench("import cycles " + dir.file("c.exr") + " -o " + dir.file("f.exr"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_THAT(r.output, HasSubstr("direct"));
  EXPECT_THAT(r.output, HasSubstr("ViewLayer.DiffDir"));
  EXPECT_THAT(r.output, HasSubstr("256 (from cycles.ViewLayer.samples)"));
  EXPECT_THAT(r.output, HasSubstr("methods that can run on it"));
  const AovFrame f = read_frame(dir.file("f.exr"));
  EXPECT_EQ(f.meta.spp, 256);
  EXPECT_EQ(f.meta.extra.at("import.format"), "cycles");
  for (const char* m : {"bilateral", "proposed", "atrous"}) {
    auto d = test::run_denoisebench("denoise " + std::string(m) + " " + dir.file("f.exr") + " -o " + dir.file(std::string(m) + ".exr"));
    EXPECT_EQ(d.exit_code, 0) << m << ": " << d.output;
  }
  // The Cycles file itself, read through the preset (auto-detected): the same image.
  auto direct = test::run_denoisebench("denoise proposed " + dir.file("c.exr") + " -o " + dir.file("p2.exr"));
  ASSERT_EQ(direct.exit_code, 0) << direct.output;
  EXPECT_THAT(direct.output, HasSubstr("read as a cycles frame"));
  const Image a = read_rgb(dir.file("proposed.exr")), b = read_rgb(dir.file("p2.exr"));
  EXPECT_TRUE(std::equal(a.data(), a.data() + a.size(), b.data()));
  // metrics scores a Cycles file's Combined against a Cycles reference.
  auto m = test::run_denoisebench("metrics " + dir.file("p2.exr") + " --ref " + dir.file("c.exr") + " --metric mse");
  EXPECT_EQ(m.exit_code, 0) << m.output;
}

TEST(ImportCommand, AFrameWithoutTheSplitIsRefusedByTheMethodsThatNeedItNamingWhatCanRun) {
  test::TempDir dir;
  test::write_exr(dir.file("p.exr"), kW, kH, pbrt_channels(false));
  auto r = test::run_denoisebench("denoise atrous " + dir.file("p.exr") + " --input-format pbrt -o " + dir.file("o.exr"));
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_THAT(r.output, HasSubstr("direct"));
  EXPECT_THAT(r.output, HasSubstr("methods that can run on it: "));
  EXPECT_THAT(r.output, HasSubstr("bilateral"));
  EXPECT_FALSE(std::filesystem::exists(dir.file("o.exr")));
  // proposed runs on it, filtering the colour, and records that it did.
  auto p = test::run_denoisebench_stdout("denoise proposed " + dir.file("p.exr") + " -o " + dir.file("o.exr") + " --json");
  ASSERT_EQ(p.exit_code, 0) << p.errors;
  const auto j = nlohmann::json::parse(p.output);
  EXPECT_EQ(j["counters"]["illumination_split"].get<double>(), 0.0);
  EXPECT_EQ(j["counters"]["albedo_demodulated"].get<double>(), 1.0);  // pbrt's Albedo: F / T is filtered
  EXPECT_EQ(j["counters"]["assumed_spp"].get<double>(), 256.0);  // pbrt wrote no sample count here
  EXPECT_THAT(p.errors, HasSubstr("sample count is unknown"));
}

TEST(ImportCommand, AMappingFileWithAnUnknownKeyOrAMissingChannelExits2NamingIt) {
  test::TempDir dir;
  test::write_exr(dir.file("f.exr"), kW, kH, {{"beauty.R", plane(1)}, {"beauty.G", plane(2)}, {"beauty.B", plane(3)}});
  test::write(dir.file("bad.toml"), "[import]\nname = 'mine'\n[layers]\ncolor = 'beauty'\nnormal = { terms = ['N'], spaec = 'camera' }\n");
  auto r = test::run_denoisebench("import map:" + dir.file("bad.toml") + " " + dir.file("f.exr") + " -o " + dir.file("o.exr"));
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_THAT(r.output, HasSubstr("spaec"));
  EXPECT_THAT(r.output, HasSubstr("bad.toml"));
  test::write(dir.file("miss.toml"), "[import]\nname = 'mine'\n[layers]\ncolor = 'beauty'\nnormal = 'N'\n");
  r = test::run_denoisebench("import map:" + dir.file("miss.toml") + " " + dir.file("f.exr") + " -o " + dir.file("o.exr"));
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_THAT(r.output, HasSubstr("N.R/G/B (or .X/Y/Z)"));
  EXPECT_THAT(r.output, HasSubstr("layer 'normal'"));
  EXPECT_FALSE(std::filesystem::exists(dir.file("o.exr")));
  test::write(dir.file("ok.toml"), "[import]\nname = 'mine'\n[layers]\ncolor = 'beauty'\n");
  r = test::run_denoisebench("import map:" + dir.file("ok.toml") + " " + dir.file("f.exr") + " -o " + dir.file("o.exr") + " --spp 32");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_EQ(read_frame(dir.file("o.exr")).meta.spp, 32);
}

}  // namespace
}  // namespace dnb

namespace dnb {
namespace {

// A real Mitsuba 3 frame (its aov integrator, python/render_mitsuba_aov.py), when scripts/setup
// installed Mitsuba into the project's .venv: imported through the preset, denoised, scored.
TEST(MitsubaImport, ARealAovRenderImportsAndDenoises) {
  const std::string py = test::source_dir() + "/.venv/bin/python";
  if (test::run_command(py + " -c 'import mitsuba' 2>&1").exit_code != 0)
    GTEST_SKIP() << "Mitsuba is not in " << py << " (scripts/setup installs it from PyPI)";
  test::TempDir dir;
  auto r = test::run_command(py + " " + test::source_dir() + "/python/render_mitsuba_aov.py " + dir.file("m.exr") +
                             " --size 32x24 --spp 8");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_EQ(interop::detect_format(dir.file("m.exr")).format, "mitsuba");
  r = test::run_denoisebench("import mitsuba " + dir.file("m.exr") + " --spp 8 -o " + dir.file("f.exr"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const AovFrame f = read_frame(dir.file("f.exr"));
  for (const char* l : {"color", "albedo", "normal", "depth"}) EXPECT_TRUE(f.has(l)) << l << "\n" << r.output;
  // Hits have depth > 0 and a normal that is a mean of unit normals (length at most 1, and near 1
  // away from edges: most pixels); misses (the box's open sides at 4:3) have depth 0.
  int hits = 0, unit = 0;
  for (std::size_t i = 0; i < f.layer("normal").pixel_count(); ++i) {
    const float* n = f.layer("normal").data() + 3 * i;
    const float len = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    EXPECT_LE(len, 1.0f + 1e-5f);
    EXPECT_GE(f.layer("depth").data()[i], 0.0f);
    if (f.layer("depth").data()[i] > 0) ++hits, unit += len > 0.99f;
  }
  EXPECT_GT(hits, int(f.layer("depth").pixel_count() / 2));
  EXPECT_GT(unit, hits / 2);
  for (const char* m : {"bilateral", "proposed"}) {
    r = test::run_denoisebench("denoise " + std::string(m) + " " + dir.file("f.exr") + " -o " + dir.file(std::string(m) + ".exr"));
    EXPECT_EQ(r.exit_code, 0) << m << ": " << r.output;
  }
  r = test::run_denoisebench("metrics " + dir.file("proposed.exr") + " " + dir.file("bilateral.exr") + " --ref " +
                             dir.file("m.exr") + " --metric mse --metric flip");
  EXPECT_EQ(r.exit_code, 0) << r.output;
}

}  // namespace
}  // namespace dnb

namespace dnb {
namespace {

// A whole table from another renderer's renders: a Cycles frame and a Cycles reference named in
// an experiment config, read through the preset.
TEST(ImportCommand, AnExperimentConfigScoresCyclesFilesAgainstACyclesReference) {
  test::TempDir dir;
  test::write_exr(dir.file("in.exr"), kW, kH, cycles_channels("ViewLayer", false), {{"cycles.ViewLayer.samples", "32"}});
  // The reference: the same passes, another "seed" (other values), far more samples.
  auto ref = cycles_channels("ViewLayer", true);
  test::write_exr(dir.file("ref.exr"), kW, kH, ref, {{"cycles.ViewLayer.samples", "4096"}});
  test::write(dir.file("exp.toml"),
              "input_format = \"cycles\"\nmethods = [\"bilateral\", \"proposed\"]\n[[scene]]\nframe = \"in.exr\"\n"
              "reference = \"ref.exr\"\nlabel = \"cycles-box\"\n");
  auto r = test::run_denoisebench("run " + dir.file("exp.toml") + " -o " + dir.file("out"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const auto doc = nlohmann::json::parse(test::slurp(dir.file("out/results.json")));
  int methods = 0;
  for (const auto& rec : doc["records"]) {
    EXPECT_EQ(rec["scene"], "cycles-box");
    EXPECT_EQ(rec["spp"], 32);  // cycles.ViewLayer.samples
    if (rec["role"] != "method") continue;
    ++methods;
    EXPECT_TRUE(rec["metrics"]["mse"].is_number()) << rec.dump();
  }
  EXPECT_EQ(methods, 2);
  // A format that does not exist is refused naming the key.
  test::write(dir.file("bad.toml"), "input_format = \"blender\"\nmethods = [\"bilateral\"]\n[[scene]]\nframe = \"in.exr\"\nreference = \"ref.exr\"\n");
  r = test::run_denoisebench("run " + dir.file("bad.toml") + " -o " + dir.file("out2"));
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_THAT(r.output, HasSubstr("input_format"));
}

}  // namespace
}  // namespace dnb

namespace dnb {
namespace {

// proposed on frames without the split: demodulated by the albedo when there is one (and then
// exact where nothing is noisy: a constant light times a texture comes back unchanged), the
// colour when there is none, and a refusal when there is neither.
TEST(ProposedWithoutTheSplit, DemodulatesByTheAlbedoFiltersTheColourOrRefuses) {
  AovFrame f(kW, kH);
  Image& t = f.add("albedo", 3);
  Image& c = f.add("color", 3);
  f.add("normal", 3);
  f.add("depth", 1);
  for (std::size_t i = 0; i < t.size(); ++i) {
    t.data()[i] = (i / 3) % 2 ? 0.8f : 0.2f;  // a checkerboard-like texture of stripes
    c.data()[i] = 0.5f * t.data()[i];        // constant untextured light 0.5
  }
  for (std::size_t i = 0; i < f.layer("normal").pixel_count(); ++i) {
    f.layer("normal").data()[3 * i + 2] = 1.0f;
    f.layer("depth").data()[i] = 2.0f;
  }
  f.meta.spp = 256;
  auto m = MethodRegistry::global().create("proposed");
  const MethodResult r = run_method(*m, MethodInput{.frame = &f});
  EXPECT_EQ(r.stats.counters.at("albedo_demodulated"), 1.0);
  EXPECT_EQ(r.stats.counters.at("illumination_split"), 0.0);
  // 2e-3 relative: the adaptive-manifold filter of a constant layer returns it to float rounding
  // of its normalised sums (many thousand terms), far below the texture's 4x contrast.
  for (std::size_t i = 0; i < c.size(); ++i) EXPECT_NEAR(r.image.data()[i], c.data()[i], 2e-3 * c.data()[i]) << i;
  AovFrame no_albedo(kW, kH);
  for (const char* l : {"color", "normal", "depth"}) no_albedo.set(l, f.layer(l));
  EXPECT_EQ(run_method(*m, MethodInput{.frame = &no_albedo}).stats.counters.at("albedo_demodulated"), 0.0);
  AovFrame nothing(kW, kH);
  for (const char* l : {"normal", "depth"}) nothing.set(l, f.layer(l));
  EXPECT_THAT(test::error_of<InputError>([&] { run_method(*m, MethodInput{.frame = &nothing}); }), HasSubstr("colour"));
}

}  // namespace
}  // namespace dnb

namespace dnb {
namespace {

// `import` lists the plug-ins among the methods that can run on the frame, loaded as `denoise`
// loads them (--plugins, $DENOISEBENCH_PLUGINS, the repository's plugins/): one that reads the
// colour only is listed for a pbrt frame, one that needs the split it lacks is not.
TEST(ImportCommand, TheMethodsThatCanRunIncludeThePlugins) {
  test::TempDir dir;
  test::write_exr(dir.file("p.exr"), kW, kH, pbrt_channels(false));
  const auto manifest = [](const std::string& name, const std::string& layers) {
    return "[plugin]\nname = \"" + name + "\"\ncommand = [\"/bin/true\"]\nprotocol = \"frame\"\nlayers = [" + layers + "]\n";
  };
  test::write(dir.path() / "plug" / "a" / "a.toml", manifest("colour_only", "\"color\""));
  test::write(dir.path() / "plug" / "b" / "b.toml", manifest("needs_split", "\"color\", \"direct\""));
  auto r = test::run_denoisebench_stdout("import pbrt " + dir.file("p.exr") + " -o " + dir.file("f.exr") + " --json --plugins " +
                                         dir.file("plug"));
  ASSERT_EQ(r.exit_code, 0) << r.errors;
  const auto methods = nlohmann::json::parse(r.output)["methods"].get<std::vector<std::string>>();
  EXPECT_THAT(methods, ::testing::Contains("colour_only"));
  EXPECT_THAT(methods, ::testing::Not(::testing::Contains("needs_split")));
  EXPECT_THAT(methods, ::testing::Contains("bilateral"));
  // The same plug-in folder through the environment, in the text report.
  r = test::run_command("DENOISEBENCH_PLUGINS='" + dir.file("plug") + "' '" + test::binary().string() + "' import pbrt " +
                        dir.file("p.exr") + " -o " + dir.file("g.exr"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_THAT(r.output, HasSubstr("colour_only"));
}

}  // namespace
}  // namespace dnb
