// Invariants every registered filter-type method must keep. The tests loop over
// MethodRegistry::global().all(), so a method added later is covered without a new line here.
// Frames are synthetic (tests/denoisers/synthetic_frame.h): no tracer involved.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>


#include "core/errors.h"
#include "denoisers/am/opencl.h"
#include "denoisers/method.h"
#include "denoisers/synthetic_frame.h"
#include "thread_count.h"

namespace dnb {
namespace {

// Every filter at its defaults, and the filters' other devices as "NAME@KEY=VALUE" (proposed's
// whole filter on an OpenCL device, in builds with OpenCL: PoCL in CI), so that a device path
// keeps the same invariants. (OpenCL is not started here: listing the tests must not start
// PoCL's threads, which LeakSanitizer's exit check trips over, docs/sanitizers.md.)
std::vector<std::string> filter_names() {
  std::vector<std::string> out;
  for (const MethodInfo* m : MethodRegistry::global().all())
    if (m->kind == MethodKind::Filter) out.push_back(m->name);
#ifdef DNB_WITH_OPENCL
  out.push_back("proposed@device=opencl");
#endif
  return out;
}

class FilterInvariants : public ::testing::TestWithParam<std::string> {
 protected:
  void SetUp() override {
    std::string why;
    if (GetParam().find("device=opencl") != std::string::npos && !am_opencl_available(&why))
      FAIL() << "built with OpenCL but no device: " << why;  // CI has PoCL
  }
  std::string name() const { return GetParam().substr(0, GetParam().find('@')); }
  std::map<std::string, std::string> set() const {
    const std::size_t at = GetParam().find('@');
    if (at == std::string::npos) return {};
    const std::string kv = GetParam().substr(at + 1);
    return {{kv.substr(0, kv.find('=')), kv.substr(kv.find('=') + 1)}};
  }
  std::unique_ptr<Method> method() const { return MethodRegistry::global().create(name(), set()); }
  MethodResult run(const AovFrame& f) const {
    auto m = method();
    return run_method(*m, {.frame = &f, .seed = 1});
  }
};

// The synthetic frames hold every layer of the contract at levels 0 and 1: a method that needs
// another layer must add it to synthetic_frame.cpp (this test says which).
TEST_P(FilterInvariants, SyntheticFramesHoldTheRequiredLayers) {
  AovFrame f = test::constant_frame(4, 4);
  EXPECT_TRUE(f.missing_channels(method()->required_layers()).empty())
      << "add these layers to tests/denoisers/synthetic_frame.cpp";
}

// A constant frame (every layer constant, colour = formula 1) gives that constant colour back.
// Tolerance: 1e-5 relative, a few float roundings of a weighted mean (sum w v / sum w) and of a
// range map and its inverse (exp/log, pow); a method that quantizes must make a flat region
// come back exactly anyway (see nlmeans).
TEST_P(FilterInvariants, ConstantImageStaysConstant) {
  for (auto [w, h] : {std::pair{48, 32}, std::pair{7, 5}}) {
    MethodResult r = run(test::constant_frame(w, h));
    float worst = 0;
    for (std::size_t k = 0; k < r.image.size(); ++k)
      worst = std::max(worst, std::abs(r.image.data()[k] - test::kConstantColor));
    EXPECT_LE(worst, 1e-5f * test::kConstantColor) << w << "x" << h;
  }
}

TEST_P(FilterInvariants, KeepsSizeAndChannels) {
  for (auto [w, h] : {std::pair{37, 23}, std::pair{5, 3}, std::pair{1, 1}, std::pair{64, 1}}) {
    const AovFrame f = test::planes_frame(w, h, 0.2f);
    MethodResult r = run(f);
    EXPECT_EQ(r.image.width(), w);
    EXPECT_EQ(r.image.height(), h);
    EXPECT_EQ(r.image.channels(), 3);
    // And the image is the frame's, not a black or blank one of the right shape:
    // its mean brightness is the input colour's within 10%. A filter averages nearby
    // pixels, which keeps the mean but for the weights at the crease and the borders (measured
    // at most 2.5%, am at 5x3); a black, halved or doubled image is far outside. 1x1 included:
    // the firefly cut used to bound a pixel without neighbours by 0 and return it black.
    double in = 0, out = 0;
    for (std::size_t k = 0; k < r.image.size(); ++k) in += f.layer(layer::kColor).data()[k], out += r.image.data()[k];
    ASSERT_GT(in, 0.0);
    EXPECT_NEAR(out / in, 1.0, 0.1) << w << "x" << h << ": mean " << out / r.image.size() << ", input's " << in / r.image.size();
  }
}

// NaN and +-Inf samples in every layer the method reads are repaired before it runs and
// counted; the output is finite (run_method checks that and throws otherwise).
TEST_P(FilterInvariants, NonFiniteInputIsRepairedAndCounted) {
  AovFrame f = test::planes_frame(40, 30, 0.2f);
  const float bad[] = {std::numeric_limits<float>::quiet_NaN(), std::numeric_limits<float>::infinity(),
                       -std::numeric_limits<float>::infinity()};
  int injected = 0;
  for (const auto& name : method()->required_layers()) {
    Image& img = f.layer(name);
    for (int k = 0; k < 3; ++k) {
      img.at(5 + 11 * k, 3 + 9 * k, k % img.channels()) = bad[k];
      ++injected;
    }
  }
  MethodResult r = run(f);
  EXPECT_EQ(r.stats.counters.at("repaired_samples"), double(injected));
  EXPECT_EQ(count_non_finite(r.image.view()), 0u);
}

// Extreme but finite values in any one layer the method reads (a guide such as normal, depth or
// albedo, or a colour layer) give a finite output: 1e30 and -1e30 (an emitter seen directly,
// a far-away depth), and 1e-30 (values whose squares underflow to 0). Set in a block and in
// scattered pixels, one layer and one value at a time, so a failure names both.
TEST_P(FilterInvariants, ExtremeFiniteInputGivesFiniteOutput) {
  const auto expect_finite_output = [&](const AovFrame& f, const std::string& what) {
    try {
      MethodResult r = run(f);
      EXPECT_EQ(count_non_finite(r.image.view()), 0u) << what;
    } catch (const std::exception& e) {
      ADD_FAILURE() << what << ": " << e.what();
    }
  };
  for (float value : {1e30f, -1e30f, 1e-30f}) {
    for (const auto& name : method()->required_layers()) {
      AovFrame f = test::planes_frame(40, 30, 0.2f);
      Image& img = f.layer(name);
      for (int y = 10; y < 16; ++y)
        for (int x = 12; x < 20; ++x)
          for (int c = 0; c < img.channels(); ++c) img.at(x, y, c) = value;
      for (int k = 0; k < 40 * 30; k += 37) img.data()[std::size_t(k) * img.channels()] = value;
      expect_finite_output(f, "layer " + name + " holding " + std::to_string(value) + " in places");
      // And the whole layer at that value (a frame of nothing but a directly seen emitter).
      AovFrame g = test::planes_frame(40, 30, 0.2f);
      std::fill(g.layer(name).data(), g.layer(name).data() + g.layer(name).size(), value);
      expect_finite_output(g, "layer " + name + " holding " + std::to_string(value) + " everywhere");
    }
  }
}

// The same input gives the bit-identical output: twice in a row on four threads, and on one
// (an explicit count, since the default is one thread on a one-core runner).
TEST_P(FilterInvariants, BitIdenticalOutputWhateverTheThreadCount) {
  AovFrame f = test::planes_frame(96, 64, 0.3f);
  MethodResult a, b, c;
  const int threads = test::run_on_threads(4, [&] {
    a = run(f);
    b = run(f);
  });
  ASSERT_GT(threads, 1) << "the many-thread runs had one thread: the comparison would be 1 against 1";
  EXPECT_TRUE(a.image == b.image) << "two runs on the same frame differ";
  EXPECT_EQ(test::run_on_threads(1, [&] { c = run(f); }), 1);
  EXPECT_TRUE(a.image == c.image) << "the one-thread run differs from the " << threads << "-thread run";
}

// A method reads no layer beyond its required_layers() and optional_layers(): `denoise` reads
// only those from the file (methods/denoise.cpp, to keep a 1920x1080 frame's 0.9 GB of layers
// out of memory), so a layer the lists forget would change its output there and not in `run`.
// The frame keeps only the listed layers (and the edge sub-pixels) and must give the same bits.
TEST_P(FilterInvariants, ReadsNoLayerItDoesNotDeclare) {
  const AovFrame full = test::planes_frame(48, 32, 0.3f);
  auto m = method();
  const std::vector<std::string> listed = m->read_layers();
  AovFrame only(full.width(), full.height());
  only.meta = full.meta;
  only.edges = full.edges;
  for (const auto& [name, image] : full.layers())
    if (std::find(listed.begin(), listed.end(), name) != listed.end()) only.set(name, image);
  ASSERT_LT(only.layers().size(), full.layers().size()) << "the frame holds no layer beyond the lists: no test";
  const MethodResult a = run(full), b = run(only);
  EXPECT_TRUE(a.image == b.image) << GetParam() << " reads a layer outside its required and optional lists";
}

// With its defaults, a filter lowers the error of a noisy flat frame (the constant frame with
// 10% relative Gaussian noise on direct and indirect, the colour composed from them) against the
// noise-free one. Flat, because there is nothing a filter could rightly keep: whether it keeps
// edges, gradients or texture depends on the method and its tuning and is tested per method
// (colour filters such as am blur texture, which is the paper's point). The bound (at most half
// the input's MSE) is loose on purpose.
// A temporal method (MethodInfo::temporal) is scored on the last frame of a static sequence of
// 8 such frames with independent noise (zero motion), given in order: what it denoises with is
// its history, and temporal_accumulation has no spatial filter to denoise a single frame with.
TEST_P(FilterInvariants, ReducesNoiseOnAFlatFrame) {
  const AovFrame truth = test::constant_frame(96, 64);
  const auto noisy_frame = [&](unsigned seed) {
    AovFrame noisy = truth;
    std::mt19937 rng(seed);
    std::normal_distribution<float> gauss(0.0f, 1.0f);
    Image& d = noisy.layer(layer::kDirect);
    Image& i = noisy.layer(layer::kIndirect);
    Image& c = noisy.layer(layer::kColor);
    const Image& t = noisy.layer(layer::kAlbedo);
    const Image& r = noisy.layer(layer::kReflection);
    for (std::size_t k = 0; k < c.size(); ++k) {
      d.data()[k] *= 1.0f + 0.1f * gauss(rng);
      i.data()[k] *= 1.0f + 0.1f * gauss(rng);
      c.data()[k] = (d.data()[k] + i.data()[k]) * t.data()[k] + r.data()[k];
    }
    // The halves carry the colour's noise too (for the filters that read them: nfor): the
    // colour's standard deviation, 0.1 T sqrt(D^2 + I^2).
    Image sd(96, 64, 3);
    for (std::size_t k = 0; k < sd.size(); ++k) sd.data()[k] = 0.1f * 0.5f * std::sqrt(0.3f * 0.3f + 0.2f * 0.2f);
    test::set_halves(noisy, &sd);
    noisy.add(layer::kMotion, 2);  // zero motion: a static camera (a still method does not read it)
    return noisy;
  };
  const int frames = MethodRegistry::global().info(name()).temporal ? 8 : 1;
  auto m = method();
  AovFrame previous, noisy;
  for (int t = 0; t < frames; ++t) {
    previous = std::move(noisy);
    noisy = noisy_frame(5 + t);
    const SequenceFrame seq{.sequence = "flat", .index = t, .count = frames, .previous = t ? &previous : nullptr};
    if (t + 1 < frames) run_method(*m, {.frame = &noisy, .sequence = &seq, .seed = 1});
  }
  const SequenceFrame last{.sequence = "flat", .index = frames - 1, .count = frames,
                           .previous = frames > 1 ? &previous : nullptr};
  const MethodResult out = run_method(*m, {.frame = &noisy, .sequence = frames > 1 ? &last : nullptr, .seed = 1});
  const double before = test::mse(noisy.layer(layer::kColor), truth.layer(layer::kColor));
  const double after = test::mse(out.image, truth.layer(layer::kColor));
  RecordProperty("mse_ratio", std::to_string(before / after));
  EXPECT_LT(after, 0.5 * before) << "input MSE " << before << ", output MSE " << after;
}

// Taking away any one required layer gets the frame refused, naming that layer's EXR channels.
TEST_P(FilterInvariants, RefusesAFrameMissingARequiredLayer) {
  const AovFrame full = test::constant_frame(8, 6);
  for (const auto& name : method()->required_layers()) {
    AovFrame f(8, 6);
    for (const auto& [n, img] : full.layers())
      if (n != name) f.set(n, img);
    try {
      run(f);
      ADD_FAILURE() << "a frame without '" << name << "' was accepted";
    } catch (const InputError& e) {
      for (const auto& ch : channel_names(name, default_channels(name)))
        EXPECT_NE(std::string(e.what()).find(ch), std::string::npos) << e.what() << " does not name " << ch;
    }
  }
}

// Every parameter refuses values outside what its spec accepts, before the method exists.
TEST_P(FilterInvariants, RefusesBadParameterValues) {
  const MethodInfo& info = MethodRegistry::global().info(name());
  for (const ParamSpec& p : info.params) {
    std::vector<std::string> bad;
    switch (p.type) {
      case dnb::ParamType::Float:
        bad = {"abc", "nan", "inf", ""};
        break;
      case dnb::ParamType::Int:
        bad = {"abc", "1.5", ""};
        break;
      case dnb::ParamType::Bool:
        bad = {"maybe", ""};
        break;
      case dnb::ParamType::String:
        if (!p.choices.empty()) bad = {"no-such-choice"};
        break;
    }
    if (p.min) bad.push_back(std::to_string(*p.min - 1));
    if (p.max) bad.push_back(std::to_string(*p.max + 1));
    for (const auto& v : bad) {
      try {
        std::map<std::string, std::string> bad_set = set();
        bad_set[p.name] = v;
        MethodRegistry::global().create(name(), bad_set);
        ADD_FAILURE() << p.name << "=" << v << " was accepted";
      } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find(p.name), std::string::npos) << e.what();
      }
    }
  }
}

INSTANTIATE_TEST_SUITE_P(AllFilters, FilterInvariants, ::testing::ValuesIn(filter_names()),
                         [](const auto& info) {
                           std::string n = info.param;
                           for (char& ch : n)
                             if (!std::isalnum(static_cast<unsigned char>(ch))) ch = '_';
                           return n;
                         });

}  // namespace
}  // namespace dnb
