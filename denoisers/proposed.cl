// OpenCL kernels of proposed's pipeline on the device (denoisers/proposed_opencl.cpp drives them):
// every step of proposed.cpp's filter_layer, compose_levels and guard_details besides the
// adaptive-manifold core (am/adaptive_manifold.cl, built into the same program, whose `real`
// these use). Each kernel follows the CPU function it names operation by operation; images are
// planar (channel c of pixel i of an n-pixel image at c n + i).

inline float pp_lum(float r, float g, float b) { return 0.2126f * r + 0.7152f * g + 0.0722f * b; }
inline float pp_finite0(float a) { return isfinite(a) ? a : 0.0f; }

// split_fireflies (illumination.cpp): each pixel's bound is ratio times the largest luminance of
// its 8 neighbours inside the image (infinite without any); a pixel above it is scaled down to it.
__kernel void pp_fireflies(int W, int H, float ratio, __global const float* in, __global float* kept,
                           __global float* bound, __global int* cut) {
  const int x = get_global_id(0), y = get_global_id(1);
  if (x >= W || y >= H) return;
  const size_t n = (size_t)W * H, i = (size_t)y * W + x;
  float m = 0;
  int any = 0;
  for (int dy = -1; dy <= 1; ++dy)
    for (int dx = -1; dx <= 1; ++dx) {
      const int xx = x + dx, yy = y + dy;
      if ((dx || dy) && xx >= 0 && yy >= 0 && xx < W && yy < H) {
        const size_t q = (size_t)yy * W + xx;
        m = max(m, pp_lum(in[q], in[n + q], in[2 * n + q]));
        any = 1;
      }
    }
  const float b = any ? ratio * m : INFINITY;
  bound[i] = b;
  float r = in[i], g = in[n + i], bl = in[2 * n + i];
  const float l = pp_lum(r, g, bl);
  if (l > b) {  // clamp_luminance
    const float s = b / l;
    r *= s, g *= s, bl *= s;
    atomic_inc(cut);
  }
  kept[i] = r, kept[n + i] = g, kept[2 * n + i] = bl;
}

// Row sums (one work-item per row) of max(0, luminance) of a planar RGB image (mode 0, nlm_space's
// mean_luminance) or of the finite values of all `ch` planes (mode 1, guard_details' mean).
__kernel void pp_sum_rows(int W, int H, int ch, int mode, __global const float* img, __global real* rows) {
  const int y = get_global_id(0);
  if (y >= H) return;
  const size_t n = (size_t)W * H;
  real s = 0;
  if (mode == 0) {
    for (int x = 0; x < W; ++x) {
      const size_t i = (size_t)y * W + x;
      s += (real)max(0.0f, pp_lum(img[i], img[n + i], img[2 * n + i]));
    }
  } else {
    for (int x = 0; x < W; ++x)  // pixel by pixel, its channels in order, as the CPU loop over the interleaved image
      for (int c = 0; c < ch; ++c) s += (real)pp_finite0(img[(size_t)c * n + (size_t)y * W + x]);
  }
  rows[y] = s;
}
// The rows' sums in row order (one work-item) over `count` values; mode 0: nlm_space's scale
// (1 for a black image), mode 1: guard_details' e = (0.01 mean)^2 + 1e-20.
__kernel void pp_sum_finish(int H, int count, int mode, __global const real* rows, __global float* out) {
  if (get_global_id(0) != 0) return;
  real s = 0;
  for (int y = 0; y < H; ++y) s += rows[y];
  if (mode == 0) {
    const real m = s / (real)count;
    out[0] = m > (real)1e-12 ? (float)m : 1.0f;
  } else {
    const real m = (real)0.01 * s / (real)max(count, 1);
    out[0] = (float)(m * m) + 1e-20f;
  }
}

// nlm_space's compressed luminance y = log(1 + max(0, lum) / m).
__kernel void pp_compress(int n, __global const float* img, __global const float* m, __global float* y) {
  const int i = get_global_id(0);
  if (i >= n) return;
  y[i] = log(1.0f + max(0.0f, pp_lum(img[i], img[n + i], img[2 * n + i])) / m[0]);
}

// Index of coordinate v in [0, n) under the border of nlm_space's padding: reflect-101, or
// replicate for an image no wider than the radius.
inline int pp_border(int v, int n, int reflect) {
  if (reflect) {
    if (v < 0) v = -v;
    if (v >= n) v = 2 * n - 2 - v;
    return v;
  }
  return clamp(v, 0, n - 1);
}

// The weighted patches of the PCA's sample pixels, planar: tap j of sample r at j * count + r, so
// that the sums below read rows (work-item (r, j): neighbours in r write neighbouring values).
__kernel void pp_patches(int count, int W, int H, int R, int reflect, __global const int* picks, __global const float* y,
                         __global const float* weight, __global real* patches) {
  const int r = get_global_id(0), j = get_global_id(1), side = 2 * R + 1;
  if (r >= count || j >= side * side) return;
  const int p = picks[r], cx = p % W, cy = p / W, dy = j / side, dx = j % side;
  const int xx = pp_border(cx + dx - R, W, reflect), yy = pp_border(cy + dy - R, H, reflect);
  patches[(size_t)j * count + r] = (real)(weight[j] * y[(size_t)yy * W + xx]);
}

// The sum of a row of n reals, in 8 lanes then across them (the order is fixed).
inline real pp_row_sum(__global const real* x, int n) {
  real l[8] = {0, 0, 0, 0, 0, 0, 0, 0};
  int r = 0;
  for (; r + 8 <= n; r += 8)
    for (int k = 0; k < 8; ++k) l[k] += x[r + k];
  real s = ((l[0] + l[1]) + (l[2] + l[3])) + ((l[4] + l[5]) + (l[6] + l[7]));
  for (; r < n; ++r) s += x[r];
  return s;
}

// The patches' mean (one work-item per tap) and covariance scaled by 1 / count (work-item (a, b),
// b >= a, writes both entries), cv::calcCovarMatrix's COVAR_NORMAL | COVAR_ROWS | COVAR_SCALE.
__kernel void pp_patch_mean(int count, int P, __global const real* patches, __global real* mean) {
  const int a = get_global_id(0);
  if (a < P) mean[a] = pp_row_sum(patches + (size_t)a * count, count) / (real)count;
}
__kernel void pp_patch_cov(int count, int P, __global const real* patches, __global const real* mean, __global real* cov) {
  const int a = get_global_id(0), b = get_global_id(1);
  if (a >= P || b >= P || b < a) return;
  __global const real* xa = patches + (size_t)a * count;
  __global const real* xb = patches + (size_t)b * count;
  const real ma = mean[a], mb = mean[b];
  real l[8] = {0, 0, 0, 0, 0, 0, 0, 0};
  int r = 0;
  for (; r + 8 <= count; r += 8)
    for (int k = 0; k < 8; ++k) l[k] += (xa[r + k] - ma) * (xb[r + k] - mb);
  real s = ((l[0] + l[1]) + (l[2] + l[3])) + ((l[4] + l[5]) + (l[6] + l[7]));
  for (; r < count; ++r) s += (xa[r] - ma) * (xb[r] - mb);
  s /= (real)count;
  cov[a * P + b] = s, cov[b * P + a] = s;
}

// y padded by R on every side under nlm_space's border, for pp_project8; the buffer has 8 floats of
// slack after it (pp_project8's last lanes read past the last row and are dropped).
__kernel void pp_pad(int W, int H, int R, int reflect, __global const float* y, __global float* padded) {
  const int x = get_global_id(0), yy = get_global_id(1);
  const int PW = W + 2 * R, PH = H + 2 * R;
  if (x >= PW || yy >= PH) return;
  padded[(size_t)yy * PW + x] = y[(size_t)pp_border(yy - R, H, reflect) * W + pp_border(x - R, W, reflect)];
}

#if DIMS > 4
// The NLM vectors (the program's guide has DIMS = NLM components + normal + depth): per component,
// the correlation of y with its kernel (P taps) minus its offset, 8 pixels of a row per work-item
// in float8 lanes (one tap loop for every component: PoCL vectorises the lanes, a GPU loses nothing).
#define NLMD (DIMS - 4)
__kernel void pp_project8(int W, int H, int R, __global const float* padded, __global const float* kern,
                          __global const float* offsets, __global float* out) {
  const int x0 = get_global_id(0) * 8, y = get_global_id(1);
  if (x0 >= W || y >= H) return;
  const int side = 2 * R + 1, P = side * side, PW = W + 2 * R;
  float8 acc[NLMD];
  for (int k = 0; k < NLMD; ++k) acc[k] = (float8)(0.0f);
  for (int dy = 0; dy < side; ++dy) {
    __global const float* row = padded + (size_t)(y + dy) * PW + x0;
    for (int dx = 0; dx < side; ++dx) {
      const float8 v = vload8(0, row + dx);
      for (int k = 0; k < NLMD; ++k) acc[k] += kern[k * P + dy * side + dx] * v;
    }
  }
  const size_t n = (size_t)W * H;
  const int lanes = min(8, W - x0);
  for (int k = 0; k < NLMD; ++k) {
    float a[8];
    vstore8(acc[k] - offsets[k], 0, a);
    for (int i = 0; i < lanes; ++i) out[(size_t)k * n + (size_t)y * W + x0 + i] = a[i];
  }
}
#endif

// make_guide of [NLM vectors, normal, depth over its median]: each group times sigma_r / its sigma.
__kernel void pp_guide(int n, int dims, __global const float* nlm, float s_nlm, __global const float* normal, float s_normal,
                       __global const float* depth, float s_depth, __global float* guide) {
  const int i = get_global_id(0);
  if (i >= n) return;
  for (int k = 0; k < dims; ++k) guide[(size_t)k * n + i] = s_nlm * nlm[(size_t)k * n + i];
  for (int c = 0; c < 3; ++c) guide[(size_t)(dims + c) * n + i] = s_normal * normal[(size_t)c * n + i];
  guide[(size_t)(dims + 3) * n + i] = s_depth * depth[i];
}

// normalized_depth (illumination.cpp): depth over the median of the positive finite depths (the
// host's, from its copy of the frame), 0 where the pixel hit nothing.
__kernel void pp_normalize_depth(int n, __global const float* z, float median, __global float* out) {
  const int i = get_global_id(0);
  if (i >= n) return;
  const float v = z[i];
  out[i] = (isfinite(v) && v > 0) ? v / median : 0.0f;
}

// The edge sub-pixels' queries (proposed.cpp's edge_queries): each sub-pixel's value, clamped to
// its pixel's firefly bound (clamp set), and its guide: the pixel's NLM vector with the centre of
// its patch replaced by the sub-pixel's compressed value, the sub-pixel's normal and depth, scaled
// as the guide.
__kernel void pp_edge_guides(int nq, int W, int H, int dims, __global const int* qxy, __global const float* sub_value,
                             int clamp_to_bound, __global const float* bound, __global const float* kept,
                             __global const float* m, __global const float* nlm, __global const float* center, float s_nlm,
                             __global const float* sub_normal, float s_normal, __global const float* sub_depth,
                             float depth_scale, float s_depth, __global float* qguide, __global float* qsrc) {
  const int q = get_global_id(0);
  if (q >= nq) return;
  const size_t n = (size_t)W * H, i = (size_t)qxy[2 * q + 1] * W + qxy[2 * q];
  float v[3] = {sub_value[3 * q], sub_value[3 * q + 1], sub_value[3 * q + 2]};
  if (clamp_to_bound) {
    const float l = pp_lum(v[0], v[1], v[2]), b = bound[i];
    if (l > b) {
      const float s = b / l;
      v[0] *= s, v[1] *= s, v[2] *= s;
    }
  }
  for (int c = 0; c < 3; ++c) qsrc[3 * q + c] = v[c];
  const float own = log(1.0f + max(0.0f, pp_lum(kept[i], kept[n + i], kept[2 * n + i])) / m[0]);
  const float delta = log(1.0f + max(0.0f, pp_lum(v[0], v[1], v[2])) / m[0]) - own;
  const int D = dims + 4;
  for (int k = 0; k < dims; ++k) qguide[(size_t)q * D + k] = (nlm[(size_t)k * n + i] + center[k] * delta) * s_nlm;
  for (int c = 0; c < 3; ++c) qguide[(size_t)q * D + dims + c] = sub_normal[3 * q + c] * s_normal;
  const float z = sub_depth[q];
  qguide[(size_t)q * D + dims + 3] = ((z > 0 && isfinite(z)) ? z * depth_scale : 0.0f) * s_depth;
}

// a + b element by element (a reflection level's D + I, reflection_sum).
__kernel void pp_add(int count, __global const float* a, __global const float* b, __global float* out) {
  const int i = get_global_id(0);
  if (i < count) out[i] = a[i] + b[i];
}

// One pass of smooth_tint (illumination.cpp) on a w x h image: the mean of the raw tints of the
// same-surface neighbours within the band around the centre value (the raw tint's sum on the
// first pass, `centre` on the second), summed in the CPU path's order (rows, then offsets); the
// second pass starts from the first's output (`prev`), as the CPU path's passes share one image.
// keep (has_keep): 1 for pixels that keep their own tint (edge pixels). next (has_next): the new
// centre values.
__kernel void pp_tint_pass(int w, int h, int r, float band, float n2, float dmax, __global const float* tint,
                           __global const float* normal, __global const float* depth, int has_keep,
                           __global const uchar* keep, int first, __global const float* centre,
                           __global const float* prev, __global float* out, int has_next, __global float* next) {
  const int x = get_global_id(0), y = get_global_id(1);
  if (x >= w || y >= h) return;
  const size_t n = (size_t)w * h, p = (size_t)y * w + x;
  const float tr = tint[p], tg = tint[n + p], tb = tint[2 * n + p], ts = tr + tg + tb;
  const float cen = first ? ts : centre[p];
  // A pixel the pass leaves keeps what it had: the raw tint, or the first pass's value.
  float o0 = first ? tr : prev[p], o1 = first ? tg : prev[n + p], o2 = first ? tb : prev[2 * n + p], nc = cen;
  const float part_p = has_keep && keep[p] ? 0.0f : 1.0f;
  if (ts != 0.0f && part_p != 0.0f) {
    float sr = 0, sg = 0, sb = 0, cnt = 0, border = 0;
    const float nx = normal[p], ny = normal[n + p], nz = normal[2 * n + p], zp = depth[p];
    for (int yy = max(0, y - r); yy <= min(h - 1, y + r); ++yy)
      for (int dx = -r; dx <= r; ++dx) {
        const int xx = x + dx;
        if (xx < 0 || xx >= w) continue;
        const size_t q = (size_t)yy * w + xx;
        const float a = nx - normal[q], b = ny - normal[n + q], c = nz - normal[2 * n + q];
        const float part_q = has_keep && keep[q] ? 0.0f : 1.0f;
        const float same = part_q * (a * a + b * b + c * c <= n2 ? 1.0f : 0.0f) * (fabs(depth[q] - zp) <= dmax ? 1.0f : 0.0f);
        const float tq0 = tint[q], tq1 = tint[n + q], tq2 = tint[2 * n + q], tsq = tq0 + tq1 + tq2;
        const float nonzero = tsq != 0.0f ? 1.0f : 0.0f;
        const float in = same * nonzero * (fabs(tsq - cen) <= band * cen ? 1.0f : 0.0f);
        border += same * (1.0f - nonzero);
        sr += in * (tq0 - tr), sg += in * (tq1 - tg), sb += in * (tq2 - tb);
        cnt += in;
      }
    if (border == 0.0f && cnt != 0.0f) {
      o0 = tr + sr / cnt, o1 = tg + sg / cnt, o2 = tb + sb / cnt;
      nc = o0 + o1 + o2;
    }
  }
  out[p] = o0, out[n + p] = o1, out[2 * n + p] = o2;
  if (has_next) next[p] = nc;
}

// What reaches level k from the levels below (proposed.cpp's compose_level, `reflected`): with a
// level below, its tint times the composed level below plus the part of R no level explains
// (R_k - raw tint F_{k+1}); without, R_k itself.
inline float pp_reflected(size_t j, int below, __global const float* R, __global const float* tint,
                          __global const float* raw_tint, __global const float* composed, __global const float* d1,
                          __global const float* i1, __global const float* t1, __global const float* r1,
                          __global const float* e1) {
  if (!below) return R[j];
  const float f1 = (d1[j] + i1[j]) * t1[j] + r1[j] + e1[j];
  return tint[j] * composed[j] + (R[j] - raw_tint[j] * f1);
}

// F'_k = (D'_k + I'_k) T_k + reflected + E_k, element by element (3 planes).
__kernel void pp_compose(int count, __global const float* fd, __global const float* fi, __global const float* T,
                         __global const float* E, __global const float* R, int below, __global const float* tint,
                         __global const float* raw_tint, __global const float* composed, __global const float* d1,
                         __global const float* i1, __global const float* t1, __global const float* r1,
                         __global const float* e1, __global float* out) {
  const int j = get_global_id(0);
  if (j >= count) return;
  out[j] = (fd[j] + fi[j]) * T[j] + pp_reflected(j, below, R, tint, raw_tint, composed, d1, i1, t1, r1, e1) + E[j];
}

// Formula 1 per sub-pixel at level 0's edge pixels: the mean over the 16 of (D'_s + I'_s) T_s, plus
// the pixel's reflected light and emission.
__kernel void pp_compose_edges(int npx, int n, int per, __global const int* pixels, __global const float* qd,
                               __global const float* qi, __global const float* sub_albedo, __global const float* E,
                               __global const float* R, int below, __global const float* tint,
                               __global const float* raw_tint, __global const float* composed, __global const float* d1,
                               __global const float* i1, __global const float* t1, __global const float* r1,
                               __global const float* e1, __global float* out) {
  const int e = get_global_id(0);
  if (e >= npx) return;
  const size_t px = (size_t)pixels[e];
  for (int c = 0; c < 3; ++c) {
    float sum = 0;
    for (int s = 0; s < per; ++s) {
      const size_t q = ((size_t)e * per + s) * 3 + c;
      sum += (qd[q] + qi[q]) * sub_albedo[q];
    }
    const size_t j = (size_t)c * n + px;
    out[j] = sum / per + pp_reflected(j, below, R, tint, raw_tint, composed, d1, i1, t1, r1, e1) + E[j];
  }
}

// The detail guard (proposed.cpp's guard_details) in its steps: the relative variance
// v / (F'^2 + e); the 5x5 median (cv::medianBlur's, replicated border) of each plane; the standard
// deviation with its floor and the change in units of it; the clamp.
__kernel void pp_guard_rel(int count, __global const float* out, __global const float* v, __global const float* e,
                           __global float* work) {
  const int k = get_global_id(0);
  if (k >= count) return;
  const float o = pp_finite0(out[k]);
  work[k] = max(pp_finite0(v[k]), 0.0f) / (o * o + e[0]);
}
// The 5x5 median by a selection network of 99 compare-exchanges (min and max, no branches, so that
// PoCL vectorises it across work-items; the network is Devillard's opt_med25, checked on all 2^25
// 0-1 inputs, which by the 0-1 principle makes it the median of any 25 values).
#define PP_SORT(a, b) { const float lo = min(v[a], v[b]); v[b] = max(v[a], v[b]); v[a] = lo; }
__kernel void pp_median5(int W, int H, __global const float* in, __global float* out) {
  const int x = get_global_id(0), y = get_global_id(1), c = get_global_id(2);
  if (x >= W || y >= H) return;
  const size_t plane = (size_t)c * W * H;
  float v[25];
  int k = 0;
  for (int dy = -2; dy <= 2; ++dy)
    for (int dx = -2; dx <= 2; ++dx) v[k++] = in[plane + (size_t)clamp(y + dy, 0, H - 1) * W + clamp(x + dx, 0, W - 1)];
  PP_SORT(0, 1); PP_SORT(3, 4); PP_SORT(2, 4); PP_SORT(2, 3); PP_SORT(6, 7); PP_SORT(5, 7);
  PP_SORT(5, 6); PP_SORT(9, 10); PP_SORT(8, 10); PP_SORT(8, 9); PP_SORT(12, 13); PP_SORT(11, 13);
  PP_SORT(11, 12); PP_SORT(15, 16); PP_SORT(14, 16); PP_SORT(14, 15); PP_SORT(18, 19); PP_SORT(17, 19);
  PP_SORT(17, 18); PP_SORT(21, 22); PP_SORT(20, 22); PP_SORT(20, 21); PP_SORT(23, 24); PP_SORT(2, 5);
  PP_SORT(3, 6); PP_SORT(0, 6); PP_SORT(0, 3); PP_SORT(4, 7); PP_SORT(1, 7); PP_SORT(1, 4);
  PP_SORT(11, 14); PP_SORT(8, 14); PP_SORT(8, 11); PP_SORT(12, 15); PP_SORT(9, 15); PP_SORT(9, 12);
  PP_SORT(13, 16); PP_SORT(10, 16); PP_SORT(10, 13); PP_SORT(20, 23); PP_SORT(17, 23); PP_SORT(17, 20);
  PP_SORT(21, 24); PP_SORT(18, 24); PP_SORT(18, 21); PP_SORT(19, 22); PP_SORT(8, 17); PP_SORT(9, 18);
  PP_SORT(0, 18); PP_SORT(0, 9); PP_SORT(10, 19); PP_SORT(1, 19); PP_SORT(1, 10); PP_SORT(11, 20);
  PP_SORT(2, 20); PP_SORT(2, 11); PP_SORT(12, 21); PP_SORT(3, 21); PP_SORT(3, 12); PP_SORT(13, 22);
  PP_SORT(4, 22); PP_SORT(4, 13); PP_SORT(14, 23); PP_SORT(5, 23); PP_SORT(5, 14); PP_SORT(15, 24);
  PP_SORT(6, 24); PP_SORT(6, 15); PP_SORT(7, 16); PP_SORT(7, 19); PP_SORT(13, 21); PP_SORT(15, 23);
  PP_SORT(7, 13); PP_SORT(7, 15); PP_SORT(1, 9); PP_SORT(3, 11); PP_SORT(5, 17); PP_SORT(11, 17);
  PP_SORT(9, 17); PP_SORT(4, 10); PP_SORT(6, 12); PP_SORT(7, 14); PP_SORT(4, 6); PP_SORT(4, 7);
  PP_SORT(12, 14); PP_SORT(10, 14); PP_SORT(6, 7); PP_SORT(10, 12); PP_SORT(6, 10); PP_SORT(6, 17);
  PP_SORT(12, 17); PP_SORT(7, 17); PP_SORT(7, 10); PP_SORT(12, 18); PP_SORT(7, 12); PP_SORT(10, 18);
  PP_SORT(12, 20); PP_SORT(10, 20); PP_SORT(10, 12);
  out[plane + (size_t)y * W + x] = v[12];
}
#undef PP_SORT
__kernel void pp_guard_sd(int count, __global const float* out, __global const float* v, __global const float* x,
                          __global const float* med, __global const float* e, __global float* sd, __global float* work) {
  const int k = get_global_id(0);
  if (k >= count) return;
  const float o = pp_finite0(out[k]);
  sd[k] = sqrt(max(max(pp_finite0(v[k]), 0.0f), med[k] * (o * o + e[0])));
  const float z = fabs(o - pp_finite0(x[k])) / sd[k];
  work[k] = isfinite(z) ? z : 0.0f;
}
__kernel void pp_guard_clamp(int count, float guard, __global const float* x, __global const float* sd,
                             __global const float* med, __global float* out, __global int* clamped) {
  const int k = get_global_id(0);
  if (k >= count) return;
  const float in = x[k], o = out[k];
  const float band = guard * sd[k] * max(1.0f, 1.4826f * med[k]);
  if (!isfinite(in) || !isfinite(o) || !isfinite(band)) return;
  const float g = clamp(o, in - band, in + band);
  if (g != o) atomic_inc(clamped);
  out[k] = g;
}

// Planar to interleaved (the result's one read-back).
__kernel void pp_interleave(int n, int ch, __global const float* planar, __global float* il) {
  const int i = get_global_id(0);
  if (i >= n) return;
  for (int c = 0; c < ch; ++c) il[(size_t)i * ch + c] = planar[(size_t)c * n + i];
}
