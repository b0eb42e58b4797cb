// The experiment runner behind `denoisebench run CONFIG.toml` (docs/design.md, "Results").
//
// For each scene of the config (experiment/config.h): get the reference (tracer/reference.h:
// cached, checkpointed), plan its cells (experiment/planner.h: plain path tracing, the input
// frame, every method and variant on it, timed by time_method()), and run the plans through the
// one cell pipeline (experiment/cells.h) with an executor (experiment/execute.h: one process,
// or several MPI ranks).
// results.json, results.csv and finished_cells.json are rewritten atomically after every cell
// (experiment/store.h), so an interrupted run resumes without redoing finished cells.
// Under mpirun the cells of each scene are dealt over the ranks and rank 0 stores them: the same
// folder as one process writes (execute_mpi.cpp; docs/cluster.md). The caller
// holds an mpi::Session; run_experiment returns an empty document on every rank but 0.
#pragma once

#include <string>
#include <vector>

#include "experiment/config.h"
#include "experiment/results.h"

namespace dnb {
class Method;
class MethodRegistry;
struct MethodInput;
struct MethodResult;
}  // namespace dnb

namespace dnb::experiment {

struct RunOptions {
  std::string out_dir;
  bool use_cache = true;   // false: render inputs and references again (--no-cache)
  std::string cache_dir;   // empty: Cache::default_dir()
};

// Runs the matrix with the methods of `registry` (the built-in ones and the plug-ins loaded into
// it); returns the results document (also written to out_dir).
ResultsDocument run_experiment(const ExperimentConfig& config, const RunOptions& options, const MethodRegistry& registry);

// Timing of one method cell: the first run (returned in `first`); if it is shorter than
// `repeat_below_seconds` it counts as the warm-up and `repeats` further runs are timed. Returns
// the seconds of every timed run (the cell's time is their median).
std::vector<double> time_method(Method& method, const MethodInput& input, int repeats, double repeat_below_seconds,
                                MethodResult& first);

}  // namespace dnb::experiment
