// The nightly quality and performance gates (`denoisebench nightly`, `.ci/nightly`).
//
// A nightly run folder holds the experiment's results.json (`denoisebench run`) and the
// benchmark program's bench.json (denoisebench_bench, nightly/ cases). Its *summary* keeps only
// what the gates compare: each (scene, method, spp)'s MSE, and each nightly benchmark case's
// time ratio (the method's time divided by the reference workload timed beside it, the median
// over repetitions). The baseline folder (reports/baseline/) holds an accepted summary
// (baseline.json, written only by `accept`) and the gate settings (gates.json: tolerances
// derived from measured noise, and which methods `proposed` must stay ahead of).
//
// Gates, each failure naming the scene, method, metric, old and new values:
//   quality      new MSE <= baseline MSE * (1 + tolerance of the method)
//   ahead        the leading method's MSE < every listed baseline method's MSE, per scene
//   performance  new ratio <= baseline ratio * (1 + tolerance of the case); run only when
//                the baseline was measured on the same CPU model (else skipped, with a note);
//                cases listed as report-only (all-core wall times) are shown, never failing
//   instructions new count <= baseline count * (1 + tolerance): the instructions of one run of
//                each method (single-threaded, under callgrind: scripts/nightly_instructions,
//                RUN_DIR/instructions.json), which do not move with the machine's load as wall
//                times do; same CPU model only, skipped with a note when either side has none
//
// Bad input (a missing or malformed file, a scene, method or case of the baseline missing
// from the run, a run of another config) is an InputError: exit status 2.
#pragma once

#include <map>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "experiment/results.h"

namespace dnb::nightly {

// How findings and verdicts print a value ("non-finite" for NaN/Inf) and a relative change.
std::string format_value(double v);
std::string format_percent(double relative);

struct QualityEntry {
  std::string scene, method, role;  // role: "method" or "ablation"
  int spp = 0;
  double mse = 0;
};

struct PerfEntry {
  std::string name;    // the benchmark case, e.g. nightly/guided/256x192/threads:1
  std::string method;  // e.g. guided, or proposed:opencl
  std::string frame;   // the benchmark's label, e.g. "cornell-box 256x192 16spp"
  double ratio = 0;    // median over repetitions of the case's ratio counter
  double ratio_min = 0, ratio_max = 0;  // over repetitions
  double method_ms = 0, reference_ms = 0;
  int repetitions = 0;
  std::string error;   // the benchmark's error when the case failed (ratio is then NaN)
};

// One case of scripts/nightly_instructions: the instructions of one run of the method.
struct InstrEntry {
  std::string name;    // the benchmark case, e.g. nightly/guided/64x48/threads:1
  std::string method;
  double instructions = 0;
};

struct Summary {
  std::string date;          // ISO 8601 UTC, when summarised
  std::string git_revision;
  std::string machine;       // "hostname (cpu model, N threads)"
  std::string cpu_model;     // of the benchmark run (the performance gate's machine identity)
  nlohmann::json config;     // name, width, height, spp, seed, reference_spp, scenes
  std::vector<QualityEntry> quality;
  std::vector<PerfEntry> performance;
  std::string reference_workload;
  std::vector<InstrEntry> instructions;  // empty when the run counted none
  std::string instructions_cpu_model;    // the machine that counted them

  nlohmann::json to_json() const;
  static Summary from_json(const nlohmann::json& j, const std::string& where);
};

// The summary of a results document (results.json of `denoisebench run`) and, optionally, a
// Google Benchmark JSON document with nightly/ cases. `where_*` name the files in errors.
Summary summarize(const experiment::ResultsDocument& results, const std::string& where_results,
                  const nlohmann::json* bench, const std::string& where_bench);
// Adds the nightly/ cases of a Google Benchmark JSON document to `s` (the median of each case's
// `ratio` counter over its repetitions) and takes the CPU model from its context.
void add_benchmarks(Summary& s, const nlohmann::json& bench, const std::string& where_bench);
// Adds the cases of scripts/nightly_instructions' JSON document to `s`.
void add_instructions(Summary& s, const nlohmann::json& doc, const std::string& where);
// summarize() of RUN_DIR/results.json and, when present, RUN_DIR/bench.json and
// RUN_DIR/instructions.json.
Summary summarize_run(const std::string& run_dir);

struct Gates {
  // Quality: relative tolerance per "<scene>/<method>", else per "<method>", else the default.
  double quality_default = 0.05;
  std::map<std::string, double> quality;
  // Performance: relative tolerance per case name, and the default.
  double performance_default = 0.25;
  std::map<std::string, double> performance;
  // Cases whose name contains one of these are compared and reported, but never fail the run:
  // all-core wall times move with how many cores other jobs leave free (reports/baseline/README.md).
  std::vector<std::string> performance_report_only = {"/threads:all"};
  // Instructions: one relative tolerance for every case. A method's count repeats to 0.003% or
  // better for one build and input, so this is not noise to absorb but the size of a change of
  // work small enough to pass without a deliberate re-accept.
  double instructions_default = 0.03;
  bool report_only(const std::string& case_name) const;
  // Ahead: `ahead_method` must have a lower MSE than each of `ahead_of` on every scene.
  std::string ahead_method = "proposed";
  std::vector<std::string> ahead_of;
  nlohmann::json derivation;  // how the tolerances were obtained (kept as written)

  double quality_tolerance(const std::string& scene, const std::string& method) const;
  double performance_tolerance(const std::string& case_name) const;
  nlohmann::json to_json() const;
  static Gates from_json(const nlohmann::json& j, const std::string& where);
};

struct Finding {
  std::string gate;    // quality, ahead, performance, instructions
  std::string scene;   // for performance: the benchmark frame
  std::string method;
  std::string metric;  // mse, time_ratio, instructions
  double old_value = 0, new_value = 0;
  double limit = 0;    // the largest passing new value (ahead: the other method's MSE)
  std::string compared_with;  // ahead: the baseline method
  bool failed = false;
  std::string message;  // one line, naming all of the above
  bool report_only = false;  // compared and shown, never failing (Gates::performance_report_only)
};

struct Verdict {
  std::vector<Finding> findings;  // every comparison, passed or failed
  std::vector<std::string> notes; // skipped gates, new entries without a baseline
  bool performance_checked = false;
  int failures() const;
  bool passed() const { return failures() == 0; }
  nlohmann::json to_json() const;
  std::string markdown(const Summary& baseline, const Summary& current) const;
};

struct CheckOptions {
  bool require_performance = false;  // a missing bench.json or another CPU model is an error
  bool performance = true;           // false: quality gates only
  bool ahead = true;                 // false: skip the ahead gate (a smoke run whose size means nothing)
};

Verdict check(const Summary& baseline, const Summary& current, const Gates& gates, const CheckOptions& options = {});

// Tolerances from repeated runs: quality from runs of the same config with different seeds
// (per scene and method: the relative standard deviation of the MSE across the runs; per
// method: the largest over its scenes), performance from repeated benchmark runs (per case:
// the relative standard deviation of the ratio); each tolerance is max(k * relative std,
// max/min - 1, floor): at least the largest change seen between two of the runs, so that a
// baseline accepted from any of them would not have raised an alarm on the others. The result keeps the measured spreads, k, the floors
// and the run names under "derivation". Without an ahead rule in `previous`, the quality runs
// give the default one (as accept does).
struct DeriveOptions {
  double quality_k = 3, quality_floor = 0.02;
  // 3 sqrt(2): a baseline run and a new run are equally noisy, their ratio's spread is sqrt(2)
  // times one run's. (Quality keeps k = 3: a denoiser changed with unchanged inputs gives the
  // same MSE bit for bit, so the MSE's seed spread only matters for changes to the inputs.)
  double performance_k = 4.25, performance_floor = 0.10;
};
// The default ahead rule for a run: `proposed` ahead of every other non-ablation filter in it
// (no rule when the run has no `proposed`; renderer-type methods are left out).
void default_ahead(Gates& gates, const Summary& run);

Gates derive_gates(const std::vector<Summary>& quality_runs, const std::vector<std::string>& quality_names,
                   const std::vector<Summary>& perf_runs, const std::vector<std::string>& perf_names,
                   const Gates& previous, const DeriveOptions& options = {});

// Appends one row for this run to a CSV history (date, revision, machine, config, verdict,
// failures, then mse/<scene>/<method> and ratio/<case> columns). A run bringing new columns
// rewrites the file with the union of the columns (old rows leave them empty); atomic.
void append_history(const std::string& path, const Summary& current, const Verdict& verdict);

// Folder-level operations of `denoisebench nightly`.
struct RunCheck {
  Summary current;
  Verdict verdict;
};
// Reads RUN_DIR and BASELINE_DIR (baseline.json, gates.json), checks, writes RUN_DIR/summary.json,
// verdict.json and verdict.md, and appends to `history` when not empty.
RunCheck check_run(const std::string& run_dir, const std::string& baseline_dir, const std::string& history,
                   const CheckOptions& options, const std::string& git_revision = "");
// Makes RUN_DIR's summary the baseline: writes BASELINE_DIR/baseline.json (and a default
// gates.json when there is none: 5% and 25% tolerances, `proposed` ahead of every other
// non-ablation method of the run). The revision recorded is `git_revision`, else the one
// RUN_DIR/summary.json (written by check) holds, else results.json's. Returns the summary.
Summary accept_run(const std::string& run_dir, const std::string& baseline_dir, const std::string& git_revision = "");
// The quality and ahead gates of BASELINE_DIR's gates.json applied to `accepted` against
// itself: the failures every later check will report until they are fixed (said at accept).
std::vector<Finding> self_check(const Summary& accepted, const std::string& baseline_dir);
// `denoisebench nightly tolerances`: derive_gates() from the results folders of repeated
// quality runs and the bench.json files of repeated benchmark runs, keeping the ahead rule of
// BASELINE_DIR/gates.json (when there is one); writes and returns the new gates.json.
Gates derive_tolerances(const std::vector<std::string>& quality_dirs, const std::vector<std::string>& perf_files,
                        const std::string& baseline_dir, const DeriveOptions& options = {});

}  // namespace dnb::nightly
