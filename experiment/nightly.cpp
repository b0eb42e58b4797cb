#include "experiment/nightly.h"

#include <algorithm>
#include <cmath>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "core/atomic_file.h"
#include "core/errors.h"
#include "denoisers/method.h"

namespace fs = std::filesystem;
using nlohmann::json;

namespace dnb::nightly {

namespace {

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n == 0 ? NAN : n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

// Relative standard deviation (sample std / mean); 0 for fewer than two values.
double relative_std(const std::vector<double>& v) {
  if (v.size() < 2) return 0;
  double mean = 0;
  for (double x : v) mean += x;
  mean /= double(v.size());
  double ss = 0;
  for (double x : v) ss += (x - mean) * (x - mean);
  return mean > 0 ? std::sqrt(ss / double(v.size() - 1)) / mean : 0;
}

// max / min - 1: the largest change between two of the runs (0 for fewer than two values).
double range(const std::vector<double>& v) {
  if (v.size() < 2) return 0;
  const auto [lo, hi] = std::minmax_element(v.begin(), v.end());
  return *lo > 0 ? *hi / *lo - 1.0 : 0;
}

std::string now_iso() {
  std::time_t t = std::time(nullptr);
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", std::gmtime(&t));
  return buf;
}

// Reads a JSON file; InputError naming it when it is missing or malformed.
json read_json(const std::string& path) {
  if (!fs::exists(path)) throw InputError(fmt::format("'{}': no such file", path));
  try {
    return json::parse(read_text_file(path));
  } catch (const json::exception& e) {
    throw InputError(fmt::format("'{}': not valid JSON ({})", path, e.what()));
  }
}

// Typed access with errors naming the file and the key.
template <class T>
T get(const json& j, const std::string& key, const std::string& where) {
  if (!j.is_object() || !j.contains(key))
    throw InputError(fmt::format("{}: missing key '{}'", where, key));
  try {
    return j.at(key).get<T>();
  } catch (const json::exception&) {
    throw InputError(fmt::format("{}: key '{}' has the wrong type ({})", where, key, j.at(key).type_name()));
  }
}

double get_number(const json& j, const std::string& key, const std::string& where) {
  if (!j.is_object() || !j.contains(key)) throw InputError(fmt::format("{}: missing key '{}'", where, key));
  const json& v = j.at(key);
  if (v.is_null()) return NAN;  // results.json writes a non-finite metric as null
  if (!v.is_number()) throw InputError(fmt::format("{}: key '{}' is not a number ({})", where, key, v.type_name()));
  return v.get<double>();
}

double optional_number(const json& j, const std::string& key, double fallback, const std::string& where) {
  return j.is_object() && j.contains(key) ? get_number(j, key, where) : fallback;
}

std::string fmt_value(double v) { return std::isfinite(v) ? fmt::format("{:.6g}", v) : std::string("non-finite"); }

std::string percent(double rel) { return fmt::format("{:+.1f}%", 100.0 * rel); }

// Case name without the suffix Google Benchmark adds for the timing mode.
std::string case_name(std::string name) {
  for (const char* suffix : {"/manual_time", "/real_time", "/process_time"}) {
    const std::string s = suffix;
    if (name.size() > s.size() && name.compare(name.size() - s.size(), s.size(), s) == 0) name.resize(name.size() - s.size());
  }
  return name;
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// Summary

json Summary::to_json() const {
  json q = json::array();
  for (const auto& e : quality)
    q.push_back({{"scene", e.scene}, {"method", e.method}, {"role", e.role}, {"spp", e.spp}, {"mse", e.mse}});
  json p = json::array();
  for (const auto& e : performance) {
    p.push_back({{"case", e.name}, {"method", e.method}, {"frame", e.frame}, {"time_ratio", e.ratio},
                 {"time_ratio_min", e.ratio_min}, {"time_ratio_max", e.ratio_max}, {"method_ms", e.method_ms},
                 {"reference_ms", e.reference_ms}, {"repetitions", e.repetitions}});
    if (!e.error.empty()) p.back()["error"] = e.error;
  }
  return {{"format", "denoisebench-nightly-summary-1"},
          {"date", date},
          {"git_revision", git_revision},
          {"machine", machine},
          {"cpu_model", cpu_model},
          {"config", config},
          {"reference_workload", reference_workload},
          {"quality", q},
          {"performance", p}};
}

Summary Summary::from_json(const json& j, const std::string& where) {
  if (!j.is_object()) throw InputError(fmt::format("{}: expected a JSON object", where));
  if (j.value("format", "") != "denoisebench-nightly-summary-1")
    throw InputError(fmt::format("{}: key 'format': expected \"denoisebench-nightly-summary-1\"", where));
  Summary s;
  s.date = get<std::string>(j, "date", where);
  s.git_revision = get<std::string>(j, "git_revision", where);
  s.machine = get<std::string>(j, "machine", where);
  s.cpu_model = get<std::string>(j, "cpu_model", where);
  s.config = j.value("config", json::object());
  s.reference_workload = j.value("reference_workload", "");
  const auto q = get<json>(j, "quality", where);
  if (!q.is_array()) throw InputError(fmt::format("{}: key 'quality': expected an array", where));
  for (std::size_t i = 0; i < q.size(); ++i) {
    const std::string w = fmt::format("{}: quality[{}]", where, i);
    s.quality.push_back({get<std::string>(q[i], "scene", w), get<std::string>(q[i], "method", w),
                         q[i].value("role", "method"), get<int>(q[i], "spp", w), get_number(q[i], "mse", w)});
  }
  const auto p = get<json>(j, "performance", where);
  if (!p.is_array()) throw InputError(fmt::format("{}: key 'performance': expected an array", where));
  for (std::size_t i = 0; i < p.size(); ++i) {
    const std::string w = fmt::format("{}: performance[{}]", where, i);
    PerfEntry e;
    e.name = get<std::string>(p[i], "case", w);
    e.method = get<std::string>(p[i], "method", w);
    e.frame = p[i].value("frame", "");
    e.ratio = get_number(p[i], "time_ratio", w);
    e.ratio_min = optional_number(p[i], "time_ratio_min", e.ratio, w);
    e.ratio_max = optional_number(p[i], "time_ratio_max", e.ratio, w);
    e.method_ms = optional_number(p[i], "method_ms", NAN, w);
    e.reference_ms = optional_number(p[i], "reference_ms", NAN, w);
    e.repetitions = p[i].value("repetitions", 0);
    e.error = p[i].value("error", "");
    s.performance.push_back(e);
  }
  return s;
}

void add_benchmarks(Summary& s, const json& bench, const std::string& where_bench) {
  if (!bench.is_object()) throw InputError(fmt::format("{}: expected a JSON object", where_bench));
  const json context = get<json>(bench, "context", where_bench);
  s.cpu_model = context.value("cpu_model", s.cpu_model);
  s.reference_workload = context.value("nightly_reference_workload", "");
  const json runs = get<json>(bench, "benchmarks", where_bench);
  if (!runs.is_array()) throw InputError(fmt::format("{}: key 'benchmarks': expected an array", where_bench));
  struct Acc {
    std::vector<double> ratio, method_ms, reference_ms;
    std::string frame, error;
  };
  std::map<std::string, Acc> acc;
  std::vector<std::string> order;
  for (std::size_t i = 0; i < runs.size(); ++i) {
    const json& b = runs[i];
    const std::string w = fmt::format("{}: benchmarks[{}]", where_bench, i);
    if (b.value("run_type", "iteration") != "iteration") continue;  // aggregates: recomputed here
    const std::string name = case_name(b.value("run_name", get<std::string>(b, "name", w)));
    if (name.rfind("nightly/", 0) != 0) continue;
    if (!acc.count(name)) order.push_back(name);
    Acc& a = acc[name];
    if (b.value("error_occurred", false)) {
      a.error = b.value("error_message", "error");
      continue;
    }
    a.ratio.push_back(get_number(b, "ratio", w));
    a.method_ms.push_back(optional_number(b, "method_ms", NAN, w));
    a.reference_ms.push_back(optional_number(b, "reference_ms", NAN, w));
    a.frame = b.value("label", "");
  }
  for (const auto& name : order) {
    const Acc& a = acc[name];
    PerfEntry e;
    e.name = name;
    e.error = a.error;
    // nightly/<method>/<size>/threads:<n>
    const auto first = name.find('/'), second = name.find('/', first + 1);
    e.method = name.substr(first + 1, second - first - 1);
    e.frame = a.frame;
    e.ratio = median(a.ratio);  // NaN when every repetition failed (e.error says why)
    e.ratio_min = a.ratio.empty() ? NAN : *std::min_element(a.ratio.begin(), a.ratio.end());
    e.ratio_max = a.ratio.empty() ? NAN : *std::max_element(a.ratio.begin(), a.ratio.end());
    e.method_ms = median(a.method_ms);
    e.reference_ms = median(a.reference_ms);
    e.repetitions = int(a.ratio.size());
    s.performance.push_back(e);
  }
}

Summary summarize(const json& results, const std::string& where_results, const json* bench, const std::string& where_bench) {
  Summary s;
  s.date = now_iso();
  if (!results.is_object()) throw InputError(fmt::format("{}: expected a JSON object", where_results));
  if (results.value("format", "") != "denoisebench-results-1")
    throw InputError(fmt::format("{}: key 'format': expected \"denoisebench-results-1\" (a results.json of `denoisebench run`)",
                                 where_results));
  const json config = get<json>(results, "config", where_results);
  s.config = {{"name", config.value("name", "")},
              {"width", config.value("width", 0)},
              {"height", config.value("height", 0)},
              {"spp", config.value("spp", json::array())},
              {"seed", config.value("seed", 0)},
              {"reference_spp", config.value("reference_spp", 0)},
              {"scenes", config.value("scenes", json::array())}};
  s.git_revision = results.value("git_revision", "unknown");
  const json machine = results.value("machine", json::object());
  s.cpu_model = machine.value("cpu", "unknown");
  s.machine = fmt::format("{} ({}, {} threads)", machine.value("hostname", "unknown"), s.cpu_model,
                          machine.value("hardware_threads", 0));
  const json records = get<json>(results, "records", where_results);
  if (!records.is_array()) throw InputError(fmt::format("{}: key 'records': expected an array", where_results));
  std::set<std::tuple<std::string, std::string, int>> seen;
  for (std::size_t i = 0; i < records.size(); ++i) {
    const json& r = records[i];
    const std::string w = fmt::format("{}: records[{}]", where_results, i);
    const std::string role = r.value("role", "");
    if (role != "method" && role != "ablation") continue;  // the input and plain path tracing
    QualityEntry e{get<std::string>(r, "scene", w), get<std::string>(r, "method", w), role, get<int>(r, "spp", w), 0};
    e.mse = get_number(get<json>(r, "metrics", w), "mse", w + ": metrics");
    if (!seen.insert({e.scene, e.method, e.spp}).second)
      throw InputError(fmt::format("{}: a second record for scene {}, method {}, spp {}", w, e.scene, e.method, e.spp));
    s.quality.push_back(e);
  }
  if (s.quality.empty()) throw InputError(fmt::format("{}: no method records", where_results));

  if (bench) add_benchmarks(s, *bench, where_bench);
  return s;
}

Summary summarize_run(const std::string& run_dir) {
  const std::string results_path = run_dir + "/results.json";
  const std::string bench_path = run_dir + "/bench.json";
  const json results = read_json(results_path);
  std::optional<json> bench;
  if (fs::exists(bench_path)) bench = read_json(bench_path);
  return summarize(results, results_path, bench ? &*bench : nullptr, bench_path);
}

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

json Gates::to_json() const {
  return {{"format", "denoisebench-nightly-gates-1"},
          {"quality", {{"metric", "mse"}, {"default_tolerance", quality_default}, {"tolerance", quality}}},
          {"performance", {{"metric", "time_ratio"}, {"default_tolerance", performance_default}, {"tolerance", performance},
                           {"report_only", performance_report_only}}},
          {"ahead", {{"method", ahead_method}, {"of", ahead_of}}},
          {"derivation", derivation}};
}

Gates Gates::from_json(const json& j, const std::string& where) {
  if (!j.is_object() || j.value("format", "") != "denoisebench-nightly-gates-1")
    throw InputError(fmt::format("{}: key 'format': expected \"denoisebench-nightly-gates-1\"", where));
  Gates g;
  auto tolerances = [&](const json& t, const std::string& w, double& def, std::map<std::string, double>& per) {
    def = get_number(t, "default_tolerance", w);
    if (!(def >= 0)) throw InputError(fmt::format("{}: default_tolerance must be >= 0", w));
    const json per_key = t.value("tolerance", json::object());
    if (!per_key.is_object()) throw InputError(fmt::format("{}: key 'tolerance': expected an object", w));
    for (const auto& [k, v] : per_key.items()) {
      if (!v.is_number() || v.get<double>() < 0)
        throw InputError(fmt::format("{}: tolerance of '{}' must be a number >= 0", w, k));
      per[k] = v.get<double>();
    }
  };
  tolerances(get<json>(j, "quality", where), where + ": quality", g.quality_default, g.quality);
  const json perf = get<json>(j, "performance", where);
  tolerances(perf, where + ": performance", g.performance_default, g.performance);
  if (perf.contains("report_only")) g.performance_report_only = get<std::vector<std::string>>(perf, "report_only", where + ": performance");
  const json ahead = get<json>(j, "ahead", where);
  g.ahead_method = get<std::string>(ahead, "method", where + ": ahead");
  g.ahead_of = get<std::vector<std::string>>(ahead, "of", where + ": ahead");
  g.derivation = j.value("derivation", json::object());
  return g;
}

// ---------------------------------------------------------------------------------------------
// Check

int Verdict::failures() const {
  return int(std::count_if(findings.begin(), findings.end(), [](const Finding& f) { return f.failed; }));
}

json Verdict::to_json() const {
  json f = json::array(), failed = json::array();
  for (const auto& x : findings) {
    json e = {{"gate", x.gate},         {"scene", x.scene},         {"method", x.method},
              {"metric", x.metric},     {"old", x.old_value},       {"new", x.new_value},
              {"limit", x.limit},       {"failed", x.failed},       {"message", x.message}};
    if (!x.compared_with.empty()) e["compared_with"] = x.compared_with;
    if (x.report_only) e["report_only"] = true;
    for (const char* k : {"old", "new", "limit"})
      if (!std::isfinite(e[k].get<double>())) e[k] = nullptr;
    (x.failed ? failed : f).push_back(e);
  }
  return {{"format", "denoisebench-nightly-verdict-1"},
          {"passed", passed()},
          {"failures", failed},
          {"checks", f},
          {"performance_checked", performance_checked},
          {"notes", notes}};
}

std::string Verdict::markdown(const Summary& baseline, const Summary& current) const {
  std::string o = fmt::format("# Nightly check: {}\n\n", passed() ? "PASS" : fmt::format("FAIL ({} regressions)", failures()));
  o += fmt::format("- run: {}, revision {}, {}\n", current.date, current.git_revision, current.machine);
  o += fmt::format("- baseline: {}, revision {}, {}\n", baseline.date, baseline.git_revision, baseline.machine);
  o += fmt::format("- config: {}\n", current.config.dump());
  if (!current.reference_workload.empty()) o += fmt::format("- reference workload: {}\n", current.reference_workload);
  if (!passed()) {
    o += "\n## Regressions\n\n";
    for (const auto& f : findings)
      if (f.failed) o += "- " + f.message + "\n";
  }
  if (!notes.empty()) {
    o += "\n## Notes\n\n";
    for (const auto& n : notes) o += "- " + n + "\n";
  }
  auto table = [&](const std::string& gate, const std::string& title) {
    std::string t;
    for (const auto& f : findings) {
      if (f.gate != gate) continue;
      const double rel = f.new_value / f.old_value - 1.0;
      if (gate == "ahead")
        t += fmt::format("| {} | {} vs {} | {} | {} | {} |\n", f.scene, f.method, f.compared_with, fmt_value(f.new_value),
                         fmt_value(f.limit), f.failed ? "**FAIL**" : "ok");
      else
        t += fmt::format("| {} | {} | {} | {} | {} | {} | {} |\n", f.scene, f.method, fmt_value(f.old_value),
                         fmt_value(f.new_value), std::isfinite(rel) ? percent(rel) : "-",
                         percent(f.limit / f.old_value - 1.0),
                         f.failed                                          ? "**FAIL**"
                         : f.report_only && !(f.new_value <= f.limit)      ? "over (report only)"
                         : f.report_only                                   ? "ok (report only)"
                                                                           : "ok");
    }
    if (t.empty()) return;
    o += "\n## " + title + "\n\n";
    if (gate == "ahead")
      o += "| scene | methods | MSE | baseline method's MSE | |\n|---|---|---:|---:|---|\n";
    else
      o += fmt::format("| {} | method | baseline | new | change | tolerance | |\n|---|---|---:|---:|---:|---:|---|\n",
                       gate == "performance" ? "case (frame)" : "scene");
    o += t;
  };
  table("quality", "Quality (MSE, 8-bit)");
  table("ahead", "Ahead (MSE must be lower)");
  table("performance", "Performance (time / reference workload)");
  return o;
}

Verdict check(const Summary& baseline, const Summary& current, const Gates& gates, const CheckOptions& options) {
  Verdict v;
  // The run must be of the config the baseline was accepted from.
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

  // Quality.
  std::map<std::tuple<std::string, std::string, int>, const QualityEntry*> now;
  for (const auto& e : current.quality) now[{e.scene, e.method, e.spp}] = &e;
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
                            old.method, f.failed ? "rose" : "went", fmt_value(old.mse), fmt_value(cur.mse),
                            std::isfinite(cur.mse) ? percent(cur.mse / old.mse - 1.0) : "non-finite", 100.0 * tol);
    v.findings.push_back(f);
  }
  for (const auto& e : current.quality)
    if (!in_baseline.count({e.scene, e.method, e.spp}))
      v.notes.push_back(fmt::format("scene {}, method {}: new in this run, no baseline (not gated)", e.scene, e.method));

  // Ahead.
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
                                fmt_value(a), f.failed ? "not below" : "below", other, fmt_value(b));
        v.findings.push_back(f);
      }
    }
  }

  // Performance.
  if (!options.performance) {
    v.notes.push_back("performance gate not run (asked for quality only)");
  } else {
    if (baseline.performance.empty()) {
      if (options.require_performance) throw InputError("the baseline has no benchmark results: accept a run with bench.json");
      v.notes.push_back("performance gate skipped: the baseline has no benchmark results (accept a run with bench.json)");
    } else if (current.performance.empty()) {
      throw InputError("the run has no nightly benchmark results (RUN_DIR/bench.json with nightly/ cases); the baseline has");
    } else if (baseline.cpu_model != current.cpu_model) {
      const std::string why = fmt::format("the baseline's ratios were measured on '{}', this run on '{}'", baseline.cpu_model,
                                          current.cpu_model);
      if (options.require_performance) throw InputError("performance gate: " + why + " (accept a baseline on this machine)");
      v.notes.push_back("performance gate skipped: " + why + "; accept a baseline on this machine to gate speed here");
    } else {
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
                                f.scene, old.method, over ? "rose" : "went", fmt_value(old.ratio), fmt_value(cur.ratio),
                                percent(cur.ratio / old.ratio - 1.0), 100.0 * tol, cur.method_ms, cur.reference_ms);
        if (!cur.error.empty())
          f.message = fmt::format("performance: case {}, method {}, time_ratio was {}, now the case fails: {}", f.scene,
                                  old.method, fmt_value(old.ratio), cur.error);
        if (over && f.report_only) v.notes.push_back("over its tolerance, reported only (not gated): " + f.message);
        v.findings.push_back(f);
      }
      std::set<std::string> old_names;
      for (const auto& e : baseline.performance) old_names.insert(e.name);
      for (const auto& e : current.performance)
        if (!old_names.count(e.name)) v.notes.push_back(fmt::format("benchmark case {}: new in this run, no baseline (not gated)", e.name));
    }
  }
  return v;
}

// ---------------------------------------------------------------------------------------------
// Tolerances from measured noise

namespace {

// The default ahead rule for a run: `proposed` ahead of every other non-ablation filter in it
// (no rule when the run has no `proposed`). Renderer-type methods (the irradiance cache) are
// left out: they render the scene with their own sample budget, not the run's input frame, so
// at the nightly's 16 spp the comparison says nothing about the filter (the irradiance cache
// against `proposed` is issue 7's comparison, at the paper's setting).
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

}  // namespace

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
      const double tol = std::max({o.quality_k * relative_std(values), range(values), o.quality_floor});
      spread[key.second][key.first] = {{"relative_std", relative_std(values)}, {"max_over_min", range(values) + 1}, {"mse", values}};
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
      const double rs = relative_std(values);
      spread[name] = {{"relative_std", rs}, {"max_over_min", range(values) + 1}, {"time_ratio", values}};
      g.performance[name] = std::max({o.performance_k * rs, range(values), o.performance_floor});
      largest = std::max(largest, g.performance[name]);
    }
    g.performance_default = std::max(largest, o.performance_floor);
    d["performance"] = {{"rule", fmt::format("tolerance(case) = max({} * relative standard deviation of the case's ratio "
                                             "across runs, max/min - 1 of the ratio across runs, {}); default: the largest",
                                             o.performance_k, o.performance_floor)},
                        {"runs", perf_names}, {"machine", perf_runs.front().machine},
                        {"cpu_model", perf_runs.front().cpu_model}, {"spread", spread}};
  }
  d["derived"] = now_iso();
  g.derivation = d;
  return g;
}

// ---------------------------------------------------------------------------------------------
// History

namespace {

std::vector<std::string> split_csv_line(const std::string& line) {
  std::vector<std::string> out;
  std::string cur;
  bool quoted = false;
  for (std::size_t i = 0; i < line.size(); ++i) {
    const char ch = line[i];
    if (quoted) {
      if (ch == '"' && i + 1 < line.size() && line[i + 1] == '"') {
        cur += '"';
        ++i;
      } else if (ch == '"') {
        quoted = false;
      } else {
        cur += ch;
      }
    } else if (ch == '"') {
      quoted = true;
    } else if (ch == ',') {
      out.push_back(cur);
      cur.clear();
    } else {
      cur += ch;
    }
  }
  out.push_back(cur);
  return out;
}

std::string csv_field(const std::string& s) {
  if (s.find_first_of(",\"\n") == std::string::npos) return s;
  std::string q = "\"";
  for (char ch : s) q += ch == '"' ? std::string("\"\"") : std::string(1, ch);
  return q + "\"";
}

}  // namespace

void append_history(const std::string& path, const Summary& current, const Verdict& verdict) {
  const std::vector<std::string> fixed = {"date", "git_revision", "machine", "config", "verdict", "failures", "failed_checks"};
  std::vector<std::string> header = fixed;
  std::vector<std::map<std::string, std::string>> rows;
  if (fs::exists(path)) {
    std::istringstream in(read_text_file(path));
    std::string line;
    if (std::getline(in, line) && !line.empty()) {
      header = split_csv_line(line);
      for (const auto& f : fixed)
        if (std::find(header.begin(), header.end(), f) == header.end())
          throw InputError(fmt::format("'{}': line 1: not a nightly history (no column '{}')", path, f));
      int n = 1;
      while (std::getline(in, line)) {
        ++n;
        if (line.empty()) continue;
        const auto cells = split_csv_line(line);
        if (cells.size() != header.size())
          throw InputError(fmt::format("'{}': line {}: {} fields, the header has {}", path, n, cells.size(), header.size()));
        std::map<std::string, std::string> row;
        for (std::size_t i = 0; i < cells.size(); ++i) row[header[i]] = cells[i];
        rows.push_back(row);
      }
    }
  }
  std::map<std::string, std::string> row;
  row["date"] = current.date;
  row["git_revision"] = current.git_revision;
  row["machine"] = current.machine;
  row["config"] = fmt::format("{} {}x{}", current.config.value("name", ""), current.config.value("width", 0),
                              current.config.value("height", 0));
  row["verdict"] = verdict.passed() ? "pass" : "fail";
  row["failures"] = std::to_string(verdict.failures());
  std::string failed;
  for (const auto& f : verdict.findings)
    if (f.failed) failed += (failed.empty() ? "" : "; ") + f.gate + " " + f.scene + " " + f.method;
  row["failed_checks"] = failed;
  for (const auto& e : current.quality) row[fmt::format("mse/{}/{}", e.scene, e.method)] = fmt::format("{:.9g}", e.mse);
  for (const auto& e : current.performance) row["ratio/" + e.name] = fmt::format("{:.6g}", e.ratio);
  for (const auto& [k, _] : row)
    if (std::find(header.begin(), header.end(), k) == header.end()) header.push_back(k);
  rows.push_back(row);
  std::string out;
  auto line = [&](const auto& cell) {
    for (std::size_t i = 0; i < header.size(); ++i) {
      if (i) out += ',';
      out += csv_field(cell(i));
    }
    out += '\n';
  };
  line([&](std::size_t i) { return header[i]; });
  for (const auto& r : rows)
    line([&](std::size_t i) {
      auto it = r.find(header[i]);
      return it == r.end() ? std::string() : it->second;
    });
  if (!fs::path(path).parent_path().empty()) fs::create_directories(fs::path(path).parent_path());
  write_text_atomic(path, out);
}

// ---------------------------------------------------------------------------------------------
// Folders

namespace {

Summary load_baseline(const std::string& baseline_dir) {
  const std::string path = baseline_dir + "/baseline.json";
  if (!fs::exists(path))
    throw InputError(fmt::format("'{}': no baseline; make one deliberately with `denoisebench nightly accept RUN_DIR "
                                 "--baseline {}` (or `.ci/nightly --accept`)",
                                 path, baseline_dir));
  return Summary::from_json(read_json(path), path);
}

Gates load_gates(const std::string& baseline_dir) {
  const std::string path = baseline_dir + "/gates.json";
  return Gates::from_json(read_json(path), path);
}

}  // namespace

RunCheck check_run(const std::string& run_dir, const std::string& baseline_dir, const std::string& history,
                   const CheckOptions& options, const std::string& git_revision) {
  const Summary baseline = load_baseline(baseline_dir);
  const Gates gates = load_gates(baseline_dir);
  RunCheck r{summarize_run(run_dir), {}};
  if (!git_revision.empty()) r.current.git_revision = git_revision;
  r.verdict = check(baseline, r.current, gates, options);
  write_text_atomic(run_dir + "/summary.json", r.current.to_json().dump(2) + "\n");
  json v = r.verdict.to_json();
  v["run"] = run_dir;
  v["baseline"] = baseline_dir;
  v["date"] = r.current.date;
  v["git_revision"] = r.current.git_revision;
  write_text_atomic(run_dir + "/verdict.json", v.dump(2) + "\n");
  write_text_atomic(run_dir + "/verdict.md", r.verdict.markdown(baseline, r.current));
  if (!history.empty()) append_history(history, r.current, r.verdict);
  return r;
}

Summary accept_run(const std::string& run_dir, const std::string& baseline_dir, const std::string& git_revision) {
  Summary s = summarize_run(run_dir);
  if (!git_revision.empty()) {
    s.git_revision = git_revision;
  } else if (fs::exists(run_dir + "/summary.json")) {
    s.git_revision = Summary::from_json(read_json(run_dir + "/summary.json"), run_dir + "/summary.json").git_revision;
  }
  fs::create_directories(baseline_dir);
  const std::string gates_path = baseline_dir + "/gates.json";
  if (!fs::exists(gates_path)) {
    Gates g;
    default_ahead(g, s);
    g.derivation = {{"note", "defaults written by accept; derive tolerances from measured noise with "
                             "`denoisebench nightly tolerances`"}};
    write_text_atomic(gates_path, g.to_json().dump(2) + "\n");
  } else {
    load_gates(baseline_dir);  // refuse to accept next to a malformed gates file
  }
  json j = s.to_json();
  j["accepted"] = now_iso();
  j["accepted_from"] = run_dir;
  write_text_atomic(baseline_dir + "/baseline.json", j.dump(2) + "\n");
  return s;
}

}  // namespace dnb::nightly
