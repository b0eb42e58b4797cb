#include "experiment/runner.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <set>
#include <thread>

#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include "core/atomic_file.h"
#include "core/config.h"
#include "core/errors.h"
#include "core/exr_io.h"
#include "core/progress.h"
#include "core/timer.h"
#include "core/version.h"
#include "denoisers/method.h"
#include "metrics/metrics.h"
#include "tracer/cache.h"
#include "tracer/cache_keys.h"
#include "tracer/reference.h"
#include "tracer/render.h"
#include "tracer/scene_loader.h"

namespace fs = std::filesystem;
using nlohmann::json;

namespace dnb::experiment {

namespace {

std::vector<int> int_list(ConfigTable& t, const std::string& key, std::vector<int> def) {
  std::vector<double> d(def.begin(), def.end());
  std::vector<int> out;
  for (double v : t.get(key, d)) {
    if (v < 1 || v != std::floor(v)) throw InputError(fmt::format("{}: expected positive integers", t.where(key)));
    out.push_back(int(v));
  }
  return out;
}

std::map<std::string, std::string> param_table(ConfigTable t) {
  std::map<std::string, std::string> out;
  for (const auto& k : t.keys()) out[k] = t.raw(k);
  return out;
}

}  // namespace

ExperimentConfig load_config(const std::string& path) {
  ConfigFile file = ConfigFile::load(path);
  ConfigTable root = file.root();
  ExperimentConfig c;
  c.path = path;
  c.name = root.get("name", fs::path(path).stem().string());
  c.width = root.get("width", c.width);
  c.height = root.get("height", c.height);
  c.seed = std::uint64_t(root.get("seed", std::int64_t(c.seed)));
  c.max_depth = root.get("max_depth", c.max_depth);
  c.threads = root.get("threads", c.threads);
  c.scenes = root.get("scenes", std::vector<std::string>{});
  if (c.scenes.empty()) throw InputError(fmt::format("{}: expected a non-empty list of scene names", root.where("scenes")));
  c.spp = int_list(root, "spp", {256});
  const auto method_names = root.get("methods", std::vector<std::string>{});
  if (auto ref = root.table("reference")) {
    c.reference_spp = ref->get("spp", c.reference_spp);
    c.reference_block_spp = ref->get("block_spp", c.reference_block_spp);
    c.reference_seed = std::uint64_t(ref->get("seed", std::int64_t(c.reference_seed)));
    ref->finish();
  }
  if (auto t = root.table("timing")) {
    c.repeats = t->get("repeats", c.repeats);
    c.repeat_below_seconds = t->get("repeat_below_seconds", c.repeat_below_seconds);
    t->finish();
  }
  if (auto t = root.table("speedup")) {
    c.plain_spp = int_list(*t, "spp", {});
    t->finish();
  }
  if (auto t = root.table("table2")) {
    c.table2_cpu = t->get("filter_cpu", c.table2_cpu);
    c.table2_opencl = t->get("filter_opencl", c.table2_opencl);
    c.table2_irradiance_cache = t->get("irradiance_cache", c.table2_irradiance_cache);
    t->finish();
  }
  std::map<std::string, std::map<std::string, std::string>> overrides;
  if (auto p = root.table("params"))
    for (const auto& m : p->keys()) {
      auto sub = p->table(m);
      if (!sub) throw InputError(fmt::format("{}: expected a table of parameters", p->where(m)));
      if (std::find(method_names.begin(), method_names.end(), m) == method_names.end())
        throw InputError(fmt::format("{}: method '{}' is not in `methods`", p->where(m), m));
      overrides[m] = param_table(*sub);
    }
  const auto& registry = MethodRegistry::global();
  std::set<std::string> seen;
  for (const auto& m : method_names) {
    if (!registry.contains(m))
      throw InputError(fmt::format("{}: method '{}' is not in the registry (valid: {})", root.where("methods"), m,
                                   fmt::join(registry.names(), ", ")));
    if (!seen.insert(m).second) throw InputError(fmt::format("{}: method '{}' listed twice", root.where("methods"), m));
    c.methods.push_back({m, m, overrides[m], ""});
  }
  for (auto& v : root.tables("variant")) {
    MethodSpec s;
    s.name = v.require_string("name");
    s.method = v.require_string("method");
    s.group = v.get("group", "");
    if (auto set = v.table("set")) s.params = param_table(*set);
    v.finish();
    if (!registry.contains(s.method))
      throw InputError(fmt::format("{}: method '{}' is not in the registry (valid: {})", v.where("method"), s.method,
                                   fmt::join(registry.names(), ", ")));
    if (!seen.insert(s.name).second) throw InputError(fmt::format("{}: name '{}' used twice", v.where("name"), s.name));
    c.methods.push_back(std::move(s));
  }
  root.finish();
  // Validate every method's parameters now, not an hour into the run.
  for (const auto& m : c.methods) registry.parse_params(m.method, m.params);
  return c;
}

namespace {

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

json number_or_null(double v) { return std::isfinite(v) ? json(v) : json(nullptr); }

json machine_info() {
  json m;
  char host[256] = {};
  gethostname(host, sizeof host - 1);
  m["hostname"] = host;
  m["hardware_threads"] = std::thread::hardware_concurrency();
  std::ifstream cpu("/proc/cpuinfo");
  for (std::string line; std::getline(cpu, line);)
    if (line.rfind("model name", 0) == 0) {
      m["cpu"] = line.substr(line.find(':') + 2);
      break;
    }
  return m;
}

// The SHA-256 of the running program's own file: it changes with any rebuild that changes code,
// so a finished method cell is reused only when the very same build computed it. (The git
// revision is fixed at configure time and misses uncommitted edits, so it cannot serve.) Input
// frames and references keep their own cache keys (scene, settings, tracer version) and are
// not re-rendered by a rebuild.
const std::string& build_id() {
  static const std::string id = [] {
    std::ifstream in("/proc/self/exe", std::ios::binary);
    std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    return bytes.empty() ? std::string("unknown") : sha256_hex(bytes);
  }();
  return id;
}

json build_info() {
  return {{"version", DNB_VERSION}, {"git_revision", DNB_GIT_REVISION}, {"build_type", DNB_BUILD_TYPE},
          {"compiler", DNB_COMPILER}, {"tracer_version", kTracerVersion}, {"build_id", build_id()}};
}

std::string safe(const std::string& s) {
  std::string o = s;
  for (char& ch : o)
    if (!std::isalnum(static_cast<unsigned char>(ch)) && ch != '-' && ch != '_' && ch != '.') ch = '_';
  return o;
}

// Scores `image` against the reference with every metric; writes the error maps the report shows.
json score(const Image& image, const Reference& reference, const std::string& out_dir, const std::string& stem,
           json& files) {
  json m;
  const Image* variance = reference.variance.empty() ? nullptr : &reference.variance;
  for (const auto& info : metrics::all_metrics()) {
    metrics::MetricResult r = info.compute(image, reference.color, variance);
    m[info.name] = number_or_null(r.value);
    if (info.name == "flip" || info.name == "relmse") {
      Image rgb(r.map.width(), r.map.height(), 3);
      for (std::size_t p = 0; p < r.map.pixel_count(); ++p)
        for (int c = 0; c < 3; ++c) rgb.data()[3 * p + c] = r.map.data()[p];
      std::string rel = stem + ".err_" + info.name + ".exr";
      write_rgb(rgb, out_dir + "/" + rel);
      files["error_" + info.name] = rel;
    }
  }
  return m;
}

class ResultsStore {
 public:
  // results.json lists the cells of this run's config; finished_cells.json keeps every cell
  // ever finished in this folder, so that a run that stops early (killed, or a config listing
  // fewer cells) does not forget the cells it had not reached yet: results.json alone is
  // rewritten after every cell with only the cells visited so far.
  ResultsStore(std::string dir, json header) : dir_(std::move(dir)), doc_(std::move(header)) {
    doc_["records"] = json::array();
    for (const char* name : {"finished_cells.json", "results.json"}) {
      const std::string path = dir_ + "/" + name;
      if (!fs::exists(path)) continue;
      try {
        json old = json::parse(read_text_file(path));
        for (auto& r : old.at("records")) cells_[r.at("cell_key").get<std::string>()] = r;
      } catch (const std::exception& e) {
        throw InputError(fmt::format("'{}' exists but cannot be resumed from ({}): remove it or choose another -o", path, e.what()));
      }
    }
  }
  const json* finished(const std::string& key) const {
    auto it = cells_.find(key);
    return it == cells_.end() ? nullptr : &it->second;
  }
  void add(json record) {
    cells_[record.at("cell_key").get<std::string>()] = record;
    doc_["records"].push_back(std::move(record));
    write();
  }
  void reuse(const json& record) { doc_["records"].push_back(record); }
  void write() {
    doc_["written"] = std::time(nullptr);
    write_text_atomic(dir_ + "/results.json", doc_.dump(2) + "\n");
    write_text_atomic(dir_ + "/results.csv", results_csv(doc_));
    json cells = {{"format", "denoisebench-finished-cells-1"}, {"records", json::array()}};
    for (const auto& [key, r] : cells_) cells["records"].push_back(r);
    write_text_atomic(dir_ + "/finished_cells.json", cells.dump(1) + "\n");
  }
  const json& doc() const { return doc_; }

 private:
  std::string dir_;
  json doc_;
  std::map<std::string, json> cells_;  // every finished cell, earlier runs' and this one's, by key
};

}  // namespace

nlohmann::json run_experiment(const ExperimentConfig& c, const RunOptions& opt) {
  fs::create_directories(opt.out_dir + "/images");
  Cache cache(opt.cache_dir.empty() ? Cache::default_dir() : opt.cache_dir);
  const auto& registry = MethodRegistry::global();

  json header;
  header["format"] = "denoisebench-results-1";
  header["config"] = {{"path", c.path}, {"name", c.name}, {"width", c.width}, {"height", c.height},
                      {"seed", c.seed}, {"reference_spp", c.reference_spp}, {"spp", c.spp},
                      {"plain_spp", c.plain_spp}, {"scenes", c.scenes}, {"repeats", c.repeats},
                      {"table2", {{"filter_cpu", c.table2_cpu}, {"filter_opencl", c.table2_opencl},
                                  {"irradiance_cache", c.table2_irradiance_cache}}}};
  json methods = json::array();
  for (const auto& m : c.methods)
    methods.push_back({{"name", m.name}, {"method", m.method}, {"group", m.group}, {"params", m.params}});
  header["config"]["methods"] = methods;
  header["machine"] = machine_info();
  header["build"] = build_info();
  header["git_revision"] = DNB_GIT_REVISION;
  ResultsStore store(opt.out_dir, header);

  const std::int64_t cells_total =
      std::int64_t(c.scenes.size()) * (std::int64_t(c.spp.size()) * (std::int64_t(c.methods.size()) + 1) + std::int64_t(c.plain_spp.size()));
  Progress progress("experiment " + c.name, cells_total, "cells", 0.0);

  for (const auto& scene_name : c.scenes) {
    auto scene = load_scene(scene_name);
    const std::string scene_hash = scene_content_hash(*scene);
    const std::string img_dir = "images/" + safe(scene_name);
    fs::create_directories(opt.out_dir + "/" + img_dir);

    // The reference (cached and checkpointed by tracer/reference.h).
    ReferenceSettings rs;
    rs.width = c.width; rs.height = c.height; rs.spp = c.reference_spp; rs.seed = c.reference_seed;
    rs.max_depth = c.max_depth; rs.block_spp = c.reference_block_spp; rs.threads = c.threads;
    ReferenceOptions ro;
    ro.cache_dir = cache.dir();
    ro.use_cache = opt.use_cache;
    spdlog::info("{}: reference {} spp at {}x{}", scene_name, rs.spp, rs.width, rs.height);
    Reference ref = reference_image(*scene, rs, ro);
    const double reference_seconds = ref.convergence.empty() ? ref.render_seconds : ref.convergence.back().seconds;
    const std::string ref_rel = img_dir + "/reference.exr";
    if (!fs::exists(opt.out_dir + "/" + ref_rel)) write_rgb(ref.color, opt.out_dir + "/" + ref_rel);
    // The reference's own unconverged pixels (fireflies carried by a few samples): mse_converged
    // leaves them out; the report names their share beside it.
    const json unconverged = ref.variance.empty() ? json(nullptr)
                                                   : json(metrics::unconverged_share(ref.color, ref.variance));

    auto base_record = [&](const std::string& method, int spp) {
      json r;
      r["scene"] = scene_name;
      r["scene_hash"] = scene_hash;
      r["method"] = method;
      r["spp"] = spp;
      r["width"] = c.width;
      r["height"] = c.height;
      r["seed"] = c.seed;
      r["reference"] = {{"spp", c.reference_spp}, {"seed", c.reference_seed}, {"seconds", reference_seconds},
                        {"cache_hit", ref.cache_hit}, {"image", ref_rel},
                        {"unconverged_share", unconverged}, {"unconverged_rse", metrics::kUnconvergedRse}};
      return r;
    };
    // Everything that determines a cell's result: a finished cell with the same key is reused.
    auto cell_key = [&](const json& identity) { return sha256_hex(identity.dump()); };

    // Plain path tracing: the error-versus-time curve of the speed-up claim.
    for (int spp : c.plain_spp) {
      json r = base_record("path_tracing", spp);
      r["role"] = "plain";
      const std::string key = cell_key({{"plain", spp}, {"scene", scene_hash}, {"w", c.width}, {"h", c.height},
                                        {"seed", c.seed}, {"ref", c.reference_spp}, {"depth", c.max_depth},
                                        {"tracer", kTracerVersion}});
      if (const json* old = store.finished(key); old && fs::exists(opt.out_dir + "/" + (*old)["files"]["image"].get<std::string>())) {
        store.reuse(*old);
        progress.add(1);
        continue;
      }
      RenderSettings s;
      s.width = c.width; s.height = c.height; s.spp = spp; s.seed = c.seed; s.threads = c.threads; s.max_depth = c.max_depth;
      Stopwatch w;
      Image img = render_color_sums(*scene, s, 0, spp).mean();
      const double t = w.seconds();
      json files;
      const std::string stem = img_dir + "/path_tracing_" + std::to_string(spp);
      write_rgb(img, opt.out_dir + "/" + stem + ".exr");
      files["image"] = stem + ".exr";
      r["metrics"] = score(img, ref, opt.out_dir, stem, files);
      r["times"] = {{"input_render", t}, {"filter", 0.0}, {"total", t}, {"reference", reference_seconds}};
      r["files"] = files;
      r["cell_key"] = key;
      store.add(r);
      progress.add(1);
    }

    for (int spp : c.spp) {
      RenderSettings s;
      s.width = c.width; s.height = c.height; s.spp = spp; s.seed = c.seed; s.threads = c.threads; s.max_depth = c.max_depth;
      const CacheKey fkey = frame_cache_key(*scene, s);
      if (!opt.use_cache) cache.remove(fkey);
      bool hit = false;
      AovFrame frame = cached_frame(cache, fkey, [&] { return render_frame(*scene, s); }, &hit);
      const double input_seconds = frame.meta.render_seconds;
      const Image& input = frame.layer(layer::kColor);

      // The unfiltered input itself: the baseline every method improves on.
      {
        json r = base_record("input", spp);
        r["role"] = "input";
        const std::string key = cell_key({{"input", fkey.digest()}, {"ref", c.reference_spp}, {"build", build_id()}});
        if (const json* old = store.finished(key)) {
          store.reuse(*old);
        } else {
          json files;
          const std::string stem = img_dir + "/input_" + std::to_string(spp);
          write_rgb(input, opt.out_dir + "/" + stem + ".exr");
          files["image"] = stem + ".exr";
          r["metrics"] = score(input, ref, opt.out_dir, stem, files);
          r["times"] = {{"input_render", input_seconds}, {"filter", 0.0}, {"total", input_seconds},
                        {"reference", reference_seconds}};
          r["input_cache_hit"] = hit;
          r["files"] = files;
          r["cell_key"] = key;
          store.add(r);
        }
        progress.add(1);
      }

      for (const auto& m : c.methods) {
        const MethodInfo& info = registry.info(m.method);
        Params params = registry.parse_params(m.method, m.params);
        json r = base_record(m.name, spp);
        r["role"] = m.group.empty() ? "method" : m.group;
        r["base_method"] = m.method;
        r["kind"] = to_string(info.kind);
        r["params"] = params.as_strings();
        const std::string key = cell_key({{"method", m.method}, {"params", r["params"]}, {"input", fkey.digest()},
                                          {"ref", c.reference_spp}, {"repeats", c.repeats},
                                          {"repeat_below", c.repeat_below_seconds}, {"build", build_id()}});
        if (const json* old = store.finished(key); old && fs::exists(opt.out_dir + "/" + (*old)["files"]["image"].get<std::string>())) {
          store.reuse(*old);
          progress.add(1);
          continue;
        }
        auto method = registry.create(m.method, m.params);
        MethodInput in;
        in.frame = &frame;
        in.scene = scene.get();
        in.sample_budget = spp;
        in.width = c.width;
        in.height = c.height;
        in.seed = c.seed;
        // Timing: the first run; if it is shorter than repeat_below_seconds it counts as the
        // warm-up and the median of `repeats` further runs is the time.
        MethodResult first = run_method(*method, in);
        std::vector<double> times{first.stats.total_seconds};
        if (first.stats.total_seconds < c.repeat_below_seconds && c.repeats > 0) {
          times.clear();
          for (int i = 0; i < c.repeats; ++i) times.push_back(run_method(*method, in).stats.total_seconds);
        }
        const double filter_seconds = median(times);
        json files;
        const std::string stem = img_dir + "/" + safe(m.name) + "_" + std::to_string(spp);
        write_rgb(first.image, opt.out_dir + "/" + stem + ".exr");
        files["image"] = stem + ".exr";
        r["metrics"] = score(first.image, ref, opt.out_dir, stem, files);
        // Renderer-type methods render the scene themselves: their total is their own time.
        const bool renderer = info.kind == MethodKind::Renderer;
        const double input_used = renderer ? 0.0 : input_seconds;
        r["times"] = {{"input_render", input_used}, {"filter", filter_seconds}, {"total", input_used + filter_seconds},
                      {"reference", reference_seconds}, {"filter_runs", times}};
        json phases = json::object();
        for (const auto& [name, sec] : first.stats.phases) phases[name] = sec;
        r["phases"] = phases;
        r["counters"] = first.stats.counters;
        r["input_cache_hit"] = hit;
        r["files"] = files;
        r["cell_key"] = key;
        store.add(r);
        progress.add(1);
      }
    }
  }
  progress.finish();
  store.write();
  spdlog::info("results in {}/results.json ({} records)", opt.out_dir, store.doc()["records"].size());
  return store.doc();
}

std::string results_csv(const nlohmann::json& results) {
  std::vector<std::string> metric_cols = metrics::metric_names();
  const std::vector<std::string> time_cols = {"input_render", "filter", "total", "reference"};
  std::string out = "scene,method,role,spp,width,height";
  for (const auto& m : metric_cols) out += "," + m;
  for (const auto& t : time_cols) out += ",time_" + t;
  out += ",params,image\n";
  auto csv_field = [](std::string s) {
    if (s.find_first_of(",\"\n") == std::string::npos) return s;
    std::string q = "\"";
    for (char ch : s) q += ch == '"' ? std::string("\"\"") : std::string(1, ch);
    return q + "\"";
  };
  for (const auto& r : results.at("records")) {
    out += fmt::format("{},{},{},{},{},{}", csv_field(r.at("scene")), csv_field(r.at("method")),
                       r.value("role", ""), r.at("spp").get<int>(), r.value("width", 0), r.value("height", 0));
    for (const auto& m : metric_cols) {
      const json& v = r.at("metrics").contains(m) ? r.at("metrics").at(m) : json(nullptr);
      out += v.is_number() ? fmt::format(",{:.9g}", v.get<double>()) : ",";
    }
    for (const auto& t : time_cols) {
      const json& v = r.at("times").contains(t) ? r.at("times").at(t) : json(nullptr);
      out += v.is_number() ? fmt::format(",{:.6g}", v.get<double>()) : ",";
    }
    std::string params;
    if (r.contains("params"))
      for (auto& [k, v] : r.at("params").items())
        params += fmt::format("{}{}={}", params.empty() ? "" : ";", k, v.get<std::string>());
    const std::string image = r.contains("files") ? r["files"].value("image", "") : "";
    out += fmt::format(",{},{}\n", csv_field(params), csv_field(image));
  }
  return out;
}

}  // namespace dnb::experiment
