// The executors of a run's plans (experiment/planner.h): one process, which runs every cell in
// order and stores it as soon as it is done; or several MPI ranks, which deal the cells of each
// scene over the ranks and let rank 0 store them in the same order (execute_mpi.cpp).
#pragma once

#include "experiment/cells.h"
#include "experiment/planner.h"
#include "experiment/runner.h"

namespace dnb::experiment {

// One process: every cell in order, each stored as soon as it is done; a group's frame is freed
// after its cells.
void run_scene_here(ScenePlans& sp, const CellContext& context);

// Several ranks (`mpirun -np N denoisebench run`); collective. `context` is rank 0's (null on
// the others). The folder ends as one process's would.
void run_scene_distributed(ScenePlans& sp, const RunOptions& opt, const CellContext* context);

}  // namespace dnb::experiment
