#include "methods/plugins.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <mutex>
#include <set>
#include <sys/statvfs.h>
#include <unistd.h>

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include "core/env.h"
#include "core/config.h"
#include "core/enum_names.h"
#include "core/exr_io.h"
#include "core/file_names.h"
#include "core/hash.h"
#include "core/line_worker.h"
#include "core/subprocess.h"
#include "core/timer.h"

namespace fs = std::filesystem;
using nlohmann::json;

namespace dnb {

namespace {

// The repository's folders (the source tree; $DENOISEBENCH_SOURCE_DIR overrides at run time, as for the
// built-in scenes).
fs::path source_dir(const char* sub, const char* compiled) {
  if (const char* s = env::get("SOURCE_DIR"); s && *s) return fs::path(s) / sub;
  return fs::path(compiled);
}
fs::path python_dir() { return source_dir("python", DNB_SOURCE_PYTHON_DIR); }

ParamType param_type(const std::string& t, const std::string& where) {
  if (t == "float") return ParamType::Float;
  if (t == "int") return ParamType::Int;
  if (t == "bool") return ParamType::Bool;
  if (t == "string") return ParamType::String;
  throw InputError(fmt::format("{}: type '{}': expected float, int, bool or string", where, t));
}

ParamSpec read_param(ConfigTable& t, const std::string& name) {
  ParamSpec s;
  s.name = name;
  s.type = param_type(t.require_string("type"), t.where("type"));
  if (!t.contains("default")) throw InputError(fmt::format("{}: parameter '{}' has no key 'default'", t.where("type"), name));
  const std::string default_where = t.where("default");
  s.default_value = t.raw("default");
  s.doc = t.get("doc", "");
  if (t.contains("min")) s.min = t.get("min", 0.0);
  if (t.contains("max")) s.max = t.get("max", 0.0);
  s.choices = t.get("choices", std::vector<std::string>{});
  t.finish();
  if ((s.min || s.max) && s.type != ParamType::Float && s.type != ParamType::Int)
    throw InputError(fmt::format("{}: min and max apply to float and int parameters only", t.where("type")));
  if (!s.choices.empty() && s.type != ParamType::String)
    throw InputError(fmt::format("{}: choices apply to string parameters only", t.where("choices")));
  if (s.min && s.max && *s.min > *s.max)
    throw InputError(fmt::format("{}: min {} is above max {}", t.where("min"), *s.min, *s.max));
  // The default must be accepted by its own spec: checked by a registry of one.
  MethodRegistry probe;
  try {
    probe.add({.name = "probe", .params = {s}, .create = [](const Params&) -> std::unique_ptr<Method> { return nullptr; }});
  } catch (const WorkError&) {
    throw InputError(fmt::format("{}: default '{}' is not {}", default_where, s.default_value, s.expected()));
  }
  return s;
}

// ---------------------------------------------------------------------------------------------
// Running a plug-in.

std::map<std::string, std::string> child_env() {
  // The helper module (python/denoisebench_plugin.py) importable without installing it.
  return python_worker_env(python_dir());
}

std::function<void(const std::string&)> log_to(const std::string& name) {
  return [name](const std::string& line) { spdlog::info("[{}] {}", name, line); };
}

std::vector<std::string> tail_of(const Subprocess& p) { return {p.log_tail().begin(), p.log_tail().end()}; }

[[noreturn]] void fail(const PluginManifest& m, const std::string& reason, std::vector<std::string> tail = {}) {
  const std::string what = fmt::format("plug-in '{}' ({}): {}", m.name, m.path, reason);
  std::string msg = what;
  if (!tail.empty()) msg += fmt::format("; the last lines of its stderr:\n  {}", fmt::join(tail, "\n  "));
  throw PluginError(what, std::move(tail), msg);
}

// Where the scratch folders go: memory (/dev/shm) when it has room for large frames (a 1024x768
// input with guides is tens of MB; containers often give /dev/shm only 64 MB), else the system's
// temporary folder. $DENOISEBENCH_PLUGIN_TMP overrides.
fs::path parent_dir() {
  if (const char* t = env::get("PLUGIN_TMP"); t && *t) return t;
  struct statvfs v {};
  if (::statvfs("/dev/shm", &v) == 0 && double(v.f_bavail) * double(v.f_frsize) >= 1024.0 * 1024 * 1024 &&
      ::access("/dev/shm", W_OK) == 0)
    return "/dev/shm";
  return fs::temp_directory_path();
}

// A private folder for one method's IN.exr and OUT.exr, removed with it.
class WorkDir {
 public:
  WorkDir() {
    const fs::path parent = parent_dir();
    std::string tmpl = (parent / "denoisebench-plugin-XXXXXX").string();
    if (!::mkdtemp(tmpl.data()))
      throw WorkError(fmt::format("cannot create a folder in '{}': {}", parent.string(), std::strerror(errno)));
    path_ = tmpl;
  }
  ~WorkDir() {
    std::error_code ec;
    fs::remove_all(path_, ec);
  }
  std::string file(const std::string& name) const { return (path_ / name).string(); }

 private:
  fs::path path_;
};

// A worker plug-in's process, shared by every method instance (cell) of the plug-in in this
// process (core/line_worker.h: started on first use, restarted once if it dies, then failing),
// its failures told as the plug-in's: PluginError, or MethodUnavailable when it cannot run here.
class Worker {
 public:
  explicit Worker(const PluginManifest& m)
      : worker_({.what = fmt::format("plug-in '{}' ({})", m.name, m.path), .short_name = fmt::format("plug-in '{}'", m.name),
                 .argv = m.command, .cwd = m.folder, .env = child_env(), .timeout_seconds = m.timeout_seconds,
                 .log_name = m.name}) {}

  // Sends one request; returns the round trip's wall seconds. PluginError on any failure.
  double request(const json& req) {
    double seconds = 0;
    try {
      worker_.request(req, &seconds);
    } catch (const WorkerUnavailable& e) {
      throw MethodUnavailable(e.what());
    } catch (const WorkerError& e) {
      throw PluginError(e.reason(), e.log_tail(), e.what());
    }
    return seconds;
  }
  double setup_seconds() const { return worker_.setup_seconds(); }
  const std::map<std::string, std::string>& info() const { return worker_.info(); }
  void stop(bool log) { worker_.stop(log); }

 private:
  LineWorker worker_;
};

std::mutex& workers_mutex() {
  static std::mutex m;
  return m;
}
std::vector<std::weak_ptr<Worker>>& workers() {
  static std::vector<std::weak_ptr<Worker>> w;
  return w;
}

class PluginMethod : public Method {
 public:
  PluginMethod(std::shared_ptr<const PluginManifest> m, Params params, std::shared_ptr<Worker> worker)
      : m_(std::move(m)), params_(std::move(params)), worker_(std::move(worker)) {}

  // A temporal plug-in's `motion` is optional: a still frame (or a one-frame sequence) has none.
  std::vector<std::string> required_layers() const override {
    std::vector<std::string> out;
    for (const auto& l : m_->layers)
      if (!m_->temporal || l != layer::kMotion) out.push_back(l);
    return out;
  }
  std::vector<std::string> optional_layers() const override {
    std::vector<std::string> out = m_->optional_layers;
    if (m_->temporal && std::find(m_->layers.begin(), m_->layers.end(), layer::kMotion) != m_->layers.end())
      out.push_back(layer::kMotion);
    return out;
  }
  bool temporal() const override { return m_->temporal; }

  MethodResult execute(const MethodInput& input) override {
    if (!input.frame) throw InputError(fmt::format("plug-in '{}' needs a frame", m_->name));
    const AovFrame& f = *input.frame;
    if (!dir_) dir_ = std::make_unique<WorkDir>();
    const std::string in = dir_->file("in.exr"), out = dir_->file("out.exr");
    MethodResult r;
    {
      ScopedPhase p(r.stats, "write_input");
      std::vector<std::string> layers;  // the declared ones the frame has (motion only in sequences)
      for (const auto& l : m_->layers)
        if (f.has(l)) layers.push_back(l);
      for (const auto& l : m_->optional_layers)
        if (f.has(l)) layers.push_back(l);
      write_frame(f, in, {.compress = false, .edges = false, .layers = layers, .durable = false});
      std::error_code ec;
      fs::remove(out, ec);
    }
    {
      // The program's time: the process's wall time, or the request's round trip (a worker's
      // start-up is setup_seconds, apart).
      std::vector<std::string> tail;
      if (worker_) {
        json req = {{"input", in}, {"output", out}, {"params", typed_params()}};
        // Where the frame stands in its sequence (docs/plugins.md, "Sequences"): a temporal
        // worker keeps its history per sequence id and starts afresh at index 0.
        if (input.sequence)
          req["sequence"] = {{"id", input.sequence->sequence}, {"index", input.sequence->index},
                             {"count", input.sequence->count}};
        r.stats.own_seconds = worker_->request(req);
        r.stats.setup_seconds = worker_->setup_seconds();
        r.stats.info = worker_->info();
      } else {
        r.stats.own_seconds = run_frame_process(in, out, tail);
      }
      r.stats.add_phase("program", *r.stats.own_seconds);
      ScopedPhase p(r.stats, "read_output");
      r.image = read_output(out, f.width(), f.height(), tail);
    }
    return r;
  }

 private:
  json typed_params() const {
    json j = json::object();
    for (const ParamSpec& s : m_->params) {
      switch (s.type) {
        case ParamType::Float: j[s.name] = params_.f(s.name); break;
        case ParamType::Int: j[s.name] = params_.i(s.name); break;
        case ParamType::Bool: j[s.name] = params_.b(s.name); break;
        case ParamType::String: j[s.name] = params_.s(s.name); break;
      }
    }
    return j;
  }

  double run_frame_process(const std::string& in, const std::string& out, std::vector<std::string>& tail) {
    std::vector<std::string> argv = m_->command;
    for (const std::string& a : {std::string("--input"), in, std::string("--output"), out}) argv.push_back(a);
    for (const auto& [k, v] : params_.as_strings()) argv.push_back("--param"), argv.push_back(k + "=" + v);
    Stopwatch sw;
    Subprocess p(ProcessOptions{.argv = argv, .cwd = m_->folder, .env = child_env(), .on_log_line = log_to(m_->name)});
    auto st = p.wait(m_->timeout_seconds);
    const double seconds = sw.seconds();
    if (!st) {
      p.kill_group();
      fail(*m_, fmt::format("timed out after timeout_seconds = {} (its process group was killed)", m_->timeout_seconds),
           tail_of(p));
    }
    if (!st->ok()) fail(*m_, fmt::format("the program {}", st->describe()), tail_of(p));
    tail = tail_of(p);
    return seconds;
  }

  Image read_output(const std::string& out, int w, int h, const std::vector<std::string>& tail) const {
    if (!fs::exists(out)) fail(*m_, fmt::format("reported success but wrote no output '{}'", out), tail);
    Image img;
    try {
      img = read_rgb(out);
    } catch (const std::exception& e) {
      fail(*m_, fmt::format("wrote an output the harness cannot use (channels R, G, B expected): {}", e.what()), tail);
    }
    if (img.width() != w || img.height() != h)
      fail(*m_, fmt::format("wrote a {}x{} image for a {}x{} frame", img.width(), img.height(), w, h), tail);
    if (const std::size_t bad = count_non_finite(img.view()))
      fail(*m_, fmt::format("wrote {} non-finite samples (NaN or Inf) of {}", bad, img.size()), tail);
    return img;
  }

  std::shared_ptr<const PluginManifest> m_;
  Params params_;
  std::shared_ptr<Worker> worker_;
  std::unique_ptr<WorkDir> dir_;
};

PluginManifest manifest_from(const ConfigFile& file, const std::string& path, const std::vector<std::string>& builtins);

}  // namespace

PluginManifest load_plugin_manifest(const std::string& path, const std::vector<std::string>& builtins) {
  return manifest_from(ConfigFile::load(path), path, builtins);
}

namespace {

PluginManifest manifest_from(const ConfigFile& file, const std::string& path, const std::vector<std::string>& builtins) {
  ConfigTable root = file.root();
  auto pl = root.table("plugin");
  if (!pl) throw InputError(fmt::format("{}: expected a [plugin] table (name, command, protocol, layers)", path));
  PluginManifest m;
  m.path = fs::absolute(path).lexically_normal().string();
  m.folder = fs::path(m.path).parent_path().string();
  // A plug-in's name is a method's name: it becomes its cells' image stems.
  m.name = file_names::checked(pl->require_string("name"), pl->where("name"));
  if (std::find(builtins.begin(), builtins.end(), m.name) != builtins.end())
    throw InputError(fmt::format("{}: name '{}' is a built-in method's; choose another", pl->where("name"), m.name));
  m.description = pl->get("description", "");
  m.command = pl->get("command", std::vector<std::string>{});
  if (m.command.empty()) throw InputError(fmt::format("{}: expected command = [\"program\", \"arg\", ...]", pl->where("command")));
  m.command[0] = resolve_program(m.command[0], m.folder, pl->where("command"));
  for (std::size_t i = 1; i < m.command.size(); ++i) {
    std::error_code ec;
    const fs::path p = fs::path(m.folder) / m.command[i];
    if (fs::path(m.command[i]).is_relative() && !m.command[i].empty() && m.command[i][0] != '-' && fs::exists(p, ec))
      m.command[i] = p.lexically_normal().string();
  }
  const std::string protocol = pl->get("protocol", "frame");
  static constexpr EnumName<PluginProtocol> kProtocols[] = {{PluginProtocol::Frame, "frame"}, {PluginProtocol::Worker, "worker"}};
  m.protocol = enum_from_name(protocol, kProtocols, pl->where("protocol"));
  m.layers = pl->get("layers", std::vector<std::string>{});
  if (m.layers.empty()) throw InputError(fmt::format("{}: expected a non-empty list of frame layers", pl->where("layers")));
  for (const auto& l : m.layers)
    if (!layer::find(l))
      throw InputError(fmt::format("{}: unknown layer '{}' (a frame's layers: {})", pl->where("layers"), l, layer::names_help()));
  m.optional_layers = pl->get("optional_layers", std::vector<std::string>{});
  for (const auto& l : m.optional_layers) {
    if (!layer::find(l))
      throw InputError(
          fmt::format("{}: unknown layer '{}' (a frame's layers: {})", pl->where("optional_layers"), l, layer::names_help()));
    if (std::find(m.layers.begin(), m.layers.end(), l) != m.layers.end())
      throw InputError(fmt::format("{}: '{}' is in layers too", pl->where("optional_layers"), l));
  }
  m.temporal = pl->get("temporal", false);
  if (m.temporal && m.protocol != PluginProtocol::Worker)
    throw InputError(fmt::format("{}: a temporal plug-in keeps history between frames, which needs protocol = \"worker\" "
                                 "(one process for the run; docs/plugins.md, \"Sequences\")",
                                 pl->where("temporal")));
  const auto reads = [&m](const char* l) {
    return std::find(m.layers.begin(), m.layers.end(), l) != m.layers.end() ||
           std::find(m.optional_layers.begin(), m.optional_layers.end(), l) != m.optional_layers.end();
  };
  if (reads(layer::kMotion) && !m.temporal)
    throw InputError(fmt::format("{}: layer 'motion' is in the frames of sequences only, which a plug-in reads as one when "
                                 "`temporal = true`",
                                 pl->where("layers")));
  m.timeout_seconds = pl->get("timeout_seconds", m.timeout_seconds);
  if (!(m.timeout_seconds > 0 && m.timeout_seconds <= 86400))
    throw InputError(fmt::format("{}: expected seconds in (0, 86400]", pl->where("timeout_seconds")));
  pl->finish();
  if (auto params = root.table("params"))
    for (const auto& k : params->keys()) {
      auto t = params->table(k);
      if (!t) throw InputError(fmt::format("{}: expected a table [params.{}] with type, default, doc", params->where(k), k));
      m.params.push_back(read_param(*t, k));
    }
  root.finish();
  return m;
}

}  // namespace

std::string plugin_content_hash(const PluginManifest& m) {
  // Every regular file under the folder and under the helper's, by relative path and content;
  // hidden entries and Python caches are left out (they do not change what the program does).
  std::vector<std::string> parts;
  hash_folder(m.folder, "plugin", true, parts);
  hash_folder(python_dir(), "harness-python", true, parts);
  return sha256_hex(fmt::format("{}", fmt::join(parts, "\n")));
}

std::vector<std::string> plugin_search_dirs(const std::vector<std::string>& extra) {
  std::vector<std::string> dirs = extra;
  if (const char* env = env::get("PLUGINS"))
    for (const std::string& d : split_path_list(env)) dirs.push_back(d);
  dirs.push_back(source_dir("plugins", DNB_SOURCE_PLUGINS_DIR).string());
  return dirs;
}

std::vector<std::string> register_plugins(const std::vector<std::string>& dirs) {
  MethodRegistry& registry = MethodRegistry::global();
  static std::mutex mutex;
  std::lock_guard<std::mutex> lock(mutex);
  std::vector<std::string> builtins;
  for (const MethodInfo* mi : registry.all())
    if (mi->origin.empty()) builtins.push_back(mi->name);
  std::vector<std::string> added;
  for (const std::string& d : dirs) {
    std::error_code ec;
    if (!fs::is_directory(d, ec)) {
      // The repository's own folder may be absent in an installed copy; a folder the user named must exist.
      if (d == source_dir("plugins", DNB_SOURCE_PLUGINS_DIR).string()) continue;
      throw InputError(fmt::format("plug-in folder '{}' {}", d, fs::exists(d, ec) ? "is not a folder" : "does not exist"));
    }
    for (const fs::path& p : manifest_files_in(d)) {
      // Any *.toml of the folder: a manifest when it has a [plugin] table (a malformed file is
      // reported: it may be a manifest with a typo).
      const ConfigFile file = ConfigFile::load(p.string());
      if (!file.root().contains("plugin")) continue;
      PluginManifest m = manifest_from(file, p.string(), builtins);
      if (registry.contains(m.name)) {
        const MethodInfo& old = registry.info(m.name);
        if (old.origin == m.path) continue;  // the same manifest, found again
        throw InputError(fmt::format("{}: plug-in name '{}' is already taken by '{}'", m.path, m.name, old.origin));
      }
      auto manifest = std::make_shared<const PluginManifest>(m);
      std::shared_ptr<Worker> worker;
      if (m.protocol == PluginProtocol::Worker) {
        worker = std::make_shared<Worker>(m);
        std::lock_guard<std::mutex> wl(workers_mutex());
        workers().push_back(worker);
      }
      MethodInfo info;
      info.name = m.name;
      info.description = m.description;
      info.kind = MethodKind::Filter;
      info.temporal = m.temporal;
      info.params = m.params;
      info.origin = m.path;
      info.content_hash = plugin_content_hash(m);
      info.create = [manifest, worker](const Params& p) -> std::unique_ptr<Method> {
        return std::make_unique<PluginMethod>(manifest, p, worker);
      };
      registry.add(std::move(info));
      added.push_back(m.name);
    }
  }
  return added;
}

std::vector<std::string> load_plugins(const std::vector<std::string>& extra) {
  return register_plugins(plugin_search_dirs(extra));
}

void shutdown_plugin_workers() {
  std::vector<std::shared_ptr<Worker>> live;
  {
    std::lock_guard<std::mutex> lock(workers_mutex());
    for (auto& w : workers())
      if (auto s = w.lock()) live.push_back(s);
  }
  for (auto& w : live) w->stop(true);
}

}  // namespace dnb
