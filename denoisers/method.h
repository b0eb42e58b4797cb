// The one interface every method implements (docs/design.md, "One interface for every method").
// Modelled on Intel Open Image Denoise's filters (created by name, named images, typed
// parameters, execute) and pbrt-v4's Create factories (unknown names and parameters are errors).
//
// A method is created from the registry by name with its parameters, declares the frame
// layers it needs, and turns a MethodInput into an image plus MethodStats:
//
//   auto m = MethodRegistry::global().create("bilateral", {{"sigma_color", "0.3"}});
//   AovFrame frame = read_frame("frame.exr", m->required_layers());
//   MethodResult r = run_method(*m, MethodInput{.frame = &frame});
//
// Always run a method through run_method (it checks the input and output and times it) rather
// than calling execute() directly. See docs/adding-a-method.md for a worked example.
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <variant>
#include <vector>

#include "denoisers/method_kind.h"
#include "core/aov_frame.h"
#include "core/image.h"
#include "core/timer.h"

namespace dnb {

class Scene;  // tracer/scene.h: only renderer-type methods use it

enum class ParamType { Float, Int, Bool, String };
const char* to_string(ParamType t);  // "float", "int", "bool", "string"

// One typed parameter: name, type, default (as text, parsed like a --set value) and a
// one-line description shown by `denoisebench list methods`. Optional bounds (Float and Int,
// inclusive) and choices (String) make the registry refuse bad values with an InputError that
// states what is accepted, before the method is created.
struct ParamSpec {
  std::string name = {};
  ParamType type = ParamType::Float;
  std::string default_value = {};
  std::string doc = {};
  std::optional<double> min = {};         // inclusive lower bound (Float, Int)
  std::optional<double> max = {};         // inclusive upper bound (Float, Int)
  std::vector<std::string> choices = {};  // accepted values (String); empty: any text

  // What a value must be, e.g. "a number in [0, 10]" or "one of log, reinhard".
  std::string expected() const;
};

// Parameter values after validation against the specs: every declared parameter is present.
class Params {
 public:
  using Value = std::variant<double, std::int64_t, bool, std::string>;
  double f(const std::string& name) const;  // Float (an Int converts)
  int i(const std::string& name) const;     // Int
  bool b(const std::string& name) const;    // Bool
  const std::string& s(const std::string& name) const;  // String
  void set(const std::string& name, Value v) { values_[name] = std::move(v); }
  bool has(const std::string& name) const { return values_.count(name) != 0; }
  // name -> value as text, for results files.
  std::map<std::string, std::string> as_strings() const;

 private:
  const Value& get(const std::string& name) const;
  std::map<std::string, Value> values_;
};

// Where a frame stands in an animated sequence (docs/sequences.md). The harness gives a temporal
// method (Method::temporal()) one instance per sequence, spp and seed, and its frames in index
// order from 0; a still method gets the frames one by one as stills.
struct SequenceFrame {
  std::string sequence;  // which sequence (scene, spp, seed): a change means a new sequence
  int index = 0;         // 0 .. count - 1; index 0 starts a sequence (history reset)
  int count = 1;         // frames in the sequence
  // The previous frame's input (its depth, normal, colour ...) for index > 0, else null.
  const AovFrame* previous = nullptr;
};

struct MethodInput {
  const AovFrame* frame = nullptr;  // the 256-spp AOV frame (filters)
  // Set when the frame is one of an animated sequence; a temporal method without it treats the
  // frame as a one-frame sequence (its history reset: its spatial part alone).
  const SequenceFrame* sequence = nullptr;
  const Scene* scene = nullptr;     // renderer-type methods render the scene themselves
  int sample_budget = 0;            // renderer-type methods: the spp budget of the input render
  int width = 0, height = 0;        // renderer-type methods: image size when there is no frame
  std::uint64_t seed = 1;
};

struct MethodStats {
  std::vector<std::pair<std::string, double>> phases;  // wall seconds per phase, in order
  std::map<std::string, double> counters;              // method-specific counters
  double total_seconds = 0;  // wall seconds of execute(), set by run_method
  // Set by a method that times itself: run_method takes it as total_seconds instead of the wall
  // time of execute(). A plug-in reports its program's wall time (the process, or the request's
  // round trip), so that the harness's own file traffic around it (phases) is not charged to it.
  std::optional<double> own_seconds;
  // Start-up paid once per run, not per frame (a worker plug-in loading its model): recorded
  // apart (results.json times.setup_seconds), never part of total_seconds.
  std::optional<double> setup_seconds;
  // What the method says about itself, recorded in results.json as the cell's method_info: a
  // worker plug-in's ready-line "info" (docs/plugins.md), such as the version of the library
  // it loaded (oidn: OIDN's).
  std::map<std::string, std::string> info;
  void add_phase(const std::string& name, double seconds) { phases.emplace_back(name, seconds); }
};

// Times one phase of execute(): `ScopedPhase p(stats, "blur");` adds ("blur", seconds) to
// stats.phases when p goes out of scope.
class ScopedPhase {
 public:
  ScopedPhase(MethodStats& stats, std::string name) : stats_(stats), name_(std::move(name)) {}
  ~ScopedPhase() { stats_.add_phase(name_, watch_.seconds()); }
  ScopedPhase(const ScopedPhase&) = delete;
  ScopedPhase& operator=(const ScopedPhase&) = delete;

 private:
  MethodStats& stats_;
  std::string name_;
  Stopwatch watch_;
};

struct MethodResult {
  Image image;  // the final RGB radiance estimate, same size as the input
  MethodStats stats;
};


class Method {
 public:
  virtual ~Method() = default;
  // Layer names (core/aov_frame.h, e.g. layer::kDirect) this method reads from the frame.
  // run_method guarantees each is present with its contract channel count and only finite
  // samples before execute() is called.
  virtual std::vector<std::string> required_layers() const = 0;
  // Layers this method uses when the frame has them and does without otherwise (recording in its
  // stats what it did). run_method checks and repairs those present exactly like required ones.
  virtual std::vector<std::string> optional_layers() const { return {}; }
  // Every layer the method may read: required_layers() then optional_layers(), each once.
  std::vector<std::string> read_layers() const;
  // Must return a 3-channel image of the frame's size (or input.width x input.height) with
  // finite samples, and give the bit-identical image for the same input whatever the thread
  // count. May throw InputError (bad input) or WorkError (failure).
  virtual MethodResult execute(const MethodInput& input) = 0;
  // A temporal method keeps history between the frames of a sequence (docs/sequences.md): it is
  // given them in order, and starts afresh at index 0, at a new SequenceFrame::sequence, or
  // after reset(). It must give the same image for the same frames in the same order.
  virtual bool temporal() const { return false; }
  virtual void reset() {}
};

struct MethodInfo {
  std::string name = {};
  std::string description = {};  // one line
  MethodKind kind = MethodKind::Filter;
  // Keeps history between the frames of a sequence (Method::temporal()): the planner gives it a
  // sequence's frames in order from one instance.
  bool temporal = false;
  std::vector<ParamSpec> params = {};
  // Plug-ins (methods/plugins.h): the manifest's path, and a hash of the manifest and every file
  // of its folder (the cell key includes it, so editing a plug-in reruns its cells). Empty for
  // built-in methods, which the build identity covers.
  std::string origin = {};
  std::string content_hash = {};
  // Builds the method from validated parameters (every declared one present, in range). May
  // throw InputError for combinations of values that are invalid together.
  std::function<std::unique_ptr<Method>(const Params&)> create = {};
};

class MethodRegistry {
 public:
  // The registry of built-in methods (methods/registry.cpp lists them).
  static MethodRegistry& global();
  // Throws WorkError on a duplicate or empty name, a missing create function, a duplicate
  // parameter, or a default value that its own spec refuses.
  void add(MethodInfo info);
  bool contains(const std::string& name) const;
  // InputError listing the valid names when unknown.
  const MethodInfo& info(const std::string& name) const;
  // Parses and validates settings ("sigma_s" -> "16"): unknown parameters, values that do not
  // parse as the declared type and values out of bounds are InputErrors naming the method, the
  // parameter and what is expected (and, for an unknown one, listing the valid parameters).
  Params parse_params(const std::string& name, const std::map<std::string, std::string>& settings) const;
  std::unique_ptr<Method> create(const std::string& name,
                                 const std::map<std::string, std::string>& settings = {}) const;
  std::vector<const MethodInfo*> all() const;  // sorted by name
  std::vector<std::string> names() const;      // sorted

 private:
  std::map<std::string, MethodInfo> methods_;
};

// Runs a method the way the harness always does:
// - checks that the frame has the method's layers (InputError naming the missing EXR
//   channels) with the contract channel counts, and that each has a finite sample;
// - repairs NaN/Inf samples of those layers in a copy: each becomes the mean of the finite
//   values of the same channel among its 8 neighbours (0 when there are none), so a lost
//   sample does not punch a black hole into the image; the number of repaired samples is
//   stats.counters["repaired_samples"] (always set) and the time it took
//   stats.counters["repair_seconds"] (set when there were any);
// - times execute() (stats.total_seconds) and checks its output: 3 channels, the input's
//   size, every sample finite (WorkError otherwise).
MethodResult run_method(Method& method, const MethodInput& input);

// Registers every built-in method (methods/registry.cpp).
void register_builtin_methods(MethodRegistry& registry);

// Parses "key=value" into a pair; InputError when there is no '=' or no key.
std::pair<std::string, std::string> parse_setting(const std::string& kv);
// Parses a list of "key=value" into a map; InputError on a malformed or repeated key.
std::map<std::string, std::string> parse_settings(const std::vector<std::string>& kvs);

}  // namespace dnb
