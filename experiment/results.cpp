#include "experiment/results.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <set>
#include <utility>

#include "core/bounds.h"
#include "core/enum_names.h"
#include "core/json_file.h"

using nlohmann::json;

namespace dnb::experiment {

namespace jf = json_file;

// ---------------------------------------------------------------------------------------------
// Roles

namespace {
constexpr EnumName<Role> kRoleNames[] = {
    {Role::Plain, "plain"}, {Role::Input, "input"}, {Role::Method, "method"}, {Role::Ablation, "ablation"}};
}  // namespace

const char* to_string(Role r) { return enum_name(r, kRoleNames); }

Role role_from_string(const std::string& s, const std::string& where) { return enum_from_name(s, kRoleNames, where + ": key 'role'"); }

Role role_of_group(const std::string& group, const std::string& where) {
  if (group.empty()) return Role::Method;
  if (group == "ablation") return Role::Ablation;
  throw InputError(fmt::format("{}: expected \"ablation\" or no group (got \"{}\")", where, group));
}

// ---------------------------------------------------------------------------------------------
// Reading helpers

namespace {

json object_or_empty(const json& j, const std::string& key, const std::string& where) {
  if (!j.contains(key)) return json::object();
  if (!j.at(key).is_object()) throw InputError(fmt::format("{}: key '{}': expected an object", where, key));
  return j.at(key);
}

std::map<std::string, double> number_map(const json& j, const std::string& where) {
  std::map<std::string, double> out;
  for (const auto& [k, v] : j.items()) out[k] = jf::number(j, k, where);
  return out;
}

std::optional<double> optional_number(const json& j, const std::string& key, const std::string& where) {
  if (!j.contains(key) || j.at(key).is_null()) return std::nullopt;
  return jf::number(j, key, where);
}

template <class T>
std::optional<T> optional_value(const json& j, const std::string& key, const std::string& where) {
  if (!j.contains(key)) return std::nullopt;
  return jf::get<T>(j, key, where);
}

// Counts and durations are never negative in a file a run wrote: a negative one was edited in,
// and would be a wrong number in a table.
double non_negative(double v, const std::string& key, const std::string& where) {
  if (!(v >= 0)) throw InputError(fmt::format("{}: key '{}': expected a value >= 0, got {}", where, key, v));
  return v;
}
double non_negative_number(const json& j, const std::string& key, const std::string& where) {
  return non_negative(jf::number(j, key, where), key, where);
}

// A file a record names is inside the results folder: a relative path that never climbs out
// (the report reads and copies these files; a shared results.json must not make it read others).
const std::string& inside_folder(const std::string& path, const std::string& key, const std::string& where) {
  const std::filesystem::path p(path);
  if (p.is_absolute() || std::find(p.begin(), p.end(), "..") != p.end())
    throw InputError(fmt::format("{}: key '{}': '{}' is outside the results folder (expected a path relative to it, "
                                 "without '..')",
                                 where, key, path));
  return path;
}

json numbers_json(const std::map<std::string, double>& m) {
  json o = json::object();
  for (const auto& [k, v] : m) o[k] = v;
  return o;
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// CellRecord

std::optional<double> CellRecord::metric(const std::string& name) const {
  auto it = metrics.find(name);
  return it == metrics.end() ? std::nullopt : it->second;
}

std::string CellRecord::file(const std::string& name) const {
  auto it = files.find(name);
  return it == files.end() ? std::string() : it->second;
}

json times_to_json(const CellTimes& times) {
  json t = {{"input_render", times.input_render}, {"filter", times.filter}, {"total", times.total}};
  if (times.reference) t["reference"] = *times.reference;
  if (times.filter_runs) t["filter_runs"] = *times.filter_runs;
  if (times.setup) t["setup_seconds"] = *times.setup;
  return t;
}

CellTimes times_from_json(const json& times, const std::string& tw) {
  CellTimes t;
  t.input_render = non_negative_number(times, "input_render", tw);
  t.filter = non_negative_number(times, "filter", tw);
  t.total = non_negative_number(times, "total", tw);
  t.reference = optional_number(times, "reference", tw);
  t.filter_runs = optional_value<std::vector<double>>(times, "filter_runs", tw);
  t.setup = optional_number(times, "setup_seconds", tw);
  if (t.reference) non_negative(*t.reference, "reference", tw);
  if (t.setup) non_negative(*t.setup, "setup_seconds", tw);
  if (t.filter_runs)
    for (double v : *t.filter_runs) non_negative(v, "filter_runs", tw);
  return t;
}

json curve_to_json(const CurveOrigin& c) { return {{"rendered_spp", c.rendered_spp}, {"prefix_spp", c.prefix_spp}}; }

CurveOrigin curve_from_json(const json& j, const std::string& where) {
  CurveOrigin c;
  c.rendered_spp = jf::get<int>(j, "rendered_spp", where);
  c.prefix_spp = jf::get<int>(j, "prefix_spp", where);
  if (c.prefix_spp < 1 || c.prefix_spp > c.rendered_spp)
    throw InputError(fmt::format("{}: expected 1 <= prefix_spp <= rendered_spp, got prefix_spp {} of rendered_spp {}",
                                 where, c.prefix_spp, c.rendered_spp));
  return c;
}

// ---- CellMeasurement: one codec per field type, the field list in results.h ----

namespace {

json field_json(const CellTimes& t) { return times_to_json(t); }
json field_json(const CurveOrigin& c) { return curve_to_json(c); }
json field_json(bool b) { return b; }
json field_json(const std::map<std::string, double>& m) { return numbers_json(m); }
json field_json(const std::map<std::string, std::string>& m) { return m; }

void read_field(const json& v, const std::string& key, const std::string& where, CellTimes& out) {
  out = times_from_json(v, where + ": " + key);
}
void read_field(const json& v, const std::string& key, const std::string& where, CurveOrigin& out) {
  out = curve_from_json(v, where + ": " + key);
}
void read_field(const json& v, const std::string& key, const std::string& where, bool& out) {
  if (!v.is_boolean()) throw InputError(fmt::format("{}: key '{}': expected true or false", where, key));
  out = v.get<bool>();
}
void read_field(const json& v, const std::string& key, const std::string& where, std::map<std::string, double>& out) {
  if (!v.is_object()) throw InputError(fmt::format("{}: key '{}': expected an object", where, key));
  out = number_map(v, where + ": " + key);
}
void read_field(const json& v, const std::string& key, const std::string& where, std::map<std::string, std::string>& out) {
  if (!v.is_object()) throw InputError(fmt::format("{}: key '{}': expected an object", where, key));
  for (const auto& [k, s] : v.items()) {
    if (!s.is_string()) throw InputError(fmt::format("{}: {}: key '{}': expected a string", where, key, k));
    out[k] = s.get<std::string>();
  }
}

template <class T>
struct IsOptional : std::false_type {};
template <class T>
struct IsOptional<std::optional<T>> : std::true_type {};

}  // namespace

void CellMeasurement::write_json(json& object) const {
  fields(*this, [&](const char* key, const auto& v) {
    if constexpr (IsOptional<std::decay_t<decltype(v)>>::value) {
      if (v) object[key] = field_json(*v);
    } else {
      object[key] = field_json(v);
    }
  });
}

CellMeasurement CellMeasurement::read_json(const json& object, const std::string& where) {
  CellMeasurement m;
  fields(m, [&](const char* key, auto& v) {
    using T = std::decay_t<decltype(v)>;
    if constexpr (IsOptional<T>::value) {
      if (!object.contains(key) || object.at(key).is_null()) return;
      typename T::value_type x{};
      read_field(object.at(key), key, where, x);
      v = std::move(x);
    } else {
      if (!object.contains(key)) throw InputError(fmt::format("{}: missing key '{}'", where, key));
      read_field(object.at(key), key, where, v);
    }
  });
  return m;
}

json CellRecord::to_json() const {
  json r = {{"scene", scene}, {"method", method}, {"role", to_string(role)}, {"spp", spp}, {"width", width}, {"height", height}};
  if (!scene_hash.empty()) r["scene_hash"] = scene_hash;
  if (seed) r["seed"] = *seed;
  if (!cell_key.empty()) r["cell_key"] = cell_key;
  json m = json::object();
  for (const auto& [k, v] : metrics) m[k] = v ? jf::number_or_null(*v) : json(nullptr);
  r["metrics"] = m;
  write_json(r);
  json ref = {{"spp", reference.spp}, {"seconds", reference.seconds}, {"image", reference.image},
              {"unconverged_share", reference.unconverged_share ? json(*reference.unconverged_share) : json(nullptr)}};
  if (reference.seed) ref["seed"] = *reference.seed;
  if (reference.cache_hit) ref["cache_hit"] = *reference.cache_hit;
  if (reference.unconverged_rse) ref["unconverged_rse"] = *reference.unconverged_rse;
  if (reference.estimated_error) ref["estimated_error"] = *reference.estimated_error;
  r["reference"] = ref;
  if (!files.empty()) r["files"] = files;
  if (!base_method.empty()) r["base_method"] = base_method;
  if (kind) r["kind"] = to_string(*kind);
  if (params) r["params"] = *params;
  if (blocks) r["blocks"] = numbers_json(*blocks);
  if (!worse_tiles.empty()) r["worse_tiles"] = worse_tiles;
  return r;
}

CellRecord CellRecord::from_json(const json& j, const std::string& where) {
  if (!j.is_object()) throw InputError(fmt::format("{}: expected an object", where));
  CellRecord r;
  r.scene = jf::get<std::string>(j, "scene", where);
  r.scene_hash = jf::get_or<std::string>(j, "scene_hash", "", where);
  r.method = jf::get<std::string>(j, "method", where);
  r.role = role_from_string(jf::get<std::string>(j, "role", where), where);
  r.spp = int(non_negative(jf::get<int>(j, "spp", where), "spp", where));
  r.width = jf::get<int>(j, "width", where);
  r.height = jf::get<int>(j, "height", where);
  for (const auto& [key, side] : {std::pair{"width", r.width}, std::pair{"height", r.height}})
    if (side < bounds::kSide.min || side > bounds::kSide.max)
      throw InputError(fmt::format("{}: key '{}': {}", where, key, bound_violation(bounds::kSide, std::to_string(side))));
  r.seed = optional_value<std::uint64_t>(j, "seed", where);
  r.cell_key = jf::get_or<std::string>(j, "cell_key", "", where);

  const json metrics = jf::get<json>(j, "metrics", where);
  if (!metrics.is_object()) throw InputError(fmt::format("{}: key 'metrics': expected an object", where));
  for (const auto& [k, v] : metrics.items()) r.metrics[k] = optional_number(metrics, k, where + ": metrics");

  static_cast<CellMeasurement&>(r) = CellMeasurement::read_json(j, where);

  const json ref = jf::get<json>(j, "reference", where);
  const std::string rw = where + ": reference";
  r.reference.spp = int(non_negative(jf::get<int>(ref, "spp", rw), "spp", rw));
  r.reference.seed = optional_value<std::uint64_t>(ref, "seed", rw);
  r.reference.seconds = non_negative_number(ref, "seconds", rw);
  r.reference.cache_hit = optional_value<bool>(ref, "cache_hit", rw);
  r.reference.image = inside_folder(jf::get_or<std::string>(ref, "image", "", rw), "image", rw);
  r.reference.unconverged_share = optional_number(ref, "unconverged_share", rw);
  r.reference.unconverged_rse = optional_number(ref, "unconverged_rse", rw);
  r.reference.estimated_error = optional_value<std::map<std::string, double>>(ref, "estimated_error", rw);

  r.files = jf::get_or<std::map<std::string, std::string>>(j, "files", {}, where);
  for (const auto& [k, f] : r.files) inside_folder(f, k, where + ": files");
  r.base_method = jf::get_or<std::string>(j, "base_method", "", where);
  if (j.contains("kind")) r.kind = method_kind_from_string(jf::get<std::string>(j, "kind", where), where);
  r.params = optional_value<std::map<std::string, std::string>>(j, "params", where);
  if (j.contains("blocks")) r.blocks = number_map(object_or_empty(j, "blocks", where), where + ": blocks");
  if (j.contains("worse_tiles")) {
    const json& t = j.at("worse_tiles");
    auto bad = [&] { return InputError(fmt::format("{}: worse_tiles: expected a list of [x, y, w, h, ratio] number lists", where)); };
    if (!t.is_array()) throw bad();
    for (const auto& e : t) {
      if (!e.is_array() || e.size() != 5) throw bad();
      std::array<double, 5> a{};
      for (std::size_t k = 0; k < 5; ++k) {
        if (!e[k].is_number()) throw bad();
        a[k] = e[k].get<double>();
      }
      r.worse_tiles.push_back(a);
    }
  }
  return r;
}

// ---------------------------------------------------------------------------------------------
// RunConfig

namespace {

json scene_files_json(const std::map<std::string, SceneFilesEntry>& files) {
  json o = json::object();
  for (const auto& [name, f] : files) {
    o[name] = {{"frame", f.frame}, {"reference", f.reference}};
    if (!f.second.empty()) o[name]["second"] = f.second;  // only where the config gives one
  }
  return o;
}

json config_json(const RunConfig& c) {
  json methods = json::array();
  for (const auto& m : c.methods)
    methods.push_back({{"name", m.name}, {"method", m.method}, {"group", m.group}, {"params", m.params}});
  json j = {{"path", c.path},
            {"name", c.name},
            {"width", c.width},
            {"height", c.height},
            {"seed", c.seed},
            {"reference_spp", c.reference_spp},
            {"spp", c.spp},
            {"plain_spp", c.plain_spp},
            {"scenes", c.scenes},
            {"repeats", c.repeats},
            {"table2",
             {{"filter_cpu", c.table2.filter_cpu},
              {"filter_opencl", c.table2.filter_opencl},
              {"irradiance_cache", c.table2.irradiance_cache}}},
            {"methods", methods}};
  if (!c.scene_files.empty()) j["scene_files"] = scene_files_json(c.scene_files);  // only configs that have them
  for (const auto& [name, r] : c.scene_renderers) j["scene_renderers"][name] = {{"renderer", r.renderer}, {"file", r.file}};
  if (!c.sequences.empty()) j["sequences"] = c.sequences;
  if (c.seeds.size() > 1) j["seeds"] = c.seeds;  // only configs of several seeds: one-seed files read as before
  if (!c.reference_scene_spp.empty()) j["reference_scene_spp"] = c.reference_scene_spp;
  return j;
}

// Keys a hand-written fixture may leave out default to an empty value; present keys are typed.
RunConfig config_from_json(const json& j, const std::string& where) {
  if (!j.is_object()) throw InputError(fmt::format("{}: expected an object", where));
  RunConfig c;
  c.path = jf::get_or<std::string>(j, "path", "", where);
  c.name = jf::get_or<std::string>(j, "name", "", where);
  c.width = jf::get_or<int>(j, "width", 0, where);
  c.height = jf::get_or<int>(j, "height", 0, where);
  c.seed = jf::get_or<std::uint64_t>(j, "seed", 0, where);
  c.seeds = jf::get_or<std::vector<std::uint64_t>>(j, "seeds", {c.seed}, where);
  c.reference_spp = jf::get_or<int>(j, "reference_spp", 0, where);
  c.reference_scene_spp = jf::get_or<std::map<std::string, int>>(j, "reference_scene_spp", {}, where);
  c.spp = jf::get_or<std::vector<int>>(j, "spp", {}, where);
  c.plain_spp = jf::get_or<std::vector<int>>(j, "plain_spp", {}, where);
  c.scenes = jf::get_or<std::vector<std::string>>(j, "scenes", {}, where);
  const json files = object_or_empty(j, "scene_files", where);
  for (const auto& [name, f] : files.items()) {
    const std::string fw = where + ": scene_files: " + name;
    c.scene_files[name] = {jf::get<std::string>(f, "frame", fw), jf::get<std::string>(f, "reference", fw),
                           jf::get_or<std::string>(f, "second", "", fw)};
  }
  const json renderers = object_or_empty(j, "scene_renderers", where);
  for (const auto& [name, r] : renderers.items()) {
    const std::string rw = where + ": scene_renderers: " + name;
    c.scene_renderers[name] = {jf::get<std::string>(r, "renderer", rw), jf::get<std::string>(r, "file", rw)};
  }
  const json sequences = object_or_empty(j, "sequences", where);
  for (const auto& [name, n] : sequences.items()) {
    if (!n.is_number_integer() || n.get<int>() < 1)
      throw InputError(fmt::format("{}: sequences: {}: expected a frame count (a positive integer)", where, name));
    c.sequences[name] = n.get<int>();
  }
  c.repeats = jf::get_or<int>(j, "repeats", 0, where);
  const json t2 = object_or_empty(j, "table2", where);
  const std::string tw = where + ": table2";
  c.table2.filter_cpu = jf::get_or<std::string>(t2, "filter_cpu", c.table2.filter_cpu, tw);
  c.table2.filter_opencl = jf::get_or<std::string>(t2, "filter_opencl", c.table2.filter_opencl, tw);
  c.table2.irradiance_cache = jf::get_or<std::string>(t2, "irradiance_cache", c.table2.irradiance_cache, tw);
  const json methods = jf::get_or<json>(j, "methods", json::array(), where);
  if (!methods.is_array()) throw InputError(fmt::format("{}: key 'methods': expected an array", where));
  for (std::size_t i = 0; i < methods.size(); ++i) {
    const std::string mw = fmt::format("{}: methods[{}]", where, i);
    c.methods.push_back({jf::get<std::string>(methods[i], "name", mw), jf::get<std::string>(methods[i], "method", mw),
                         jf::get_or<std::string>(methods[i], "group", "", mw),
                         jf::get_or<std::map<std::string, std::string>>(methods[i], "params", {}, mw)});
  }
  return c;
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// ResultsDocument

std::vector<std::string> ResultsDocument::scenes() const {
  if (!config.scenes.empty()) return config.scenes;
  std::vector<std::string> s;
  for (const auto& r : records)
    if (std::find(s.begin(), s.end(), r.scene) == s.end()) s.push_back(r.scene);
  return s;
}

int ResultsDocument::table_spp() const {
  if (!config.spp.empty()) return config.spp.front();
  for (const auto& r : records)
    if (r.role != Role::Plain) return r.spp;
  return 0;
}

std::vector<std::string> ResultsDocument::methods(Role role) const {
  std::vector<std::string> m;
  for (const auto& r : records)
    if (r.role == role && std::find(m.begin(), m.end(), r.method) == m.end()) m.push_back(r.method);
  return m;
}

json FailedCell::to_json() const {
  return {{"scene", scene}, {"method", method}, {"spp", spp}, {"cell_key", cell_key}, {"reason", reason}, {"log_tail", log_tail}};
}

FailedCell FailedCell::from_json(const json& j, const std::string& where) {
  if (!j.is_object()) throw InputError(fmt::format("{}: expected an object", where));
  FailedCell f;
  f.scene = jf::get<std::string>(j, "scene", where);
  f.method = jf::get<std::string>(j, "method", where);
  f.spp = jf::get<int>(j, "spp", where);
  f.cell_key = jf::get_or<std::string>(j, "cell_key", "", where);
  f.reason = jf::get<std::string>(j, "reason", where);
  f.log_tail = jf::get_or<std::vector<std::string>>(j, "log_tail", {}, where);
  return f;
}

json SkippedCell::to_json() const { return {{"scene", scene}, {"method", method}, {"spp", spp}, {"reason", reason}}; }

SkippedCell SkippedCell::from_json(const json& j, const std::string& where) {
  if (!j.is_object()) throw InputError(fmt::format("{}: expected an object", where));
  return {jf::get<std::string>(j, "scene", where), jf::get<std::string>(j, "method", where), jf::get<int>(j, "spp", where),
          jf::get<std::string>(j, "reason", where)};
}

std::optional<double> SequenceRecord::metric(const std::string& name) const {
  const auto it = metrics.find(name);
  if (it == metrics.end() || !it->second || !std::isfinite(*it->second)) return std::nullopt;
  return it->second;
}

json SequenceRecord::to_json() const {
  json j = {{"sequence", sequence}, {"method", method}, {"role", to_string(role)}, {"spp", spp}, {"frames", frames},
            {"images", images}};
  if (seed) j["seed"] = *seed;
  json m = json::object();
  for (const auto& [k, v] : metrics) m[k] = v ? jf::number_or_null(*v) : json(nullptr);
  j["metrics"] = m;
  json pf = json::object();
  for (const auto& [k, values] : per_frame) {
    json a = json::array();
    for (const auto& v : values) a.push_back(v ? jf::number_or_null(*v) : json(nullptr));
    pf[k] = a;
  }
  j["per_frame"] = pf;
  return j;
}

SequenceRecord SequenceRecord::from_json(const json& j, const std::string& where) {
  if (!j.is_object()) throw InputError(fmt::format("{}: expected an object", where));
  SequenceRecord r;
  r.sequence = jf::get<std::string>(j, "sequence", where);
  r.method = jf::get<std::string>(j, "method", where);
  r.role = role_from_string(jf::get<std::string>(j, "role", where), where);
  r.spp = jf::get<int>(j, "spp", where);
  r.frames = jf::get<int>(j, "frames", where);
  r.seed = optional_value<std::uint64_t>(j, "seed", where);
  r.images = jf::get_or<std::vector<std::string>>(j, "images", {}, where);
  const json metrics = jf::get<json>(j, "metrics", where);
  if (!metrics.is_object()) throw InputError(fmt::format("{}: key 'metrics': expected an object", where));
  for (const auto& [k, v] : metrics.items()) r.metrics[k] = optional_number(metrics, k, where + ": metrics");
  const json pf = jf::get_or<json>(j, "per_frame", json::object(), where);
  if (!pf.is_object()) throw InputError(fmt::format("{}: key 'per_frame': expected an object", where));
  for (const auto& [k, values] : pf.items()) {
    if (!values.is_array()) throw InputError(fmt::format("{}: per_frame: {}: expected an array", where, k));
    auto& out = r.per_frame[k];
    for (const auto& v : values) {
      if (v.is_null()) out.emplace_back();
      else if (v.is_number()) out.emplace_back(v.get<double>());
      else throw InputError(fmt::format("{}: per_frame: {}: expected numbers or null", where, k));
    }
  }
  return r;
}

const SkippedCell* ResultsDocument::skip(const std::string& scene, const std::string& method, int spp) const {
  for (const auto& s : skipped)
    if (s.scene == scene && s.method == method && s.spp == spp) return &s;
  return nullptr;
}

const FailedCell* ResultsDocument::failure(const std::string& scene, const std::string& method, int spp) const {
  for (const auto& f : failures)
    if (f.scene == scene && f.method == method && f.spp == spp) return &f;
  return nullptr;
}

std::vector<const CellRecord*> ResultsDocument::find_all(const std::string& scene, const std::string& method, int spp) const {
  std::vector<const CellRecord*> out;
  for (const auto& r : records)
    if (r.scene == scene && r.method == method && r.spp == spp) out.push_back(&r);
  std::stable_sort(out.begin(), out.end(), [](const CellRecord* a, const CellRecord* b) { return a->seed < b->seed; });
  return out;
}

const CellRecord* ResultsDocument::find(const std::string& scene, const std::string& method, int spp) const {
  for (const auto& r : records)
    if (r.scene == scene && r.method == method && r.spp == spp) return &r;
  return nullptr;
}

json ResultsDocument::to_json() const {
  json j;
  j["format"] = kResultsFormat;
  j["schema_version"] = kResultsSchemaVersion;
  j["config"] = config_json(config);
  j["machine"] = machine;
  j["build"] = build;
  j["git_revision"] = git_revision;
  if (written) j["written"] = *written;
  json recs = json::array();
  for (const auto& r : records) recs.push_back(r.to_json());
  j["records"] = std::move(recs);
  json fails = json::array();
  for (const auto& f : failures) fails.push_back(f.to_json());
  j["failures"] = std::move(fails);
  json skips = json::array();
  for (const auto& k : skipped) skips.push_back(k.to_json());
  j["skipped"] = std::move(skips);
  if (!sequences.empty()) {
    json seqs = json::array();
    for (const auto& s : sequences) seqs.push_back(s.to_json());
    j["sequences"] = std::move(seqs);
  }
  return j;
}

ResultsDocument ResultsDocument::from_json(const json& j, const std::string& where) {
  if (!j.is_object()) throw InputError(fmt::format("{}: expected a JSON object (a results.json of `denoisebench run`)", where));
  const std::string format = jf::get_or<std::string>(j, "format", "", where);
  if (format == "denoisebench-results-1")
    throw InputError(fmt::format("{}: key 'format': written by an older denoisebench (results schema 1); this one reads "
                                 "schema_version {}: run the config again into a new folder",
                                 where, kResultsSchemaVersion));
  if (format != kResultsFormat)
    throw InputError(fmt::format("{}: key 'format': expected \"{}\" (a results.json of `denoisebench run`), got \"{}\"", where,
                                 kResultsFormat, format));
  const int version = jf::get<int>(j, "schema_version", where);
  if (version < kOldestResultsSchemaVersion || version > kResultsSchemaVersion)
    throw InputError(fmt::format("{}: key 'schema_version': this denoisebench reads versions {} to {}, the file has {}", where,
                                 kOldestResultsSchemaVersion, kResultsSchemaVersion, version));
  ResultsDocument d;
  d.config = config_from_json(jf::get_or<json>(j, "config", json::object(), where), where + ": config");
  d.machine = object_or_empty(j, "machine", where);
  d.build = object_or_empty(j, "build", where);
  d.git_revision = jf::get_or<std::string>(j, "git_revision", "", where);
  d.written = optional_value<std::int64_t>(j, "written", where);
  const json records = jf::get<json>(j, "records", where);
  if (!records.is_array()) throw InputError(fmt::format("{}: key 'records': expected an array", where));
  std::set<std::pair<std::string, std::optional<std::uint64_t>>> cells;
  for (std::size_t i = 0; i < records.size(); ++i) {
    const std::string rw = fmt::format("{}: records[{}]", where, i);
    d.records.push_back(CellRecord::from_json(records[i], rw));
    // A run keeps one record per cell and seed (a rerun replaces it): a second one was pasted in
    // and would count twice in a mean.
    const CellRecord& r = d.records.back();
    if (!r.cell_key.empty() && !cells.emplace(r.cell_key, r.seed).second)
      throw InputError(fmt::format("{}: key 'cell_key': cell {} (seed {}) has a record already", rw, r.cell_key,
                                   r.seed ? std::to_string(*r.seed) : std::string("none")));
  }
  const json failures = jf::get_or<json>(j, "failures", json::array(), where);
  if (!failures.is_array()) throw InputError(fmt::format("{}: key 'failures': expected an array", where));
  for (std::size_t i = 0; i < failures.size(); ++i)
    d.failures.push_back(FailedCell::from_json(failures[i], fmt::format("{}: failures[{}]", where, i)));
  const json skipped = jf::get_or<json>(j, "skipped", json::array(), where);
  if (!skipped.is_array()) throw InputError(fmt::format("{}: key 'skipped': expected an array", where));
  for (std::size_t i = 0; i < skipped.size(); ++i)
    d.skipped.push_back(SkippedCell::from_json(skipped[i], fmt::format("{}: skipped[{}]", where, i)));
  const json sequences = jf::get_or<json>(j, "sequences", json::array(), where);
  if (!sequences.is_array()) throw InputError(fmt::format("{}: key 'sequences': expected an array", where));
  for (std::size_t i = 0; i < sequences.size(); ++i)
    d.sequences.push_back(SequenceRecord::from_json(sequences[i], fmt::format("{}: sequences[{}]", where, i)));
  return d;
}

ResultsDocument ResultsDocument::load(const std::string& path) { return from_json(jf::read(path), "'" + path + "'"); }

}  // namespace dnb::experiment
