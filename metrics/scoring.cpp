#include "metrics/scoring.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>

#include <OpenImageIO/imageio.h>
#include <fmt/format.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "core/atomic_file.h"
#include "core/csv.h"
#include "core/errors.h"
#include "core/exr_io.h"
#include "core/file_names.h"
#include "interop/import.h"
#include "metrics/metrics.h"

namespace dnb::metrics {
namespace fs = std::filesystem;

namespace {

std::string lower_extension(const std::string& path) {
  std::string e = fs::path(path).extension().string();
  std::transform(e.begin(), e.end(), e.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  return e;
}

// An 8- or 16-bit PNG or JPEG: its values are display values, sRGB-encoded unless its header
// says linear (a PNG with gAMA 1.0), so they are decoded to linear light before scoring; without
// this a mid-grey 128 would be scored as radiance 0.502 instead of 0.216.
ScoredFile read_display_file(const std::string& path) {
  if (!fs::is_regular_file(path)) throw InputError(fmt::format("'{}': no such file", path));
  auto in = OIIO::ImageInput::open(path);
  if (!in) throw InputError(fmt::format("'{}': cannot open as an image: {}", path, OIIO::geterror()));
  const OIIO::ImageSpec spec = in->spec();
  const std::string fmt_name = in->format_name();
  if (fmt_name != "png" && fmt_name != "jpeg")
    throw InputError(fmt::format("'{}': a {} file; images are read as OpenEXR, PNG or JPEG", path, fmt_name));
  Image::check_size(spec.width, spec.height, spec.nchannels, path.c_str());
  std::vector<float> buf(std::size_t(spec.width) * spec.height * spec.nchannels);
  if (!in->read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::FLOAT, buf.data()))
    throw InputError(fmt::format("'{}': cannot read pixels: {}", path, in->geterror()));
  const std::string space = spec.get_string_attribute("oiio:ColorSpace");
  const bool linear = space == "linear" || space == "Linear" || space == "lin_srgb";
  ScoredFile f;
  f.path = path;
  f.eight_bit = true;
  f.note = fmt::format("{}-bit {} {}, {}", spec.format.size() * 8, linear ? "linear" : "sRGB",
                       fmt_name == "png" ? "PNG" : "JPEG", linear ? "read as linear" : "decoded to linear with the sRGB transfer");
  f.rgb = Image(spec.width, spec.height, 3);
  const int nc = spec.nchannels;
  const int colour = nc >= 3 ? 3 : 1;  // grey (+ alpha) spreads to R, G, B; alpha is ignored
  for (std::size_t i = 0; i < f.rgb.pixel_count(); ++i)
    for (int c = 0; c < 3; ++c) {
      const float v = buf[i * std::size_t(nc) + std::size_t(colour == 3 ? c : 0)];
      f.rgb.data()[i * 3 + std::size_t(c)] = linear ? v : float(srgb_decode(v));
    }
  return f;
}

}  // namespace

ScoredFile read_scored_file(const std::string& path, const ReadOptions& o) {
  const std::string ext = lower_extension(path);
  if (ext == ".png" || ext == ".jpg" || ext == ".jpeg") {
    if (!o.layer.empty())
      throw InputError(fmt::format("'{}': --layer {} names EXR channels, and this is a {} file", path, o.layer, ext));
    return read_display_file(path);
  }
  if (ext != ".exr")
    throw InputError(fmt::format("'{}': expected an OpenEXR (.exr), PNG (.png) or JPEG (.jpg) file", path));
  ScoredFile f;
  f.path = path;
  if (!o.layer.empty()) {
    const ExrChannels ch = read_exr_channels(path);
    std::string prefix = o.layer;
    if (prefix.back() == '.') prefix.pop_back();
    f.rgb = Image(ch.width, ch.height, 3);
    const char* suffix[3] = {"R", "G", "B"};
    for (int c = 0; c < 3; ++c) {
      const std::string name = prefix + "." + suffix[c];
      if (!ch.has(name)) {
        std::set<std::string> layers;
        for (const auto& n : ch.names) {
          const auto dot = n.rfind('.');
          if (dot != std::string::npos) layers.insert(n.substr(0, dot));
        }
        throw InputError(fmt::format("'{}': no channel '{}' (--layer {}); the file's layers: {}", path, name, o.layer,
                                     layers.empty() ? std::string("none") : fmt::format("{}", fmt::join(layers, ", "))));
      }
      const auto& p = ch.plane(name);
      for (std::size_t i = 0; i < p.size(); ++i) f.rgb.data()[i * 3 + std::size_t(c)] = p[i];
    }
    f.note = fmt::format("channels {}.R/G/B", prefix);
    return f;
  }
  interop::ImportReport report;
  AovFrame frame = interop::read_frame_as(path, o.input_format, {.layers = std::vector<std::string>{layer::kColor, layer::kVariance}},
                                          {layer::kColor},
                                          &report);
  if (report.format != "native") f.note = fmt::format("the colour of a {} frame", report.format);
  f.rgb = std::move(frame.layer(layer::kColor));
  if (frame.has(layer::kVariance)) f.variance = std::move(frame.layer(layer::kVariance));
  return f;
}

ScoreOutcome score(const ScoreRequest& q) {
  if (q.images.empty()) throw InputError("metrics: no image to score");
  ScoreOutcome out;
  ScoredFile ref = read_scored_file(q.reference, q.reference_read);
  std::vector<ScoredFile> images;
  for (const auto& p : q.images) images.push_back(read_scored_file(p, q.image_read));
  for (const ScoredFile* f : [&] {
         std::vector<const ScoredFile*> all{&ref};
         for (const auto& i : images) all.push_back(&i);
         return all;
       }())
    if (!f->note.empty()) out.notes.push_back(fmt::format("'{}': {}", f->path, f->note));
  std::vector<std::string> eight_bit;
  if (ref.eight_bit) eight_bit.push_back(ref.path);
  for (const auto& i : images)
    if (i.eight_bit) eight_bit.push_back(i.path);

  // The metrics: those asked for (each known, none twice), else every one the inputs allow.
  if (q.metrics.empty()) {
    for (const auto& m : all_metrics()) {
      if (m.needs_linear && !eight_bit.empty() && !q.linear_metrics_on_8bit) continue;
      out.metrics.push_back(m.name);
    }
    if (out.metrics.size() < all_metrics().size())
      out.notes.push_back(fmt::format("8-bit input ({}): scored on the 8-bit metrics only; the linear ones "
                                      "(mse_hdr, relmse, ...) need --linear-metrics-on-8bit",
                                      fmt::join(eight_bit, ", ")));
  } else {
    for (const auto& name : q.metrics) {
      const MetricInfo& m = metric(name);  // InputError listing the valid names
      if (std::find(out.metrics.begin(), out.metrics.end(), name) != out.metrics.end())
        throw InputError(fmt::format("--metric {} given twice", name));
      if (m.needs_linear && !eight_bit.empty() && !q.linear_metrics_on_8bit)
        throw InputError(fmt::format("--metric {} scores linear radiance, and {} holds 8-bit display values clipped "
                                     "to [0, 1]: add --linear-metrics-on-8bit to score it anyway",
                                     name, fmt::join(eight_bit, ", ")));
      out.metrics.push_back(name);
    }
  }

  const Image* variance = ref.variance.empty() ? nullptr : &ref.variance;
  if (variance) {
    out.reference_has_variance = true;
    try {
      out.reference_unconverged_share = unconverged_share(ref.rgb, *variance);
      out.reference_error = reference_error(ref.rgb, *variance);
    } catch (const InputError& e) {
      throw InputError(fmt::format("'{}': {}", q.reference, e.what()));
    }
  }
  if (std::find(out.metrics.begin(), out.metrics.end(), "hdrflip") != out.metrics.end())
    out.hdrflip_exposures = hdrflip_exposures(ref.rgb);
  // Error-map file names: the image's stem, numbered when two images share one.
  std::map<std::string, int> stem_count;
  const auto stem_of = [](const std::string& p) { return file_names::mapped(fs::path(p).stem().string()); };
  for (const auto& p : q.images) ++stem_count[stem_of(p)];
  if (!q.error_maps_dir.empty()) create_folder(q.error_maps_dir);
  for (std::size_t k = 0; k < images.size(); ++k) {
    const ScoredFile& im = images[k];
    check_pair(im.rgb, ref.rgb, "'" + im.path + "'", "'" + ref.path + "'");
    ImageScore row;
    row.image = im.path;
    std::string stem = stem_of(im.path);
    if (stem_count[stem] > 1) stem = fmt::format("{}-{}", k + 1, stem);
    for (const auto& name : out.metrics) {
      const MetricInfo& m = metric(name);
      MetricResult r = m.compute(im.rgb, ref.rgb, variance);
      row.values.emplace_back(name, r.value);
      if (m.pooled) row.pooled[name] = pool_flip(r.map);
      if (q.error_maps_dir.empty() || r.map.empty()) continue;
      const std::string base = (fs::path(q.error_maps_dir) / (stem + "." + name)).string();
      Image grey(r.map.width(), r.map.height(), 3);
      for (std::size_t p = 0; p < r.map.pixel_count(); ++p)
        for (int c = 0; c < 3; ++c) grey.data()[3 * p + std::size_t(c)] = r.map.data()[p];
      write_rgb(grey, base + ".exr", {{"metric", name}, {"image", im.path}, {"reference", ref.path}});
      // FLIP's maps (and 1 - SSIM) live in [0, 1]; the others are shown up to their 99th
      // percentile, so that one firefly does not turn the rest of the map black.
      double hi = 1.0;
      if (!m.unit_map) {
        std::vector<float> v(r.map.data(), r.map.data() + r.map.size());
        std::nth_element(v.begin(), v.begin() + std::ptrdiff_t(v.size() * 99 / 100), v.end());
        hi = std::max(double(v[v.size() * 99 / 100]), 1e-12);
      }
      write_png(false_colour_with_bar(r.map, 0.0, hi, m.map_name()), base + ".png");
      row.maps.push_back(base + ".exr");
      row.maps.push_back(base + ".png");
    }
    out.rows.push_back(std::move(row));
  }
  return out;
}

Threshold parse_threshold(const std::string& text, bool above) {
  const std::string opt = above ? "--fail-above" : "--fail-below";
  const auto eq = text.find('=');
  if (eq == std::string::npos || eq == 0)
    throw InputError(fmt::format("{} '{}': expected METRIC=VALUE (e.g. mse=12.5)", opt, text));
  Threshold t;
  t.metric = text.substr(0, eq);
  t.above = above;
  metric(t.metric);  // InputError listing the valid names
  const std::string v = text.substr(eq + 1);
  try {
    std::size_t used = 0;
    t.value = std::stod(v, &used);
    if (used != v.size() || !std::isfinite(t.value)) throw std::invalid_argument(v);
  } catch (const std::exception&) {
    throw InputError(fmt::format("{} '{}': '{}' is not a finite number", opt, text, v));
  }
  return t;
}

std::vector<std::string> failed_thresholds(const ScoreOutcome& outcome, const std::vector<Threshold>& thresholds) {
  std::vector<std::string> out;
  for (const auto& t : thresholds)
    if (std::find(outcome.metrics.begin(), outcome.metrics.end(), t.metric) == outcome.metrics.end())
      throw InputError(fmt::format("--fail-{} {}: the metric is not among those scored ({})", t.above ? "above" : "below",
                                   t.metric, fmt::join(outcome.metrics, ", ")));
  for (const auto& row : outcome.rows)
    for (const auto& t : thresholds)
      for (const auto& [name, v] : row.values) {
        if (name != t.metric) continue;
        if (!std::isfinite(v) && !(name == "psnr" && v > 0))
          out.push_back(fmt::format("'{}': {} is n/a and cannot be checked against {} {}", row.image, name,
                                    t.above ? "at most" : "at least", t.value));
        else if (t.above ? v > t.value : v < t.value)
          out.push_back(fmt::format("'{}': {} {:.9g} is {} {:.9g}", row.image, name, v, t.above ? "above" : "below", t.value));
      }
  return out;
}

void append_csv(const std::string& path, const std::string& reference, const ScoreOutcome& outcome) {
  std::vector<std::string> header{"image", "reference"};
  header.insert(header.end(), outcome.metrics.begin(), outcome.metrics.end());
  std::string text;
  if (fs::exists(path)) {
    std::ifstream f(path, std::ios::binary);
    std::stringstream ss;
    ss << f.rdbuf();
    text = ss.str();
    const std::string first = text.substr(0, text.find('\n'));
    if (csv::split(first) != header)
      throw InputError(fmt::format("'{}': its columns are '{}', this call scores '{}': rows would land under the wrong "
                                   "metric (write to a new file, or choose the same --metric list)",
                                   path, first, csv::line(header)));
    if (!text.empty() && text.back() != '\n') text += '\n';
  } else {
    text = csv::line(header) + "\n";
  }
  for (const auto& row : outcome.rows) {
    std::vector<std::string> fields{row.image, reference};
    for (const auto& [name, v] : row.values)
      // The shortest text that reads back as the same double: the CSV holds the scores exactly.
      fields.push_back(std::isfinite(v) ? fmt::format("{}", v) : (name == "psnr" && v > 0 ? "inf" : ""));
    text += csv::line(fields) + "\n";
  }
  write_text_atomic(path, text);
}

FalseColour false_colour_with_bar(const Image& map, double lo, double hi, const std::string& label) {
  const int w = map.width(), h = map.height();
  // The bar: a strip under the image, magma from lo to hi, with both ends and the metric written.
  const int bar = 12, text_h = 16, pad = 2;
  const int total_w = std::max(w, 160);
  cv::Mat grey(h + pad + bar + text_h, total_w, CV_8UC1, cv::Scalar(0));
  const double span = hi > lo ? hi - lo : 1.0;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const double t = std::clamp((double(map.at(x, y, 0)) - lo) / span, 0.0, 1.0);
      grey.at<uchar>(y, x) = uchar(std::lround(255 * t));
    }
  for (int y = h + pad; y < h + pad + bar; ++y)
    for (int x = 0; x < total_w; ++x) grey.at<uchar>(y, x) = uchar(std::lround(255.0 * x / std::max(1, total_w - 1)));
  cv::Mat colour;
  cv::applyColorMap(grey, colour, cv::COLORMAP_MAGMA);
  colour(cv::Rect(0, h + pad + bar, total_w, text_h)).setTo(cv::Scalar(255, 255, 255));
  if (w < total_w) colour(cv::Rect(w, 0, total_w - w, h + pad)).setTo(cv::Scalar(255, 255, 255));
  colour(cv::Rect(0, h, total_w, pad)).setTo(cv::Scalar(255, 255, 255));
  const auto put = [&](const std::string& s, int x) {
    cv::putText(colour, s, cv::Point(x, h + pad + bar + text_h - 4), cv::FONT_HERSHEY_PLAIN, 0.8, cv::Scalar(0, 0, 0), 1,
                cv::LINE_AA);
  };
  const std::string lo_s = fmt::format("{:.3g}", lo), hi_s = fmt::format("{:.3g}", hi);
  put(lo_s, 1);
  int base = 0;
  const int hi_w = cv::getTextSize(hi_s, cv::FONT_HERSHEY_PLAIN, 0.8, 1, &base).width;
  put(hi_s, total_w - hi_w - 1);
  const int label_w = cv::getTextSize(label, cv::FONT_HERSHEY_PLAIN, 0.8, 1, &base).width;
  put(label, (total_w - label_w) / 2);
  FalseColour fc;
  fc.width = colour.cols;
  fc.height = colour.rows;
  fc.bgr.assign(colour.data, colour.data + colour.total() * colour.elemSize());
  return fc;
}

void write_png(const FalseColour& fc, const std::string& path) {
  cv::Mat m(fc.height, fc.width, CV_8UC3, const_cast<unsigned char*>(fc.bgr.data()));
  std::vector<uchar> png;
  if (!cv::imencode(".png", m, png)) throw WorkError(fmt::format("cannot encode '{}' as PNG", path));
  AtomicOutput out(path);
  out.write(png.data(), png.size());
  out.commit();
}

}  // namespace dnb::metrics
