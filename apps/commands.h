// Sub-commands of the denoisebench program. Each lives in its own cmd_*.cpp and only parses
// arguments and calls the libraries (DESIGN.md: apps hold no algorithms).
#pragma once

#include <functional>
#include <string>

#include <CLI/CLI.hpp>

namespace dnb::app {

// The work of the chosen sub-command, set by its parse callback; returns the exit status.
using Action = std::function<int()>;

void add_render(CLI::App& app, Action& action);
void add_reference(CLI::App& app, Action& action);
void add_denoise(CLI::App& app, Action& action);
void add_metrics(CLI::App& app, Action& action);
void add_run(CLI::App& app, Action& action);
void add_report(CLI::App& app, Action& action);
void add_list(CLI::App& app, Action& action);
void add_nightly(CLI::App& app, Action& action);

// A sub-command whose issue has not landed: it parses anything, says it is not available and
// exits 2. No fake output.
void add_unavailable(CLI::App& app, Action& action, const std::string& name, const std::string& what);

}  // namespace dnb::app
