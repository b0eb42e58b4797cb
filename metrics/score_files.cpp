#include "metrics/metrics.h"
#include "metrics/scoring.h"

namespace dnb::metrics {

FileScores score_files(const std::string& image_path, const std::string& reference_path) {
  ScoreRequest q;
  q.images = {image_path};
  q.reference = reference_path;
  q.metrics = metric_names();  // every metric: an 8-bit file given here is refused, not silently half-scored
  const ScoreOutcome o = score(q);
  FileScores s;
  s.values = o.rows.front().values;
  s.has_variance = o.reference_has_variance;
  s.unconverged_share = o.reference_unconverged_share;
  return s;
}

}  // namespace dnb::metrics
