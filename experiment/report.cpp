#include "experiment/report.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <set>

#include <fmt/format.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <spdlog/spdlog.h>

#include "core/atomic_file.h"
#include "core/errors.h"
#include "core/exr_io.h"
#include "metrics/metrics.h"

namespace fs = std::filesystem;
using nlohmann::json;

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
  auto field = [](const std::string& s) {
    if (s.find_first_of(",\"\n") == std::string::npos) return s;
    std::string q = "\"";
    for (char ch : s) q += ch == '"' ? std::string("\"\"") : std::string(1, ch);
    return q + "\"";
  };
  std::string o;
  for (const auto* r : [&] {
         std::vector<const std::vector<std::string>*> all{&header};
         for (const auto& row : rows) all.push_back(&row);
         return all;
       }()) {
    for (std::size_t i = 0; i < r->size(); ++i) o += (i ? "," : "") + field((*r)[i]);
    o += "\n";
  }
  return o;
}

std::string Table::latex() const {
  auto esc = [](const std::string& s) {
    std::string o;
    for (char ch : s) {
      if (ch == '_' || ch == '%' || ch == '&' || ch == '#') o += '\\';
      o += ch;
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
// Tables from results.json

namespace {

std::vector<std::string> scenes_of(const json& res) {
  std::vector<std::string> s;
  if (res.contains("config") && res["config"].contains("scenes")) return res["config"]["scenes"].get<std::vector<std::string>>();
  for (const auto& r : res.at("records"))
    if (std::find(s.begin(), s.end(), r.at("scene").get<std::string>()) == s.end()) s.push_back(r.at("scene"));
  return s;
}

// The input spp the tables are drawn for: the first of the config's list.
int table_spp(const json& res) {
  if (res.contains("config") && res["config"].contains("spp") && !res["config"]["spp"].empty()) return res["config"]["spp"][0];
  for (const auto& r : res.at("records"))
    if (r.value("role", "") != "plain") return r.at("spp");
  return 0;
}

std::vector<std::string> methods_of(const json& res, const std::string& role) {
  std::vector<std::string> m;
  for (const auto& r : res.at("records"))
    if (r.value("role", "") == role && std::find(m.begin(), m.end(), r.at("method").get<std::string>()) == m.end())
      m.push_back(r.at("method"));
  return m;
}

const json* find(const json& res, const std::string& scene, const std::string& method, int spp) {
  for (const auto& r : res.at("records"))
    if (r.at("scene") == scene && r.at("method") == method && r.at("spp") == spp) return &r;
  return nullptr;
}

std::string fmt_metric(const json& v) { return v.is_number() ? fmt::format("{:.4g}", v.get<double>()) : "n/a"; }
std::string fmt_time(double s) { return fmt::format("{:.2f}", s); }

// The share of the scene's reference pixels mse_converged leaves out, as the run recorded it.
std::string unconverged_cell(const json& res, const std::string& scene) {
  for (const auto& r : res.at("records"))
    if (r.at("scene") == scene && r.contains("reference") && r["reference"].contains("unconverged_share") &&
        r["reference"]["unconverged_share"].is_number())
      return fmt::format("{:.3f}%", 100.0 * r["reference"]["unconverged_share"].get<double>());
  return "n/a";
}

}  // namespace

Table table1(const json& res, const std::string& metric) {
  Table t;
  const int spp = table_spp(res);
  const auto methods = methods_of(res, "method");
  t.title = fmt::format("Table 1: {} at {} spp input", metric, spp);
  t.header = {"scene"};
  for (const auto& m : methods) t.header.push_back(m);
  t.header.push_back(fmt::format("input ({} spp)", spp));
  for (const auto& s : scenes_of(res)) {
    std::vector<std::string> row{s};
    for (const auto& m : methods) {
      const json* r = find(res, s, m, spp);
      row.push_back(r ? fmt_metric(r->at("metrics").value(metric, json(nullptr))) : "n/a");
    }
    const json* in = find(res, s, "input", spp);
    row.push_back(in ? fmt_metric(in->at("metrics").value(metric, json(nullptr))) : "n/a");
    if (metric == "mse_converged") row.push_back(unconverged_cell(res, s));
    t.rows.push_back(row);
  }
  if (metric == "mse_converged") t.header.push_back("reference pixels left out");
  const auto& info = metrics::metric(metric);
  t.note = fmt::format("{}; {} is better. From results.json.", info.description, info.lower_is_better ? "lower" : "higher");
  return t;
}

Table ratio_table(const json& res, const std::string& method) {
  Table t;
  const int spp = table_spp(res);
  std::vector<std::string> others;
  for (const auto& m : methods_of(res, "method"))
    if (m != method) others.push_back(m);
  t.title = fmt::format("Ratios: {}'s error over each method's at {} spp input", method, spp);
  t.header = {"scene", "metric"};
  for (const auto& m : others) t.header.push_back(m);
  for (const auto& s : scenes_of(res)) {
    const json* p = find(res, s, method, spp);
    for (const char* metric : {"mse", "mse_converged"}) {
      std::vector<std::string> row{s, metric};
      for (const auto& m : others) {
        const json* r = find(res, s, m, spp);
        const json a = p ? p->at("metrics").value(metric, json(nullptr)) : json(nullptr);
        const json b = r ? r->at("metrics").value(metric, json(nullptr)) : json(nullptr);
        row.push_back(a.is_number() && b.is_number() && b.get<double>() > 0
                          ? fmt::format("{:.2f}", a.get<double>() / b.get<double>())
                          : "n/a");
      }
      t.rows.push_back(row);
    }
  }
  t.note = fmt::format("Below 1: {} has the lower error. mse_converged leaves out the reference's unconverged "
                       "pixels (Table 1, mse_converged). From results.json.",
                       method);
  return t;
}

std::string table2_cpu_method(const json& res) {
  if (res.contains("config") && res["config"].contains("table2"))
    return res["config"]["table2"].value("filter_cpu", std::string("proposed"));
  return "proposed";
}

Table table2(const json& res) {
  Table t;
  const int spp = table_spp(res);
  const std::string cpu = table2_cpu_method(res);
  std::string ocl, ic = "irradiance_cache";
  if (res.contains("config") && res["config"].contains("table2")) {
    const auto& c = res["config"]["table2"];
    ocl = c.value("filter_opencl", ocl);
    ic = c.value("irradiance_cache", ic);
  }
  int ref_spp = 0;
  for (const auto& r : res.at("records")) if (r.contains("reference")) ref_spp = r["reference"].value("spp", 0);
  t.title = "Table 2: time in seconds";
  t.header = {"scene", fmt::format("render input ({} spp)", spp), fmt::format("filter CPU ({})", cpu), "total CPU",
              ocl.empty() ? "filter OpenCL" : fmt::format("filter OpenCL ({})", ocl), "total OpenCL", "irradiance cache",
              fmt::format("reference ({} spp)", ref_spp)};
  for (const auto& s : scenes_of(res)) {
    const json* in = find(res, s, "input", spp);
    const json* c = find(res, s, cpu, spp);
    const json* o = ocl.empty() ? nullptr : find(res, s, ocl, spp);
    const json* i = find(res, s, ic, spp);
    const json* any = in ? in : c;
    auto time = [](const json* r, const char* k) { return r ? fmt_time(r->at("times").at(k).get<double>()) : std::string("n/a"); };
    double input = in ? in->at("times").at("input_render").get<double>() : NAN;
    t.rows.push_back({s, in ? fmt_time(input) : "n/a", time(c, "filter"),
                      c && in ? fmt_time(input + c->at("times").at("filter").get<double>()) : "n/a", time(o, "filter"),
                      o && in ? fmt_time(input + o->at("times").at("filter").get<double>()) : "n/a", time(i, "total"),
                      any ? fmt_time(any->at("reference").at("seconds").get<double>()) : "n/a"});
  }
  t.note = "Wall-clock seconds on the machine named in results.json; filter times are medians of repeated runs after a warm-up for methods under a second. n/a: the method was not in the run.";
  return t;
}

Table speedup_table(const json& res, const std::string& metric) {
  Table t;
  const int spp = table_spp(res);
  t.title = fmt::format("Speed-up over plain path tracing ({} at {} spp input)", metric, spp);
  t.header = {"scene", "method", metric, "total time (s)", "plain PT spp needed", "plain PT time needed (s)", "speed-up"};
  std::string fits;
  for (const auto& s : scenes_of(res)) {
    std::vector<double> times, errs, spps;
    for (const auto& r : res.at("records"))
      if (r.at("scene") == s && r.value("role", "") == "plain" && r.at("metrics").value(metric, json(nullptr)).is_number()) {
        times.push_back(r.at("times").at("total"));
        errs.push_back(r.at("metrics").at(metric));
        spps.push_back(r.at("spp").get<int>());
      }
    const PowerFit err_t = fit_power_law(times, errs);
    // time = c * spp^d, fitted as a power law of spp (b = -d).
    const PowerFit t_spp = fit_power_law(spps, times);
    if (!err_t.ok) {
      fits += fmt::format("- {}: too few plain path tracing points to fit ({}).\n", s, times.size());
      continue;
    }
    const double tmax = *std::max_element(times.begin(), times.end());
    fits += fmt::format("- {}: {} = {:.4g} * t^-{:.3f} over {} plain path tracing renders ({}..{} spp).\n", s, metric,
                        err_t.a, err_t.b, times.size(), *std::min_element(spps.begin(), spps.end()),
                        *std::max_element(spps.begin(), spps.end()));
    for (const auto& m : methods_of(res, "method")) {
      const json* r = find(res, s, m, spp);
      if (!r || !r->at("metrics").value(metric, json(nullptr)).is_number()) continue;
      const double e = r->at("metrics").at(metric), total = r->at("times").at("total");
      const double t_need = err_t.inverse(e);
      const double spp_need = t_spp.a > 0 ? std::pow(t_need / t_spp.a, -1.0 / t_spp.b) : NAN;
      t.rows.push_back({s, m, fmt_metric(json(e)), fmt_time(total), std::isfinite(spp_need) ? fmt::format("{:.0f}", spp_need) : "n/a",
                        fmt::format("{:.3g}{}", t_need, t_need > tmax ? " (extrapolated)" : ""),
                        fmt::format("{:.1f}x", t_need / total)});
    }
  }
  t.note = "Fits (least squares in log-log over the plain path tracing renders of the run):\n\n" + fits +
           "\nspeed-up = time plain path tracing needs to reach the method's error / the method's total time (input render + filtering).";
  return t;
}

Table ablation_table(const json& res, const std::string& metric) {
  Table t;
  const int spp = table_spp(res);
  auto variants = methods_of(res, "ablation");
  std::set<std::string> bases;
  for (const auto& r : res.at("records"))
    if (r.value("role", "") == "ablation") bases.insert(r.value("base_method", ""));
  std::vector<std::string> rows_m(bases.begin(), bases.end());
  rows_m.insert(rows_m.end(), variants.begin(), variants.end());
  t.title = fmt::format("Ablation: {} at {} spp input (each row switches one part off)", metric, spp);
  t.header = {"variant"};
  const auto scenes = scenes_of(res);
  for (const auto& s : scenes) t.header.push_back(s);
  for (const auto& m : rows_m) {
    std::vector<std::string> row{m};
    for (const auto& s : scenes) {
      const json* r = find(res, s, m, spp);
      const json* base = r ? find(res, s, r->value("base_method", m), spp) : nullptr;
      std::string cell = r ? fmt_metric(r->at("metrics").value(metric, json(nullptr))) : "n/a";
      if (r && base && base != r && r->at("metrics").value(metric, json(nullptr)).is_number() &&
          base->at("metrics").value(metric, json(nullptr)).is_number() && base->at("metrics").at(metric).get<double>() != 0)
        cell += fmt::format(" ({:+.0f}%)", 100.0 * (r->at("metrics").at(metric).get<double>() / base->at("metrics").at(metric).get<double>() - 1));
      row.push_back(cell);
    }
    t.rows.push_back(row);
  }
  t.note = variants.empty() ? "No ablation variants in this run ([[variant]] group = \"ablation\")."
                            : "Percentages: change against the full method in the first row(s).";
  return t;
}

// ---------------------------------------------------------------------------------------------
// The report folder

std::string reports_dir() {
  if (const char* s = std::getenv("DNB_SOURCE_DIR"); s && *s && fs::exists(fs::path(s) / "reports")) return (fs::path(s) / "reports").string();
  return (fs::path(DNB_SOURCE_DIR) / "reports").string();
}

namespace {

void write_table(const std::string& dir, const std::string& stem, const Table& t) {
  write_text_atomic(dir + "/" + stem + ".md", t.markdown());
  write_text_atomic(dir + "/" + stem + ".csv", t.csv());
  write_text_atomic(dir + "/" + stem + ".tex", t.latex());
}

void write_png(const cv::Mat& bgr8, const std::string& path) {
  fs::create_directories(fs::path(path).parent_path());
  AtomicOutput out(path);
  if (!cv::imwrite(out.temp_path(), bgr8)) throw WorkError(fmt::format("cannot write '{}'", path));
  out.commit();
}

cv::Mat srgb8(const Image& rgb) {
  Image s = metrics::to_srgb8(rgb);
  cv::Mat m(rgb.height(), rgb.width(), CV_8UC3);
  for (int y = 0; y < rgb.height(); ++y)
    for (int x = 0; x < rgb.width(); ++x)
      m.at<cv::Vec3b>(y, x) = {uchar(s.at(x, y, 2)), uchar(s.at(x, y, 1)), uchar(s.at(x, y, 0))};
  return m;
}

// FLIP's own display: its error in [0,1] through the magma colour map.
cv::Mat false_colour(const Image& err) {
  cv::Mat g(err.height(), err.width(), CV_8UC1);
  for (int y = 0; y < err.height(); ++y)
    for (int x = 0; x < err.width(); ++x) g.at<uchar>(y, x) = uchar(std::lround(255 * std::clamp(err.at(x, y, 0), 0.0f, 1.0f)));
  cv::Mat c;
  cv::applyColorMap(g, c, cv::COLORMAP_MAGMA);
  return c;
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

std::string html_table(const Table& t) {
  std::string o = "<h3>" + html_escape(t.title) + "</h3>\n<table><thead><tr>";
  for (const auto& h : t.header) o += "<th>" + html_escape(h) + "</th>";
  o += "</tr></thead><tbody>\n";
  for (const auto& r : t.rows) {
    o += "<tr>";
    for (const auto& c : r) o += "<td>" + html_escape(c) + "</td>";
    o += "</tr>\n";
  }
  o += "</tbody></table>\n";
  if (!t.note.empty()) o += "<p class=\"note\">" + html_escape(t.note) + "</p>\n";
  return o;
}

std::string png_of(const std::string& exr_rel) { return "web/" + fs::path(exr_rel).replace_extension(".png").string(); }

}  // namespace

void write_report(const std::string& dir, const ReportOptions& opt) {
  const std::string path = dir + "/results.json";
  if (!fs::exists(path)) throw InputError(fmt::format("'{}' not found: run `denoisebench run CONFIG -o {}` first", path, dir));
  json res;
  try {
    res = json::parse(read_text_file(path));
    if (!res.contains("records") || !res["records"].is_array()) throw std::runtime_error("no 'records' array");
  } catch (const std::exception& e) {
    throw InputError(fmt::format("'{}' is not a results file: {}", path, e.what()));
  }

  std::vector<std::pair<std::string, Table>> tables;
  for (const auto& m : metrics::metric_names()) tables.emplace_back("table1_" + m, table1(res, m));
  tables.emplace_back("table2_time", table2(res));
  for (const auto& [stem, t] : tables) write_table(dir, stem, t);
  const Table sp = speedup_table(res), ab = ablation_table(res), ra = ratio_table(res, table2_cpu_method(res));
  write_table(dir, "speedup", sp);
  write_table(dir, "ablation", ab);
  write_table(dir, "ratios", ra);
  spdlog::info("tables written to {}", dir);

  std::vector<std::string> plots;
  if (opt.plots) {
    const std::string script = reports_dir() + "/plots.py";
    const std::string cmd = fmt::format("/usr/bin/python3 '{}' '{}'", script, dir);
    if (std::system(cmd.c_str()) != 0) throw WorkError(fmt::format("plots failed: `{}`", cmd));
    for (const auto& e : fs::directory_iterator(dir + "/plots"))
      if (e.path().extension() == ".png") plots.push_back("plots/" + e.path().filename().string());
    std::sort(plots.begin(), plots.end());
  }

  // Per-scene image comparison: PNGs for the browser, FLIP maps, crops of the same regions.
  std::string scenes_html;
  const int spp = table_spp(res);
  if (opt.images) {
    for (const auto& s : scenes_of(res)) {
      std::vector<const json*> recs;
      std::string ref_rel;
      for (const auto& r : res["records"])
        if (r.at("scene") == s && r.value("role", "") != "plain" && r.at("spp") == spp && r.contains("files") &&
            fs::exists(dir + "/" + r["files"].value("image", ""))) {
          recs.push_back(&r);
          ref_rel = r["reference"].value("image", "");
        }
      if (recs.empty() || !fs::exists(dir + "/" + ref_rel)) continue;
      const Image ref = read_rgb(dir + "/" + ref_rel);
      write_png(srgb8(ref), dir + "/" + png_of(ref_rel));
      // Crop: the 1/6-size window where the first filtered method's FLIP error is largest.
      const json* pick = recs.size() > 1 ? recs[1] : recs[0];
      for (const json* r : recs)
        if (r->at("method") == res["config"]["table2"].value("filter_cpu", "")) pick = r;
      const int cw = std::max(8, ref.width() / 6), ch = std::max(8, ref.height() / 6);
      cv::Rect crop(0, 0, cw, ch);
      if (pick->at("files").contains("error_flip")) {
        Image e = read_rgb(dir + "/" + pick->at("files")["error_flip"].get<std::string>());
        cv::Mat m(e.height(), e.width(), CV_32F), integ;
        for (int y = 0; y < e.height(); ++y) for (int x = 0; x < e.width(); ++x) m.at<float>(y, x) = e.at(x, y, 0);
        cv::Mat box;
        cv::boxFilter(m, box, -1, cv::Size(cw, ch), cv::Point(0, 0), false, cv::BORDER_CONSTANT);
        double best = -1;
        for (int y = 0; y + ch <= e.height(); y += 2)
          for (int x = 0; x + cw <= e.width(); x += 2)
            if (box.at<float>(y, x) > best) { best = box.at<float>(y, x); crop = {x, y, cw, ch}; }
      }
      auto crop_png = [&](const cv::Mat& full, const std::string& rel) {
        cv::Mat c;
        cv::resize(full(crop), c, cv::Size(), 4, 4, cv::INTER_NEAREST);
        write_png(c, dir + "/" + rel);
      };
      const std::string ref_crop = "web/" + s + "/crop_reference.png";
      crop_png(srgb8(ref), ref_crop);
      std::string options, panels, crops = fmt::format("<figure><img src=\"{}\" alt=\"reference crop\"><figcaption>reference</figcaption></figure>", ref_crop);
      for (const json* r : recs) {
        const std::string m = r->at("method");
        const std::string img_rel = r->at("files")["image"];
        const Image im = read_rgb(dir + "/" + img_rel);
        const cv::Mat png = srgb8(im);
        write_png(png, dir + "/" + png_of(img_rel));
        const std::string c_rel = "web/" + s + "/crop_" + m + ".png";
        crop_png(png, c_rel);
        std::string err_rel;
        if (r->at("files").contains("error_flip")) {
          err_rel = png_of(r->at("files")["error_flip"]);
          write_png(false_colour(read_rgb(dir + "/" + r->at("files")["error_flip"].get<std::string>())), dir + "/" + err_rel);
        }
        options += fmt::format("<option value=\"{}\" data-err=\"{}\"{}>{} (mse {})</option>", png_of(img_rel), err_rel,
                               r == (recs.size() > 1 ? recs[1] : recs[0]) ? " selected" : "", html_escape(m), fmt_metric(r->at("metrics").value("mse", json(nullptr))));
        crops += fmt::format("<figure><img src=\"{}\" alt=\"{} crop\"><figcaption>{}</figcaption></figure>", c_rel, html_escape(m), html_escape(m));
      }
      const json* first = recs.size() > 1 ? recs[1] : recs[0];
      const std::string first_png = png_of(first->at("files")["image"]);
      const std::string first_err = first->at("files").contains("error_flip") ? png_of(first->at("files")["error_flip"]) : "";
      scenes_html += fmt::format(R"(<section class="scene">
<h3>{0}</h3>
<label>method <select class="method">{1}</select></label>
<label>exposure <input class="exposure" type="range" min="-4" max="4" step="0.25" value="0"> <output>0</output> stops</label>
<div class="compare">
<img-comparison-slider><img slot="first" class="left" src="{2}" alt="method"><img slot="second" src="{3}" alt="reference"></img-comparison-slider>
<figure><img class="err" src="{4}" alt="FLIP error"><figcaption>FLIP error (magma, 0..1)</figcaption></figure>
</div>
<p>Left: method, right: reference ({5} spp). Crops of the region (x {6}, y {7}, {8}x{9}) where {10}'s FLIP error is largest:</p>
<div class="crops">{11}</div>
</section>
)",
                                 html_escape(s), options, first_png, png_of(ref_rel), first_err,
                                 first->at("reference").value("spp", 0), crop.x, crop.y, crop.width, crop.height,
                                 html_escape(pick->at("method").get<std::string>()), crops);
    }
    // The vendored comparison component travels with the page (opened from disk, no network).
    const fs::path vendor = fs::path(reports_dir()) / "vendor" / "img-comparison-slider";
    fs::create_directories(dir + "/web/vendor");
    for (const char* f : {"index.js", "styles.css", "LICENSE"})
      if (fs::exists(vendor / f)) fs::copy_file(vendor / f, fs::path(dir) / "web/vendor" / f, fs::copy_options::overwrite_existing);
  }

  std::string tables_html;
  for (const auto& [stem, t] : tables)
    if (stem == "table1_mse" || stem == "table2_time") tables_html += html_table(t);
  tables_html += html_table(ra) + html_table(sp) + html_table(ab);
  std::string other_html;
  for (const auto& [stem, t] : tables)
    if (stem != "table1_mse" && stem != "table2_time") other_html += html_table(t);
  std::string plots_html;
  for (const auto& p : plots) plots_html += fmt::format("<figure><img src=\"{}\" alt=\"{}\"></figure>\n", p, p);

  std::string page = read_text_file(reports_dir() + "/template.html");
  auto replace = [&](const std::string& key, const std::string& value) {
    const std::string k = "{{" + key + "}}";
    for (std::size_t pos; (pos = page.find(k)) != std::string::npos;) page.replace(pos, k.size(), value);
  };
  std::string title = res.contains("config") ? res["config"].value("name", "results") : "results";
  replace("title", html_escape(title));
  replace("machine", html_escape(res.value("machine", json::object()).dump()));
  replace("build", html_escape(res.value("build", json::object()).dump()));
  replace("tables", tables_html);
  replace("other_tables", other_html);
  replace("plots", plots_html);
  replace("scenes", scenes_html);
  write_text_atomic(dir + "/index.html", page);
  spdlog::info("report: {}/index.html", dir);
}

}  // namespace dnb::experiment
