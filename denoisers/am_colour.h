// What the two adaptive-manifold methods on the colour, `am` (our core) and `am_opencv`
// (OpenCV's), share: one definition of their parameters, read into one settings struct, and
// their guide (the colour in a range-compressed domain). Defined in am.cpp.
#pragma once

#include <string>
#include <vector>

#include "denoisers/adaptive_manifold.h"
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

}  // namespace dnb
