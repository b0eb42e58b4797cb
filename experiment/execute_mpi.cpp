// Several MPI ranks (`mpirun -np N denoisebench run`).
//
// Per scene, after its reference (rendered over every rank by blocks, tracer/reference.h):
//   1. rank 0 sees which cells are finished (reused) or spooled by an earlier, interrupted run
//      and tells every rank;
//   2. frames: every input cell to compute, and every frame whose method cells are to be
//      computed, is rendered (or found in the cache) by one rank; the plain curve's points
//      too, all by one rank (they come from one render). Every rank then learns each frame's
//      cache hit;
//   3. methods: every method or renderer cell to compute, by one rank, reading its frame from
//      the (shared) cache;
//   4. rank 0 stores every cell in the order a one-process run visits them, from the spool
//      (cells.h), and alone writes the results folder's files.
// Cells are dealt to ranks longest first, each to the rank with the least estimated work so far
// (LPT), from a rough cost: samples rendered for plain and input cells, a fixed number of
// samples per pixel for a filter (kFilterCostSpp) or a renderer-type method (kRendererCostSpp). Each rank spools every
// cell it computes (the results folder and the cache must be on storage every rank sees:
// docs/cluster.md), so a rank that dies loses only the cell it was computing.

#include <algorithm>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include "core/errors.h"
#include "experiment/execute.h"
#include "distributed/mpi_context.h"

using nlohmann::json;

namespace dnb::experiment {

namespace {

// What rank 0 finds of a plan before the ranks start (step 1); sent to every rank as one letter each.
enum class CellState : char { Reused = 'r', Spooled = 's', ToCompute = 't', Skipped = 'k' };
using States = std::vector<std::vector<CellState>>;  // per group, per plan

// The dealing's rough cost of a method cell, in samples per pixel of the frame.
constexpr double kFilterCostSpp = 16;
constexpr double kRendererCostSpp = 128;

// A piece of work of steps 2-3.
struct Unit {
  enum class Kind {
    EveryPlan,  // every plan of the group that is to be computed (the plain curve: one render)
    LoadFrame,  // only loading the group's frame (render or cache), for its method cells
    Plan,       // one plan of the group
  };
  Kind kind = Kind::Plan;
  std::size_t group = 0;
  std::size_t plan = 0;  // Kind::Plan
  double cost = 0;
  // The order a one-process run has them in.
  std::pair<std::size_t, long> order() const {
    return {group, kind == Kind::Plan ? long(plan) : kind == Kind::LoadFrame ? -1 : -2};
  }
};

// Longest first, each to the least loaded rank (ties: the lower rank, the earlier unit); this
// rank's units in the order a one-process run has them, so that a rank loads each frame once.
std::vector<Unit> my_units(std::vector<Unit> units) {
  std::vector<std::size_t> order(units.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return units[a].cost > units[b].cost; });
  std::vector<double> load(std::size_t(mpi::size()), 0.0);
  std::vector<Unit> mine;
  for (std::size_t i : order) {
    const auto r = std::size_t(std::min_element(load.begin(), load.end()) - load.begin());
    load[r] += units[i].cost;
    if (int(r) == mpi::rank()) mine.push_back(units[i]);
  }
  std::sort(mine.begin(), mine.end(), [](const Unit& a, const Unit& b) { return a.order() < b.order(); });
  return mine;
}

// 1. Rank 0 decides every plan's state; every rank gets them.
States plan_states(const ScenePlans& sp, const RunOptions& opt, const CellContext* context) {
  std::string letters;
  if (mpi::is_root())
    for (const PlanGroup& g : sp.groups)
      for (const CellPlan& p : g.plans) {
        const std::string key = cell_key(p);
        const CellState s = p.skip_reason                    ? CellState::Skipped
                            : reusable(key, p, *context)     ? CellState::Reused
                            : is_spooled(opt.out_dir, key)   ? CellState::Spooled
                                                             : CellState::ToCompute;
        letters += char(s);
      }
  letters = mpi::broadcast_string(letters);
  States states(sp.groups.size());
  for (std::size_t g = 0, k = 0; g < sp.groups.size(); ++g)
    for (std::size_t i = 0; i < sp.groups[g].plans.size(); ++i) states[g].push_back(CellState(letters.at(k++)));
  if (mpi::is_root()) {
    std::size_t n[3] = {0, 0, 0};
    for (const auto& g : states)
      for (CellState s : g) n[0] += s == CellState::ToCompute, n[1] += s == CellState::Reused, n[2] += s == CellState::Spooled;
    spdlog::info("{}: {} cells to compute over {} ranks, {} finished, {} from an earlier run's spool", sp.cells.scene, n[0],
                 mpi::size(), n[1], n[2]);
  }
  return states;
}

void compute_and_spool(const ScenePlans& sp, const CellPlan& p, const RunOptions& opt) {
  const std::string key = cell_key(p);
  write_spooled(opt.out_dir, key, compute_cell(p, sp.cells.scene, key));
}

// 2's units: a group's plain curve, its input cell, or only its frame (for its method cells).
std::vector<Unit> frame_units(const ScenePlans& sp, const States& todo) {
  const double pixels = double(sp.cells.width) * sp.cells.height;
  std::vector<Unit> units;
  for (std::size_t g = 0; g < sp.groups.size(); ++g) {
    const PlanGroup& group = sp.groups[g];
    const auto to_compute = [&](std::size_t i) { return todo[g][i] == CellState::ToCompute; };
    bool any = false, methods = false;
    for (std::size_t i = 0; i < group.plans.size(); ++i) any = any || to_compute(i), methods = methods || (i > 0 && to_compute(i));
    if (!group.frame) {
      if (any) units.push_back({Unit::Kind::EveryPlan, g, 0, pixels * (group.curve ? group.curve->rendered_spp() : 0)});
      continue;
    }
    const double cost = pixels * (group.frame->from_file() ? 1 : group.plans[0].spp);
    if (to_compute(0))
      units.push_back({Unit::Kind::Plan, g, 0, cost});
    else if (methods && !group.frame->from_file())
      units.push_back({Unit::Kind::LoadFrame, g, 0, cost});
  }
  return units;
}

// 2. This rank's frames and plain curves; then every rank learns each frame's cache hit.
void run_frame_units(ScenePlans& sp, const States& todo, const RunOptions& opt) {
  json hits = json::object();
  for (const Unit& u : my_units(frame_units(sp, todo))) {
    PlanGroup& g = sp.groups[u.group];
    if (u.kind == Unit::Kind::Plan) compute_and_spool(sp, g.plans[u.plan], opt);
    if (u.kind == Unit::Kind::EveryPlan) {
      for (std::size_t i = 0; i < g.plans.size(); ++i)
        if (todo[u.group][i] == CellState::ToCompute) compute_and_spool(sp, g.plans[i], opt);
      g.release();
    }
    if (g.frame) {
      g.frame->get();
      hits[std::to_string(u.group)] = g.frame->cache_hit() ? json(*g.frame->cache_hit()) : json(nullptr);
      g.frame->release();
    }
  }
  std::string all_hits;
  const auto gathered = mpi::gather_strings(hits.dump());
  if (mpi::is_root()) {
    json merged = json::object();
    for (const auto& h : gathered) merged.update(json::parse(h));
    all_hits = merged.dump();
  }
  const json frame_hits = json::parse(mpi::broadcast_string(all_hits));
  for (const auto& [g, hit] : frame_hits.items())
    sp.groups.at(std::stoul(g)).frame->use_stored(hit.is_null() ? std::nullopt : std::optional<bool>(hit.get<bool>()));
}

// 3. This rank's method and renderer cells, each frame read from the (shared) cache once.
std::size_t run_method_units(ScenePlans& sp, const States& todo, const RunOptions& opt) {
  const double pixels = double(sp.cells.width) * sp.cells.height;
  std::vector<Unit> units;
  for (std::size_t g = 0; g < sp.groups.size(); ++g)
    if (sp.groups[g].frame)
      for (std::size_t i = 1; i < sp.groups[g].plans.size(); ++i)
        if (todo[g][i] == CellState::ToCompute) {
          const bool renderer = sp.groups[g].plans[i].kind == MethodKind::Renderer;
          units.push_back({Unit::Kind::Plan, g, i, pixels * (renderer ? kRendererCostSpp : kFilterCostSpp)});
        }
  std::optional<std::size_t> loaded;
  std::size_t computed = 0;
  for (const Unit& u : my_units(units)) {
    if (loaded && *loaded != u.group) sp.groups[*loaded].frame->release();
    loaded = u.group;
    compute_and_spool(sp, sp.groups[u.group].plans[u.plan], opt);
    ++computed;
  }
  if (loaded) sp.groups[*loaded].frame->release();
  return computed;
}

// 4. Rank 0 stores every cell in a one-process run's order: from the spool, or reused, skipped
// or (no rank spooled it) computed here.
void store_in_order(ScenePlans& sp, const RunOptions& opt, const CellContext& context) {
  for (PlanGroup& g : sp.groups) {
    for (const CellPlan& p : g.plans) {
      const std::string key = cell_key(p);
      std::optional<ComputedCell> spooled;
      if (!p.skip_reason && !reusable(key, p, context)) {
        try {
          spooled = read_spooled(opt.out_dir, key);
        } catch (const InputError& e) {
          spdlog::warn("{}; computing the cell again", e.what());
          remove_spooled(opt.out_dir, key);
        }
      }
      if (!spooled) {
        run_cell(p, sp.cells, context);
        continue;
      }
      store_cell(p, sp.cells, context, key, std::move(*spooled));
      remove_spooled(opt.out_dir, key);
    }
    g.release();
  }
}

}  // namespace

void run_scene_distributed(ScenePlans& sp, const RunOptions& opt, const CellContext* context) {
  const States todo = plan_states(sp, opt, context);
  run_frame_units(sp, todo, opt);
  const std::size_t computed = run_method_units(sp, todo, opt);
  const auto counts = mpi::gather_strings(std::to_string(computed));  // also: every rank has spooled its cells
  if (!mpi::is_root()) return;
  spdlog::info("{}: method cells computed per rank: {}", sp.cells.scene, fmt::join(counts, ", "));
  store_in_order(sp, opt, *context);
}

}  // namespace dnb::experiment
