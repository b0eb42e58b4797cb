// The AOV frame: every layer the shared tracer writes for one render (docs/design.md, "AOV
// frame file"), the sub-pixel data of edge pixels (paper 3.1), and the header metadata.
#pragma once

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "core/image.h"

namespace dnb {

// Layer names. A layer of reflection level k is named "refl<k>." + base name, e.g.
// "refl1.direct", "refl1.tint". The colour layer F is stored as the bare R,G,B channels.
namespace layer {
inline constexpr const char* kColor = "color";          // F
inline constexpr const char* kDirect = "direct";        // D
inline constexpr const char* kIndirect = "indirect";    // I
inline constexpr const char* kAlbedo = "albedo";        // T
inline constexpr const char* kReflection = "reflection";// R
inline constexpr const char* kEmission = "emission";    // E
inline constexpr const char* kNormal = "normal";        // world-space shading normal, X/Y/Z
inline constexpr const char* kDepth = "depth";          // distance camera -> first hit, Z
inline constexpr const char* kVariance = "variance";    // variance of the mean of F
inline constexpr const char* kDirectVariance = "direct_variance";
inline constexpr const char* kIndirectVariance = "indirect_variance";
inline constexpr const char* kEdge = "edge";            // 1 for pixels of G, Y
inline constexpr const char* kSamples = "samples";      // finite samples accumulated, Y
inline constexpr const char* kTint = "tint";            // only at reflection levels
// Frames of an animated sequence only (docs/sequences.md): screen-space motion in pixels from
// this frame's pixel centre to where the surface seen there was in the previous frame
// (motion.X to the right, motion.Y down the rows; Cycles' Vector pass's first two components).
inline constexpr const char* kMotion = "motion";
// R split as Cycles splits it (level 0 only): R = gloss_color * (gloss_direct + gloss_indirect)
// + trans_color * (trans_direct + trans_indirect); direct: the light of an emitter (or the sky)
// reached by the glossy or transmitted bounce itself, indirect: the rest; both demodulated by
// the lobe's colour (docs/design.md, "AOV frame file").
inline constexpr const char* kGlossDirect = "gloss_direct";
inline constexpr const char* kGlossIndirect = "gloss_indirect";
inline constexpr const char* kGlossColor = "gloss_color";
inline constexpr const char* kTransDirect = "trans_direct";
inline constexpr const char* kTransIndirect = "trans_indirect";
inline constexpr const char* kTransColor = "trans_color";
// Reflection levels a frame may hold, refl1 .. refl8 (the tracer's bound, tracer/integrator.h).
inline constexpr int kMaxLevels = 8;
// "refl<k>.<base>" for reflection level k >= 1; level 0 returns base itself.
std::string at_level(int level, const std::string& base);
// Half buffers: the level-0 layers below over half of the samples only: half 0 the
// even samples 0, 2, 4, ..., half 1 the odd ones. Those are the tracer's even and odd sample
// groups (tracer/render.cpp's top: eight independently scrambled groups, sample s in group s mod 8),
// so each half is stratified on its own and the two halves are independent estimates of the pixel
// (NFOR's and any cross-validating filter's input).
// Named "half<h>.<base>": half0.color.R/G/B, half1.normal.X/Y/Z, half0.depth.Z, ... (the
// layers with `halves` in table() below: color, direct, indirect, albedo, normal, depth).
std::string at_half(int half, const std::string& base);

// Every layer a frame can hold and where it may be: the one list that the tracer's frame
// (tracer/render.cpp), the plug-in manifests' check (methods/plugins.cpp), the importer's
// mappings (interop/mapping.cpp) and docs/design.md's channel table (a test compares) follow.
// Adding a layer is one entry here.
struct Info {
  const char* name;  // the base name
  int channels;      // 3 (R/G/B or X/Y/Z), 2 (motion.X/Y) or 1 (Y or Z)
  bool level0;       // the frame's own layer "<name>"
  bool levels;       // at every reflection level k >= 1: "refl<k>.<name>"
  bool halves;       // in both half buffers: "half<h>.<name>"
  bool importable;   // an import mapping may fill it from another renderer's passes
  bool sequence_only = false;  // written only in the frames of an animated sequence (motion)
};
const std::vector<Info>& table();
// The entry of a full layer name ("depth", "refl2.direct", "half1.color") when a frame can hold
// a layer of that name, else null.
const Info* find(const std::string& name);
// "color, direct, ..., refl<k>.<name> (k 1..8: ...), half<h>.<name> (...)" for messages.
std::string names_help();
}  // namespace layer

// EXR channel names of a layer with the given channel count, in channel order:
// color -> R,G,B; normal -> normal.X/Y/Z; depth -> depth.Z; edge/samples -> edge.Y;
// motion -> motion.X/Y;
// any other 3-channel layer -> name.R/G/B; any other 1-channel layer -> name.Y.
std::vector<std::string> channel_names(const std::string& layer, int channels);
// The channel count a layer of this name has in a frame (layer::table(): 1 for depth, edge and
// samples); 3 for a name the table does not know.
int default_channels(const std::string& layer);

struct FrameMeta {
  std::string scene;             // scene name or file
  int spp = 0;                   // samples per pixel
  std::uint64_t seed = 0;
  std::string tracer_version;
  std::string build_version;     // denoisebench version and git revision
  double render_seconds = 0.0;
  std::int64_t dropped_samples = 0;  // samples that produced NaN/Inf and were dropped
  int reflection_levels = 0;
  std::map<std::string, std::string> extra;  // anything else, kept through a round trip
};

// Sub-pixel data of one edge pixel: 4x4 strata, each the mean over that stratum's samples.
struct EdgeSample {
  float normal[3] = {0, 0, 0};
  float depth = 0;
  float albedo[3] = {0, 0, 0};
  float direct[3] = {0, 0, 0};
  float indirect[3] = {0, 0, 0};
  bool operator==(const EdgeSample&) const = default;
};

struct EdgeSubpixels {
  static constexpr int kPerSide = 4;
  static constexpr int kPerPixel = kPerSide * kPerSide;
  std::vector<std::int32_t> pixels;  // y * width + x, ascending
  std::vector<EdgeSample> samples;   // kPerPixel per entry of `pixels`, sub-pixel row-major
  std::size_t size() const { return pixels.size(); }
  const EdgeSample* of(std::size_t i) const { return samples.data() + i * kPerPixel; }
  bool operator==(const EdgeSubpixels&) const = default;
};

class AovFrame {
 public:
  AovFrame() = default;
  AovFrame(int width, int height) : width_(width), height_(height) {}

  int width() const { return width_; }
  int height() const { return height_; }

  FrameMeta meta;
  std::optional<EdgeSubpixels> edges;

  bool has(const std::string& name) const { return layers_.count(name) != 0; }
  // Throws InputError naming the layer's EXR channels when it is absent.
  const Image& layer(const std::string& name) const;
  Image& layer(const std::string& name);
  // Adds (or replaces with) a zero layer of the frame's size.
  Image& add(const std::string& name, int channels);
  void set(const std::string& name, Image image);
  const std::map<std::string, Image>& layers() const { return layers_; }
  // Names of the EXR channels missing for the given layers (empty when all present).
  std::vector<std::string> missing_channels(const std::vector<std::string>& names) const;

 private:
  int width_ = 0;
  int height_ = 0;
  std::map<std::string, Image> layers_;
};

}  // namespace dnb
