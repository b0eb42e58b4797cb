// The variance-guided a-trous filter of SVGF (Schied, Kaplanyan, Wyman, Patney, Chaitanya,
// Burgess, Liu, Dachsbacher, Lefohn and Salvi 2017, "Spatiotemporal Variance-Guided Filtering",
// HPG), shared by `svgf` (one frame: the variance from the tracer's variance layers,
// denoisers/svgf.cpp) and `svgf_temporal` (the paper's whole pipeline: the variance from temporal
// moments, denoisers/svgf_temporal.cpp).
//
// Pass i (step 2^i) filters the illumination c with the 5x5 B3-spline kernel h, taps 2^i apart;
// tap q of pixel p has the weight
//     w(p, q) = h(q) * exp(-|z_p - z_q| / (sigma_z |grad z_p| 2^i |q - p|_taps)
//                          - |l_p - l_q| / (sigma_l sqrt(g3x3(Var(l))_p) + eps))
//                    * max(0, n_p . n_q)^sigma_n,
// l the luminance of the pass's input, g3x3 the 3x3 Gaussian prefilter of the variance, and the
// variance is carried through as Var'(p) = sum w^2 Var(q) / (sum w)^2 (the paper's equations
// 1-4). |grad z| is SVGF's fwidth of depth: the sum over x and y of the one-sided depth difference
// of smaller magnitude (it does not jump at silhouettes), on the depth normalised by its median
// (normalized_depth), floored at 1e-8. Pixels that hit nothing (zero normal) blend only with each
// other.
//
// Hand-written: no library implements SVGF (OpenCV, OIIO and OIDN do not). Each pixel of a pass
// reads only the previous pass, rows run in parallel (TBB), taps are summed in a fixed order: the
// output does not depend on the thread count.
#pragma once

#include "core/aov_frame.h"
#include "core/image.h"
#include "denoisers/buffer_pool.h"

namespace dnb::svgf {

inline constexpr float kLumW[3] = {0.2126f, 0.7152f, 0.0722f};  // Rec. 709

// What the edge-stopping functions compare, fixed over the passes.
struct Guides {
  Planes n;          // unit normal (x, y, z, 0); a pixel that hit nothing gets (0, 0, 0, 1)
  Planes z, inv_fw;  // normalised depth, 1 / (sigma_z max(fwidth z, 1e-8))
};
// From the frame's normal and depth layers.
Guides make_guides(const AovFrame& f, float sigma_z);

// Illumination being filtered (three planes) and its luminance variance (one).
struct Signal {
  Planes c;
  Planes var;
};

struct PassSettings {
  float sigma_luminance = 4;       // the paper's sigma_l
  int sigma_normal = 128;          // the paper's sigma_n
  bool variance_prefilter = true;  // the 3x3 Gaussian of the variance before each pass
};

// One a-trous pass with taps `step` pixels apart.
Signal pass(const Signal& in, const Guides& g, int step, const PassSettings& s);

// The 3x3 Gaussian (1/4 centre, 1/8 edge, 1/16 corner) of a variance plane, renormalised where
// taps fall outside the image.
Planes prefilter_variance(const Planes& var);

// Interleaved RGB <-> three planes.
Planes to_planes(const Image& rgb);
Image to_image(const Planes& rgb);

}  // namespace dnb::svgf
