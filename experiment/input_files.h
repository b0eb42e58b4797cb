// Frames and references that an experiment config names by file instead of rendering them
// ([[scene]] frame = "...", reference = "...": experiment/config.h), read in one place.
//
//   AovFrame frame = read_input_frame("frames/in.exr");
//   Reference ref = file_reference("frames/ref.exr");
#pragma once

#include <string>

#include "core/aov_frame.h"
#include "tracer/reference.h"

namespace dnb::experiment {

// THE hook where the experiment reads an input frame (or a reference) from a file a config
// names: the config check, the input cells and the method cells all read through it. `format` is
// interop/import.h's --input-format (`input_format` in the config: "auto" reads the harness's own
// frames natively and recognises Cycles, pbrt-v4 and Mitsuba 3 files; a preset; map:FILE.toml);
// `spp` > 0 is the frame's sample count over any the file records. InputError naming the file.
// `second`, when given, is a render of the same view with another seed, read the same way: the
// two are one frame with half buffers and variances (interop::combine_halves, `import --second`).
AovFrame read_input_frame(const std::string& path, const std::string& format = "auto", int spp = 0,
                          const std::string& second = "");

// What the cells of a file scene are keyed by (core/hash.h): the SHA-256 of the frame's bytes,
// and of its edge file's bytes when it has one (edges_path), so that editing either reruns them.
std::string frame_file_hash(const std::string& path);

// A reference read from a file through read_input_frame: R,G,B, the variance of the mean when
// the file has variance.R/G/B (empty otherwise: mse_converged is then n/a), metadata, and `path`.
Reference file_reference(const std::string& path, const std::string& format = "auto");

}  // namespace dnb::experiment
