// What the two adaptive-manifold methods on the colour, `am` (our core) and `am_opencv`
// (OpenCV's), share: one definition of their parameters, read into one settings struct, and
// their guide (the colour in a range-compressed domain). Defined in am.cpp.
#pragma once

#include <string>
#include <vector>

#include "denoisers/am/adaptive_manifold.h"
#include "denoisers/hdr_mapping.h"
#include "denoisers/method.h"

namespace dnb {

struct ColourAmSettings {
  AmSettings am;  // sigma_s, sigma_r, tree_height, pca_iterations, adjust_outliers
  RangeMap range_map = RangeMap::Reinhard;
};

// The parameter specs of both methods; pca_iterations_doc says what an iteration is in each.
std::vector<ParamSpec> colour_am_params(const std::string& pca_iterations_doc);
ColourAmSettings read_colour_am(const Params& p);

// The guide: the colour compressed by `map` (timed as the phase "guide").
Image colour_am_guide(const Image& color, RangeMap map, MethodStats& stats);

// Both methods' frame: the colour in, the guide made (colour_am_guide), the filter timed as
// the phase "adaptive_manifolds". A method supplies the filter.
class ColourAmMethod : public Method {
 public:
  explicit ColourAmMethod(const Params& p) : settings_(read_colour_am(p)) {}
  std::vector<std::string> required_layers() const override { return {layer::kColor}; }
  MethodResult execute(const MethodInput& in) final;

 protected:
  // The filtered colour, guided by the compressed colour; counters go into stats.
  virtual Image filter(const Image& color, const Image& guide, MethodStats& stats) const = 0;
  const AmSettings& settings() const { return settings_.am; }

 private:
  ColourAmSettings settings_;
};

}  // namespace dnb
