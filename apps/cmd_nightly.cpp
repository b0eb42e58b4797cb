// denoisebench nightly check|accept|tolerances: the nightly gates (experiment/nightly.h), as
// .ci/nightly runs them.
//
//   denoisebench nightly check RUN_DIR [--baseline DIR] [--history FILE]   exit 1 on a regression
//   denoisebench nightly accept RUN_DIR [--baseline DIR]                   the deliberate update
//   denoisebench nightly tolerances --quality RUN_DIR... --perf BENCH.json... [--baseline DIR]
#include <filesystem>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "apps/commands.h"
#include "experiment/nightly.h"
#include "methods/plugins.h"

namespace dnb::app {

namespace {

void add_check(CLI::App& parent, Action& action) {
  auto* cmd = parent.add_subcommand("check", "Compare a nightly run with the baseline; exit 1 on a regression");
  struct Opts {
    std::string run, baseline = "reports/baseline", history, revision;
    bool require_perf = false, no_perf = false, no_ahead = false;
  };
  auto o = std::make_shared<Opts>();
  cmd->add_option("RUN_DIR", o->run, "folder with results.json (denoisebench run) and bench.json (denoisebench_bench)")
      ->required();
  cmd->add_option("--baseline", o->baseline, "folder with baseline.json and gates.json")->capture_default_str();
  cmd->add_option("--history", o->history, "CSV to append this run's row to (none when not given)");
  cmd->add_option("--revision", o->revision, "git revision to record (default: the one in results.json)");
  cmd->add_flag("--require-performance", o->require_perf,
                "a baseline measured on another CPU model is an error instead of a skipped gate");
  cmd->add_flag("--no-performance", o->no_perf, "check quality only");
  cmd->add_flag("--no-ahead", o->no_ahead, "skip the ahead gate (for smoke runs at sizes where it means nothing)");
  cmd->callback([&action, o] {
    action = [o] {
      nightly::CheckOptions opt;
      opt.require_performance = o->require_perf;
      opt.performance = !o->no_perf;
      opt.ahead = !o->no_ahead;
      const auto r = nightly::check_run(o->run, o->baseline, o->history, opt, o->revision);
      for (const auto& n : r.verdict.notes) spdlog::warn("{}", n);
      for (const auto& f : r.verdict.findings)
        if (f.failed) spdlog::error("REGRESSION {}", f.message);
      const int checks = int(r.verdict.findings.size());
      if (r.verdict.passed()) {
        spdlog::info("nightly check PASSED: {} comparisons{}; {}/verdict.md", checks,
                     r.verdict.performance_checked ? "" : " (performance not checked)", o->run);
        return 0;
      }
      spdlog::error("nightly check FAILED: {} of {} comparisons; {}/verdict.md", r.verdict.failures(), checks, o->run);
      return 1;
    };
  });
}

void add_accept(CLI::App& parent, Action& action) {
  auto* cmd = parent.add_subcommand("accept", "Make a run the new baseline (deliberately; never done by check)");
  struct Opts {
    std::string run, baseline = "reports/baseline", revision;
  };
  auto o = std::make_shared<Opts>();
  cmd->add_option("RUN_DIR", o->run, "folder with results.json and bench.json")->required();
  cmd->add_option("--baseline", o->baseline, "baseline folder to write baseline.json into")->capture_default_str();
  cmd->add_option("--revision", o->revision, "git revision to record (default: the one in results.json)");
  cmd->callback([&action, o] {
    action = [o] {
      const auto s = nightly::accept_run(o->run, o->baseline, o->revision);
      // Say now what every later check would say: a baseline whose own run fails the ahead gate.
      for (const auto& f : nightly::self_check(s, o->baseline))
        spdlog::warn("the accepted run fails a gate by itself (every check will, until it is fixed): {}", f.message);
      spdlog::info("accepted {} as the baseline in {}/baseline.json: {} MSE entries, {} benchmark ratios, revision {}, {}",
                   o->run, o->baseline, s.quality.size(), s.performance.size(), s.git_revision, s.machine);
      return 0;
    };
  });
}

void add_tolerances(CLI::App& parent, Action& action) {
  auto* cmd = parent.add_subcommand(
      "tolerances", "Derive the gates' tolerances from repeated runs (seeds for quality, benchmark runs for speed)");
  struct Opts {
    std::vector<std::string> quality, perf;
    std::string baseline = "reports/baseline";
    nightly::DeriveOptions d;
  };
  auto o = std::make_shared<Opts>();
  cmd->add_option("--quality", o->quality, "results folders of one config run with different seeds");
  cmd->add_option("--perf", o->perf, "bench.json files of repeated nightly benchmark runs");
  cmd->add_option("--baseline", o->baseline, "folder whose gates.json is updated (ahead rule kept)")->capture_default_str();
  cmd->add_option("--quality-k", o->d.quality_k, "tolerance = max(k * relative std, floor)")->capture_default_str();
  cmd->add_option("--quality-floor", o->d.quality_floor)->capture_default_str();
  cmd->add_option("--perf-k", o->d.performance_k)->capture_default_str();
  cmd->add_option("--perf-floor", o->d.performance_floor)->capture_default_str();
  cmd->callback([&action, o] {
    action = [o] {
      const auto g = nightly::derive_tolerances(o->quality, o->perf, o->baseline, o->d);
      for (const auto& [m, t] : g.quality) spdlog::info("quality tolerance {}: +{:.1f}%", m, 100 * t);
      for (const auto& [c, t] : g.performance) spdlog::info("performance tolerance {}: +{:.1f}%", c, 100 * t);
      spdlog::info("wrote {}/gates.json", o->baseline);
      return 0;
    };
  });
}

}  // namespace

void add_nightly(CLI::App& app, Action& action) {
  auto* cmd = app.add_subcommand("nightly", "The nightly quality and performance gates (see .ci/nightly)");
  cmd->require_subcommand(1, 1);
  // Before the sub-command: `nightly --plugins DIR check RUN_DIR`. The plug-ins are registered
  // before the sub-command's work, so that it sees them as methods.
  auto plugins = add_plugins_option(cmd);
  add_check(*cmd, action);
  add_accept(*cmd, action);
  add_tolerances(*cmd, action);
  cmd->callback([&action, plugins] {  // runs after the sub-command's own callback has set `action`
    action = [inner = action, plugins] {
      load_plugins(*plugins);
      return inner ? inner() : 2;
    };
  });
}

}  // namespace dnb::app
