#include <fmt/format.h>

#include "core/aov_frame.h"
#include "core/errors.h"
#include "core/exr_io.h"
#include "metrics/metrics.h"

namespace dnb::metrics {

FileScores score_files(const std::string& image_path, const std::string& reference_path) {
  const Image a = read_rgb(image_path);  // InputError naming the file and the missing channel
  // The reference with its variance of the mean when the file has it, in one read.
  const AovFrame ref_frame = read_frame(reference_path, {layer::kColor});
  const Image& b = ref_frame.layer(layer::kColor);
  check_pair(a, b, "'" + image_path + "'", "'" + reference_path + "'");
  FileScores s;
  const Image* variance = ref_frame.has(layer::kVariance) ? &ref_frame.layer(layer::kVariance) : nullptr;
  if (variance) {
    s.has_variance = true;
    try {  // also checks the variance before any metric uses it
      s.unconverged_share = unconverged_share(b, *variance);
    } catch (const InputError& e) {
      throw InputError(fmt::format("'{}': {}", reference_path, e.what()));
    }
  }
  for (const auto& m : all_metrics()) s.values.emplace_back(m.name, m.compute(a, b, variance).value);
  return s;
}

}  // namespace dnb::metrics
