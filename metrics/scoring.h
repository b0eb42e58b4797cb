// `denoisebench metrics IMAGE... --ref REF`: reading what is scored (EXR by channel name, a
// Cycles/pbrt/Mitsuba frame's colour, or an 8-bit PNG/JPEG decoded from sRGB), scoring many
// images against one reference, error maps, thresholds. The command only parses and prints.
#pragma once

#include <map>
#include <optional>
#include <string>
#include <vector>

#include "core/image.h"
#include "metrics/metrics.h"

namespace dnb::metrics {

struct ReadOptions {
  std::string layer;                  // EXR: read PREFIX.R/G/B (e.g. "ViewLayer.Combined", "denoised")
  std::string input_format = "auto";  // EXR without --layer: interop/import.h's formats; the frame's colour
};

struct ScoredFile {
  std::string path;
  Image rgb;           // linear radiance (or sRGB-decoded display values for an 8-bit file)
  Image variance;      // the reference's variance of the mean, when the file has it; else empty
  bool eight_bit = false;
  std::string note;    // how it was read, when that is worth saying ("8-bit sRGB PNG, decoded to linear")
};

// An EXR by channel name, or a PNG/JPEG (8 or 16 bits per channel, sRGB-encoded unless its header
// says linear: decoded with the sRGB transfer; grey is spread to R, G, B; alpha ignored). Any other
// extension is an InputError naming the file and the accepted ones.
ScoredFile read_scored_file(const std::string& path, const ReadOptions& options = {});

struct ScoreRequest {
  std::vector<std::string> images;
  std::string reference;
  std::vector<std::string> metrics;  // empty: every metric the inputs allow
  ReadOptions image_read, reference_read;
  // An 8-bit input allows only the 8-bit metrics (and flip) unless this is set: the linear ones
  // would score display values clipped to [0, 1].
  bool linear_metrics_on_8bit = false;
  std::string error_maps_dir;  // non-empty: every chosen metric's map as EXR and false-colour PNG
};

struct ImageScore {
  std::string image;
  std::vector<std::pair<std::string, double>> values;  // the chosen metrics in order; NaN: n/a
  std::vector<std::string> maps;                       // files written under error_maps_dir
  std::map<std::string, FlipPooled> pooled;            // flip, hdrflip: FLIP's tool's pooled statistics
};

struct ScoreOutcome {
  std::vector<std::string> metrics;  // chosen, in order
  std::vector<ImageScore> rows;      // one per image, in order
  bool reference_has_variance = false;
  double reference_unconverged_share = 0;
  ReferenceError reference_error;   // the reference's own expected error (when it has variance)
  std::vector<std::string> notes;    // what the user should know (8-bit inputs, metrics left out)
  std::optional<HdrFlipExposures> hdrflip_exposures;  // when hdrflip is scored: the reference's range
};

// InputError (exit 2) for an unknown metric, a linear metric on an 8-bit input without
// linear_metrics_on_8bit, unreadable files, unequal sizes; each naming the file.
ScoreOutcome score(const ScoreRequest& request);

// A threshold "NAME=VALUE" of --fail-above / --fail-below.
struct Threshold {
  std::string metric;
  double value = 0;
  bool above = true;  // fail when the score is above (else below) the value
};
Threshold parse_threshold(const std::string& text, bool above);
// One line per image and threshold that fails: "IMAGE: mse 12.5 is above 10" (a metric that
// could not be scored, n/a, fails too: a gate must not pass on a missing number).
std::vector<std::string> failed_thresholds(const ScoreOutcome& outcome, const std::vector<Threshold>& thresholds);

// Appends one row per image to `path` (image, reference, then the metrics), with a header line
// when the file is new; an existing file whose header differs is an InputError naming both
// headers (rows under the wrong columns would be read as the wrong metric). Written atomically.
void append_csv(const std::string& path, const std::string& reference, const ScoreOutcome& outcome);

// The false-colour display of an error map (FLIP's convention: magma) with a colour bar and its
// scale [lo, hi] written beside it, as an 8-bit BGR image ready for a PNG.
struct FalseColour {
  int width = 0, height = 0;
  std::vector<unsigned char> bgr;
};
FalseColour false_colour_with_bar(const Image& map, double lo, double hi, const std::string& label);
// PNG bytes of `fc`, atomically at `path`.
void write_png(const FalseColour& fc, const std::string& path);

}  // namespace dnb::metrics
