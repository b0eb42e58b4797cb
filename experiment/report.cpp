// The report folder (experiment/report.h): tables as files, plots through reports/plots.py, and
// the static page with one image comparison per scene.
#include "experiment/report.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>

#include <fmt/format.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <spdlog/spdlog.h>

#include "core/atomic_file.h"
#include "core/errors.h"
#include "core/exr_io.h"
#include "metrics/metrics.h"

namespace fs = std::filesystem;

namespace dnb::experiment {

std::string reports_dir() {
  if (const char* s = std::getenv("DNB_SOURCE_DIR"); s && *s && fs::exists(fs::path(s) / "reports")) return (fs::path(s) / "reports").string();
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

void write_png(const cv::Mat& bgr8, const std::string& path) {
  fs::create_directories(fs::path(path).parent_path());
  std::vector<uchar> png;
  if (!cv::imencode(".png", bgr8, png)) throw WorkError(fmt::format("cannot encode '{}' as PNG", path));
  AtomicOutput out(path);
  out.write(png.data(), png.size());
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

// ---------------------------------------------------------------------------------------------
// One scene's comparison

// The 1/6-size window where `pick`'s FLIP error is largest (the top-left one without a map).
cv::Rect worst_crop(const std::string& dir, const CellRecord& pick, int width, int height) {
  const int cw = std::max(8, width / 6), ch = std::max(8, height / 6);
  cv::Rect crop(0, 0, cw, ch);
  const std::string flip = pick.file("error_flip");
  if (flip.empty()) return crop;
  Image e = read_rgb(dir + "/" + flip);
  cv::Mat m(e.height(), e.width(), CV_32F);
  for (int y = 0; y < e.height(); ++y)
    for (int x = 0; x < e.width(); ++x) m.at<float>(y, x) = e.at(x, y, 0);
  cv::Mat box;
  cv::boxFilter(m, box, -1, cv::Size(cw, ch), cv::Point(0, 0), false, cv::BORDER_CONSTANT);
  double best = -1;
  for (int y = 0; y + ch <= e.height(); y += 2)
    for (int x = 0; x + cw <= e.width(); x += 2)
      if (box.at<float>(y, x) > best) {
        best = box.at<float>(y, x);
        crop = {x, y, cw, ch};
      }
  return crop;
}

void write_crop(const std::string& dir, const cv::Mat& full, const cv::Rect& crop, const std::string& rel) {
  cv::Mat c;
  cv::resize(full(crop), c, cv::Size(), 4, 4, cv::INTER_NEAREST);
  write_png(c, dir + "/" + rel);
}

// The records of `scene` shown on the page: every non-plain record at the table's spp whose
// image is in the folder.
std::vector<const CellRecord*> shown_records(const ResultsDocument& res, const std::string& dir, const std::string& scene,
                                             int spp) {
  std::vector<const CellRecord*> recs;
  for (const auto& r : res.records)
    if (r.scene == scene && r.role != Role::Plain && r.spp == spp && !r.image().empty() && fs::exists(dir + "/" + r.image()))
      recs.push_back(&r);
  return recs;
}

std::string scene_section(const ResultsDocument& res, const std::string& dir, const std::string& s, int spp) {
  const auto recs = shown_records(res, dir, s, spp);
  if (recs.empty()) return "";
  const std::string ref_rel = recs.back()->reference.image;
  if (!fs::exists(dir + "/" + ref_rel)) return "";
  const Image ref = read_rgb(dir + "/" + ref_rel);
  const cv::Mat ref_png = srgb8(ref);
  write_png(ref_png, dir + "/" + png_of(ref_rel));
  // The first filtered method is shown first; the crop follows Table 2's CPU method's error.
  const CellRecord* first = recs.size() > 1 ? recs[1] : recs[0];
  const CellRecord* pick = first;
  for (const CellRecord* r : recs)
    if (r->method == res.config.table2.filter_cpu) pick = r;
  const cv::Rect crop = worst_crop(dir, *pick, ref.width(), ref.height());
  const std::string ref_crop = "web/" + s + "/crop_reference.png";
  write_crop(dir, ref_png, crop, ref_crop);
  std::string options, crops = fmt::format("<figure><img src=\"{}\" alt=\"reference crop\"><figcaption>reference</figcaption></figure>", ref_crop);
  for (const CellRecord* r : recs) {
    const cv::Mat png = srgb8(read_rgb(dir + "/" + r->image()));
    write_png(png, dir + "/" + png_of(r->image()));
    const std::string c_rel = "web/" + s + "/crop_" + r->method + ".png";
    write_crop(dir, png, crop, c_rel);
    std::string err_rel;
    if (const std::string flip = r->file("error_flip"); !flip.empty()) {
      err_rel = png_of(flip);
      write_png(false_colour(read_rgb(dir + "/" + flip)), dir + "/" + err_rel);
    }
    options += fmt::format("<option value=\"{}\" data-err=\"{}\"{}>{} (mse {})</option>", png_of(r->image()), err_rel,
                           r == first ? " selected" : "", html_escape(r->method), format_metric(r->metric("mse")));
    crops += fmt::format("<figure><img src=\"{}\" alt=\"{} crop\"><figcaption>{}</figcaption></figure>", c_rel,
                         html_escape(r->method), html_escape(r->method));
  }
  const std::string first_err = first->file("error_flip").empty() ? "" : png_of(first->file("error_flip"));
  return fmt::format(R"(<section class="scene">
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
                     html_escape(s), options, png_of(first->image()), png_of(ref_rel), first_err, first->reference.spp,
                     crop.x, crop.y, crop.width, crop.height, html_escape(pick->method), crops);
}

// The vendored comparison component travels with the page (opened from disk, no network).
void copy_vendor(const std::string& dir) {
  const fs::path vendor = fs::path(reports_dir()) / "vendor" / "img-comparison-slider";
  fs::create_directories(dir + "/web/vendor");
  for (const char* f : {"index.js", "styles.css", "LICENSE"})
    if (fs::exists(vendor / f)) fs::copy_file(vendor / f, fs::path(dir) / "web/vendor" / f, fs::copy_options::overwrite_existing);
}

std::vector<std::string> run_plots(const std::string& dir) {
  const std::string script = reports_dir() + "/plots.py";
  const std::string cmd = fmt::format("/usr/bin/python3 '{}' '{}'", script, dir);
  if (std::system(cmd.c_str()) != 0) throw WorkError(fmt::format("plots failed: `{}`", cmd));
  std::vector<std::string> plots;
  for (const auto& e : fs::directory_iterator(dir + "/plots"))
    if (e.path().extension() == ".png") plots.push_back("plots/" + e.path().filename().string());
  std::sort(plots.begin(), plots.end());
  return plots;
}

struct NamedTable {
  std::string stem;
  Table table;
  bool on_top = false;  // shown first on the page
};

std::vector<NamedTable> all_tables(const ResultsDocument& res) {
  std::vector<NamedTable> t;
  for (const auto& m : metrics::metric_names()) t.push_back({"table1_" + m, table1(res, m), m == "mse"});
  t.push_back({"table2_time", table2(res), true});
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
                const std::vector<std::string>& plots, const std::string& scenes_html) {
  std::string tables_html, other_html, plots_html;
  for (const auto& t : tables) (t.on_top ? tables_html : other_html) += html_table(t.table);
  for (const auto& p : plots) plots_html += fmt::format("<figure><img src=\"{}\" alt=\"{}\"></figure>\n", p, p);
  std::string page = read_text_file(reports_dir() + "/template.html");
  auto replace = [&](const std::string& key, const std::string& value) {
    const std::string k = "{{" + key + "}}";
    for (std::size_t pos; (pos = page.find(k)) != std::string::npos;) page.replace(pos, k.size(), value);
  };
  replace("title", html_escape(res.config.name.empty() ? "results" : res.config.name));
  replace("machine", html_escape(res.machine.dump()));
  replace("build", html_escape(res.build.dump()));
  replace("tables", tables_html);
  replace("other_tables", other_html);
  replace("plots", plots_html);
  replace("scenes", scenes_html);
  write_text_atomic(dir + "/index.html", page);
}

}  // namespace

void write_report(const std::string& dir, const ReportOptions& opt) {
  const std::string path = dir + "/results.json";
  if (!fs::exists(path)) throw InputError(fmt::format("'{}' not found: run `denoisebench run CONFIG -o {}` first", path, dir));
  const ResultsDocument res = ResultsDocument::load(path);

  const auto tables = all_tables(res);
  for (const auto& t : tables) write_table(dir, t.stem, t.table);
  spdlog::info("tables written to {}", dir);
  const std::vector<std::string> plots = opt.plots ? run_plots(dir) : std::vector<std::string>{};

  std::string scenes_html;
  if (opt.images) {
    for (const auto& s : res.scenes()) scenes_html += scene_section(res, dir, s, res.table_spp());
    copy_vendor(dir);
  }
  write_page(dir, res, tables, plots, scenes_html);
  spdlog::info("report: {}/index.html", dir);
}

}  // namespace dnb::experiment
