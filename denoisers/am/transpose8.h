// Moves between planar rows (one channel a row) and pixel-interleaved rows (dp floats a pixel,
// dp a multiple of 8), eight channels by eight pixels at a time through an in-register 8 x 8
// transpose. The adaptive-manifold core changes layout on the reduced grid several times per
// manifold (the blur's horizontal pass, the children's splats and their manifolds: am/tree.cpp,
// domain_transform.h); element by element, those moves took about a seventh of its instructions
// on proposed's 1024x768 frames (callgrind, 2026-12-04). Pure data movement: the values are the
// element loops' bit for bit.
// Written by hand: OpenCV's cv::hal::merge32f / split32f, the nearest library routines, move
// whole rows whose pixel stride equals the channel count and vectorise only up to 4 channels;
// these rows hold 8 (or 16) with padding.
#pragma once

#include <cstddef>

#if defined(__AVX__)
#include <immintrin.h>
#endif

namespace dnb::am_detail {

// out[j][c] = in[c][j] for j, c in 0 .. 7.
inline void transpose8x8(const float* const* in, float* const* out) {
#if defined(__AVX__)
  const __m256 r0 = _mm256_loadu_ps(in[0]), r1 = _mm256_loadu_ps(in[1]), r2 = _mm256_loadu_ps(in[2]),
               r3 = _mm256_loadu_ps(in[3]), r4 = _mm256_loadu_ps(in[4]), r5 = _mm256_loadu_ps(in[5]),
               r6 = _mm256_loadu_ps(in[6]), r7 = _mm256_loadu_ps(in[7]);
  const __m256 t0 = _mm256_unpacklo_ps(r0, r1), t1 = _mm256_unpackhi_ps(r0, r1);
  const __m256 t2 = _mm256_unpacklo_ps(r2, r3), t3 = _mm256_unpackhi_ps(r2, r3);
  const __m256 t4 = _mm256_unpacklo_ps(r4, r5), t5 = _mm256_unpackhi_ps(r4, r5);
  const __m256 t6 = _mm256_unpacklo_ps(r6, r7), t7 = _mm256_unpackhi_ps(r6, r7);
  const __m256 s0 = _mm256_shuffle_ps(t0, t2, 0x44), s1 = _mm256_shuffle_ps(t0, t2, 0xEE);
  const __m256 s2 = _mm256_shuffle_ps(t1, t3, 0x44), s3 = _mm256_shuffle_ps(t1, t3, 0xEE);
  const __m256 s4 = _mm256_shuffle_ps(t4, t6, 0x44), s5 = _mm256_shuffle_ps(t4, t6, 0xEE);
  const __m256 s6 = _mm256_shuffle_ps(t5, t7, 0x44), s7 = _mm256_shuffle_ps(t5, t7, 0xEE);
  _mm256_storeu_ps(out[0], _mm256_permute2f128_ps(s0, s4, 0x20));
  _mm256_storeu_ps(out[1], _mm256_permute2f128_ps(s1, s5, 0x20));
  _mm256_storeu_ps(out[2], _mm256_permute2f128_ps(s2, s6, 0x20));
  _mm256_storeu_ps(out[3], _mm256_permute2f128_ps(s3, s7, 0x20));
  _mm256_storeu_ps(out[4], _mm256_permute2f128_ps(s0, s4, 0x31));
  _mm256_storeu_ps(out[5], _mm256_permute2f128_ps(s1, s5, 0x31));
  _mm256_storeu_ps(out[6], _mm256_permute2f128_ps(s2, s6, 0x31));
  _mm256_storeu_ps(out[7], _mm256_permute2f128_ps(s3, s7, 0x31));
#else
  float t[8][8];
  for (int c = 0; c < 8; ++c)
    for (int j = 0; j < 8; ++j) t[j][c] = in[c][j];
  for (int j = 0; j < 8; ++j)
    for (int c = 0; c < 8; ++c) out[j][c] = t[j][c];
#endif
}

// Planar rows planes[0 .. n) (w floats each) into the interleaved row `il` (w pixels of dp
// floats): il[x dp + c] = planes[c][x] for c < n, and 0 for n <= c < dp.
inline void to_interleaved(const float* const* planes, int n, int w, float* il, int dp) {
  static constexpr float kZeros[8] = {};  // a padding channel's 8 pixels
  for (int b = 0; b < dp; b += 8) {
    int x = 0;
    for (; x + 8 <= w; x += 8) {
      const float* src[8];
      float* dst[8];
      for (int k = 0; k < 8; ++k) {
        src[k] = b + k < n ? planes[b + k] + x : kZeros;
        dst[k] = il + std::size_t(x + k) * dp + b;
      }
      transpose8x8(src, dst);
    }
    for (; x < w; ++x)
      for (int c = 0; c < 8; ++c) il[std::size_t(x) * dp + b + c] = b + c < n ? planes[b + c][x] : 0.0f;
  }
}

// The inverse for the first n channels, from pixels `stride` floats apart (any stride >= n: an
// interleaved row, or an image's pixels): planes[c][x] = il[x stride + c], c < n. A transpose
// reads 8 floats from each pixel, so it is used where those stay inside the row.
inline void from_interleaved(const float* il, int stride, int w, float* const* planes, int n) {
  float sink[8];  // the transposes' rows of channels past n
  const std::size_t row_end = std::size_t(w) * stride;
  for (int b = 0; b < n; b += 8) {
    int x = 0;
    for (; std::size_t(x + 7) * stride + b + 8 <= row_end; x += 8) {
      const float* src[8];
      float* dst[8];
      for (int k = 0; k < 8; ++k) {
        src[k] = il + std::size_t(x + k) * stride + b;
        dst[k] = b + k < n ? planes[b + k] + x : sink;
      }
      transpose8x8(src, dst);
    }
    for (; x < w; ++x)
      for (int c = b; c < n && c < b + 8; ++c) planes[c][x] = il[std::size_t(x) * stride + c];
  }
}

}  // namespace dnb::am_detail
