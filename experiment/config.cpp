#include "experiment/config.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>
#include <set>
#include <tuple>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "core/bounds.h"
#include "core/config.h"
#include "interop/import.h"
#include "interop/renderers.h"
#include "tracer/scene.h"
#include "tracer/scene_loader.h"
#include "core/errors.h"
#include "core/file_names.h"
#include "core/hash.h"
#include "denoisers/method.h"
#include "experiment/input_files.h"
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
    if (auto per = ref->table("scene")) {
      for (const auto& name : per->keys()) {
        auto t = per->table(name);  // the key is there: a table, or an InputError naming it
        const bool rendered = std::any_of(c.scenes.begin(), c.scenes.end(),
                                          [&](const SceneSpec& s) { return s.name == name && !s.files; });
        if (!rendered)
          throw InputError(fmt::format("{}: '{}' is not a rendered scene of this config: only those have a reference "
                                       "to render",
                                       per->where(name), name));
        c.reference_scene_spp[name] = t->get("spp", c.reference_spp, bounds::kSpp);
        t->finish();
      }
      per->finish();
    }
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
    s.name = file_names::checked(v.require_string("name"), v.where("name"));
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

// A [[scene]] path, relative to the config file's folder; InputError naming the key when the
// file is not there.
std::string scene_file(ConfigTable& t, const std::string& key, const fs::path& config_dir) {
  const std::string given = t.require_string(key);
  const fs::path p = (fs::path(given).is_absolute() ? fs::path(given) : config_dir / given).lexically_normal();
  if (!fs::is_regular_file(p)) throw InputError(fmt::format("{}: file '{}' does not exist", t.where(key), p.string()));
  return p.string();
}

// Reads a file of a [[scene]] through read_input_frame, naming the key that named it.
template <class F>
auto read_named(ConfigTable& t, const std::string& key, F read) {
  try {
    return read();
  } catch (const InputError& e) {
    throw InputError(fmt::format("{}: {}", t.where(key), e.what()));
  }
}

// A [[scene]] read from files: both read now, so that a wrong file is an error before any work.
SceneSpec file_scene(ConfigTable& t, const fs::path& config_dir, const std::string& input_format) {
  if (!t.contains("reference"))
    throw InputError(fmt::format("{}: a frame needs its reference: add `reference = \"...\"` to this [[scene]]", t.where("frame")));
  if (!t.contains("frame"))
    throw InputError(fmt::format("{}: a reference without a frame: add `frame = \"...\"` (the input to filter) to this [[scene]]",
                                 t.where("reference")));
  SceneFiles f;
  f.frame = scene_file(t, "frame", config_dir);
  f.reference = scene_file(t, "reference", config_dir);
  if (t.contains("second")) f.second = scene_file(t, "second", config_dir);
  // A label the config gives is refused unless it is a file name; the default, the frame file's
  // stem, is mapped to one.
  SceneSpec s{t.contains("label") ? file_names::checked(t.require_string("label"), t.where("label"))
                                  : file_names::mapped(fs::path(f.frame).stem().string()),
              std::nullopt};
  const int spp = t.contains("spp") ? t.get("spp", 0, bounds::kSpp) : 0;
  f.input_format = t.get("input_format", input_format);
  t.finish();
  const AovFrame frame = read_named(t, f.second.empty() ? "frame" : "second",
                                    [&] { return read_input_frame(f.frame, f.input_format, spp, f.second); });
  const Reference ref = read_named(t, "reference", [&] { return file_reference(f.reference, f.input_format); });
  f.width = frame.width();
  f.height = frame.height();
  if (ref.color.width() != f.width || ref.color.height() != f.height)
    throw InputError(fmt::format("{}: '{}' is {}x{}, its frame '{}' is {}x{}: a reference must have its frame's size",
                                 t.where("reference"), f.reference, ref.color.width(), ref.color.height(), f.frame, f.width,
                                 f.height));
  f.spp = frame.meta.spp;
  if (!f.second.empty() && spp > 0) f.spp = 2 * spp;  // `spp` is each file's
  if (spp > 0 && f.second.empty() && f.spp > 0 && spp != f.spp)
    throw InputError(fmt::format("{}: {} spp, but '{}' records {} spp", t.where("spp"), spp, f.frame, f.spp));
  if (f.spp <= 0) f.spp = spp;
  if (f.spp <= 0)
    throw InputError(fmt::format("{}: '{}' records no sample count: add `spp = N` to this [[scene]]", t.where("frame"), f.frame));
  // The format is part of what the cells are keyed by: the same bytes read another way are
  // another frame.
  f.frame_hash = f.input_format == "auto" ? frame_file_hash(f.frame)
                                          : sha256_hex(frame_file_hash(f.frame) + "\ninput_format=" + f.input_format);
  if (!f.second.empty()) f.frame_hash = sha256_hex(f.frame_hash + "\nsecond=" + frame_file_hash(f.second));
  f.reference_hash = sha256_file(f.reference);
  s.files = std::move(f);
  return s;
}

// A [[scene]] a renderer back-end renders: the back-end must exist and the file too; what the
// back-end makes of the file is its own business (a malformed file fails that scene's cells
// with the back-end's message, when the run renders it).
SceneSpec renderer_scene(ConfigTable& t, const fs::path& config_dir, const std::vector<std::string>& renderer_dirs) {
  for (const char* key : {"name", "frame", "reference", "second", "input_format", "spp"})
    if (t.contains(key))
      throw InputError(fmt::format("{}: a [[scene]] a back-end renders (`renderer`, `file`) takes only `label` besides: "
                                   "remove `{}`",
                                   t.where(key), key));
  SceneRenderer r;
  r.renderer = t.require_string("renderer");
  if (t.contains("file") == t.contains("scene"))
    throw InputError(fmt::format("{}: a back-end renders a scene file (`file = \"scene.xml\"`) or one of the tracer's "
                                 "scenes exported as glTF (`scene = \"cornell-box\"`): give one of the two",
                                 t.where("renderer")));
  if (t.contains("scene")) {
    // Checked now (a typo is an error naming the key, before any work); exported by the run.
    r.scene = t.require_string("scene");
    const fs::path as_file = config_dir / r.scene;
    std::error_code ec;
    if (fs::is_regular_file(as_file, ec)) r.scene = as_file.lexically_normal().string();
    try {
      (void)load_scene(r.scene);
    } catch (const InputError& e) {
      throw InputError(fmt::format("{}: {}", t.where("scene"), e.what()));
    }
  } else {
    r.file = scene_file(t, "file", config_dir);
  }
  const auto found = interop::find_renderers(interop::renderer_search_dirs(renderer_dirs));
  if (!found.count(r.renderer)) {
    std::vector<std::string> names;
    for (const auto& [n, m] : found) names.push_back(n);
    throw InputError(fmt::format("{}: renderer '{}' is not a back-end found in {} (found: {}; docs/renderers.md)",
                                 t.where("renderer"), r.renderer,
                                 fmt::join(interop::renderer_search_dirs(renderer_dirs), ", "),
                                 names.empty() ? std::string("none") : fmt::format("{}", fmt::join(names, ", "))));
  }
  if (!r.file.empty()) r.file_hash = sha256_file(r.file);
  const std::string stem = r.file.empty() ? fs::path(r.scene).stem().string() + "-" + r.renderer : fs::path(r.file).stem().string();
  SceneSpec s{t.contains("label") ? file_names::checked(t.require_string("label"), t.where("label")) : file_names::mapped(stem),
              std::nullopt, std::move(r)};
  t.finish();
  return s;
}

// `frames = N` of a rendered [[scene]]: the scene must be animated and have N frames at least.
int sequence_frames(ConfigTable& t, const std::string& name) {
  static constexpr Bound kFrames{1, 100000, "a sequence of 1 to 100000 frames"};
  const int n = t.get("frames", 1, kFrames);
  std::shared_ptr<const Scene> scene;
  try {
    scene = load_scene(name);
  } catch (const InputError& e) {
    throw InputError(fmt::format("{}: {}", t.where("name"), e.what()));
  }
  if (!scene->animated())
    throw InputError(fmt::format("{}: scene '{}' is a still (no [animation] table): only an animated scene runs as a "
                                 "sequence (docs/sequences.md)",
                                 t.where("frames"), name));
  if (n > scene->frames)
    throw InputError(fmt::format("{}: {} frames asked of scene '{}', which has {}", t.where("frames"), n, name, scene->frames));
  return n;
}

}  // namespace

std::string sequence_row(const std::string& name, int frame) { return fmt::format("{}.f{:02d}", name, frame); }

namespace {

// `scenes = [...]` (rendered), then every [[scene]]: `name = "..."` (rendered, as in `scenes`)
// or `frame` and `reference` (read from files).
void read_scenes(ConfigTable& root, ExperimentConfig& c) {
  const fs::path config_dir = fs::absolute(c.path).parent_path();
  const bool listed = root.contains("scenes");
  for (const auto& n : root.get("scenes", std::vector<std::string>{})) c.scenes.push_back({n, std::nullopt});
  for (const auto& d : root.get("renderers", std::vector<std::string>{})) {
    const fs::path p = fs::path(d).is_absolute() ? fs::path(d) : config_dir / d;
    if (!fs::is_directory(p))
      throw InputError(fmt::format("{}: renderer folder '{}' is not a folder", root.where("renderers"), p.string()));
    c.renderers.push_back(p.lexically_normal().string());
  }
  const std::string input_format = root.get("input_format", std::string("auto"));
  if (input_format != "auto" && input_format != "native")
    read_named(root, "input_format", [&] { return interop::mapping_for(input_format).name; });  // a typo fails here
  for (auto& t : root.tables("scene")) {
    if (t.contains("renderer")) {
      c.scenes.push_back(renderer_scene(t, config_dir, c.renderers));
      continue;
    }
    if (t.contains("file"))
      throw InputError(fmt::format("{}: a scene file for a renderer back-end needs `renderer = \"NAME\"` (docs/renderers.md); "
                                   "a scene file for the harness's tracer is `name = \"...\"`",
                                   t.where("file")));
    const bool files = t.contains("frame") || t.contains("reference");
    if (t.contains("name") && files)
      throw InputError(fmt::format("{}: a [[scene]] is rendered (`name`) or read from files (`frame`, `reference`), not both",
                                   t.where(t.contains("frame") ? "frame" : "reference")));
    if (!t.contains("name") && !files)
      throw InputError(fmt::format("{}: expected `name` (a scene to render), `renderer` and `file` (a scene a back-end "
                                   "renders) or `frame` and `reference` (files)",
                                   t.where("name")));
    if (files) {
      c.scenes.push_back(file_scene(t, config_dir, input_format));
    } else {
      SceneSpec s{t.require_string("name"), std::nullopt};
      if (t.contains("frames")) s.frames = sequence_frames(t, s.name);
      c.scenes.push_back(std::move(s));
      t.finish();
    }
  }
  if (c.scenes.empty())
    throw InputError(fmt::format("{}: expected a non-empty list of scene names{}", root.where("scenes"),
                                 listed ? "" : " (or [[scene]] tables)"));
  // Rendered scenes may be named by a scene file's path: their folders take the mapped name, so
  // two scenes must differ in that too.
  std::map<std::string, std::string> folders;
  for (const auto& s : c.scenes) {
    const auto [it, fresh] = folders.emplace(file_names::mapped(s.name), s.name);
    if (fresh) continue;
    if (it->second == s.name)
      throw InputError(fmt::format("{}: scene '{}' is named twice (a [[scene]] read from files takes `label = \"...\"`)",
                                   root.where(listed ? "scenes" : "scene"), s.name));
    throw InputError(fmt::format("{}: scenes '{}' and '{}' would share the folder name '{}': rename one",
                                 root.where(listed ? "scenes" : "scene"), it->second, s.name, it->first));
  }
}

bool any_rendered(const ExperimentConfig& c) {
  return std::any_of(c.scenes.begin(), c.scenes.end(), [](const SceneSpec& s) { return !s.files; });
}

// Keys that only set up renders have no effect when every scene is read from files: an error,
// not silence.
void refuse_render_keys(const ConfigTable& root) {
  for (const char* key : {"width", "height", "seed", "seeds", "max_depth", "spp", "reference", "speedup"})
    if (root.contains(key))
      throw InputError(fmt::format("{}: sets up rendered scenes, and every scene of this config is read from files "
                                   "([[scene]] frame = ...): remove it",
                                   root.where(key)));
}

}  // namespace

ExperimentConfig load_config(const std::string& path) {
  ConfigFile file = ConfigFile::load(path);
  ConfigTable root = file.root();
  ExperimentConfig c;
  c.path = path;
  // The default results folder is results/<name>: a name the config writes must be a file name,
  // the default (the config file's stem) is mapped to one.
  c.name = root.contains("name") ? file_names::checked(root.require_string("name"), root.where("name"))
                                 : file_names::mapped(fs::path(path).stem().string());
  c.width = root.get("width", c.width, bounds::kSide);
  c.height = root.get("height", c.height, bounds::kSide);
  if (std::int64_t(c.width) * c.height > bounds::kMaxPixels)
    throw InputError(fmt::format("{}: {}x{} is more than {} pixels ({})", root.where("height"), c.width, c.height,
                                 bounds::kMaxPixels, bounds::kSide.why));
  if (root.contains("seed") && root.contains("seeds"))
    throw InputError(fmt::format("{}: give `seed` or `seeds`, not both", root.where("seeds")));
  c.seed = std::uint64_t(root.get("seed", std::int64_t(c.seed), bounds::kSeed));
  c.seeds = {c.seed};
  if (root.contains("seeds")) {
    const auto list = root.get("seeds", std::vector<int>{}, Bound{0, std::numeric_limits<int>::max(), "seeds are non-negative"});
    if (list.empty()) throw InputError(fmt::format("{}: expected a non-empty list of seeds", root.where("seeds")));
    c.seeds.assign(list.begin(), list.end());
    std::set<std::uint64_t> seen;
    for (auto s : c.seeds)
      if (!seen.insert(s).second) throw InputError(fmt::format("{}: seed {} is listed twice", root.where("seeds"), s));
    c.seed = c.seeds.front();
  }
  c.max_depth = root.get("max_depth", c.max_depth, bounds::kMaxDepth);
  c.threads = root.get("threads", c.threads, bounds::kThreads);
  read_scenes(root, c);
  if (!any_rendered(c)) refuse_render_keys(root);
  c.spp = root.get("spp", std::vector<int>{256}, bounds::kSpp);
  if (c.spp.empty()) throw InputError(fmt::format("{}: expected a non-empty list of spp", root.where("spp")));
  // A back-end's input is two independent halves of spp / 2 samples each (its half buffers).
  if (std::any_of(c.scenes.begin(), c.scenes.end(), [](const SceneSpec& s) { return s.renderer.has_value(); }))
    for (int spp : c.spp)
      if (spp % 2 != 0)
        throw InputError(fmt::format("{}: {} spp: a scene a renderer back-end renders takes an even spp (its input is two "
                                     "independent halves of spp / 2 samples)",
                                     root.where("spp"), spp));
  if (!any_rendered(c)) c.spp.clear();
  // Plug-in folders, relative to the config file; registered before the methods are checked.
  for (const auto& d : root.get("plugins", std::vector<std::string>{})) {
    const fs::path p = fs::path(d).is_absolute() ? fs::path(d) : fs::absolute(path).parent_path() / d;
    if (!fs::is_directory(p))
      throw InputError(fmt::format("{}: plug-in folder '{}' is not a folder", root.where("plugins"), p.string()));
    c.plugins.push_back(p.lexically_normal().string());
  }
  load_plugins(c.plugins);
  read_sections(root, c);
  // The reference's samples must be independent of every input's.
  if (std::find(c.seeds.begin(), c.seeds.end(), c.reference_seed) != c.seeds.end())
    throw InputError(fmt::format("{}: the reference's seed {} is also an input seed: a reference must not share an input's "
                                 "samples (choose another [reference] seed)",
                                 path, c.reference_seed));
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
  r.seeds = seeds;
  r.reference_spp = reference_spp;
  r.reference_scene_spp = reference_scene_spp;
  r.spp = spp;
  r.plain_spp = plain_spp;
  // The tables are drawn at the first of these: the rendered scenes' spp, then the file scenes'.
  // A config of file scenes only records the first one's size.
  bool rendered = false;
  for (const auto& s : scenes) {
    if (s.frames > 0) {
      r.sequences[s.name] = s.frames;
      for (int t = 0; t < s.frames; ++t) r.scenes.push_back(sequence_row(s.name, t));
    } else {
      r.scenes.push_back(s.name);
    }
    if (s.renderer)
      r.scene_renderers[s.name] = {s.renderer->renderer, s.renderer->file.empty() ? "scene:" + s.renderer->scene : s.renderer->file};
    rendered = rendered || !s.files;
    if (!s.files) continue;
    r.scene_files[s.name] = {s.files->frame, s.files->reference, s.files->second};
    if (std::find(r.spp.begin(), r.spp.end(), s.files->spp) == r.spp.end()) r.spp.push_back(s.files->spp);
  }
  if (!rendered && !scenes.empty()) std::tie(r.width, r.height) = std::tuple(scenes[0].files->width, scenes[0].files->height);
  r.repeats = repeats;
  r.table2 = table2;
  for (const auto& m : methods) r.methods.push_back({m.name, m.method, m.group, m.params});
  return r;
}

}  // namespace dnb::experiment
