// am: the plain adaptive-manifold filter (Gastal and Oliveira 2012) on the colour image F, the
// paper's "adaptive manifolds" baseline (Table 1). Like the bilateral filter it sees only the
// colour, so texture and noise are smoothed alike. The core is denoisers/adaptive_manifold.h.
//
// HDR: the guide (the space in which sigma_r measures distances) is the colour in a range-
// compressed domain (denoisers/hdr_mapping.h, default reinhard: [0, inf) -> [0, 1), where
// Gastal and Oliveira's sigma_r = 0.2 for [0, 1] images keeps its meaning); the filtered
// values are the linear colour itself, so the weighted means are unbiased (no Jensen darkening).
//
// Parameters: the ParamSpec list below, the same list as am_opencv's; `denoisebench list
// methods` prints it. How the defaults were chosen: docs/method-defaults.md.
#include "denoisers/adaptive_manifold.h"
#include "denoisers/hdr_mapping.h"
#include "denoisers/method.h"

namespace dnb {
namespace {

class Am final : public Method {
 public:
  explicit Am(const Params& p) : map_(parse_range_map(p.s("range_map"))) {
    s_.sigma_s = p.f("sigma_s");
    s_.sigma_r = p.f("sigma_r");
    s_.tree_height = p.i("tree_height");
    s_.pca_iterations = p.i("pca_iterations");
    s_.adjust_outliers = p.b("adjust_outliers");
  }

  std::vector<std::string> required_layers() const override { return {layer::kColor}; }

  MethodResult execute(const MethodInput& in) override {
    MethodResult r;
    const Image& color = in.frame->layer(layer::kColor);
    Image guide = color;
    {
      ScopedPhase p(r.stats, "guide");
      compress(map_, guide);
    }
    {
      ScopedPhase p(r.stats, "adaptive_manifolds");
      r.image = am_filter(color.cview(), guide.cview(), s_);
    }
    r.stats.counters["tree_height"] = s_.tree_height > 0 ? s_.tree_height : am_tree_height(s_.sigma_s, s_.sigma_r);
    return r;
  }

 private:
  AmSettings s_;
  RangeMap map_;
};

}  // namespace

MethodInfo am_method() {
  return {
      .name = "am",
      .description = "adaptive-manifold filter (Gastal and Oliveira 2012) on the colour, guided by the compressed colour",
      .kind = MethodKind::Filter,
      .params =
          {
              {"sigma_s", ParamType::Float, "4", "spatial standard deviation, pixels", 1.0, 512.0},
              {"sigma_r", ParamType::Float, "0.05", "range standard deviation, compressed-colour units", 1e-3, 1.0},
              {"tree_height", ParamType::Int, "0", "manifold tree height; 0: from sigma_s and sigma_r", 0.0, 12.0},
              {"pca_iterations", ParamType::Int, "1", "power-iteration steps of each manifold split", 1.0, 100.0},
              {"adjust_outliers", ParamType::Bool, "true", "Gastal and Oliveira's outlier adjustment (eq. 11)"},
              {"range_map", ParamType::String, "reinhard", "domain of the guide (denoisers/hdr_mapping.h)", {}, {},
               range_map_names()},
          },
      .create = [](const Params& p) { return std::make_unique<Am>(p); },
  };
}

}  // namespace dnb
