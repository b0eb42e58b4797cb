#include "denoisers/temporal_history.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "core/errors.h"
#include "denoisers/illumination.h"

namespace dnb {

bool SequenceCursor::continues(const MethodInput& in) const {
  if (!in.sequence) return false;
  const SequenceFrame& s = *in.sequence;
  if (s.count < 1 || s.index < 0 || s.index >= s.count)
    throw InputError(fmt::format("sequence '{}': frame index {} outside 0 .. {}", s.sequence, s.index, s.count - 1));
  if (s.index > 0 && in.frame && !in.frame->has(layer::kMotion))
    throw InputError(fmt::format("sequence '{}': frame {} lacks channels {} (the motion layer), which a temporal "
                                 "method needs to reproject its history after frame 0",
                                 s.sequence, s.index, fmt::join(channel_names(layer::kMotion, 2), ", ")));
  if (s.index == 0 || !sequence_ || *sequence_ != s.sequence) return false;
  if (s.index != index_ + 1)
    throw InputError(fmt::format("sequence '{}': frame {} given after frame {}; a temporal method needs the frames in "
                                 "order from 0 (docs/sequences.md)",
                                 s.sequence, s.index, index_));
  return true;
}

void SequenceCursor::advance(const MethodInput& in) {
  if (!in.sequence) return reset();
  sequence_ = in.sequence->sequence;
  index_ = in.sequence->index;
}

std::vector<ParamSpec> surface_test_params() {
  const metrics::SurfaceTest d;
  return {
      {"max_relative_depth", ParamType::Float, fmt::format("{}", d.max_relative_depth),
       "disocclusion test: history is kept where |z - z_prev| <= this * max(z, z_prev)", 0.0, 10.0},
      {"min_normal_cosine", ParamType::Float, fmt::format("{}", d.min_normal_cosine),
       "disocclusion test: history is kept where n . n_prev >= this (unit normals)", -1.0, 1.0},
  };
}

metrics::SurfaceTest surface_test(const Params& p) {
  return {.max_relative_depth = float(p.f("max_relative_depth")), .min_normal_cosine = float(p.f("min_normal_cosine"))};
}

metrics::Reprojection reproject_history(const AovFrame& f, const PreviousGuides& previous,
                                        const metrics::SurfaceTest& test) {
  return metrics::Reprojection(f.layer(layer::kMotion), f.layer(layer::kDepth), f.layer(layer::kNormal), previous.depth,
                               previous.normal, test);
}

std::vector<std::string> TemporalIlluminationMethod::required_layers() const {
  auto l = illumination_layers();
  l.emplace_back(layer::kNormal);
  l.emplace_back(layer::kDepth);
  return l;
}

}  // namespace dnb
