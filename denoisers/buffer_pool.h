// Scratch memory for the full-resolution passes of the filters: a process-wide pool of large
// float buffers, and the planar image type built on it (Planes).
//
// What it caches: std::vector<float> buffers of at least 1 MiB that their users give back, up
// to kPoolBytes in all; take(n) hands out the smallest cached buffer that holds n floats (or an
// empty vector: the caller then allocates). Smaller buffers are not kept (malloc recycles them).
//
// Why: the adaptive-manifold filter needs per call a few hundred megabytes of planes (1024x768
// with a 10-channel guide: about 100 MB for the guide's copy alone, and as much again for the
// weights of a group of manifolds, the accumulators and the query sums). Fresh allocations of
// that size are mapped by the kernel page by page on first touch, and those page faults cost
// more than a pass over the data; recycled buffers are already mapped. Every call of a method
// that runs that filter (proposed runs it 2-6 times per frame, concurrently) draws from here.
//
// Thread-safety: take() and give() lock one mutex and may be called from any thread; a buffer
// belongs to its taker alone until it is given back. The pool only grows to kPoolBytes, and
// what it holds is freed at exit.
#pragma once

#include <cstddef>
#include <mutex>
#include <utility>
#include <vector>

namespace dnb {

class BufferPool {
 public:
  // The process's pool.
  static BufferPool& get();
  // A cached buffer with capacity for at least n floats (its size and contents unspecified),
  // or an empty vector when none is cached.
  std::vector<float> take(std::size_t n);
  // Returns a buffer to the pool (kept when it is at least 1 MiB and the pool has room).
  void give(std::vector<float>&& v);

 private:
  BufferPool() = default;
  static constexpr std::size_t kPoolBytes = std::size_t(512) << 20;
  std::mutex m_;
  std::vector<std::vector<float>> free_;
  std::size_t bytes_ = 0;
};

// n floats set to `fill`, in a recycled buffer when one is cached.
std::vector<float> pooled(std::size_t n, float fill);
// For a buffer its user overwrites whole: a recycled one keeps its stale values (shrinking a
// vector writes nothing; only growth beyond its size value-initialises the tail).
std::vector<float> pooled_uninitialised(std::size_t n);

// Planar float images: channel c of pixel (x, y) at data[(c * h + y) * w + x], the storage
// from the pool (given back when the planes are destroyed or assigned over).
struct Planes {
  int w = 0, h = 0, n = 0;
  std::vector<float> data;
  Planes() = default;
  Planes(int w_, int h_, int n_) : w(w_), h(h_), n(n_), data(pooled(std::size_t(w_) * h_ * n_, 0.0f)) {}
  // Contents unspecified: for planes the caller writes in full before reading.
  struct Overwritten {};
  Planes(int w_, int h_, int n_, Overwritten) : w(w_), h(h_), n(n_), data(pooled_uninitialised(std::size_t(w_) * h_ * n_)) {}
  Planes(const Planes& o) : w(o.w), h(o.h), n(o.n), data(BufferPool::get().take(o.data.size())) {
    data.assign(o.data.begin(), o.data.end());
  }
  Planes(Planes&&) = default;
  Planes& operator=(Planes&& o) {
    BufferPool::get().give(std::move(data));
    w = o.w, h = o.h, n = o.n, data = std::move(o.data);
    return *this;
  }
  Planes& operator=(const Planes&) = delete;
  ~Planes() { BufferPool::get().give(std::move(data)); }
  float* plane(int c) { return data.data() + std::size_t(c) * w * h; }
  const float* plane(int c) const { return data.data() + std::size_t(c) * w * h; }
  float* row(int c, int y) { return plane(c) + std::size_t(y) * w; }
  const float* row(int c, int y) const { return plane(c) + std::size_t(y) * w; }
};

}  // namespace dnb
