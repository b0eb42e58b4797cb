// The one main() of denoisebench_bench: the other bench/*.cpp files register cases. It adds
// the machine's description to the output's context (what Google Benchmark records, plus the
// CPU model, the OpenCL device, the build and the nightly reference workload), so that a JSON
// file (--benchmark_out=FILE --benchmark_out_format=json) says where its numbers come from.
//
// Options of its own, removed before Google Benchmark reads the rest:
//   --dnb_nightly_size=WxH        frame size of the nightly/ cases (default 256x192)
//   --dnb_count_instructions      nightly/ cases run the method once more after the warm-up
//                                 with callgrind's collection on, and time nothing: run under
//                                 `valgrind --tool=callgrind --collect-atstart=no`, the count
//                                 valgrind reports is that one run's (scripts/nightly_instructions)
#include <benchmark/benchmark.h>

#include <cstring>
#include <fstream>
#include <string>
#include <thread>
#include <vector>

#include <unistd.h>

#include "core/env.h"
#include "bench/bench_util.h"
#include "core/build_info.h"
#include "tracer/render.h"

#ifdef DNB_WITH_OPENCL
#include <CL/opencl.hpp>
#endif

namespace dnb::bench {
void register_nightly_cases(int width, int height, bool count_instructions);  // nightly_bench.cpp
}

namespace {

std::string cpu_model() {
  std::ifstream cpu("/proc/cpuinfo");
  for (std::string line; std::getline(cpu, line);)
    if (line.rfind("model name", 0) == 0) return line.substr(line.find(':') + 2);
  return "unknown";
}

// The device the OpenCL path uses (denoisers/am/opencl.h: the first device of the
// first platform, or of platform $DENOISEBENCH_OPENCL_PLATFORM).
std::string opencl_device() {
#ifdef DNB_WITH_OPENCL
  try {
    std::vector<cl::Platform> platforms;
    cl::Platform::get(&platforms);
    std::size_t index = 0;
    if (const char* p = dnb::env::get("OPENCL_PLATFORM")) index = std::size_t(std::atoi(p));
    if (index >= platforms.size()) return "none";
    std::vector<cl::Device> devices;
    platforms[index].getDevices(CL_DEVICE_TYPE_ALL, &devices);
    if (devices.empty()) return "none";
    return platforms[index].getInfo<CL_PLATFORM_NAME>() + ": " + devices[0].getInfo<CL_DEVICE_NAME>();
  } catch (const std::exception& e) {
    return std::string("none (") + e.what() + ")";
  }
#else
  return "not built (DNB_WITH_OPENCL=OFF)";
#endif
}

}  // namespace

int main(int argc, char** argv) {
  int width = 256, height = 192;
  bool count_instructions = false;
  std::vector<char*> args;
  for (int i = 0; i < argc; ++i) {
    if (std::strcmp(argv[i], "--dnb_count_instructions") == 0) {
      count_instructions = true;
      continue;
    }
    const char* flag = "--dnb_nightly_size=";
    if (std::strncmp(argv[i], flag, std::strlen(flag)) == 0) {
      if (std::sscanf(argv[i] + std::strlen(flag), "%dx%d", &width, &height) != 2 || width < 8 || height < 8) {
        std::fprintf(stderr, "denoisebench_bench: %s: expected --dnb_nightly_size=WxH with W, H >= 8\n", argv[i]);
        return 2;
      }
      continue;
    }
    args.push_back(argv[i]);
  }
  int n = int(args.size());
  dnb::bench::register_nightly_cases(width, height, count_instructions);

  char host[256] = {};
  gethostname(host, sizeof host - 1);
  benchmark::AddCustomContext("cpu_model", cpu_model());
  benchmark::AddCustomContext("hostname", host);
  benchmark::AddCustomContext("hardware_threads", std::to_string(std::thread::hardware_concurrency()));
  benchmark::AddCustomContext("opencl_device", opencl_device());
  benchmark::AddCustomContext("denoisebench_version", dnb::build_version());
  benchmark::AddCustomContext("git_revision", dnb::build_revision());
  benchmark::AddCustomContext("build_type", dnb::build_type());
  benchmark::AddCustomContext("compiler", dnb::build_compiler());
  benchmark::AddCustomContext("tracer_version", dnb::kTracerVersion);
  benchmark::AddCustomContext("nightly_reference_workload", dnb::bench::ReferenceWorkload::description());
  benchmark::AddCustomContext("nightly_size", std::to_string(width) + "x" + std::to_string(height));

  benchmark::Initialize(&n, args.data());
  if (benchmark::ReportUnrecognizedArguments(n, args.data())) return 2;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
