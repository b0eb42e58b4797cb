// denoisebench report RESULTS_DIR: tables, plots and index.html from results.json
// (experiment/report.h).
#include "apps/commands.h"
#include "experiment/report.h"

namespace dnb::app {

void add_report(CLI::App& app, Action& action) {
  auto* cmd = app.add_subcommand("report", "Write tables, plots and the HTML report of a results folder");
  struct Opts {
    std::string dir;
    bool no_plots = false, no_images = false;
  };
  auto o = std::make_shared<Opts>();
  cmd->add_option("RESULTS_DIR", o->dir, "folder written by `denoisebench run`")->required();
  cmd->add_flag("--no-plots", o->no_plots, "skip the matplotlib plots");
  cmd->add_flag("--no-images", o->no_images, "skip the PNG images, crops and error maps");
  cmd->callback([&action, o] {
    action = [o] {
      experiment::write_report(o->dir, {!o->no_plots, !o->no_images});
      return 0;
    };
  });
}

}  // namespace dnb::app
