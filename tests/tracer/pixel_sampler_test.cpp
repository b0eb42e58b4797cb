// render_frame with a PixelSampler (tracer/render.h): the main pass's samples come from it, every
// pixel's exactly once, in batches of at most batch_samples() / spp pixels, and the frame's layers
// are made from them by the tracer's own accumulation.
#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <limits>
#include <vector>

#include "tracer/integrator.h"
#include "tracer/render.h"
#include "tracer/scene.h"
#include "tracer/scene_loader.h"

namespace dnb {
namespace {

// Sample s of pixel (x, y): D = (x, y, s % 2), I = 1, T = 0.5, E = 0.25, normal +z, depth 2 + s % 2;
// one sample (pixel (nan_x, nan_y), sample 0) is NaN. Counts the calls per pixel.
class FakeSampler : public PixelSampler {
 public:
  FakeSampler(int w, int h, int batch) : width(w), calls(std::size_t(w) * std::size_t(h)), batch(batch) {
    for (auto& c : calls) c = 0;
  }
  std::uint64_t trace_pixels(int x0, int y, int count, int spp, rt::SampleResult* out) const override {
    EXPECT_GE(count, 1);
    EXPECT_LE(count, std::max(1, batch / spp));
    for (int p = 0; p < count; ++p) {
      ++calls[std::size_t(y) * std::size_t(width) + std::size_t(x0 + p)];
      for (int s = 0; s < spp; ++s) {
        rt::SampleResult& r = out[std::size_t(p) * std::size_t(spp) + std::size_t(s)];
        r.levels = 1;
        r.specular = rt::SpecularParts{};
        rt::LevelSample& l = r.level[0];
        l = rt::LevelSample{};
        l.present = true;
        l.direct = {float(x0 + p), float(y), float(s % 2)};
        l.indirect = rt::Vec3(1.0f);
        l.albedo = rt::Vec3(0.5f);
        l.emission = rt::Vec3(0.25f);
        l.normal = {0, 0, 1};
        l.depth = 2.0f + float(s % 2);
        if (x0 + p == nan_x && y == nan_y && s == 0) l.direct.x = std::numeric_limits<float>::quiet_NaN();
      }
    }
    return std::uint64_t(count) * std::uint64_t(spp) * 3;  // "three rays a sample"
  }
  int batch_samples() const override { return batch; }

  int width;
  int nan_x = 5, nan_y = 3;
  mutable std::vector<std::atomic<int>> calls;
  int batch;
};

TEST(PixelSampler, TracesTheMainPassAndTheLayersAreMadeFromItsSamples) {
  auto scene = load_scene("cornell-box");
  RenderSettings s;
  s.width = 40;  // not a multiple of the tile (16) nor of the batch (48 / 8 = 6 pixels)
  s.height = 20;
  s.spp = 8;
  s.threads = 2;
  FakeSampler fake(s.width, s.height, 48);
  const AovFrame f = render_frame(*scene, s, fake);
  for (const auto& c : fake.calls) EXPECT_EQ(c.load(), 1);
  EXPECT_EQ(f.meta.dropped_samples, 1);
  EXPECT_EQ(f.meta.extra.at("rays"), std::to_string(std::uint64_t(s.width) * s.height * s.spp * 3));
  const Image& color = f.layer(layer::kColor);
  const Image& direct = f.layer(layer::kDirect);
  const Image& depth = f.layer(layer::kDepth);
  const Image& samples = f.layer(layer::kSamples);
  for (int y = 0; y < s.height; ++y)
    for (int x = 0; x < s.width; ++x) {
      const bool nan_pixel = x == fake.nan_x && y == fake.nan_y;
      // The pixel's finite samples: all 8, or 7 without sample 0 (D.z = 0 in it).
      const double n = nan_pixel ? 7 : 8, odd = 4;
      const double dz = odd / n;
      EXPECT_EQ(samples.at(x, y, 0), float(n));
      EXPECT_FLOAT_EQ(direct.at(x, y, 0), float(x));
      EXPECT_FLOAT_EQ(direct.at(x, y, 1), float(y));
      EXPECT_NEAR(direct.at(x, y, 2), dz, 1e-6);
      EXPECT_NEAR(depth.at(x, y, 0), 2.0 + odd / n, 1e-6);
      // F = (D + I) T + E, the mean of the samples' colours.
      EXPECT_NEAR(color.at(x, y, 0), (x + 1) * 0.5 + 0.25, 1e-4 * (x + 1));
      EXPECT_NEAR(color.at(x, y, 2), (dz + 1) * 0.5 + 0.25, 1e-6);
    }
}

TEST(PixelSampler, OnePixelAtATimeWhenABatchHoldsLessThanOnePixel) {
  auto scene = load_scene("cornell-box");
  RenderSettings s;
  s.width = 8;
  s.height = 4;
  s.spp = 16;
  FakeSampler fake(s.width, s.height, 4);  // 4 / 16 < 1: one pixel a call
  fake.nan_x = -1;
  const AovFrame f = render_frame(*scene, s, fake);
  for (const auto& c : fake.calls) EXPECT_EQ(c.load(), 1);
  EXPECT_EQ(f.meta.dropped_samples, 0);
  EXPECT_FLOAT_EQ(f.layer(layer::kSamples).at(7, 3, 0), 16.0f);
}

}  // namespace
}  // namespace dnb
