// The adaptive-manifold filter's reduced grid (adaptive_manifold.h): manifolds are stored at a
// resolution reduced by df, each reduced pixel the box average of a df x df block; pixels read
// them back by bilinear upsampling, pixel centres aligned. Shared by the CPU core
// (adaptive_manifold.cpp, am/tree.cpp) and the OpenCL path (am/opencl.cpp), so both
// sample the grid the same way.
#pragma once

#include <algorithm>
#include <cstddef>
#include <type_traits>
#include <vector>

#include "denoisers/buffer_pool.h"

namespace dnb::am_detail {

// Bilinear upsampling tables for n full-resolution pixels from `small` reduced ones: pixel x
// sits at (x + 0.5) / df - 0.5 on the reduced grid, between i0[x] and i1[x] at fraction f[x].
inline void bilinear_table(int n, int small, int df, std::vector<int>& i0, std::vector<int>& i1, std::vector<float>& f) {
  i0.resize(n), i1.resize(n), f.resize(n);
  for (int x = 0; x < n; ++x) {
    const float u = std::clamp((x + 0.5f) / df - 0.5f, 0.0f, float(small - 1));
    i0[x] = std::min(int(u), small - 1);
    i1[x] = std::min(i0[x] + 1, small - 1);
    f[x] = u - float(i0[x]);
  }
}

// A W x H image's reduced grid of sw x sh pixels (df the factor): resampling between the two
// resolutions, one row at a time.
struct ReducedGrid {
  int W = 0, H = 0, df = 1, sw = 1, sh = 1;
  std::vector<int> x0, x1, y0, y1;
  std::vector<float> fx, fy, frac;

  ReducedGrid() = default;
  ReducedGrid(int W_, int H_, int df_) : W(W_), H(H_), df(df_), sw((W_ + df_ - 1) / df_), sh((H_ + df_ - 1) / df_) {
    bilinear_table(W, sw, df, x0, x1, fx);
    bilinear_table(H, sh, df, y0, y1, fy);
    frac.resize(df);
    // Output pixel df sx + df/2 + k sits at sx + (df/2 + k + 0.5) / df - 0.5 on the reduced grid.
    for (int k = 0; k < df; ++k) frac[k] = (df / 2 + k + 0.5f) / df - 0.5f;
  }

  // Calls f with std::integral_constant<int, W> for the W among Widths equal to df, else with
  // the constant 0 (the loop then reads df): the block width as a compile-time constant, so
  // that the loops over a block unroll into vector code.
  template <int... Widths, typename F>
  static void with_block_width(int df, F&& f) {
    const bool done = ((df == Widths ? (f(std::integral_constant<int, Widths>{}), true) : false) || ...);
    if (!done) f(std::integral_constant<int, 0>{});
  }

  // The vertical half of bilinear upsampling: plane c's two reduced rows around full row y,
  // blended into one reduced row (sw floats).
  void blend_rows(const Planes& p, int c, int y, float* out) const {
    const float* r0 = p.row(c, y0[y]);
    const float* r1 = p.row(c, y1[y]);
    const float f = fy[y];
    for (int x = 0; x < sw; ++x) out[x] = r0[x] + f * (r1[x] - r0[x]);
  }

  // Planes [first, first + count) of the reduced `p` upsampled at full row y into `out`
  // (count rows of W floats); tmp holds sw floats.
  void upsample_rows(const Planes& p, int first, int count, int y, float* out, float* tmp) const {
    for (int c = 0; c < count; ++c) {
      blend_rows(p, first + c, y, tmp);
      float* o = out + std::size_t(c) * W;
      upsample_x(tmp, o);
    }
  }

  // Horizontal bilinear upsampling of one reduced row. Inside the image, output pixel
  // df sx + df/2 + k lies between reduced pixels sx and sx + 1 at fraction
  // (df/2 + k + 0.5) / df - 0.5 for every sx ((k + 0.5) / df for even df, 0 for df = 1), so the
  // interior needs no index tables (and vectorises); the borders use them.
  void upsample_x(const float* tmp, float* o) const {
    with_block_width<2, 4, 8, 16>(df, [&](auto d) { upsample_x<decltype(d)::value>(tmp, o); });
  }
  template <int DF>
  void upsample_x(const float* tmp, float* o) const {
    const int df_ = DF > 0 ? DF : df;
    const int lead = std::min(W, df_ / 2);
    for (int x = 0; x < lead; ++x) o[x] = tmp[x0[x]] + fx[x] * (tmp[x1[x]] - tmp[x0[x]]);
    int x = lead;
    float fr[DF > 0 ? DF : 1];
    if constexpr (DF > 0)
      for (int k = 0; k < DF; ++k) fr[k] = (DF / 2 + k + 0.5f) / DF - 0.5f;
    const int n = std::min(sw - 1, (W - lead) / df_);
    for (int sx = 0; sx < n; ++sx, x += df_) {
      const float a = tmp[sx], b = tmp[sx + 1] - tmp[sx];
      if constexpr (DF > 0) {
        for (int k = 0; k < DF; ++k) o[x + k] = a + fr[k] * b;
      } else {
        for (int k = 0; k < df_; ++k) o[x + k] = a + frac[k] * b;
      }
    }
    for (; x < W; ++x) o[x] = tmp[x0[x]] + fx[x] * (tmp[x1[x]] - tmp[x0[x]]);
  }

  // Adds the df-wide blocks of `col` (W floats) to the reduced row `out`, scaled by inv_rows.
  void reduce_columns(const float* col, float* out, float inv_rows) const {
    with_block_width<1, 2, 4, 8>(df, [&](auto d) { reduce_columns<decltype(d)::value>(col, out, inv_rows); });
  }
  template <int DF>
  void reduce_columns(const float* col, float* out, float inv_rows) const {
    const int df_ = DF > 0 ? DF : df;
    const int full = W / df_;  // blocks of df columns; a partial one may follow
    const float scale = inv_rows / float(df_);
    for (int sx = 0; sx < full; ++sx) {
      float s = 0;
      for (int k = 0; k < df_; ++k) s += col[sx * df_ + k];
      out[sx] = s * scale;
    }
    if (full < sw) {
      float s = 0;
      for (int x = full * df_; x < W; ++x) s += col[x];
      out[full] = s * inv_rows / float(W - full * df_);
    }
  }

  // Adds the sums of row r's df-wide blocks to o (a partial block may end the row).
  void add_blocks(const float* r, float* o) const {
    with_block_width<2, 4>(df, [&](auto d) { add_blocks<decltype(d)::value>(r, o); });
  }
  template <int DF>
  void add_blocks(const float* r, float* o) const {
    const int df_ = DF > 0 ? DF : df;
    const int full = W / df_;
    for (int sx = 0; sx < full; ++sx) {
      float s = 0;
      for (int k = 0; k < df_; ++k) s += r[sx * df_ + k];
      o[sx] += s;
    }
    if (full < sw) {
      float s = 0;
      for (int x = full * df_; x < W; ++x) s += r[x];
      o[full] += s;
    }
  }
};

}  // namespace dnb::am_detail
