// The report folder (experiment/report.h): tables as files, plots through reports/plots.py, and
// the static page with one image comparison per scene.
#include "core/env.h"
#include "experiment/report.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <ctime>
#include <functional>
#include <optional>
#include <filesystem>

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <spdlog/spdlog.h>

#include "core/atomic_file.h"
#include "core/errors.h"
#include "core/exr_io.h"
#include "core/subprocess.h"
#include "metrics/metrics.h"

namespace fs = std::filesystem;

namespace dnb::experiment {

std::string reports_dir() {
  if (const char* s = env::get("SOURCE_DIR"); s && *s && fs::exists(fs::path(s) / "reports")) return (fs::path(s) / "reports").string();
  return (fs::path(DNB_SOURCE_DIR) / "reports").string();
}

namespace {

// ---------------------------------------------------------------------------------------------
// Files

void write_table(const std::string& dir, const std::string& stem, const Table& t) {
  write_text_atomic(dir + "/" + stem + ".md", t.markdown());
  write_text_atomic(dir + "/" + stem + ".csv", t.csv());
  write_text_atomic(dir + "/" + stem + ".tex", t.latex());
}

std::string html_escape(const std::string& s) {
  std::string o;
  for (char ch : s) {
    if (ch == '<') o += "&lt;";
    else if (ch == '>') o += "&gt;";
    else if (ch == '&') o += "&amp;";
    else if (ch == '"') o += "&quot;";
    else o += ch;
  }
  return o;
}

// The leading number of a cell ("12.5 ± 1.2 *" -> 12.5), or nullopt ("n/a", "failed").
std::optional<double> cell_number(const std::string& c) {
  char* end = nullptr;
  const double v = std::strtod(c.c_str(), &end);
  if (end == c.c_str() || !std::isfinite(v)) return std::nullopt;
  return v;
}

// How a table's best cells are marked on the page: per row, over columns [first, last), the
// lowest (lower_is_better) or highest number.
struct BestMark {
  bool on = false, lower_is_better = true;
  std::size_t first = 1, last = 0;
};

std::string html_table(const Table& t, const BestMark& best = {}) {
  std::string o = "<h3>" + html_escape(t.title) + "</h3>\n<div class=\"table-scroll\"><table><thead><tr>";
  for (const auto& h : t.header) o += "<th>" + html_escape(h) + "</th>";
  o += "</tr></thead><tbody>\n";
  for (const auto& r : t.rows) {
    std::optional<std::size_t> mark;
    if (best.on)
      for (std::size_t c = best.first; c < std::min(best.last, r.size()); ++c)
        if (const auto v = cell_number(r[c]))
          if (!mark || (best.lower_is_better ? *v < *cell_number(r[*mark]) : *v > *cell_number(r[*mark]))) mark = c;
    o += "<tr>";
    for (std::size_t c = 0; c < r.size(); ++c)
      o += (mark && *mark == c ? "<td class=\"best\" title=\"best of the row\">" : "<td>") + html_escape(r[c]) + "</td>";
    o += "</tr>\n";
  }
  o += "</tbody></table></div>\n";
  if (!t.note.empty()) o += "<p class=\"note\">" + html_escape(t.note) + "</p>\n";
  return o;
}

// The run's provenance at the top of the page: what built it, where, from which config, when.
std::string provenance_html(const ResultsDocument& res) {
  auto item = [](const std::string& k, const std::string& v) { return "<dt>" + html_escape(k) + "</dt><dd>" + html_escape(v) + "</dd>\n"; };
  auto flat = [](const nlohmann::json& v) { return v.is_string() ? v.get<std::string>() : v.dump(); };
  std::string o = item("config", res.config.name + (res.config.path.empty() ? "" : " (" + res.config.path + ")"));
  std::string date = "not recorded";
  if (res.written) {
    const std::time_t t = std::time_t(*res.written);
    char b[64];
    std::strftime(b, sizeof b, "%Y-%m-%d %H:%M:%S UTC", std::gmtime(&t));
    date = b;
  }
  o += item("written", date);
  if (!res.git_revision.empty()) o += item("git revision", res.git_revision);
  for (const auto* part : {&res.build, &res.machine})
    if (part->is_object())
      for (const auto& [k, v] : part->items()) o += item((part == &res.build ? "build " : "machine ") + k, flat(v));
  o += item("input", fmt::format("{}x{}, {} spp (tables), seeds {}", res.config.width, res.config.height, res.table_spp(),
                                 res.config.seeds.empty() ? std::string("-") : fmt::format("{}", fmt::join(res.config.seeds, ", "))));
  return o;
}

// ---------------------------------------------------------------------------------------------
// The scenes' image viewer

// Runs a Python script of reports/ on the folder (its lines logged by `log`). The scripts exit 2
// when results.json names an image that is missing or unreadable, naming the file and the key:
// bad input (InputError), as a malformed results.json is; any other failure is a WorkError.
void run_report_script(const std::string& name, std::vector<std::string> args, double timeout_seconds,
                       std::function<void(const std::string&)> log) {
  const std::string script = reports_dir() + "/" + name;
  std::vector<std::string> argv = {"/usr/bin/python3", script};
  argv.insert(argv.end(), args.begin(), args.end());
  Subprocess p({.argv = argv, .on_log_line = std::move(log)});
  const std::optional<ExitStatus> st = p.wait(timeout_seconds);
  if (!st) p.kill_group();
  auto last = [&] { return p.log_tail().empty() ? std::string("(no message)") : p.log_tail().back(); };
  if (st && st->exited && st->code == 2) throw InputError(last());
  if (!st || !st->ok()) throw WorkError(fmt::format("'{}' {}: {}", script, st ? st->describe() : "timed out", last()));
}

// reports/viewer.py writes the viewer's data (web/viewer/manifest.js and one script per image:
// linear half floats); reports/viewer.js, copied beside it, draws the viewer from them.
void write_viewer(const std::string& dir) {
  run_report_script("viewer.py", {dir}, 1800, [](const std::string& l) { spdlog::info("viewer.py: {}", l); });
  create_folder(dir + "/web/viewer");
  fs::copy_file(reports_dir() + "/viewer.js", dir + "/web/viewer/viewer.js", fs::copy_options::overwrite_existing);
}

// reports/video.py, for a run with sequences: an MP4 per sequence and input spp (videos/; with
// `videos` false, or without ffmpeg, none, the log and the page saying why) and the page's
// Sequences section (web/sequences.html, returned) linking them and the per-frame plots.
std::string write_sequences(const std::string& dir, const ResultsDocument& res, bool videos) {
  if (res.sequences.empty()) return "";
  std::vector<std::string> args = {dir};
  if (!videos) args.push_back("--no-video");
  run_report_script("video.py", args, 3600, [](const std::string& l) {
    if (l.rfind("warning: ", 0) == 0) spdlog::warn("video.py: {}", l.substr(9));
    else spdlog::info("video.py: {}", l);
  });
  return read_text_file(dir + "/web/sequences.html");
}

std::vector<std::string> run_plots(const std::string& dir) {
  const std::string script = reports_dir() + "/plots.py";
  const std::string cmd = fmt::format("/usr/bin/python3 '{}' '{}'", script, dir);
  if (std::system(cmd.c_str()) != 0) throw WorkError(fmt::format("plots failed: `{}`", cmd));
  std::vector<std::string> plots;
  for (const auto& e : fs::directory_iterator(dir + "/plots"))
    // The per-frame plots of sequences are shown in the page's Sequences section instead.
    if (e.path().extension() == ".png" && !e.path().filename().string().starts_with("sequence_"))
      plots.push_back("plots/" + e.path().filename().string());
  std::sort(plots.begin(), plots.end());
  return plots;
}

struct NamedTable {
  std::string stem;
  Table table;
  bool on_top = false;  // shown first on the page
  BestMark best = {};
};

// Table 1's method columns: from the second to the input's.
BestMark table1_best(const Table& t, const std::string& metric) {
  BestMark b{.on = true, .lower_is_better = metrics::metric(metric).lower_is_better, .first = 1, .last = t.header.size()};
  for (std::size_t c = 1; c < t.header.size(); ++c)
    if (t.header[c].rfind("input (", 0) == 0) b.last = c;
  return b;
}

std::vector<NamedTable> all_tables(const ResultsDocument& res) {
  std::vector<NamedTable> t;
  for (const auto& m : metrics::metric_names()) {
    Table t1 = table1(res, m);
    const BestMark b = table1_best(t1, m);
    t.push_back({"table1_" + m, std::move(t1), m == "mse", b});
  }
  if (!res.sequences.empty()) {
    Table st = sequence_table(res);
    const std::size_t cols = st.header.size() - 1;  // the input column is not marked
    t.push_back({"table1_sequences", std::move(st), true, {.on = true, .lower_is_better = true, .first = 3, .last = cols}});
  }
  t.push_back({"table2_time", table2(res), true});
  Table ft = filter_time_table(res);
  const std::size_t ft_cols = ft.header.size();
  t.push_back({"table2_filter_times", std::move(ft), true, {.on = true, .lower_is_better = true, .first = 2, .last = ft_cols}});
  t.push_back({"ratios", ratio_table(res, res.config.table2.filter_cpu), true});
  if (const Table v = versus_modern_table(res, res.config.table2.filter_cpu); !v.rows.empty())
    t.push_back({"versus_modern", v, true});
  t.push_back({"worse_blocks", worse_blocks_table(res), true});
  t.push_back({"speedup_measured", measured_speedup_table(res), true});
  t.push_back({"speedup", speedup_table(res), true});
  t.push_back({"ablation", ablation_table(res), true});
  if (!res.failures.empty()) t.insert(t.begin(), {"failures", failures_table(res), true});
  return t;
}

void write_page(const std::string& dir, const ResultsDocument& res, const std::vector<NamedTable>& tables,
                const std::vector<std::string>& plots, bool viewer, const std::string& sequences_html) {
  std::string tables_html, other_html, plots_html;
  for (const auto& t : tables) (t.on_top ? tables_html : other_html) += html_table(t.table, t.best);
  for (const auto& p : plots) {
    const std::string pdf = fs::path(p).replace_extension(".pdf").string();
    plots_html += fmt::format("<figure><img src=\"{0}\" alt=\"{0}\"><figcaption>{0}{1}</figcaption></figure>\n", p,
                              fs::exists(dir + "/" + pdf) ? fmt::format(" (<a href=\"{}\">PDF</a>)", pdf) : "");
  }
  std::string page = read_text_file(reports_dir() + "/template.html");
  auto replace = [&](const std::string& key, const std::string& value) {
    const std::string k = "{{" + key + "}}";
    for (std::size_t pos; (pos = page.find(k)) != std::string::npos;) page.replace(pos, k.size(), value);
  };
  replace("title", html_escape(res.config.name.empty() ? "results" : res.config.name));
  replace("provenance", provenance_html(res));
  replace("machine", html_escape(res.machine.dump()));
  replace("build", html_escape(res.build.dump()));
  replace("tables", tables_html);
  replace("other_tables", other_html);
  replace("plots", plots_html);
  replace("sequences", sequences_html);
  replace("sequences_nav", sequences_html.empty() ? "" : "<li><a href=\"#sequences\">sequences</a></li>");
  replace("viewer", viewer ? "<script src=\"web/viewer/manifest.js\"></script>\n<script src=\"web/viewer/viewer.js\"></script>"
                           : "<p>(written without images: <code>report --no-images</code>)</p>");
  write_text_atomic(dir + "/index.html", page);
}

}  // namespace

void write_report(const std::string& dir, const ReportOptions& opt) {
  const std::string path = dir + "/results.json";
  if (!fs::exists(path)) throw InputError(fmt::format("'{}' not found: run `denoisebench run CONFIG -o {}` first", path, dir));
  const ResultsDocument res = ResultsDocument::load(path);

  auto tables = all_tables(res);
  if (!opt.ranking_against.empty()) {
    const std::string other = opt.ranking_against + "/results.json";
    if (!fs::exists(other))
      throw InputError(fmt::format("--ranking-against: '{}' not found (a folder written by `denoisebench run`)", other));
    const ResultsDocument o = ResultsDocument::load(other);
    auto name = [](const ResultsDocument& d, const std::string& dir) {
      return d.config.name.empty() ? fs::path(dir).filename().string() : d.config.name;
    };
    std::string here_name = name(res, dir), other_name = name(o, opt.ranking_against);
    if (here_name == other_name)
      here_name = fs::path(dir).filename().string(), other_name = fs::path(opt.ranking_against).filename().string();
    tables.push_back({"ranking", ranking_table(res, o, here_name, other_name), true});
  }
  for (const auto& t : tables) write_table(dir, t.stem, t.table);
  spdlog::info("tables written to {}", dir);
  const std::vector<std::string> plots = opt.plots ? run_plots(dir) : std::vector<std::string>{};

  if (opt.images) write_viewer(dir);
  const std::string sequences_html = write_sequences(dir, res, opt.images);
  write_page(dir, res, tables, plots, opt.images, sequences_html);
  spdlog::info("report: {}/index.html", dir);
}

}  // namespace dnb::experiment
