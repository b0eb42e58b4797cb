// Synthetic AOV frames for the method tests, built in memory (no tracer): every test knows the
// noise-free answer exactly.
#pragma once

#include <cstdint>

#include "core/aov_frame.h"

namespace dnb::test {

// Every layer of the frame contract (docs/design.md) at levels 0 and 1, each filled with a constant:
// direct 0.3, indirect 0.2, albedo 0.5, reflection 0.05, emission 0, colour 0.3 (= formula 1),
// normal (0, 0, 1), depth 2, variances 0.01, edge 0, samples 64, half buffers equal to the full
// layers (set_halves), refl1.* the same as level 0
// with tint 1/6, so that R = tint * F1 holds as in a tracer's frame (0.05 = 0.3 / 6). A filter
// must return this colour everywhere.
AovFrame constant_frame(int width, int height);
inline constexpr float kConstantColor = 0.3f;
inline constexpr float kConstantTint = 0.05f / 0.3f;

// A smooth scene: two planes meeting at a vertical line x = width / 2 (different normals and
// depths), a smooth illumination gradient that jumps at the crease, an 8-pixel checkerboard
// albedo (0.25 / 0.75), small constant reflection (0.02, with refl1.tint = 0.02 / 0.3 so that
// R = tint * F1 holds) and no emission. With noise_sigma > 0,
// Gaussian noise of that standard deviation (relative to the local illumination) is added to
// direct and indirect, and the colour is composed from the noisy layers, as a path tracer's
// would be, and the colour's noise is split into independent half buffers (set_halves). The same
// seed gives the same frame.
AovFrame planes_frame(int width, int height, float noise_sigma, std::uint64_t seed = 7);

// Sets the half buffers (core/aov_frame.h: half0.*, half1.*) from the frame's full layers: the
// features (albedo, normal, depth; direct, indirect) copied, and the colour split into two
// independent halves whose mean is the colour: half0 = F + e, half1 = F - e with e Gaussian of
// standard deviation sd(x, y, c), the colour's own noise there (then each half has twice the
// colour's variance and the halves are uncorrelated, as the tracer's are). sd = 0: copies.
void set_halves(AovFrame& f, const Image* colour_noise_sd = nullptr, std::uint64_t seed = 11);

// Mean squared error between two images of equal shape.
double mse(const Image& a, const Image& b);

}  // namespace dnb::test
