#include "experiment/runner.h"

#include <filesystem>
#include <functional>
#include <optional>
#include <tuple>
#include <utility>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "core/atomic_file.h"
#include "core/exr_io.h"
#include "core/hash.h"
#include "core/progress.h"
#include "core/stats.h"
#include "core/timer.h"
#include "core/version.h"
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
  s.image_dir = "images/" + safe_file_name(name);
  s.frame_dir = "frames/" + safe_file_name(name);
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
// every record of the scene says about it.
SceneCells rendered_scene_cells(const ExperimentConfig& c, const RunOptions& opt, const Cache& cache, const Scene& scene,
                                const std::string& name, Reference& ref) {
  const ReferenceSettings rs{.width = c.width, .height = c.height, .spp = c.reference_spp_for(name), .seed = c.reference_seed,
                             .max_depth = c.max_depth, .block_spp = c.reference_block_spp, .threads = c.threads};
  ReferenceOptions ro;
  ro.cache_dir = cache.dir();
  ro.use_cache = opt.use_cache;
  spdlog::info("{}: reference {} spp at {}x{}", name, rs.spp, rs.width, rs.height);
  ref = reference_image(scene, rs, ro);
  SceneCells s = scene_cells(opt.out_dir, name, ref);
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
// records them (0 otherwise), no seed, no cache.
SceneCells file_scene_cells(const RunOptions& opt, const SceneSpec& spec, Reference& ref) {
  spdlog::info("{}: frame '{}', reference '{}'", spec.name, spec.files->frame, spec.files->reference);
  ref = file_reference(spec.files->reference, spec.files->input_format);
  SceneCells s = scene_cells(opt.out_dir, spec.name, ref);
  s.scene_hash = sha256_hex("frame=" + spec.files->frame_hash + "\nreference=" + spec.files->reference_hash + "\n");
  s.reference_info.spp = ref.meta.spp;
  s.reference_info.seconds = ref.meta.render_seconds;
  return s;
}

// The input frame of a scene at one spp, read on first use only (a scene whose cells are all
// finished reads no frame): rendered, through the render cache, or read from the file a
// [[scene]] names (read_input_frame). `identity` is what its cells are keyed by; `path` the file
// it was read from, which the input cell keeps in the folder.
class InputFrame {
 public:
  // A rendered frame: keyed by its cache key's digest and the reference's spp, as since schema 2.
  InputFrame(Cache& cache, const Scene& scene, RenderSettings settings, bool use_cache, int reference_spp) {
    const CacheKey key = frame_cache_key(scene, settings);
    identity_ = {{"input", key.digest()}, {"ref", reference_spp}};
    load_ = [&cache, &scene, settings, use_cache, key](bool* hit) {
      if (!use_cache) cache.remove(key);
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
  const json& identity() const { return identity_; }
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
  std::optional<bool> cache_hit() const { return from_file_ ? std::nullopt : std::optional<bool>(hit_); }

 private:
  json identity_;
  bool from_file_ = false;
  std::function<std::pair<AovFrame, std::string>(bool* hit)> load_;
  bool hit_ = false;
  std::optional<AovFrame> frame_;
  std::string path_;
};

CellPlan plain_cell(const ExperimentConfig& c, const Scene& scene, const std::string& scene_hash, int spp,
                    int reference_spp) {
  CellPlan p;
  p.role = Role::Plain;
  p.method = "path_tracing";
  p.spp = spp;
  p.identity = {{"plain", spp}, {"scene", scene_hash}, {"w", c.width}, {"h", c.height}, {"seed", c.seed},
                {"ref", reference_spp}, {"depth", c.max_depth}, {"tracer", kTracerVersion}};
  p.stem = "path_tracing_" + std::to_string(spp);
  p.compute = [&c, &scene, spp] {
    Stopwatch w;
    CellOutput out;
    out.image = render_color_sums(scene, input_settings(c, spp, c.seed), 0, spp).mean();
    const double t = w.seconds();
    out.times.input_render = out.times.total = t;
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
  p.identity["build"] = build_id();
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
  p.identity.update({{"method", m.method}, {"params", *p.params}, {"repeats", c.repeats},
                     {"repeat_below", c.repeat_below_seconds}, {"build", build_id()}});
  // A plug-in's code is not in the build: its folder's hash is (built-in cells keep their keys).
  if (!info.content_hash.empty()) p.identity["method_content"] = info.content_hash;
  p.contain_failures = true;
  p.stem = safe_file_name(m.name) + "_" + std::to_string(spp);
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
  d.build = build_info();
  d.git_revision = DNB_GIT_REVISION;
  return d;
}

// Every cell of a rendered scene: the plain path-tracing curve, then per input spp the input
// and every method on it.
void run_rendered_scene(const ExperimentConfig& c, const RunOptions& opt, Cache& cache, const std::string& name,
                        const CellContext& context) {
  const auto scene = load_scene(name);
  Reference ref;
  const SceneCells cells = rendered_scene_cells(c, opt, cache, *scene, name, ref);
  for (int spp : c.plain_spp)
    run_cell(plain_cell(c, *scene, cells.scene_hash, spp, c.reference_spp_for(name)), cells, context);
  // Every input seed gives its own input and method cells (Table 1's intervals are over them).
  // With one seed the stems are the same as before seeds existed; with several, "_s<seed>" is added.
  for (int spp : c.spp)
    for (std::uint64_t seed : c.seeds) {
      InputFrame frame(cache, *scene, input_settings(c, spp, seed), opt.use_cache, c.reference_spp_for(name));
      const std::string suffix = c.seeds.size() > 1 ? fmt::format("_s{}", seed) : "";
      auto seeded = [&](CellPlan p) {
        p.seed = seed;
        p.stem += suffix;
        return p;
      };
      run_cell(seeded(input_cell(frame, spp)), cells, context);
      for (const auto& m : c.methods) run_cell(seeded(method_cell(c, m, scene.get(), frame, spp)), cells, context);
    }
}

// Every cell of a scene read from files: the input (the frame, at its spp) and every filter on
// it. A renderer-type method renders the scene, which the files do not hold: skipped, with the
// reason recorded (results.json "skipped"); it is no failure of the run.
void run_file_scene(const ExperimentConfig& c, const RunOptions& opt, const SceneSpec& spec, const CellContext& context) {
  Reference ref;
  const SceneCells cells = file_scene_cells(opt, spec, ref);
  const int spp = spec.files->spp;
  InputFrame frame(spec);
  run_cell(input_cell(frame, spp), cells, context);
  for (const auto& m : c.methods) {
    if (MethodRegistry::global().info(m.method).kind == MethodKind::Renderer) {
      SkippedCell skip{spec.name, m.name, spp,
                       fmt::format("'{}' renders the scene itself, and scene '{}' is read from files ('{}', '{}'): there is "
                                   "no scene to render",
                                   m.method, spec.name, spec.files->frame, spec.files->reference)};
      skip_cell(context, std::move(skip));
      continue;
    }
    run_cell(method_cell(c, m, nullptr, frame, spp), cells, context);
  }
}

}  // namespace

ResultsDocument run_experiment(const ExperimentConfig& c, const RunOptions& opt) {
  create_folder(opt.out_dir + "/images");
  Cache cache(opt.cache_dir.empty() ? Cache::default_dir() : opt.cache_dir);
  ResultsStore store(opt.out_dir, results_header(c));
  const std::int64_t methods = std::int64_t(c.methods.size());
  std::int64_t cells = 0;
  for (const auto& s : c.scenes)
    cells += s.files ? methods + 1
                     : std::int64_t(c.spp.size() * c.seeds.size()) * (methods + 1) + std::int64_t(c.plain_spp.size());
  Progress progress("experiment " + c.name, cells, "cells", 0.0);
  const CellContext context{opt.out_dir, &store, &progress};

  for (const auto& s : c.scenes) {
    if (s.files)
      run_file_scene(c, opt, s, context);
    else
      run_rendered_scene(c, opt, cache, s.name, context);
  }
  progress.finish();
  store.write();
  spdlog::info("results in {}/results.json ({} records)", opt.out_dir, store.document().records.size());
  return store.document();
}

}  // namespace dnb::experiment
