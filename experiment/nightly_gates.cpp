// The nightly's gates (experiment/nightly.h): the pure comparison of a run's summary with the
// baseline's, and the derivation of tolerances from measured noise. No file is read here.
#include <algorithm>
#include <cmath>
#include <set>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "core/errors.h"
#include "core/stats.h"
#include "core/timer.h"
#include "denoisers/method.h"
#include "experiment/nightly.h"

using nlohmann::json;

namespace dnb::nightly {

// ---------------------------------------------------------------------------------------------
// Gates

double Gates::quality_tolerance(const std::string& scene, const std::string& method) const {
  for (const auto& key : {scene + "/" + method, method}) {
    auto it = quality.find(key);
    if (it != quality.end()) return it->second;
  }
  return quality_default;
}

double Gates::performance_tolerance(const std::string& name) const {
  auto it = performance.find(name);
  return it == performance.end() ? performance_default : it->second;
}

bool Gates::report_only(const std::string& case_name) const {
  return std::any_of(performance_report_only.begin(), performance_report_only.end(),
                     [&](const std::string& p) { return !p.empty() && case_name.find(p) != std::string::npos; });
}

namespace {

using QualityIndex = std::map<std::tuple<std::string, std::string, int>, const QualityEntry*>;

// The run must be of the config the baseline was accepted from (a differing seed is noted).
void check_config(const Summary& baseline, const Summary& current, Verdict& v) {
  for (const char* key : {"name", "width", "height", "spp", "reference_spp"}) {
    const json a = baseline.config.value(key, json()), b = current.config.value(key, json());
    if (a != b)
      throw InputError(fmt::format("the run is not of the baseline's config: {} is {} in the baseline, {} in the run "
                                   "(run the same config, or accept a new baseline deliberately)",
                                   key, a.dump(), b.dump()));
  }
  if (baseline.config.value("seed", json()) != current.config.value("seed", json()))
    v.notes.push_back(fmt::format("seed differs: {} in the baseline, {} in the run", baseline.config.value("seed", json()).dump(),
                                  current.config.value("seed", json()).dump()));

}

// Each baseline MSE against the run's: new <= old * (1 + tolerance).
void check_quality(const Summary& baseline, const Summary& current, const QualityIndex& now, const Gates& gates, Verdict& v) {
  std::set<std::tuple<std::string, std::string, int>> in_baseline;
  for (const auto& old : baseline.quality) {
    in_baseline.insert({old.scene, old.method, old.spp});
    auto it = now.find({old.scene, old.method, old.spp});
    if (it == now.end())
      throw InputError(fmt::format("the run has no result for scene {}, method {}, spp {} (the baseline has one): "
                                   "a method or scene was dropped; accept a new baseline if that is intended",
                                   old.scene, old.method, old.spp));
    const QualityEntry& cur = *it->second;
    const double tol = gates.quality_tolerance(old.scene, old.method);
    Finding f{"quality", old.scene, old.method, "mse", old.mse, cur.mse, old.mse * (1.0 + tol), "", false, ""};
    f.failed = !std::isfinite(cur.mse) || !(cur.mse <= f.limit);
    f.message = fmt::format("quality: scene {}, method {}, mse {} from {} to {} ({}, tolerance +{:.1f}%)", old.scene,
                            old.method, f.failed ? "rose" : "went", format_value(old.mse), format_value(cur.mse),
                            std::isfinite(cur.mse) ? format_percent(cur.mse / old.mse - 1.0) : "non-finite", 100.0 * tol);
    v.findings.push_back(f);
  }
  for (const auto& e : current.quality)
    if (!in_baseline.count({e.scene, e.method, e.spp}))
      v.notes.push_back(fmt::format("scene {}, method {}: new in this run, no baseline (not gated)", e.scene, e.method));

}

// The leading method's MSE below each listed method's, per scene.
void check_ahead(const Summary& current, const QualityIndex& now, const Gates& gates, const CheckOptions& options,
                 Verdict& v) {
  if (!options.ahead && !gates.ahead_method.empty())
    v.notes.push_back(fmt::format("ahead gate not run ({} ahead of {})", gates.ahead_method, fmt::join(gates.ahead_of, ", ")));
  if (options.ahead && !gates.ahead_method.empty()) {
    std::set<std::pair<std::string, int>> scenes;
    for (const auto& e : current.quality) scenes.insert({e.scene, e.spp});
    for (const auto& [scene, spp] : scenes) {
      auto lead = now.find({scene, gates.ahead_method, spp});
      if (lead == now.end())
        throw InputError(fmt::format("the run has no result for scene {}, method {} (the method that must stay ahead)", scene,
                                     gates.ahead_method));
      for (const auto& other : gates.ahead_of) {
        auto it = now.find({scene, other, spp});
        if (it == now.end())
          throw InputError(fmt::format("the run has no result for scene {}, method {} (a method {} must stay ahead of)", scene,
                                       other, gates.ahead_method));
        const double a = lead->second->mse, b = it->second->mse;
        Finding f{"ahead", scene, gates.ahead_method, "mse", b, a, b, other, !(a < b), ""};
        f.message = fmt::format("ahead: scene {}, method {} mse {} is {} method {} mse {}", scene, gates.ahead_method,
                                format_value(a), f.failed ? "not below" : "below", other, format_value(b));
        v.findings.push_back(f);
      }
    }
  }

}

// Each benchmark case's time ratio against the baseline's, on the same CPU model only.
void check_performance(const Summary& baseline, const Summary& current, const Gates& gates, Verdict& v) {
  v.performance_checked = true;
  std::map<std::string, const PerfEntry*> perf_now;
  for (const auto& e : current.performance) perf_now[e.name] = &e;
  for (const auto& old : baseline.performance) {
    auto it = perf_now.find(old.name);
    if (it == perf_now.end())
      throw InputError(fmt::format("the run has no benchmark case {} (the baseline has it): run the same --benchmark_filter",
                                   old.name));
    const PerfEntry& cur = *it->second;
    const double tol = gates.performance_tolerance(old.name);
    Finding f{"performance", old.frame.empty() ? old.name : old.name + " (frame " + old.frame + ")", old.method, "time_ratio", old.ratio, cur.ratio,
              old.ratio * (1.0 + tol), "", false, ""};
    const bool over = !std::isfinite(cur.ratio) || !(cur.ratio <= f.limit);
    f.report_only = gates.report_only(old.name);
    f.failed = over && !f.report_only;
    f.message = fmt::format("performance: case {}, method {}, time_ratio {} from {} to {} ({}, tolerance +{:.1f}%; "
                            "method {:.3g} ms, reference workload {:.3g} ms)",
                            f.scene, old.method, over ? "rose" : "went", format_value(old.ratio), format_value(cur.ratio),
                            format_percent(cur.ratio / old.ratio - 1.0), 100.0 * tol, cur.method_ms, cur.reference_ms);
    if (!cur.error.empty())
      f.message = fmt::format("performance: case {}, method {}, time_ratio was {}, now the case fails: {}", f.scene,
                              old.method, format_value(old.ratio), cur.error);
    if (over && f.report_only) v.notes.push_back("over its tolerance, reported only (not gated): " + f.message);
    v.findings.push_back(f);
  }
  std::set<std::string> old_names;
  for (const auto& e : baseline.performance) old_names.insert(e.name);
  for (const auto& e : current.performance)
    if (!old_names.count(e.name)) v.notes.push_back(fmt::format("benchmark case {}: new in this run, no baseline (not gated)", e.name));
}

// Each case's instruction count against the baseline's: same CPU model only (another processor
// runs other code paths of OpenCV, Embree and the compiler's dispatch), and only when both the
// baseline and the run counted (a note says why when not).
void check_instructions(const Summary& baseline, const Summary& current, const Gates& gates, Verdict& v) {
  if (baseline.instructions.empty()) {
    if (!current.instructions.empty())
      v.notes.push_back("instruction gate skipped: the baseline has no instruction counts (accept a run with instructions.json)");
    return;
  }
  if (current.instructions.empty()) {
    v.notes.push_back("instruction gate skipped: this run has no instruction counts (RUN_DIR/instructions.json, "
                      "scripts/nightly_instructions)");
    return;
  }
  if (baseline.instructions_cpu_model != current.instructions_cpu_model) {
    v.notes.push_back(fmt::format("instruction gate skipped: the baseline's counts come from '{}', this run's from '{}'",
                                  baseline.instructions_cpu_model, current.instructions_cpu_model));
    return;
  }
  std::map<std::string, const InstrEntry*> now;
  for (const auto& e : current.instructions) now[e.name] = &e;
  const double tol = gates.instructions_default;
  for (const auto& old : baseline.instructions) {
    auto it = now.find(old.name);
    if (it == now.end())
      throw InputError(fmt::format("the run has no instruction count for case {} (the baseline has it): run "
                                   "scripts/nightly_instructions with the same cases",
                                   old.name));
    const double n = it->second->instructions;
    Finding f{"instructions", old.name, old.method, "instructions", old.instructions, n, old.instructions * (1.0 + tol),
              "", false, ""};
    f.failed = !(n <= f.limit);
    f.message = fmt::format("instructions: case {}, method {}, {} from {} to {} ({}, tolerance +{:.1f}%)", old.name,
                            old.method, f.failed ? "rose" : "went", format_value(old.instructions), format_value(n),
                            format_percent(n / old.instructions - 1.0), 100.0 * tol);
    v.findings.push_back(f);
  }
  std::set<std::string> old_names;
  for (const auto& e : baseline.instructions) old_names.insert(e.name);
  for (const auto& e : current.instructions)
    if (!old_names.count(e.name)) v.notes.push_back(fmt::format("instruction count of case {}: new in this run, no baseline (not gated)", e.name));
}

// Why the performance gate cannot run, or "" when it can (InputError where it must and cannot).
std::string performance_skipped(const Summary& baseline, const Summary& current, const CheckOptions& options) {
  if (!options.performance) return "performance gate not run (asked for quality only)";
  if (baseline.performance.empty()) {
    if (options.require_performance) throw InputError("the baseline has no benchmark results: accept a run with bench.json");
    return "performance gate skipped: the baseline has no benchmark results (accept a run with bench.json)";
  }
  if (current.performance.empty())
    throw InputError("the run has no nightly benchmark results (RUN_DIR/bench.json with nightly/ cases); the baseline has");
  if (baseline.cpu_model != current.cpu_model) {
    const std::string why =
        fmt::format("the baseline's ratios were measured on '{}', this run on '{}'", baseline.cpu_model, current.cpu_model);
    if (options.require_performance) throw InputError("performance gate: " + why + " (accept a baseline on this machine)");
    return "performance gate skipped: " + why + "; accept a baseline on this machine to gate speed here";
  }
  return "";
}

}  // namespace

Verdict check(const Summary& baseline, const Summary& current, const Gates& gates, const CheckOptions& options) {
  Verdict v;
  check_config(baseline, current, v);
  QualityIndex now;
  for (const auto& e : current.quality) now[{e.scene, e.method, e.spp}] = &e;
  check_quality(baseline, current, now, gates, v);
  check_ahead(current, now, gates, options, v);
  if (const std::string skipped = performance_skipped(baseline, current, options); !skipped.empty())
    v.notes.push_back(skipped);
  else
    check_performance(baseline, current, gates, v);
  if (options.performance) check_instructions(baseline, current, gates, v);
  return v;
}

// ---------------------------------------------------------------------------------------------
// Tolerances from measured noise

// The default ahead rule for a run: `proposed` ahead of every other non-ablation filter in it
// (no rule when the run has no `proposed`). Renderer-type methods (the irradiance cache) are
// left out: they render the scene with their own sample budget, not the run's input frame, so
// at the nightly's 16 spp the comparison says nothing about the filter (the irradiance cache
// is compared with `proposed` at the paper's setting, configs/paper.toml).
void default_ahead(Gates& g, const Summary& s) {
  g.ahead_of.clear();
  if (std::none_of(s.quality.begin(), s.quality.end(), [&](const QualityEntry& e) { return e.method == g.ahead_method; })) {
    g.ahead_method.clear();
    return;
  }
  const MethodRegistry& registry = MethodRegistry::global();
  for (const auto& e : s.quality) {
    const bool renderer = registry.contains(e.method) && registry.info(e.method).kind == MethodKind::Renderer;
    if (e.role == "method" && e.method != g.ahead_method && !renderer &&
        std::find(g.ahead_of.begin(), g.ahead_of.end(), e.method) == g.ahead_of.end())
      g.ahead_of.push_back(e.method);
  }
}


Gates derive_gates(const std::vector<Summary>& quality_runs, const std::vector<std::string>& quality_names,
                   const std::vector<Summary>& perf_runs, const std::vector<std::string>& perf_names, const Gates& previous,
                   const DeriveOptions& o) {
  Gates g = previous;
  if (g.ahead_of.empty() && !g.ahead_method.empty() && !quality_runs.empty()) default_ahead(g, quality_runs.front());
  json d = previous.derivation.is_object() ? previous.derivation : json::object();
  d.erase("note");
  if (!quality_runs.empty()) {
    if (quality_runs.size() < 2) throw InputError("deriving quality tolerances needs at least two runs (different seeds)");
    // (scene, method) -> MSE per run.
    std::map<std::pair<std::string, std::string>, std::vector<double>> mse;
    for (std::size_t r = 0; r < quality_runs.size(); ++r)
      for (const auto& e : quality_runs[r].quality) mse[{e.scene, e.method}].push_back(e.mse);
    std::map<std::string, double> worst;
    json spread = json::object();
    g.quality.clear();
    for (const auto& [key, values] : mse) {
      if (values.size() != quality_runs.size())
        throw InputError(fmt::format("scene {}, method {}: in {} of {} runs (the runs must be of one config)", key.first,
                                     key.second, values.size(), quality_runs.size()));
      const double tol = std::max({o.quality_k * stats::relative_std(values), stats::max_over_min_minus_one(values), o.quality_floor});
      spread[key.second][key.first] = {{"relative_std", stats::relative_std(values)}, {"max_over_min", stats::max_over_min_minus_one(values) + 1}, {"mse", values}};
      g.quality[key.first + "/" + key.second] = tol;
      worst[key.second] = std::max(worst[key.second], tol);
    }
    // A scene without a tolerance of its own (added later) gets its method's largest.
    for (const auto& [method, tol] : worst) g.quality[method] = tol;
    g.quality_default = std::max(o.quality_floor, g.quality.empty() ? o.quality_floor : [&] {
      double m = 0;
      for (const auto& [k, t] : g.quality) m = std::max(m, t);
      return m;
    }());
    std::vector<json> seeds;
    for (const auto& r : quality_runs) seeds.push_back(r.config.value("seed", json()));
    d["quality"] = {{"rule", fmt::format("tolerance(scene/method) = max({} * relative standard deviation of the MSE "
                                         "across runs, max/min - 1 of the MSE across runs, {}); tolerance(method): its "
                                         "largest over scenes (for scenes added later); default: the largest",
                                         o.quality_k, o.quality_floor)},
                    {"runs", quality_names}, {"seeds", seeds}, {"config", quality_runs.front().config},
                    {"relative_std", spread}};
  }
  if (!perf_runs.empty()) {
    if (perf_runs.size() < 2) throw InputError("deriving performance tolerances needs at least two benchmark runs");
    std::map<std::string, std::vector<double>> ratio;
    for (const auto& r : perf_runs)
      for (const auto& e : r.performance) ratio[e.name].push_back(e.ratio);
    json spread = json::object();
    g.performance.clear();
    double largest = 0;
    for (const auto& [name, values] : ratio) {
      if (values.size() != perf_runs.size())
        throw InputError(fmt::format("benchmark case {}: in {} of {} runs (run the same cases each time)", name, values.size(),
                                     perf_runs.size()));
      const double rs = stats::relative_std(values);
      spread[name] = {{"relative_std", rs}, {"max_over_min", stats::max_over_min_minus_one(values) + 1}, {"time_ratio", values}};
      g.performance[name] = std::max({o.performance_k * rs, stats::max_over_min_minus_one(values), o.performance_floor});
      largest = std::max(largest, g.performance[name]);
    }
    g.performance_default = std::max(largest, o.performance_floor);
    d["performance"] = {{"rule", fmt::format("tolerance(case) = max({} * relative standard deviation of the case's ratio "
                                             "across runs, max/min - 1 of the ratio across runs, {}); default: the largest",
                                             o.performance_k, o.performance_floor)},
                        {"runs", perf_names}, {"machine", perf_runs.front().machine},
                        {"cpu_model", perf_runs.front().cpu_model}, {"spread", spread}};
  }
  d["derived"] = utc_now_iso();
  g.derivation = d;
  return g;
}

}  // namespace dnb::nightly
