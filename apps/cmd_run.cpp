// denoisebench run CONFIG.toml [-o RESULTS_DIR] [--no-cache] [--seed S]: the experiment matrix
// (experiment/runner.h). --seed replaces the config's input seed (the nightly's noise
// measurement runs one config with several seeds). Under `mpirun -np N` the matrix spreads over
// the ranks and rank 0 writes the results folder (experiment/execute_mpi.cpp, docs/cluster.md).
#include <algorithm>
#include <cstdint>
#include <filesystem>
#include <optional>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "apps/args.h"
#include "apps/commands.h"
#include "core/errors.h"
#include "denoisers/method.h"
#include "experiment/estimate.h"
#include "experiment/runner.h"
#include "core/atomic_file.h"
#include "methods/plugins.h"
#include "distributed/mpi_context.h"

namespace dnb::app {

namespace {

struct Opts {
  std::string config, out, cache_dir, estimate_json;
  bool no_cache = false, estimate = false;
  std::vector<int> ranks;
  std::optional<std::uint64_t> seed;
};

int run(const Opts& o, const std::vector<std::string>& plugin_folders) {
  load_plugins(plugin_folders);
  experiment::ExperimentConfig c = experiment::load_config(o.config);
  if (o.seed) c.seed = *o.seed;
  experiment::RunOptions opt;
  opt.out_dir = o.out.empty() ? "results/" + c.name : o.out;
  opt.use_cache = !o.no_cache;
  opt.cache_dir = o.cache_dir;
  if (o.estimate) {
    if (mpi::size() > 1) throw InputError("run --estimate: run it as one process; --ranks N says how N ranks would do");
    const auto est = experiment::estimate_run(c, opt, MethodRegistry::global());
    fmt::print("{}", est.text(o.ranks));
    if (!o.estimate_json.empty()) write_text_atomic(o.estimate_json, est.to_json(o.ranks).dump(1) + "\n");
    return 0;
  }
  const auto doc = experiment::run_experiment(c, opt, MethodRegistry::global());
  if (doc.failures.empty()) return 0;
  // The run kept every other cell; the failed ones are listed in results.json and tried
  // again by the next run into the folder.
  for (const auto& f : doc.failures) spdlog::error("failed cell: {} / {} / {} spp: {}", f.scene, f.method, f.spp, f.reason);
  spdlog::error("{} of the run's cells failed (listed in {}/results.json, key 'failures')", doc.failures.size(), opt.out_dir);
  return 1;
}

}  // namespace

void add_run(CLI::App& app, Action& action) {
  auto* cmd = app.add_subcommand("run", "Run an experiment matrix from a config (scenes x methods x spp)");
  auto o = std::make_shared<Opts>();
  cmd->add_option("CONFIG", o->config, "experiment config (TOML), e.g. configs/quick.toml")->required();
  cmd->add_option("-o,--output", o->out, "results folder (default: results/<config name>)");
  cmd->add_flag("--no-cache", o->no_cache, "render inputs and references again instead of using the cache");
  cmd->add_option("--seed", o->seed, "seed of the input frames instead of the config's (the reference keeps its own)")
      ->check(in_bounds(bounds::kSeed));
  cmd->add_option("--cache-dir", o->cache_dir, "render cache folder (default: $DENOISEBENCH_CACHE or ~/.cache/denoisebench)");
  cmd->add_flag("--estimate", o->estimate,
                "print what the run would cost (per scene and stage, from a short probe of this machine; what the "
                "cache and the results folder hold) and do nothing else (docs/estimate.md)");
  cmd->add_option("--ranks", o->ranks,
                  "with --estimate: also the estimate for MPI runs of N ranks, each as fast as this process "
                  "(several: --ranks 8 32)")
      ->check(CLI::Range(1, 100000));
  cmd->add_option("--estimate-json", o->estimate_json, "with --estimate: also write the estimate as JSON to this file");
  auto plugins = add_plugins_option(cmd);
  cmd->callback([&action, o, plugins] {
    action = [o, plugins] {
      mpi::Session mpi_session;  // under mpirun: the matrix spreads over the ranks
      // Rank 0 speaks for the job; other ranks only warn.
      if (!mpi::is_root()) spdlog::set_level(std::max(spdlog::get_level(), spdlog::level::warn));
      try {
        return run(*o, *plugins);
      } catch (const std::exception& e) {
        // One rank's error would leave the others waiting in a collective: end the whole job.
        if (mpi::size() > 1) {
          spdlog::error("rank {}: {}", mpi::rank(), e.what());
          mpi::abort_job(dynamic_cast<const InputError*>(&e) ? 2 : 1);
        }
        throw;
      }
    };
  });
}

}  // namespace dnb::app
