// The paper's decomposition F = (D + I) * T + R + E (its formula 1 plus the emission E seen
// directly; docs/paper.md), shared by the methods that filter the untextured illumination instead of the colour (guided, atrous):
// filtering L = D + I lets a pixel borrow lighting from neighbours with a different texture,
// so textures stay sharp. The tracer writes D and I already demodulated (untextured), so no
// division by the albedo is needed.
#pragma once

#include <string>
#include <vector>

#include "core/aov_frame.h"
#include "core/image.h"
#include "denoisers/method.h"

namespace dnb {

// Layers compose() and illumination() read: direct, indirect, albedo, reflection, emission.
std::vector<std::string> illumination_layers();

// L = D + I at the first non-specular hit (3 channels).
Image illumination(const AovFrame& frame);

// F' = L' * T + R + E with the filtered illumination L'. R and E pass through unfiltered.
Image compose(const Image& filtered_illumination, const AovFrame& frame);
// F' = L' * T + R' + E with a filtered reflection R' as well.
Image compose(const Image& filtered_illumination, const AovFrame& frame, const Image& filtered_reflection);

// The guide layers of the first reflection level (paper 3.2): what the mirror shows, i.e. the
// albedo, normal and depth of the hit seen through it (refl1.albedo, refl1.normal, refl1.depth).
// A filter of R uses them as L's filter uses the level-0 layers.
std::vector<std::string> reflection_guide_layers();

// What a guided filter of L reads (guided, atrous): illumination_layers(), the normal and the
// depth, and with filter_reflection also reflection_guide_layers() for the filter of R.
std::vector<std::string> illumination_filter_layers(bool filter_reflection);

// Depth divided by the median of its positive finite values, so that depth-based weights and
// guides work the same in a room of 5 m and a hall of 50 m. Pixels that hit nothing (depth 0 or
// not finite) get 0.
// `level` 1 reads refl1.depth (the reflection level's depth) instead.
Image normalized_depth(const AovFrame& frame, int level = 0);

// A rectangle of pixels.
struct PixelBox {
  int x = 0, y = 0, w = 0, h = 0;
  bool empty() const { return w <= 0 || h <= 0; }
};
// The median of the positive finite depths of `depth` inside box b, 1 when there are none: the
// divisor of normalized_depth (over a crop: proposed's reflection levels, on either device).
float median_depth(const Image& depth, const PixelBox& b);
// Bounding box of the pixels with a non-zero channel, grown by `margin` and clipped to the
// image; empty when there are none.
PixelBox nonzero_box(const Image& image, int margin);

// A reflection tint (reflK.tint) averaged over each pixel's neighbours on the same surface.
// The tracer picks a coated surface's specular lobe per sample with probability pc (its Fresnel
// term clamped to [0.2, 0.8], tracer/integrator.cpp) and records tint * fr / pc on those samples,
// 0 on the others, so a pixel's tint is unbiased but carries the binomial noise of that choice,
// relative standard deviation sqrt((1 - pc) / (pc N)) <= 2 / sqrt(N) for N samples (12.5% at
// 256 spp), while its expectation (tint * fr) varies smoothly over a surface. The filtered
// reflection is multiplied by it, so without this the noise reaches the image unfiltered (on
// conference's table it was most of the error of the reflective pixels).
// Each pixel with a non-zero tint gets the mean tint of the pixels q of its (2r+1)^2 window
// that are on the same surface (unit normals within `max_normal_distance`, Euclidean, and
// normalised depths, normalized_depth(), within `max_depth_distance`) and whose tint is within
// the noise band: |t_q - t_p| <= max_relative_deviation * t_p (t: the sum over R, G, B). The
// band keeps what is not noise: a mirror's edge on a coplanar wall (no edge pixel: same normal
// and depth) gives its pixels a partial coverage, a step in the tint that lies outside it.
// Pixels with a zero tint stay 0 and give nothing; pixels marked in `keep` (edge pixels:
// several surfaces in one pixel) keep their own tint and give nothing. Deterministic.
Image smooth_tint(const Image& tint, const Image& normal, const Image& normalized_depth, int radius,
                  float max_relative_deviation, float max_normal_distance, float max_depth_distance,
                  const std::vector<char>* keep = nullptr);

// Firefly split of an illumination layer: `kept` is the layer with every pixel whose Rec. 709
// luminance exceeds `ratio` times the largest luminance of its 8 neighbours scaled down to that
// bound; `excess` = layer - kept (zero except at those pixels); `bound` holds each pixel's bound
// (luminance), for clamping the pixel's edge sub-pixels alike.
// Why: a 256-spp frame carries rare paths (a small bright source seen through a specular
// bounce) as single pixels hundreds of times brighter than their neighbours. An edge-aware
// filter keeps such a pixel distinct or smears it into a blotch of its own kernel's shape;
// their expected light is spread thinly over the whole surface, which only a very wide
// low-pass of `excess` estimates. ratio <= 0: nothing is cut (excess and bound stay empty).
// with_excess = false leaves `excess` empty (for callers that drop the cut light).
struct FireflySplit {
  Image kept, excess;
  std::vector<float> bound;
  std::size_t cut = 0;  // pixels cut
};
FireflySplit split_fireflies(Image layer, float ratio, bool with_excess = true);
// The `firefly_ratio` parameter of the baselines that cut L's fireflies before filtering it, as
// proposed does (atrous, guided): one spec, so its doc and bounds cannot drift apart.
ParamSpec firefly_ratio_param();

// Clamps the luminance of `rgb` to `bound` (scaling all channels alike).
void clamp_luminance(float rgb[3], float bound);

}  // namespace dnb
