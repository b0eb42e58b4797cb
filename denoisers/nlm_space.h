// Non-local-means space (paper step 1; Buades et al. 2005, and Gastal and Oliveira 2012's NLM
// application of adaptive manifolds): every pixel is mapped to the vector of its patch, reduced
// by PCA to a few dimensions, so that Euclidean distance between two pixels' vectors is (up to
// the dropped components, mostly noise) the Gaussian-weighted patch distance NL-means uses.
//
// Choices, documented here because the method's parameters depend on them:
//   - range-compressed domain: y = log(1 + lum / m), lum the Rec. 709 luminance of the
//     illumination and m its mean over the image. Distances are then about relative
//     differences (0.1 = 10% brighter) whatever the scene's exposure, and a lamp does not
//     dominate the PCA. Luminance only: the patch has 49 dimensions instead of 147, a 3x
//     cheaper projection, and the illumination's chroma varies slowly (it is untextured).
//   - patch: (2 radius + 1)^2 pixels (7x7 by default), each weighted by a Gaussian of
//     patch_sigma pixels normalised to sum 1 (so the first component is about the local mean);
//     borders reflect (OpenCV's BORDER_REFLECT_101).
//   - PCA: covariance of the weighted patches of `samples` pixels drawn without a fixed grid
//     by std::mt19937_64 seeded from a hash of the image (deterministic), eigenvectors by
//     cv::eigen; the projection of every pixel is a 7x7 correlation per component
//     (cv::filter2D), minus the projected mean patch.
#pragma once

#include <cstdint>
#include <vector>

#include <opencv2/core/mat.hpp>

#include "core/image.h"

namespace dnb {

struct NlmSpaceSettings {
  int radius = 3;             // patch radius: (2 radius + 1)^2 patch
  float patch_sigma = 2.0f;   // Gaussian weight of the patch pixels, pixels
  int dims = 6;               // leading principal components kept
  int samples = 4096;         // patches drawn to estimate the PCA
};

struct NlmSpace {
  Image vectors;               // dims channels per pixel
  std::vector<float> center;   // per component: basis weight of the patch's centre pixel
  float mean_luminance = 1.0f; // m of the range compression
  // The compressed value y = log(1 + lum / m) of an RGB illumination value.
  float compress(const float* rgb) const;
  // The vector of pixel (x, y) if its own illumination were `rgb` (its neighbours unchanged):
  // only the centre pixel of the patch changes, so the change is linear in y (paper 3.1, a
  // sub-pixel's NLM vector). Writes dims floats.
  void vector_with_center(const Image& illumination, int x, int y, const float* rgb, float* out) const;
  // The same for n values at one pixel (an edge pixel's sub-pixels): rgb holds n RGB triples,
  // vector i goes to out + i * stride. Equal to n calls of vector_with_center, in one pass.
  void vectors_with_centers(const Image& illumination, int x, int y, const float* rgb, int n, float* out,
                            int stride) const;
};

NlmSpace nlm_space(const Image& illumination, const NlmSpaceSettings& settings);

// The pieces of nlm_space() that proposed's OpenCL pipeline (denoisers/proposed_opencl.cpp)
// shares, so that both build the space the same way:
// the seed of the PCA's patch sample: a hash of every 53rd float of the image and its size;
std::uint64_t nlm_sample_seed(ConstImageView image);
// the patch's Gaussian weights, (2 radius + 1)^2 row by row, summing to 1;
std::vector<float> nlm_patch_weights(const NlmSpaceSettings& settings);
// the pixels (y w + x) whose patches estimate the PCA: min(samples, w h) of them, every pixel
// once when that is all of them, else drawn by std::mt19937_64(seed);
std::vector<int> nlm_sample_pixels(std::uint64_t seed, int w, int h, int samples);
// and the basis from the weighted patches (one per row, CV_64F): per component its correlation
// kernel (the eigenvector times the weights, P floats), the projected mean patch (subtracted) and
// the kernel's centre weight.
struct NlmBasis {
  std::vector<float> kernels;   // dims x P
  std::vector<double> offsets;  // dims
  std::vector<float> center;    // dims
};
NlmBasis nlm_basis(const cv::Mat& patches, const std::vector<float>& weight, int dims);
// The same from the patches' covariance (P x P, scaled by 1 / count) and mean (1 x P), CV_64F.
NlmBasis nlm_basis_from_covariance(const cv::Mat& covar, const cv::Mat& mean, const std::vector<float>& weight, int dims);

// m of the range compression: the mean Rec. 709 luminance (1 for a black image).
float illumination_scale(const Image& illumination);
// The compressed illumination itself (3 channels, y = log(1 + L / m) per channel): the guide of
// the "no NLM space" ablation.
Image compressed_illumination(const Image& illumination, float m);

}  // namespace dnb
