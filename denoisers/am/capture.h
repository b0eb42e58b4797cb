// The adaptive-manifold core's inputs (source, guide, settings, slice queries) recorded to files,
// so that the core can be run and timed on another machine without the harness and its libraries
// (bench/device/am_device.cpp: a GPU's OpenCL driver; docs/opencl-gpu.md). A developer's
// facility, off unless DENOISEBENCH_AM_CAPTURE names a folder: then every call of am_filter() and am_filter_opencl() writes its
// inputs there as am-<pid>-<n>.bin (n counts the process's calls from 1), whole or not at all
// (written to a temporary name, then renamed). DENOISEBENCH_AM_CAPTURE_MAX=N keeps only the first N calls
// (a benchmark's warm-up run, say).
//
//   DENOISEBENCH_AM_CAPTURE=/tmp/cap build/denoisebench denoise proposed FRAME.exr -o out.exr
//   DENOISEBENCH_AM_CAPTURE=/tmp/cap DENOISEBENCH_AM_CAPTURE_MAX=4 build/bench/denoisebench_bench --benchmark_filter='^proposed/cpu/1024x768/0/'
#pragma once

#include <string>
#include <vector>

#include "denoisers/am/adaptive_manifold.h"

namespace dnb {

// Writes the call's inputs when DENOISEBENCH_AM_CAPTURE is set (a failed write is a WorkError naming the
// file); does nothing otherwise.
void am_capture_if_asked(ConstImageView src, ConstImageView guide, const AmSettings& settings,
                         const std::vector<AmQuery>& queries);

// One recorded call. `queries` point into query_guide and query_src (keep the object in place).
struct AmCapture {
  Image src, guide;
  AmSettings settings;
  std::vector<float> query_guide, query_src;
  std::vector<AmQuery> queries;
};

// Reads a file written by am_capture_if_asked; InputError naming the file and what is wrong when
// it is not one (wrong magic or version, sizes out of range, truncated).
AmCapture read_am_capture(const std::string& path);

}  // namespace dnb
