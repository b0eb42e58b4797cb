#include "experiment/execute.h"

namespace dnb::experiment {

void run_scene_here(ScenePlans& sp, const CellContext& context) {
  for (PlanGroup& g : sp.groups) {
    for (const CellPlan& p : g.plans) run_cell(p, sp.cells, context);
    g.release();
  }
}

}  // namespace dnb::experiment
