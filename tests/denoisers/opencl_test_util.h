// What the OpenCL tests of this folder share.
#pragma once

#include <string>

#include <gtest/gtest.h>

#include "denoisers/am/opencl.h"

namespace dnb::test {

// True when an OpenCL device answers. A build with OpenCL but no device is a failure (CI has
// PoCL); a build without OpenCL skips.
inline bool have_opencl() {
  std::string why;
  if (am_opencl_available(&why)) return true;
#ifdef DNB_WITH_OPENCL
  ADD_FAILURE() << "built with OpenCL but no device: " << why;
#endif
  return false;
}

}  // namespace dnb::test
