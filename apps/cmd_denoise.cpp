// denoisebench denoise METHOD FRAME.exr -o OUT.exr [--set key=value ...] [--threads T] [--json]
//                      [--scene SCENE]
// Creates the method by name (its parameters validated first, so a typo costs no frame read),
// reads only the layers it needs, runs it through run_method and writes R,G,B atomically.
// A renderer-type method (irradiance_cache) renders the frame's scene itself: the scene is the
// one the frame's metadata names (or --scene), at the frame's size, seed and spp budget.
#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "apps/args.h"
#include "apps/commands.h"
#include "interop/import.h"
#include "methods/denoise.h"
#include "methods/plugins.h"

namespace dnb::app {

void add_denoise(CLI::App& app, Action& action) {
  auto* cmd = app.add_subcommand("denoise", "Run a method on an AOV frame and write the result as an RGB EXR");
  struct Opts {
    DenoiseRequest request;
    std::vector<std::string> settings;
    bool json = false;
  };
  auto o = std::make_shared<Opts>();
  cmd->add_option("METHOD", o->request.method, "method name (see: denoisebench list methods)")->required();
  cmd->add_option("FRAME", o->request.frame, "AOV frame (EXR written by denoisebench render, or another renderer's: --input-format)")->required();
  cmd->add_option("-o,--output", o->request.output, "output EXR (R,G,B), written atomically")->required();
  cmd->add_option("--set", o->settings, "method parameter as key=value (repeatable)");
  add_threads_option(*cmd, o->request.threads, "worker threads (0: all cores; the image does not depend on it)");
  cmd->add_option("--scene", o->request.scene,
                  "renderer-type methods: scene to render (default: the scene named in the frame's metadata)");
  cmd->add_option("--input-format", o->request.input_format, "FRAME's format: " + interop::input_format_help());
  cmd->add_flag("--json", o->json, "print the statistics as JSON instead of text");
  auto plugins = add_plugins_option(cmd);
  cmd->callback([&action, o, plugins] {
    action = [o, plugins] {
      load_plugins(*plugins);
      DenoiseRequest q = o->request;
      q.settings = parse_settings(o->settings);
      const DenoiseOutcome d = denoise_file(q);
      const MethodResult& r = d.result;
      const Params& params = d.params;
      if (o->json) {
        nlohmann::json j;
        j["method"] = q.method;
        j["frame"] = q.frame;
        j["output"] = q.output;
        j["params"] = params.as_strings();
        j["total_seconds"] = r.stats.total_seconds;
        if (r.stats.setup_seconds) j["setup_seconds"] = *r.stats.setup_seconds;
        j["phases"] = nlohmann::json::array();
        for (const auto& [name, s] : r.stats.phases) j["phases"].push_back({{"name", name}, {"seconds", s}});
        j["counters"] = r.stats.counters;
        fmt::print("{}\n", j.dump(2));
      } else {
        fmt::print("method {} on '{}' ({}x{}) -> '{}'\n", q.method, q.frame, d.width, d.height, q.output);
        for (const auto& [k, v] : params.as_strings()) fmt::print("  param    {:<20} {}\n", k, v);
        fmt::print("  total    {:<20} {:.6f} s\n", "execute", r.stats.total_seconds);
        if (r.stats.setup_seconds) fmt::print("  setup    {:<20} {:.6f} s\n", "worker start-up", *r.stats.setup_seconds);
        for (const auto& [name, s] : r.stats.phases) fmt::print("  phase    {:<20} {:.6f} s\n", name, s);
        for (const auto& [name, v] : r.stats.counters) fmt::print("  counter  {:<20} {:.9g}\n", name, v);
      }
      return 0;
    };
  });
}

}  // namespace dnb::app
