// denoisebench metrics IMAGE.exr REF.exr [--json]: every metric of metrics/metrics.h.
#include <cmath>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "apps/commands.h"
#include "metrics/metrics.h"

namespace dnb::app {

void add_metrics(CLI::App& app, Action& action) {
  auto* cmd = app.add_subcommand("metrics", "Score IMAGE.exr against REF.exr with every metric (R,G,B channels, equal sizes)");
  struct Opts {
    std::string image, reference;
    bool json = false;
  };
  auto o = std::make_shared<Opts>();
  cmd->add_option("IMAGE", o->image, "image to score (EXR with R,G,B)")->required();
  cmd->add_option("REF", o->reference,
                  "reference (EXR with R,G,B; with variance.R/G/B, as `denoisebench reference` writes it, "
                  "mse_converged is scored too)")
      ->required();
  cmd->add_flag("--json", o->json, "print one JSON object (non-finite values, e.g. the psnr of identical images, as null)");
  cmd->callback([&action, o] {
    action = [o] {
      const metrics::FileScores scores = metrics::score_files(o->image, o->reference);
      nlohmann::json j = nlohmann::json::object();
      for (const auto& [name, v] : scores.values) {
        if (o->json) j[name] = std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr);
        else if (name == "mse_converged" && !scores.has_variance)
          fmt::print("{:<14} n/a ('{}' has no variance.R/G/B channels)\n", name, o->reference);
        else fmt::print("{:<14} {:.9g}\n", name, v);
      }
      if (scores.has_variance && o->json) j["reference_unconverged_share"] = scores.unconverged_share;
      if (o->json) fmt::print("{}\n", j.dump());
      return 0;
    };
  });
}

}  // namespace dnb::app
