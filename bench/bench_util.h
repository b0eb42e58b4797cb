// Shared pieces of denoisebench_bench: rendered input frames (from the render cache, so that
// preparing them is paid once per machine, never inside a timed loop), a thread-count guard, a
// CPU-time clock and the fixed reference workload the nightly performance ratios divide by.
#pragma once

#include <map>
#include <memory>
#include <string>

#include "core/aov_frame.h"
#include "tracer/render.h"

namespace dnb {
class Scene;
}

namespace dnb::bench {

// The built-in scene `name` (loaded once per process).
std::shared_ptr<const Scene> scene(const std::string& name);

// The AOV frame of `scene` at w x h and `spp` samples per pixel (seed 1, the runner's
// settings), from the render cache ($DENOISEBENCH_CACHE or ~/.cache/denoisebench): rendered
// and stored on the first use on a machine, read from the cache afterwards, kept in memory
// for the rest of the process.
const AovFrame& rendered_frame(const std::string& scene, int w, int h, int spp);

// The tracer's settings for a speed case: w x h, `spp`, path length `max_depth`, the rest the
// defaults (every AOV, two reflection levels, edge sub-pixels, seed 1, all cores).
RenderSettings render_settings(int w, int h, int spp, int max_depth);

// Limits TBB and OpenCV to `threads` threads while alive (0: leave them at all cores).
class ThreadLimit {
 public:
  explicit ThreadLimit(int threads);
  ~ThreadLimit();
  ThreadLimit(const ThreadLimit&) = delete;
  ThreadLimit& operator=(const ThreadLimit&) = delete;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// Seconds of CPU time used by the whole process (every thread) so far.
double process_cpu_seconds();
// Seconds on a monotonic wall clock.
double wall_seconds();

// The reference workload of the nightly performance gate: a fixed small path-tracing job
// (the built-in cornell-box, 32x24 pixels, 4 spp, path length 8, colour only; a few ms on
// one core). Methods are timed as multiples of it, which cancels most of a machine's speed
// and of its momentary load, so the gate can compare runs on a shared machine.
class ReferenceWorkload {
 public:
  explicit ReferenceWorkload(int threads);
  void run() const;
  static std::string description();

 private:
  std::shared_ptr<const Scene> scene_;
  int threads_;
};

}  // namespace dnb::bench
