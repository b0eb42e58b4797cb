#include "experiment/estimate.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <optional>
#include <set>

#include <unistd.h>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "core/exr_io.h"
#include "core/file_names.h"
#include "experiment/cells.h"
#include "experiment/frame_sources.h"
#include "experiment/planner.h"
#include "experiment/results.h"
#include "methods/inputs.h"
#include "tracer/reference.h"
#include "tracer/render.h"
#include "tracer/render_cache_keys.h"
#include "tracer/scene_loader.h"

namespace fs = std::filesystem;

namespace dnb::experiment {
namespace {

double now() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

// Seconds of f().
template <typename F>
double timed(F&& f) {
  const double t0 = now();
  f();
  return now() - t0;
}

// A cost a + b * n fitted through two measurements (n1, t1) and (n2, t2), n2 > n1: a is the
// fixed part (a worker's start, a kernel's compile), b the part per unit (pixel or sample). Both
// kept non-negative: noise can make the fitted a or b negative on small probes, and then the
// larger measurement alone (a = 0) is the safer extrapolation.
struct Linear {
  double a = 0, b = 0;
  static Linear fit(double n1, double t1, double n2, double t2) {
    Linear l;
    l.b = (t2 - t1) / (n2 - n1);
    l.a = t1 - l.b * n1;
    if (l.b < 0 || l.a < 0) {
      l.a = 0;
      l.b = t2 / n2;
    }
    return l;
  }
  double at(double n) const { return a + b * n; }
};

// The probe image sizes of a config of size w x h: about 160 x 120 pixels (never more than the
// config's), and half of that on each side.
struct ProbeSizes {
  int w1, h1, w2, h2;
};
ProbeSizes probe_sizes(int w, int h) {
  const double f = std::min(1.0, std::sqrt(160.0 * 120.0 / (double(w) * h)));
  ProbeSizes p;
  p.w2 = std::max(8, int(std::lround(w * f)));
  p.h2 = std::max(6, int(std::lround(h * f)));
  p.w1 = std::max(4, p.w2 / 2);
  p.h1 = std::max(3, p.h2 / 2);
  return p;
}

struct SceneModel {
  Linear frame;       // frame render seconds per (pixel x spp), with every AOV
  Linear color;       // colour-only render (references, the curve) per (pixel x spp)
  Linear write, read; // a frame's EXR per pixel
  Linear score;       // scoring one cell per pixel
  std::map<std::string, Linear> method;         // one run per pixel
  std::map<std::string, double> method_create;  // creating the method (a plug-in's worker start)
  std::map<std::string, std::string> method_failed;
};

// Renders at both probe sizes with a spp doubled until the larger takes a quarter of a second
// (shorter renders are too noisy to time), after a warm-up render.
template <typename Render>
Linear probe_render(const ProbeSizes& p, Render&& render) {
  render(p.w1, p.h1, 1);  // warm-up: threads, caches
  int spp = 2;
  double t2 = 0;
  for (;; spp *= 2) {
    t2 = timed([&] { render(p.w2, p.h2, spp); });
    if (t2 >= 0.25 || spp >= 1024) break;
  }
  const double t1 = timed([&] { render(p.w1, p.h1, spp); });
  return Linear::fit(double(p.w1) * p.h1 * spp, t1, double(p.w2) * p.h2 * spp, t2);
}

// `methods`: the models of the filters (probed on the first scene: a filter's cost depends on the
// frame's size, not on what it shows), else empty and probed here. Renderer-type methods render
// the scene: probed on every scene.
SceneModel probe_scene(const ExperimentConfig& c, const Scene& scene, const MethodRegistry& registry,
                       const std::string& tmp, const SceneModel* methods) {
  SceneModel m;
  const ProbeSizes p = probe_sizes(c.width, c.height);
  auto settings = [&](int w, int h, int spp) {
    RenderSettings s = input_settings(c, spp, c.seed);
    s.width = w;
    s.height = h;
    return s;
  };
  m.frame = probe_render(p, [&](int w, int h, int spp) { (void)render_frame(scene, settings(w, h, spp)); });
  m.color = probe_render(p, [&](int w, int h, int spp) {
    render_color_prefixes(scene, settings(w, h, spp), {spp}, [](std::size_t, Image, double) {});
  });
  // The probe frames the methods run on: the smallest input spp of the config.
  const int spp = c.spp.empty() ? 4 : *std::min_element(c.spp.begin(), c.spp.end());
  const AovFrame f1 = render_frame(scene, settings(p.w1, p.h1, spp));
  const AovFrame f2 = render_frame(scene, settings(p.w2, p.h2, spp));
  const double n1 = double(p.w1) * p.h1, n2 = double(p.w2) * p.h2;
  const std::string path1 = tmp + "/f1.exr", path2 = tmp + "/f2.exr";
  const double w1 = timed([&] { write_frame(f1, path1); }), w2 = timed([&] { write_frame(f2, path2); });
  m.write = Linear::fit(n1, w1, n2, w2);
  const double r1 = timed([&] { (void)read_frame(path1); }), r2 = timed([&] { (void)read_frame(path2); });
  m.read = Linear::fit(n1, r1, n2, r2);
  auto score = [&](const AovFrame& f) {
    Reference ref;
    ref.color = f.layer(layer::kColor);
    ref.variance = f.layer(layer::kVariance);
    std::map<std::string, std::string> files;
    return timed([&] { (void)score_image(f.layer(layer::kColor), ref, tmp, "probe", files); });
  };
  m.score = Linear::fit(n1, score(f1), n2, score(f2));
  for (const MethodSpec& spec : c.methods) {
    if (methods && registry.info(spec.method).kind != MethodKind::Renderer) {
      m.method[spec.name] = methods->method.at(spec.name);
      m.method_create[spec.name] = methods->method_create.at(spec.name);
      continue;
    }
    try {
      std::unique_ptr<Method> method;
      m.method_create[spec.name] = timed([&] { method = registry.create(spec.method, spec.params); });
      const MethodInput in1 = frame_input(f1, &scene), in2 = frame_input(f2, &scene);
      (void)run_method(*method, in1);  // warm-up, as a cell's first run is
      // The median of three runs per size: a plug-in's runs (files and a pipe to another process)
      // vary by tens of percent from one to the next, and the fit extrapolates their difference.
      auto median_run = [&](const MethodInput& in) {
        std::vector<double> t;
        for (int i = 0; i < 3; ++i) t.push_back(timed([&] { (void)run_method(*method, in); }));
        std::sort(t.begin(), t.end());
        return t[1];
      };
      const double t1 = median_run(in1), t2 = median_run(in2);
      m.method[spec.name] = Linear::fit(n1, t1, n2, t2);
    } catch (const std::exception& e) {
      // The cell will fail the same way: it costs what creating the method costs.
      m.method_failed[spec.name] = e.what();
      m.method[spec.name] = Linear{};
    }
  }
  return m;
}

bool cache_holds(const Cache& cache, const CacheKey& key) {
  std::error_code ec;
  // An entry is renamed into place only when whole (render_cache.h): its manifest says it is
  // there. Not verified: the run verifies it, and a damaged one is rendered again.
  return fs::is_regular_file(cache.entry_dir(key) + "/MANIFEST.json", ec);
}

// The cell keys of the results folder's finished records (nothing when there is no folder yet).
std::set<std::string> finished_keys(const std::string& out_dir) {
  std::set<std::string> keys;
  const std::string path = out_dir + "/results.json";
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) return keys;
  for (const CellRecord& r : ResultsDocument::load(path).records) keys.insert(r.cell_key);
  return keys;
}

std::string duration(double s) {
  if (s < 60) return fmt::format("{:.1f} s", s);
  if (s < 3600) return fmt::format("{}m{:02d}s", int(s) / 60, int(s) % 60);
  return fmt::format("{}h{:02d}m", int(s) / 3600, (int(s) % 3600) / 60);
}

// What one rendered scene's (or one sequence frame's) plans add to its estimate: the reference,
// the input frames and the method cells that are not finished, priced with the scene's probe `m`.
// A sequence frame's input is keyed as the run keys it (experiment/sequences.h) and its temporal
// methods run once (a repeat would advance their history).
void add_scene_plans(const ExperimentConfig& c, const RunOptions& opt, const MethodRegistry& registry, Cache& cache,
                     const std::set<std::string>& finished, SceneModel& m, double pixels, const std::string& base_name,
                     bool sequence, ScenePlans& plans, SceneEstimate& se, double& longest_group) {
  ScenePlans* sp = &plans;
  const Scene& scene = *sp->scene;
  // The reference.
  const ReferenceSettings rs{.width = c.width, .height = c.height, .spp = c.reference_spp_for(base_name),
                             .seed = c.reference_seed, .max_depth = c.max_depth, .block_spp = c.reference_block_spp,
                             .threads = c.threads};
  se.reference.items += 1;
  if (opt.use_cache && cache_holds(cache, reference_cache_key(scene, rs))) se.reference.held += 1;
  else se.reference.seconds += m.color.at(pixels * rs.spp);
  // Groups: the plain curve, then one per input frame.
  for (PlanGroup& g : sp->groups) {
    double group = 0;
    std::vector<const CellPlan*> open;
    for (const CellPlan& p : g.plans)
      if (!p.skip_reason && !finished.count(cell_key(p))) open.push_back(&p);
    if (!g.frame) {  // the curve
      se.curve.items = int(g.plans.size());
      se.curve.held = int(g.plans.size() - open.size());
      if (!open.empty()) {
        const int top = *std::max_element(c.plain_spp.begin(), c.plain_spp.end());
        std::vector<int> prefixes(c.plain_spp.begin(), c.plain_spp.end());
        std::sort(prefixes.begin(), prefixes.end());
        prefixes.erase(std::unique(prefixes.begin(), prefixes.end()), prefixes.end());
        const bool held = opt.use_cache && cache_holds(cache, curve_cache_key(scene, input_settings(c, top, c.seed), prefixes));
        group += held ? 0 : m.color.at(pixels * top);
        group += double(open.size()) * m.score.at(pixels);
      }
      se.curve.seconds += group;
    } else {
      const CellPlan& input = g.plans.front();
      se.inputs.items += 1;
      const bool input_open = !finished.count(cell_key(input));
      if (!input_open) se.inputs.held += 1;
      if (!open.empty()) {
        // The frame: rendered and stored, or read from the cache.
        const RenderSettings rset = input_settings(c, input.spp, input.seed.value_or(c.seed));
        const bool held =
            opt.use_cache && cache_holds(cache, sequence ? sequence_frame_key(scene, rset) : frame_cache_key(scene, rset));
        const double frame = held ? m.read.at(pixels) : m.frame.at(pixels * input.spp) + m.write.at(pixels);
        double in = frame + (input_open ? m.score.at(pixels) : 0.0);
        se.inputs.seconds += in;
        group += in;
      }
      for (const CellPlan* p : open) {
        if (p->role == Role::Input) continue;
        const double run = m.method[p->method].at(pixels);
        const bool temporal = sequence && registry.contains(p->base_method) && registry.info(p->base_method).temporal;
        const int runs = !temporal && run < c.repeat_below_seconds && c.repeats > 0 ? 1 + c.repeats : 1;
        const double cell = m.method_create[p->method] + run * runs + m.score.at(pixels);
        se.method_cell_seconds[p->method] = cell;
        se.methods.seconds += cell;
        group += cell;
      }
      se.methods.items += int(g.plans.size()) - 1;
      se.methods.held += int(g.plans.size() - 1) - int(std::count_if(open.begin(), open.end(), [](const CellPlan* p) { return p->role != Role::Input; }));
    }
    longest_group = std::max(longest_group, group);
  }
}

}  // namespace

RunEstimate estimate_run(const ExperimentConfig& c, const RunOptions& opt, const MethodRegistry& registry) {
  RunEstimate est;
  Cache cache(opt.cache_dir.empty() ? Cache::default_dir() : opt.cache_dir);
  const std::set<std::string> finished = finished_keys(opt.out_dir);
  const fs::path tmp = fs::temp_directory_path() / fmt::format("dnb-estimate-{}", ::getpid());
  fs::create_directories(tmp);
  struct Cleanup {
    fs::path p;
    ~Cleanup() {
      std::error_code ec;
      fs::remove_all(p, ec);
    }
  } cleanup{tmp};
  const double pixels = double(c.width) * c.height;
  double longest_group = 0;
  std::optional<SceneModel> first;  // the first scene's model: its filters' costs
  for (const SceneSpec& spec : c.scenes) {
    SceneEstimate se;
    se.scene = spec.name;
    if (spec.files || spec.renderer) {
      se.estimated = false;
      se.why_not = spec.files ? "read from files: not probed"
                              : fmt::format("rendered by the '{}' back-end: not probed", spec.renderer->renderer);
      est.scenes.push_back(se);
      continue;
    }
    // A sequence: every frame's plans (their keys say which cells are finished), priced with the
    // probe of its first frame; a still: its one plan.
    const bool sequence = spec.frames > 0;
    std::optional<SequenceRun> run;
    if (sequence) run.emplace(spec.name, spec.frames, cache);
    SceneModel m;
    for (int t = 0; t < std::max(spec.frames, 1); ++t) {
      // The plans as the run makes them, without the reference; loading the scene is timed as
      // the run's load.
      std::unique_ptr<ScenePlans> sp;
      se.load_seconds += timed([&] {
        sp = rendered_scene_plans(c, opt, registry, cache, spec.name, false, run ? &*run : nullptr, t);
      });
      const Scene& scene = *sp->scene;
      if (t == 0) {
        se.probe_seconds = timed([&] { m = probe_scene(c, scene, registry, tmp.string(), first ? &*first : nullptr); });
        if (!first) first = m;
        est.probe_seconds += se.probe_seconds;
      }
      add_scene_plans(c, opt, registry, cache, finished, m, pixels, spec.name, sequence, *sp, se, longest_group);
    }
    est.one_process_seconds += se.total();
    est.scenes.push_back(std::move(se));
  }
  for (const auto& s : est.scenes) {
    est.load_seconds += s.load_seconds;
    est.reference_seconds += s.reference.seconds;
    est.cell_seconds += s.inputs.seconds + s.curve.seconds + s.methods.seconds;
  }
  est.longest_group_seconds = longest_group;
  return est;
}

std::string RunEstimate::text(const std::vector<int>& ranks) const {
  std::string t = fmt::format("{:<22} {:>9} {:>19} {:>19} {:>19} {:>19} {:>10}\n", "scene", "load", "reference",
                              "inputs", "curve", "methods", "total");
  auto stage = [](const StageEstimate& s) {
    return fmt::format("{:>9} ({}/{} held)", duration(s.seconds), s.held, s.items);
  };
  for (const auto& s : scenes) {
    if (!s.estimated) {
      t += fmt::format("{:<22} not estimated: {}\n", s.scene, s.why_not);
      continue;
    }
    t += fmt::format("{:<22} {:>9} {:>19} {:>19} {:>19} {:>19} {:>10}\n", s.scene, duration(s.load_seconds),
                     stage(s.reference), stage(s.inputs), stage(s.curve), stage(s.methods), duration(s.total()));
  }
  t += fmt::format("predicted: {} on one process; the probes took {}\n", duration(one_process_seconds), duration(probe_seconds));
  for (int n : ranks)
    if (n > 1) t += fmt::format("predicted: {} with {} ranks, each as fast as this process\n", duration(with_ranks(n)), n);
  return t;
}

nlohmann::json RunEstimate::to_json(const std::vector<int>& ranks) const {
  nlohmann::json j = {{"one_process_seconds", one_process_seconds}, {"probe_seconds", probe_seconds},
                      {"longest_group_seconds", longest_group_seconds}, {"ranks", nlohmann::json::object()},
                      {"scenes", nlohmann::json::array()}};
  for (int n : ranks) j["ranks"][std::to_string(n)] = with_ranks(n);
  auto stage = [](const StageEstimate& s) { return nlohmann::json{{"seconds", s.seconds}, {"items", s.items}, {"held", s.held}}; };
  for (const auto& s : scenes) {
    nlohmann::json e = {{"scene", s.scene}, {"estimated", s.estimated}};
    if (!s.estimated) {
      e["why_not"] = s.why_not;
    } else {
      e.update({{"load_seconds", s.load_seconds}, {"reference", stage(s.reference)}, {"inputs", stage(s.inputs)},
                {"curve", stage(s.curve)}, {"methods", stage(s.methods)}, {"method_cell_seconds", s.method_cell_seconds},
                {"total_seconds", s.total()}, {"probe_seconds", s.probe_seconds}});
    }
    j["scenes"].push_back(e);
  }
  return j;
}

}  // namespace dnb::experiment
