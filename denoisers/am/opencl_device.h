// The OpenCL core for callers whose images already live on the device (proposed's pipeline,
// denoisers/proposed_opencl.cpp): the process's OpenCL state (am/opencl.cpp: one context, queue,
// program cache and buffer pool), pooled buffers, and the adaptive-manifold filter on planar
// device images. Internal to the denoisers library; only in builds with OpenCL.
#pragma once

#ifdef DNB_WITH_OPENCL
#define CL_HPP_ENABLE_EXCEPTIONS
#include <CL/opencl.hpp>

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "denoisers/am/adaptive_manifold.h"

namespace dnb::am_cl {

// The process's queue (in order: every command sees the ones enqueued before it).
cl::CommandQueue& queue();
// The device computes in double where it has cl_khr_fp64 (the kernels' `real`).
bool device_has_fp64();
// The program of the core's and proposed's kernels for guide and source channel counts.
cl::Program program(int dims, int chans);
// DENOISEBENCH_OPENCL_PROFILE is set: callers time their steps.
bool profiling();

// A device buffer from the pool, given back when it goes (safe while commands that use it are
// still queued: the queue is in order).
class Pooled {
 public:
  Pooled() = default;
  explicit Pooled(std::size_t bytes);
  ~Pooled();
  Pooled(Pooled&& o) noexcept : bytes_(o.bytes_), buf_(std::move(o.buf_)) { o.bytes_ = 0; }
  Pooled& operator=(Pooled&& o) noexcept;
  Pooled(const Pooled&) = delete;
  Pooled& operator=(const Pooled&) = delete;
  const cl::Buffer& operator*() const { return buf_; }
  cl::Buffer& operator*() { return buf_; }
  std::size_t bytes() const { return bytes_; }
  bool empty() const { return bytes_ == 0; }

 private:
  std::size_t bytes_ = 0;
  cl::Buffer buf_;
};

// Slice queries whose data is on the device: pixel (x, y) pairs, guides (D floats each) and
// source values (C floats each, every query adjusted towards its own value, as proposed's edge
// sub-pixels are); `runs` (host): the first query of each run of queries at one pixel, then the count.
struct DeviceQueries {
  std::size_t count = 0;
  cl::Buffer xy, guide, src;
  std::vector<int> runs;
};

// am_filter() on the device: src (C planes of width x height) filtered with guide (D planes);
// the output into `out` (C planes) and the queries' answers (C floats each) into `answers`.
// `seed` seeds the split vectors (the CPU path hashes its guide; any function of the input keeps
// the result deterministic). Nothing is read back; the host does not wait.
void am_filter_planar(const cl::Buffer& src, const cl::Buffer& guide, int width, int height, int C, int D,
                      std::uint64_t seed, const AmSettings& settings, const DeviceQueries* queries, const cl::Buffer& out,
                      const cl::Buffer* answers);

}  // namespace dnb::am_cl
#endif
