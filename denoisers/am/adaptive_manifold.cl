// OpenCL kernels of the adaptive-manifold core (denoisers/am/opencl.cpp drives them;
// the algorithm and its choices are documented in denoisers/am/adaptive_manifold.h). Images are
// planar: channel c of pixel (x, y) of a w x h image at [(c * h + y) * w + x]. Built with
// -DDIMS=<guide channels> -DCHANS=<source channels> so private arrays have exact sizes.
// The arithmetic follows the CPU path operation by operation; only summation order differs.
//
// Speed on a CPU device (PoCL): PoCL runs a work-group as a loop over its work-items and leaves
// vectorising it to LLVM, which vectorises innermost loops only, so a kernel with a loop of its
// own (over rows, over a block, over channels) runs one work-item at a time. Such kernels are
// written in float8 lanes instead (rf_rows, rf_cols, dt_weights, splat_group, slice_split_group):
// each work-item does 8 rows or columns at once, which costs a GPU nothing; the bilinear taps of
// 8 columns come from one vector blend and constant swizzles where they follow the pattern of a
// reduction by 2 or 4 (tap_pattern), gathers elsewhere. The host launches work-groups of 32 x 1
// (am/opencl.cpp). As the CPU path (am/tree.cpp), the tree runs level by level and a
// level's manifolds in groups (up to MAXG): the full-resolution passes (splat_group,
// slice_split_group) read the guide, the source and the sums once per group, not once per
// manifold, which bound them by memory traffic; queries at one pixel share its upsampled values
// (query_group). Measured (bench, against the native path in the same run): proposed at
// 1024x768 8.7x the native time at first, 3.1x with the float8 kernels, about 1.9x grouped
// (with the host's buffer pool and one query pass per pixel, am/opencl.cpp).

// The float8 helpers of the hot kernels, inlined by force: PoCL's compiler left upsample8 a call
// (its float8 arguments passed through memory), a tenth of the splat's and the slice's time.
#define INLINE inline __attribute__((always_inline))

// Bilinear sample of plane p (sw wide) at full-resolution pixel (x, y): vertical first, as the
// CPU path's row upsampling.
inline float upsample(__global const float* p, int sw, int x0, int x1, float fx, int y0, int y1, float fy) {
  const float a = p[y0 * sw + x0] + fy * (p[y1 * sw + x0] - p[y0 * sw + x0]);
  const float b = p[y0 * sw + x1] + fy * (p[y1 * sw + x1] - p[y0 * sw + x1]);
  return a + fx * (b - a);
}

// The covariance sums keep the upper triangle of the D x D matrix, row by row (a, b >= a).
#define TRI (DIMS * (DIMS + 1) / 2)

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

// Whether 8 consecutive columns' bilinear taps (ix0, ix1: am/grid.h's tables) follow the interior
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
INLINE float8 upsample8(__global const float* r0, __global const float* r1, float fy, int taps, int base, int8 ix0,
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
// (am/grid.h's tables) with their swizzle pattern (tap_pattern; 0: gathers).
typedef struct {
  int8 xs, ix0, ix1;
  float8 valid, fx;
  int full, base, taps;
} Cols8;

INLINE Cols8 cols8(int x0, int W, int sw, int eta_full, __global const int* tx0, __global const int* tx1,
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
INLINE float8 load8(__global const float* r, int x0, int8 xs, int full) {
  return full ? vload8(0, r + x0) : gather8(r, xs);
}

// Channel c of a manifold at the 8 columns of `k` in full-resolution row y: read (the root's,
// at full resolution) or bilinearly upsampled from the reduced grid.
INLINE float8 eta8(__global const float* eta, int eta_full, int c, int W, int H, int sw, int sh, int y, int x0,
                   const Cols8* k, __global const int* ty0, __global const int* ty1, __global const float* tfy) {
  if (eta_full) return load8(eta + (size_t)c * W * H + (size_t)y * W, x0, k->xs, k->full);
  __global const float* p = eta + (size_t)c * sw * sh;
  return upsample8(p + (size_t)ty0[y] * sw, p + (size_t)ty1[y] * sw, tfy[y], k->taps, k->base, k->ix0, k->ix1, k->fx);
}


// Where df divides 8, a work-item's 8 columns hold 8 / df whole blocks of the reduced grid, and
// the block sums are finished in the work-item (block_store) instead of going through column sums
// in memory (sh x W per plane) and a second kernel (splat_blocks, split_blocks), which cost a
// tenth of proposed's time at df = 2. The sums are added in the same order as the second kernel
// adds them, from 0 and left to right, so both routes give the same values bit for bit.
// For a work-item whose 8 columns are all in the row, the blocks are whole and summed by
// swizzles; inv_full = 1 / (rows df) and sx0 = x0 / df are the work-item's, computed once (an
// integer and a float division per block were a sixth of slice_split_group's time).
INLINE void block_store(float8 v, int x0, int W, int df, int rows, int sx0, float inv_full, __global float* out_row) {
  if (x0 + 8 <= W) {
    if (df == 2) {
      vstore4((((float4)(0.0f) + v.even) + v.odd) * inv_full, 0, out_row + sx0);
      return;
    }
    if (df == 4) {
      vstore2((((((float2)(0.0f) + v.s04) + v.s15) + v.s26) + v.s37) * inv_full, 0, out_row + sx0);
      return;
    }
    if (df == 1) {
      vstore8(((float8)(0.0f) + v) * inv_full, 0, out_row + sx0);
      return;
    }
  }
  for (int j = 0; j < 8 / df; ++j) {
    const int xa = x0 + j * df;
    if (xa >= W) return;
    const int xb = min(W, xa + df);
    const float inv = xb - xa == df ? inv_full : 1.0f / (float)(rows * (xb - xa));
    float t = 0;
    for (int x = xa; x < xb; ++x) t += v[x - x0];
    out_row[sx0 + j] = t * inv;
  }
}

// Splat (pass 1) for a group of m manifolds of one tree level (m <= MAXG), in float8 lanes:
// one work-item per 8 full-resolution columns of reduced row sy (a CPU device such as PoCL
// vectorises across work-items only in loop-free kernels, and this one loops over the block's
// rows). The guide, the source and the outlier distance are read once per pixel for the whole
// group, as the CPU path's am/tree.cpp does: one manifold at a time, the splat read the guide
// once per manifold and was bound by that memory traffic (half the OpenCL path's time). For
// every pixel and manifold k: w = exp(-|g - eta_k|^2 / sigma_r^2) into plane k of wbuf, the
// nearest distance so far, and (w src, w) summed over the block's rows into manifold k's column
// sums (C + 1 planes of sh x W from plane k (C + 1) of colsum); splat_blocks adds the columns of
// each block. Above the leaves also the uncentred covariance of (g - eta_k) over manifold k's
// cluster (label id0 + k), the work-item's D x D sums into cov (one entry per 8 columns).
// Manifold k's eta: planes (e0 + k) D of `eta` (reduced grid), or with eta_full the root's
// full-resolution planes (m = 1). Each manifold's sums are added in the same order as when the
// kernel ran one manifold, so grouping changes no result.
__kernel void splat_group(int W, int H, int sw, int sh, int df, int m, __global const float* guide,
                          __global const float* src, __global const float* eta, int e0, int eta_full, TABLES,
                          float inv_sr2, __global float* wbuf, __global float* min_d2, int adjust,
                          __global float* colsum, int direct, __global float* splats, int split, int id0,
                          __global const ushort* label, __global float* cov) {
  const int x0 = 8 * get_global_id(0), sy = get_global_id(1);
  if (x0 >= W || sy >= sh) return;
  const Cols8 k8 = cols8(x0, W, sw, eta_full, tx0, tx1, tfx);
  const int8 xs = k8.xs;
  const float8 valid = k8.valid;
  const int full = k8.full;
  const int ya = sy * df, yb = min(H, ya + df);
  const size_t N = (size_t)W * H, n = (size_t)sw * sh;
  float8 acc[MAXG][CHANS + 1];
  float8 cv[MAXG][TRI];  // the upper triangle, row by row
  for (int k = 0; k < m; ++k) {
    for (int c = 0; c <= CHANS; ++c) acc[k][c] = 0;
    if (split)
      for (int e = 0; e < TRI; ++e) cv[k][e] = 0;
  }
  for (int y = ya; y < yb; ++y) {
    const size_t row = (size_t)y * W;
    float8 g[DIMS], f[CHANS];
    for (int c = 0; c < DIMS; ++c) g[c] = load8(guide + (size_t)c * N + row, x0, xs, full);
    for (int c = 0; c < CHANS; ++c) f[c] = load8(src + (size_t)c * N + row, x0, xs, full);
    int8 lab = 0;
    if (split)
      lab = full ? convert_int8(vload8(0, label + row + x0))
                 : (int8)(label[row + xs.s0], label[row + xs.s1], label[row + xs.s2], label[row + xs.s3],
                          label[row + xs.s4], label[row + xs.s5], label[row + xs.s6], label[row + xs.s7]);
    float8 nearest = INFINITY;
    for (int k = 0; k < m; ++k) {
      __global const float* ek = eta + (size_t)(e0 + k) * DIMS * n;
      float8 X[DIMS];
      float8 d2 = 0;
      for (int c = 0; c < DIMS; ++c) {
        X[c] = g[c] - eta8(ek, eta_full, c, W, H, sw, sh, y, x0, &k8, ty0, ty1, tfy);
        d2 += X[c] * X[c];
      }
      const float8 w = exp(-d2 * inv_sr2);
      nearest = fmin(nearest, d2);
      __global float* wk = wbuf + (size_t)k * N + row + x0;
      if (full)
        vstore8(w, 0, wk);
      else
        for (int l = 0; l < W - x0; ++l) wk[l] = w[l];
      const float8 wv = w * valid;
      for (int c = 0; c < CHANS; ++c) acc[k][c] += wv * f[c];
      acc[k][CHANS] += wv;
      // The covariance only where a lane holds a pixel of the cluster: elsewhere every term is a
      // zero, which changes no sum (below the root a cluster holds part of each row: on
      // conference at 1024x768, 43% of the pixels of the rows it reaches).
      const int8 in_cluster = lab == (int8)(id0 + k);  // -1 or 0
      if (split && any(in_cluster)) {
        const float8 mine = convert_float8(in_cluster) * -1.0f * valid;
        int e = 0;
        for (int a = 0; a < DIMS; ++a) {
          const float8 xa = X[a] * mine;
          for (int b = a; b < DIMS; ++b) cv[k][e++] += xa * X[b];
        }
      }
    }
    if (adjust) {
      if (full)
        vstore8(fmin(vload8(0, min_d2 + row + x0), nearest), 0, min_d2 + row + x0);
      else
        for (int l = 0; l < W - x0; ++l) min_d2[row + x0 + l] = fmin(min_d2[row + x0 + l], nearest[l]);
    }
  }
  const int nwx = (W + 7) / 8;
  const int sx0 = direct ? x0 / df : 0;
  const float inv_full = direct ? 1.0f / (float)((yb - ya) * df) : 0.0f;
  for (int k = 0; k < m; ++k) {
    for (int c = 0; c <= CHANS; ++c) {
      if (direct) {
        block_store(acc[k][c], x0, W, df, yb - ya, sx0, inv_full, splats + ((size_t)(k * (CHANS + 1) + c) * sh + sy) * sw);
        continue;
      }
      __global float* o = colsum + ((size_t)(k * (CHANS + 1) + c) * sh + sy) * W + x0;
      if (full)
        vstore8(acc[k][c], 0, o);
      else
        for (int l = 0; l < W - x0; ++l) o[l] = acc[k][c][l];
    }
    if (!split) continue;
    __global float* o = cov + (((size_t)k * sh + sy) * nwx + get_global_id(0)) * TRI;
    for (int e = 0; e < TRI; ++e) {
      const float8 v = cv[k][e];
      o[e] = ((v.s0 + v.s1) + (v.s2 + v.s3)) + ((v.s4 + v.s5) + (v.s6 + v.s7));
    }
  }
}

// The splat's blocks of manifold k of the group: each reduced pixel's column sums added over its
// df columns, over the block's pixel count, into planes o0 .. o0 + C of splat_out.
__kernel void splat_blocks(int W, int H, int sw, int sh, int df, int k, __global const float* colsum,
                           int o0, __global float* splat_out) {
  const int sx = get_global_id(0), sy = get_global_id(1);
  if (sx >= sw || sy >= sh) return;
  const int xa = sx * df, xb = min(W, xa + df), ya = sy * df, yb = min(H, ya + df);
  const float inv = 1.0f / (float)((yb - ya) * (xb - xa));
  for (int c = 0; c <= CHANS; ++c) {
    __global const float* r = colsum + ((size_t)(k * (CHANS + 1) + c) * sh + sy) * W;
    float t = 0;
    for (int x = xa; x < xb; ++x) t += r[x];
    splat_out[((size_t)(o0 + c) * sh + sy) * sw + sx] = t * inv;
  }
}

// Row sums of the per-block covariances: one work-item per reduced row, reading the row's blocks
// in memory order (each block's D x D entries are contiguous) into private sums.
// Manifold k's (cov: the group's blocks, sh x sw per manifold; rows: sh rows per manifold).
__kernel void cov_rows(int sw, int sh, int node, __global const float* cov, __global float* rows) {  // sw: entries per row
  const int sy = get_global_id(0);
  if (sy >= sh) return;
  cov += (size_t)node * sh * sw * TRI;
  rows += (size_t)node * sh * TRI;
  float s[TRI];
  for (int k = 0; k < TRI; ++k) s[k] = 0;
  __global const float* r = cov + (size_t)sy * sw * TRI;
  for (int sx = 0; sx < sw; ++sx)
    for (int k = 0; k < TRI; ++k) s[k] += r[(size_t)sx * TRI + k];
  for (int k = 0; k < TRI; ++k) rows[(size_t)sy * TRI + k] = s[k];
}

// The split directions of a group's m manifolds (one work-item each), on the device so that the
// host never waits for the tree: the row sums of cov_rows added in row order into the D x D
// matrix, then the power iteration of am_detail::split_direction (adaptive_manifold.cpp) step for
// step, from the start vector the host drew for each node (start: D per node id, by id). In
// double where the device has it (as the CPU path computes), float otherwise; products not fused,
// as the CPU path's are not required to be either: the two agree to rounding.
#ifdef cl_khr_fp64
#pragma OPENCL EXTENSION cl_khr_fp64 : enable
typedef double real;
#define REAL_TINY 1e-300
#else
typedef float real;
#define REAL_TINY 1e-37f
#endif
__kernel void split_dirs(int sh, int m, int id0, int iterations, __global const float* rows,
                         __global const real* start, __global float* v) {
#pragma OPENCL FP_CONTRACT OFF
  const int j = get_global_id(0);
  if (j >= m) return;
  real cov[DIMS * DIMS], vd[DIMS], u[DIMS];
  for (int k = 0; k < DIMS * DIMS; ++k) cov[k] = 0;
  for (int sy = 0; sy < sh; ++sy) {
    __global const float* r = rows + ((size_t)j * sh + sy) * TRI;
    for (int a = 0, e = 0; a < DIMS; ++a)
      for (int b = a; b < DIMS; ++b) cov[a * DIMS + b] += (real)r[e++];
  }
  for (int a = 0; a < DIMS; ++a)
    for (int b = 0; b < a; ++b) cov[a * DIMS + b] = cov[b * DIMS + a];
  for (int i = 0; i < DIMS; ++i) vd[i] = start[(size_t)(id0 + j) * DIMS + i];
  for (int it = 0; it < max(1, iterations); ++it) {
    real n = 0;
    for (int i = 0; i < DIMS; ++i) {
      u[i] = 0;
      for (int k = 0; k < DIMS; ++k) u[i] += cov[i * DIMS + k] * vd[k];
      n += u[i] * u[i];
    }
    if (!(n > REAL_TINY)) break;  // the cluster is flat: any direction splits it
    n = sqrt(n);
    for (int i = 0; i < DIMS; ++i) vd[i] = u[i] / n;
  }
  for (int i = 0; i < DIMS; ++i) v[(size_t)j * DIMS + i] = (float)vd[i];
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
// The manifold's D planes start at plane e0 of `eta`.
__kernel void dt_weights(int sw, int sh, int hstride, __global const float* eta, int e0, float ratio2, float ln_a,
                         __global float* ah, __global float* av) {
  const int x0 = 8 * get_global_id(0), y = get_global_id(1);
  if (x0 >= sw || y >= sh) return;
  eta += (size_t)e0 * sw * sh;
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
// (the low-pass h_filter), else ah. A plane's last rows, fewer than 8, run one by one. The planes
// filtered are p0 + get_global_id(1).
__kernel void rf_rows(int w, int h, __global float* p, int p0, __global const float* ah, int hstride, float fixed_a) {
  const int y0 = 8 * get_global_id(0), c = p0 + get_global_id(1);
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
__kernel void rf_cols(int w, int h, __global float* p, int p0, __global const float* av, float fixed_a) {
  const int x0 = 8 * get_global_id(0), c = p0 + get_global_id(1);
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

// The column filter for a GPU: one column of a plane per work-item, the same arithmetic per
// element as rf_cols; neighbouring work-items read neighbouring floats. The rows run as columns of
// the transposed planes (transpose_planes, ClRun::recursive). Measured on an H200 through
// NVIDIA's OpenCL (bench/device/am_device.cpp, DENOISEBENCH_OPENCL_PROFILE): with 8 lanes per work-item
// the recursive filters launched a few hundred work-items and took 72% of the device's time of a
// 1024x768 call. The host picks this form on a GPU device (DENOISEBENCH_OPENCL_LANES overrides).
__kernel void rf_cols1(int w, int h, __global float* p, int p0, __global const float* av, float fixed_a) {
  const int x = get_global_id(0), c = p0 + get_global_id(1);
  if (x >= w) return;
  __global float* q = p + (size_t)c * h * w + x;
  float prev = q[0];
  for (int y = 1; y < h; ++y) {
    const float k = fixed_a != 0 ? fixed_a : av[(size_t)(y - 1) * w + x];
    float cur = q[(size_t)y * w];
    cur += k * (prev - cur);
    q[(size_t)y * w] = cur;
    prev = cur;
  }
  for (int y = h - 2; y >= 0; --y) {
    const float k = fixed_a != 0 ? fixed_a : av[(size_t)y * w + x];
    float cur = q[(size_t)y * w];
    cur += k * (prev - cur);
    q[(size_t)y * w] = cur;
    prev = cur;
  }
}

// Planes s0 + z of src (w x h each, row-major) transposed into planes d0 + z of dst (h x w), in
// 16 x 16 tiles through local memory so that both the reads and the writes of neighbouring
// work-items touch neighbouring floats. The GPU's row filter (ClRun::recursive) runs as
// transpose, column filter, transpose back: a row per work-item (each reading a different row)
// took 3x the column filter's time for the same data on the H200.
#define TT 16
__kernel void transpose_planes(int w, int h, __global const float* src, int s0, __global float* dst, int d0) {
  __local float tile[TT][TT + 1];
  const int z = get_global_id(2);
  const int bx = get_group_id(0) * TT, by = get_group_id(1) * TT;
  const int lx = get_local_id(0), ly = get_local_id(1);
  const size_t plane = (size_t)w * h;
  if (bx + lx < w && by + ly < h) tile[ly][lx] = src[(size_t)(s0 + z) * plane + (size_t)(by + ly) * w + bx + lx];
  barrier(CLK_LOCAL_MEM_FENCE);
  // Element (x, y) of src is element (y, x) of dst, whose rows are h long.
  if (by + lx < h && bx + ly < w) dst[(size_t)(d0 + z) * plane + (size_t)(bx + ly) * h + by + lx] = tile[lx][ly];
}
#undef TT

// n pixels of ch interleaved floats (il) to ch planes of n (planar), one pixel per work-item.
__kernel void to_planar(int n, int ch, __global const float* il, __global float* planar) {
  const int i = get_global_id(0);
  if (i >= n) return;
  for (int c = 0; c < ch; ++c) planar[(size_t)c * n + i] = il[(size_t)i * ch + c];
}

// v . eta of each manifold of a group on the reduced grid (planes (e0 + k) D of eta, v: D
// floats per manifold), one plane per manifold into veta: v . (g - eta) = v . g - v . eta, and
// v . eta is linear in eta, so slice_split_group upsamples one plane instead of D (as the CPU
// path's n.veta).
__kernel void veta(int n, int m, __global const float* eta, int e0, __global const float* v, __global float* out) {
  const int i = get_global_id(0);
  if (i >= n) return;
  for (int k = 0; k < m; ++k) {
    float t = 0;
    for (int c = 0; c < DIMS; ++c) t += v[k * DIMS + c] * eta[((size_t)(e0 + k) * DIMS + c) * n + i];
    out[(size_t)k * n + i] = t;
  }
}

// Slice and split (pass 3) for a group of m manifolds, in float8 lanes like the splat: one
// work-item per 8 full-resolution columns of reduced row sy. Every pixel gathers w_k * blurred_k
// (C + 1 planes per manifold, from plane k (C + 1) of `blurred`) from each manifold in turn into
// acc, which is read and written once per group. Above the leaves, each manifold's cluster
// (label id0 + k) is split: its pixels go left (v_k . (g - eta_k) < 0) or right and are
// relabelled, and each side's (1 - w_k) g and (1 - w_k) are summed over the block's rows into the
// column sums `colsum` (2 (D + 1) planes of sh x W per manifold: the left child's, then the
// right's); split_blocks adds each block's columns into the children's reduced splats. v . eta
// comes from veta's planes, or for the root (eta_full, m = 1) from its full-resolution planes.
// The children's labels belong to the next level, so no other manifold of the group sees them.
__kernel void slice_split_group(int W, int H, int sw, int sh, int df, int m, __global const float* blurred, TABLES,
                                __global const float* wbuf, __global float* acc, int split,
                                __global const float* guide, __global const float* eta_root, int eta_full,
                                __global const float* v, __global const float* vetas, __global ushort* label,
                                int id0, __global float* colsum, int direct, __global float* kids) {
  const int x0 = 8 * get_global_id(0), sy = get_global_id(1);
  if (x0 >= W || sy >= sh) return;
  const Cols8 kt = cols8(x0, W, sw, 0, tx0, tx1, tfx);  // the reduced grid's taps (blurred, veta)
  const int8 xs = kt.xs;
  const float8 valid = kt.valid;
  const int full = kt.full;
  const size_t N = (size_t)W * H, n = (size_t)sw * sh;
  const int ya = sy * df, yb = min(H, ya + df);
  float8 l[MAXG][DIMS + 1], r[MAXG][DIMS + 1];
  if (split)
    for (int k = 0; k < m; ++k)
      for (int c = 0; c <= DIMS; ++c) l[k][c] = r[k][c] = 0;
  for (int y = ya; y < yb; ++y) {
    const size_t row = (size_t)y * W;
    const int r0 = ty0[y], r1 = ty1[y];
    const float fy = tfy[y];
    float8 a[CHANS + 1];
    for (int c = 0; c <= CHANS; ++c) a[c] = load8(acc + (size_t)c * N + row, x0, xs, full);
    float8 g[DIMS];
    int8 lab = 0;
    if (split) {
      for (int c = 0; c < DIMS; ++c) g[c] = load8(guide + (size_t)c * N + row, x0, xs, full);
      lab = full ? convert_int8(vload8(0, label + row + x0))
                 : (int8)(label[row + xs.s0], label[row + xs.s1], label[row + xs.s2], label[row + xs.s3],
                          label[row + xs.s4], label[row + xs.s5], label[row + xs.s6], label[row + xs.s7]);
    }
    int8 relabel = lab;
    for (int k = 0; k < m; ++k) {
      const float8 w = load8(wbuf + (size_t)k * N + row, x0, xs, full);
      for (int c = 0; c <= CHANS; ++c) {
        __global const float* p = blurred + (size_t)(k * (CHANS + 1) + c) * n;
        a[c] += w * upsample8(p + (size_t)r0 * sw, p + (size_t)r1 * sw, fy, kt.taps, kt.base, kt.ix0, kt.ix1, kt.fx);
      }
      if (!split) continue;
      const int id = id0 + k;
      const int8 mine = lab == (int8)(id);  // -1 or 0
      if (!any(mine)) continue;  // no pixel of the cluster: nothing to split, zeros to add
      float8 dot = 0;
      if (eta_full) {
        for (int c = 0; c < DIMS; ++c)
          dot += v[k * DIMS + c] * (g[c] - load8(eta_root + (size_t)c * N + row, x0, xs, full));
      } else {
        __global const float* p = vetas + (size_t)k * n;
        dot = -upsample8(p + (size_t)r0 * sw, p + (size_t)r1 * sw, fy, kt.taps, kt.base, kt.ix0, kt.ix1, kt.fx);
        for (int c = 0; c < DIMS; ++c) dot += v[k * DIMS + c] * g[c];
      }
      const int8 left = dot < (float8)(0.0f);  // -1 or 0
      const float8 theta = (1.0f - w) * -convert_float8(mine) * valid;
      const float8 tl = theta * -convert_float8(left), tr = theta - tl;
      relabel = select(relabel, select((int8)(2 * id + 1), (int8)(2 * id), left), mine);
      for (int c = 0; c < DIMS; ++c) {
        l[k][c] += tl * g[c];
        r[k][c] += tr * g[c];
      }
      l[k][DIMS] += tl;
      r[k][DIMS] += tr;
    }
    for (int c = 0; c <= CHANS; ++c) {
      __global float* o = acc + (size_t)c * N + row + x0;
      if (full)
        vstore8(a[c], 0, o);
      else
        for (int q = 0; q < W - x0; ++q) o[q] = a[c][q];
    }
    if (!split) continue;
    if (full)
      vstore8(convert_ushort8(relabel), 0, label + row + x0);
    else
      for (int q = 0; q < W - x0; ++q) label[row + x0 + q] = (ushort)relabel[q];
  }
  if (!split) return;
  const int sx0 = direct ? x0 / df : 0;
  const float inv_full = direct ? 1.0f / (float)((yb - ya) * df) : 0.0f;
  for (int k = 0; k < m; ++k)
    for (int c = 0; c <= DIMS; ++c) {
      if (direct) {
        const int rows = yb - ya;
        block_store(l[k][c], x0, W, df, rows, sx0, inv_full, kids + ((size_t)(k * 2 * (DIMS + 1) + c) * sh + sy) * sw);
        block_store(r[k][c], x0, W, df, rows, sx0, inv_full,
                    kids + ((size_t)(k * 2 * (DIMS + 1) + DIMS + 1 + c) * sh + sy) * sw);
        continue;
      }
      __global float* ol = colsum + ((size_t)(k * 2 * (DIMS + 1) + c) * sh + sy) * W + x0;
      __global float* orr = colsum + ((size_t)(k * 2 * (DIMS + 1) + DIMS + 1 + c) * sh + sy) * W + x0;
      if (full) {
        vstore8(l[k][c], 0, ol);
        vstore8(r[k][c], 0, orr);
      } else {
        for (int q = 0; q < W - x0; ++q) ol[q] = l[k][c][q], orr[q] = r[k][c][q];
      }
    }
}

// The children's reduced splats from split's column sums: each reduced pixel's df columns
// added, over the block's pixel count (D + 1 planes per child).
__kernel void split_blocks(int W, int H, int sw, int sh, int df, int node, __global const float* colsum,
                           __global float* kids) {
  const int sx = get_global_id(0), sy = get_global_id(1);
  if (sx >= sw || sy >= sh) return;
  const int xa = sx * df, xb = min(W, xa + df), ya = sy * df, yb = min(H, ya + df);
  const float inv = 1.0f / (float)((yb - ya) * (xb - xa));
  for (int c = 0; c <= DIMS; ++c) {
    __global const float* rl = colsum + ((size_t)(node * 2 * (DIMS + 1) + c) * sh + sy) * W;
    __global const float* rr = colsum + ((size_t)(node * 2 * (DIMS + 1) + DIMS + 1 + c) * sh + sy) * W;
    float a = 0, b = 0;
    for (int x = xa; x < xb; ++x) a += rl[x], b += rr[x];
    kids[((size_t)(node * 2 * (DIMS + 1) + c) * sh + sy) * sw + sx] = a * inv;
    kids[((size_t)(node * 2 * (DIMS + 1) + DIMS + 1 + c) * sh + sy) * sw + sx] = b * inv;
  }
}

// A child's manifold: low-passed weighted guide over low-passed weight; where the child's
// cluster left no weight it keeps the parent's manifold (planes p0 .. of parent; the child's go
// to planes e0 .. of eta).
__kernel void divide_eta(int n, __global const float* kid, int k0, __global const float* parent, int p0,
                         __global float* eta, int e0) {
  const int i = get_global_id(0);
  if (i >= n) return;
  kid += (size_t)k0 * n;
  parent += (size_t)p0 * n;
  eta += (size_t)e0 * n;
  const float den = kid[(size_t)DIMS * n + i];
  for (int c = 0; c < DIMS; ++c)
    eta[(size_t)c * n + i] = den > 1e-20f ? kid[(size_t)c * n + i] / den : parent[(size_t)c * n + i];
}

// Slice queries (paper 3.1): the slice at a pixel with another guide value, for a group of m
// manifolds. One work-item per run of queries at the same pixel (runs: the first query of each
// run, then the end): the manifolds' values and blurred splats at the pixel are upsampled once
// for the run (an edge pixel has 16 sub-pixel queries), and each query's sums are read and
// written once per group. Manifold k: D planes from plane (e0 + k) D of eta, C + 1 from plane
// k (C + 1) of blurred.
__kernel void query_group(int nruns, __global const int* runs, int W, int H, int sw, int sh, int m,
                          __global const int* qxy, __global const float* qguide, __global const float* eta, int e0,
                          int eta_full, __global const float* blurred, TABLES, float inv_sr2, __global float* qacc,
                          __global float* qmin) {
  const int r = get_global_id(0);
  if (r >= nruns) return;
  const int q0 = runs[r], q1 = runs[r + 1];
  const int x = qxy[2 * q0], y = qxy[2 * q0 + 1];
  const size_t plane = eta_full ? (size_t)W * H : (size_t)sw * sh, n = (size_t)sw * sh;
  float e[MAXG][DIMS], b[MAXG][CHANS + 1];
  for (int k = 0; k < m; ++k) {
    eta_at(eta + (size_t)(e0 + k) * DIMS * plane, eta_full, W, H, sw, sh, x, y, tx0, tx1, tfx, ty0, ty1, tfy, e[k]);
    for (int c = 0; c <= CHANS; ++c)
      b[k][c] = upsample(blurred + (size_t)(k * (CHANS + 1) + c) * n, sw, tx0[x], tx1[x], tfx[x], ty0[y], ty1[y], tfy[y]);
  }
  for (int q = q0; q < q1; ++q) {
    float a[CHANS + 1];
    for (int c = 0; c <= CHANS; ++c) a[c] = qacc[(size_t)q * (CHANS + 1) + c];
    float nearest = qmin[q];
    for (int k = 0; k < m; ++k) {
      float d2 = 0;
      for (int c = 0; c < DIMS; ++c) {
        const float d = qguide[(size_t)q * DIMS + c] - e[k][c];
        d2 += d * d;
      }
      const float wq = exp(-d2 * inv_sr2);
      for (int c = 0; c <= CHANS; ++c) a[c] += wq * b[k][c];
      nearest = min(nearest, d2);
    }
    for (int c = 0; c <= CHANS; ++c) qacc[(size_t)q * (CHANS + 1) + c] = a[c];
    qmin[q] = nearest;
  }
}

// The queries' answers, as finish computes a pixel's: sum(w blur) / sum(w blur_0) at the query's
// guide, with the outlier adjustment towards its source value where asked (flags bit 0), that
// value being the query's own (flags bit 1: qsrc) or its pixel's; C floats per query.
__kernel void finish_queries(int nq, int W, int H, __global const int* qxy, __global const float* qacc,
                             __global const float* qmin, __global const float* qsrc, __global const int* flags,
                             __global const float* src, float alpha_k, __global float* out) {
  const int q = get_global_id(0);
  if (q >= nq) return;
  const size_t n = (size_t)W * H, i = (size_t)qxy[2 * q + 1] * W + qxy[2 * q];
  const float den = qacc[(size_t)q * (CHANS + 1) + CHANS];
  const float alpha = (flags[q] & 1) ? exp(alpha_k * qmin[q]) : 1.0f;
  for (int c = 0; c < CHANS; ++c) {
    const float f = (flags[q] & 2) ? qsrc[(size_t)q * CHANS + c] : src[(size_t)c * n + i];
    const float g = den > 1e-30f ? qacc[(size_t)q * (CHANS + 1) + c] / den : f;  // kAmMinWeight
    out[(size_t)q * CHANS + c] = f + alpha * (g - f);
  }
}

// The output: sum(w blur) / sum(w blur_0), with the optional outlier adjustment; interleaved, or
// planar (proposed's pipeline, am_cl::am_filter_planar).
__kernel void finish(int W, int H, __global const float* acc, __global const float* src, __global const float* min_d2,
                     int adjust, float alpha_k, int planar, __global float* out) {
  const int x = get_global_id(0), y = get_global_id(1);
  if (x >= W || y >= H) return;
  const size_t i = (size_t)y * W + x, n = (size_t)W * H;
  const float den = acc[(size_t)CHANS * n + i];
  const float alpha = adjust ? exp(alpha_k * min_d2[i]) : 1.0f;
  for (int c = 0; c < CHANS; ++c) {
    const float f = src[(size_t)c * n + i];
    const float g = den > 1e-30f ? acc[(size_t)c * n + i] / den : f;  // kAmMinWeight
    out[planar ? (size_t)c * n + i : i * CHANS + c] = f + alpha * (g - f);
  }
}
