// The tables of a results document (experiment/report.h): Table 1 per metric, Table 2's
// times, the speed-up over plain path tracing, the ablation and the ratios. Pure functions of
// the document.
#include <algorithm>
#include <tuple>
#include <cmath>
#include <map>
#include <set>

#include <fmt/format.h>

#include "core/csv.h"
#include "core/stats.h"
#include "experiment/report.h"
#include "metrics/metrics.h"

namespace dnb::experiment {

// ---------------------------------------------------------------------------------------------
// Table formats

std::string Table::markdown() const {
  std::string o = title.empty() ? "" : "## " + title + "\n\n";
  auto line = [&](const std::vector<std::string>& cells) {
    o += "|";
    for (const auto& c : cells) o += " " + c + " |";
    o += "\n";
  };
  line(header);
  o += "|";
  for (std::size_t i = 0; i < header.size(); ++i) o += i == 0 ? "---|" : "---:|";
  o += "\n";
  for (const auto& r : rows) line(r);
  if (!note.empty()) o += "\n" + note + "\n";
  return o;
}

std::string Table::csv() const {
  std::string o = csv::line(header) + "\n";
  for (const auto& row : rows) o += csv::line(row) + "\n";
  return o;
}

std::string Table::latex() const {
  auto esc = [](const std::string& s) {
    std::string o;
    for (char ch : s) {
      if (ch == '_' || ch == '%' || ch == '&' || ch == '#') o += '\\';
      o += ch;
    }
    for (std::size_t at = 0; (at = o.find("±", at)) != std::string::npos;) {
      o.replace(at, std::string("±").size(), "$\\pm$");
      at += 5;
    }
    return o;
  };
  std::string o = "% " + title + "\n\\begin{tabular}{l" + std::string(header.size() - 1, 'r') + "}\n\\hline\n";
  auto line = [&](const std::vector<std::string>& cells) {
    for (std::size_t i = 0; i < cells.size(); ++i) o += (i ? " & " : "") + esc(cells[i]);
    o += " \\\\\n";
  };
  line(header);
  o += "\\hline\n";
  for (const auto& r : rows) line(r);
  o += "\\hline\n\\end{tabular}\n";
  return o;
}

// ---------------------------------------------------------------------------------------------
// Fits

double PowerFit::at(double t) const { return a * std::pow(t, -b); }
double PowerFit::inverse(double err) const { return std::pow(err / a, -1.0 / b); }

PowerFit fit_power_law(const std::vector<double>& x, const std::vector<double>& y) {
  // log y = log a - b log x, ordinary least squares over the points with positive values.
  double n = 0, sx = 0, sy = 0, sxx = 0, sxy = 0;
  for (std::size_t i = 0; i < x.size(); ++i) {
    if (!(x[i] > 0) || !(y[i] > 0)) continue;
    double lx = std::log(x[i]), ly = std::log(y[i]);
    n += 1; sx += lx; sy += ly; sxx += lx * lx; sxy += lx * ly;
  }
  PowerFit f;
  const double den = n * sxx - sx * sx;
  if (n < 2 || std::abs(den) < 1e-12) return f;
  const double slope = (n * sxy - sx * sy) / den;
  f.b = -slope;
  f.a = std::exp((sy - slope * sx) / n);
  f.ok = f.b > 0;
  return f;
}

// ---------------------------------------------------------------------------------------------
// Tables

std::string format_metric(std::optional<double> v) { return v ? fmt::format("{:.4g}", *v) : "n/a"; }

namespace {

std::string fmt_time(double s) { return fmt::format("{:.2f}", s); }

std::optional<double> metric_of(const CellRecord* r, const std::string& metric) {
  return r ? r->metric(metric) : std::nullopt;
}

// A cell's metric over its seeds: seed -> value (the seeds whose record has the metric).
std::map<std::uint64_t, double> seed_values(const ResultsDocument& res, const std::string& scene, const std::string& method,
                                            int spp, const std::string& metric) {
  std::map<std::uint64_t, double> out;
  for (const CellRecord* r : res.find_all(scene, method, spp))
    if (auto v = r->metric(metric)) out[r->seed.value_or(0)] = *v;
  return out;
}

std::vector<double> values_of(const std::map<std::uint64_t, double>& m) {
  std::vector<double> v;
  for (const auto& [seed, x] : m) v.push_back(x);
  return v;
}

// One seed: the value; several: the mean and its 95% t-interval's half width.
std::string format_interval(const std::map<std::uint64_t, double>& m) {
  if (m.empty()) return "n/a";
  if (m.size() == 1) return format_metric(m.begin()->second);
  const stats::Interval i = stats::t_interval(values_of(m));
  return fmt::format("{:.4g} ± {:.2g}", i.mean, i.half_width);
}

}  // namespace

int significantly_best(const std::vector<std::map<std::uint64_t, double>>& cells, bool lower_is_better, double alpha) {
  // Rank the cells of at least two seeds by their mean.
  std::vector<std::pair<double, int>> ranked;
  for (std::size_t k = 0; k < cells.size(); ++k)
    if (cells[k].size() >= 2) ranked.emplace_back(stats::mean(values_of(cells[k])), int(k));
  if (ranked.size() < 2) return -1;
  std::sort(ranked.begin(), ranked.end());
  if (!lower_is_better) std::reverse(ranked.begin(), ranked.end());
  const auto& best = cells[std::size_t(ranked[0].second)];
  const auto& next = cells[std::size_t(ranked[1].second)];
  // Paired over the seeds both have.
  std::vector<double> a, b;
  for (const auto& [seed, v] : best)
    if (auto it = next.find(seed); it != next.end()) a.push_back(v), b.push_back(it->second);
  const double p = stats::paired_t_test_p(a, b);
  return std::isfinite(p) && p < alpha && ranked[0].first != ranked[1].first ? ranked[0].second : -1;
}

namespace {

// The share of the scene's reference pixels mse_converged leaves out, as the run recorded it.
std::string unconverged_cell(const ResultsDocument& res, const std::string& scene) {
  for (const auto& r : res.records)
    if (r.scene == scene && r.reference.unconverged_share)
      return fmt::format("{:.3f}%", 100.0 * *r.reference.unconverged_share);
  return "n/a";
}

// The reference's own expected error in `metric` (mse, mse_hdr, relmse), as the run recorded it:
// what a perfect image would score against this reference.
std::optional<double> reference_error_of(const ResultsDocument& res, const std::string& scene, const std::string& metric) {
  for (const auto& r : res.records)
    if (r.scene == scene && r.reference.estimated_error)
      if (auto it = r.reference.estimated_error->find(metric); it != r.reference.estimated_error->end()) return it->second;
  return std::nullopt;
}

// The column is there for the metrics the reference's noise adds to, when a scene has the estimate.
bool has_reference_error(const ResultsDocument& res, const std::string& metric) {
  const metrics::MetricInfo* info = metrics::find_metric(metric);
  if (!info || !info->reference_error) return false;
  for (const auto& s : res.scenes())
    if (reference_error_of(res, s, metric)) return true;
  return false;
}

}  // namespace

Table table1(const ResultsDocument& res, const std::string& metric) {
  Table t;
  const int spp = res.table_spp();
  // Methods whose cells failed in this run are columns too: their cells say "failed", not n/a.
  auto methods = res.methods(Role::Method);
  // So are methods skipped on every scene (a renderer-type method, every scene read from files).
  auto add_column = [&](const std::string& method, int cell_spp) {
    const bool ablation = std::any_of(res.config.methods.begin(), res.config.methods.end(),
                                      [&](const MethodEntry& e) { return e.name == method && !e.group.empty(); });
    if (cell_spp == spp && !ablation && std::find(methods.begin(), methods.end(), method) == methods.end())
      methods.push_back(method);
  };
  for (const auto& f : res.failures) add_column(f.method, f.spp);
  for (const auto& k : res.skipped) add_column(k.method, k.spp);
  t.title = fmt::format("Table 1: {} at {} spp input", metric, spp);
  t.header = {"scene"};
  for (const auto& m : methods) t.header.push_back(m);
  t.header.push_back(fmt::format("input ({} spp)", spp));
  const auto& info = metrics::metric(metric);
  const bool reference_column = has_reference_error(res, metric);
  bool several = false;
  for (const auto& s : res.scenes()) {
    std::vector<std::string> row{s};
    std::vector<std::map<std::uint64_t, double>> vals;
    for (const auto& m : methods) {
      vals.push_back(seed_values(res, s, m, spp, metric));
      several = several || vals.back().size() > 1;
      row.push_back(res.failure(s, m, spp) ? "failed" : res.skip(s, m, spp) ? "skipped" : format_interval(vals.back()));
    }
    if (const int best = significantly_best(vals, info.lower_is_better); best >= 0) row[std::size_t(best) + 1] += " *";
    row.push_back(format_interval(seed_values(res, s, "input", spp, metric)));
    if (info.masks_unconverged) row.push_back(unconverged_cell(res, s));
    if (reference_column) row.push_back(format_metric(reference_error_of(res, s, metric)));
    t.rows.push_back(row);
  }
  if (info.masks_unconverged) t.header.push_back("reference pixels left out");
  if (reference_column) t.header.push_back("reference's own (est.)");
  t.note = fmt::format("{}; {} is better. From results.json.{}{}{}", info.description, info.lower_is_better ? "lower" : "higher",
                       several ? fmt::format(" Several input seeds: mean ± the half width of its 95% t-interval over the seeds; "
                                            "*: the best method of the row, {} than the runner-up by a paired t-test over the "
                                            "seeds (two-sided, p < 0.05); no * where the difference is not significant.",
                                            info.lower_is_better ? "significantly lower" : "significantly higher")
                               : std::string(),
                       res.failures.empty() ? "" : " failed: the cell failed in this run (see the failed-cells table).",
                       res.skipped.empty() ? "" : " skipped: the cell cannot run here (results.json's skipped gives each reason: a "
                                                   "renderer on a scene read from files, a method whose package or weights are "
                                                   "not installed).");
  if (reference_column)
    t.note += " reference's own (est.): what a perfect image would score against this reference, from the reference's "
              "variance of the mean (metrics::reference_error; first order for the 8-bit mse): that much of every cell is "
              "the reference's noise, not the method's error (mse_hdr_nc and relmse_nc take it out).";
  return t;
}

Table failures_table(const ResultsDocument& res) {
  Table t;
  t.title = "Failed cells";
  t.header = {"scene", "method", "spp", "reason", "last lines of its stderr"};
  for (const auto& f : res.failures)
    t.rows.push_back({f.scene, f.method, std::to_string(f.spp), f.reason.substr(0, f.reason.find('\n')),
                      fmt::format("{}", fmt::join(f.log_tail, " / "))});
  t.note = "Cells of this run that failed (results.json, key failures): the run kept every other cell and exited 1; the next "
           "run into the folder tries these again.";
  return t;
}

namespace {

// Method a's and method b's `metric` on the seeds both have (b's value positive, so that a / b is
// a ratio), in seed order.
struct SeedPairs {
  std::vector<double> a, b, ratios;  // ratios[i] = a[i] / b[i]
};
SeedPairs seed_pairs(const ResultsDocument& res, const std::string& scene, const std::string& a_method,
                     const std::string& b_method, int spp, const std::string& metric) {
  SeedPairs p;
  const auto a = seed_values(res, scene, a_method, spp, metric);
  for (const auto& [seed, v] : seed_values(res, scene, b_method, spp, metric))
    if (auto it = a.find(seed); it != a.end() && v > 0) {
      p.a.push_back(it->second), p.b.push_back(v), p.ratios.push_back(it->second / v);
    }
  return p;
}

}  // namespace

Table ratio_table(const ResultsDocument& res, const std::string& method) {
  Table t;
  const int spp = res.table_spp();
  std::vector<std::string> others;
  for (const auto& m : res.methods(Role::Method))
    if (m != method) others.push_back(m);
  t.title = fmt::format("Ratios: {}'s error over each method's at {} spp input", method, spp);
  t.header = {"scene", "metric"};
  for (const auto& m : others) t.header.push_back(m);
  for (const auto& s : res.scenes()) {
    for (const char* metric : {"mse", "mse_converged"}) {
      std::vector<std::string> row{s, metric};
      for (const auto& m : others) {
        // The ratio per seed (both on the same input frame), then its mean and interval.
        const std::vector<double> ratios = seed_pairs(res, s, method, m, spp, metric).ratios;
        if (ratios.empty()) row.push_back("n/a");
        else if (ratios.size() == 1) row.push_back(fmt::format("{:.2f}", ratios[0]));
        else {
          const stats::Interval i = stats::t_interval(ratios);
          row.push_back(fmt::format("{:.2f} ± {:.2f}", i.mean, i.half_width));
        }
      }
      t.rows.push_back(row);
    }
  }
  t.note = fmt::format("Below 1: {} has the lower error. mse_converged leaves out the reference's unconverged "
                       "pixels (Table 1, mse_converged). With several input seeds: the mean of the per-seed ratios ± "
                       "the half width of their 95% t-interval. From results.json.",
                       method);
  return t;
}

Table versus_modern_table(const ResultsDocument& res, const std::string& method) {
  Table t;
  const int spp = res.table_spp();
  // The modern baselines and their variants (a variant names its base method), in run order.
  std::vector<std::string> others;
  for (const auto& r : res.records) {
    if (r.role != Role::Method || r.spp != spp || r.method == method) continue;
    const std::string& base = r.base_method.empty() ? r.method : r.base_method;
    if (std::find(kModernBaselines.begin(), kModernBaselines.end(), base) != kModernBaselines.end() &&
        std::find(others.begin(), others.end(), r.method) == others.end())
      others.push_back(r.method);
  }
  t.title = fmt::format("{} against today's baselines at {} spp input (reported, not gated)", method, spp);
  t.header = {"scene", "metric"};
  for (const auto& m : others) t.header.push_back(m);
  if (others.empty()) return t;
  for (const auto& s : res.scenes()) {
    for (const char* metric : {"mse", "mse_hdr"}) {
      std::vector<std::string> row{s, metric};
      for (const auto& m : others) {
        const SeedPairs pairs = seed_pairs(res, s, method, m, spp, metric);
        const std::vector<double>& ratios = pairs.ratios;
        if (ratios.empty()) {
          row.push_back(res.skip(s, m, spp) ? "skipped" : res.failure(s, m, spp) ? "failed" : "n/a");
          continue;
        }
        if (ratios.size() == 1) {
          row.push_back(fmt::format("{} ({:.2f}; one seed: no test)", ratios[0] < 1 ? "lower" : "higher", ratios[0]));
          continue;
        }
        const stats::Interval i = stats::t_interval(ratios);
        const double p = stats::paired_t_test_p(pairs.a, pairs.b);
        const char* verdict = !(std::isfinite(p) && p < 0.05) ? "no significant difference"
                              : stats::mean(pairs.a) < stats::mean(pairs.b) ? "ahead"
                                                                        : "behind";
        row.push_back(fmt::format("{} ({:.2f} ± {:.2f})", verdict, i.mean, i.half_width));
      }
      t.rows.push_back(row);
    }
  }
  t.note = fmt::format("Is {} ahead of the strongest baselines of today (SVGF's spatial filter, NFOR, OIDN, a learned one)? "
                       "ahead / behind: its error is lower / higher, significantly by a paired t-test over the input "
                       "seeds (two-sided, p < 0.05); in brackets the mean of the per-seed ratios {} / baseline ± the half "
                       "width of their 95% t-interval. The nightly gates {} only against the paper's baselines. From "
                       "results.json.",
                       method, method, method);
  return t;
}

Table worse_blocks_table(const ResultsDocument& res) {
  Table t;
  const int spp = res.table_spp();
  const auto methods = res.methods(Role::Method);
  t.title = fmt::format("Where methods make things worse: tiles above the input's error at {} spp", spp);
  t.header = {"scene"};
  for (const auto& m : methods) t.header.push_back(m);
  int block = 0;
  for (const auto& s : res.scenes()) {
    std::vector<std::string> row{s};
    for (const auto& m : methods) {
      std::vector<double> worse, twice;
      for (const CellRecord* r : res.find_all(s, m, spp))
        if (r->blocks && r->blocks->count("worse") && r->blocks->count("worse_twice")) {
          worse.push_back(r->blocks->at("worse"));
          twice.push_back(r->blocks->at("worse_twice"));
          if (r->blocks->count("block")) block = int(r->blocks->at("block"));
        }
      row.push_back(worse.empty() ? "n/a"
                                  : fmt::format("{:.1f}% ({:.1f}%)", 100 * stats::mean(worse), 100 * stats::mean(twice)));
    }
    t.rows.push_back(row);
  }
  t.note = fmt::format("Share of the image's {0}x{0} tiles whose 8-bit mse against the reference is above the unfiltered "
                       "input's, and in brackets above twice it: a method can have the lowest mean error and still "
                       "be worse than its input in places (thin features erased, halos). The mean over the input seeds "
                       "where there are several. From results.json (records' blocks).",
                       block > 0 ? block : 16);
  return t;
}

std::map<std::string, double> ranking_scores(const ResultsDocument& res, const std::string& metric) {
  std::map<std::string, double> out;
  const int spp = res.table_spp();
  const auto scenes = res.scenes();
  if (scenes.empty()) return out;
  auto seed_mean = [&](const std::string& s, const std::string& m) {
    const auto v = values_of(seed_values(res, s, m, spp, metric));
    return v.empty() ? 0.0 : stats::mean(v);
  };
  std::vector<double> input;  // per scene, once for every method
  for (const auto& s : scenes) input.push_back(seed_mean(s, "input"));
  for (const auto& m : res.methods(Role::Method)) {
    double log_sum = 0;
    bool complete = true;
    for (std::size_t i = 0; i < scenes.size() && complete; ++i) {
      const double a = seed_mean(scenes[i], m), b = input[i];
      complete = a > 0 && b > 0;
      if (complete) log_sum += std::log(a / b);
    }
    if (complete) out[m] = std::exp(log_sum / double(scenes.size()));
  }
  return out;
}

Table ranking_table(const ResultsDocument& here, const ResultsDocument& other, const std::string& here_name,
                    const std::string& other_name, const std::string& metric) {
  const auto a = ranking_scores(here, metric), b = ranking_scores(other, metric);
  std::vector<std::string> methods;
  std::vector<double> xa, xb;
  for (const auto& [m, v] : a)
    if (b.count(m)) methods.push_back(m), xa.push_back(v), xb.push_back(b.at(m));
  // Ranks (1 = lowest error; equal scores share the lower rank).
  auto ranks = [](const std::vector<double>& v) {
    std::vector<int> r(v.size());
    for (std::size_t i = 0; i < v.size(); ++i)
      r[i] = 1 + int(std::count_if(v.begin(), v.end(), [&](double w) { return w < v[i]; }));
    return r;
  };
  const auto ra = ranks(xa), rb = ranks(xb);
  std::vector<std::size_t> order(methods.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::stable_sort(order.begin(), order.end(), [&](std::size_t i, std::size_t j) { return ra[i] < ra[j]; });
  Table t;
  t.title = fmt::format("Method ranking: {} against {} ({}, relative to the input)", here_name, other_name, metric);
  t.header = {"method", fmt::format("{} (rank)", here_name), fmt::format("{} (rank)", other_name)};
  for (std::size_t i : order)
    t.rows.push_back({methods[i], fmt::format("{:.4g} ({})", xa[i], ra[i]), fmt::format("{:.4g} ({})", xb[i], rb[i])});
  const stats::KendallTau k = stats::kendall_tau_b(xa, xb);
  const std::string tau = std::isnan(k.tau) ? "n/a" : fmt::format("{:.3f}", k.tau);
  const std::string p = std::isnan(k.p_value) ? "n/a" : fmt::format("{:.2g}", k.p_value);
  t.rows.push_back({"Kendall's tau-b", tau, fmt::format("p = {} ({}), n = {}", p, k.exact ? "exact" : "normal approx.", k.n)});
  t.note = fmt::format(
      "Each method's score is the geometric mean over the scenes of its {0} divided by the unfiltered input's "
      "(means over the input seeds, at each run's table spp); rank 1 is the lowest. Kendall's tau-b between the two "
      "rankings over the {1} methods both runs scored: 1 = the same order, 0 = unrelated, -1 = reversed; p: two-sided "
      "test of tau = 0 ({2}). Concordant pairs {3}, discordant {4}. From the two runs' results.json.",
      metric, k.n, k.exact ? "exact permutation distribution" : "normal approximation with ties", k.concordant, k.discordant);
  return t;
}

Table sequence_table(const ResultsDocument& res) {
  Table t;
  t.title = "Table 1, sequences: the still mse's mean over the frames, tmse and disocclusion_mse";
  std::vector<std::string> methods;  // record order, input last
  for (const auto& s : res.sequences)
    if (s.method != "input" && std::find(methods.begin(), methods.end(), s.method) == methods.end())
      methods.push_back(s.method);
  t.header = {"sequence", "spp", "metric"};
  for (const auto& m : methods) t.header.push_back(m);
  t.header.push_back("input");
  std::vector<std::pair<std::string, int>> rows;  // (sequence, spp), first-seen order
  for (const auto& s : res.sequences)
    if (std::find(rows.begin(), rows.end(), std::pair(s.sequence, s.spp)) == rows.end()) rows.emplace_back(s.sequence, s.spp);
  bool several = false;
  for (const auto& key : rows)
    for (const char* metric : {"mse", "tmse", "disocclusion_mse"}) {
      // Plain names, not structured bindings: clang 14 (the fuzz and sanitizer builds) cannot
      // capture a binding in a lambda.
      const std::string& sequence = key.first;
      const int spp = key.second;
      auto values = [&](const std::string& method) {
        std::map<std::uint64_t, double> out;
        for (const auto& s : res.sequences)
          if (s.sequence == sequence && s.spp == spp && s.method == method)
            if (auto v = s.metric(metric)) out[s.seed.value_or(0)] = *v;
        return out;
      };
      std::vector<std::string> row{sequence, std::to_string(spp), metric};
      std::vector<std::map<std::uint64_t, double>> vals;
      for (const auto& m : methods) {
        vals.push_back(values(m));
        several = several || vals.back().size() > 1;
        row.push_back(format_interval(vals.back()));
      }
      if (const int best = significantly_best(vals, true); best >= 0) row[std::size_t(best) + 3] += " *";
      row.push_back(format_interval(values("input")));
      t.rows.push_back(std::move(row));
    }
  t.note = "docs/temporal-metrics.md: mse is the 8-bit mse's mean over the frames; tmse the mean square of the output's "
           "frame-to-frame change less the reference's, over the pixels with history (flicker; true motion does not "
           "count); disocclusion_mse the 8-bit mse over the pixels without history (ghosting, lag). Lower is better. "
           "From results.json's sequences.";
  if (several) t.note += " Several input seeds: mean ± the half width of its 95% t-interval; *: significantly best (paired t-test).";
  return t;
}

Table table2(const ResultsDocument& res) {
  Table t;
  const int spp = res.table_spp();
  const Table2Columns& cols = res.config.table2;
  int ref_spp = 0;
  for (const auto& r : res.records) ref_spp = r.reference.spp;
  t.title = "Table 2: time in seconds";
  t.header = {"scene", fmt::format("render input ({} spp)", spp), fmt::format("filter CPU ({})", cols.filter_cpu), "total CPU",
              cols.filter_opencl.empty() ? "filter OpenCL" : fmt::format("filter OpenCL ({})", cols.filter_opencl),
              "total OpenCL", "irradiance cache", fmt::format("reference ({} spp)", ref_spp)};
  for (const auto& s : res.scenes()) {
    const CellRecord* in = res.find(s, "input", spp);
    const CellRecord* c = res.find(s, cols.filter_cpu, spp);
    const CellRecord* o = cols.filter_opencl.empty() ? nullptr : res.find(s, cols.filter_opencl, spp);
    const CellRecord* i = res.find(s, cols.irradiance_cache, spp);
    const CellRecord* any = in ? in : c;
    auto filter = [](const CellRecord* r) { return r ? fmt_time(r->times.filter) : std::string("n/a"); };
    auto total = [&](const CellRecord* r) { return r && in ? fmt_time(in->times.input_render + r->times.filter) : "n/a"; };
    t.rows.push_back({s, in ? fmt_time(in->times.input_render) : "n/a", filter(c), total(c), filter(o), total(o),
                      i ? fmt_time(i->times.total) : "n/a", any ? fmt_time(any->reference.seconds) : "n/a"});
  }
  t.note = "Wall-clock seconds on the machine named in results.json; filter times are medians of repeated runs after a warm-up for methods under a second. n/a: the method was not in the run.";
  // A run spread over MPI ranks timed each cell on the rank that computed it, with other ranks
  // sharing the machine (or on other machines): say so beside the seconds.
  if (const int ranks = res.machine.value("ranks", 1); ranks > 1)
    t.note += fmt::format(" This run was spread over {} MPI ranks: each cell was timed on the rank that computed it, "
                          "possibly beside other ranks on the same machine, so times are not those of one process.",
                          ranks);
  return t;
}

Table filter_time_table(const ResultsDocument& res) {
  Table t;
  const int spp = res.table_spp();
  std::vector<std::string> methods = res.methods(Role::Method);
  for (const auto& m : res.methods(Role::Ablation)) methods.push_back(m);
  t.title = fmt::format("Table 2, every method: filter time in seconds ({} spp input)", spp);
  t.header = {"scene", fmt::format("render input ({} spp)", spp)};
  for (const auto& m : methods) t.header.push_back(m);
  for (const auto& s : res.scenes()) {
    const CellRecord* in = res.find(s, "input", spp);
    std::vector<std::string> row{s, in ? fmt::format("{:.3g}", in->times.input_render) : "n/a"};
    for (const auto& m : methods) {
      const CellRecord* r = res.find(s, m, spp);
      row.push_back(res.failure(s, m, spp) ? "failed" : res.skip(s, m, spp) ? "skipped" : r ? fmt::format("{:.3g}", r->times.filter) : "n/a");
    }
    t.rows.push_back(row);
  }
  t.note = "Wall-clock seconds of each method's filtering alone (times.filter of the first input seed's record; a renderer-type "
           "method's is its rendering), medians of repeated runs after a warm-up for methods under the config's "
           "repeat_below_seconds. From results.json.";
  return t;
}

namespace {

// One scene's plain path-tracing curve: time, error and spp of every plain record.
struct PlainCurve {
  std::vector<double> times, errors, spps;
};

PlainCurve plain_curve(const ResultsDocument& res, const std::string& scene, const std::string& metric) {
  PlainCurve c;
  for (const auto& r : res.records)
    if (r.scene == scene && r.role == Role::Plain && r.metric(metric)) {
      c.times.push_back(r.times.total);
      c.errors.push_back(*r.metric(metric));
      c.spps.push_back(r.spp);
    }
  return c;
}

}  // namespace

Table speedup_table(const ResultsDocument& res, const std::string& metric) {
  Table t;
  const int spp = res.table_spp();
  t.title = fmt::format("Speed-up over plain path tracing ({} at {} spp input)", metric, spp);
  t.header = {"scene", "method", metric, "total time (s)", "plain PT spp needed", "plain PT time needed (s)", "speed-up"};
  std::string fits;
  for (const auto& s : res.scenes()) {
    const PlainCurve pc = plain_curve(res, s, metric);
    const PowerFit err_t = fit_power_law(pc.times, pc.errors);
    // time = c * spp^d, fitted as a power law of spp (b = -d).
    const PowerFit t_spp = fit_power_law(pc.spps, pc.times);
    if (!err_t.ok) {
      fits += fmt::format("- {}: too few plain path tracing points to fit ({}).\n", s, pc.times.size());
      continue;
    }
    const double tmax = *std::max_element(pc.times.begin(), pc.times.end());
    fits += fmt::format("- {}: {} = {:.4g} * t^-{:.3f} over {} plain path tracing renders ({}..{} spp).\n", s, metric,
                        err_t.a, err_t.b, pc.times.size(), *std::min_element(pc.spps.begin(), pc.spps.end()),
                        *std::max_element(pc.spps.begin(), pc.spps.end()));
    for (const auto& m : res.methods(Role::Method)) {
      const CellRecord* r = res.find(s, m, spp);
      if (!r || !r->metric(metric)) continue;
      const double e = *r->metric(metric), total = r->times.total;
      const double t_need = err_t.inverse(e);
      const double spp_need = t_spp.a > 0 ? t_spp.inverse(t_need) : NAN;
      t.rows.push_back({s, m, format_metric(e), fmt_time(total), std::isfinite(spp_need) ? fmt::format("{:.0f}", spp_need) : "n/a",
                        fmt::format("{:.3g}{}", t_need, t_need > tmax ? " (extrapolated)" : ""),
                        fmt::format("{:.1f}x", t_need / total)});
    }
  }
  t.note = "Fits (least squares in log-log over the plain path tracing renders of the run):\n\n" + fits +
           "\nspeed-up = time plain path tracing needs to reach the method's error / the method's total time (input render + filtering).";
  return t;
}

Table measured_speedup_table(const ResultsDocument& res, const std::string& metric) {
  Table t;
  const int spp = res.table_spp();
  t.title = fmt::format("Measured speed-up over plain path tracing ({} at {} spp input)", metric, spp);
  t.header = {"scene", "method", metric, "total time (s)", "plain PT time for that error (s)", "speed-up"};
  std::string ranges;
  for (const auto& s : res.scenes()) {
    // The plain renders in spp order, each with its time and error (seed-averaged records are
    // one per spp here: the plain curve has the first seed only).
    std::vector<std::tuple<int, double, double>> curve;  // spp, time, error
    for (const auto& r : res.records)
      if (r.scene == s && r.role == Role::Plain && r.metric(metric)) curve.emplace_back(r.spp, r.times.total, *r.metric(metric));
    std::sort(curve.begin(), curve.end());
    if (curve.size() < 2) {
      ranges += fmt::format("- {}: too few plain path tracing renders ({}).\n", s, curve.size());
      continue;
    }
    const auto& [lo_spp, lo_t, lo_e] = curve.front();
    const auto& [hi_spp, hi_t, hi_e] = curve.back();
    ranges += fmt::format("- {}: plain path tracing measured at {}..{} spp ({:.3g}..{:.3g} s, {} {:.4g}..{:.4g}).\n", s,
                          lo_spp, hi_spp, lo_t, hi_t, metric, lo_e, hi_e);
    for (const auto& m : res.methods(Role::Method)) {
      const CellRecord* r = res.find(s, m, spp);
      if (!r || !r->metric(metric)) continue;
      const double e = *r->metric(metric), total = r->times.total;
      std::string need, speed;
      if (!(e < lo_e) && e > 0) {  // no better than the cheapest plain render
        need = fmt::format("< {:.3g} (below the measured range)", lo_t);
        speed = fmt::format("< {:.2g}x", lo_t / total);
      } else if (!(e > hi_e)) {  // better than the most expensive plain render (or below 0: within the reference's noise)
        need = fmt::format("> {:.3g} (beyond the measured range)", hi_t);
        speed = fmt::format("> {:.2g}x", hi_t / total);
      } else {
        // The first pair of consecutive renders that brackets the error; time interpolated in
        // log-log between them (where plain path tracing's expected error falls as 1/spp).
        for (std::size_t k = 0; k + 1 < curve.size(); ++k) {
          const double e0 = std::get<2>(curve[k]), e1 = std::get<2>(curve[k + 1]);
          if (!(e0 >= e && e >= e1) || !(e1 > 0)) continue;
          const double t0 = std::get<1>(curve[k]), t1 = std::get<1>(curve[k + 1]);
          const double f = e0 == e1 ? 0.0 : std::log(e0 / e) / std::log(e0 / e1);
          const double tn = std::exp(std::log(t0) + f * (std::log(t1) - std::log(t0)));
          need = fmt::format("{:.3g}", tn);
          speed = fmt::format("{:.3g}x", tn / total);
          break;
        }
        if (need.empty()) need = speed = "n/a (the plain curve does not fall through it)";
      }
      t.rows.push_back({s, m, format_metric(e), fmt_time(total), need, speed});
    }
  }
  t.note = "Plain path tracing's time to reach each method's error, interpolated between the two measured plain renders "
           "that bracket it (log-log), never extrapolated: outside the measured range the table says so, with the bound "
           "the range gives. " + metric + " is chosen because its expectation for plain path tracing falls as 1/spp "
           "(the reference's own noise taken out: docs/references.md); speedup.md is the 8-bit reading with a fitted "
           "power law.\n\n" + ranges;
  return t;
}

Table ablation_table(const ResultsDocument& res, const std::string& metric) {
  Table t;
  const int spp = res.table_spp();
  auto variants = res.methods(Role::Ablation);
  std::set<std::string> bases;
  for (const auto& r : res.records)
    if (r.role == Role::Ablation) bases.insert(r.base_method);
  std::vector<std::string> rows_m(bases.begin(), bases.end());
  rows_m.insert(rows_m.end(), variants.begin(), variants.end());
  t.title = fmt::format("Ablation: {} at {} spp input (each row switches one part off)", metric, spp);
  t.header = {"variant"};
  const auto scenes = res.scenes();
  for (const auto& s : scenes) t.header.push_back(s);
  for (const auto& m : rows_m) {
    std::vector<std::string> row{m};
    for (const auto& s : scenes) {
      const CellRecord* r = res.find(s, m, spp);
      const CellRecord* base = r ? res.find(s, r->base_method.empty() ? m : r->base_method, spp) : nullptr;
      const auto v = metric_of(r, metric), b = metric_of(base, metric);
      std::string cell = r ? format_metric(v) : "n/a";
      if (base && base != r && v && b && *b != 0) cell += fmt::format(" ({:+.0f}%)", 100.0 * (*v / *b - 1));
      row.push_back(cell);
    }
    t.rows.push_back(row);
  }
  t.note = variants.empty() ? "No ablation variants in this run ([[variant]] group = \"ablation\")."
                            : "Percentages: change against the full method in the first row(s).";
  return t;
}

}  // namespace dnb::experiment
