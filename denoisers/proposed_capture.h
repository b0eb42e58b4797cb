// One frame of `proposed` recorded for proposed's device pipeline, to be carried to a machine
// that has a GPU and its OpenCL driver but none of the harness's libraries
// (bench/device/proposed_device.cpp, scripts/am_device_bundle --whole): the layers the pipeline
// reads, the edge sub-pixels, the frame's plan (ProposedDevicePlan) and the CPU path's output on
// it. Written by a CPU run of proposed on the illumination split when
// DENOISEBENCH_PROPOSED_CAPTURE names a file that does not exist yet (written whole or not at
// all; a benchmark's later repetitions leave it).
//
// Format (little-endian, as the machines that read it): "DNBPCAP1", the plan's fields in the order
// of write_plan, width and height, the layer count, each layer as its name (length, bytes), its
// channel count and its floats; the edge pixels and their samples (EdgeSample's 13 floats each);
// the CPU output (width x height x 3 floats). Bad files give an InputError naming the file and
// what was expected.
#pragma once

#include <string>

#include "core/aov_frame.h"
#include "core/image.h"
#include "denoisers/proposed_opencl.h"

namespace dnb {

struct ProposedCapture {
  AovFrame frame;
  ProposedDevicePlan plan;
  Image cpu_output;
};

void write_proposed_capture(const std::string& path, const AovFrame& frame, const ProposedDevicePlan& plan,
                            const Image& cpu_output);
ProposedCapture read_proposed_capture(const std::string& path);

}  // namespace dnb
