// The adaptive-manifold core on whatever OpenCL device a machine has, from recorded inputs: a
// small program that needs neither the harness's libraries nor its frames, so that it can be
// carried to a machine with a GPU and its OpenCL driver (to measure the OpenCL path on a GPU
// against the paper's 0.16 s; docs/opencl-gpu.md). The inputs are the exact calls of a real run,
// recorded with DENOISEBENCH_AM_CAPTURE (denoisers/am/capture.h); scripts/am_device_bundle makes the bundle
// (this program, its two shared libraries and the captures) and says how to run it.
//
//   denoisebench_am_device [--repeat N] [--json OUT] [--perturb EPS] CAPTURE.bin...
//
// For each capture: one OpenCL run that builds the program (timed on its own), then N timed runs;
// the same on the CPU path (am_filter, all cores); the medians, and the relative RMS difference
// between the two outputs (the image and the slice queries), which tests/denoisers/opencl_test.cpp
// holds below 1e-4 on PoCL. --perturb EPS also runs the CPU path on the guide with its values
// scaled by 1 + EPS u (u uniform in [-1, 1], fixed seed; not those that seed the splits) and reports how far that moves the output:
// the input's own sensitivity, against which to read the two paths' difference (a split whose
// cluster has no dominant direction moves with rounding). Times are wall-clock milliseconds of the whole call: the upload of the
// source and guide, every kernel, the host's tree walk and the read-back.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include <tbb/info.h>

#include "core/errors.h"
#include "device_common.h"
#include "denoisers/am/adaptive_manifold.h"
#include "denoisers/am/opencl.h"
#include "denoisers/am/capture.h"

using namespace dnb::device_tool;
using dnb::relative_rms;

namespace {

using Clock = std::chrono::steady_clock;

double ms_since(Clock::time_point t0) { return std::chrono::duration<double, std::milli>(Clock::now() - t0).count(); }

// Pixels whose values differ by more than 1% of the reference's RMS value (in any channel): few
// and large when the two paths split a tree node's cluster differently (a pixel whose projection
// lies within rounding of the split plane), many and small when the arithmetic drifts.
std::size_t pixels_off(const dnb::Image& a, const dnb::Image& b) {
  double r = 0;
  for (std::size_t i = 0; i < b.size(); ++i) r += double(b.data()[i]) * b.data()[i];
  const double tol = 0.01 * std::sqrt(r / double(std::max<std::size_t>(b.size(), 1)));
  std::size_t n = 0;
  const int c = b.channels();
  for (std::size_t p = 0; p < b.pixel_count(); ++p)
    for (int k = 0; k < c; ++k)
      if (std::fabs(double(a.data()[p * c + k]) - b.data()[p * c + k]) > tol) {
        ++n;
        break;
      }
  return n;
}

struct Result {
  std::string file;
  int w = 0, h = 0, c = 0, d = 0;
  std::size_t queries = 0;
  double cl_first = 0, cl_median = 0, cpu_median = 0, rms_image = 0, rms_queries = 0, rms_perturbed = -1;
  std::size_t pixels_off = 0;
};

}  // namespace

int main(int argc, char** argv) {
  const Args args =
      parse_args(argc, argv, 0.0, "[--repeat N >= 1] [--json OUT] [--perturb EPS] CAPTURE.bin...");
  if (!args.ok) return args.help ? 0 : 2;
  const int repeat = args.repeat;
  const double perturb = args.perturb;
  const std::string& json = args.json;
  const std::vector<std::string>& files = args.files;
  std::string why;
  if (!dnb::am_opencl_available(&why)) {
    std::fprintf(stderr, "am_device: %s\n", why.c_str());
    return 1;
  }
  const std::string device = dnb::am_opencl_device_name();
  std::printf("OpenCL device: %s; CPU path on %d threads\n", device.c_str(), tbb::info::default_concurrency());
  std::vector<Result> results;
  try {
    for (const std::string& f : files) {
      const dnb::AmCapture cap = dnb::read_am_capture(f);
      Result r;
      r.file = f;
      r.w = cap.src.width();
      r.h = cap.src.height();
      r.c = cap.src.channels();
      r.d = cap.guide.channels();
      r.queries = cap.queries.size();
      std::vector<float> q_cl, q_cpu;
      auto t0 = Clock::now();
      dnb::Image out_cl = dnb::am_filter_opencl(cap.src.cview(), cap.guide.cview(), cap.settings, cap.queries, &q_cl);
      r.cl_first = ms_since(t0);
      std::vector<double> t_cl, t_cpu;
      for (int k = 0; k < repeat; ++k) {
        t0 = Clock::now();
        out_cl = dnb::am_filter_opencl(cap.src.cview(), cap.guide.cview(), cap.settings, cap.queries, &q_cl);
        t_cl.push_back(ms_since(t0));
      }
      dnb::Image out_cpu = dnb::am_filter(cap.src.cview(), cap.guide.cview(), cap.settings, cap.queries, &q_cpu);
      for (int k = 0; k < repeat; ++k) {
        t0 = Clock::now();
        out_cpu = dnb::am_filter(cap.src.cview(), cap.guide.cview(), cap.settings, cap.queries, &q_cpu);
        t_cpu.push_back(ms_since(t0));
      }
      r.cl_median = median(t_cl);
      r.cpu_median = median(t_cpu);
      r.rms_image = relative_rms(out_cl.data(), out_cpu.data(), out_cpu.size());
      r.pixels_off = pixels_off(out_cl, out_cpu);
      if (perturb > 0) {
        dnb::Image g = cap.guide;
        std::mt19937 rng(1);
        std::uniform_real_distribution<float> u(-1.0f, 1.0f);
        // Not the floats that seed the power iteration (adaptive_manifold.cpp's guide_seed reads
        // every 61st): a new seed would start every split from another random vector.
        for (std::size_t k = 0; k < g.size(); ++k)
          if (k % 61 != 0) g.data()[k] *= 1.0f + float(perturb) * u(rng);
        const dnb::Image moved = dnb::am_filter(cap.src.cview(), g.cview(), cap.settings, cap.queries);
        r.rms_perturbed = relative_rms(moved.data(), out_cpu.data(), out_cpu.size());
        std::printf("%s: the CPU path on the guide perturbed by %g: relative RMS %.2e (%zu pixels off)\n", f.c_str(),
                    perturb, r.rms_perturbed, pixels_off(moved, out_cpu));
      }
      r.rms_queries = q_cpu.size() == q_cl.size() ? relative_rms(q_cl.data(), q_cpu.data(), q_cpu.size()) : -1.0;
      std::printf("%s: %dx%d, %d source and %d guide channels, %zu queries: OpenCL first %.1f ms, median %.2f ms; "
                  "CPU median %.2f ms; relative RMS image %.2e (%zu pixels off by over 1%% of its RMS), queries %.2e\n",
                  f.c_str(), r.w, r.h, r.c, r.d, r.queries, r.cl_first, r.cl_median, r.cpu_median, r.rms_image,
                  r.pixels_off, r.rms_queries);
      results.push_back(r);
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "am_device: %s\n", e.what());
    return 1;
  }
  double sum_cl = 0, sum_cpu = 0;
  for (const Result& r : results) {
    sum_cl += r.cl_median;
    sum_cpu += r.cpu_median;
  }
  std::printf("all %zu captures: OpenCL %.2f ms, CPU %.2f ms (sums of the medians of %d runs)\n", results.size(), sum_cl,
              sum_cpu, repeat);
  if (!json.empty()) {
    // Written by hand: this program links no JSON library, so that it travels with two shared libraries.
    std::ofstream o(json + ".tmp");
    o << "{\n  \"device\": " << json_string(device) << ",\n  \"cpu_threads\": " << tbb::info::default_concurrency()
      << ",\n  \"repeat\": " << repeat << ",\n  \"captures\": [\n";
    for (std::size_t i = 0; i < results.size(); ++i) {
      const Result& r = results[i];
      o << "    {\"file\": " << json_string(r.file) << ", \"width\": " << r.w << ", \"height\": " << r.h
        << ", \"source_channels\": " << r.c << ", \"guide_channels\": " << r.d << ", \"queries\": " << r.queries
        << ", \"opencl_first_ms\": " << json_number(r.cl_first) << ", \"opencl_median_ms\": " << json_number(r.cl_median)
        << ", \"cpu_median_ms\": " << json_number(r.cpu_median) << ", \"relative_rms_image\": " << json_number(r.rms_image)
        << ", \"relative_rms_queries\": " << json_number(r.rms_queries) << ", \"pixels_off\": " << r.pixels_off
        << ", \"relative_rms_perturbed\": " << json_number(r.rms_perturbed) << "}" << (i + 1 < results.size() ? "," : "") << "\n";
    }
    o << "  ],\n  \"opencl_ms_sum\": " << json_number(sum_cl) << ",\n  \"cpu_ms_sum\": " << json_number(sum_cpu) << "\n}\n";
    o.close();
    if (!o || std::rename((json + ".tmp").c_str(), json.c_str()) != 0) {
      std::fprintf(stderr, "am_device: cannot write %s\n", json.c_str());
      return 1;
    }
  }
  return 0;
}
