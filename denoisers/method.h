// The one interface every method implements (DESIGN.md, "One interface for every method").
// Modelled on Intel Open Image Denoise's filters (created by name, named images, typed
// parameters, execute) and pbrt-v4's Create factories (unknown names and parameters are errors).
//
// A method is created from the registry by name with its parameters, declares the frame
// layers it needs, and turns a MethodInput into an image plus MethodStats. See
// docs/adding-a-method.md for a worked example.
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <utility>
#include <variant>
#include <vector>

#include "core/aov_frame.h"
#include "core/image.h"

namespace dnb {

class Scene;  // tracer/scene.h: only renderer-type methods use it

enum class ParamType { Float, Int, Bool, String };

// One typed parameter: name, type, default (as text, parsed like a --set value) and a
// one-line description shown by `denoisebench list methods`.
struct ParamSpec {
  std::string name;
  ParamType type = ParamType::Float;
  std::string default_value;
  std::string doc;
};

// Parameter values after validation against the specs: every declared parameter is present.
class Params {
 public:
  using Value = std::variant<double, std::int64_t, bool, std::string>;
  double f(const std::string& name) const;
  int i(const std::string& name) const;
  bool b(const std::string& name) const;
  const std::string& s(const std::string& name) const;
  void set(const std::string& name, Value v) { values_[name] = std::move(v); }
  bool has(const std::string& name) const { return values_.count(name) != 0; }
  // name -> value as text, for results files.
  std::map<std::string, std::string> as_strings() const;

 private:
  const Value& get(const std::string& name) const;
  std::map<std::string, Value> values_;
};

struct MethodInput {
  const AovFrame* frame = nullptr;  // the 256-spp AOV frame (filters)
  const Scene* scene = nullptr;     // renderer-type methods render the scene themselves
  int sample_budget = 0;            // renderer-type methods: the spp budget of the input render
  int width = 0, height = 0;        // renderer-type methods: image size when there is no frame
  std::uint64_t seed = 1;
};

struct MethodStats {
  std::vector<std::pair<std::string, double>> phases;  // wall seconds per phase, in order
  std::map<std::string, double> counters;              // method-specific counters
  double total_seconds = 0;
  void add_phase(const std::string& name, double seconds) { phases.emplace_back(name, seconds); }
};

struct MethodResult {
  Image image;  // the final RGB radiance estimate, same size as the input
  MethodStats stats;
};

enum class MethodKind { Filter, Renderer };

class Method {
 public:
  virtual ~Method() = default;
  // Layer names (core/aov_frame.h) this method reads from the frame.
  virtual std::vector<std::string> required_layers() const = 0;
  virtual MethodResult execute(const MethodInput& input) = 0;
};

struct MethodInfo {
  std::string name;
  std::string description;  // one line
  MethodKind kind = MethodKind::Filter;
  std::vector<ParamSpec> params;
  std::function<std::unique_ptr<Method>(const Params&)> create;
};

class MethodRegistry {
 public:
  // The registry of built-in methods (denoisers/registry.cpp lists them).
  static MethodRegistry& global();
  void add(MethodInfo info);  // throws WorkError on a duplicate name
  bool contains(const std::string& name) const;
  // InputError listing the valid names when unknown.
  const MethodInfo& info(const std::string& name) const;
  // Parses and validates settings ("sigma_s" -> "16"): unknown parameters and values that do
  // not parse as the declared type are InputErrors listing the valid parameters.
  Params parse_params(const std::string& name, const std::map<std::string, std::string>& settings) const;
  std::unique_ptr<Method> create(const std::string& name,
                                 const std::map<std::string, std::string>& settings = {}) const;
  std::vector<const MethodInfo*> all() const;  // sorted by name

 private:
  std::map<std::string, MethodInfo> methods_;
};

// Runs a method the way the harness always does: checks that the frame has the method's
// layers (InputError naming the missing channels), refuses frames with no finite sample,
// repairs NaN/Inf input samples (replaced by 0, counted in stats.counters["repaired_samples"]),
// times execute(), and checks the output (size kept, 3 channels, finite).
MethodResult run_method(Method& method, const MethodInput& input);

// Registers every built-in method (denoisers/registry.cpp).
void register_builtin_methods(MethodRegistry& registry);

// Parses "key=value" into a pair; InputError when there is no '='.
std::pair<std::string, std::string> parse_setting(const std::string& kv);

}  // namespace dnb
