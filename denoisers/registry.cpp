// The list of built-in methods: adding a method is one source file plus one line here.
// Each method's file defines `MethodInfo <name>_method()`; its line declares that function and
// adds what it returns (a block-scope extern declaration, so the list needs no header).
// Keep the lines sorted by name.
#include "denoisers/method.h"

namespace dnb {

void register_builtin_methods(MethodRegistry& r) {
  extern MethodInfo am_method(); r.add(am_method());                // denoisers/am.cpp
  extern MethodInfo am_opencv_method(); r.add(am_opencv_method());  // denoisers/am_opencv.cpp
  extern MethodInfo atrous_method(); r.add(atrous_method());        // denoisers/atrous.cpp
  extern MethodInfo bilateral_method(); r.add(bilateral_method());  // denoisers/bilateral.cpp
  extern MethodInfo guided_method(); r.add(guided_method());        // denoisers/guided.cpp
  extern MethodInfo irradiance_cache_method(); r.add(irradiance_cache_method());  // irradiance_cache/irradiance_cache.cpp
  extern MethodInfo nlmeans_method(); r.add(nlmeans_method());      // denoisers/nlmeans.cpp
  extern MethodInfo proposed_method(); r.add(proposed_method());    // denoisers/proposed.cpp
}

// Defined here, not in method.cpp, so that linking anything that uses the global registry pulls
// in this list (dnb_methods) and with it every method.
MethodRegistry& MethodRegistry::global() {
  static MethodRegistry r = [] {
    MethodRegistry reg;
    register_builtin_methods(reg);
    return reg;
  }();
  return r;
}

}  // namespace dnb
