// `denoisebench report RESULTS_DIR`: everything is derived from results.json (and the images it
// names), never typed by hand.
//
//   table1_<metric>.{md,csv,tex}   rows scenes, columns methods (the paper's Table 1 layout;
//                                  table1_mse is Table 1 itself)
//   table2_time.{md,csv,tex}       input render, filter CPU, total CPU, filter OpenCL, total
//                                  OpenCL, irradiance cache, reference (Table 2's layout)
//   table2_filter_times.{md,csv,tex}  every method's filter time
//   speedup.md                     plain path tracing's fitted error-vs-time curve, and for each
//                                  method the spp and time it needs to reach the method's error
//   speedup_measured.md            the same on mse_hdr_nc, measured (interpolated, never
//                                  extrapolated: "beyond the measured range" instead)
//   ablation.md                    the ablation variants against the full method
//   ratios.md                      Table 2's CPU method's error over every other method's
//   plots/*.{png,pdf}              by reports/plots.py (matplotlib); sequence_*: a sequence's
//                                  per-frame mse and tmse (docs/sequences.md)
//   videos/<sequence>_<spp>spp.mp4 by reports/video.py (ffmpeg): input, methods and reference
//                                  side by side; web/sequences.html its part of the page
//   web/viewer/**, index.html      the static page: reports/viewer.py writes every image of each
//                                  scene as linear half floats, reports/viewer.js shows them
//
// The tables are pure functions of the results document (experiment/tables.cpp); the folder
// writer (experiment/report.cpp) adds the images and the page.
#pragma once

#include <optional>
#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "experiment/results.h"

namespace dnb::experiment {

struct Table {
  std::string title;
  std::vector<std::string> header;             // first column is the row label
  std::vector<std::vector<std::string>> rows;
  std::string note;                            // a line under the table
  std::string markdown() const;
  std::string csv() const;
  std::string latex() const;
};

// Power-law fit error = a * t^-b in log-log (least squares), and time = c * spp^d likewise.
struct PowerFit {
  double a = 0, b = 0;
  bool ok = false;
  double at(double t) const;          // a * t^-b
  double inverse(double err) const;   // t with at(t) == err
};
PowerFit fit_power_law(const std::vector<double>& x, const std::vector<double>& y);

// The tables of a results document (pure: used by the report and by the tests).
Table table1(const ResultsDocument& results, const std::string& metric);
// Of a row's cells (each: input seed -> value), the index of the best by its mean when it is
// significantly better than the runner-up's by a paired t-test over the seeds both have
// (two-sided p < alpha); -1 when no cell has two seeds, the two tie, or the test does not say so.
int significantly_best(const std::vector<std::map<std::uint64_t, double>>& cells, bool lower_is_better,
                       double alpha = 0.05);
Table table2(const ResultsDocument& results);
// Table 1 of the sequences (docs/temporal-metrics.md): a row per (sequence, spp, metric) for the
// mean still mse, tmse and disocclusion_mse, columns the methods then the input; empty without
// sequences.
Table sequence_table(const ResultsDocument& results);
// Every method's and variant's filter time per scene (Table 2 gives the CPU and OpenCL filter's
// only), with the input's render time.
Table filter_time_table(const ResultsDocument& results);
// The run's failed cells with their reasons (no rows when none failed).
Table failures_table(const ResultsDocument& results);
Table speedup_table(const ResultsDocument& results, const std::string& metric = "mse");
// The equal-error speed-up measured on the plain path tracing renders of the run, on a metric
// whose expectation falls as 1/spp for plain path tracing (mse_hdr_nc): interpolated between
// the renders that bracket a method's error, and "> X (beyond the measured range)" outside them.
Table measured_speedup_table(const ResultsDocument& results, const std::string& metric = "mse_hdr_nc");
Table ablation_table(const ResultsDocument& results, const std::string& metric = "mse");
// `method`'s mse and mse_converged over every other method's, per scene (Table 1's methods).
Table ratio_table(const ResultsDocument& results, const std::string& method);
// Whether `method` is ahead of each of today's baselines present in the run (kModernBaselines,
// and variants of them), per scene and metric (mse, mse_hdr): "ahead", "behind" or "no
// significant difference" by a paired t-test over the seeds (p < 0.05), with the mean per-seed
// error ratio and its 95% interval. Reported, never gated (the nightly gates these baselines for
// their own regressions only). Empty rows without any.
Table versus_modern_table(const ResultsDocument& results, const std::string& method);
inline const std::vector<std::string> kModernBaselines = {"svgf", "nfor", "oidn", "kpcn"};
// Per scene and method: the share of 16x16 tiles whose 8-bit mse is above the input frame's,
// and above twice it (records' `blocks`; the mean over the seeds when there are several).
Table worse_blocks_table(const ResultsDocument& results);

// A method's score for ranking methods over a set of scenes: the geometric mean over the scenes
// of (the method's metric / the unfiltered input's), each the mean over the input seeds, at the
// table's spp. Methods (role Method: no ablations, no input) with a value on every scene only.
std::map<std::string, double> ranking_scores(const ResultsDocument& results, const std::string& metric = "mse");
// The methods both documents rank, each with its score and rank in each, and Kendall's tau-b
// between the two rankings (stats::kendall_tau_b) in the note and a last row.
Table ranking_table(const ResultsDocument& here, const ResultsDocument& other, const std::string& here_name,
                    const std::string& other_name, const std::string& metric = "mse");
// A metric's value as the tables print it ("n/a" when absent or non-finite).
std::string format_metric(std::optional<double> value);

struct ReportOptions {
  bool plots = true;   // run reports/plots.py
  bool images = true;  // PNGs, crops, error maps for the page
  // Another results folder (e.g. the evaluation scenes' run) whose method ranking this run's is
  // compared with: the `ranking` table and Kendall's tau (configs/generalisation.toml).
  std::string ranking_against;
};

// Writes every file above into `dir` (which holds results.json).
void write_report(const std::string& dir, const ReportOptions& options = {});

// The folder holding reports/ (plots.py, viewer.py, viewer.js, the page template):
// $DENOISEBENCH_SOURCE_DIR/reports, else the source tree this program was built from.
std::string reports_dir();

}  // namespace dnb::experiment
