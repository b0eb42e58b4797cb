// denoisebench report RESULTS_DIR: tables, plots and index.html from results.json
// (experiment/report.h).
#include "apps/commands.h"
#include "experiment/report.h"

namespace dnb::app {

void add_report(CLI::App& app, Action& action) {
  auto* cmd = app.add_subcommand("report", "Write tables, plots and the HTML report of a results folder");
  struct Opts {
    std::string dir, ranking_against;
    bool no_plots = false, no_images = false;
  };
  auto o = std::make_shared<Opts>();
  cmd->add_option("RESULTS_DIR", o->dir, "folder written by `denoisebench run`")->required();
  cmd->add_flag("--no-plots", o->no_plots, "skip the matplotlib plots");
  cmd->add_flag("--no-images", o->no_images, "skip the PNG images, crops and error maps");
  cmd->add_option("--ranking-against", o->ranking_against,
                  "another results folder (e.g. the evaluation scenes' run): a `ranking` table with Kendall's tau between "
                  "the two runs' method rankings (configs/generalisation.toml)");
  cmd->callback([&action, o] {
    action = [o] {
      experiment::write_report(o->dir, {!o->no_plots, !o->no_images, o->ranking_against});
      return 0;
    };
  });
}

}  // namespace dnb::app
