#include "denoisers/method.h"

#include <algorithm>
#include <climits>
#include <cmath>
#include <set>

#include <fmt/format.h>
#include <tbb/parallel_for.h>

#include "core/enum_names.h"
#include "core/errors.h"

namespace dnb {

const char* to_string(ParamType t) {
  switch (t) {
    case ParamType::Float: return "float";
    case ParamType::Int: return "int";
    case ParamType::Bool: return "bool";
    case ParamType::String: return "string";
  }
  return "?";
}

namespace {
constexpr EnumName<MethodKind> kMethodKindNames[] = {{MethodKind::Filter, "filter"}, {MethodKind::Renderer, "renderer"}};
}  // namespace

const char* to_string(MethodKind k) { return enum_name(k, kMethodKindNames); }

MethodKind method_kind_from_string(const std::string& s, const std::string& where) {
  return enum_from_name(s, kMethodKindNames, where + ": key 'kind'");
}

std::string ParamSpec::expected() const {
  switch (type) {
    case ParamType::Float:
    case ParamType::Int: {
      const char* what = type == ParamType::Float ? "a finite number" : "an integer";
      if (min && max) return fmt::format("{} in [{}, {}]", what, *min, *max);
      if (min) return fmt::format("{} >= {}", what, *min);
      if (max) return fmt::format("{} <= {}", what, *max);
      return what;
    }
    case ParamType::Bool: return "true or false";
    case ParamType::String:
      return choices.empty() ? "any text" : fmt::format("one of {}", fmt::join(choices, ", "));
  }
  return "a value";
}

const Params::Value& Params::get(const std::string& name) const {
  auto it = values_.find(name);
  if (it == values_.end()) throw WorkError(fmt::format("parameter '{}' was not declared", name));
  return it->second;
}
double Params::f(const std::string& name) const {
  const Value& v = get(name);
  if (auto* d = std::get_if<double>(&v)) return *d;
  if (auto* i = std::get_if<std::int64_t>(&v)) return double(*i);
  throw WorkError(fmt::format("parameter '{}' is not a number", name));
}
int Params::i(const std::string& name) const {
  const Value& v = get(name);
  if (auto* i = std::get_if<std::int64_t>(&v)) return int(*i);  // parse_value keeps it in int range
  throw WorkError(fmt::format("parameter '{}' is not an integer", name));
}
bool Params::b(const std::string& name) const {
  const Value& v = get(name);
  if (auto* b = std::get_if<bool>(&v)) return *b;
  throw WorkError(fmt::format("parameter '{}' is not a boolean", name));
}
const std::string& Params::s(const std::string& name) const {
  const Value& v = get(name);
  if (auto* s = std::get_if<std::string>(&v)) return *s;
  throw WorkError(fmt::format("parameter '{}' is not a string", name));
}
std::map<std::string, std::string> Params::as_strings() const {
  std::map<std::string, std::string> out;
  for (const auto& [k, v] : values_)
    out[k] = std::visit(
        [](const auto& x) -> std::string {
          using T = std::decay_t<decltype(x)>;
          if constexpr (std::is_same_v<T, std::string>) return x;
          else if constexpr (std::is_same_v<T, bool>) return x ? "true" : "false";
          else return fmt::format("{}", x);
        },
        v);
  return out;
}

// Parses one value of a parameter and checks it against the spec. InputError naming the
// method, the parameter, the value and what is expected.
static Params::Value parse_value(const std::string& method, const ParamSpec& spec, const std::string& text) {
  auto bad = [&] {
    return InputError(fmt::format("method '{}': parameter '{}' = '{}': expected {}", method, spec.name, text,
                                  spec.expected()));
  };
  auto in_bounds = [&](double v) { return (!spec.min || v >= *spec.min) && (!spec.max || v <= *spec.max); };
  // std::sto* skip leading spaces and accept "inf"/"nan": a value must be exactly a number.
  if ((spec.type == ParamType::Float || spec.type == ParamType::Int) &&
      (text.empty() || std::isspace(static_cast<unsigned char>(text.front()))))
    throw bad();
  switch (spec.type) {
    case ParamType::Float: {
      double d = 0;
      std::size_t pos = 0;
      try {
        d = std::stod(text, &pos);
      } catch (const std::logic_error&) {
        throw bad();
      }
      if (pos != text.size() || !std::isfinite(d) || !in_bounds(d)) throw bad();
      return d;
    }
    case ParamType::Int: {
      long long v = 0;
      std::size_t pos = 0;
      try {
        v = std::stoll(text, &pos);
      } catch (const std::logic_error&) {
        throw bad();
      }
      if (pos != text.size() || v < INT_MIN || v > INT_MAX || !in_bounds(double(v))) throw bad();
      return std::int64_t(v);
    }
    case ParamType::Bool:
      if (text == "true" || text == "1" || text == "on") return true;
      if (text == "false" || text == "0" || text == "off") return false;
      throw bad();
    case ParamType::String:
      if (!spec.choices.empty() && std::find(spec.choices.begin(), spec.choices.end(), text) == spec.choices.end())
        throw bad();
      return text;
  }
  throw bad();
}

void MethodRegistry::add(MethodInfo info) {
  if (info.name.empty()) throw WorkError("a method was registered without a name");
  if (methods_.count(info.name)) throw WorkError(fmt::format("method '{}' registered twice", info.name));
  if (!info.create) throw WorkError(fmt::format("method '{}' has no create function", info.name));
  std::set<std::string> seen;
  for (const auto& spec : info.params) {
    if (!seen.insert(spec.name).second)
      throw WorkError(fmt::format("method '{}' declares parameter '{}' twice", info.name, spec.name));
    try {
      parse_value(info.name, spec, spec.default_value);
    } catch (const InputError& e) {
      throw WorkError(fmt::format("default value refused by its own spec: {}", e.what()));
    }
  }
  std::string n = info.name;
  methods_.emplace(n, std::move(info));
}

bool MethodRegistry::contains(const std::string& name) const { return methods_.count(name) != 0; }

std::vector<std::string> MethodRegistry::names() const {
  std::vector<std::string> out;
  for (const auto& [k, v] : methods_) out.push_back(k);
  return out;
}

const MethodInfo& MethodRegistry::info(const std::string& name) const {
  auto it = methods_.find(name);
  if (it == methods_.end())
    throw InputError(fmt::format("unknown method '{}' (valid methods: {})", name,
                                 methods_.empty() ? std::string("none") : fmt::format("{}", fmt::join(names(), ", "))));
  return it->second;
}

Params MethodRegistry::parse_params(const std::string& name,
                                    const std::map<std::string, std::string>& settings) const {
  const MethodInfo& mi = info(name);
  Params p;
  for (const auto& spec : mi.params) p.set(spec.name, parse_value(name, spec, spec.default_value));
  for (const auto& [k, v] : settings) {
    // k by init-capture: clang before 16 cannot capture a structured binding (the fuzz build).
    auto it = std::find_if(mi.params.begin(), mi.params.end(), [&k = k](const ParamSpec& s) { return s.name == k; });
    if (it == mi.params.end()) {
      std::vector<std::string> valid;
      for (auto& s : mi.params) valid.push_back(s.name);
      throw InputError(fmt::format("method '{}' has no parameter '{}' (valid parameters: {})", name, k,
                                   valid.empty() ? std::string("none") : fmt::format("{}", fmt::join(valid, ", "))));
    }
    p.set(k, parse_value(name, *it, v));
  }
  return p;
}

std::unique_ptr<Method> MethodRegistry::create(const std::string& name,
                                               const std::map<std::string, std::string>& settings) const {
  auto m = info(name).create(parse_params(name, settings));
  if (!m) throw WorkError(fmt::format("method '{}': create returned nothing", name));
  return m;
}

std::vector<const MethodInfo*> MethodRegistry::all() const {
  std::vector<const MethodInfo*> out;
  for (const auto& [k, v] : methods_) out.push_back(&v);
  return out;
}

std::pair<std::string, std::string> parse_setting(const std::string& kv) {
  auto eq = kv.find('=');
  if (eq == std::string::npos || eq == 0)
    throw InputError(fmt::format("--set '{}': expected key=value", kv));
  return {kv.substr(0, eq), kv.substr(eq + 1)};
}

std::map<std::string, std::string> parse_settings(const std::vector<std::string>& kvs) {
  std::map<std::string, std::string> out;
  for (const auto& kv : kvs) {
    auto [k, v] = parse_setting(kv);
    if (!out.emplace(k, v).second) throw InputError(fmt::format("--set '{}': parameter '{}' set twice", kv, k));
  }
  return out;
}

// Replaces each non-finite sample of `img` by the mean of the finite values of the same
// channel among its 8 neighbours in `src` (0 when none is finite). Reads only `src`, so the
// result does not depend on the order pixels are visited. Returns the number replaced.
static std::int64_t repair_non_finite(const Image& src, Image& img) {
  const int w = src.width(), h = src.height(), nc = src.channels();
  std::vector<std::int64_t> per_row(h, 0);
  tbb::parallel_for(0, h, [&](int y) {
    for (int x = 0; x < w; ++x)
      for (int c = 0; c < nc; ++c) {
        if (std::isfinite(src.at(x, y, c))) continue;
        double sum = 0;
        int n = 0;
        for (int dy = -1; dy <= 1; ++dy)
          for (int dx = -1; dx <= 1; ++dx) {
            const int xx = x + dx, yy = y + dy;
            if ((dx == 0 && dy == 0) || xx < 0 || yy < 0 || xx >= w || yy >= h) continue;
            const float v = src.at(xx, yy, c);
            if (std::isfinite(v)) sum += v, ++n;
          }
        img.at(x, y, c) = n ? float(sum / n) : 0.0f;
        ++per_row[y];
      }
  });
  std::int64_t total = 0;
  for (auto n : per_row) total += n;
  return total;
}

static std::string frame_label(const AovFrame& f) {
  return f.meta.scene.empty() ? std::string("the frame") : fmt::format("frame of '{}'", f.meta.scene);
}

std::vector<std::string> Method::read_layers() const {
  std::vector<std::string> out = required_layers();
  for (auto& name : optional_layers())
    if (std::find(out.begin(), out.end(), name) == out.end()) out.push_back(std::move(name));
  return out;
}

MethodResult run_method(Method& method, const MethodInput& input) {
  MethodInput in = input;
  AovFrame repaired;
  std::int64_t repaired_samples = 0;
  const std::vector<std::string> required = method.required_layers();
  if (!input.frame && !required.empty())
    throw InputError(fmt::format("this method needs a frame with layers {}, and none was given", fmt::join(required, ", ")));
  Stopwatch repair_watch;
  if (input.frame) {
    const AovFrame& f = *input.frame;
    if (f.width() <= 0 || f.height() <= 0)
      throw InputError(fmt::format("{} is empty ({}x{})", frame_label(f), f.width(), f.height()));
    auto missing = f.missing_channels(required);
    if (!missing.empty())
      throw InputError(fmt::format("{} lacks channel{} {} required by this method", frame_label(f),
                                   missing.size() > 1 ? "s" : "", fmt::join(missing, ", ")));
    // Repair non-finite samples in a copy, only when there are any (no copy in the common case).
    std::vector<std::string> checked;  // the required layers (all present) and the optional ones present
    for (const auto& name : method.read_layers())
      if (f.has(name)) checked.push_back(name);
    bool any = false;
    for (const auto& name : checked) {
      const Image& img = f.layer(name);
      const int want = default_channels(name);
      if (img.channels() != want || img.width() != f.width() || img.height() != f.height())
        throw InputError(fmt::format("{}: layer '{}' is {}x{} with {} channels, expected {}x{} with {} ({})",
                                     frame_label(f), name, img.width(), img.height(), img.channels(), f.width(),
                                     f.height(), want, fmt::join(channel_names(name, want), ",")));
      std::size_t bad = count_non_finite(img.view());
      if (bad == img.size())
        throw InputError(fmt::format("{}: layer '{}' has no finite sample", frame_label(f), name));
      any |= bad > 0;
    }
    if (any) {
      repaired = f;
      for (const auto& name : checked) {
        const Image& src = f.layer(name);
        if (count_non_finite(src.view()) == 0) continue;
        repaired_samples += repair_non_finite(src, repaired.layer(name));
      }
      in.frame = &repaired;
    }
  }
  const double repair_seconds = repair_watch.seconds();
  Stopwatch sw;
  MethodResult r = method.execute(in);
  r.stats.total_seconds = r.stats.own_seconds.value_or(sw.seconds());
  // The repair is the harness's work, not the method's: it is reported apart from total_seconds.
  if (repaired_samples) r.stats.counters["repair_seconds"] = repair_seconds;
  r.stats.counters["repaired_samples"] = double(repaired_samples);
  if (r.image.channels() != 3)
    throw WorkError(fmt::format("method returned {} channels, expected 3", r.image.channels()));
  const int want_w = input.frame ? input.frame->width() : input.width;
  const int want_h = input.frame ? input.frame->height() : input.height;
  if ((want_w > 0 || want_h > 0) && (r.image.width() != want_w || r.image.height() != want_h))
    throw WorkError(fmt::format("method returned a {}x{} image for a {}x{} input", r.image.width(),
                                r.image.height(), want_w, want_h));
  std::size_t bad = count_non_finite(r.image.view());
  if (bad) throw WorkError(fmt::format("method produced {} non-finite output samples", bad));
  return r;
}

}  // namespace dnb
