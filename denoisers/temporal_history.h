// What the temporal methods (temporal_accumulation, svgf_temporal) share: when a frame carries a
// method's history on (docs/sequences.md, "Temporal methods"), the checks of a sequence frame's
// input, and the parameters of the disocclusion test, which is the temporal metrics' own
// (metrics/temporal.h: the same Reprojection class and thresholds).
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "denoisers/method.h"
#include "metrics/temporal.h"

namespace dnb {

// Follows a method through the frames it is given.
//
// A frame continues the history when it is frame index > 0 of the sequence whose frame index - 1
// was the last one given. It starts afresh (method.h) when it has no SequenceFrame (a still: a
// one-frame sequence), is index 0, or names another sequence; and after reset(). Frame index > 0
// of the same sequence but not the next one (a frame skipped or repeated) is an InputError: the
// output would differ from an uninterrupted run's, which the harness must not record.
class SequenceCursor {
 public:
  // Whether `in` continues the history. InputError for a frame out of order, an index outside
  // 0 .. count - 1, or a frame index > 0 without the motion layer (naming motion.X, motion.Y).
  bool continues(const MethodInput& in) const;
  // Records `in` as the last frame given, once the method has finished it (so a frame that threw
  // leaves the cursor where it was).
  void advance(const MethodInput& in);
  void reset() { sequence_.reset(), index_ = -1; }

 private:
  std::optional<std::string> sequence_;
  int index_ = -1;
};

// What the built-in temporal methods are alike in: they read the demodulated illumination with
// normal and depth (denoisers/illumination.h), the motion layer where the frame has it (a still
// has none; a sequence frame after the first must: SequenceCursor), and follow their frames with
// a SequenceCursor, which reset() rewinds (a derived class's reset() calls this one).
class TemporalIlluminationMethod : public Method {
 public:
  std::vector<std::string> required_layers() const override;
  std::vector<std::string> optional_layers() const override { return {layer::kMotion}; }
  bool temporal() const override { return true; }
  void reset() override { cursor_.reset(); }

 protected:
  SequenceCursor cursor_;
};

// The disocclusion test's parameters (max_relative_depth, min_normal_cosine), their defaults
// metrics::SurfaceTest's; and the test they make.
std::vector<ParamSpec> surface_test_params();
metrics::SurfaceTest surface_test(const Params& p);

// The previous frame's depth and normal, which the disocclusion test compares with the current
// frame's: kept by the method from the frame it last finished (the run_method-repaired layers),
// rather than read from SequenceFrame::previous, so that history and guides always come from the
// same frame.
struct PreviousGuides {
  Image depth, normal;
  static PreviousGuides of(const AovFrame& f) { return {f.layer(layer::kDepth), f.layer(layer::kNormal)}; }
};

// Frame `f`'s history seen from the current frame: its motion layer and the disocclusion test
// against the previous frame's guides.
metrics::Reprojection reproject_history(const AovFrame& f, const PreviousGuides& previous,
                                        const metrics::SurfaceTest& test);

}  // namespace dnb
