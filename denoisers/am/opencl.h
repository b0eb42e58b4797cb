// The adaptive-manifold core on OpenCL (kernels in denoisers/am/adaptive_manifold.cl): splat, blur,
// slice, split, the split directions (the D x D power iteration of am_detail::split_direction,
// from the same start vectors, so both paths split the same way) and the slice queries' answers
// run as kernels; the host only enqueues the tree, level by level, and never waits for the device
// before the read-back. Output matches am_filter() up to float summation order (relative RMS
// difference well below 1e-4, tests/denoisers/opencl_test.cpp).
//
// Device: the first device of the first OpenCL platform (PoCL's CPU device here, any GPU
// elsewhere); DENOISEBENCH_OPENCL_PLATFORM=<index> picks another platform. Programs are built once per
// process for each (guide channels, source channels) pair and cached; PoCL also caches the
// binaries in POCL_CACHE_DIR across processes.
#pragma once

#include <string>
#include <vector>

#include "denoisers/am/adaptive_manifold.h"

namespace dnb {

// True when the build has OpenCL and a device answers; `why` says what is missing otherwise.
bool am_opencl_available(std::string* why = nullptr);

// The platform and device the OpenCL path runs on ("platform / device"), or "" when none.
std::string am_opencl_device_name();

// am_filter() on the OpenCL device. Throws WorkError when OpenCL is unavailable or fails.
Image am_filter_opencl(ConstImageView src, ConstImageView guide, const AmSettings& settings,
                       const std::vector<AmQuery>& queries = {}, std::vector<float>* query_out = nullptr);

}  // namespace dnb
