// denoisebench run CONFIG.toml [-o RESULTS_DIR] [--no-cache] [--seed S]: the experiment matrix
// (experiment/runner.h). --seed replaces the config's input seed (the nightly's noise
// measurement runs one config with several seeds).
#include <cstdint>
#include <filesystem>
#include <optional>

#include "apps/args.h"
#include "apps/commands.h"
#include "experiment/runner.h"

namespace dnb::app {

void add_run(CLI::App& app, Action& action) {
  auto* cmd = app.add_subcommand("run", "Run an experiment matrix from a config (scenes x methods x spp)");
  struct Opts {
    std::string config, out, cache_dir;
    bool no_cache = false;
    std::optional<std::uint64_t> seed;
  };
  auto o = std::make_shared<Opts>();
  cmd->add_option("CONFIG", o->config, "experiment config (TOML), e.g. configs/quick.toml")->required();
  cmd->add_option("-o,--output", o->out, "results folder (default: results/<config name>)");
  cmd->add_flag("--no-cache", o->no_cache, "render inputs and references again instead of using the cache");
  cmd->add_option("--seed", o->seed, "seed of the input frames instead of the config's (the reference keeps its own)")
      ->check(in_bounds(bounds::kSeed));
  cmd->add_option("--cache-dir", o->cache_dir, "render cache folder (default: $DENOISEBENCH_CACHE or ~/.cache/denoisebench)");
  cmd->callback([&action, o] {
    action = [o] {
      experiment::ExperimentConfig c = experiment::load_config(o->config);
      if (o->seed) c.seed = *o->seed;
      experiment::RunOptions opt;
      opt.out_dir = o->out.empty() ? "results/" + c.name : o->out;
      opt.use_cache = !o->no_cache;
      opt.cache_dir = o->cache_dir;
      experiment::run_experiment(c, opt);
      return 0;
    };
  });
}

}  // namespace dnb::app
