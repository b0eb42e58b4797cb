// docs/adding-a-method.md, proved: a method defined only here (the guide's worked example,
// verbatim) is registered, created by name with a parameter, run through run_method, and held
// to the same invariants as the built-in methods.
#include <gtest/gtest.h>

#include <opencv2/imgproc.hpp>

#include <fstream>
#include <sstream>

#include "core/errors.h"
#include "denoisers/synthetic_frame.h"
#include "test_util.h"

// ---- begin: the guide's denoisers/illum_blur.cpp ----
// illum_blur: a Gaussian blur of the untextured illumination L = D + I, composed back as
// F' = L' * T + R + E. Textures stay sharp because only the lighting is blurred; lighting
// edges (shadows, creases) are not protected. A teaching example, not a baseline.
//
// Parameters: the ParamSpec list at the end of this file (`denoisebench list methods`).
#include <opencv2/imgproc.hpp>

#include "denoisers/hdr_mapping.h"   // as_mat: an Image seen as a cv::Mat, no copy
#include "denoisers/illumination.h"  // illumination(), compose(), illumination_layers()
#include "denoisers/method.h"

namespace dnb {
namespace {

class IllumBlur final : public Method {
 public:
  explicit IllumBlur(const Params& p) : sigma_(p.f("sigma")) {}

  std::vector<std::string> required_layers() const override { return illumination_layers(); }

  MethodResult execute(const MethodInput& in) override {
    MethodResult r;
    Image light = illumination(*in.frame);
    Image blurred(light.width(), light.height(), 3);
    {
      ScopedPhase phase(r.stats, "blur");
      cv::Mat dst = as_mat(blurred);
      cv::GaussianBlur(as_mat(light), dst, cv::Size(0, 0), sigma_, sigma_, cv::BORDER_REFLECT);
    }
    r.image = compose(blurred, *in.frame);
    return r;
  }

 private:
  double sigma_;
};

}  // namespace

MethodInfo illum_blur_method() {
  return {
      .name = "illum_blur",
      .description = "Gaussian blur of the illumination D+I (worked example of docs/adding-a-method.md)",
      .kind = MethodKind::Filter,
      .params = {{"sigma", ParamType::Float, "2", "Gaussian standard deviation in pixels", 0.1, 50.0}},
      .create = [](const Params& p) { return std::make_unique<IllumBlur>(p); },
  };
}

}  // namespace dnb
// ---- end ----

namespace dnb {
namespace {

TEST(AddingAMethod, TheWorkedExampleRegistersAndRuns) {
  MethodRegistry registry;  // a registry of its own: the global list stays the built-ins
  registry.add(illum_blur_method());
  ASSERT_TRUE(registry.contains("illum_blur"));

  auto method = registry.create("illum_blur", {{"sigma", "1.5"}});
  EXPECT_EQ(method->required_layers(), illumination_layers());

  AovFrame noisy = test::planes_frame(96, 64, 0.3f);
  const Image truth = test::planes_frame(96, 64, 0.0f).layer(layer::kColor);
  MethodResult r = run_method(*method, {.frame = &noisy});
  EXPECT_EQ(r.image.width(), 96);
  ASSERT_EQ(r.stats.phases.size(), 1u);
  EXPECT_EQ(r.stats.phases[0].first, "blur");
  // It denoises: the blur of the lighting takes most of the noise away (measured 17x).
  EXPECT_LT(test::mse(r.image, truth), test::mse(noisy.layer(layer::kColor), truth) / 3);

  // It obeys the same rules as the built-ins.
  EXPECT_THROW(registry.create("illum_blur", {{"sigma", "0"}}), InputError);
  EXPECT_THROW(registry.create("illum_blur", {{"radius", "3"}}), InputError);
  AovFrame constant = test::constant_frame(20, 10);
  MethodResult c = run_method(*method, {.frame = &constant});
  for (std::size_t k = 0; k < c.image.size(); ++k) ASSERT_NEAR(c.image.data()[k], test::kConstantColor, 1e-6f);
}

std::string slurp(const std::string& path) {
  std::ifstream in(path);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// The guide shows the code above, character for character: the guide cannot drift from code
// that compiles and passes.
TEST(AddingAMethod, TheGuideShowsThisCode) {
  const std::string doc = slurp(test::source_dir() + "/docs/adding-a-method.md");
  const std::string self = slurp(test::source_dir() + "/tests/denoisers/adding_a_method_test.cpp");
  ASSERT_FALSE(doc.empty()) << "docs/adding-a-method.md not found under " << test::source_dir();
  const std::string begin = "// ---- begin: the guide's denoisers/illum_blur.cpp ----\n", end = "// ---- end ----";
  const auto b = self.find(begin) + begin.size();
  const std::string code = self.substr(b, self.find(end, b) - b);
  const auto fence = doc.find("```cpp\n") + 7;
  EXPECT_EQ(doc.substr(fence, doc.find("```", fence) - fence), code);
}

}  // namespace
}  // namespace dnb
