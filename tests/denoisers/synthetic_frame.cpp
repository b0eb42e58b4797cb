#include "denoisers/synthetic_frame.h"

#include <algorithm>
#include <cmath>
#include <random>
#include <stdexcept>

namespace dnb::test {

static void fill(Image& img, std::initializer_list<float> v) {
  for (std::size_t p = 0; p < img.pixel_count(); ++p) {
    int c = 0;
    for (float x : v) img.data()[p * img.channels() + c++] = x;
  }
}

AovFrame constant_frame(int width, int height) {
  AovFrame f(width, height);
  for (int level = 0; level <= 1; ++level) {
    auto n = [&](const char* base) { return layer::at_level(level, base); };
    if (level == 0) fill(f.add(layer::kColor, 3), {kConstantColor, kConstantColor, kConstantColor});
    fill(f.add(n(layer::kDirect), 3), {0.3f, 0.3f, 0.3f});
    fill(f.add(n(layer::kIndirect), 3), {0.2f, 0.2f, 0.2f});
    fill(f.add(n(layer::kAlbedo), 3), {0.5f, 0.5f, 0.5f});
    fill(f.add(n(layer::kReflection), 3), {0.05f, 0.05f, 0.05f});
    fill(f.add(n(layer::kEmission), 3), {0, 0, 0});
    fill(f.add(n(layer::kNormal), 3), {0, 0, 1});
    fill(f.add(n(layer::kDepth), 1), {2});
    fill(f.add(n(layer::kVariance), 3), {0.01f, 0.01f, 0.01f});
    fill(f.add(n(layer::kDirectVariance), 3), {0.01f, 0.01f, 0.01f});
    fill(f.add(n(layer::kIndirectVariance), 3), {0.01f, 0.01f, 0.01f});
    if (level == 0) {
      fill(f.add(layer::kEdge, 1), {0});
      fill(f.add(layer::kSamples, 1), {64});
    } else {
      // R = tint * F at level 1 (the tracer's contract, tracer/integrator.h): 0.05 = tint * 0.3.
      fill(f.add(n(layer::kTint), 3), {kConstantTint, kConstantTint, kConstantTint});
    }
  }
  set_halves(f);
  f.meta.scene = "synthetic-constant";
  f.meta.spp = 64;
  f.meta.reflection_levels = 1;
  return f;
}

AovFrame planes_frame(int width, int height, float noise_sigma, std::uint64_t seed) {
  AovFrame f = constant_frame(width, height);
  f.meta.scene = "synthetic-planes";
  f.meta.seed = seed;
  std::mt19937_64 rng(seed);
  std::normal_distribution<float> gauss(0.0f, 1.0f);
  Image& color = f.layer(layer::kColor);
  Image& direct = f.layer(layer::kDirect);
  Image& indirect = f.layer(layer::kIndirect);
  Image& albedo = f.layer(layer::kAlbedo);
  Image& normal = f.layer(layer::kNormal);
  Image& depth = f.layer(layer::kDepth);
  Image& reflection = f.layer(layer::kReflection);
  const float s = 0.70710678f;
  Image noise_sd(width, height, 3);
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x) {
      const bool left = x < width / 2;
      const float u = float(x) / float(std::max(width - 1, 1)), v = float(y) / float(std::max(height - 1, 1));
      const float nx = left ? -s : s;
      normal.at(x, y, 0) = nx, normal.at(x, y, 1) = 0, normal.at(x, y, 2) = s;
      depth.at(x, y, 0) = left ? 3.0f + u : 4.0f - 0.5f * u;
      const float tex = ((x / 8 + y / 8) % 2) ? 0.75f : 0.25f;
      for (int c = 0; c < 3; ++c) {
        const float d = (left ? 0.8f : 0.3f) * (0.6f + 0.4f * v) * (1.0f + 0.1f * c);
        const float i = 0.2f + 0.1f * u;
        const float dn = std::max(0.0f, d * (1.0f + noise_sigma * gauss(rng)));
        const float in = std::max(0.0f, i * (1.0f + noise_sigma * gauss(rng)));
        direct.at(x, y, c) = dn;
        indirect.at(x, y, c) = in;
        albedo.at(x, y, c) = tex;
        reflection.at(x, y, c) = 0.02f;
        f.layer(layer::at_level(1, layer::kTint)).at(x, y, c) = 0.02f / kConstantColor;  // R = tint * F1
        color.at(x, y, c) = (dn + in) * tex + 0.02f;
        noise_sd.at(x, y, c) = noise_sigma * tex * std::sqrt(d * d + i * i);
      }
    }
  set_halves(f, &noise_sd, seed + 1);
  return f;
}

void set_halves(AovFrame& f, const Image* sd, std::uint64_t seed) {
  for (int h = 0; h < 2; ++h)
    for (const char* b : {layer::kColor, layer::kDirect, layer::kIndirect, layer::kAlbedo, layer::kNormal, layer::kDepth})
      if (std::string(b) != layer::kColor) f.set(layer::at_half(h, b), f.layer(b));
  Image h0 = f.layer(layer::kColor), h1 = h0;
  if (sd) {
    std::mt19937_64 rng(seed);
    std::normal_distribution<float> gauss(0.0f, 1.0f);
    for (std::size_t k = 0; k < h0.size(); ++k) {
      const float e = sd->data()[k] * gauss(rng);
      h0.data()[k] += e;
      h1.data()[k] -= e;
    }
  }
  f.set(layer::at_half(0, layer::kColor), std::move(h0));
  f.set(layer::at_half(1, layer::kColor), std::move(h1));
}

double mse(const Image& a, const Image& b) {
  if (!a.same_shape(b)) throw std::invalid_argument("mse: shapes differ");
  double s = 0;
  for (std::size_t k = 0; k < a.size(); ++k) {
    const double d = double(a.data()[k]) - double(b.data()[k]);
    s += d * d;
  }
  return s / double(a.size());
}

}  // namespace dnb::test
