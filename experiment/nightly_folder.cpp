// The nightly's folder operations (experiment/nightly.h): read a run folder and a baseline
// folder, check, accept, and derive tolerances from repeated runs' files.
#include <filesystem>

#include <fmt/format.h>

#include "core/atomic_file.h"
#include "core/errors.h"
#include "core/json_file.h"
#include "core/timer.h"
#include "experiment/nightly.h"

namespace fs = std::filesystem;
using nlohmann::json;

namespace dnb::nightly {

// ---------------------------------------------------------------------------------------------
// Folders

namespace {

Summary load_baseline(const std::string& baseline_dir) {
  const std::string path = baseline_dir + "/baseline.json";
  if (!fs::exists(path))
    throw InputError(fmt::format("'{}': no baseline; make one deliberately with `denoisebench nightly accept RUN_DIR "
                                 "--baseline {}` (or `.ci/nightly --accept`)",
                                 path, baseline_dir));
  return Summary::from_json(json_file::read(path), path);
}

Gates load_gates(const std::string& baseline_dir) {
  const std::string path = baseline_dir + "/gates.json";
  return Gates::from_json(json_file::read(path), path);
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
    s.git_revision = Summary::from_json(json_file::read(run_dir + "/summary.json"), run_dir + "/summary.json").git_revision;
  }
  create_folder(baseline_dir);
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
  j["accepted"] = utc_now_iso();
  j["accepted_from"] = run_dir;
  write_text_atomic(baseline_dir + "/baseline.json", j.dump(2) + "\n");
  return s;
}

std::vector<Finding> self_check(const Summary& accepted, const std::string& baseline_dir) {
  CheckOptions quality_only;
  quality_only.performance = false;
  std::vector<Finding> failed;
  for (const auto& f : check(accepted, accepted, load_gates(baseline_dir), quality_only).findings)
    if (f.failed) failed.push_back(f);
  return failed;
}

Gates derive_tolerances(const std::vector<std::string>& quality_dirs, const std::vector<std::string>& perf_files,
                        const std::string& baseline_dir, const DeriveOptions& options) {
  if (quality_dirs.empty() && perf_files.empty()) throw InputError("nightly tolerances: give --quality and/or --perf runs");
  std::vector<Summary> q, p;
  for (const auto& dir : quality_dirs) {
    const std::string path = dir + "/results.json";
    q.push_back(summarize(experiment::ResultsDocument::load(path), "'" + path + "'", nullptr, ""));
  }
  for (const auto& file : perf_files) {
    Summary s;
    add_benchmarks(s, json_file::read(file), file);
    if (s.performance.empty()) throw InputError(fmt::format("'{}': no nightly/ benchmark cases", file));
    p.push_back(s);
  }
  const std::string gates_path = baseline_dir + "/gates.json";
  Gates previous;
  if (fs::exists(gates_path)) previous = Gates::from_json(json_file::read(gates_path), gates_path);
  const Gates g = derive_gates(q, quality_dirs, p, perf_files, previous, options);
  create_folder(baseline_dir);
  json_file::write(gates_path, g.to_json());
  return g;
}

}  // namespace dnb::nightly
