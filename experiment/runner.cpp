#include "experiment/runner.h"

#include <filesystem>
#include <optional>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "core/atomic_file.h"
#include "core/build_info.h"
#include "core/progress.h"
#include "denoisers/method.h"
#include "experiment/execute.h"
#include "experiment/planner.h"
#include "experiment/provenance.h"
#include "experiment/sequences.h"
#include "experiment/store.h"
#include "tracer/render_cache.h"
#include "distributed/mpi_context.h"

namespace fs = std::filesystem;

namespace dnb::experiment {

std::vector<double> time_method(Method& method, const MethodInput& input, int repeats, double repeat_below_seconds,
                                MethodResult& first) {
  first = run_method(method, input);
  std::vector<double> times{first.stats.total_seconds};
  if (first.stats.total_seconds < repeat_below_seconds && repeats > 0) {
    times.clear();
    for (int i = 0; i < repeats; ++i) times.push_back(run_method(method, input).stats.total_seconds);
  }
  return times;
}

namespace {

ResultsDocument results_header(const ExperimentConfig& c) {
  ResultsDocument d;
  d.config = c.recorded();
  d.machine = machine_info();
  d.machine["ranks"] = mpi::size();  // the MPI ranks the run was spread over (1: one process)
  d.build = build_info();
  d.git_revision = build_revision();
  return d;
}

}  // namespace

ResultsDocument run_experiment(const ExperimentConfig& c, const RunOptions& opt, const MethodRegistry& registry) {
  const bool distributed = mpi::size() > 1, root = mpi::is_root();
  Cache cache(opt.cache_dir.empty() ? Cache::default_dir() : opt.cache_dir);
  // Rank 0 alone writes the folder's files and holds its lock (taken before any collective, so
  // that the other ranks of a second run into the folder wait with it).
  std::optional<ResultsStore> store;
  std::optional<Progress> progress;
  std::optional<CellContext> context;
  std::optional<RunLock> run_lock;
  if (root) {
    create_folder(opt.out_dir + "/images");
    if (distributed) create_folder(spool_dir(opt.out_dir));
    store.emplace(opt.out_dir, results_header(c));
    // After the folder's lock (one first process at a time): every process of an earlier run
    // into the folder has ended, the ranks of a killed mpirun included (core/atomic_file.h).
    run_lock.emplace(opt.out_dir, true, [&] {
      spdlog::warn("results folder '{}': processes of an earlier run into it are still running (the ranks of a killed "
                   "mpirun run on for a moment); waiting for them to end",
                   opt.out_dir);
    });
    progress.emplace("experiment " + c.name, cell_count(c), "cells", 0.0);
    context = CellContext{opt.out_dir, &*store, &*progress};
  }
  mpi::barrier();  // the spool folder exists before any rank writes into it
  if (!root) run_lock.emplace(opt.out_dir, false);
  auto run_plans = [&](ScenePlans& sp) {
    if (distributed)
      run_scene_distributed(sp, opt, root ? &*context : nullptr);
    else
      run_scene_here(sp, *context);
  };
  for (const auto& s : c.scenes) {
    if (s.frames > 0) {
      // A sequence: its frames in order, each planned (and its reference rendered) when its turn
      // comes; the temporal methods' history carries from one to the next (docs/sequences.md).
      SequenceRun sequence(s.name, s.frames, cache);
      for (int t = 0; t < s.frames; ++t) run_plans(*rendered_scene_plans(c, opt, registry, cache, s.name, true, &sequence, t));
      if (root) store->set_sequence(s.name, score_sequence(store->document(), opt.out_dir, s.name, s.frames));
      continue;
    }
    const auto sp = s.files      ? file_scene_plans(c, opt, registry, s)
                    : s.renderer ? backend_scene_plans(c, opt, registry, cache, s)
                                 : rendered_scene_plans(c, opt, registry, cache, s.name);
    run_plans(*sp);
  }
  if (!root) return {};
  progress->finish();
  store->write();
  if (distributed && fs::is_empty(spool_dir(opt.out_dir))) fs::remove(spool_dir(opt.out_dir));
  spdlog::info("results in {}/results.json ({} records)", opt.out_dir, store->document().records.size());
  return store->document();
}

}  // namespace dnb::experiment
