// denoisebench metrics IMAGE... --ref REF [--metric M]... [--csv FILE] [--error-maps DIR]
//                      [--fail-above M=V]... [--fail-below M=V]... [--layer PREFIX] [--json]
// and the two-argument form `metrics IMAGE REF`: metrics/scoring.h scores, this prints.
#include <cmath>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "apps/commands.h"
#include "core/errors.h"
#include "interop/import.h"
#include "metrics/metrics.h"
#include "metrics/scoring.h"

namespace dnb::app {

void add_metrics(CLI::App& app, Action& action) {
  auto* cmd = app.add_subcommand(
      "metrics", "Score images against a reference (EXR by channel name, other renderers' frames, sRGB PNG/JPEG): "
                 "one row per image, CSV, error maps, thresholds for CI gates");
  struct Opts {
    std::vector<std::string> files, metrics, fail_above, fail_below;
    std::string reference, csv, error_maps;
    metrics::ReadOptions image_read, reference_read;
    bool json = false, linear_on_8bit = false;
  };
  auto o = std::make_shared<Opts>();
  cmd->add_option("IMAGE", o->files,
                  "images to score (EXR, PNG, JPEG); without --ref the last one is the reference (metrics IMAGE REF)")
      ->required();
  cmd->add_option("--ref", o->reference,
                  "the reference (with variance.R/G/B, as `denoisebench reference` writes it, mse_converged is scored too)");
  cmd->add_option("--metric", o->metrics, "a metric to score (repeatable; default: every one the inputs allow)");
  cmd->add_option("--csv", o->csv, "append one row per image to this CSV (a header line when the file is new)");
  cmd->add_option("--error-maps", o->error_maps, "write each metric's per-pixel map here: IMAGE.METRIC.exr and a false-colour .png with its scale");
  cmd->add_option("--fail-above", o->fail_above, "METRIC=VALUE: exit 1 when an image scores above it (repeatable)");
  cmd->add_option("--fail-below", o->fail_below, "METRIC=VALUE: exit 1 when an image scores below it (psnr, ssim)");
  cmd->add_option("--layer", o->image_read.layer, "read the images' PREFIX.R/G/B channels (e.g. ViewLayer.Combined, denoised)");
  cmd->add_option("--ref-layer", o->reference_read.layer, "read the reference's PREFIX.R/G/B channels");
  cmd->add_option("--input-format", o->image_read.input_format, "EXR images' format (their colour is scored): " + interop::input_format_help());
  cmd->add_option("--ref-format", o->reference_read.input_format, "the reference's format (same choices)");
  cmd->add_flag("--linear-metrics-on-8bit", o->linear_on_8bit,
                "score mse_hdr and relmse on 8-bit inputs too (they then measure display values clipped to [0, 1])");
  cmd->add_flag("--json", o->json, "print one JSON object per image, one per line (non-finite values as null)");
  cmd->callback([&action, o] {
    action = [o] {
      metrics::ScoreRequest q;
      q.images = o->files;
      q.reference = o->reference;
      if (q.reference.empty()) {
        if (q.images.size() != 2)
          throw InputError(fmt::format("metrics: {} file{} given and no --ref: expected IMAGE REF, or IMAGE... --ref REF",
                                       q.images.size(), q.images.size() == 1 ? "" : "s"));
        q.reference = q.images.back();
        q.images.pop_back();
      }
      q.metrics = o->metrics;
      q.image_read = o->image_read;
      q.reference_read = o->reference_read;
      q.linear_metrics_on_8bit = o->linear_on_8bit;
      q.error_maps_dir = o->error_maps;
      std::vector<metrics::Threshold> thresholds;  // parsed before any scoring: a typo costs no work
      for (const auto& t : o->fail_above) thresholds.push_back(metrics::parse_threshold(t, true));
      for (const auto& t : o->fail_below) thresholds.push_back(metrics::parse_threshold(t, false));
      const metrics::ScoreOutcome out = metrics::score(q);
      const auto failed = metrics::failed_thresholds(out, thresholds);
      if (!o->csv.empty()) metrics::append_csv(o->csv, q.reference, out);
      for (const auto& n : out.notes) fmt::print(stderr, "note: {}\n", n);
      for (const auto& row : out.rows) {
        if (o->json) {
          nlohmann::json j = nlohmann::json::object();
          j["image"] = row.image;
          j["reference"] = q.reference;
          for (const auto& [name, v] : row.values) j[name] = std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr);
          if (out.reference_has_variance) {
            j["reference_unconverged_share"] = out.reference_unconverged_share;
            j["reference_estimated_error"] = metrics::reference_error_by_metric(out.reference_error);
          }
          if (!row.maps.empty()) j["error_maps"] = row.maps;
          for (const auto& [name, p] : row.pooled)
            j[name + "_pooled"] = {{"mean", p.mean},           {"weighted_median", p.weighted_median},
                                   {"weighted_first_quartile", p.weighted_first_quartile},
                                   {"weighted_third_quartile", p.weighted_third_quartile},
                                   {"min", p.min},             {"max", p.max}};
          if (out.hdrflip_exposures)
            j["hdrflip_exposures"] = {{"start", out.hdrflip_exposures->start},
                                      {"stop", out.hdrflip_exposures->stop},
                                      {"count", out.hdrflip_exposures->count}};
          fmt::print("{}\n", j.dump());
          continue;
        }
        if (out.rows.size() > 1) fmt::print("{}\n", row.image);
        for (const auto& [name, v] : row.values) {
          if (metrics::metric(name).needs_reference_variance && !out.reference_has_variance)
            fmt::print("{:<14} n/a ('{}' has no variance.R/G/B channels)\n", name, q.reference);
          else fmt::print("{:<14} {:.9g}\n", name, v);
          if (auto p = row.pooled.find(name); p != row.pooled.end())
            fmt::print("{:<14} weighted median {:.6g}, quartiles {:.6g} .. {:.6g}, min {:.6g}, max {:.6g}\n", "", p->second.weighted_median,
                       p->second.weighted_first_quartile, p->second.weighted_third_quartile, p->second.min, p->second.max);
          if (name == "hdrflip" && out.hdrflip_exposures)
            fmt::print("{:<14} exposures {:.4g} .. {:.4g} stops, {} of them (from the reference)\n", "",
                       out.hdrflip_exposures->start, out.hdrflip_exposures->stop, out.hdrflip_exposures->count);
        }
      }
      for (const auto& f : failed) fmt::print(stderr, "threshold failed: {}\n", f);
      return failed.empty() ? 0 : 1;
    };
  });
}

}  // namespace dnb::app
