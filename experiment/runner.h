// The experiment runner behind `denoisebench run CONFIG.toml` (docs/design.md, "Results").
//
// For each scene of the config (experiment/config.h): get the reference (tracer/reference.h:
// cached, checkpointed), then build one CellPlan per cell (experiment/cells.h) and run each
// through the one cell pipeline:
//   plain_cell   plain path tracing at each [speedup] spp: the error-versus-time curve
//   input_cell   the unfiltered input frame at each input spp (content-keyed render cache)
//   method_cell  every method and variant on that frame, through the registry
//                (denoisers/method.h), timed by time_method()
// results.json, results.csv and finished_cells.json are rewritten atomically after every cell
// (experiment/store.h), so an interrupted run resumes without redoing finished cells.
// Under mpirun the cells of each scene are dealt over the ranks and rank 0 stores them: the same
// folder as one process writes (runner.cpp, "Several MPI ranks"; docs/cluster.md). The caller
// holds an mpi::Session; run_experiment returns an empty document on every rank but 0.
#pragma once

#include <string>
#include <vector>

#include "experiment/config.h"
#include "experiment/results.h"

namespace dnb {
class Method;
struct MethodInput;
struct MethodResult;
}  // namespace dnb

namespace dnb::experiment {

struct RunOptions {
  std::string out_dir;
  bool use_cache = true;   // false: render inputs and references again (--no-cache)
  std::string cache_dir;   // empty: Cache::default_dir()
};

// Runs the matrix; returns the results document (also written to out_dir).
ResultsDocument run_experiment(const ExperimentConfig& config, const RunOptions& options);

// Timing of one method cell: the first run (returned in `first`); if it is shorter than
// `repeat_below_seconds` it counts as the warm-up and `repeats` further runs are timed. Returns
// the seconds of every timed run (the cell's time is their median).
std::vector<double> time_method(Method& method, const MethodInput& input, int repeats, double repeat_below_seconds,
                                MethodResult& first);

}  // namespace dnb::experiment
