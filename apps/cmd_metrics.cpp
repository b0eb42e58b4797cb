// denoisebench metrics IMAGE.exr REF.exr [--json]: every metric of metrics/metrics.h.
#include <cmath>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "apps/commands.h"
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
  cmd->add_option("REF", o->reference, "reference (EXR with R,G,B)")->required();
  cmd->add_flag("--json", o->json, "print one JSON object (non-finite values, e.g. the psnr of identical images, as null)");
  cmd->callback([&action, o] {
    action = [o] {
      Image a = read_rgb(o->image);  // InputError naming the file and the missing channel
      Image b = read_rgb(o->reference);
      metrics::check_pair(a, b, "'" + o->image + "'", "'" + o->reference + "'");
      nlohmann::json j = nlohmann::json::object();
      for (const auto& m : metrics::all_metrics()) {
        double v = m.compute(a, b).value;
        if (o->json) j[m.name] = std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr);
        else fmt::print("{:<8} {:.9g}\n", m.name, v);
      }
      if (o->json) fmt::print("{}\n", j.dump());
      return 0;
    };
  });
}

}  // namespace dnb::app
