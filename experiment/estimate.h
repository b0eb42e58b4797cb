// `denoisebench run CONFIG --estimate [--ranks N ...]`: what a run will cost, before any of it is
// done. Per rendered scene, a probe measures this machine on that scene: loading it, frame
// renders (every AOV) and colour-only renders (references and the plain curve) at two small
// sizes, writing and reading a frame, every method of the config and the scoring of a cell on
// the probe frames. Each cost is fitted as a + b * pixels (a: fixed cost, such as a plug-in
// worker's start) over the two sizes, times samples per pixel for renders, and the plan's work
// at the config's size is priced with it. What the render cache and the results folder already
// hold costs nothing (or a read). docs/estimate.md says how the model was checked.
#pragma once

#include <algorithm>
#include <map>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "denoisers/method.h"
#include "experiment/config.h"
#include "experiment/runner.h"

namespace dnb::experiment {

// One stage of one scene: its seconds on one process, and how many of its items (renders or
// cells) there are and how many the cache or the results folder already holds.
struct StageEstimate {
  double seconds = 0;
  int items = 0;
  int held = 0;
};

struct SceneEstimate {
  std::string scene;
  bool estimated = true;
  std::string why_not;  // when not estimated (a scene read from files)
  double load_seconds = 0;
  StageEstimate reference, inputs, curve, methods;
  std::map<std::string, double> method_cell_seconds;  // per column, one cell at the config's size
  double probe_seconds = 0;                            // what the probe itself took
  double total() const { return load_seconds + reference.seconds + inputs.seconds + curve.seconds + methods.seconds; }
};

struct RunEstimate {
  std::vector<SceneEstimate> scenes;
  double one_process_seconds = 0;  // the sum of every scene's stages
  double load_seconds = 0, reference_seconds = 0, cell_seconds = 0;  // over the scenes
  double longest_group_seconds = 0;  // the costliest group of cells (one input and its methods)
  double probe_seconds = 0;
  // With N MPI ranks, each as fast as this process: every rank loads every scene; the
  // references' blocks are shared over the ranks; the groups of cells are handed out one at a
  // time, so the run cannot end before its longest group.
  double with_ranks(int n) const {
    return n <= 1 ? one_process_seconds
                  : load_seconds + reference_seconds / n + std::max(cell_seconds / n, longest_group_seconds);
  }
  std::string text(const std::vector<int>& ranks = {}) const;  // the table `run --estimate` prints
  nlohmann::json to_json(const std::vector<int>& ranks = {}) const;
};

// The estimate of running `c` into options.out_dir. Renders and runs methods only at probe
// sizes, in a temporary folder; writes nothing into the results folder or the render cache.
RunEstimate estimate_run(const ExperimentConfig& c, const RunOptions& options, const MethodRegistry& registry);

}  // namespace dnb::experiment
