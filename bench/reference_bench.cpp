// The fixed costs of references, per pass and per cache lookup, at the paper's 1024x768:
//   references/checkpoint_write  one checkpoint (38 MB of double sums, SHA-256, fsync, rename)
//   references/checkpoint_read   reading and verifying it (what a resume costs)
//   references/cache_verify      verifying a cached reference entry (every cache hit)
//
//   build/bench/denoisebench_bench --benchmark_filter='references/'
//
// Compare checkpoint_write with the time of one pass (block_spp samples of the whole image):
// that ratio is the checkpoint overhead (goal under 2%).
#include <benchmark/benchmark.h>

#include <filesystem>
#include <fstream>
#include <random>

#include "tracer/render_cache.h"
#include "tracer/reference.h"

namespace dnb {
namespace {

// A fresh folder under the system temp dir, removed afterwards.
struct TempFolder {
  std::filesystem::path path;
  TempFolder() {
    std::random_device rd;
    path = std::filesystem::temp_directory_path() / ("dnb-bench-" + std::to_string(rd()) + std::to_string(rd()));
    std::filesystem::create_directories(path);
  }
  ~TempFolder() {
    std::error_code ec;
    std::filesystem::remove_all(path, ec);
  }
  std::string file(const std::string& name) const { return (path / name).string(); }
};

Checkpoint example_checkpoint(int w, int h) {
  Checkpoint ck;
  ck.identity = "bench\n";
  ck.blocks_done = 3;
  ck.sums.width = w;
  ck.sums.height = h;
  ck.sums.samples = 192;
  for (auto& g : ck.sums.group_samples) g = 192 / kSampleGroups;
  ck.sums.sum.resize(std::size_t(w) * h * 3);
  ck.sums.group_sum.resize(ck.sums.sum.size() * kSampleGroups);
  for (std::size_t i = 0; i < ck.sums.sum.size(); ++i) ck.sums.sum[i] = 0.37 * double(i % 1013) + 1e-3 * double(i % 97);
  for (std::size_t i = 0; i < ck.sums.group_sum.size(); ++i) ck.sums.group_sum[i] = 0.21 * double(i % 331);
  return ck;
}

void checkpoint_write(benchmark::State& state) {
  TempFolder tmp;
  const Checkpoint ck = example_checkpoint(1024, 768);
  const std::string path = tmp.file("reference.ckpt");
  write_checkpoint(path, ck);  // warm-up
  for (auto _ : state) write_checkpoint(path, ck);
  state.SetBytesProcessed(std::int64_t(state.iterations()) * std::int64_t(std::filesystem::file_size(path)));
}

void checkpoint_read(benchmark::State& state) {
  TempFolder tmp;
  const std::string path = tmp.file("reference.ckpt");
  write_checkpoint(path, example_checkpoint(1024, 768));
  for (auto _ : state) benchmark::DoNotOptimize(read_checkpoint(path));
}

void cache_verify(benchmark::State& state) {
  TempFolder tmp;
  Cache cache(tmp.file("cache"));
  CacheKey key("reference");
  key.add("bench", 1);
  // A reference EXR of 1024x768 holds about 20 MB (6 float channels, zip-compressed noise).
  cache.store(key, [](const std::string& dir) {
    std::ofstream f(dir + "/reference.exr", std::ios::binary);
    std::string chunk(1 << 20, '\0');
    for (std::size_t i = 0; i < chunk.size(); ++i) chunk[i] = char((i * 2654435761u) >> 13);
    for (int k = 0; k < 20; ++k) f.write(chunk.data(), std::streamsize(chunk.size()));
  });
  for (auto _ : state) benchmark::DoNotOptimize(verify_cache_entry(cache.entry_dir(key), key));
}

BENCHMARK(checkpoint_write)->Name("references/checkpoint_write/1024x768")->Unit(benchmark::kMillisecond)
    ->Repetitions(5)->ReportAggregatesOnly(true);
BENCHMARK(checkpoint_read)->Name("references/checkpoint_read/1024x768")->Unit(benchmark::kMillisecond)
    ->Repetitions(5)->ReportAggregatesOnly(true);
BENCHMARK(cache_verify)->Name("references/cache_verify/20MB")->Unit(benchmark::kMillisecond)
    ->Repetitions(5)->ReportAggregatesOnly(true);

}  // namespace
}  // namespace dnb
