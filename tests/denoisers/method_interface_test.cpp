// The method interface itself: the registry's refusals name what is valid, parameters
// are typed and bounded, and run_method checks the frame, repairs it and checks the output.
#include <gtest/gtest.h>
#include <gmock/gmock.h>

#include <cmath>
#include <limits>

#include "core/errors.h"
#include "denoisers/method.h"
#include "denoisers/synthetic_frame.h"

namespace dnb {
namespace {
using ::testing::HasSubstr;

// A method whose behaviour each test sets: it returns `output` (or copies the colour layer).
class Probe final : public Method {
 public:
  std::vector<std::string> layers = {layer::kColor, layer::kDepth};
  std::function<Image(const AovFrame&)> output;
  AovFrame seen;  // the frame execute() received
  std::vector<std::string> required_layers() const override { return layers; }
  MethodResult execute(const MethodInput& in) override {
    seen = *in.frame;
    MethodResult r;
    r.image = output ? output(*in.frame) : in.frame->layer(layer::kColor);
    return r;
  }
};

MethodRegistry probe_registry() {
  MethodRegistry r;
  r.add({.name = "probe",
         .description = "test method",
         .params = {{"radius", ParamType::Int, "2", "window radius", 0.0, 10.0},
                    {"sigma", ParamType::Float, "0.5", "a sigma", 0.001, {}},
                    {"fast", ParamType::Bool, "false", "a switch"},
                    {"mode", ParamType::String, "a", "a mode", {}, {}, {"a", "b"}}},
         .create = [](const Params&) { return std::make_unique<Probe>(); }});
  r.add({.name = "other", .description = "another", .create = [](const Params&) { return std::make_unique<Probe>(); }});
  return r;
}

template <typename F>
std::string error_of(F f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  }
  return "(no InputError)";
}

TEST(MethodRegistry, UnknownMethodListsTheValidOnes) {
  auto r = probe_registry();
  EXPECT_THAT(error_of([&] { r.create("prob"); }), HasSubstr("unknown method 'prob' (valid methods: other, probe)"));
}

TEST(MethodRegistry, GlobalUnknownMethodListsBuiltins) {
  const std::string msg = error_of([] { MethodRegistry::global().create("no-such-method"); });
  EXPECT_THAT(msg, HasSubstr("unknown method 'no-such-method'"));
  for (const auto& name : MethodRegistry::global().names()) EXPECT_THAT(msg, HasSubstr(name));
}

TEST(MethodRegistry, UnknownParameterListsTheValidOnes) {
  auto r = probe_registry();
  EXPECT_THAT(error_of([&] { r.create("probe", {{"radious", "3"}}); }),
              HasSubstr("method 'probe' has no parameter 'radious' (valid parameters: radius, sigma, fast, mode)"));
  EXPECT_THAT(error_of([&] { r.create("other", {{"x", "3"}}); }), HasSubstr("(valid parameters: none)"));
}

TEST(MethodRegistry, BadValuesAreRefusedWithWhatIsExpected) {
  auto r = probe_registry();
  EXPECT_THAT(error_of([&] { r.create("probe", {{"radius", "2.5"}}); }),
              HasSubstr("parameter 'radius' = '2.5': expected an integer in [0, 10]"));
  EXPECT_THAT(error_of([&] { r.create("probe", {{"radius", "11"}}); }), HasSubstr("expected an integer in [0, 10]"));
  EXPECT_THAT(error_of([&] { r.create("probe", {{"radius", "-1"}}); }), HasSubstr("'radius' = '-1'"));
  EXPECT_THAT(error_of([&] { r.create("probe", {{"radius", "99999999999"}}); }), HasSubstr("'radius'"));
  EXPECT_THAT(error_of([&] { r.create("probe", {{"sigma", "0"}}); }), HasSubstr("expected a finite number >= 0.001"));
  EXPECT_THAT(error_of([&] { r.create("probe", {{"sigma", "nan"}}); }), HasSubstr("'sigma' = 'nan'"));
  EXPECT_THAT(error_of([&] { r.create("probe", {{"sigma", "inf"}}); }), HasSubstr("'sigma' = 'inf'"));
  EXPECT_THAT(error_of([&] { r.create("probe", {{"sigma", " 1"}}); }), HasSubstr("'sigma' = ' 1'"));
  EXPECT_THAT(error_of([&] { r.create("probe", {{"sigma", "1x"}}); }), HasSubstr("'sigma' = '1x'"));
  EXPECT_THAT(error_of([&] { r.create("probe", {{"sigma", ""}}); }), HasSubstr("'sigma' = ''"));
  EXPECT_THAT(error_of([&] { r.create("probe", {{"fast", "yes"}}); }), HasSubstr("expected true or false"));
  EXPECT_THAT(error_of([&] { r.create("probe", {{"mode", "c"}}); }), HasSubstr("expected one of a, b"));
}

TEST(MethodRegistry, ValuesParseToTheirTypes) {
  auto r = probe_registry();
  Params p = r.parse_params("probe", {{"radius", "7"}, {"sigma", "1e-2"}, {"fast", "on"}, {"mode", "b"}});
  EXPECT_EQ(p.i("radius"), 7);
  EXPECT_DOUBLE_EQ(p.f("sigma"), 0.01);
  EXPECT_DOUBLE_EQ(p.f("radius"), 7.0);  // an int reads as a float too
  EXPECT_TRUE(p.b("fast"));
  EXPECT_EQ(p.s("mode"), "b");
  Params d = r.parse_params("probe", {});
  EXPECT_EQ(d.as_strings(), (std::map<std::string, std::string>{
                                {"fast", "false"}, {"mode", "a"}, {"radius", "2"}, {"sigma", "0.5"}}));
  EXPECT_THROW(d.i("sigma"), WorkError);    // reading a float as an int is a programming error
  EXPECT_THROW(d.f("missing"), WorkError);  // so is reading an undeclared parameter
}

TEST(MethodRegistry, RegistrationMistakesAreCaught) {
  MethodRegistry r = probe_registry();
  auto make = [](const Params&) { return std::make_unique<Probe>(); };
  EXPECT_THROW(r.add({.name = "probe", .create = make}), WorkError);  // duplicate
  EXPECT_THROW(r.add({.name = "", .create = make}), WorkError);
  EXPECT_THROW(r.add({.name = "nocreate"}), WorkError);
  EXPECT_THROW(r.add({.name = "baddefault", .params = {{"k", ParamType::Int, "20", "k", 0.0, 10.0}}, .create = make}),
               WorkError);
  EXPECT_THROW(r.add({.name = "twice",
                      .params = {{"k", ParamType::Int, "1", "k"}, {"k", ParamType::Int, "1", "k"}},
                      .create = make}),
               WorkError);
}

TEST(MethodRegistry, BuiltinDefaultsAreDocumented) {
  for (const MethodInfo* m : MethodRegistry::global().all()) {
    EXPECT_FALSE(m->description.empty()) << m->name;
    for (const ParamSpec& p : m->params) {
      EXPECT_FALSE(p.doc.empty()) << m->name << "." << p.name;
      EXPECT_FALSE(p.default_value.empty()) << m->name << "." << p.name;
    }
    EXPECT_NO_THROW(MethodRegistry::global().create(m->name)) << m->name;
  }
}

TEST(ParseSettings, SplitsAndRefusesRepeats) {
  EXPECT_EQ(parse_settings({"a=1", "b=x=y", "c="}),
            (std::map<std::string, std::string>{{"a", "1"}, {"b", "x=y"}, {"c", ""}}));
  EXPECT_THAT(error_of([] { parse_settings({"a=1", "a=2"}); }), HasSubstr("parameter 'a' set twice"));
  EXPECT_THAT(error_of([] { parse_settings({"a"}); }), HasSubstr("expected key=value"));
  EXPECT_THAT(error_of([] { parse_settings({"=1"}); }), HasSubstr("expected key=value"));
}

TEST(RunMethod, RefusesAFrameMissingALayerNamingTheChannels) {
  AovFrame f = test::constant_frame(8, 4);
  AovFrame g(8, 4);
  g.set(layer::kColor, f.layer(layer::kColor));
  g.meta.scene = "cornell-box";
  Probe p;
  EXPECT_THAT(error_of([&] { run_method(p, {.frame = &g}); }),
              HasSubstr("frame of 'cornell-box' lacks channel depth.Z required by this method"));
  p.layers = {layer::kNormal, layer::kDirect};
  EXPECT_THAT(error_of([&] { run_method(p, {.frame = &g}); }),
              HasSubstr("lacks channels normal.X, normal.Y, normal.Z, direct.R, direct.G, direct.B"));
  EXPECT_THAT(error_of([&] { run_method(p, {}); }), HasSubstr("needs a frame with layers normal, direct"));
}

TEST(RunMethod, RefusesWrongChannelCountsAndAllNanLayers) {
  AovFrame f = test::constant_frame(8, 4);
  f.set(layer::kDepth, Image(8, 4, 3, 1.0f));
  Probe p;
  EXPECT_THAT(error_of([&] { run_method(p, {.frame = &f}); }), HasSubstr("layer 'depth' is 8x4 with 3 channels"));
  f.set(layer::kDepth, Image(8, 4, 1, std::numeric_limits<float>::quiet_NaN()));
  EXPECT_THAT(error_of([&] { run_method(p, {.frame = &f}); }), HasSubstr("layer 'depth' has no finite sample"));
}

TEST(RunMethod, RepairsNonFiniteSamplesFromTheirNeighboursAndCountsThem) {
  AovFrame f = test::constant_frame(8, 4);
  Image& c = f.layer(layer::kColor);
  for (std::size_t k = 0; k < c.size(); ++k) c.data()[k] = float(k % 3);  // channel index
  c.at(3, 2, 1) = std::numeric_limits<float>::quiet_NaN();
  c.at(0, 0, 2) = std::numeric_limits<float>::infinity();
  c.at(1, 0, 2) = -std::numeric_limits<float>::infinity();  // neighbour of (0,0): not used for it
  f.layer(layer::kDepth).at(7, 3, 0) = std::numeric_limits<float>::quiet_NaN();
  Probe p;
  MethodResult r = run_method(p, {.frame = &f});
  EXPECT_EQ(r.stats.counters.at("repaired_samples"), 4.0);
  EXPECT_GT(r.stats.counters.count("repair_seconds"), 0u);
  EXPECT_EQ(r.image.at(3, 2, 1), 1.0f);  // mean of its finite neighbours in channel 1
  EXPECT_EQ(r.image.at(0, 0, 2), 2.0f);
  EXPECT_EQ(r.image.at(1, 0, 2), 2.0f);
  EXPECT_EQ(p.seen.layer(layer::kDepth).at(7, 3, 0), 2.0f);
  // The caller's frame is left as it was.
  EXPECT_TRUE(std::isnan(f.layer(layer::kColor).at(3, 2, 1)));
  // Layers the method did not ask for are neither repaired nor counted.
  f.layer(layer::kNormal).at(0, 0, 0) = std::numeric_limits<float>::quiet_NaN();
  EXPECT_EQ(run_method(p, {.frame = &f}).stats.counters.at("repaired_samples"), 4.0);
}

TEST(RunMethod, ChecksTheOutput) {
  AovFrame f = test::constant_frame(8, 4);
  Probe p;
  p.output = [](const AovFrame&) { return Image(8, 4, 1); };
  EXPECT_THROW(run_method(p, {.frame = &f}), WorkError);
  p.output = [](const AovFrame&) { return Image(4, 4, 3); };
  EXPECT_THROW(run_method(p, {.frame = &f}), WorkError);
  p.output = [](const AovFrame&) {
    Image i(8, 4, 3);
    i.at(1, 1, 1) = std::numeric_limits<float>::quiet_NaN();
    return i;
  };
  EXPECT_THROW(run_method(p, {.frame = &f}), WorkError);
  p.output = nullptr;
  MethodResult r = run_method(p, {.frame = &f});
  EXPECT_EQ(r.stats.counters.at("repaired_samples"), 0.0);
  EXPECT_GT(r.stats.total_seconds, 0.0);  // timed: a run takes some time (0 is an unset stopwatch)
}

}  // namespace
}  // namespace dnb
