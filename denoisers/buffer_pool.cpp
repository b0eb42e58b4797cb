// The scratch-memory pool (see buffer_pool.h).
#include "denoisers/buffer_pool.h"

#include <limits>

namespace dnb {

BufferPool& BufferPool::get() {
  static BufferPool pool;
  return pool;
}

std::vector<float> BufferPool::take(std::size_t n) {
  std::lock_guard<std::mutex> lock(m_);
  std::size_t best = free_.size();
  for (std::size_t i = 0; i < free_.size(); ++i)
    if (free_[i].capacity() >= n && (best == free_.size() || free_[i].capacity() < free_[best].capacity())) best = i;
  if (best == free_.size()) return {};
  std::vector<float> v = std::move(free_[best]);
  free_.erase(free_.begin() + std::ptrdiff_t(best));
  bytes_ -= v.capacity() * sizeof(float);
  return v;
}

void BufferPool::give(std::vector<float>&& v) {
  const std::size_t b = v.capacity() * sizeof(float);
  if (b < (std::size_t(1) << 20)) return;  // small buffers: malloc recycles them anyway
  std::lock_guard<std::mutex> lock(m_);
  if (bytes_ + b > kPoolBytes) return;
  bytes_ += b;
  free_.push_back(std::move(v));
}

std::vector<float> pooled(std::size_t n, float fill) {
  std::vector<float> v = BufferPool::get().take(n);
  v.assign(n, fill);
  return v;
}

std::vector<float> pooled_uninitialised(std::size_t n) {
  std::vector<float> v = BufferPool::get().take(n);
#ifdef DNB_POISON_POOL
  // Sanitizer builds (CMake's DNB_SANITIZE): every "overwritten in full" buffer starts as NaN, so
  // that a read of a value its user did not write shows as NaN in the output. AddressSanitizer
  // cannot see such a read: the memory is allocated, only stale (a fresh buffer reads as zeros,
  // a recycled one as the last user's values, so the output would depend on what ran before).
  v.assign(n, std::numeric_limits<float>::quiet_NaN());
#else
  v.resize(n);
#endif
  return v;
}

}  // namespace dnb
