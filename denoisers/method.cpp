#include "denoisers/method.h"

#include <algorithm>
#include <cmath>

#include <fmt/format.h>

#include "core/errors.h"
#include "core/timer.h"

namespace dnb {

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
  if (auto* i = std::get_if<std::int64_t>(&v)) return int(*i);
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

MethodRegistry& MethodRegistry::global() {
  static MethodRegistry r = [] {
    MethodRegistry reg;
    register_builtin_methods(reg);
    return reg;
  }();
  return r;
}

void MethodRegistry::add(MethodInfo info) {
  if (methods_.count(info.name)) throw WorkError(fmt::format("method '{}' registered twice", info.name));
  std::string n = info.name;
  methods_.emplace(n, std::move(info));
}

bool MethodRegistry::contains(const std::string& name) const { return methods_.count(name) != 0; }

const MethodInfo& MethodRegistry::info(const std::string& name) const {
  auto it = methods_.find(name);
  if (it == methods_.end()) {
    std::vector<std::string> names;
    for (auto& [k, v] : methods_) names.push_back(k);
    throw InputError(fmt::format("unknown method '{}' (valid methods: {})", name, fmt::join(names, ", ")));
  }
  return it->second;
}

static Params::Value parse_value(const std::string& method, const ParamSpec& spec, const std::string& text) {
  auto bad = [&](const char* expected) {
    return InputError(fmt::format("method '{}': parameter '{}' = '{}': expected {}", method, spec.name, text,
                                  expected));
  };
  switch (spec.type) {
    case ParamType::Float: {
      try {
        std::size_t pos = 0;
        double d = std::stod(text, &pos);
        if (pos != text.size() || !std::isfinite(d)) throw bad("a finite number");
        return d;
      } catch (const std::logic_error&) {
        throw bad("a number");
      }
    }
    case ParamType::Int: {
      try {
        std::size_t pos = 0;
        long long v = std::stoll(text, &pos);
        if (pos != text.size()) throw bad("an integer");
        return std::int64_t(v);
      } catch (const std::logic_error&) {
        throw bad("an integer");
      }
    }
    case ParamType::Bool:
      if (text == "true" || text == "1" || text == "on") return true;
      if (text == "false" || text == "0" || text == "off") return false;
      throw bad("true or false");
    case ParamType::String:
      return text;
  }
  throw bad("a value");
}

Params MethodRegistry::parse_params(const std::string& name,
                                    const std::map<std::string, std::string>& settings) const {
  const MethodInfo& mi = info(name);
  Params p;
  for (const auto& spec : mi.params) p.set(spec.name, parse_value(name, spec, spec.default_value));
  for (const auto& [k, v] : settings) {
    auto it = std::find_if(mi.params.begin(), mi.params.end(), [&](const ParamSpec& s) { return s.name == k; });
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
  return info(name).create(parse_params(name, settings));
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

MethodResult run_method(Method& method, const MethodInput& input) {
  MethodInput in = input;
  AovFrame repaired;
  std::int64_t repaired_samples = 0;
  if (input.frame) {
    const AovFrame& f = *input.frame;
    auto missing = f.missing_channels(method.required_layers());
    if (!missing.empty())
      throw InputError(fmt::format("frame '{}' lacks channel{} {} required by this method", f.meta.scene,
                                   missing.size() > 1 ? "s" : "", fmt::join(missing, ", ")));
    // Repair non-finite samples in a copy, only when there are any (no copy in the common case).
    bool any = false;
    for (const auto& name : method.required_layers()) {
      const Image& img = f.layer(name);
      std::size_t bad = count_non_finite(img.view());
      if (bad == img.size())
        throw InputError(fmt::format("frame '{}': layer '{}' has no finite sample", f.meta.scene, name));
      any |= bad > 0;
    }
    if (any) {
      repaired = f;
      for (const auto& name : method.required_layers()) {
        Image& img = repaired.layer(name);
        for (std::size_t i = 0; i < img.size(); ++i)
          if (!std::isfinite(img.data()[i])) {
            img.data()[i] = 0.0f;
            ++repaired_samples;
          }
      }
      in.frame = &repaired;
    }
  }
  Stopwatch sw;
  MethodResult r = method.execute(in);
  r.stats.total_seconds = sw.seconds();
  r.stats.counters["repaired_samples"] = double(repaired_samples);
  if (r.image.channels() != 3) throw WorkError(fmt::format("method returned {} channels, expected 3", r.image.channels()));
  if (input.frame && (r.image.width() != input.frame->width() || r.image.height() != input.frame->height()))
    throw WorkError("method changed the image size");
  std::size_t bad = count_non_finite(r.image.view());
  if (bad) throw WorkError(fmt::format("method produced {} non-finite output samples", bad));
  return r;
}

}  // namespace dnb
