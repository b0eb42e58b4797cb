// The nightly's file formats (experiment/nightly.h): summaries, gates and verdicts as JSON, the
// verdict as Markdown, Google Benchmark's JSON, and the CSV history. The gate logic itself is
// in nightly_gates.cpp, the folder operations in nightly_folder.cpp.
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <map>
#include <set>
#include <sstream>
#include <tuple>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "core/atomic_file.h"
#include "core/csv.h"
#include "core/errors.h"
#include "core/json_file.h"
#include "core/stats.h"
#include "core/timer.h"
#include "experiment/nightly.h"

namespace fs = std::filesystem;
using nlohmann::json;

namespace dnb::nightly {

namespace {

// Case name without the suffix Google Benchmark adds for the timing mode.
std::string case_name(std::string name) {
  for (const char* suffix : {"/manual_time", "/real_time", "/process_time"}) {
    const std::string s = suffix;
    if (name.size() > s.size() && name.compare(name.size() - s.size(), s.size(), s) == 0) name.resize(name.size() - s.size());
  }
  return name;
}

// The method of a nightly case name, nightly/<method>/<size>/threads:<n>.
std::string method_of_case(const std::string& name) {
  const auto first = name.find('/'), second = name.find('/', first + 1);
  return name.substr(first + 1, second - first - 1);
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
  json ins = json::array();
  for (const auto& e : instructions)
    ins.push_back({{"case", e.name}, {"method", e.method}, {"instructions", e.instructions}});
  return {{"format", "denoisebench-nightly-summary-1"},
          {"date", date},
          {"git_revision", git_revision},
          {"machine", machine},
          {"cpu_model", cpu_model},
          {"config", config},
          {"reference_workload", reference_workload},
          {"quality", q},
          {"performance", p},
          {"instructions", ins},
          {"instructions_cpu_model", instructions_cpu_model}};
}

Summary Summary::from_json(const json& j, const std::string& where) {
  if (!j.is_object()) throw InputError(fmt::format("{}: expected a JSON object", where));
  if (j.value("format", "") != "denoisebench-nightly-summary-1")
    throw InputError(fmt::format("{}: key 'format': expected \"denoisebench-nightly-summary-1\"", where));
  Summary s;
  s.date = json_file::get<std::string>(j, "date", where);
  s.git_revision = json_file::get<std::string>(j, "git_revision", where);
  s.machine = json_file::get<std::string>(j, "machine", where);
  s.cpu_model = json_file::get<std::string>(j, "cpu_model", where);
  s.config = j.value("config", json::object());
  s.reference_workload = j.value("reference_workload", "");
  const auto q = json_file::get<json>(j, "quality", where);
  if (!q.is_array()) throw InputError(fmt::format("{}: key 'quality': expected an array", where));
  for (std::size_t i = 0; i < q.size(); ++i) {
    const std::string w = fmt::format("{}: quality[{}]", where, i);
    s.quality.push_back({json_file::get<std::string>(q[i], "scene", w), json_file::get<std::string>(q[i], "method", w),
                         q[i].value("role", "method"), json_file::get<int>(q[i], "spp", w), json_file::number(q[i], "mse", w)});
  }
  const auto p = json_file::get<json>(j, "performance", where);
  if (!p.is_array()) throw InputError(fmt::format("{}: key 'performance': expected an array", where));
  for (std::size_t i = 0; i < p.size(); ++i) {
    const std::string w = fmt::format("{}: performance[{}]", where, i);
    PerfEntry e;
    e.name = json_file::get<std::string>(p[i], "case", w);
    e.method = json_file::get<std::string>(p[i], "method", w);
    e.frame = p[i].value("frame", "");
    e.ratio = json_file::number(p[i], "time_ratio", w);
    e.ratio_min = json_file::number_or(p[i], "time_ratio_min", e.ratio, w);
    e.ratio_max = json_file::number_or(p[i], "time_ratio_max", e.ratio, w);
    e.method_ms = json_file::number_or(p[i], "method_ms", NAN, w);
    e.reference_ms = json_file::number_or(p[i], "reference_ms", NAN, w);
    e.repetitions = p[i].value("repetitions", 0);
    e.error = p[i].value("error", "");
    s.performance.push_back(e);
  }
  // Optional: summaries written before the instruction gate have none.
  if (j.contains("instructions")) {
    const auto ins = json_file::get<json>(j, "instructions", where);
    if (!ins.is_array()) throw InputError(fmt::format("{}: key 'instructions': expected an array", where));
    for (std::size_t i = 0; i < ins.size(); ++i) {
      const std::string w = fmt::format("{}: instructions[{}]", where, i);
      s.instructions.push_back({json_file::get<std::string>(ins[i], "case", w),
                                json_file::get<std::string>(ins[i], "method", w), json_file::number(ins[i], "instructions", w)});
    }
    s.instructions_cpu_model = j.value("instructions_cpu_model", "");
  }
  return s;
}

void add_benchmarks(Summary& s, const json& bench, const std::string& where_bench) {
  if (!bench.is_object()) throw InputError(fmt::format("{}: expected a JSON object", where_bench));
  const json context = json_file::get<json>(bench, "context", where_bench);
  s.cpu_model = context.value("cpu_model", s.cpu_model);
  s.reference_workload = context.value("nightly_reference_workload", "");
  const json runs = json_file::get<json>(bench, "benchmarks", where_bench);
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
    const std::string name = case_name(b.value("run_name", json_file::get<std::string>(b, "name", w)));
    if (name.rfind("nightly/", 0) != 0) continue;
    if (!acc.count(name)) order.push_back(name);
    Acc& a = acc[name];
    if (b.value("error_occurred", false)) {
      a.error = b.value("error_message", "error");
      continue;
    }
    a.ratio.push_back(json_file::number(b, "ratio", w));
    a.method_ms.push_back(json_file::number_or(b, "method_ms", NAN, w));
    a.reference_ms.push_back(json_file::number_or(b, "reference_ms", NAN, w));
    a.frame = b.value("label", "");
  }
  for (const auto& name : order) {
    const Acc& a = acc[name];
    PerfEntry e;
    e.name = name;
    e.error = a.error;
    e.method = method_of_case(name);
    e.frame = a.frame;
    e.ratio = stats::median(a.ratio);  // NaN when every repetition failed (e.error says why)
    e.ratio_min = a.ratio.empty() ? NAN : *std::min_element(a.ratio.begin(), a.ratio.end());
    e.ratio_max = a.ratio.empty() ? NAN : *std::max_element(a.ratio.begin(), a.ratio.end());
    e.method_ms = stats::median(a.method_ms);
    e.reference_ms = stats::median(a.reference_ms);
    e.repetitions = int(a.ratio.size());
    s.performance.push_back(e);
  }
}

void add_instructions(Summary& s, const json& doc, const std::string& where) {
  if (!doc.is_object() || doc.value("format", "") != "denoisebench-instructions-1")
    throw InputError(fmt::format("{}: key 'format': expected \"denoisebench-instructions-1\"", where));
  const json context = json_file::get<json>(doc, "context", where);
  s.instructions_cpu_model = json_file::get<std::string>(context, "cpu_model", where + ": context");
  const json cases = json_file::get<json>(doc, "cases", where);
  if (!cases.is_array() || cases.empty())
    throw InputError(fmt::format("{}: key 'cases': expected a non-empty array", where));
  for (std::size_t i = 0; i < cases.size(); ++i) {
    const std::string w = fmt::format("{}: cases[{}]", where, i);
    InstrEntry e;
    e.name = json_file::get<std::string>(cases[i], "name", w);
    if (e.name.rfind("nightly/", 0) != 0 || std::count(e.name.begin(), e.name.end(), '/') < 3)
      throw InputError(fmt::format("{}: key 'name': expected nightly/<method>/<size>/threads:<n>, got '{}'", w, e.name));
    e.method = method_of_case(e.name);
    e.instructions = json_file::number(cases[i], "instructions", w);
    if (!(e.instructions > 0)) throw InputError(fmt::format("{}: key 'instructions': expected a positive count", w));
    s.instructions.push_back(e);
  }
}

Summary summarize(const experiment::ResultsDocument& results, const std::string& where_results, const json* bench,
                  const std::string& where_bench) {
  Summary s;
  s.date = utc_now_iso();
  const experiment::RunConfig& config = results.config;
  s.config = {{"name", config.name},   {"width", config.width}, {"height", config.height},
              {"spp", config.spp},     {"seed", config.seed},   {"reference_spp", config.reference_spp},
              {"scenes", config.scenes}};
  s.git_revision = results.git_revision.empty() ? "unknown" : results.git_revision;
  const json& machine = results.machine;
  s.cpu_model = machine.value("cpu", "unknown");
  s.machine = fmt::format("{} ({}, {} threads)", machine.value("hostname", "unknown"), s.cpu_model,
                          machine.value("hardware_threads", 0));
  if (config.seeds.size() > 1) s.config["seeds"] = config.seeds;
  // Several input seeds (config `seeds`): a cell's entry is the mean of its seeds' MSE, so the
  // gates compare like with like; one seed twice for a cell is a malformed file.
  std::map<std::tuple<std::string, std::string, int>, std::size_t> entry_of;
  std::set<std::tuple<std::string, std::string, int, std::uint64_t>> seen;
  std::vector<int> seeds_in;
  for (std::size_t i = 0; i < results.records.size(); ++i) {
    const experiment::CellRecord& r = results.records[i];
    if (!experiment::is_method_role(r.role)) continue;  // the input and plain path tracing
    const std::string w = fmt::format("{}: records[{}]", where_results, i);
    const auto mse = r.metrics.find("mse");
    if (mse == r.metrics.end()) throw InputError(fmt::format("{}: metrics: missing key 'mse'", w));
    const double value = mse->second ? *mse->second : NAN;
    if (!seen.insert({r.scene, r.method, r.spp, r.seed.value_or(0)}).second)
      throw InputError(fmt::format("{}: a second record for scene {}, method {}, spp {}{}", w, r.scene, r.method, r.spp,
                                   r.seed ? fmt::format(", seed {}", *r.seed) : std::string()));
    const auto key = std::make_tuple(r.scene, r.method, r.spp);
    if (auto it = entry_of.find(key); it != entry_of.end()) {
      s.quality[it->second].mse += value;  // NaN stays NaN: a non-finite seed fails the gate
      ++seeds_in[it->second];
      continue;
    }
    entry_of[key] = s.quality.size();
    s.quality.push_back({r.scene, r.method, experiment::to_string(r.role), r.spp, value});
    seeds_in.push_back(1);
  }
  for (std::size_t k = 0; k < s.quality.size(); ++k) s.quality[k].mse /= seeds_in[k];
  if (s.quality.empty()) throw InputError(fmt::format("{}: no method records", where_results));

  if (bench) add_benchmarks(s, *bench, where_bench);
  return s;
}

Summary summarize_run(const std::string& run_dir) {
  const std::string results_path = run_dir + "/results.json";
  const std::string bench_path = run_dir + "/bench.json";
  const auto results = experiment::ResultsDocument::load(results_path);
  std::optional<json> bench;
  if (fs::exists(bench_path)) bench = json_file::read(bench_path);
  Summary s = summarize(results, "'" + results_path + "'", bench ? &*bench : nullptr, bench_path);
  const std::string instr_path = run_dir + "/instructions.json";
  if (fs::exists(instr_path)) add_instructions(s, json_file::read(instr_path), "'" + instr_path + "'");
  return s;
}

json Gates::to_json() const {
  return {{"format", "denoisebench-nightly-gates-1"},
          {"quality", {{"metric", "mse"}, {"default_tolerance", quality_default}, {"tolerance", quality}}},
          {"performance", {{"metric", "time_ratio"}, {"default_tolerance", performance_default}, {"tolerance", performance},
                           {"report_only", performance_report_only}}},
          {"instructions", {{"metric", "instructions"}, {"default_tolerance", instructions_default}}},
          {"ahead", {{"method", ahead_method}, {"of", ahead_of}}},
          {"derivation", derivation}};
}

Gates Gates::from_json(const json& j, const std::string& where) {
  if (!j.is_object() || j.value("format", "") != "denoisebench-nightly-gates-1")
    throw InputError(fmt::format("{}: key 'format': expected \"denoisebench-nightly-gates-1\"", where));
  Gates g;
  auto tolerances = [&](const json& t, const std::string& w, double& def, std::map<std::string, double>& per) {
    def = json_file::number(t, "default_tolerance", w);
    if (!(def >= 0)) throw InputError(fmt::format("{}: default_tolerance must be >= 0", w));
    const json per_key = t.value("tolerance", json::object());
    if (!per_key.is_object()) throw InputError(fmt::format("{}: key 'tolerance': expected an object", w));
    for (const auto& [k, v] : per_key.items()) {
      if (!v.is_number() || v.get<double>() < 0)
        throw InputError(fmt::format("{}: tolerance of '{}' must be a number >= 0", w, k));
      per[k] = v.get<double>();
    }
  };
  tolerances(json_file::get<json>(j, "quality", where), where + ": quality", g.quality_default, g.quality);
  const json perf = json_file::get<json>(j, "performance", where);
  tolerances(perf, where + ": performance", g.performance_default, g.performance);
  if (perf.contains("report_only")) g.performance_report_only = json_file::get<std::vector<std::string>>(perf, "report_only", where + ": performance");
  if (j.contains("instructions"))  // optional: gates written before the instruction gate
    g.instructions_default =
        json_file::number(json_file::get<json>(j, "instructions", where), "default_tolerance", where + ": instructions");
  const json ahead = json_file::get<json>(j, "ahead", where);
  g.ahead_method = json_file::get<std::string>(ahead, "method", where + ": ahead");
  g.ahead_of = json_file::get<std::vector<std::string>>(ahead, "of", where + ": ahead");
  g.derivation = j.value("derivation", json::object());
  return g;
}

// ---------------------------------------------------------------------------------------------
// Verdicts

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
        t += fmt::format("| {} | {} vs {} | {} | {} | {} |\n", f.scene, f.method, f.compared_with, format_value(f.new_value),
                         format_value(f.limit), f.failed ? "**FAIL**" : "ok");
      else
        t += fmt::format("| {} | {} | {} | {} | {} | {} | {} |\n", f.scene, f.method, format_value(f.old_value),
                         format_value(f.new_value), std::isfinite(rel) ? format_percent(rel) : "-",
                         format_percent(f.limit / f.old_value - 1.0),
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
                       gate == "performance" ? "case (frame)" : gate == "instructions" ? "case" : "scene");
    o += t;
  };
  table("quality", "Quality (MSE, 8-bit)");
  table("ahead", "Ahead (MSE must be lower)");
  table("performance", "Performance (time / reference workload)");
  table("instructions", "Instructions (one run, callgrind)");
  return o;
}

// ---------------------------------------------------------------------------------------------
// History

void append_history(const std::string& path, const Summary& current, const Verdict& verdict) {
  const std::vector<std::string> fixed = {"date", "git_revision", "machine", "config", "verdict", "failures", "failed_checks"};
  std::vector<std::string> header = fixed;
  std::vector<std::map<std::string, std::string>> rows;
  if (fs::exists(path)) {
    std::istringstream in(read_text_file(path));
    std::string line;
    if (std::getline(in, line) && !line.empty()) {
      header = csv::split(line);
      for (const auto& f : fixed)
        if (std::find(header.begin(), header.end(), f) == header.end())
          throw InputError(fmt::format("'{}': line 1: not a nightly history (no column '{}')", path, f));
      int n = 1;
      while (std::getline(in, line)) {
        ++n;
        if (line.empty()) continue;
        const auto cells = csv::split(line);
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
  for (const auto& e : current.instructions) row["instructions/" + e.name] = fmt::format("{:.0f}", e.instructions);
  for (const auto& [k, _] : row)
    if (std::find(header.begin(), header.end(), k) == header.end()) header.push_back(k);
  rows.push_back(row);
  std::string out;
  auto line = [&](const auto& cell) {
    for (std::size_t i = 0; i < header.size(); ++i) {
      if (i) out += ',';
      out += csv::field(cell(i));
    }
    out += '\n';
  };
  line([&](std::size_t i) { return header[i]; });
  for (const auto& r : rows)
    line([&](std::size_t i) {
      auto it = r.find(header[i]);
      return it == r.end() ? std::string() : it->second;
    });
  if (!fs::path(path).parent_path().empty()) create_folder(fs::path(path).parent_path().string());
  write_text_atomic(path, out);
}

std::string format_value(double v) { return std::isfinite(v) ? fmt::format("{:.6g}", v) : std::string("non-finite"); }

std::string format_percent(double relative) { return fmt::format("{:+.1f}%", 100.0 * relative); }

}  // namespace dnb::nightly
