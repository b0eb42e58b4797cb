// The planner of `denoisebench run`: a config's scene becomes its cells' plans (CellPlan,
// experiment/cells.h), in the order a one-process run visits them, grouped by the input frame
// they share. It computes nothing: a plan's compute() does, when an executor (execute.h) runs it.
//   plain cells   plain path tracing at each [speedup] spp: the error-versus-time curve
//   input cells   the unfiltered input frame at each input spp and seed
//   method cells  every method and variant on that frame, created from the registry passed in
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "denoisers/method.h"
#include "experiment/cells.h"
#include "experiment/config.h"
#include "experiment/frame_sources.h"
#include "experiment/runner.h"
#include "experiment/sequences.h"
#include "tracer/render_cache.h"
#include "tracer/reference.h"
#include "tracer/scene.h"

namespace dnb::experiment {

// A scene's cells in the order a one-process run visits them, in groups that share an input
// frame (the plain path-tracing curve is a group without one). Built whole per scene, run group
// by group: a group's frame is freed after its cells.
struct PlanGroup {
  std::unique_ptr<InputFrame> frame;  // null: the plain curve
  std::unique_ptr<PlainCurve> curve;  // the plain curve's render
  std::vector<CellPlan> plans;        // with a frame: the input cell first, then every method
  void release() {
    if (frame) frame->release();
    if (curve) curve->release();
  }
};

struct ScenePlans {
  std::shared_ptr<const Scene> scene;  // null for a scene read from files or rendered by a back-end
  std::unique_ptr<BackendScene> backend;  // a scene a renderer back-end renders
  Reference ref;                       // under MPI: on rank 0 only
  SceneCells cells;
  std::vector<PlanGroup> groups;
};

// Every cell of a rendered scene: the plain path-tracing curve, then per input spp and seed the
// input and every method on it. Renders (or reads from the cache) the scene's reference: under
// MPI collectively, only rank 0 keeping it. Without `with_reference` (run --estimate: the plans'
// cell keys only) the reference is neither rendered nor read, and the folder is not touched.
// With `sequence`: frame `t` of that animated scene (docs/sequences.md), row sequence_row(name, t),
// without a plain curve, its temporal methods run from the sequence's state.
std::unique_ptr<ScenePlans> rendered_scene_plans(const ExperimentConfig& c, const RunOptions& opt,
                                                 const MethodRegistry& registry, Cache& cache, const std::string& name,
                                                 bool with_reference = true, SequenceRun* sequence = nullptr, int t = 0);
// Every cell of a scene read from files: the input and every filter on it; a renderer-type
// method is a skipped plan (there is no scene to render).
std::unique_ptr<ScenePlans> file_scene_plans(const ExperimentConfig& c, const RunOptions& opt, const MethodRegistry& registry,
                                             const SceneSpec& spec);
// Every cell of a scene a renderer back-end renders (docs/renderers.md): as a rendered scene's,
// the reference, inputs (two halves each) and curve coming from the back-end. A back-end that
// cannot render (not installed, its version command fails, the scene file is refused) fails
// every cell of the scene with its message, and the run goes on; a render that fails fails the
// cells that need it. Renderer-type methods are skipped (they render with the harness's tracer).
std::unique_ptr<ScenePlans> backend_scene_plans(const ExperimentConfig& c, const RunOptions& opt, const MethodRegistry& registry,
                                                Cache& cache, const SceneSpec& spec);
// How many cells the config has (the progress bar's total).
std::int64_t cell_count(const ExperimentConfig& c);

}  // namespace dnb::experiment
