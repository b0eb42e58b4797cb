// The irradiance-cache renderer as a method (irradiance_cache.cpp): a renderer-type method that
// renders the scene itself with an irradiance cache instead of filtering the input frame.
#pragma once

#include "denoisers/method.h"

namespace dnb {

MethodInfo irradiance_cache_method();

}  // namespace dnb
