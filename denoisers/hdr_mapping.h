// Range compression of HDR radiance for filters whose range kernel or storage assumes a
// bounded, perceptually even scale (bilateral, non-local means, edge-stopping weights).
// A filter maps its input with compress(), works there, and maps its result back with
// expand(); expand(compress(x)) == x up to float rounding for every x >= 0 the map keeps
// (srgb keeps only [0, 1]).
//
//   linear    y = x                                    no compression
//   log       y = log(1 + x)                           relative differences; unbounded
//   reinhard  y = (x / (1 + x))^(1/2.2)                Reinhard's global operator, then a
//                                                      display gamma so dark tones get codes;
//                                                      maps [0, inf) onto [0, 1)
//   srgb      y = sRGB transfer of clamp(x, 0, 1)      the metrics' 8-bit domain; loses x > 1
//
// Negative radiance is not physical: every map except linear clamps x at 0 first.
#pragma once

#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "core/image.h"

namespace dnb {

enum class RangeMap { Linear, Log, Reinhard, Srgb };

// "linear", "log", "reinhard", "srgb": the choices of a method's range_map parameter.
std::vector<std::string> range_map_names();
RangeMap parse_range_map(const std::string& name);  // InputError listing the names

float compress(RangeMap map, float x);
float expand(RangeMap map, float y);
// In place over every sample (parallel, order-independent).
void compress(RangeMap map, Image& image);
void expand(RangeMap map, Image& image);

// 8-bit storage for filters that only take 8-bit input (OpenCV's non-local means):
// code = round(255 * compress(x)), clamped to 0..255.
cv::Mat to_8bit(RangeMap map, const Image& image);

// The float image that sits on a 32-bit float cv::Mat of the same shape without copying
// (the Image must outlive the Mat). Channels map to cv::Mat channels.
cv::Mat as_mat(Image& image);
cv::Mat as_mat(const Image& image);  // do not write through it
Image from_mat(const cv::Mat& m);   // copy of a CV_32FC(n) matrix

}  // namespace dnb
