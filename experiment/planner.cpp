#include "experiment/planner.h"

#include <algorithm>
#include <filesystem>
#include <tuple>
#include <utility>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "core/atomic_file.h"
#include "core/file_names.h"
#include "core/hash.h"
#include "core/stats.h"
#include "core/build_info.h"
#include "experiment/provenance.h"
#include "metrics/metrics.h"
#include "methods/inputs.h"
#include "distributed/mpi_context.h"
#include "core/errors.h"
#include "interop/renderers.h"
#include "tracer/gltf_export.h"
#include "tracer/scene_loader.h"

namespace fs = std::filesystem;

namespace dnb::experiment {

namespace {

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
    info.estimated_error = metrics::reference_error_by_metric(e);
  }
  info.unconverged_rse = metrics::kUnconvergedRse;
  return s;
}

// The reference of a rendered scene (cached and checkpointed by tracer/reference.h) and what
// every record of the scene says about it. Collective under MPI (the reference renders over every
// rank); only rank 0 gets the reference and keeps it in the folder, the others its identity.
// `name` is the row (a sequence's frame: sequence_row), `ref_spp` the reference's spp.
SceneCells rendered_scene_cells(const ExperimentConfig& c, const RunOptions& opt, const Cache& cache, const Scene& scene,
                                const std::string& name, Reference& ref, int ref_spp) {
  const ReferenceSettings rs{.width = c.width, .height = c.height, .spp = ref_spp, .seed = c.reference_seed,
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
    out.measured.times.input_render = out.measured.times.total = seconds;
    out.measured.curve = CurveOrigin{curve.rendered_spp(), spp};
    out.measured.input_cache_hit = curve.cache_hit();
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
    out.measured.times.input_render = out.measured.times.total = t;
    out.measured.input_cache_hit = frame.cache_hit();
    out.frame_file = frame.path();
    return out;
  };
  return p;
}

// `scene` is null for a scene read from files (renderer-type methods are skipped there).
// `sequence`: the frame is frame `t` of that sequence at `settings` (a temporal method runs from
// the sequence's state, docs/sequences.md).
CellPlan method_cell(const ExperimentConfig& c, const MethodRegistry& registry, const MethodSpec& m, const Scene* scene,
                     InputFrame& frame, int spp, SequenceRun* sequence = nullptr, int t = 0,
                     const RenderSettings& settings = {}) {
  const MethodInfo& info = registry.info(m.method);
  CellPlan p;
  p.role = m.role();
  p.method = m.name;
  p.spp = spp;
  p.base_method = m.method;
  p.kind = info.kind;
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
  const bool temporal = info.temporal && sequence;
  // The frame's place in its sequence (its history is frames 0 .. t), not the sequence's length:
  // a run that extends a sequence reuses the frames it has.
  if (temporal) p.identity["sequence"] = {{"name", sequence->name()}, {"frame", t}};
  p.compute = [&c, &registry, &m, &info, scene, &frame, sequence, t, settings, temporal] {
    MethodResult first;
    std::vector<double> runs;
    if (temporal) {
      first = sequence->run_temporal(m.name, [&] { return registry.create(m.method, m.params); }, t, frame.get(), scene,
                                     settings);
      runs = {first.stats.total_seconds};  // one run: a repeat would advance the history
    } else {
      auto method = registry.create(m.method, m.params);
      const MethodInput in = frame_input(frame.get(), scene);
      runs = time_method(*method, in, c.repeats, c.repeat_below_seconds, first);
    }
    // Renderer-type methods render the scene themselves: their total is their own time.
    const double input_used = info.kind == MethodKind::Renderer ? 0.0 : frame.get().meta.render_seconds;
    const double filter = stats::median(runs);
    CellOutput out;
    out.image = std::move(first.image);
    out.measured.times.input_render = input_used;
    out.measured.times.filter = filter;
    out.measured.times.total = input_used + filter;
    out.measured.times.filter_runs = runs;
    out.measured.times.setup = first.stats.setup_seconds;
    out.measured.phases.emplace();
    for (const auto& [name, sec] : first.stats.phases) (*out.measured.phases)[name] = sec;
    out.measured.counters = first.stats.counters;
    if (!first.stats.info.empty()) out.measured.method_info = first.stats.info;
    out.measured.input_cache_hit = frame.cache_hit();
    out.baseline = frame.get().layer(layer::kColor);
    return out;
  };
  return p;
}

}  // namespace

// Every cell of a rendered scene: the plain path-tracing curve, then per input spp and seed the
// input and every method on it.
std::unique_ptr<ScenePlans> rendered_scene_plans(const ExperimentConfig& c, const RunOptions& opt,
                                                 const MethodRegistry& registry, Cache& cache, const std::string& name,
                                                 bool with_reference, SequenceRun* sequence, int t) {
  auto sp = std::make_unique<ScenePlans>();
  SceneLoadOptions load;
  if (sequence) load.frame = t;
  sp->scene = load_scene(name, load);
  const Scene& scene = *sp->scene;
  const std::string row = sequence ? sequence_row(name, t) : name;
  const int ref_spp = c.reference_spp_for(name);
  if (with_reference) {
    sp->cells = rendered_scene_cells(c, opt, cache, scene, row, sp->ref, ref_spp);
  } else {
    sp->cells.scene = row;
    std::tie(sp->cells.width, sp->cells.height) = std::pair(c.width, c.height);
    sp->cells.scene_hash = scene_content_hash(scene);
    sp->cells.seed = c.seed;
  }
  sp->cells.reference = &sp->ref;
  // A sequence's frames have no plain path-tracing curve (the speed-up claim is the stills').
  if (!sequence) {
    PlanGroup& plain = sp->groups.emplace_back();
    plain.curve = std::make_unique<PlainCurve>(c, scene, cache, opt.use_cache);
    for (int spp : c.plain_spp) plain.plans.push_back(plain_cell(c, *plain.curve, sp->cells.scene_hash, spp, ref_spp));
  }
  // Every input seed gives its own input and method cells (Table 1's intervals are over them).
  // With one seed the stems are the same as before seeds existed; with several, "_s<seed>" is added.
  for (int spp : c.spp)
    for (std::uint64_t seed : c.seeds) {
      PlanGroup& g = sp->groups.emplace_back();
      const RenderSettings settings = input_settings(c, spp, seed);
      g.frame = sequence ? std::make_unique<InputFrame>(cache, scene, name, settings, opt.use_cache, ref_spp)
                         : std::make_unique<InputFrame>(cache, scene, settings, opt.use_cache, ref_spp);
      const std::string suffix = c.seeds.size() > 1 ? fmt::format("_s{}", seed) : "";
      auto seeded = [&](CellPlan p) {
        p.seed = seed;
        p.stem += suffix;
        return p;
      };
      g.plans.push_back(seeded(input_cell(*g.frame, spp)));
      for (const auto& m : c.methods)
        g.plans.push_back(seeded(method_cell(c, registry, m, &scene, *g.frame, spp, sequence, t, settings)));
    }
  return sp;
}

// Every cell of a scene read from files: the input (the frame, at its spp) and every filter on
// it. A renderer-type method renders the scene, which the files do not hold: skipped, with the
// reason recorded (results.json "skipped"); it is no failure of the run.
std::unique_ptr<ScenePlans> file_scene_plans(const ExperimentConfig& c, const RunOptions& opt, const MethodRegistry& registry,
                                             const SceneSpec& spec) {
  auto sp = std::make_unique<ScenePlans>();
  sp->cells = file_scene_cells(opt, spec, sp->ref);
  sp->cells.reference = &sp->ref;
  const int spp = spec.files->spp;
  PlanGroup& g = sp->groups.emplace_back();
  g.frame = std::make_unique<InputFrame>(spec);
  g.plans.push_back(input_cell(*g.frame, spp));
  for (const auto& m : c.methods) {
    if (registry.info(m.method).kind == MethodKind::Renderer) {
      CellPlan skip;
      skip.method = m.name;
      skip.spp = spp;
      skip.skip_reason = fmt::format("'{}' renders the scene itself, and scene '{}' is read from files ('{}', '{}'): there is "
                                     "no scene to render",
                                     m.method, spec.name, spec.files->frame, spec.files->reference);
      g.plans.push_back(std::move(skip));
      continue;
    }
    g.plans.push_back(method_cell(c, registry, m, nullptr, *g.frame, spp));
  }
  return sp;
}

namespace {

// A plan that fails with `error` (its scene's back-end or reference could not be had): recorded
// as a failed cell with the back-end's message, like any contained failure.
CellPlan failing(CellPlan p, std::exception_ptr error) {
  if (p.skip_reason) return p;
  p.contain_failures = true;
  p.compute = [error]() -> CellOutput { std::rethrow_exception(error); };
  return p;
}

// `scene = "NAME"` of a back-end's [[scene]]: the tracer's scene exported as glTF into the render
// cache (scenes/<name>-<content hash>-<W>x<H>.gltf: the camera's aspect ratio is the run's), once
// (rank 0 first under MPI; the others find it), then rendered as a file. export-gltf's refusals
// (a thin lens, motion blur, maps) fail the scene's cells.
void export_for_backend(const ExperimentConfig& c, const Cache& cache, const std::string& scene_name, BackendScene& b) {
  const auto scene = load_scene(scene_name);
  const std::string path = fmt::format("{}/scenes/{}-{}-{}x{}.gltf", cache.dir(), file_names::mapped(scene->name),
                                       scene_content_hash(*scene), c.width, c.height);
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) {
    create_folder(fs::path(path).parent_path().string());
    export_gltf(*scene, {.width = c.width, .height = c.height}, path);
  }
  b.file = path;
  b.file_hash = sha256_file(path);
}

}  // namespace

std::unique_ptr<ScenePlans> backend_scene_plans(const ExperimentConfig& c, const RunOptions& opt, const MethodRegistry& registry,
                                                Cache& cache, const SceneSpec& spec) {
  auto sp = std::make_unique<ScenePlans>();
  sp->backend = std::make_unique<BackendScene>();
  BackendScene& b = *sp->backend;
  b.backend = interop::renderer_backend(spec.renderer->renderer, interop::renderer_search_dirs(c.renderers));
  b.file = spec.renderer->file;
  b.file_hash = spec.renderer->file_hash;
  const std::string& name = spec.name;
  const int ref_spp = c.reference_spp_for(name);
  // The back-end's identity and the reference: rank 0 first, the other ranks then find the
  // reference in the (shared) cache. A failure fails the scene's cells, not the run.
  std::exception_ptr failure;
  auto prepare = [&] {
    try {
      if (!spec.renderer->scene.empty()) export_for_backend(c, cache, spec.renderer->scene, b);
      b.identity = b.backend->identity();
      spdlog::info("{}: reference {} spp at {}x{} by renderer '{}' ({})", name, ref_spp, c.width, c.height,
                   b.backend->manifest().name, b.backend->version());
      sp->ref = backend_reference(cache, b, input_settings(c, ref_spp, c.reference_seed), c.reference_seed,
                                  c.reference_block_spp, opt.use_cache);
    } catch (const std::exception& e) {
      if (!dynamic_cast<const WorkError*>(&e) && !dynamic_cast<const InputError*>(&e)) throw;
      spdlog::error("{}: renderer '{}' on '{}': {}; every cell of the scene fails", name, spec.renderer->renderer, b.file,
                    e.what());
      failure = std::current_exception();
    }
  };
  if (mpi::is_root()) prepare();
  mpi::barrier();
  if (!mpi::is_root()) prepare();
  SceneCells& s = sp->cells;
  if (mpi::is_root() && !failure) {
    s = scene_cells(opt.out_dir, name, sp->ref);
  } else {
    s.scene = name;
    std::tie(s.width, s.height) = std::pair(c.width, c.height);
  }
  s.scene_hash = b.scene_hash();
  s.seed = c.seed;
  s.reference_info.spp = ref_spp;
  s.reference_info.seed = c.reference_seed;
  s.reference_info.seconds = sp->ref.meta.render_seconds;  // as first rendered, also from the cache
  s.reference_info.cache_hit = sp->ref.cache_hit;
  s.reference = &sp->ref;
  auto add = [&](PlanGroup& g, CellPlan p) {
    p.contain_failures = true;  // a render that fails fails the cells that need it, not the run
    g.plans.push_back(failure ? failing(std::move(p), failure) : std::move(p));
  };
  PlanGroup& plain = sp->groups.emplace_back();
  plain.curve = std::make_unique<PlainCurve>(c, b, cache, opt.use_cache);
  for (int spp : c.plain_spp) add(plain, plain_cell(c, *plain.curve, s.scene_hash, spp, ref_spp));
  for (int spp : c.spp)
    for (std::uint64_t seed : c.seeds) {
      PlanGroup& g = sp->groups.emplace_back();
      g.frame = std::make_unique<InputFrame>(cache, b, input_settings(c, spp, seed), opt.use_cache, ref_spp);
      const std::string suffix = c.seeds.size() > 1 ? fmt::format("_s{}", seed) : "";
      auto seeded = [&](CellPlan p) {
        p.seed = seed;
        p.stem += suffix;
        return p;
      };
      add(g, seeded(input_cell(*g.frame, spp)));
      for (const auto& m : c.methods) {
        if (registry.info(m.method).kind == MethodKind::Renderer) {
          CellPlan skip;
          skip.method = m.name;
          skip.spp = spp;
          skip.seed = seed;
          skip.skip_reason = fmt::format("'{}' renders with the harness's tracer, and scene '{}' is rendered by renderer '{}' "
                                         "('{}')",
                                         m.method, name, spec.renderer->renderer, b.file);
          g.plans.push_back(std::move(skip));
          continue;
        }
        add(g, seeded(method_cell(c, registry, m, nullptr, *g.frame, spp)));
      }
    }
  return sp;
}

std::int64_t cell_count(const ExperimentConfig& c) {
  const std::int64_t methods = std::int64_t(c.methods.size());
  std::int64_t cells = 0;
  for (const auto& s : c.scenes)
    cells += s.files        ? methods + 1
             : s.frames > 0 ? std::int64_t(s.frames) * std::int64_t(c.spp.size() * c.seeds.size()) * (methods + 1)
                            : std::int64_t(c.spp.size() * c.seeds.size()) * (methods + 1) + std::int64_t(c.plain_spp.size());
  return cells;
}

}  // namespace dnb::experiment
