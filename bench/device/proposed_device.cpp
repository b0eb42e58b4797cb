// proposed's whole filter on whatever OpenCL device a machine has (denoisers/proposed_opencl.h),
// from a recorded frame: a small program that needs neither the harness's libraries nor its
// frames, so that it can be carried to a machine with a GPU and its OpenCL driver to measure the
// issue's goal (the whole filter at 1024x768 in at most 10 ms; the paper's 160 ms). The input is a
// real run's frame, plan and CPU output, recorded with DENOISEBENCH_PROPOSED_CAPTURE
// (denoisers/proposed_capture.h); scripts/am_device_bundle --whole makes the bundle.
//
//   denoisebench_proposed_device [--repeat N] [--json OUT] [--perturb EPS] CAPTURE.bin
//
// One run that builds the program (timed on its own), then N timed runs: wall-clock milliseconds
// of the whole filter, from the frame's layers on the host (uploaded) to the composed image back
// on the host, median and minimum. Agreement: the relative RMS difference from the CPU path's
// output recorded with the frame, and the device path's own sensitivity to the rounding of its
// input (the frame's D and I layers, every level, scaled by 1 + EPS u, u uniform in [-1, 1], three
// draws, the largest change; EPS 1e-7 by default: about one ulp), against which to read it
// (tests/denoisers/proposed_opencl_test.cpp holds the two paths within 2x the CPU path's).
// DENOISEBENCH_OPENCL_PROFILE=1 prints each adaptive-manifold call's kernels.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <string>
#include <vector>

#include "core/errors.h"
#include "denoisers/am/opencl.h"
#include "denoisers/proposed_capture.h"
#include "denoisers/proposed_opencl.h"
#include "device_common.h"

namespace {

using namespace dnb;
using namespace dnb::device_tool;

double run_ms(const AovFrame& f, const ProposedDevicePlan& p, Image* out) {
  MethodStats stats;
  const auto t0 = std::chrono::steady_clock::now();
  Image im = proposed_opencl(f, p, stats);
  const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  if (out) *out = std::move(im);
  return ms;
}

}  // namespace

int main(int argc, char** argv) {
  const Args args = parse_args(argc, argv, 1e-7, "[--repeat N >= 1] [--json OUT] [--perturb EPS in (0, 1)] CAPTURE.bin");
  if (!args.ok) return args.help ? 0 : 2;
  if (args.files.size() != 1 || !(args.perturb > 0 && args.perturb < 1)) {
    std::fprintf(stderr, "usage: %s [--repeat N >= 1] [--json OUT] [--perturb EPS in (0, 1)] CAPTURE.bin\n", argv[0]);
    return 2;
  }
  const int repeat = args.repeat;
  const double perturb = args.perturb;
  const std::string &json = args.json, &file = args.files[0];
  try {
    std::string why;
    if (!am_opencl_available(&why)) {
      std::fprintf(stderr, "no OpenCL device: %s\n", why.c_str());
      return 1;
    }
    const std::string device = am_opencl_device_name();
    std::printf("OpenCL device: %s\n", device.c_str());
    const ProposedCapture c = read_proposed_capture(file);
    const AovFrame& f = c.frame;
    Image out;
    const double first = run_ms(f, c.plan, &out);
    std::vector<double> t;
    for (int k = 0; k < repeat; ++k) t.push_back(run_ms(f, c.plan, nullptr));
    const double vs_cpu = relative_rms(out, c.cpu_output);
    double own = 0;
    for (unsigned r = 1; r <= 3; ++r) {
      Image moved;
      run_ms(with_rounding_noise(f, c.plan.levels, float(perturb), r), c.plan, &moved);
      own = std::max(own, relative_rms(moved, out));
    }
    const std::size_t edges = f.edges ? f.edges->size() : 0;
    std::printf("%s: %dx%d, %d reflection levels, %zu edge pixels: first run %.1f ms, median %.2f ms, min %.2f ms over %d; "
                "relative RMS vs the CPU path %.2e, the device path's own under %.0e of its input %.2e\n",
                file.c_str(), f.width(), f.height(), c.plan.levels, edges, first, median(t),
                *std::min_element(t.begin(), t.end()), repeat, vs_cpu, perturb, own);
    if (!json.empty()) {
      std::ofstream o(json + ".tmp");
      o << "{\n  \"device\": " << json_string(device) << ",\n  \"file\": " << json_string(file)
        << ",\n  \"width\": " << f.width() << ",\n  \"height\": " << f.height() << ",\n  \"reflection_levels\": "
        << c.plan.levels << ",\n  \"edge_pixels\": " << edges << ",\n  \"repeat\": " << repeat
        << ",\n  \"first_ms\": " << first << ",\n  \"median_ms\": " << median(t)
        << ",\n  \"min_ms\": " << *std::min_element(t.begin(), t.end()) << ",\n  \"relative_rms_vs_cpu\": " << vs_cpu
        << ",\n  \"perturb\": " << perturb << ",\n  \"relative_rms_perturbed\": " << own << "\n}\n";
      o.close();
      if (!o || std::rename((json + ".tmp").c_str(), json.c_str()) != 0) {
        std::fprintf(stderr, "cannot write %s\n", json.c_str());
        return 1;
      }
    }
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s: %s\n", file.c_str(), e.what());
    return 1;
  }
}
