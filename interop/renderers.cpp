#include "interop/renderers.h"

#include <algorithm>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <mutex>
#include <unistd.h>

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include "core/config.h"
#include "core/env.h"
#include "core/errors.h"
#include "core/exr_io.h"
#include "core/file_names.h"
#include "core/hash.h"
#include "core/line_worker.h"
#include "core/subprocess.h"
#include "interop/import.h"

namespace fs = std::filesystem;
using nlohmann::json;

namespace dnb::interop {

namespace {

// The repository's renderers/ folder (the source tree; $DENOISEBENCH_SOURCE_DIR overrides at run
// time, as for the scenes and plug-ins). The Python helper denoisebench_renderer.py lives there.
fs::path renderers_dir() {
  if (const char* s = env::get("SOURCE_DIR"); s && *s) return fs::path(s) / "renderers";
  return fs::path(DNB_SOURCE_RENDERERS_DIR);
}

// An argv as it will be run: argv[0] absolute, relative to the folder, or found on PATH; later
// arguments naming files of the folder made absolute.
std::vector<std::string> resolve_argv(std::vector<std::string> argv, const fs::path& folder, const std::string& where) {
  if (argv.empty() || argv[0].empty())
    throw InputError(fmt::format("{}: expected [\"program\", \"arg\", ...] with a program first", where));
  argv[0] = resolve_program(argv[0], folder, where);
  for (std::size_t i = 1; i < argv.size(); ++i) {
    std::error_code ec;
    const fs::path p = folder / argv[i];
    if (fs::path(argv[i]).is_relative() && !argv[i].empty() && argv[i][0] != '-' && fs::exists(p, ec))
      argv[i] = p.lexically_normal().string();
  }
  return argv;
}

std::map<std::string, std::string> child_env() {
  // The helper module (renderers/denoisebench_renderer.py) importable.
  return python_worker_env(renderers_dir());
}

RendererManifest manifest_from(const ConfigFile& file, const std::string& path) {
  ConfigTable root = file.root();
  auto r = root.table("renderer");
  if (!r) throw InputError(fmt::format("{}: expected a [renderer] table (name, command, version, protocol)", path));
  RendererManifest m;
  m.path = fs::absolute(path).lexically_normal().string();
  m.folder = fs::path(m.path).parent_path().string();
  m.name = file_names::checked(r->require_string("name"), r->where("name"));
  m.description = r->get("description", "");
  m.command = resolve_argv(r->get("command", std::vector<std::string>{}), m.folder, r->where("command"));
  m.version_command = resolve_argv(r->get("version", std::vector<std::string>{}), m.folder, r->where("version"));
  // One protocol today; the key is there so that a per-render process ("frame", as the plug-ins
  // have) can be added without changing existing manifests.
  const std::string protocol = r->get("protocol", "worker");
  if (protocol != "worker")
    throw InputError(fmt::format("{}: protocol '{}': expected \"worker\" (docs/renderers.md)", r->where("protocol"), protocol));
  m.format = r->get("format", m.format);
  if (m.format != "native") {
    try {
      mapping_for(m.format);
    } catch (const InputError& e) {
      throw InputError(fmt::format("{}: {}", r->where("format"), e.what()));
    }
  }
  m.layers = r->get("layers", std::vector<std::string>{"color"});
  if (std::find(m.layers.begin(), m.layers.end(), layer::kColor) == m.layers.end())
    throw InputError(fmt::format("{}: the layers must include \"color\"", r->where("layers")));
  for (const auto& l : m.layers)
    if (!layer::find(l))
      throw InputError(fmt::format("{}: unknown layer '{}' (a frame's layers: {})", r->where("layers"), l, layer::names_help()));
  m.timeout_seconds = r->get("timeout_seconds", m.timeout_seconds);
  if (!(m.timeout_seconds > 0 && m.timeout_seconds <= 7 * 86400))
    throw InputError(fmt::format("{}: expected seconds in (0, 604800]", r->where("timeout_seconds")));
  r->finish();
  root.finish();
  return m;
}

// A private folder for a back-end's outputs, removed with it.
std::string make_work_dir() {
  std::string tmpl = (fs::temp_directory_path() / "denoisebench-renderer-XXXXXX").string();
  if (!::mkdtemp(tmpl.data()))
    throw WorkError(fmt::format("cannot create a folder in '{}': {}", fs::temp_directory_path().string(), std::strerror(errno)));
  return tmpl;
}

}  // namespace

RendererManifest load_renderer_manifest(const std::string& path) { return manifest_from(ConfigFile::load(path), path); }

std::vector<std::string> renderer_search_dirs(const std::vector<std::string>& extra) {
  std::vector<std::string> dirs = extra;
  if (const char* env = env::get("RENDERERS"))
    for (const std::string& d : split_path_list(env)) dirs.push_back(d);
  dirs.push_back(renderers_dir().string());
  return dirs;
}

std::map<std::string, RendererManifest> find_renderers(const std::vector<std::string>& dirs) {
  std::map<std::string, RendererManifest> found;
  for (const std::string& d : dirs) {
    std::error_code ec;
    if (!fs::is_directory(d, ec)) {
      if (d == renderers_dir().string()) continue;  // an installed copy may lack the repository's folder
      throw InputError(fmt::format("renderer folder '{}' {}", d, fs::exists(d, ec) ? "is not a folder" : "does not exist"));
    }
    for (const fs::path& p : manifest_files_in(d)) {
      const ConfigFile file = ConfigFile::load(p.string());
      if (!file.root().contains("renderer")) continue;
      RendererManifest m = manifest_from(file, p.string());
      const auto it = found.find(m.name);
      if (it != found.end()) {
        if (it->second.path == m.path) continue;  // the same manifest through two folders
        throw InputError(fmt::format("{}: renderer name '{}' is already taken by '{}'", m.path, m.name, it->second.path));
      }
      found.emplace(m.name, std::move(m));
    }
  }
  return found;
}

RendererBackend::RendererBackend(RendererManifest manifest) : m_(std::move(manifest)) {
  worker_ = std::make_unique<LineWorker>(LineWorkerOptions{
      .what = fmt::format("renderer '{}' ({})", m_.name, m_.path), .short_name = fmt::format("renderer '{}'", m_.name),
      .argv = m_.command, .cwd = m_.folder, .env = child_env(), .timeout_seconds = m_.timeout_seconds, .log_name = m_.name});
}

RendererBackend::~RendererBackend() {
  worker_.reset();
  if (!work_dir_.empty()) {
    std::error_code ec;
    fs::remove_all(work_dir_, ec);
  }
}

const std::string& RendererBackend::version() {
  if (!version_.empty()) return version_;
  if (!version_error_.empty()) throw WorkError(version_error_);
  Subprocess p(ProcessOptions{.argv = m_.version_command, .cwd = m_.folder, .env = child_env(), .pipe_stdout = true,
                              .on_log_line = [name = m_.name](const std::string& l) { spdlog::debug("[{}] {}", name, l); }});
  std::string line;
  const auto r = p.read_line(line, std::min(m_.timeout_seconds, 120.0));
  auto st = p.wait(10.0);
  if (!st) st = p.kill_group();
  const std::vector<std::string> tail(p.log_tail().begin(), p.log_tail().end());
  if (r != Subprocess::Read::Line || !st->ok() || line.empty()) {
    version_error_ = fmt::format("renderer '{}' ({}): its version command [{}] {}{}{}", m_.name, m_.path,
                                 fmt::join(m_.version_command, ", "),
                                 r == Subprocess::Read::Timeout ? "printed nothing in time" : st->describe(),
                                 line.empty() ? ", without a version line" : "",
                                 tail.empty() ? "" : fmt::format(":\n  {}", fmt::join(tail, "\n  ")));
    throw WorkError(version_error_);
  }
  version_ = line;
  return version_;
}

const std::string& RendererBackend::identity() {
  if (!identity_.empty()) return identity_;
  std::vector<std::string> parts = {"name=" + m_.name, "version=" + version()};
  hash_folder(m_.folder, "renderer", true, parts);
  hash_folder(renderers_dir(), "helper", false, parts);  // denoisebench_renderer.py, not the other back-ends
  identity_ = sha256_hex(fmt::format("{}", fmt::join(parts, "\n")));
  return identity_;
}

double RendererBackend::setup_seconds() const { return worker_->setup_seconds(); }

void RendererBackend::stop(bool log) { worker_->stop(log); }

AovFrame RendererBackend::render(const RenderRequest& q) {
  if (work_dir_.empty()) work_dir_ = make_work_dir();
  for (const auto& l : q.layers)
    if (std::find(m_.layers.begin(), m_.layers.end(), l) == m_.layers.end())
      throw WorkError(fmt::format("renderer '{}' ({}) does not make layer '{}' (its layers: {})", m_.name, m_.path, l,
                                  fmt::join(m_.layers, ", ")));
  const std::string out = (fs::path(work_dir_) / "out.exr").string();
  std::error_code ec;
  fs::remove(out, ec);
  const json req = {{"scene", q.scene}, {"width", q.width}, {"height", q.height}, {"spp", q.spp},
                    {"seed", q.seed},   {"max_depth", q.max_depth}, {"threads", q.threads},
                    {"output", out},    {"layers", q.layers}};
  json answer;
  double round_trip = 0;
  try {
    answer = worker_->request(req, &round_trip);
  } catch (const WorkerUnavailable& e) {
    throw WorkError(e.what());  // no other source of the scene's pixels: a failure, not a skip
  }
  const std::string what = fmt::format("renderer '{}' ({}) on '{}'", m_.name, m_.path, q.scene);
  if (!fs::exists(out)) throw WorkError(fmt::format("{}: reported success but wrote no output '{}'", what, out));
  AovFrame f;
  try {
    f = read_frame_as(out, m_.format, {.spp = q.spp}, q.layers);
  } catch (const InputError& e) {
    throw WorkError(fmt::format("{}: wrote an output the harness cannot use: {}", what, e.what()));
  }
  if (f.width() != q.width || f.height() != q.height)
    throw WorkError(fmt::format("{}: wrote a {}x{} image, {}x{} was asked for", what, f.width(), f.height(), q.width, q.height));
  for (const auto& [name, image] : f.layers())
    if (const std::size_t bad = count_non_finite(image.view()))
      throw WorkError(fmt::format("{}: layer '{}' has {} non-finite samples (NaN or Inf)", what, name, bad));
  f.meta.scene = q.scene;
  f.meta.spp = q.spp;
  f.meta.seed = q.seed;
  f.meta.tracer_version = m_.name + ": " + version();
  const json secs = answer.value("render_seconds", json(round_trip));
  f.meta.render_seconds = secs.is_number() ? secs.get<double>() : round_trip;
  f.meta.extra["renderer.round_trip_seconds"] = fmt::format("{}", round_trip);
  return f;
}

namespace {

std::mutex& backends_mutex() {
  static std::mutex m;
  return m;
}
std::map<std::string, std::shared_ptr<RendererBackend>>& backends() {  // by manifest path
  static std::map<std::string, std::shared_ptr<RendererBackend>> b;
  return b;
}

}  // namespace

std::shared_ptr<RendererBackend> renderer_backend(const std::string& name, const std::vector<std::string>& dirs) {
  const auto found = find_renderers(dirs);
  const auto it = found.find(name);
  if (it == found.end()) {
    std::vector<std::string> names;
    for (const auto& [n, m] : found) names.push_back(n);
    throw InputError(fmt::format("renderer '{}' is not a back-end found in {} (found: {})", name, fmt::join(dirs, ", "),
                                 names.empty() ? std::string("none") : fmt::format("{}", fmt::join(names, ", "))));
  }
  std::lock_guard<std::mutex> lock(backends_mutex());
  auto& b = backends()[it->second.path];
  if (!b) b = std::make_shared<RendererBackend>(it->second);
  return b;
}

void shutdown_renderer_workers() {
  std::vector<std::shared_ptr<RendererBackend>> live;
  {
    std::lock_guard<std::mutex> lock(backends_mutex());
    for (auto& [path, b] : backends()) live.push_back(b);
  }
  for (auto& b : live) b->stop(true);
}

}  // namespace dnb::interop
