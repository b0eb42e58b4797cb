#include "experiment/runner.h"

#include <algorithm>
#include <filesystem>
#include <memory>
#include <functional>
#include <map>
#include <optional>
#include <tuple>
#include <utility>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "core/atomic_file.h"
#include "core/errors.h"
#include "core/exr_io.h"
#include "core/file_names.h"
#include "core/hash.h"
#include "core/progress.h"
#include "core/stats.h"
#include "core/timer.h"
#include "core/build_info.h"
#include "denoisers/method.h"
#include "experiment/cells.h"
#include "experiment/input_files.h"
#include "experiment/provenance.h"
#include "experiment/store.h"
#include "metrics/metrics.h"
#include "methods/inputs.h"
#include "tracer/cache.h"
#include "tracer/cache_keys.h"
#include "tracer/reference.h"
#include "tracer/mpi_context.h"
#include "tracer/render.h"
#include "tracer/scene_loader.h"

namespace fs = std::filesystem;
using nlohmann::json;

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

RenderSettings input_settings(const ExperimentConfig& c, int spp, std::uint64_t seed) {
  RenderSettings s;
  std::tie(s.width, s.height, s.spp, s.seed, s.threads, s.max_depth) =
      std::tuple(c.width, c.height, spp, seed, c.threads, c.max_depth);
  return s;
}

// What every cell of a scene shares, with `ref` kept in the results folder as
// images/<scene>/reference.exr: the reference file itself (R,G,B, variance.*, metadata), hard
// linked or copied (keep_file), so that `metrics IMAGE reference.exr` scores as the run did.
SceneCells scene_cells(const std::string& out_dir, const std::string& name, const Reference& ref) {
  SceneCells s;
  s.scene = name;
  s.image_dir = "images/" + file_names::mapped(name);
  s.frame_dir = "frames/" + file_names::mapped(name);
  s.width = ref.color.width();
  s.height = ref.color.height();
  s.reference = &ref;
  create_folder(out_dir + "/" + s.image_dir);
  ReferenceInfo& info = s.reference_info;
  info.image = s.image_dir + "/reference.exr";
  const std::string dest = out_dir + "/" + info.image;
  if (!ref.path.empty())
    keep_file(ref.path, dest);
  else
    write_reference(ref, dest, "");
  // The reference's own unconverged pixels (fireflies carried by a few samples): mse_converged
  // leaves them out; the report names their share beside it.
  if (!ref.variance.empty()) {
    info.unconverged_share = metrics::unconverged_share(ref.color, ref.variance);
    const metrics::ReferenceError e = metrics::reference_error(ref.color, ref.variance);
    info.estimated_error = std::map<std::string, double>{{"mse", e.mse}, {"mse_hdr", e.mse_hdr}, {"relmse", e.relmse}};
  }
  info.unconverged_rse = metrics::kUnconvergedRse;
  return s;
}

// The reference of a rendered scene (cached and checkpointed by tracer/reference.h) and what
// every record of the scene says about it. Collective under MPI (the reference renders over every
// rank); only rank 0 gets the reference and keeps it in the folder, the others its identity.
SceneCells rendered_scene_cells(const ExperimentConfig& c, const RunOptions& opt, const Cache& cache, const Scene& scene,
                                const std::string& name, Reference& ref) {
  const ReferenceSettings rs{.width = c.width, .height = c.height, .spp = c.reference_spp_for(name), .seed = c.reference_seed,
                             .max_depth = c.max_depth, .block_spp = c.reference_block_spp, .threads = c.threads};
  ReferenceOptions ro;
  ro.cache_dir = cache.dir();
  ro.use_cache = opt.use_cache;
  spdlog::info("{}: reference {} spp at {}x{}", name, rs.spp, rs.width, rs.height);
  ref = reference_image(scene, rs, ro);
  SceneCells s;
  if (mpi::is_root()) {
    s = scene_cells(opt.out_dir, name, ref);
  } else {
    s.scene = name;
    std::tie(s.width, s.height) = std::pair(c.width, c.height);
  }
  s.scene_hash = scene_content_hash(scene);
  s.seed = c.seed;
  ReferenceInfo& info = s.reference_info;
  info.spp = rs.spp;
  info.seed = c.reference_seed;
  info.seconds = ref.convergence.empty() ? ref.render_seconds : ref.convergence.back().seconds;
  info.cache_hit = ref.cache_hit;
  return s;
}

// The reference of a scene read from files, as its file says: its spp and render time where it
// records them (0 otherwise), no seed, no cache. Under MPI only rank 0 reads it.
SceneCells file_scene_cells(const RunOptions& opt, const SceneSpec& spec, Reference& ref) {
  SceneCells s;
  if (mpi::is_root()) {
    spdlog::info("{}: frame '{}', reference '{}'", spec.name, spec.files->frame, spec.files->reference);
    ref = file_reference(spec.files->reference, spec.files->input_format);
    s = scene_cells(opt.out_dir, spec.name, ref);
    s.reference_info.spp = ref.meta.spp;
    s.reference_info.seconds = ref.meta.render_seconds;
  } else {
    s.scene = spec.name;
  }
  s.scene_hash = sha256_hex("frame=" + spec.files->frame_hash + "\nreference=" + spec.files->reference_hash + "\n");
  return s;
}

// The input frame of a scene at one spp, read on first use only (a scene whose cells are all
// finished reads no frame): rendered, through the render cache, or read from the file a
// [[scene]] names (read_input_frame). `identity` is what its cells are keyed by; `path` the file
// it was read from, which the input cell keeps in the folder. Not movable: loading refers to it.
class InputFrame {
 public:
  // A rendered frame: keyed by its cache key's digest and the reference's spp, the identity older
  // results folders' cells have too, so that their finished cells are still reused.
  InputFrame(Cache& cache, const Scene& scene, RenderSettings settings, bool use_cache, int reference_spp)
      : use_cache_(use_cache) {
    const CacheKey key = frame_cache_key(scene, settings);
    identity_ = {{"input", key.digest()}, {"ref", reference_spp}};
    load_ = [this, &cache, &scene, settings, key](bool* hit) {
      if (!use_cache_) cache.remove(key);
      AovFrame f = cached_frame(cache, key, [&] { return render_frame(scene, settings); }, hit);
      return std::pair(std::move(f), cache.entry_dir(key) + "/frame.exr");
    };
  }
  // A frame read from a file: keyed by the contents of both files and the scene's name.
  explicit InputFrame(const SceneSpec& spec)
      : identity_{{"input_file", spec.files->frame_hash}, {"reference_file", spec.files->reference_hash}, {"scene", spec.name}},
        from_file_(true) {
    load_ = [files = *spec.files](bool*) {
      return std::pair(read_input_frame(files.frame, files.input_format, files.spp), files.frame);
    };
  }
  InputFrame(const InputFrame&) = delete;
  InputFrame& operator=(const InputFrame&) = delete;

  const json& identity() const { return identity_; }
  bool from_file() const { return from_file_; }
  const AovFrame& get() {
    if (!frame_) {
      auto [frame, path] = load_(&hit_);
      frame_ = std::move(frame);
      path_ = std::move(path);
    }
    return *frame_;
  }
  const std::string& path() {
    get();
    return path_;
  }
  std::optional<bool> cache_hit() const {
    if (from_file_) return std::nullopt;
    return stored_hit_ ? stored_hit_ : std::optional<bool>(hit_);
  }
  // A distributed run's method cells: another rank has put the frame in the cache (rendered it,
  // or found it there: `hit`). Read it from the cache, and report `hit` as the cells of a
  // one-process run, which share one load of the frame, do.
  void use_stored(std::optional<bool> hit) {
    use_cache_ = true;
    stored_hit_ = hit;
  }
  // Frees the frame (it is loaded again on the next use).
  void release() { frame_.reset(); }

 private:
  json identity_;
  bool from_file_ = false;
  bool use_cache_ = true;
  std::function<std::pair<AovFrame, std::string>(bool* hit)> load_;
  bool hit_ = false;
  std::optional<bool> stored_hit_;
  std::optional<AovFrame> frame_;
  std::string path_;
};

// The plain path-tracing curve of a scene: one progressive render to the curve's largest spp,
// each point the image of its first N samples (tracer/render.h's render_color_prefixes: bit for
// bit `render --spp N`), its time what the render took to reach N. Rendered whole when the first
// cell that needs a point asks for it, so the curve costs one render whichever of its points are
// computed, and kept in the render cache (a resumed run that misses one point reads them all from
// there, or renders to the largest again: its records then say the same as an uninterrupted run's).
class PlainCurve {
 public:
  PlainCurve(const ExperimentConfig& c, const Scene& scene, Cache& cache, bool use_cache)
      : config_(c), scene_(scene), cache_(cache), use_cache_(use_cache) {
    for (int spp : c.plain_spp) prefixes_.push_back(spp);
    std::sort(prefixes_.begin(), prefixes_.end());
    prefixes_.erase(std::unique(prefixes_.begin(), prefixes_.end()), prefixes_.end());
  }
  int rendered_spp() const { return prefixes_.empty() ? 0 : prefixes_.back(); }
  // Point spp's image and seconds.
  const std::pair<Image, double>& get(int spp) {
    if (points_.empty()) load();
    return points_.at(spp);
  }
  // Whether the points came from the render cache (known once a point was asked for).
  bool cache_hit() const { return hit_; }
  void release() { points_.clear(); }

 private:
  // From the render cache when it holds this curve (each point's image and the seconds the render
  // took to reach it, as first measured), else rendered and stored there: a run whose plain cells
  // must be scored again (the metrics changed) reads the curve instead of rendering it again.
  void load() {
    const RenderSettings settings = input_settings(config_, rendered_spp(), config_.seed);
    const CacheKey key = curve_cache_key(scene_, settings, prefixes_);
    if (!use_cache_) cache_.remove(key);
    if (auto entry = cache_.lookup(key)) {
      for (int spp : prefixes_) {
        const std::string path = entry->file(point_file(spp));
        const auto attrs = read_rgb_attributes(path);
        const auto it = attrs.find("render_seconds");
        if (it == attrs.end()) throw InputError(fmt::format("'{}': no attribute 'render_seconds'", path));
        points_[spp] = {read_rgb(path), std::stod(it->second)};
      }
      hit_ = true;
      return;
    }
    render_color_prefixes(scene_, settings, prefixes_, [&](std::size_t k, Image image, double seconds) {
      points_[prefixes_[k]] = {std::move(image), seconds};
    });
    hit_ = false;
    cache_.store(key, [&](const std::string& dir) {
      for (const auto& [spp, point] : points_)
        write_rgb(point.first, dir + "/" + point_file(spp), {{"render_seconds", fmt::format("{}", point.second)}});
    });
  }
  static std::string point_file(int spp) { return fmt::format("prefix_{}.exr", spp); }

  const ExperimentConfig& config_;
  const Scene& scene_;
  Cache& cache_;
  bool use_cache_;
  bool hit_ = false;
  std::vector<int> prefixes_;
  std::map<int, std::pair<Image, double>> points_;
};

CellPlan plain_cell(const ExperimentConfig& c, PlainCurve& curve, const std::string& scene_hash, int spp,
                    int reference_spp) {
  CellPlan p;
  p.role = Role::Plain;
  p.method = "path_tracing";
  p.spp = spp;
  // The code too (the metrics score the point): the render itself is cached (PlainCurve), so
  // scoring the curve again after a change costs a read, not a render.
  p.identity = {{"plain", spp}, {"scene", scene_hash}, {"w", c.width}, {"h", c.height}, {"seed", c.seed},
                {"ref", reference_spp}, {"depth", c.max_depth}, {"tracer", kTracerVersion}, {"code", shared_code_id()}};
  p.stem = "path_tracing_" + std::to_string(spp);
  p.compute = [&curve, spp] {
    CellOutput out;
    const auto& [image, seconds] = curve.get(spp);
    out.image = image;
    out.times.input_render = out.times.total = seconds;
    out.curve = CurveOrigin{curve.rendered_spp(), spp};
    out.input_cache_hit = curve.cache_hit();
    return out;
  };
  return p;
}

CellPlan input_cell(InputFrame& frame, int spp) {
  CellPlan p;
  p.role = Role::Input;
  p.method = "input";
  p.spp = spp;
  p.identity = frame.identity();
  p.identity["code"] = shared_code_id();
  p.stem = "input_" + std::to_string(spp);
  p.required_files = {"image", "frame"};
  p.compute = [&frame] {
    CellOutput out;
    out.image = frame.get().layer(layer::kColor);
    const double t = frame.get().meta.render_seconds;
    out.times.input_render = out.times.total = t;
    out.input_cache_hit = frame.cache_hit();
    out.frame_file = frame.path();
    return out;
  };
  return p;
}

// `scene` is null for a scene read from files (renderer-type methods are skipped there).
CellPlan method_cell(const ExperimentConfig& c, const MethodSpec& m, const Scene* scene, InputFrame& frame, int spp) {
  const MethodRegistry& registry = MethodRegistry::global();
  const MethodInfo& info = registry.info(m.method);
  CellPlan p;
  p.role = m.role();
  p.method = m.name;
  p.spp = spp;
  p.base_method = m.method;
  p.kind = to_string(info.kind);
  p.params = registry.parse_params(m.method, m.params).as_strings();
  p.identity = frame.identity();
  // The column's name too: two columns of the same method and parameters (a variant and
  // [params.<method>], or two variants) are two cells, each listed under its own name.
  p.identity.update({{"column", m.name}, {"method", m.method}, {"params", *p.params}, {"repeats", c.repeats},
                     {"repeat_below", c.repeat_below_seconds}, {"code", method_code_id(m.method)}});
  // A plug-in's code is not in the build: its folder's hash is (built-in cells keep their keys).
  if (!info.content_hash.empty()) p.identity["method_content"] = info.content_hash;
  p.contain_failures = true;
  p.stem = file_names::mapped(m.name) + "_" + std::to_string(spp);
  p.compute = [&c, &m, &info, scene, &frame] {
    auto method = MethodRegistry::global().create(m.method, m.params);
    const MethodInput in = frame_input(frame.get(), scene);
    MethodResult first;
    const std::vector<double> runs = time_method(*method, in, c.repeats, c.repeat_below_seconds, first);
    // Renderer-type methods render the scene themselves: their total is their own time.
    const double input_used = info.kind == MethodKind::Renderer ? 0.0 : frame.get().meta.render_seconds;
    const double filter = stats::median(runs);
    CellOutput out;
    out.image = std::move(first.image);
    out.times.input_render = input_used;
    out.times.filter = filter;
    out.times.total = input_used + filter;
    out.times.filter_runs = runs;
    out.times.setup = first.stats.setup_seconds;
    out.phases.emplace();
    for (const auto& [name, sec] : first.stats.phases) (*out.phases)[name] = sec;
    out.counters = first.stats.counters;
    if (!first.stats.info.empty()) out.method_info = first.stats.info;
    out.input_cache_hit = frame.cache_hit();
    out.baseline = frame.get().layer(layer::kColor);
    return out;
  };
  return p;
}

ResultsDocument results_header(const ExperimentConfig& c) {
  ResultsDocument d;
  d.config = c.recorded();
  d.machine = machine_info();
  d.machine["ranks"] = mpi::size();  // the MPI ranks the run was spread over (1: one process)
  d.build = build_info();
  d.git_revision = build_revision();
  return d;
}

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
  std::shared_ptr<const Scene> scene;  // null for a scene read from files
  Reference ref;                       // under MPI: on rank 0 only
  SceneCells cells;
  std::vector<PlanGroup> groups;
};

// Every cell of a rendered scene: the plain path-tracing curve, then per input spp and seed the
// input and every method on it.
std::unique_ptr<ScenePlans> rendered_scene_plans(const ExperimentConfig& c, const RunOptions& opt, Cache& cache,
                                                 const std::string& name) {
  auto sp = std::make_unique<ScenePlans>();
  sp->scene = load_scene(name);
  const Scene& scene = *sp->scene;
  sp->cells = rendered_scene_cells(c, opt, cache, scene, name, sp->ref);
  sp->cells.reference = &sp->ref;
  PlanGroup& plain = sp->groups.emplace_back();
  plain.curve = std::make_unique<PlainCurve>(c, scene, cache, opt.use_cache);
  for (int spp : c.plain_spp)
    plain.plans.push_back(plain_cell(c, *plain.curve, sp->cells.scene_hash, spp, c.reference_spp_for(name)));
  // Every input seed gives its own input and method cells (Table 1's intervals are over them).
  // With one seed the stems are the same as before seeds existed; with several, "_s<seed>" is added.
  for (int spp : c.spp)
    for (std::uint64_t seed : c.seeds) {
      PlanGroup& g = sp->groups.emplace_back();
      g.frame = std::make_unique<InputFrame>(cache, scene, input_settings(c, spp, seed), opt.use_cache,
                                             c.reference_spp_for(name));
      const std::string suffix = c.seeds.size() > 1 ? fmt::format("_s{}", seed) : "";
      auto seeded = [&](CellPlan p) {
        p.seed = seed;
        p.stem += suffix;
        return p;
      };
      g.plans.push_back(seeded(input_cell(*g.frame, spp)));
      for (const auto& m : c.methods) g.plans.push_back(seeded(method_cell(c, m, &scene, *g.frame, spp)));
    }
  return sp;
}

// Every cell of a scene read from files: the input (the frame, at its spp) and every filter on
// it. A renderer-type method renders the scene, which the files do not hold: skipped, with the
// reason recorded (results.json "skipped"); it is no failure of the run.
std::unique_ptr<ScenePlans> file_scene_plans(const ExperimentConfig& c, const RunOptions& opt, const SceneSpec& spec) {
  auto sp = std::make_unique<ScenePlans>();
  sp->cells = file_scene_cells(opt, spec, sp->ref);
  sp->cells.reference = &sp->ref;
  const int spp = spec.files->spp;
  PlanGroup& g = sp->groups.emplace_back();
  g.frame = std::make_unique<InputFrame>(spec);
  g.plans.push_back(input_cell(*g.frame, spp));
  for (const auto& m : c.methods) {
    if (MethodRegistry::global().info(m.method).kind == MethodKind::Renderer) {
      CellPlan skip;
      skip.method = m.name;
      skip.spp = spp;
      skip.skip_reason = fmt::format("'{}' renders the scene itself, and scene '{}' is read from files ('{}', '{}'): there is "
                                     "no scene to render",
                                     m.method, spec.name, spec.files->frame, spec.files->reference);
      g.plans.push_back(std::move(skip));
      continue;
    }
    g.plans.push_back(method_cell(c, m, nullptr, *g.frame, spp));
  }
  return sp;
}

// One process: every cell in order, each stored as soon as it is done.
void run_scene_here(ScenePlans& sp, const CellContext& context) {
  for (PlanGroup& g : sp.groups) {
    for (const CellPlan& p : g.plans) run_cell(p, sp.cells, context);
    g.release();
  }
}

// ---- Several MPI ranks (`mpirun -np N denoisebench run`) ----
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
// samples per pixel for a filter (16) or a renderer-type method (128). Each rank spools every
// cell it computes (the results folder and the cache must be on storage every rank sees:
// docs/cluster.md), so a rank that dies loses only the cell it was computing.

// A piece of work of steps 2-3: a plan of a group, (plan < 0) loading a group's frame, or
// (plan == kEveryPlan) every plan of the group that is to be computed (the plain curve).
struct Unit {
  static constexpr long kEveryPlan = -2;
  std::size_t group = 0;
  long plan = -1;
  double cost = 0;
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
  std::sort(mine.begin(), mine.end(), [](const Unit& a, const Unit& b) { return std::pair(a.group, a.plan) < std::pair(b.group, b.plan); });
  return mine;
}

void run_scene_distributed(ScenePlans& sp, const RunOptions& opt, const CellContext* context) {
  const bool root = mpi::is_root();
  // 1. One letter per plan, in order: 'r' reused, 's' spooled, 't' to compute, 'k' skipped.
  std::string state;
  if (root)
    for (const PlanGroup& g : sp.groups)
      for (const CellPlan& p : g.plans) {
        const std::string key = cell_key(p);
        state += p.skip_reason                           ? 'k'
                 : reusable(key, p, *context)            ? 'r'
                 : is_spooled(opt.out_dir, key)          ? 's'
                                                         : 't';
      }
  state = mpi::broadcast_string(state);
  if (root)
    spdlog::info("{}: {} cells to compute over {} ranks, {} finished, {} from an earlier run's spool", sp.cells.scene,
                 std::count(state.begin(), state.end(), 't'), mpi::size(), std::count(state.begin(), state.end(), 'r'),
                 std::count(state.begin(), state.end(), 's'));
  std::vector<std::vector<char>> todo(sp.groups.size());
  for (std::size_t g = 0, k = 0; g < sp.groups.size(); ++g)
    for (std::size_t i = 0; i < sp.groups[g].plans.size(); ++i) todo[g].push_back(state.at(k++));

  const double pixels = double(sp.cells.width) * sp.cells.height;
  auto compute_and_spool = [&](PlanGroup& g, std::size_t i) {
    const CellPlan& p = g.plans[i];
    const std::string key = cell_key(p);
    write_spooled(opt.out_dir, key, compute_cell(p, sp.cells.scene, key));
  };

  // 2. Frames and the plain curve.
  std::vector<Unit> frames;
  for (std::size_t g = 0; g < sp.groups.size(); ++g) {
    const PlanGroup& group = sp.groups[g];
    const auto t = [&](std::size_t i) { return todo[g][i] == 't'; };
    if (!group.frame) {
      bool any = false;
      for (std::size_t i = 0; i < group.plans.size(); ++i) any = any || t(i);
      if (any) frames.push_back({g, Unit::kEveryPlan, pixels * (group.curve ? group.curve->rendered_spp() : 0)});
      continue;
    }
    bool methods = false;
    for (std::size_t i = 1; i < group.plans.size(); ++i) methods = methods || t(i);
    const double cost = pixels * (group.frame->from_file() ? 1 : group.plans[0].spp);
    if (t(0))
      frames.push_back({g, 0, cost});
    else if (methods && !group.frame->from_file())
      frames.push_back({g, -1, cost});
  }
  json hits = json::object();
  for (const Unit& u : my_units(frames)) {
    PlanGroup& g = sp.groups[u.group];
    if (u.plan >= 0) compute_and_spool(g, std::size_t(u.plan));
    if (u.plan == Unit::kEveryPlan) {
      for (std::size_t i = 0; i < g.plans.size(); ++i)
        if (todo[u.group][i] == 't') compute_and_spool(g, i);
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
  if (root) {
    json merged = json::object();
    for (const auto& h : gathered) merged.update(json::parse(h));
    all_hits = merged.dump();
  }
  const json frame_hits = json::parse(mpi::broadcast_string(all_hits));
  for (const auto& [g, hit] : frame_hits.items())
    sp.groups.at(std::stoul(g)).frame->use_stored(hit.is_null() ? std::nullopt : std::optional<bool>(hit.get<bool>()));

  // 3. Methods and renderers.
  std::vector<Unit> methods;
  for (std::size_t g = 0; g < sp.groups.size(); ++g)
    if (sp.groups[g].frame)
      for (std::size_t i = 1; i < sp.groups[g].plans.size(); ++i)
        if (todo[g][i] == 't') methods.push_back({g, long(i), pixels * (sp.groups[g].plans[i].kind == "renderer" ? 128 : 16)});
  std::optional<std::size_t> loaded;
  std::size_t computed = 0;
  for (const Unit& u : my_units(methods)) {
    if (loaded && *loaded != u.group) sp.groups[*loaded].frame->release();
    loaded = u.group;
    compute_and_spool(sp.groups[u.group], std::size_t(u.plan));
    ++computed;
  }
  if (loaded) sp.groups[*loaded].frame->release();
  const auto counts = mpi::gather_strings(std::to_string(computed));  // also: every rank has spooled its cells
  if (!root) return;
  spdlog::info("{}: method cells computed per rank: {}", sp.cells.scene, fmt::join(counts, ", "));

  // 4. Store, in a one-process run's order.
  for (PlanGroup& g : sp.groups) {
    for (const CellPlan& p : g.plans) {
      const std::string key = cell_key(p);
      std::optional<ComputedCell> spooled;
      if (!p.skip_reason && !reusable(key, p, *context)) {
        try {
          spooled = read_spooled(opt.out_dir, key);
        } catch (const InputError& e) {
          spdlog::warn("{}; computing the cell again", e.what());
          remove_spooled(opt.out_dir, key);
        }
      }
      if (!spooled) {
        run_cell(p, sp.cells, *context);  // reused, skipped, or (no rank spooled it) computed here
        continue;
      }
      store_cell(p, sp.cells, *context, key, std::move(*spooled));
      remove_spooled(opt.out_dir, key);
    }
    g.release();
  }
}

}  // namespace

ResultsDocument run_experiment(const ExperimentConfig& c, const RunOptions& opt) {
  const bool distributed = mpi::size() > 1, root = mpi::is_root();
  Cache cache(opt.cache_dir.empty() ? Cache::default_dir() : opt.cache_dir);
  // Rank 0 alone writes the folder's files and holds its lock (taken before any collective, so
  // that the other ranks of a second run into the folder wait with it).
  std::optional<ResultsStore> store;
  std::optional<Progress> progress;
  std::optional<CellContext> context;
  if (root) {
    create_folder(opt.out_dir + "/images");
    if (distributed) create_folder(spool_dir(opt.out_dir));
    store.emplace(opt.out_dir, results_header(c));
    const std::int64_t methods = std::int64_t(c.methods.size());
    std::int64_t cells = 0;
    for (const auto& s : c.scenes)
      cells += s.files ? methods + 1
                       : std::int64_t(c.spp.size() * c.seeds.size()) * (methods + 1) + std::int64_t(c.plain_spp.size());
    progress.emplace("experiment " + c.name, cells, "cells", 0.0);
    context = CellContext{opt.out_dir, &*store, &*progress};
  }
  mpi::barrier();  // the spool folder exists before any rank writes into it
  for (const auto& s : c.scenes) {
    const auto sp = s.files ? file_scene_plans(c, opt, s) : rendered_scene_plans(c, opt, cache, s.name);
    if (distributed)
      run_scene_distributed(*sp, opt, root ? &*context : nullptr);
    else
      run_scene_here(*sp, *context);
  }
  if (!root) return {};
  progress->finish();
  store->write();
  if (distributed && fs::is_empty(spool_dir(opt.out_dir))) fs::remove(spool_dir(opt.out_dir));
  spdlog::info("results in {}/results.json ({} records)", opt.out_dir, store->document().records.size());
  return store->document();
}

}  // namespace dnb::experiment
