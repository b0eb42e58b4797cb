// The experiment config file behind `denoisebench run CONFIG.toml` (configs/quick.toml is the
// smallest example): scenes, input spp, methods and variants, reference, timing and the
// speed-up curve. Read strictly: unknown keys, unknown methods (listing the registry's),
// unknown method parameters and bad values are InputErrors naming the file and key, before
// any work starts.
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "experiment/results.h"

namespace dnb::experiment {

// A method as the config names it: a registry method with parameter overrides. A variant
// ([[variant]] name = "proposed-no-nlm", method = "proposed", set = {...}) is one of these too.
struct MethodSpec {
  std::string name;     // the column name in the tables
  std::string method;   // the registry name
  std::map<std::string, std::string> params;
  std::string group;    // "ablation" for ablation rows, else ""
  Role role() const { return role_of_group(group, name); }  // validated by load_config
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
  Table2Columns table2;               // [table2] filter_cpu, filter_opencl, irradiance_cache
  std::vector<std::string> plugins;   // plug-in folders (`plugins = [...]`, relative to the file)

  // The config as results.json records it.
  RunConfig recorded() const;
};

// Also registers the plug-ins the config's `plugins` folders, $DENOISEBENCH_PLUGINS and the
// repository's plugins/ hold (methods/plugins.h), so that its methods can name them.
ExperimentConfig load_config(const std::string& path);

}  // namespace dnb::experiment
