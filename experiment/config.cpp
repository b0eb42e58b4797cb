#include "experiment/config.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <set>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "core/bounds.h"
#include "core/config.h"
#include "core/errors.h"
#include "denoisers/method.h"
#include "methods/plugins.h"

namespace fs = std::filesystem;

namespace dnb::experiment {

namespace {

// A method's parameters from a [params.NAME] or [[variant]] set table, each checked against the
// method's ParamSpec here, so that an error names the file, line and key that wrote it.
std::map<std::string, std::string> param_table(ConfigTable t, const std::string& method) {
  std::map<std::string, std::string> out;
  for (const auto& k : t.keys()) {
    out[k] = t.raw(k);
    try {
      MethodRegistry::global().parse_params(method, {{k, out[k]}});
    } catch (const InputError& e) {
      throw InputError(fmt::format("{}: {}", t.where(k), e.what()));
    }
  }
  return out;
}

void read_sections(ConfigTable& root, ExperimentConfig& c) {
  if (auto ref = root.table("reference")) {
    c.reference_spp = ref->get("spp", c.reference_spp, bounds::kSpp);
    c.reference_block_spp = ref->get("block_spp", c.reference_block_spp, bounds::kBlockSpp);
    c.reference_seed = std::uint64_t(ref->get("seed", std::int64_t(c.reference_seed), bounds::kSeed));
    ref->finish();
  }
  if (auto t = root.table("timing")) {
    c.repeats = t->get("repeats", c.repeats, bounds::kRepeats);
    c.repeat_below_seconds = t->get("repeat_below_seconds", c.repeat_below_seconds,
                                    RealBound{0, 86400, "seconds: at most a day"});
    t->finish();
  }
  if (auto t = root.table("speedup")) {
    c.plain_spp = t->get("spp", std::vector<int>{}, bounds::kSpp);
    t->finish();
  }
  if (auto t = root.table("table2")) {
    c.table2.filter_cpu = t->get("filter_cpu", c.table2.filter_cpu);
    c.table2.filter_opencl = t->get("filter_opencl", c.table2.filter_opencl);
    c.table2.irradiance_cache = t->get("irradiance_cache", c.table2.irradiance_cache);
    t->finish();
  }
}

void require_registered(const MethodRegistry& registry, const std::string& method, const std::string& where) {
  if (!registry.contains(method))
    throw InputError(fmt::format("{}: method '{}' is not in the registry (valid: {})", where, method,
                                 fmt::join(registry.names(), ", ")));
}

// `methods = [...]` with their [params.NAME] overrides, then every [[variant]].
void read_methods(ConfigTable& root, ExperimentConfig& c) {
  const auto method_names = root.get("methods", std::vector<std::string>{});
  std::map<std::string, std::map<std::string, std::string>> overrides;
  const auto& registry = MethodRegistry::global();
  if (auto p = root.table("params"))
    for (const auto& m : p->keys()) {
      auto sub = p->table(m);
      if (!sub) throw InputError(fmt::format("{}: expected a table of parameters", p->where(m)));
      if (std::find(method_names.begin(), method_names.end(), m) == method_names.end())
        throw InputError(fmt::format("{}: method '{}' is not in `methods`", p->where(m), m));
      require_registered(registry, m, root.where("methods"));
      overrides[m] = param_table(*sub, m);
    }
  std::set<std::string> seen;
  for (const auto& m : method_names) {
    require_registered(registry, m, root.where("methods"));
    if (!seen.insert(m).second) throw InputError(fmt::format("{}: method '{}' listed twice", root.where("methods"), m));
    c.methods.push_back({m, m, overrides[m], ""});
  }
  for (auto& v : root.tables("variant")) {
    MethodSpec s;
    s.name = v.require_string("name");
    s.method = v.require_string("method");
    s.group = v.get("group", "");
    role_of_group(s.group, v.where("group"));
    require_registered(registry, s.method, v.where("method"));
    if (auto set = v.table("set")) s.params = param_table(*set, s.method);
    v.finish();
    if (!seen.insert(s.name).second) throw InputError(fmt::format("{}: name '{}' used twice", v.where("name"), s.name));
    c.methods.push_back(std::move(s));
  }
}

}  // namespace

ExperimentConfig load_config(const std::string& path) {
  ConfigFile file = ConfigFile::load(path);
  ConfigTable root = file.root();
  ExperimentConfig c;
  c.path = path;
  c.name = root.get("name", fs::path(path).stem().string());
  c.width = root.get("width", c.width, bounds::kSide);
  c.height = root.get("height", c.height, bounds::kSide);
  if (std::int64_t(c.width) * c.height > bounds::kMaxPixels)
    throw InputError(fmt::format("{}: {}x{} is more than {} pixels ({})", root.where("height"), c.width, c.height,
                                 bounds::kMaxPixels, bounds::kSide.why));
  c.seed = std::uint64_t(root.get("seed", std::int64_t(c.seed), bounds::kSeed));
  c.max_depth = root.get("max_depth", c.max_depth, bounds::kMaxDepth);
  c.threads = root.get("threads", c.threads, bounds::kThreads);
  c.scenes = root.get("scenes", std::vector<std::string>{});
  if (c.scenes.empty()) throw InputError(fmt::format("{}: expected a non-empty list of scene names", root.where("scenes")));
  c.spp = root.get("spp", std::vector<int>{256}, bounds::kSpp);
  if (c.spp.empty()) throw InputError(fmt::format("{}: expected a non-empty list of spp", root.where("spp")));
  // Plug-in folders, relative to the config file; registered before the methods are checked.
  for (const auto& d : root.get("plugins", std::vector<std::string>{})) {
    const fs::path p = fs::path(d).is_absolute() ? fs::path(d) : fs::absolute(path).parent_path() / d;
    if (!fs::is_directory(p))
      throw InputError(fmt::format("{}: plug-in folder '{}' is not a folder", root.where("plugins"), p.string()));
    c.plugins.push_back(p.lexically_normal().string());
  }
  load_plugins(c.plugins);
  read_sections(root, c);
  read_methods(root, c);
  root.finish();
  // Validate every method's parameters now, not an hour into the run.
  for (const auto& m : c.methods) MethodRegistry::global().parse_params(m.method, m.params);
  return c;
}

RunConfig ExperimentConfig::recorded() const {
  RunConfig r;
  r.path = path;
  r.name = name;
  r.width = width;
  r.height = height;
  r.seed = seed;
  r.reference_spp = reference_spp;
  r.spp = spp;
  r.plain_spp = plain_spp;
  r.scenes = scenes;
  r.repeats = repeats;
  r.table2 = table2;
  for (const auto& m : methods) r.methods.push_back({m.name, m.method, m.group, m.params});
  return r;
}

}  // namespace dnb::experiment
