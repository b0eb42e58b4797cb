// The built-in filters' factories, one per method file, for the method list in
// methods/registry.cpp (the layer above denoisers/ and irradiance_cache/). Adding a filter:
// its file defines `MethodInfo <name>_method()`, declared here, and registry.cpp adds it.
#pragma once

#include "denoisers/method.h"

namespace dnb {

MethodInfo am_method();         // denoisers/am.cpp
MethodInfo am_opencv_method();  // denoisers/am_opencv.cpp
MethodInfo atrous_method();     // denoisers/atrous.cpp
MethodInfo bilateral_method();  // denoisers/bilateral.cpp
MethodInfo guided_method();     // denoisers/guided.cpp
MethodInfo nfor_method();       // denoisers/nfor.cpp
MethodInfo nlmeans_method();    // denoisers/nlmeans.cpp
MethodInfo proposed_method();   // denoisers/proposed.cpp
MethodInfo svgf_method();       // denoisers/svgf.cpp
MethodInfo svgf_temporal_method();  // denoisers/svgf_temporal.cpp
MethodInfo temporal_accumulation_method();  // denoisers/temporal_accumulation.cpp

}  // namespace dnb
