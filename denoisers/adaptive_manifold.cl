// OpenCL kernels of the adaptive-manifold core (denoisers/adaptive_manifold_cl.cpp drives them;
// the algorithm and its choices are documented in denoisers/adaptive_manifold.h). Images are
// planar: channel c of pixel (x, y) of a w x h image at [(c * h + y) * w + x]. Built with
// -DDIMS=<guide channels> -DCHANS=<source channels> so private arrays have exact sizes.
// The arithmetic follows the CPU path operation by operation; only summation order differs.
//
// Speed on a CPU device (PoCL): PoCL runs a work-group as a loop over its work-items and leaves
// vectorising it to LLVM, which vectorises innermost loops only, so a kernel with a loop of its
// own (over rows, over a block, over channels) runs one work-item at a time. Such kernels are
// written in float8 lanes instead (rf_rows, rf_cols, dt_weights, splat, split, slice): each
// work-item does 8 rows or columns at once, which costs a GPU nothing; the bilinear taps of 8
// columns come from one vector blend and constant swizzles where they follow the pattern of a
// reduction by 2 or 4 (tap_pattern), gathers elsewhere. The host launches work-groups of 32 x 1
// (adaptive_manifold_cl.cpp). Measured (bench, proposed at 1024x768, against the native path in
// the same run): 8.7x its time before, 3.1x after. What is left: the splat (a fifth of the time:
// exp and the covariance sums), the slice queries (gathers at scattered pixels), and the
// structure: the native path fuses a level's manifolds into one pass over the image
// (am_tree.cpp), which this path does manifold by manifold.

// Bilinear sample of plane p (sw wide) at full-resolution pixel (x, y): vertical first, as the
// CPU path's row upsampling.
inline float upsample(__global const float* p, int sw, int x0, int x1, float fx, int y0, int y1, float fy) {
  const float a = p[y0 * sw + x0] + fy * (p[y1 * sw + x0] - p[y0 * sw + x0]);
  const float b = p[y0 * sw + x1] + fy * (p[y1 * sw + x1] - p[y0 * sw + x1]);
  return a + fx * (b - a);
}

#define TABLES __global const int* tx0, __global const int* tx1, __global const float* tfx, \
               __global const int* ty0, __global const int* ty1, __global const float* tfy

// The manifold's value at pixel (x, y): full resolution (first manifold) or upsampled.
inline void eta_at(__global const float* eta, int eta_full, int W, int H, int sw, int sh, int x, int y,
                   TABLES, float* e) {
  for (int c = 0; c < DIMS; ++c) {
    if (eta_full)
      e[c] = eta[((size_t)c * H + y) * W + x];
    else
      e[c] = upsample(eta + (size_t)c * sw * sh, sw, tx0[x], tx1[x], tfx[x], ty0[y], ty1[y], tfy[y]);
  }
}

// Eight lanes of a reduced row `r` at the columns `i` (a gather).
inline float8 gather8(__global const float* r, int8 i) {
  return (float8)(r[i.s0], r[i.s1], r[i.s2], r[i.s3], r[i.s4], r[i.s5], r[i.s6], r[i.s7]);
}

// Whether 8 consecutive columns' bilinear taps (ix0, ix1: am_grid.h's tables) follow the interior
// pattern of a reduction by 2 or by 4 (2 or 4), with 8 reduced columns from the first tap inside
// the row; 0 otherwise (borders, other factors, odd sizes: gathers).
inline int tap_pattern(int8 ix0, int8 ix1, int sw) {
  const int base = ix0.s0;
  if (base + 8 > sw) return 0;
  const int8 b8 = (int8)(base);
  if (all(ix0 == b8 + (int8)(0, 1, 1, 2, 2, 3, 3, 4)) && all(ix1 == b8 + (int8)(1, 2, 2, 3, 3, 4, 4, 5))) return 2;
  if (all(ix0 == b8 + (int8)(0, 0, 1, 1, 1, 1, 2, 2)) && all(ix1 == b8 + (int8)(1, 1, 2, 2, 2, 2, 3, 3))) return 4;
  return 0;
}

// Eight columns of a reduced plane bilinearly upsampled at one full-resolution row (reduced rows
// r0 and r1, vertical weight fy): vertical first, as upsample() and the CPU path. With a tap
// pattern, 8 reduced columns are blended by one vector operation and the taps picked by
// constant swizzles (the same operations on the same values as the gathers).
inline float8 upsample8(__global const float* r0, __global const float* r1, float fy, int taps, int base, int8 ix0,
                        int8 ix1, float8 fx) {
  float8 a, b;
  if (taps) {
    const float8 v0 = vload8(0, r0 + base), v1 = vload8(0, r1 + base);
    const float8 vb = v0 + fy * (v1 - v0);
    a = taps == 2 ? vb.s01122334 : vb.s00111122;
    b = taps == 2 ? vb.s12233445 : vb.s11222233;
  } else {
    const float8 a0 = gather8(r0, ix0), a1 = gather8(r1, ix0), b0 = gather8(r0, ix1), b1 = gather8(r1, ix1);
    a = a0 + fy * (a1 - a0), b = b0 + fy * (b1 - b0);
  }
  return a + fx * (b - a);
}

// What the float8 kernels (splat, split) know about their 8 columns x0 .. x0 + 7 of a W-wide row:
// the columns clamped to the row (the tail's lanes repeat the last one), which lanes are in it
// (1 or 0), whether all are, and for a manifold on the reduced grid the bilinear taps and weights
// (am_grid.h's tables) with their swizzle pattern (tap_pattern; 0: gathers).
typedef struct {
  int8 xs, ix0, ix1;
  float8 valid, fx;
  int full, base, taps;
} Cols8;

inline Cols8 cols8(int x0, int W, int sw, int eta_full, __global const int* tx0, __global const int* tx1,
                   __global const float* tfx) {
  Cols8 k;
  const int8 lane = (int8)(0, 1, 2, 3, 4, 5, 6, 7);
  k.xs = min((int8)(x0) + lane, (int8)(W - 1));
  k.valid = convert_float8((int8)(x0) + lane < (int8)(W)) * -1.0f;  // true is -1
  k.full = x0 + 8 <= W;
  k.ix0 = 0, k.ix1 = 0;
  k.fx = 0;
  if (!eta_full) {
    const int8 xs = k.xs;
    k.ix0 = (int8)(tx0[xs.s0], tx0[xs.s1], tx0[xs.s2], tx0[xs.s3], tx0[xs.s4], tx0[xs.s5], tx0[xs.s6], tx0[xs.s7]);
    k.ix1 = (int8)(tx1[xs.s0], tx1[xs.s1], tx1[xs.s2], tx1[xs.s3], tx1[xs.s4], tx1[xs.s5], tx1[xs.s6], tx1[xs.s7]);
    k.fx = (float8)(tfx[xs.s0], tfx[xs.s1], tfx[xs.s2], tfx[xs.s3], tfx[xs.s4], tfx[xs.s5], tfx[xs.s6], tfx[xs.s7]);
  }
  k.base = k.ix0.s0;
  k.taps = !eta_full && k.full ? tap_pattern(k.ix0, k.ix1, sw) : 0;
  return k;
}

// Eight consecutive values of `r` from column x0 (a vector load), or for the row's tail the
// clamped columns xs.
inline float8 load8(__global const float* r, int x0, int8 xs, int full) {
  return full ? vload8(0, r + x0) : gather8(r, xs);
}

// Channel c of a manifold at the 8 columns of `k` in full-resolution row y: read (the root's,
// at full resolution) or bilinearly upsampled from the reduced grid.
inline float8 eta8(__global const float* eta, int eta_full, int c, int W, int H, int sw, int sh, int y, int x0,
                   const Cols8* k, __global const int* ty0, __global const int* ty1, __global const float* tfy) {
  if (eta_full) return load8(eta + (size_t)c * W * H + (size_t)y * W, x0, k->xs, k->full);
  __global const float* p = eta + (size_t)c * sw * sh;
  return upsample8(p + (size_t)ty0[y] * sw, p + (size_t)ty1[y] * sw, tfy[y], k->taps, k->base, k->ix0, k->ix1, k->fx);
}


// Splat (pass 1), in float8 lanes: one work-item per 8 full-resolution columns of reduced row sy
// (a CPU device such as PoCL vectorises across work-items only in loop-free kernels, and this
// one loops over the block's rows). For every pixel: w = exp(-|g - eta|^2 / sigma_r^2) into
// wbuf, the outlier distance, and (w src, w) summed over the block's rows into the column sums
// `colsum` (C + 1 planes of sh x W); splat_blocks adds the columns of each block. Above the
// leaves also the uncentred covariance of (g - eta) over the node's cluster, the work-item's
// D x D sums into cov (one entry per 8 columns).
__kernel void splat(int W, int H, int sw, int sh, int df, __global const float* guide, __global const float* src,
                    __global const float* eta, int eta_full, TABLES, float inv_sr2, __global float* wbuf,
                    __global float* min_d2, int adjust, __global float* colsum, int split, int id,
                    __global const ushort* label, __global float* cov) {
  const int x0 = 8 * get_global_id(0), sy = get_global_id(1);
  if (x0 >= W || sy >= sh) return;
  const Cols8 k8 = cols8(x0, W, sw, eta_full, tx0, tx1, tfx);
  const int8 xs = k8.xs;
  const float8 valid = k8.valid;
  const int full = k8.full;
  const int ya = sy * df, yb = min(H, ya + df);
  float8 acc[CHANS + 1];
  for (int c = 0; c <= CHANS; ++c) acc[c] = 0;
  float8 cv[DIMS * DIMS];
  if (split)
    for (int k = 0; k < DIMS * DIMS; ++k) cv[k] = 0;
  const size_t N = (size_t)W * H;
  for (int y = ya; y < yb; ++y) {
    const size_t row = (size_t)y * W;
    float8 X[DIMS];
    float8 d2 = 0;
    for (int c = 0; c < DIMS; ++c) {
      const float8 e = eta8(eta, eta_full, c, W, H, sw, sh, y, x0, &k8, ty0, ty1, tfy);
      X[c] = load8(guide + (size_t)c * N + row, x0, xs, full) - e;
      d2 += X[c] * X[c];
    }
    const float8 w = exp(-d2 * inv_sr2);
    if (full) {
      vstore8(w, 0, wbuf + row + x0);
      if (adjust) vstore8(fmin(vload8(0, min_d2 + row + x0), d2), 0, min_d2 + row + x0);
    } else {
      for (int l = 0; l < W - x0; ++l) {
        wbuf[row + x0 + l] = w[l];
        if (adjust) min_d2[row + x0 + l] = fmin(min_d2[row + x0 + l], d2[l]);
      }
    }
    const float8 wv = w * valid;
    for (int c = 0; c < CHANS; ++c) acc[c] += wv * load8(src + (size_t)c * N + row, x0, xs, full);
    acc[CHANS] += wv;
    if (split) {
      const ushort8 lab = full ? vload8(0, label + row + x0)
                               : (ushort8)(label[row + xs.s0], label[row + xs.s1], label[row + xs.s2], label[row + xs.s3],
                                           label[row + xs.s4], label[row + xs.s5], label[row + xs.s6], label[row + xs.s7]);
      const float8 mine = convert_float8(convert_int8(lab) == (int8)(id)) * -1.0f * valid;
      for (int a = 0; a < DIMS; ++a) {
        const float8 xa = X[a] * mine;
        for (int b = a; b < DIMS; ++b) cv[a * DIMS + b] += xa * X[b];
      }
    }
  }
  for (int c = 0; c <= CHANS; ++c) {
    __global float* o = colsum + ((size_t)c * sh + sy) * W + x0;
    if (full)
      vstore8(acc[c], 0, o);
    else
      for (int l = 0; l < W - x0; ++l) o[l] = acc[c][l];
  }
  if (split) {
    const int nwx = (W + 7) / 8;
    __global float* o = cov + ((size_t)sy * nwx + get_global_id(0)) * DIMS * DIMS;
    for (int k = 0; k < DIMS * DIMS; ++k) {
      const float8 v = cv[k];
      o[k] = ((v.s0 + v.s1) + (v.s2 + v.s3)) + ((v.s4 + v.s5) + (v.s6 + v.s7));
    }
  }
}

// The splat's blocks: each reduced pixel's column sums added over its df columns, over the
// block's pixel count.
__kernel void splat_blocks(int W, int H, int sw, int sh, int df, __global const float* colsum, __global float* splat_out) {
  const int sx = get_global_id(0), sy = get_global_id(1);
  if (sx >= sw || sy >= sh) return;
  const int xa = sx * df, xb = min(W, xa + df), ya = sy * df, yb = min(H, ya + df);
  const float inv = 1.0f / (float)((yb - ya) * (xb - xa));
  for (int c = 0; c <= CHANS; ++c) {
    __global const float* r = colsum + ((size_t)c * sh + sy) * W;
    float t = 0;
    for (int x = xa; x < xb; ++x) t += r[x];
    splat_out[((size_t)c * sh + sy) * sw + sx] = t * inv;
  }
}

// Row sums of the per-block covariances: one work-item per reduced row, reading the row's blocks
// in memory order (each block's D x D entries are contiguous) into private sums.
__kernel void cov_rows(int sw, int sh, __global const float* cov, __global float* rows) {  // sw: entries per row
  const int sy = get_global_id(0);
  if (sy >= sh) return;
  float s[DIMS * DIMS];
  for (int k = 0; k < DIMS * DIMS; ++k) s[k] = 0;
  __global const float* r = cov + (size_t)sy * sw * DIMS * DIMS;
  for (int sx = 0; sx < sw; ++sx)
    for (int k = 0; k < DIMS * DIMS; ++k) s[k] += r[(size_t)sx * DIMS * DIMS + k];
  for (int k = 0; k < DIMS * DIMS; ++k) rows[(size_t)sy * DIMS * DIMS + k] = s[k];
}

// Box average of the full-resolution first manifold onto the reduced grid.
__kernel void downsample(int W, int H, int sw, int sh, int df, __global const float* full, __global float* small) {
  const int sx = get_global_id(0), sy = get_global_id(1);
  if (sx >= sw || sy >= sh) return;
  const int xa = sx * df, xb = min(W, xa + df), ya = sy * df, yb = min(H, ya + df);
  for (int c = 0; c < DIMS; ++c) {
    float s = 0;
    for (int y = ya; y < yb; ++y)
      for (int x = xa; x < xb; ++x) s += full[((size_t)c * H + y) * W + x];
    small[((size_t)c * sh + sy) * sw + sx] = s / (float)((yb - ya) * (xb - xa));
  }
}

// Domain-transform edge feedbacks a^sqrt(1 + ratio2 |d eta|^2) along rows (ah: sw - 1 per row,
// stride hstride) and columns (av: sw per row pair). One work-item per 8 reduced columns, in
// float8 lanes where all 8 and their right neighbours are in the row; one by one otherwise.
__kernel void dt_weights(int sw, int sh, int hstride, __global const float* eta, float ratio2, float ln_a,
                         __global float* ah, __global float* av) {
  const int x0 = 8 * get_global_id(0), y = get_global_id(1);
  if (x0 >= sw || y >= sh) return;
  if (x0 + 9 <= sw) {
    float8 dh = 0, dv = 0;
    for (int c = 0; c < DIMS; ++c) {
      __global const float* e = eta + ((size_t)c * sh + y) * sw + x0;
      const float8 here = vload8(0, e);
      const float8 t = vload8(0, e + 1) - here;
      dh += t * t;
      if (y + 1 < sh) {
        const float8 u = vload8(0, e + sw) - here;
        dv += u * u;
      }
    }
    vstore8(exp(ln_a * sqrt(1.0f + ratio2 * dh)), 0, ah + (size_t)y * hstride + x0);
    if (y + 1 < sh) vstore8(exp(ln_a * sqrt(1.0f + ratio2 * dv)), 0, av + (size_t)y * sw + x0);
    return;
  }
  for (int x = x0; x < min(sw, x0 + 8); ++x) {
    if (x + 1 < sw) {
      float d = 0;
      for (int c = 0; c < DIMS; ++c) {
        const float t = eta[((size_t)c * sh + y) * sw + x + 1] - eta[((size_t)c * sh + y) * sw + x];
        d += t * t;
      }
      ah[(size_t)y * hstride + x] = exp(ln_a * sqrt(1.0f + ratio2 * d));
    }
    if (y + 1 < sh) {
      float d = 0;
      for (int c = 0; c < DIMS; ++c) {
        const float t = eta[((size_t)c * sh + y + 1) * sw + x] - eta[((size_t)c * sh + y) * sw + x];
        d += t * t;
      }
      av[(size_t)y * sw + x] = exp(ln_a * sqrt(1.0f + ratio2 * d));
    }
  }
}

// Recursive filter along rows, causal then anti-causal: one work-item per 8 rows of a plane, in
// float8 lanes (one row per lane; see rf_cols). With fixed_a != 0 the feedback is that constant
// (the low-pass h_filter), else ah. A plane's last rows, fewer than 8, run one by one.
__kernel void rf_rows(int w, int h, __global float* p, __global const float* ah, int hstride, float fixed_a) {
  const int y0 = 8 * get_global_id(0), c = get_global_id(1);
  if (y0 >= h) return;
  if (y0 + 8 <= h) {
    __global float* r = p + ((size_t)c * h + y0) * w;
    __global const float* a = ah + (size_t)y0 * hstride;
    const size_t S = (size_t)w, A = (size_t)hstride;
    const float8 fa = (float8)(fixed_a);
#define ROWS8(q, i, s) (float8)((q)[(i)], (q)[(i) + (s)], (q)[(i) + 2 * (s)], (q)[(i) + 3 * (s)], (q)[(i) + 4 * (s)], \
                                (q)[(i) + 5 * (s)], (q)[(i) + 6 * (s)], (q)[(i) + 7 * (s)])
#define STORE8(v, q, i, s)                                                                       \
  do {                                                                                           \
    (q)[(i)] = (v).s0, (q)[(i) + (s)] = (v).s1, (q)[(i) + 2 * (s)] = (v).s2, (q)[(i) + 3 * (s)] = (v).s3; \
    (q)[(i) + 4 * (s)] = (v).s4, (q)[(i) + 5 * (s)] = (v).s5, (q)[(i) + 6 * (s)] = (v).s6;                 \
    (q)[(i) + 7 * (s)] = (v).s7;                                                                 \
  } while (0)
    float8 prev = ROWS8(r, 0, S);
    for (int x = 1; x < w; ++x) {
      const float8 k = fixed_a != 0 ? fa : ROWS8(a, x - 1, A);
      float8 cur = ROWS8(r, x, S);
      cur += k * (prev - cur);
      STORE8(cur, r, x, S);
      prev = cur;
    }
    for (int x = w - 2; x >= 0; --x) {
      const float8 k = fixed_a != 0 ? fa : ROWS8(a, x, A);
      float8 cur = ROWS8(r, x, S);
      cur += k * (prev - cur);
      STORE8(cur, r, x, S);
      prev = cur;
    }
#undef ROWS8
#undef STORE8
    return;
  }
  for (int y = y0; y < h; ++y) {
    __global float* r = p + ((size_t)c * h + y) * w;
    __global const float* a = ah + (size_t)y * hstride;
    for (int x = 1; x < w; ++x) r[x] += (fixed_a != 0 ? fixed_a : a[x - 1]) * (r[x - 1] - r[x]);
    for (int x = w - 2; x >= 0; --x) r[x] += (fixed_a != 0 ? fixed_a : a[x]) * (r[x + 1] - r[x]);
  }
}

// Recursive filter along columns: one work-item per 8 columns of a plane, as float8 (a CPU
// device such as PoCL vectorises across work-items only where a kernel has no loop of its own;
// this one is a loop over rows, so it is written for 8 lanes; a GPU loses nothing by it). The last
// work-item of a row of fewer than 8 columns runs them one by one.
__kernel void rf_cols(int w, int h, __global float* p, __global const float* av, float fixed_a) {
  const int x0 = 8 * get_global_id(0), c = get_global_id(1);
  if (x0 >= w) return;
  __global float* q = p + (size_t)c * h * w;
  if (x0 + 8 <= w) {
    const float8 fa = (float8)(fixed_a);
    float8 prev = vload8(0, q + x0);
    for (int y = 1; y < h; ++y) {
      const float8 k = fixed_a != 0 ? fa : vload8(0, av + (size_t)(y - 1) * w + x0);
      float8 cur = vload8(0, q + (size_t)y * w + x0);
      cur += k * (prev - cur);
      vstore8(cur, 0, q + (size_t)y * w + x0);
      prev = cur;
    }
    for (int y = h - 2; y >= 0; --y) {
      const float8 k = fixed_a != 0 ? fa : vload8(0, av + (size_t)y * w + x0);
      float8 cur = vload8(0, q + (size_t)y * w + x0);
      cur += k * (prev - cur);
      vstore8(cur, 0, q + (size_t)y * w + x0);
      prev = cur;
    }
    return;
  }
  for (int x = x0; x < w; ++x) {
    for (int y = 1; y < h; ++y) {
      const float k = fixed_a != 0 ? fixed_a : av[(size_t)(y - 1) * w + x];
      q[(size_t)y * w + x] += k * (q[(size_t)(y - 1) * w + x] - q[(size_t)y * w + x]);
    }
    for (int y = h - 2; y >= 0; --y) {
      const float k = fixed_a != 0 ? fixed_a : av[(size_t)y * w + x];
      q[(size_t)y * w + x] += k * (q[(size_t)(y + 1) * w + x] - q[(size_t)y * w + x]);
    }
  }
}

// Slice: every pixel gathers w * blurred (C + 1 planes) from the manifold; one work-item per 8
// columns of a full-resolution row, in float8 lanes (the taps as in the splat).
__kernel void slice(int W, int H, int sw, int sh, __global const float* blurred, TABLES, __global const float* wbuf,
                    __global float* acc) {
  const int x0 = 8 * get_global_id(0), y = get_global_id(1);
  if (x0 >= W || y >= H) return;
  const size_t row = (size_t)y * W;
  if (x0 + 8 > W) {  // the row's last columns, fewer than 8
    for (int x = x0; x < W; ++x) {
      const float w = wbuf[row + x];
      for (int c = 0; c <= CHANS; ++c)
        acc[(size_t)c * W * H + row + x] +=
            w * upsample(blurred + (size_t)c * sw * sh, sw, tx0[x], tx1[x], tfx[x], ty0[y], ty1[y], tfy[y]);
    }
    return;
  }
  const int8 ix0 = vload8(0, tx0 + x0), ix1 = vload8(0, tx1 + x0);
  const float8 fx = vload8(0, tfx + x0);
  const int taps = tap_pattern(ix0, ix1, sw), base = ix0.s0;
  const float8 w = vload8(0, wbuf + row + x0);
  for (int c = 0; c <= CHANS; ++c) {
    __global const float* p = blurred + (size_t)c * sw * sh;
    __global float* a = acc + (size_t)c * W * H + row + x0;
    vstore8(vload8(0, a) + w * upsample8(p + (size_t)ty0[y] * sw, p + (size_t)ty1[y] * sw, tfy[y], taps, base, ix0, ix1, fx),
            0, a);
  }
}

// Split, in float8 lanes like the splat: one work-item per 8 full-resolution columns of reduced
// row sy. The cluster's pixels go left (dot < 0) or right and are relabelled, and each side's
// (1 - w) g and (1 - w) are summed over the block's rows into the column sums `colsum` (D + 1
// planes for the left child, then D + 1 for the right, each sh x W); split_blocks adds each
// block's columns into the children's reduced splats.
__kernel void split(int W, int H, int sw, int sh, int df, __global const float* guide, __global const float* eta,
                    int eta_full, TABLES, __global const float* v, __global const float* wbuf,
                    __global ushort* label, int id, __global float* colsum) {
  const int x0 = 8 * get_global_id(0), sy = get_global_id(1);
  if (x0 >= W || sy >= sh) return;
  const Cols8 k8 = cols8(x0, W, sw, eta_full, tx0, tx1, tfx);
  const int8 xs = k8.xs;
  const float8 valid = k8.valid;
  const int full = k8.full;
  float8 l[DIMS + 1], r[DIMS + 1];
  for (int c = 0; c <= DIMS; ++c) l[c] = r[c] = 0;
  const size_t N = (size_t)W * H;
  const int ya = sy * df, yb = min(H, ya + df);
  for (int y = ya; y < yb; ++y) {
    const size_t row = (size_t)y * W;
    const int8 lab = full ? convert_int8(vload8(0, label + row + x0))
                          : (int8)(label[row + xs.s0], label[row + xs.s1], label[row + xs.s2], label[row + xs.s3],
                                   label[row + xs.s4], label[row + xs.s5], label[row + xs.s6], label[row + xs.s7]);
    const int8 mine = lab == (int8)(id);  // -1 or 0
    float8 g[DIMS];
    float8 dot = 0;
    for (int c = 0; c < DIMS; ++c) {
      const float8 e = eta8(eta, eta_full, c, W, H, sw, sh, y, x0, &k8, ty0, ty1, tfy);
      g[c] = load8(guide + (size_t)c * N + row, x0, xs, full);
      dot += v[c] * (g[c] - e);
    }
    const int8 left = dot < (float8)(0.0f);  // -1 or 0
    const float8 theta = (1.0f - load8(wbuf + row, x0, xs, full)) * -convert_float8(mine) * valid;
    const float8 tl = theta * -convert_float8(left), tr = theta - tl;
    const int8 relabel = select(lab, select((int8)(2 * id + 1), (int8)(2 * id), left), mine);
    if (full)
      vstore8(convert_ushort8(relabel), 0, label + row + x0);
    else
      for (int k = 0; k < W - x0; ++k) label[row + x0 + k] = (ushort)relabel[k];
    for (int c = 0; c < DIMS; ++c) {
      l[c] += tl * g[c];
      r[c] += tr * g[c];
    }
    l[DIMS] += tl;
    r[DIMS] += tr;
  }
  for (int c = 0; c <= DIMS; ++c) {
    __global float* ol = colsum + ((size_t)c * sh + sy) * W + x0;
    __global float* orr = colsum + ((size_t)(DIMS + 1 + c) * sh + sy) * W + x0;
    if (full) {
      vstore8(l[c], 0, ol);
      vstore8(r[c], 0, orr);
    } else {
      for (int k = 0; k < W - x0; ++k) ol[k] = l[c][k], orr[k] = r[c][k];
    }
  }
}

// The children's reduced splats from split's column sums: each reduced pixel's df columns
// added, over the block's pixel count (D + 1 planes per child).
__kernel void split_blocks(int W, int H, int sw, int sh, int df, __global const float* colsum, __global float* kid_l,
                           __global float* kid_r) {
  const int sx = get_global_id(0), sy = get_global_id(1);
  if (sx >= sw || sy >= sh) return;
  const int xa = sx * df, xb = min(W, xa + df), ya = sy * df, yb = min(H, ya + df);
  const float inv = 1.0f / (float)((yb - ya) * (xb - xa));
  for (int c = 0; c <= DIMS; ++c) {
    __global const float* rl = colsum + ((size_t)c * sh + sy) * W;
    __global const float* rr = colsum + ((size_t)(DIMS + 1 + c) * sh + sy) * W;
    float a = 0, b = 0;
    for (int x = xa; x < xb; ++x) a += rl[x], b += rr[x];
    kid_l[((size_t)c * sh + sy) * sw + sx] = a * inv;
    kid_r[((size_t)c * sh + sy) * sw + sx] = b * inv;
  }
}

// A child's manifold: low-passed weighted guide over low-passed weight; where the child's
// cluster left no weight it keeps the parent's manifold.
__kernel void divide_eta(int n, __global const float* kid, __global const float* parent, __global float* eta) {
  const int i = get_global_id(0);
  if (i >= n) return;
  const float den = kid[(size_t)DIMS * n + i];
  for (int c = 0; c < DIMS; ++c)
    eta[(size_t)c * n + i] = den > 1e-20f ? kid[(size_t)c * n + i] / den : parent[(size_t)c * n + i];
}

// Slice queries (paper 3.1): the slice at a pixel with another guide value.
__kernel void query(int nq, int W, int H, int sw, int sh, __global const int* qxy, __global const float* qguide,
                    __global const float* eta, int eta_full, __global const float* blurred, TABLES, float inv_sr2,
                    __global float* qacc, __global float* qmin) {
  const int q = get_global_id(0);
  if (q >= nq) return;
  const int x = qxy[2 * q], y = qxy[2 * q + 1];
  float e[DIMS];
  eta_at(eta, eta_full, W, H, sw, sh, x, y, tx0, tx1, tfx, ty0, ty1, tfy, e);
  float d2 = 0;
  for (int c = 0; c < DIMS; ++c) {
    const float d = qguide[(size_t)q * DIMS + c] - e[c];
    d2 += d * d;
  }
  const float wq = exp(-d2 * inv_sr2);
  for (int c = 0; c <= CHANS; ++c)
    qacc[(size_t)q * (CHANS + 1) + c] += wq * upsample(blurred + (size_t)c * sw * sh, sw, tx0[x], tx1[x], tfx[x], ty0[y], ty1[y], tfy[y]);
  qmin[q] = min(qmin[q], d2);
}

// The output: sum(w blur) / sum(w blur_0), with the optional outlier adjustment; interleaved.
__kernel void finish(int W, int H, __global const float* acc, __global const float* src, __global const float* min_d2,
                     int adjust, float alpha_k, __global float* out) {
  const int x = get_global_id(0), y = get_global_id(1);
  if (x >= W || y >= H) return;
  const size_t i = (size_t)y * W + x, n = (size_t)W * H;
  const float den = acc[(size_t)CHANS * n + i];
  const float alpha = adjust ? exp(alpha_k * min_d2[i]) : 1.0f;
  for (int c = 0; c < CHANS; ++c) {
    const float f = src[(size_t)c * n + i];
    const float g = den > 1e-30f ? acc[(size_t)c * n + i] / den : f;  // kAmMinWeight
    out[i * CHANS + c] = f + alpha * (g - f);
  }
}
