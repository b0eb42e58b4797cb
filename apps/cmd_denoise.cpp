// denoisebench denoise METHOD FRAME.exr -o OUT.exr [--set key=value ...] [--threads T] [--json]
//                      [--scene SCENE]
// Creates the method by name (its parameters validated first, so a typo costs no frame read),
// reads only the layers it needs, runs it through run_method and writes R,G,B atomically.
// A renderer-type method (irradiance_cache) renders the frame's scene itself: the scene is the
// one the frame's metadata names (or --scene), at the frame's size, seed and spp budget.
#include <memory>

#include <fmt/format.h>
#include <nlohmann/json.hpp>
#include <tbb/global_control.h>

#include "apps/commands.h"
#include "core/errors.h"
#include "core/exr_io.h"
#include "core/version.h"
#include "denoisers/method.h"
#include "tracer/render.h"
#include "tracer/scene_loader.h"

namespace dnb::app {

void add_denoise(CLI::App& app, Action& action) {
  auto* cmd = app.add_subcommand("denoise", "Run a method on an AOV frame and write the result as an RGB EXR");
  struct Opts {
    std::string method, frame, output, scene;
    std::vector<std::string> settings;
    int threads = 0;
    bool json = false;
  };
  auto o = std::make_shared<Opts>();
  cmd->add_option("METHOD", o->method, "method name (see: denoisebench list methods)")->required();
  cmd->add_option("FRAME", o->frame, "AOV frame (EXR written by denoisebench render)")->required();
  cmd->add_option("-o,--output", o->output, "output EXR (R,G,B), written atomically")->required();
  cmd->add_option("--set", o->settings, "method parameter as key=value (repeatable)");
  cmd->add_option("--threads", o->threads, "worker threads (0: all cores; the image does not depend on it)")
      ->check(CLI::Range(0, 1024));
  cmd->add_option("--scene", o->scene,
                  "renderer-type methods: scene to render (default: the scene named in the frame's metadata)");
  cmd->add_flag("--json", o->json, "print the statistics as JSON instead of text");
  cmd->callback([&action, o] {
    action = [o] {
      const MethodRegistry& registry = MethodRegistry::global();
      const auto settings = parse_settings(o->settings);
      std::unique_ptr<Method> method = registry.create(o->method, settings);
      const Params params = registry.parse_params(o->method, settings);
      std::unique_ptr<tbb::global_control> limit;
      if (o->threads > 0)
        limit = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, o->threads);

      AovFrame frame = read_frame(o->frame, method->required_layers());
      MethodInput input{.frame = &frame, .seed = frame.meta.seed};
      std::shared_ptr<const Scene> scene;
      if (registry.info(o->method).kind == MethodKind::Renderer) {
        const std::string name = o->scene.empty() ? frame.meta.scene : o->scene;
        if (name.empty())
          throw InputError(fmt::format("'{}' names no scene in its metadata: give --scene for method '{}'", o->frame,
                                       o->method));
        scene = load_scene(name);
        input.scene = scene.get();
        input.sample_budget = frame.meta.spp;
        input.width = frame.width();
        input.height = frame.height();
      }
      MethodResult r;
      try {
        r = run_method(*method, input);
      } catch (const InputError& e) {
        throw InputError(fmt::format("'{}': {}", o->frame, e.what()));
      }
      std::vector<std::pair<std::string, std::string>> attrs = {
          {"method", o->method}, {"source_frame", o->frame}, {"build_version", DNB_VERSION " (" DNB_GIT_REVISION ")"}};
      for (const auto& [k, v] : params.as_strings()) attrs.emplace_back("param." + k, v);
      write_rgb(r.image, o->output, attrs);

      if (o->json) {
        nlohmann::json j;
        j["method"] = o->method;
        j["frame"] = o->frame;
        j["output"] = o->output;
        j["params"] = params.as_strings();
        j["total_seconds"] = r.stats.total_seconds;
        j["phases"] = nlohmann::json::array();
        for (const auto& [name, s] : r.stats.phases) j["phases"].push_back({{"name", name}, {"seconds", s}});
        j["counters"] = r.stats.counters;
        fmt::print("{}\n", j.dump(2));
      } else {
        fmt::print("method {} on '{}' ({}x{}) -> '{}'\n", o->method, o->frame, frame.width(), frame.height(), o->output);
        for (const auto& [k, v] : params.as_strings()) fmt::print("  param    {:<20} {}\n", k, v);
        fmt::print("  total    {:<20} {:.6f} s\n", "execute", r.stats.total_seconds);
        for (const auto& [name, s] : r.stats.phases) fmt::print("  phase    {:<20} {:.6f} s\n", name, s);
        for (const auto& [name, v] : r.stats.counters) fmt::print("  counter  {:<20} {:.9g}\n", name, v);
      }
      return 0;
    };
  });
}

}  // namespace dnb::app
