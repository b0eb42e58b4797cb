// Frames from other renderers: a mapping from a foreign EXR's channels to the harness's layers
// (docs/design.md, "AOV frame file"), the presets written in that form (configs/import/: Blender
// Cycles, pbrt-v4's GBufferFilm, Mitsuba 3's aov integrator), and the import itself.
// docs/importing.md describes each format, what it leaves out and which methods run on it.
//
// A mapping file (TOML):
//   [import]
//   name = "mine"                 description = "..."
//   prefix = "auto"               # text before every pass name; "auto": the one before `color`'s
//                                 # first pass (Cycles' view layer, whatever the user named it)
//   detect = ["Combined"]         # passes that mark this format for --input-format auto
//   detect_attribute = ["generatedBy", "Mitsuba"]   # or a header attribute's name and value prefix
//   spp_attributes = ["cycles.{view_layer}.samples"] # header attributes that hold the spp
//   optional = ["direct", ...]    # layers that may be absent (every other mapped layer is required)
//   ignore = ["Combined.A"]       # passes known and deliberately not used (not listed as unmapped)
//   [layers]
//   direct = "DiffDir"            # one pass: its channels DiffDir.R/G/B (or .X/Y/Z, or DiffDirr...)
//   reflection = { terms = ["GlossDir * GlossCol"], optional_terms = ["TransDir * TransCol"] }
//   [[layers.depth]]              # alternatives, the first whose passes are all present is used
//   terms = ["Denoising Depth"]
//   [[layers.depth]]
//   terms = ["Depth"]
//   miss_above = 1e9              # values above are misses: the harness stores 0 there
// A source's keys: terms (strings "A * B": products of passes, summed), optional_terms (added
// when all their passes are present), channels (whole channel names instead of passes), transform
// ("length": a 3-channel pass's Euclidean norm, e.g. depth from a camera-space position), scale,
// divide_by_spp (a per-sample variance made the variance of the mean), miss_above, space (normals:
// "world" or "camera"), note (recorded in the frame's metadata). Unknown keys are errors.
#pragma once

#include <map>
#include <optional>
#include <string>
#include <vector>

#include "core/aov_frame.h"

namespace dnb::interop {

// What is done to a source's channels: nothing, or a 3-channel pass's Euclidean norm.
enum class SourceTransform { None, Length };
const char* to_string(SourceTransform t);  // "none", "length"
// The space a normal pass is in: the harness's (world) or the camera's (rotated into world).
enum class NormalSpace { World, Camera };
const char* to_string(NormalSpace s);  // "world", "camera"

struct LayerSource {
  std::vector<std::vector<std::string>> terms;           // each term: a product of passes
  std::vector<std::vector<std::string>> optional_terms;  // added when every pass of the term is present
  std::vector<std::string> channels;                     // explicit channel names (no prefix added)
  SourceTransform transform = SourceTransform::None;
  double scale = 1.0;
  bool divide_by_spp = false;
  std::optional<double> miss_above;
  std::optional<NormalSpace> space;  // normals only; unset: as the preset says nothing
  std::string note;
  std::string where;  // "file:line: key 'layers.depth[1]'" for messages
};

struct LayerMapping {
  std::string layer;  // a harness layer name (core/aov_frame.h)
  bool required = true;
  std::vector<LayerSource> sources;  // alternatives, in order
  std::string where;
};

struct ImportMapping {
  std::string name, description;
  std::string source;  // the mapping file, or "preset 'cycles'"
  std::string prefix;  // "auto" or literal text
  std::vector<std::string> detect;
  std::vector<std::string> detect_attribute;  // {} or {name, value prefix}
  std::vector<std::string> spp_attributes;
  std::vector<std::string> ignore;
  std::vector<LayerMapping> layers;
};

// The layers a mapping may fill (what docs/design.md's frame contract names, reflection levels aside).
const std::vector<std::string>& mappable_layers();

// A mapping file; InputError naming the file, line and key for an unknown key or layer, a bad
// type or value, a layer with no source.
ImportMapping load_mapping(const std::string& path);
ImportMapping parse_mapping(const std::string& text, const std::string& source_name);
// The shipped presets by name (configs/import/NAME.toml, compiled into the program).
std::vector<std::string> preset_names();
ImportMapping preset(const std::string& name);  // InputError listing the presets when unknown
// "cycles", "pbrt", "mitsuba" (presets) or "map:FILE.toml"; InputError naming what is accepted.
ImportMapping mapping_for(const std::string& format);

struct ImportOptions {
  int spp = 0;         // > 0: the frame's sample count (over any the file records)
  std::string prefix = {};  // non-empty: instead of the mapping's (e.g. a Cycles view layer "Layer2.")
  // read_frame_as, native frames: when given, only these layers are kept (read_frame's `only`).
  std::optional<std::vector<std::string>> layers = std::nullopt;
};

struct ImportReport {
  std::string format = {};   // the mapping's name
  std::string prefix = {};   // the prefix used
  std::vector<std::pair<std::string, std::string>> kept = {};      // layer -> what it was made from
  std::vector<std::pair<std::string, std::string>> left_out = {};  // layer -> why
  std::vector<std::string> unmapped = {};  // channels of the file that no layer used (nor `ignore` names)
  int spp = 0;                        // 0: unknown
  std::string spp_source = {};             // "--spp", the attribute's name, or "unknown"
  // Relative RMS of (D + I) * T + R + E against the colour layer, when the frame has every term
  // of the split: how exactly the mapped passes add up to the file's own image.
  std::optional<double> composition_rel_rms = {};
  std::vector<std::string> warnings = {};
};

struct Imported {
  AovFrame frame;
  ImportReport report;
};

// Reads `path` (an OpenEXR file) through the mapping. InputError naming the file, the layer, the
// mapping's key and the channels looked for when a required layer cannot be made; naming the
// prefixes found when "auto" finds several (pass ImportOptions::prefix to choose).
Imported import_frame(const std::string& path, const ImportMapping& mapping, const ImportOptions& options = {});

// Two renders of one view with different seeds (`import --second`), each read through the
// mapping, as one frame: every layer their mean, half0.* and half1.* the two files' layers (those
// the tracer's frames have halves of), and the variances of the means the files do not carry from
// the two: variance, direct_variance and indirect_variance = (a - b)^2 / 4, one degree of freedom
// per value (a file's own variance layers become the sum of the two over 4). spp the sum. So the
// methods that need half buffers or variances (nfor, svgf, kpcn) run on the frame. InputError
// naming the files when their sizes or layers differ, when either already has half buffers, or
// when their colours are identical (the same seed twice).
Imported import_frame_pair(const std::string& first, const std::string& second, const ImportMapping& mapping,
                           const ImportOptions& options = {});
// The same from two frames already read (`first`'s report is extended).
Imported combine_halves(Imported first, Imported second, const std::string& first_path, const std::string& second_path);

// --input-format: "native" (the harness's own layout), "auto", a preset or "map:FILE.toml".
// "auto" reads a frame the harness wrote (denoisebench: attributes) natively, then tries each
// preset's detect rules in order, and reads anything else natively.
struct DetectedFormat {
  std::string format;  // "native" or a preset's name
  std::string reason;  // why, for the log
};
DetectedFormat detect_format(const std::string& path);

// A frame from `path` in any accepted format. `required` as for read_frame (native frames are
// read with it; an imported frame is checked against it after the import). `report`, when given,
// receives the import's report (its format is "native" for a native frame).
AovFrame read_frame_as(const std::string& path, const std::string& format, const ImportOptions& options = {},
                       const std::vector<std::string>& required = {}, ImportReport* report = nullptr);

// The accepted values of --input-format, for help texts.
std::string input_format_help();

}  // namespace dnb::interop
