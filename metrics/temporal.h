// Reprojection between consecutive frames of a sequence and the temporal metrics
// (docs/temporal-metrics.md): library code, no I/O.
//
// Reprojection. Frame t's motion layer (core/aov_frame.h, motion.X/Y) holds, per pixel c, the
// offset in pixels from c's centre to where its surface was in frame t - 1 (x right, y down). The
// history of c is frame t - 1 fetched bilinearly at film position (x + 0.5 + motion.X,
// y + 0.5 + motion.Y), pixel centres at half-integers. The temporal methods (temporal_accumulation,
// svgf_temporal) reproject their history with this same code, so what the metrics call a
// disocclusion is what the methods reject.
//
//   metrics::Reprojection r(motion, depth, normal, previous_depth, previous_normal);
//   Image history = r.warp(previous_output);   // 0 where r.valid(pixel) is false
//
// Metrics, on the 8-bit sRGB scale of `mse` (metrics.h: exposure 1, clamp, sRGB, x255, rounded),
// per pixel the mean over R, G, B; W the warp of frame t - 1 onto frame t by frame t's motion
// with the disocclusion test, V_t the pixels it finds valid:
//   tmse              mean over t >= 1 and p in V_t of ((O_t - W O_{t-1}) - (R_t - W R_{t-1}))^2:
//                     the output's frame-to-frame change less the reference's, so flicker
//                     counts and true motion does not.
//   disocclusion_mse  per frame, mse(O_t, R_t) over the pixels not in V_t (those without
//                     history); the sequence's value is the mean over the frames that have any:
//                     what ghosting and slow history build-up raise.
//
// Determinism: every pixel is computed on its own and sums run in pixel order, so results do
// not depend on threads (none are used).
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <vector>

#include "core/image.h"
#include "metrics/metrics.h"

namespace dnb::metrics {

// When a pixel of the previous frame shows the surface a pixel of the current frame shows (the
// disocclusion test). Depth is the distance camera -> first hit, 0 (or not finite) for a miss.
//   - A miss matches only a miss (the sky seen before and now; nothing to compare but that).
//   - Depths agree within max_relative_depth of the larger: the depth layer is measured from each
//     frame's own camera, so a surface point's depth changes by up to the camera's displacement
//     between frames; 10% lets the camera move a tenth of the distance to what it sees per frame,
//     while a silhouette usually separates depths by more (a ball 1 m in front of a wall 4 m
//     away: 25%). Relative, like the filters' normalised depth, so it is the same in a room and
//     in a hall.
//   - Unit normals have a dot product of at least min_normal_cosine (0.9: 25.8 degrees). Normals
//     are in world space, so the camera's motion does not turn them; an object's rotation does,
//     and so does an edge between two faces at the same depth (a fold, a box's corner), which the
//     depth test alone would miss.
struct SurfaceTest {
  float max_relative_depth = 0.1f;
  float min_normal_cosine = 0.9f;
};
bool same_surface(float depth, const float* normal, float previous_depth, const float* previous_normal,
                  const SurfaceTest& test);

// The smallest share of its bilinear weight a pixel must keep after the disocclusion test drops
// taps to count as having history (SVGF's reference code's 0.01): below it, the position is
// essentially on a tap that failed.
inline constexpr float kMinHistoryWeight = 0.01f;

// Where each pixel of the current frame finds its history in the previous one: the bilinear taps
// at c + motion(c), edges clamped (a position within half a pixel of the border reads the border
// pixel, as a GPU sampler in clamp-to-edge mode).
//
// Hand-written, not cv::remap: remap's bilinear weights are fixed-point, quantised to 1/32 pixel
// (INTER_BITS 5), so a motion of 0.3 px would warp as 0.3125 px, and it has no per-tap test
// (SVGF drops the taps of other surfaces and renormalises the rest).
class Reprojection {
 public:
  // Every tap kept; a pixel is valid when its position is inside the image, [0, w] x [0, h]
  // (a non-finite motion is outside).
  explicit Reprojection(const Image& motion);
  // The disocclusion test as well: taps of nonzero weight whose previous pixel fails
  // same_surface() with the current pixel are dropped and the rest renormalised; a pixel is valid
  // when inside and the kept taps carry at least kMinHistoryWeight of the weight.
  // InputError unless motion has 2 channels, depths 1, normals 3, all of one size.
  Reprojection(const Image& motion, const Image& depth, const Image& normal, const Image& previous_depth,
               const Image& previous_normal, const SurfaceTest& test = {});

  int width() const { return w_; }
  int height() const { return h_; }
  bool valid(std::size_t pixel) const {
    const float* w = taps_[pixel].weight;
    return w[0] + w[1] + w[2] + w[3] > 0;
  }
  // 1 channel: 1 where a pixel has history, 0 where not.
  Image mask() const;
  // Pixels without history.
  std::size_t invalid_count() const;
  // `previous` (any channel count, this frame's size) seen from the current frame: each pixel the
  // weighted sum of its kept taps, 0 where not valid. InputError on another size.
  Image warp(const Image& previous) const;
  // The same for one pixel into out[0 .. previous.channels() - 1] (the caller checked the size).
  void warp_pixel(const Image& previous, std::size_t pixel, float* out) const;

 private:
  struct Taps {
    std::int32_t index[4];  // pixel indices of the previous frame
    float weight[4];        // renormalised over the kept taps; all 0 when the pixel is not valid
  };
  void place(const Image& motion, const Image* depth, const Image* normal, const Image* previous_depth,
             const Image* previous_normal, const SurfaceTest& test);
  int w_ = 0, h_ = 0;
  std::vector<Taps> taps_;
};

// `previous` fetched bilinearly at each pixel's film position (x + 0.5 + motion.X,
// y + 0.5 + motion.Y), and `valid` (1 channel) 1 where that position is inside the image.
struct Reprojected {
  Image image;
  Image valid;
};
Reprojected reproject(const Image& previous, const Image& motion);

// 1 where the pixel has history (inside the image, and the previous frame's depth and normal
// around its position agree with its own: Reprojection's rules), 0 where it is disoccluded.
Image disocclusion_mask(const Image& motion, const Image& depth, const Image& normal, const Image& previous_depth,
                        const Image& previous_normal, const SurfaceTest& test = {});

// One frame's terms. `map` is per pixel (1 channel, 0 where the pixel does not count); `value`
// the mean over the pixels that count (NaN when none does); `sum` and `count` what it is the mean
// of, for pooling over frames.
struct FrameTerm {
  MetricResult result;
  double sum = 0;
  std::size_t count = 0;
};

// Frame t's tmse term: the pixels valid in `history`, the warps W by it. O and R (output and
// reference, 3 channels) at t and t - 1. InputError on unequal shapes or non-finite samples.
FrameTerm tmse_frame(const Image& output, const Image& previous_output, const Image& reference,
                     const Image& previous_reference, const Reprojection& history);
// Frame t's disocclusion_mse term: the 8-bit mse of output against reference over the pixels
// `history` finds not valid.
FrameTerm disocclusion_mse_frame(const Image& output, const Image& reference, const Reprojection& history);

// One frame of a sequence for TemporalScorer: the method's output, the reference, and the
// frame's motion, depth and normal (the same for every method scored on the sequence; the
// reference render's where it has them, the converged ones).
struct TemporalFrame {
  const Image* output = nullptr;
  const Image* reference = nullptr;
  const Image* motion = nullptr;  // frame 0's is not read (it holds zeros)
  const Image* depth = nullptr;
  const Image* normal = nullptr;
};

struct TemporalScores {
  double tmse = 0;  // pooled over every frame t >= 1 and its valid pixels; NaN with none
  double disocclusion_mse = 0;  // mean of the per-frame values over the frames that have any; NaN if none has
  // Per frame, index t (frame 0: NaN for both, as it has no previous frame).
  std::vector<double> tmse_per_frame;
  std::vector<double> disocclusion_mse_per_frame;  // NaN where no pixel is disoccluded
  std::vector<std::size_t> disoccluded_pixels;     // per frame (0 at frame 0)
};

// The temporal metrics of one method's run over a sequence, fed frame by frame in index order
// from 0 (it keeps only the previous frame, as the run does).
class TemporalScorer {
 public:
  explicit TemporalScorer(const SurfaceTest& test = {}) : test_(test) {}
  // InputError on a missing image, unequal sizes or wrong channel counts.
  void add(const TemporalFrame& frame);
  TemporalScores scores() const;

 private:
  struct Previous {
    Image output, reference, depth, normal;
  };
  SurfaceTest test_;
  std::optional<Previous> previous_;
  TemporalScores scores_;
  double tmse_sum_ = 0;
  std::size_t tmse_count_ = 0;
};

}  // namespace dnb::metrics
