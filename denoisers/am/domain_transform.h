// The domain-transform recursive filter (Gastal and Oliveira 2011, "Domain Transform for
// Edge-Aware Image and Video Processing", section 4, RF): per direction one causal and one
// anti-causal pass out[x] += a_x (out[x-1] - out[x]), a_x the feedback of the edge between x-1
// and x. The adaptive-manifold filter (adaptive_manifold.h) uses it twice: with a per-edge
// feedback a^(geodesic distance) as the blur along a manifold (recursive_filter, on planar
// images), and with a constant feedback as the low-pass of its h_filter (low_pass, on
// pixel-interleaved images).
//
// Compile the users of this header with -fno-trapping-math -fno-math-errno (as
// denoisers/CMakeLists.txt does for the adaptive-manifold files): the loops only vectorise so.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstring>
#include <memory>
#include <vector>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "denoisers/buffer_pool.h"
#include "denoisers/am/transpose8.h"

namespace dnb::domain_transform {

// The vertical half of recursive_filter: columns are independent, split into 64-wide chunks.
template <typename WV>
void recursive_filter_vertical(Planes& p, int first, int count, WV wv) {
  const int w = p.w, h = p.h;
  constexpr int kChunk = 64;
  tbb::parallel_for(0, (w + kChunk - 1) / kChunk, [&](int chunk) {
    const int x0 = chunk * kChunk, x1 = std::min(w, x0 + kChunk);
    for (int c = first; c < first + count; ++c) {
      for (int y = 1; y < h; ++y) {
        const float* a = wv(y - 1);
        float* r = p.row(c, y);
        const float* q = p.row(c, y - 1);
        for (int x = x0; x < x1; ++x) r[x] += a[x] * (q[x] - r[x]);
      }
      for (int y = h - 2; y >= 0; --y) {
        const float* a = wv(y);
        float* r = p.row(c, y);
        const float* q = p.row(c, y + 1);
        for (int x = x0; x < x1; ++x) r[x] += a[x] * (q[x] - r[x]);
      }
    }
  });
}

// The horizontal recursion runs along x, so in planar rows it is a scalar dependency chain per
// channel, latency-bound. Here rows are pixel-interleaved (channels padded to blocks of 8): the
// 8 channels of a block are one SIMD vector, and R rows x NB blocks independent chains hide
// the latency. GCC/Clang vector extensions keep it portable; each element sees the same
// operations, in the same order, as in the planar loop. a[r] holds row r's w-1 edge weights.
using Vec8 = float __attribute__((vector_size(32)));
inline Vec8 load8(const float* p) {
  Vec8 v;
  std::memcpy(&v, p, sizeof v);
  return v;
}
inline void store8(float* p, Vec8 v) { std::memcpy(p, &v, sizeof v); }

template <int NB, int R>
void recursive_interleaved(float* const* rows, const float* const* a, int w) {
  constexpr int DP = 8 * NB;
  Vec8 prev[R][NB];
  auto start = [&](int x) {
    for (int r = 0; r < R; ++r)
      for (int b = 0; b < NB; ++b) prev[r][b] = load8(rows[r] + std::size_t(x) * DP + 8 * b);
  };
  // Pixel x of row r moves towards the previous one along the pass by the edge weight k.
  auto step = [&](int r, int x, float k) {
    for (int b = 0; b < NB; ++b) {
      float* q = rows[r] + std::size_t(x) * DP + 8 * b;
      Vec8 v = load8(q);
      v += k * (prev[r][b] - v);
      store8(q, v);
      prev[r][b] = v;
    }
  };
  start(0);
  for (int x = 1; x < w; ++x)
    for (int r = 0; r < R; ++r) step(r, x, a[r][x - 1]);
  start(w - 1);
  for (int x = w - 2; x >= 0; --x)
    for (int r = 0; r < R; ++r) step(r, x, a[r][x]);
}

// Rows of `nb` blocks, in groups of kRowGroup (the last group may be smaller).
constexpr int kRowGroup = 4;
template <int R>
void recursive_interleaved(float* const* rows, const float* const* a, int w, int nb) {
  switch (nb) {
    case 1: return recursive_interleaved<1, R>(rows, a, w);
    case 2: return recursive_interleaved<2, R>(rows, a, w);
    case 3: return recursive_interleaved<3, R>(rows, a, w);
    case 4: return recursive_interleaved<4, R>(rows, a, w);
    default: break;
  }
  // Wider (guides of more than 32 channels, rare): block by block through a copy.
  std::vector<float> tmp(std::size_t(w) * 8);
  for (int r = 0; r < R; ++r)
    for (int b = 0; b < nb; ++b) {
      for (int x = 0; x < w; ++x) std::memcpy(&tmp[std::size_t(x) * 8], rows[r] + std::size_t(x) * nb * 8 + 8 * b, 32);
      float* one = tmp.data();
      recursive_interleaved<1, 1>(&one, a + r, w);
      for (int x = 0; x < w; ++x) std::memcpy(rows[r] + std::size_t(x) * nb * 8 + 8 * b, &tmp[std::size_t(x) * 8], 32);
    }
}
inline void recursive_interleaved(float* const* rows, const float* const* a, int w, int nb, int n) {
  switch (n) {
    case 4: return recursive_interleaved<4>(rows, a, w, nb);
    case 3: return recursive_interleaved<3>(rows, a, w, nb);
    case 2: return recursive_interleaved<2>(rows, a, w, nb);
    default: return recursive_interleaved<1>(rows, a, w, nb);
  }
}

// Recursive filter, one causal and one anti-causal pass per direction (Gastal and Oliveira
// 2011, domain transform RF): out[x] += a_x (out[x-1] - out[x]) with a per-edge feedback a_x.
// `wh(y)` returns the w-1 horizontal edge weights of row y, `wv(y)` the w vertical weights
// between rows y and y+1. Rows are independent in the horizontal pass and columns in the
// vertical one, so the parallel split does not change the result.
template <typename WH, typename WV>
void recursive_filter(Planes& p, int first, int count, WH wh, WV wv) {
  const int w = p.w, h = p.h;
  // Horizontal: groups of rows gathered into interleaved buffers (recursive_interleaved).
  const int nb = (count + 7) / 8, dp = 8 * nb;
  const int groups = (h + kRowGroup - 1) / kRowGroup;
  tbb::parallel_for(tbb::blocked_range<int>(0, groups), [&](const tbb::blocked_range<int>& range) {
    // The rows' planes moved to interleaved buffers and back (am_detail's 8 x 8 transposes).
    std::unique_ptr<float[]> buf(new float[std::size_t(kRowGroup) * w * dp]);  // written in full by the moves
    std::vector<float*> planes(static_cast<std::size_t>(count));
    float* rows[kRowGroup];
    const float* a[kRowGroup];
    for (int r = 0; r < kRowGroup; ++r) rows[r] = buf.get() + std::size_t(r) * w * dp;
    for (int g = range.begin(); g != range.end(); ++g) {
      const int y0 = g * kRowGroup, n = std::min(kRowGroup, h - y0);
      for (int r = 0; r < n; ++r) {
        a[r] = wh(y0 + r);
        for (int c = 0; c < count; ++c) planes[std::size_t(c)] = p.row(first + c, y0 + r);
        am_detail::to_interleaved(planes.data(), count, w, rows[r], dp);
      }
      recursive_interleaved(rows, a, w, nb, n);
      for (int r = 0; r < n; ++r) {
        for (int c = 0; c < count; ++c) planes[std::size_t(c)] = p.row(first + c, y0 + r);
        am_detail::from_interleaved(rows[r], dp, w, planes.data(), count);
      }
    }
  });
  recursive_filter_vertical(p, first, count, wv);
}


// Their h_filter's edge weights: the constant feedback exp(-sqrt 2 / sigma), for rows of n pixels.
std::vector<float> low_pass_weights(int n, double sigma);

// Pixel-interleaved float image: row y holds w pixels of dp floats (n channels, then zeros up
// to dp, a multiple of 8), so that both halves of a constant-feedback recursive filter run in
// place: the horizontal one as recursive_interleaved over the rows themselves, the vertical one
// as one vector loop along each row (no per-column weights). Planar planes had to be
// transposed to interleaved rows and back for the horizontal half: that transpose cost more
// than the filtering.
struct Interleaved {
  int w = 0, h = 0, n = 0, dp = 8;
  Planes storage;  // one plane of w * dp floats by h rows (the pool's buffers, as planes use)
  Interleaved() = default;
  Interleaved(int w_, int h_, int n_)
      : w(w_), h(h_), n(n_), dp(8 * ((n_ + 7) / 8)), storage(w_ * dp, h_, 1, Planes::Overwritten{}) {}
  float* row(int y) { return storage.row(0, y); }
  const float* row(int y) const { return storage.row(0, y); }
};


// Their h_filter: the recursive filter with a constant feedback, on an interleaved image (every
// element sees the operations recursive_filter() would apply to its plane, in the same order).
void low_pass(Interleaved& p, double sigma);

}  // namespace dnb::domain_transform
