// denoisebench metrics IMAGE.exr REF.exr [--json]: every metric of metrics/metrics.h.
#include <cmath>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "apps/commands.h"
#include "core/aov_frame.h"
#include "core/errors.h"
#include "core/exr_io.h"
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
      Image a = read_rgb(o->image);  // InputError naming the file and the missing channel
      // The reference with its variance of the mean when the file has it (mse_converged needs
      // it), in one read; a missing R, G or B is an InputError naming the file and the channel.
      const AovFrame ref_frame = read_frame(o->reference, {layer::kColor});
      const Image& b = ref_frame.layer(layer::kColor);
      metrics::check_pair(a, b, "'" + o->image + "'", "'" + o->reference + "'");
      const Image* variance = ref_frame.has(layer::kVariance) ? &ref_frame.layer(layer::kVariance) : nullptr;
      double unconverged = 0;  // also checks the variance before any metric uses it
      if (variance) {
        try {
          unconverged = metrics::unconverged_share(b, *variance);
        } catch (const InputError& e) {
          throw InputError(fmt::format("'{}': {}", o->reference, e.what()));
        }
      }
      nlohmann::json j = nlohmann::json::object();
      for (const auto& m : metrics::all_metrics()) {
        double v = m.compute(a, b, variance).value;
        if (o->json) j[m.name] = std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr);
        else if (m.name == "mse_converged" && !variance)
          fmt::print("{:<14} n/a ('{}' has no variance.R/G/B channels)\n", m.name, o->reference);
        else fmt::print("{:<14} {:.9g}\n", m.name, v);
      }
      if (variance && o->json) j["reference_unconverged_share"] = unconverged;
      if (o->json) fmt::print("{}\n", j.dump());
      return 0;
    };
  });
}

}  // namespace dnb::app
