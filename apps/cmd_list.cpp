// denoisebench list methods|scenes|metrics: what can be named on the command line and in
// configs, with every method parameter's type, default, accepted values and description.
#include <fmt/format.h>

#include "apps/commands.h"
#include "core/errors.h"
#include "denoisers/method.h"
#include "methods/plugins.h"
#include "metrics/metrics.h"
#include "tracer/scene_loader.h"

namespace dnb::app {

static int list_methods() {
  for (const MethodInfo* m : MethodRegistry::global().all()) {
    // "temporal": it keeps history over a sequence's frames (docs/sequences.md).
    const std::string kind = std::string(to_string(m->kind)) + (m->temporal ? ", temporal" : "");
    if (m->origin.empty()) fmt::print("{}  ({})\n    {}\n", m->name, kind, m->description);
    else fmt::print("{}  ({}, plug-in: {})\n    {}\n", m->name, kind, m->origin, m->description);
    try {
      auto instance = MethodRegistry::global().create(m->name);
      auto layers = instance->required_layers();
      fmt::print("    layers: {}\n", layers.empty() ? std::string("none") : fmt::format("{}", fmt::join(layers, ", ")));
      if (const auto optional = instance->optional_layers(); !optional.empty())
        fmt::print("    optional layers: {}\n", fmt::join(optional, ", "));
    } catch (const std::exception& e) {
      fmt::print("    layers: (cannot create with defaults: {})\n", e.what());
    }
    if (m->params.empty()) fmt::print("    (no parameters)\n");
    for (const ParamSpec& p : m->params)
      fmt::print("    {:<18} {:<7} default {:<10} {}; {}\n", p.name, to_string(p.type), p.default_value, p.doc,
                 p.expected());
    fmt::print("\n");
  }
  return 0;
}

static int list_scenes() {
  for (const auto& name : builtin_scene_names()) fmt::print("{}\n", name);
  return 0;
}

static int list_metrics() {
  for (const auto& m : metrics::all_metrics())
    fmt::print("{:<8} {:<16} {}\n", m.name, m.lower_is_better ? "lower is better" : "higher is better", m.description);
  return 0;
}

void add_list(CLI::App& app, Action& action) {
  auto* cmd = app.add_subcommand("list", "List methods (with parameters), scenes or metrics");
  auto what = std::make_shared<std::string>();
  cmd->add_option("WHAT", *what, "methods, scenes or metrics")
      ->required()
      ->check(CLI::IsMember({"methods", "scenes", "metrics"}));
  auto plugins = add_plugins_option(cmd);
  cmd->callback([&action, what, plugins] {
    action = [what, plugins] {
      if (*what == "methods") {
        load_plugins(*plugins);
        return list_methods();
      }
      if (*what == "scenes") return list_scenes();
      return list_metrics();
    };
  });
}

}  // namespace dnb::app
