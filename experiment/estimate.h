// `denoisebench run CONFIG --estimate [--ranks N]`: what a run will cost, before any of it is
// done. Per rendered scene, a probe measures this machine on that scene: loading it, frame
// renders (every AOV) and colour-only renders (references and the plain curve) at two small
// sizes, writing and reading a frame, every method of the config and the scoring of a cell on
// the probe frames. Each cost is fitted as a + b * pixels (a: fixed cost, such as a plug-in
// worker's start) over the two sizes, times samples per pixel for renders, and the plan's work
// at the config's size is priced with it. What the render cache and the results folder already
// hold costs nothing (or a read). docs/estimate.md says how the model was checked.
#pragma once

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
  int ranks = 1;
  double one_process_seconds = 0;  // the sum of every scene's stages
  double seconds = 0;              // with `ranks` ranks (one_process_seconds for 1)
  double probe_seconds = 0;
  std::string text() const;        // the table `run --estimate` prints
  nlohmann::json to_json() const;
};

// The estimate of running `c` into options.out_dir with `ranks` MPI ranks, each as fast as this
// process. Renders and runs methods only at probe sizes, in a temporary folder; writes nothing
// into the results folder or the render cache.
RunEstimate estimate_run(const ExperimentConfig& c, const RunOptions& options, const MethodRegistry& registry, int ranks);

}  // namespace dnb::experiment
