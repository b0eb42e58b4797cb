// The deep OpenEXR file of a frame's edge sub-pixels ("frame.exr" -> "frame.edges.exr", layout
// in core/exr_io.h at edges_path): written and read back before it may be committed, read with
// every pixel's sample count checked. Internal to core/.
#pragma once

#include <memory>
#include <string>

#include "core/aov_frame.h"
#include "core/atomic_file.h"

namespace dnb::exr {

// The edge file written to its temporary file and read back, not yet committed; `digest` gets
// the SHA-256 of its bytes (the frame records it, so that a reader never pairs a frame with
// an edge file of another render).
std::unique_ptr<AtomicOutput> stage_edges(const EdgeSubpixels& e, int width, int height, const std::string& path,
                                          std::string& digest);
// InputError naming `path` when it is not a deep width x height image with the edge channels
// and kPerPixel samples in every pixel that has any.
EdgeSubpixels read_edges(const std::string& path, int width, int height);

}  // namespace dnb::exr
