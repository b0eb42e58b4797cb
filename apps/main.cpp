// denoisebench: the command-line program (docs/design.md, "Command line"). Exit status: 0 success,
// 1 failure of the work, 2 bad usage or bad input.
#include <cstdlib>
#include <exception>

#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

#include "apps/commands.h"
#include "core/errors.h"
#include "core/build_info.h"
#include "interop/renderers.h"
#include "methods/plugins.h"

int main(int argc, char** argv) {
  CLI::App app{std::string("denoisebench ") + dnb::build_version() +
               ": renders Monte Carlo AOV frames, runs denoisers, scores them against references"};
  app.set_version_flag("--version", dnb::build_version_and_revision());
  app.require_subcommand(1, 1);
  std::string log_level = "info";
  app.add_option("--log-level", log_level, "trace, debug, info, warn, error or off")
      ->check(CLI::IsMember({"trace", "debug", "info", "warn", "error", "off"}));
  dnb::app::Action action;
  dnb::app::add_render(app, action);
  dnb::app::add_reference(app, action);
  dnb::app::add_denoise(app, action);
  dnb::app::add_metrics(app, action);
  dnb::app::add_import(app, action);
  dnb::app::add_run(app, action);
  dnb::app::add_report(app, action);
  dnb::app::add_list(app, action);
  dnb::app::add_nightly(app, action);
  dnb::app::add_export_mitsuba(app, action);
  dnb::app::add_export_gltf(app, action);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    int code = app.exit(e);
    return code == 0 ? 0 : 2;
  }
  // The log goes to stderr: stdout is the commands' output (--json is parsed by scripts).
  spdlog::set_default_logger(spdlog::stderr_color_mt("denoisebench"));
  spdlog::set_level(spdlog::level::from_str(log_level));
  spdlog::set_pattern("[%H:%M:%S] %^%l%$ %v");
  int status = 2;
  try {
    status = action ? action() : 2;
  } catch (const dnb::InputError& e) {
    spdlog::error("{}", e.what());
    status = 2;
  } catch (const std::exception& e) {
    spdlog::error("{}", e.what());
    status = 1;
  }
  dnb::shutdown_plugin_workers();  // worker plug-ins end while the log still runs
  dnb::interop::shutdown_renderer_workers();  // and renderer back-ends' workers
  return status;
}
