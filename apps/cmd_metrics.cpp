#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "apps/commands.h"
#include "core/errors.h"
#include "core/exr_io.h"
#include "metrics/metrics.h"

namespace dnb::app {

void add_metrics(CLI::App& app, Action& action) {
  auto* cmd = app.add_subcommand("metrics", "Score IMAGE.exr against REF.exr (R,G,B channels, equal sizes)");
  struct Opts {
    std::string image, reference;
    bool json = false;
  };
  auto o = std::make_shared<Opts>();
  cmd->add_option("IMAGE", o->image, "image to score (EXR with R,G,B)")->required();
  cmd->add_option("REF", o->reference, "reference (EXR with R,G,B)")->required();
  cmd->add_flag("--json", o->json, "print JSON instead of text");
  cmd->callback([&action, o] {
    action = [o] {
      Image a = read_rgb(o->image);
      Image b = read_rgb(o->reference);
      if (a.width() != b.width() || a.height() != b.height())
        throw InputError(fmt::format("'{}' is {}x{} but '{}' is {}x{}: sizes must match", o->image, a.width(),
                                     a.height(), o->reference, b.width(), b.height()));
      double v = metrics::mse_hdr(a, b);
      if (o->json) fmt::print("{}\n", nlohmann::json{{"mse_hdr", v}}.dump());
      else fmt::print("mse_hdr {:.9g}\n", v);
      return 0;
    };
  });
}

}  // namespace dnb::app
