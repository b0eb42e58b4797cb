// Frame files at the paper's 1024x768 (core/exr_io.h): what every step of a run pays to write and
// read an AOV frame (cornell-box, 16 spp, every layer and the edge file).
//   io/write_frame          the whole frame: strips interleaved, zip-compressed, written through a
//                           temporary file, fsynced and renamed (AtomicOutput)
//   io/read_frame           the whole frame, strip by strip, with its edge file
//   io/read_frame_colour    the colour layer alone (what metrics and the reference cache read;
//                           the other layers are decoded a strip at a time and dropped)
//
//   build/bench/denoisebench_bench --benchmark_filter='io/'
//
// Bytes per second are of the frame file (bytes_per_second), for comparing with the disk.
#include <benchmark/benchmark.h>

#include <filesystem>
#include <random>

#include "bench/bench_util.h"
#include "core/exr_io.h"

namespace dnb {
namespace {

struct TempFrame {
  std::filesystem::path dir;
  std::string path;
  TempFrame() {
    std::random_device rd;
    dir = std::filesystem::temp_directory_path() / ("dnb-bench-io-" + std::to_string(rd()) + std::to_string(rd()));
    std::filesystem::create_directories(dir);
    path = (dir / "frame.exr").string();
  }
  ~TempFrame() {
    std::error_code ec;
    std::filesystem::remove_all(dir, ec);
  }
  std::int64_t bytes() const { return std::int64_t(std::filesystem::file_size(path)); }
};

const AovFrame& frame() { return bench::rendered_frame("cornell-box", 1024, 768, 16); }

void write_frame_bench(benchmark::State& state) {
  TempFrame tmp;
  write_frame(frame(), tmp.path);  // warm-up
  for (auto _ : state) write_frame(frame(), tmp.path);
  state.SetBytesProcessed(state.iterations() * tmp.bytes());
  state.counters["layers"] = double(frame().layers().size());
}

void read_frame_bench(benchmark::State& state, bool colour_only) {
  TempFrame tmp;
  write_frame(frame(), tmp.path);
  const auto only = colour_only ? std::optional<std::vector<std::string>>(std::vector<std::string>{layer::kColor})
                                : std::nullopt;
  benchmark::DoNotOptimize(read_frame(tmp.path, {}, only));  // warm-up (page cache)
  for (auto _ : state) benchmark::DoNotOptimize(read_frame(tmp.path, {}, only));
  state.SetBytesProcessed(state.iterations() * tmp.bytes());
}

BENCHMARK(write_frame_bench)->Name("io/write_frame/1024x768")->Unit(benchmark::kMillisecond)->UseRealTime()
    ->Repetitions(5)->ReportAggregatesOnly(true);
BENCHMARK_CAPTURE(read_frame_bench, all, false)->Name("io/read_frame/1024x768")->Unit(benchmark::kMillisecond)
    ->UseRealTime()->Repetitions(5)->ReportAggregatesOnly(true);
BENCHMARK_CAPTURE(read_frame_bench, colour, true)->Name("io/read_frame_colour/1024x768")->Unit(benchmark::kMillisecond)
    ->UseRealTime()->Repetitions(5)->ReportAggregatesOnly(true);

}  // namespace
}  // namespace dnb
