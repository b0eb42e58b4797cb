// Reading and writing AOV frames and plain RGB images as OpenEXR through OpenImageIO.
// Channels are always looked up by name (OpenEXR stores them sorted, OIIO reorders them).
// Every write goes to a temporary name and is renamed when complete.
#pragma once

#include <map>
#include <optional>
#include <string>
#include <vector>

#include "core/aov_frame.h"
#include "core/image.h"

namespace dnb {

// The sub-pixel data of a frame's edge pixels lives beside it in a deep OpenEXR file
// ("frame.exr" -> "frame.edges.exr"): 16 samples for each pixel of G, none elsewhere.
// Deep channels: normal.X/Y/Z, Z (sub-pixel depth), albedo.R/G/B, direct.R/G/B,
// indirect.R/G/B; sample s of a pixel is sub-pixel (s % 4, s / 4) of its 4x4 strata.
std::string edges_path(const std::string& frame_path);

// Frames and RGB images are written as OpenEXR only (32-bit float, channels by name, the deep
// edge file): InputError naming `path` as given and the accepted extension otherwise. The
// writers below check it; commands call it before any work, so a typo costs no render.
void require_exr_output(const std::string& path);

struct FrameWriteOptions {
  bool compress = true;  // false: uncompressed (a plug-in's input: read fastest, by any reader)
  bool edges = true;     // false: no edge file even when the frame has edge sub-pixels
  std::vector<std::string> layers = {};  // only these layers (each must exist); empty: every layer
  // false: written straight to `path`, without the temporary name, the fsyncs and the in-memory
  // encode (every call still checked): for scratch files nobody must find half-written after a
  // crash, such as a plug-in's input in the harness's private folder.
  bool durable = true;
};

// Writes every layer, the metadata and (if present) the edge file.
void write_frame(const AovFrame& frame, const std::string& path, const FrameWriteOptions& options = {});

// Reads a frame. `required` lists layer names that must be present; a missing one is an
// InputError naming the file and the missing channels. `only`, when given, lists the layers to
// keep (the others are decoded strip by strip and dropped: a filter that needs 8 of a frame's
// 40 layers holds only those; an empty list keeps none, for a method that needs the size only).
// The edge file is read when the frame's header says it has one; a header that names one which
// is missing is an error.
AovFrame read_frame(const std::string& path, const std::vector<std::string>& required = {},
                    const std::optional<std::vector<std::string>>& only = std::nullopt);
// Writes a 3-channel image as R,G,B (plus optional string attributes).
void write_rgb(const Image& rgb, const std::string& path,
               const std::vector<std::pair<std::string, std::string>>& attributes = {});

// Reads the R,G,B channels of any EXR (by name); InputError naming the file and the
// channel when one is missing.
Image read_rgb(const std::string& path);

// The attributes write_rgb wrote into `path`'s header, by the names it was given (without the
// header's "denoisebench:" prefix), read without the pixels; InputError naming the file when it
// cannot be read.
std::map<std::string, std::string> read_rgb_attributes(const std::string& path);

// Every channel of a flat OpenEXR file, by name, with its header attributes: what an importer of
// another renderer's frames reads (interop/). The parts of a multi-part file are merged (their
// channel names are already distinct in the files Blender, pbrt and Mitsuba write; a repeated
// name is an InputError). Planes are stored one after the other, each width x height floats.
struct ExrChannels {
  int width = 0, height = 0;
  std::vector<std::string> names;                     // in the file's order
  std::map<std::string, std::string> attributes;      // every header attribute, as text
  std::vector<std::vector<float>> planes;             // one per name
  bool has(const std::string& name) const { return index(name) >= 0; }
  int index(const std::string& name) const;           // -1 when absent
  const std::vector<float>& plane(const std::string& name) const;  // InputError naming it when absent
};
// `with_pixels` false: names and attributes only (planes empty), for telling formats apart.
ExrChannels read_exr_channels(const std::string& path, bool with_pixels = true);

}  // namespace dnb
