// The experiment runner behind `denoisebench run CONFIG.toml` (DESIGN.md, "Results").
//
// For each scene of the config: render the input frame at every input spp (content-keyed
// cache, tracer/cache.h), get the reference (tracer/reference.h: cached, checkpointed), run
// every method and method variant through the registry (denoisers/method.h), time it (one
// run; methods under a second are run `repeats` more times and the median taken, the first run
// being the warm-up), score it with every metric (metrics/metrics.h), and write the output
// image and its error maps as EXR. Plain path tracing at the config's speed-up spp list gives
// the error-versus-time curve of the speed-up claim. results.json and results.csv are rewritten
// atomically after every cell, so an interrupted run resumes without redoing finished cells.
#pragma once

#include <map>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace dnb::experiment {

// A method as the config names it: a registry method with parameter overrides. A variant
// ([[variant]] name = "proposed-no-nlm", method = "proposed", set = {...}) is one of these too.
struct MethodSpec {
  std::string name;     // the column name in the tables
  std::string method;   // the registry name
  std::map<std::string, std::string> params;
  std::string group;    // "ablation" for ablation rows, else ""
};

struct ExperimentConfig {
  std::string path;
  std::string name;
  int width = 256, height = 192;
  std::uint64_t seed = 1;
  std::uint64_t reference_seed = 1000003;  // independent of the inputs' samples
  std::vector<std::string> scenes;
  std::vector<int> spp;               // input spp of the matrix
  int reference_spp = 1024;
  int reference_block_spp = 64;
  int max_depth = 8;
  std::vector<int> plain_spp;         // plain path tracing curve (speed-up claim)
  std::vector<MethodSpec> methods;    // methods then variants, config order
  int repeats = 3;                    // timing repeats of methods under a second
  double repeat_below_seconds = 1.0;
  int threads = 0;
  // Table 2 columns: which method is "the filter" on CPU and on OpenCL ("" when none).
  std::string table2_cpu = "proposed", table2_opencl = "", table2_irradiance_cache = "irradiance_cache";
};

// Strict reading: unknown keys, unknown methods (listing the registry's) and unknown method
// parameters are InputErrors naming the file and key.
ExperimentConfig load_config(const std::string& path);

struct RunOptions {
  std::string out_dir;
  bool use_cache = true;   // false: render inputs and references again (--no-cache)
  std::string cache_dir;   // empty: Cache::default_dir()
};

// Runs the matrix; returns the results document (also written to out_dir).
nlohmann::json run_experiment(const ExperimentConfig& config, const RunOptions& options);

// results.csv from results.json's records: one row per record, metrics and timings as columns.
std::string results_csv(const nlohmann::json& results);

}  // namespace dnb::experiment
