// Sub-commands of the denoisebench program. Each lives in its own cmd_*.cpp and only parses
// arguments and calls the libraries (docs/design.md, "Where code lives": apps hold no algorithms).
#pragma once

#include <functional>
#include <memory>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

namespace dnb::app {

// The work of the chosen sub-command, set by its parse callback; returns the exit status.
using Action = std::function<int()>;

void add_render(CLI::App& app, Action& action);
void add_reference(CLI::App& app, Action& action);
void add_denoise(CLI::App& app, Action& action);
void add_metrics(CLI::App& app, Action& action);
void add_import(CLI::App& app, Action& action);
void add_run(CLI::App& app, Action& action);
void add_report(CLI::App& app, Action& action);
void add_list(CLI::App& app, Action& action);
void add_nightly(CLI::App& app, Action& action);
void add_export_mitsuba(CLI::App& app, Action& action);
void add_export_gltf(CLI::App& app, Action& action);

// --plugins DIR (repeatable) on the commands that name methods: plug-in folders searched before
// $DENOISEBENCH_PLUGINS and the repository's plugins/ (methods/plugins.h). The folders are read
// when the command runs (load_plugins), not at parse time.
std::shared_ptr<std::vector<std::string>> add_plugins_option(CLI::App* cmd);

// A sub-command whose issue has not landed: it parses anything, says it is not available and
// exits 2. No fake output.
void add_unavailable(CLI::App& app, Action& action, const std::string& name, const std::string& what);

}  // namespace dnb::app
