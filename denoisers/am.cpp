// am: the plain adaptive-manifold filter (Gastal and Oliveira 2012) on the colour image F, the
// paper's "adaptive manifolds" baseline (Table 1). Like the bilateral filter it sees only the
// colour, so texture and noise are smoothed alike. The core is denoisers/adaptive_manifold.h.
//
// HDR: the guide (the space in which sigma_r measures distances) is the colour in a range-
// compressed domain (denoisers/hdr_mapping.h, default reinhard: [0, inf) -> [0, 1), where
// Gastal and Oliveira's sigma_r = 0.2 for [0, 1] images keeps its meaning); the filtered
// values are the linear colour itself, so the weighted means are unbiased (no Jensen darkening).
//
// Parameters: the ParamSpec list below, shared with am_opencv (am_colour.h); `denoisebench list
// methods` prints it. How the defaults were chosen: docs/method-defaults.md.
#include "denoisers/am_colour.h"

namespace dnb {
namespace {

class Am final : public ColourAmMethod {
 public:
  using ColourAmMethod::ColourAmMethod;

 private:
  Image filter(const Image& color, const Image& guide, MethodStats& stats) const override {
    const AmSettings& s = settings();
    stats.counters["tree_height"] = s.tree_height > 0 ? s.tree_height : am_tree_height(s.sigma_s, s.sigma_r);
    return am_filter(color.cview(), guide.cview(), s);
  }
};

}  // namespace

std::vector<ParamSpec> colour_am_params(const std::string& pca_iterations_doc) {
  return {
      {"sigma_s", ParamType::Float, "4", "spatial standard deviation, pixels", 1.0, 512.0},
      {"sigma_r", ParamType::Float, "0.05", "range standard deviation, compressed-colour units", 1e-3, 1.0},
      {"tree_height", ParamType::Int, "0", "manifold tree height; 0: from sigma_s and sigma_r", 0.0, 12.0},
      {"pca_iterations", ParamType::Int, "1", pca_iterations_doc, 1.0, 100.0},
      {"adjust_outliers", ParamType::Bool, "true", "Gastal and Oliveira's outlier adjustment (eq. 11)"},
      {"range_map", ParamType::String, "reinhard", "domain of the guide (denoisers/hdr_mapping.h)", {}, {},
       range_map_names()},
  };
}

ColourAmSettings read_colour_am(const Params& p) {
  ColourAmSettings s;
  s.am.sigma_s = p.f("sigma_s");
  s.am.sigma_r = p.f("sigma_r");
  s.am.tree_height = p.i("tree_height");
  s.am.pca_iterations = p.i("pca_iterations");
  s.am.adjust_outliers = p.b("adjust_outliers");
  s.range_map = parse_range_map(p.s("range_map"));
  return s;
}

Image colour_am_guide(const Image& color, RangeMap map, MethodStats& stats) {
  Image guide = color;
  ScopedPhase p(stats, "guide");
  compress(map, guide);
  return guide;
}

MethodResult ColourAmMethod::execute(const MethodInput& in) {
  MethodResult r;
  const Image& color = in.frame->layer(layer::kColor);
  const Image guide = colour_am_guide(color, settings_.range_map, r.stats);
  ScopedPhase p(r.stats, "adaptive_manifolds");
  r.image = filter(color, guide, r.stats);
  return r;
}

MethodInfo am_method() {
  return {
      .name = "am",
      .description = "adaptive-manifold filter (Gastal and Oliveira 2012) on the colour, guided by the compressed colour",
      .kind = MethodKind::Filter,
      .params = colour_am_params("power-iteration steps of each manifold split"),
      .create = [](const Params& p) { return std::make_unique<Am>(p); },
  };
}

}  // namespace dnb
