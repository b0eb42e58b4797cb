// Applying a mapping to a foreign EXR's channels (interop/import.h).
#include "interop/import.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <set>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "core/errors.h"
#include "core/exr_io.h"

namespace dnb::interop {

namespace {

// Suffix spellings of a 3-component pass: "Pass.R" (OpenEXR's layer.channel convention) and,
// for pbrt-v4's first GBufferFilm, "Passr"/"Passx" run together ("Px", "Nsx").
const std::vector<std::vector<std::string>> kTriples = {{"R", "G", "B"}, {"X", "Y", "Z"}, {"r", "g", "b"}, {"x", "y", "z"}};
// A 1-component pass: the bare name ("dzdx"), or Cycles' "Depth.Z", Mitsuba's "dd.T", "Pass.Y", "Pass.V".
const std::vector<std::string> kSingles = {"", ".Z", ".Y", ".T", ".V"};

std::vector<std::string> resolve_pass(const ExrChannels& ch, const std::string& prefix, const std::string& pass, int n) {
  const std::string base = prefix + pass;
  if (n == 1) {
    for (const auto& s : kSingles)
      if (ch.has(base + s)) return {base + s};
    return {};
  }
  for (const auto& t : kTriples) {
    for (const char* sep : {".", ""}) {
      std::vector<std::string> names;
      for (const auto& c : t) names.push_back(base + sep + c);
      if (std::all_of(names.begin(), names.end(), [&](const std::string& x) { return ch.has(x); })) return names;
    }
  }
  return {};
}

// What a pass's channels would be called, for messages: "ViewLayer.DiffDir.R/G/B".
std::string expected_channels(const std::string& prefix, const std::string& pass, int n) {
  return n == 1 ? fmt::format("{}{} (or {}{}.Z/.Y/.T/.V)", prefix, pass, prefix, pass)
                : fmt::format("{}{}.R/G/B (or .X/Y/Z)", prefix, pass);
}

struct Resolved {
  std::vector<std::vector<std::vector<std::string>>> terms;  // term -> factor -> channel names
  std::vector<std::string> used;                             // every channel it reads
  std::string description;
};

// Resolves one source; nullopt with `missing` set when a required pass or channel is absent.
std::optional<Resolved> resolve_source(const ExrChannels& ch, const std::string& prefix, const LayerSource& s, int n,
                                       std::string& missing) {
  Resolved r;
  const int src_n = s.transform == SourceTransform::Length ? 3 : n;
  if (!s.channels.empty()) {
    for (const auto& c : s.channels)
      if (!ch.has(c)) {
        missing = fmt::format("channel '{}'", c);
        return std::nullopt;
      }
    r.terms.push_back({s.channels});
    r.used = s.channels;
    r.description = fmt::format("{}", fmt::join(s.channels, ","));
  } else {
    auto add = [&](const std::vector<std::string>& term, bool optional) -> bool {
      std::vector<std::vector<std::string>> factors;
      for (const auto& pass : term) {
        auto names = resolve_pass(ch, prefix, pass, src_n);
        if (names.empty()) {
          if (!optional) missing = expected_channels(prefix, pass, src_n);
          return false;
        }
        factors.push_back(std::move(names));
      }
      for (const auto& f : factors) r.used.insert(r.used.end(), f.begin(), f.end());
      r.terms.push_back(std::move(factors));
      if (!r.description.empty()) r.description += " + ";
      std::vector<std::string> shown;
      for (const auto& pass : term) shown.push_back(prefix + pass);
      r.description += fmt::format("{}", fmt::join(shown, " * "));
      return true;
    };
    for (const auto& t : s.terms)
      if (!add(t, false)) return std::nullopt;
    for (const auto& t : s.optional_terms) add(t, true);
  }
  if (s.transform == SourceTransform::Length) r.description = "|" + r.description + "|";
  if (s.scale != 1.0) r.description += fmt::format(" x {}", s.scale);
  return r;
}

Image evaluate(const ExrChannels& ch, const Resolved& r, const LayerSource& s, int n, int spp) {
  const std::size_t pixels = std::size_t(ch.width) * ch.height;
  const int src_n = s.transform == SourceTransform::Length ? 3 : n;
  std::vector<double> acc(pixels * std::size_t(src_n), 0.0);
  for (const auto& term : r.terms) {
    for (int c = 0; c < src_n; ++c) {
      std::vector<const float*> planes;
      for (const auto& factor : term) planes.push_back(ch.plane(factor[std::size_t(c)]).data());
      for (std::size_t i = 0; i < pixels; ++i) {
        double v = 1.0;
        for (const float* p : planes) v *= double(p[i]);
        acc[i * std::size_t(src_n) + std::size_t(c)] += v;
      }
    }
  }
  double scale = s.scale;
  if (s.divide_by_spp) scale /= double(spp);  // spp > 0: import_channels skips the source otherwise
  Image out(ch.width, ch.height, n);
  float* dst = out.data();
  for (std::size_t i = 0; i < pixels; ++i) {
    if (s.transform == SourceTransform::Length) {
      const double* v = &acc[i * 3];
      dst[i] = float(std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]) * scale);
    } else {
      for (int c = 0; c < n; ++c) dst[i * std::size_t(n) + std::size_t(c)] = float(acc[i * std::size_t(n) + std::size_t(c)] * scale);
    }
    if (s.miss_above)
      for (int c = 0; c < n; ++c) {
        float& x = dst[i * std::size_t(n) + std::size_t(c)];
        if (x > *s.miss_above) x = 0.0f;  // the harness's miss: depth 0 (tracer/integrator.cpp)
      }
  }
  return out;
}

// The prefix before the colour layer's first pass: every distinct one the file holds.
std::vector<std::string> find_prefixes(const ExrChannels& ch, const std::string& pass) {
  std::set<std::string> found;
  for (const auto& name : ch.names)
    for (const auto& t : kTriples)
      for (const char* sep : {".", ""}) {
        const std::string tail = pass + sep + t[0];
        if (name.size() < tail.size() || name.compare(name.size() - tail.size(), tail.size(), tail) != 0) continue;
        const std::string prefix = name.substr(0, name.size() - tail.size());
        if (!prefix.empty() && prefix.back() != '.') continue;
        if (!resolve_pass(ch, prefix, pass, 3).empty()) found.insert(prefix);
      }
  return {found.begin(), found.end()};
}

std::string replace_all(std::string s, const std::string& from, const std::string& to) {
  for (std::size_t at = 0; (at = s.find(from, at)) != std::string::npos; at += to.size()) s.replace(at, from.size(), to);
  return s;
}

std::string resolve_prefix(const ExrChannels& ch, const ImportMapping& m, const ImportOptions& o, const std::string& path) {
  if (!o.prefix.empty()) {
    std::string p = o.prefix;
    if (p.back() != '.') p += '.';
    return p;
  }
  if (m.prefix != "auto") return m.prefix;
  const LayerMapping& color = *std::find_if(m.layers.begin(), m.layers.end(), [](const LayerMapping& l) { return l.layer == layer::kColor; });
  const std::string pass = color.sources.front().terms.front().front();
  const auto prefixes = find_prefixes(ch, pass);
  if (prefixes.empty())
    throw InputError(fmt::format("'{}': no '{}' pass (channels '<layer>.{}.R/G/B') for the {} import; the file has {}",
                                 path, pass, pass, m.name, fmt::join(ch.names, ", ")));
  if (prefixes.size() > 1)
    throw InputError(fmt::format("'{}': {} layers hold a '{}' pass ({}): choose one with --layer NAME", path,
                                 prefixes.size(), pass, fmt::join(prefixes, ", ")));
  return prefixes.front();
}

bool matches_detect(const ExrChannels& ch, const ImportMapping& m, std::string& reason) {
  if (m.detect.empty() && m.detect_attribute.empty()) return false;
  if (!m.detect_attribute.empty()) {
    auto it = ch.attributes.find(m.detect_attribute[0]);
    if (it == ch.attributes.end() || it->second.rfind(m.detect_attribute[1], 0) != 0) return false;
    reason = fmt::format("its header's {} is '{}'", it->first, it->second);
  }
  if (!m.detect.empty()) {
    std::string prefix = m.prefix;
    if (prefix == "auto") {
      const auto prefixes = find_prefixes(ch, m.detect.front());
      if (prefixes.empty()) return false;
      prefix = prefixes.front();
    }
    for (const auto& pass : m.detect)
      if (resolve_pass(ch, prefix, pass, 3).empty()) return false;
    std::vector<std::string> shown;
    for (const auto& p : m.detect) shown.push_back(prefix + p);
    reason = fmt::format("it has the passes {}", fmt::join(shown, ", "));
  }
  return true;
}

bool is_native(const ExrChannels& ch) {
  return std::any_of(ch.attributes.begin(), ch.attributes.end(),
                     [](const auto& a) { return a.first.rfind("denoisebench:", 0) == 0; });
}

Imported import_channels(const ExrChannels& ch, const std::string& path, const ImportMapping& m, const ImportOptions& o) {
  Imported out;
  ImportReport& rep = out.report;
  rep.format = m.name;
  rep.prefix = resolve_prefix(ch, m, o, path);
  const std::string view_layer = rep.prefix.empty() ? "" : rep.prefix.substr(0, rep.prefix.size() - 1);

  // The sample count: --spp, else the first attribute the mapping names that the file has.
  rep.spp = o.spp;
  rep.spp_source = o.spp > 0 ? "--spp" : "unknown";
  if (o.spp <= 0)
    for (const auto& a : m.spp_attributes) {
      const std::string name = replace_all(a, "{view_layer}", view_layer);
      auto it = ch.attributes.find(name);
      if (it == ch.attributes.end()) continue;
      try {
        std::size_t used = 0;
        const long v = std::stol(it->second, &used);
        if (used != it->second.size() || v <= 0 || v > (1L << 30)) throw std::invalid_argument("range");
        rep.spp = int(v);
        rep.spp_source = name;
      } catch (const std::exception&) {
        throw InputError(fmt::format("'{}': header attribute {} is '{}', expected a positive whole sample count", path,
                                     name, it->second));
      }
      break;
    }

  AovFrame& frame = out.frame;
  frame = AovFrame(ch.width, ch.height);
  std::set<std::string> used;
  for (const LayerMapping& lm : m.layers) {
    const int n = default_channels(lm.layer);
    std::vector<std::string> missing;
    bool done = false;
    for (const LayerSource& s : lm.sources) {
      std::string miss;
      auto r = resolve_source(ch, rep.prefix, s, n, miss);
      if (!r) {
        missing.push_back(miss);
        continue;
      }
      if (s.divide_by_spp && rep.spp <= 0) {  // a per-sample variance, and the count to divide by unknown
        missing.push_back(fmt::format("sample count to divide {} by (give --spp N)", r->description));
        continue;
      }
      frame.set(lm.layer, evaluate(ch, *r, s, n, rep.spp));
      used.insert(r->used.begin(), r->used.end());
      std::string how = r->description;
      if (s.space) {
        how += fmt::format(" ({} space)", to_string(*s.space));
        frame.meta.extra["import.normal_space"] = to_string(*s.space);
      }
      if (!s.note.empty()) how += " (" + s.note + ")";
      rep.kept.emplace_back(lm.layer, how);
      frame.meta.extra["import." + lm.layer] = how;
      done = true;
      break;
    }
    if (done) continue;
    const std::string why = fmt::format("no {}", fmt::join(missing, ", nor "));
    if (lm.required)
      throw InputError(fmt::format("'{}': cannot make layer '{}' ({}, {}): {}", path, lm.layer, m.source, lm.where, why));
    rep.left_out.emplace_back(lm.layer, why);
  }
  for (const auto& name : ch.names) {
    if (used.count(name)) continue;
    const bool ignored = std::any_of(m.ignore.begin(), m.ignore.end(), [&](const std::string& ig) {
      const std::string full = rep.prefix + ig;
      return name == full || name == ig || name.rfind(full + ".", 0) == 0;
    });
    if (!ignored) rep.unmapped.push_back(name);
  }

  // How exactly the split adds up to the file's own image.
  if (frame.has(layer::kColor) && frame.has(layer::kDirect) && frame.has(layer::kIndirect) && frame.has(layer::kAlbedo)) {
    const float* f = frame.layer(layer::kColor).data();
    const float* d = frame.layer(layer::kDirect).data();
    const float* ind = frame.layer(layer::kIndirect).data();
    const float* t = frame.layer(layer::kAlbedo).data();
    const float* r = frame.has(layer::kReflection) ? frame.layer(layer::kReflection).data() : nullptr;
    const float* e = frame.has(layer::kEmission) ? frame.layer(layer::kEmission).data() : nullptr;
    double err = 0, norm = 0;
    for (std::size_t i = 0; i < frame.layer(layer::kColor).size(); ++i) {
      double c = (double(d[i]) + ind[i]) * t[i] + (r ? r[i] : 0.0) + (e ? e[i] : 0.0);
      if (!std::isfinite(c) || !std::isfinite(f[i])) continue;
      err += (c - f[i]) * (c - f[i]);
      norm += double(f[i]) * f[i];
    }
    rep.composition_rel_rms = norm > 0 ? std::sqrt(err / norm) : std::sqrt(err);
    frame.meta.extra["import.composition_rel_rms"] = fmt::format("{:.3g}", *rep.composition_rel_rms);
    // 1e-3: far above float rounding of a sum of a few products (about 1e-7 relative), far below a
    // missing pass (volume, background, a light group), which moves whole regions.
    if (*rep.composition_rel_rms > 1e-3)
      rep.warnings.push_back(fmt::format(
          "(D + I) * T + R + E differs from the colour layer by {:.3g} (relative RMS): the file holds light no "
          "mapped pass carries (volume, background or unlisted passes); methods that filter the split will miss it",
          *rep.composition_rel_rms));
  }
  frame.meta.spp = rep.spp;
  frame.meta.scene = "";
  frame.meta.extra["import.format"] = m.name;
  frame.meta.extra["import.source"] = std::filesystem::path(path).filename().string();
  frame.meta.extra["import.spp_source"] = rep.spp_source;
  if (!rep.prefix.empty()) frame.meta.extra["import.prefix"] = rep.prefix;
  if (!rep.left_out.empty()) {
    std::vector<std::string> names;
    for (const auto& [l, why] : rep.left_out) names.push_back(l);
    frame.meta.extra["import.left_out"] = fmt::format("{}", fmt::join(names, ","));
  }
  return out;
}

}  // namespace

Imported import_frame(const std::string& path, const ImportMapping& mapping, const ImportOptions& options) {
  return import_channels(read_exr_channels(path), path, mapping, options);
}

DetectedFormat detect_format(const std::string& path) {
  const ExrChannels header = read_exr_channels(path, false);
  if (is_native(header)) return {"native", "it was written by denoisebench"};
  for (const auto& name : preset_names()) {
    std::string reason;
    if (matches_detect(header, preset(name), reason)) return {name, reason};
  }
  return {"native", "no other renderer's layout matched"};
}

AovFrame read_frame_as(const std::string& path, const std::string& format, const ImportOptions& options,
                       const std::vector<std::string>& required, ImportReport* report) {
  std::string f = format.empty() ? "native" : format;
  if (f == "auto") {
    const DetectedFormat d = detect_format(path);
    if (d.format != "native") spdlog::info("'{}': read as a {} frame ({})", path, d.format, d.reason);
    f = d.format;
  }
  if (f == "native") {
    if (report) *report = ImportReport{.format = "native"};
    return read_frame(path, required, options.layers);
  }
  Imported im = import_frame(path, mapping_for(f), options);
  for (const auto& w : im.report.warnings) spdlog::warn("'{}': {}", path, w);
  for (const auto& r : required)
    if (!im.frame.has(r)) {
      std::string why = "the mapping has no source for it";
      for (const auto& [l, w] : im.report.left_out)
        if (l == r) why = w;
      throw InputError(fmt::format("'{}' (read as {}): no layer '{}' ({})", path, im.report.format, r, why));
    }
  if (report) *report = im.report;
  return std::move(im.frame);
}

std::string input_format_help() {
  return fmt::format("auto (default: the harness's own frames natively, Cycles and pbrt-v4 by their channel names, "
                     "Mitsuba by its header), native, {}, or map:FILE.toml (docs/importing.md)",
                     fmt::join(preset_names(), ", "));
}

}  // namespace dnb::interop
