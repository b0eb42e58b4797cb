#include "experiment/runner.h"

#include <filesystem>
#include <tuple>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "core/exr_io.h"
#include "core/progress.h"
#include "core/stats.h"
#include "core/timer.h"
#include "core/version.h"
#include "denoisers/method.h"
#include "experiment/cells.h"
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

RenderSettings input_settings(const ExperimentConfig& c, int spp) {
  RenderSettings s;
  std::tie(s.width, s.height, s.spp, s.seed, s.threads, s.max_depth) =
      std::tuple(c.width, c.height, spp, c.seed, c.threads, c.max_depth);
  return s;
}

// The reference of one scene (cached and checkpointed by tracer/reference.h), copied into the
// results folder, and what every record of the scene says about it.
SceneCells scene_cells(const ExperimentConfig& c, const RunOptions& opt, const Cache& cache, const Scene& scene,
                       const std::string& name, Reference& ref) {
  const ReferenceSettings rs{.width = c.width, .height = c.height, .spp = c.reference_spp, .seed = c.reference_seed,
                             .max_depth = c.max_depth, .block_spp = c.reference_block_spp, .threads = c.threads};
  ReferenceOptions ro;
  ro.cache_dir = cache.dir();
  ro.use_cache = opt.use_cache;
  spdlog::info("{}: reference {} spp at {}x{}", name, rs.spp, rs.width, rs.height);
  ref = reference_image(scene, rs, ro);

  SceneCells s;
  s.scene = name;
  s.scene_hash = scene_content_hash(scene);
  s.image_dir = "images/" + safe_file_name(name);
  s.reference = &ref;
  fs::create_directories(opt.out_dir + "/" + s.image_dir);
  ReferenceInfo& info = s.reference_info;
  info.spp = c.reference_spp;
  info.seed = c.reference_seed;
  info.seconds = ref.convergence.empty() ? ref.render_seconds : ref.convergence.back().seconds;
  info.cache_hit = ref.cache_hit;
  info.image = s.image_dir + "/reference.exr";
  if (!fs::exists(opt.out_dir + "/" + info.image)) write_rgb(ref.color, opt.out_dir + "/" + info.image);
  // The reference's own unconverged pixels (fireflies carried by a few samples): mse_converged
  // leaves them out; the report names their share beside it.
  if (!ref.variance.empty()) info.unconverged_share = metrics::unconverged_share(ref.color, ref.variance);
  info.unconverged_rse = metrics::kUnconvergedRse;
  return s;
}

// The input frame at one spp, rendered or read from the render cache on first use only: a
// scene whose cells are all finished reads no frame.
class InputFrame {
 public:
  InputFrame(Cache& cache, const Scene& scene, RenderSettings settings, bool use_cache)
      : cache_(cache), scene_(scene), settings_(settings), key_(frame_cache_key(scene, settings)), use_cache_(use_cache) {}
  const CacheKey& key() const { return key_; }
  const AovFrame& get() {
    if (!frame_) {
      if (!use_cache_) cache_.remove(key_);
      frame_ = cached_frame(cache_, key_, [&] { return render_frame(scene_, settings_); }, &hit_);
    }
    return *frame_;
  }
  bool cache_hit() const { return hit_; }

 private:
  Cache& cache_;
  const Scene& scene_;
  RenderSettings settings_;
  CacheKey key_;
  bool use_cache_;
  bool hit_ = false;
  std::optional<AovFrame> frame_;
};

CellPlan plain_cell(const ExperimentConfig& c, const Scene& scene, const std::string& scene_hash, int spp) {
  CellPlan p;
  p.role = Role::Plain;
  p.method = "path_tracing";
  p.spp = spp;
  p.identity = {{"plain", spp}, {"scene", scene_hash}, {"w", c.width}, {"h", c.height}, {"seed", c.seed},
                {"ref", c.reference_spp}, {"depth", c.max_depth}, {"tracer", kTracerVersion}};
  p.stem = "path_tracing_" + std::to_string(spp);
  p.compute = [&c, &scene, spp] {
    Stopwatch w;
    CellOutput out;
    out.image = render_color_sums(scene, input_settings(c, spp), 0, spp).mean();
    const double t = w.seconds();
    out.times.input_render = out.times.total = t;
    return out;
  };
  return p;
}

CellPlan input_cell(const ExperimentConfig& c, InputFrame& frame, int spp) {
  CellPlan p;
  p.role = Role::Input;
  p.method = "input";
  p.spp = spp;
  p.identity = {{"input", frame.key().digest()}, {"ref", c.reference_spp}, {"build", build_id()}};
  p.stem = "input_" + std::to_string(spp);
  p.compute = [&frame] {
    CellOutput out;
    out.image = frame.get().layer(layer::kColor);
    const double t = frame.get().meta.render_seconds;
    out.times.input_render = out.times.total = t;
    out.input_cache_hit = frame.cache_hit();
    return out;
  };
  return p;
}

CellPlan method_cell(const ExperimentConfig& c, const MethodSpec& m, const Scene& scene, InputFrame& frame, int spp) {
  const MethodRegistry& registry = MethodRegistry::global();
  const MethodInfo& info = registry.info(m.method);
  CellPlan p;
  p.role = m.role();
  p.method = m.name;
  p.spp = spp;
  p.base_method = m.method;
  p.kind = to_string(info.kind);
  p.params = registry.parse_params(m.method, m.params).as_strings();
  p.identity = {{"method", m.method}, {"params", *p.params}, {"input", frame.key().digest()},
                {"ref", c.reference_spp}, {"repeats", c.repeats}, {"repeat_below", c.repeat_below_seconds},
                {"build", build_id()}};
  // A plug-in's code is not in the build: its folder's hash is (built-in cells keep their keys).
  if (!info.content_hash.empty()) p.identity["method_content"] = info.content_hash;
  p.contain_failures = true;
  p.stem = safe_file_name(m.name) + "_" + std::to_string(spp);
  p.compute = [&c, &m, &info, &scene, &frame] {
    auto method = MethodRegistry::global().create(m.method, m.params);
    const MethodInput in = frame_input(frame.get(), &scene);
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
    out.input_cache_hit = frame.cache_hit();
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

}  // namespace

ResultsDocument run_experiment(const ExperimentConfig& c, const RunOptions& opt) {
  fs::create_directories(opt.out_dir + "/images");
  Cache cache(opt.cache_dir.empty() ? Cache::default_dir() : opt.cache_dir);
  ResultsStore store(opt.out_dir, results_header(c));
  const std::int64_t per_scene = std::int64_t(c.spp.size()) * (std::int64_t(c.methods.size()) + 1) + std::int64_t(c.plain_spp.size());
  Progress progress("experiment " + c.name, std::int64_t(c.scenes.size()) * per_scene, "cells", 0.0);
  const CellContext context{opt.out_dir, c.width, c.height, c.seed, &store, &progress};

  for (const auto& scene_name : c.scenes) {
    const auto scene = load_scene(scene_name);
    Reference ref;
    const SceneCells cells = scene_cells(c, opt, cache, *scene, scene_name, ref);
    for (int spp : c.plain_spp) run_cell(plain_cell(c, *scene, cells.scene_hash, spp), cells, context);
    for (int spp : c.spp) {
      InputFrame frame(cache, *scene, input_settings(c, spp), opt.use_cache);
      run_cell(input_cell(c, frame, spp), cells, context);
      for (const auto& m : c.methods) run_cell(method_cell(c, m, *scene, frame, spp), cells, context);
    }
  }
  progress.finish();
  store.write();
  spdlog::info("results in {}/results.json ({} records)", opt.out_dir, store.document().records.size());
  return store.document();
}

}  // namespace dnb::experiment
