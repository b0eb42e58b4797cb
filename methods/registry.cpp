// The list of built-in methods: the one place that knows every method, above the folders that
// define them (denoisers/, irradiance_cache/). Adding a method is one source file, its factory's
// declaration in its folder's header, and one line here. Keep the lines sorted by name.
#include "denoisers/builtin_methods.h"
#include "denoisers/method.h"
#include "irradiance_cache/irradiance_cache.h"

namespace dnb {

void register_builtin_methods(MethodRegistry& r) {
  r.add(am_method());
  r.add(am_opencv_method());
  r.add(atrous_method());
  r.add(bilateral_method());
  r.add(guided_method());
  r.add(irradiance_cache_method());
  r.add(nfor_method());
  r.add(nlmeans_method());
  r.add(proposed_method());
  r.add(svgf_method());
  r.add(svgf_temporal_method());
  r.add(temporal_accumulation_method());
}

// Defined here, not in denoisers/method.cpp, so that linking anything that uses the global
// registry pulls in this list (dnb_methods) and with it every method.
MethodRegistry& MethodRegistry::global() {
  static MethodRegistry r = [] {
    MethodRegistry reg;
    register_builtin_methods(reg);
    return reg;
  }();
  return r;
}

}  // namespace dnb
