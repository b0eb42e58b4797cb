// The experiment config file behind `denoisebench run CONFIG.toml` (configs/quick.toml is the
// smallest example): scenes, input spp, methods and variants, reference, timing and the
// speed-up curve. Read strictly: unknown keys, unknown methods (listing the registry's),
// unknown method parameters and bad values are InputErrors naming the file and key, before
// any work starts.
//
// Scenes are rendered (`scenes = ["cornell-box", ...]`, or `[[scene]] name = "..."`) or read
// from files (docs/results.md, "Scenes read from files"):
//
//   [[scene]]
//   frame = "frames/in.exr"       # an AOV frame (docs/design.md), relative to the config's folder
//   reference = "frames/ref.exr"  # its reference (R,G,B; variance.* used when present)
//   label = "kitchen"             # optional: the scene's name in the tables (default: the
//                                 # frame's file stem)
//   spp = 64                      # optional: the frame's sample count, for a frame that records
//                                 # none (one that does must agree)
//   input_format = "cycles"       # optional: another renderer's files (interop/import.h; the
//                                 # config's top-level `input_format`, else "auto")
//   second = "frames/in_s2.exr"   # optional: the same view rendered with another seed; the two
//                                 # are the frame's half buffers and give its variances
//                                 # (`import --second`), so nfor, svgf and kpcn run on it
//
// A scene rendered by a renderer back-end (docs/renderers.md) instead of the tracer:
//
//   [[scene]]
//   renderer = "mitsuba"          # a back-end of renderers/ (or of `renderers = ["dir"]`, or
//                                 # $DENOISEBENCH_RENDERERS)
//   file = "scenes/box.xml"       # the back-end's scene file, relative to the config's folder
//   label = "box"                 # optional: the scene's name (default: the file's stem)
//
// It is a rendered scene: width, height, seeds, spp (even: the input is two halves of spp / 2
// samples, two seeds, combined as `import --second` does), [reference] and [speedup] apply.
//
// A file scene has one input (the frame, at its spp), no plain path-tracing curve, and no
// renderer-type cells (they render the scene, which a file does not hold: skipped, with the
// reason in results.json). Both files are read when the config is loaded: a missing file,
// `name` with `frame`, a frame without a reference (or the reverse), and sizes that differ are
// InputErrors naming the key and the file. When every scene is read from files, the keys that
// only set up renders (width, height, seed, max_depth, spp, [reference], [speedup]) are errors.
#pragma once

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "experiment/results.h"

namespace dnb::experiment {

// A method as the config names it: a registry method with parameter overrides. A variant
// ([[variant]] name = "proposed-no-nlm", method = "proposed", set = {...}) is one of these too.
struct MethodSpec {
  std::string name;     // the column name in the tables
  std::string method;   // the registry name
  std::map<std::string, std::string> params;
  std::string group;    // "ablation" for ablation rows, else ""
  Role role() const { return role_of_group(group, name); }  // validated by load_config
};

// A scene read from files ([[scene]] frame = ..., reference = ...), checked at load.
struct SceneFiles {
  std::string frame, reference;  // absolute paths
  std::string frame_hash;        // SHA-256 of the frame's bytes and of its edge file's (if any)
  std::string reference_hash;    // SHA-256 of the reference's bytes
  int width = 0, height = 0;     // of both
  int spp = 0;                   // the frame's sample count
  std::string input_format = "auto";  // how both files are read (interop/import.h; `input_format`)
  std::string second;            // `second`: a render of the frame's view with another seed, or ""
};

// A scene a renderer back-end renders ([[scene]] renderer = "mitsuba", file = "scene.xml";
// interop/renderers.h, docs/renderers.md), checked at load: the back-end exists, the file too.
struct SceneRenderer {
  std::string renderer;   // the back-end's name
  std::string file;       // the scene file, absolute (empty with `scene`)
  std::string file_hash;  // SHA-256 of its bytes (empty with `scene`: known once exported)
  // Or a scene of the tracer (`scene = "cornell-box"`: a built-in name or a scene file), which the
  // run exports as glTF into the render cache (tracer/gltf_export.h) for the back-end to render.
  std::string scene;
};

// A scene of the matrix: a rendered one (a built-in scene or scene file, by the tracer or by a
// renderer back-end), or one read from files.
struct SceneSpec {
  std::string name;                 // the row name: the scene, or a file or back-end scene's label
  std::optional<SceneFiles> files;  // set: read from files, not rendered
  std::optional<SceneRenderer> renderer = std::nullopt;  // set: rendered by this back-end, not the tracer
  // An animated scene run as a sequence (`[[scene]] name = "..." frames = N`, docs/sequences.md):
  // its frames 0 .. frames - 1, each a row sequence_row(name, t) with its own reference. 0: a still.
  int frames = 0;
};

// The row (and folder) name of frame t of sequence `name`: "name.f03" (two digits at least).
std::string sequence_row(const std::string& name, int frame);

struct ExperimentConfig {
  std::string path;
  std::string name;
  int width = 256, height = 192;
  std::uint64_t seed = 1;                  // the first of `seeds` (the plain path-tracing curve's)
  std::vector<std::uint64_t> seeds = {1};  // input seeds: every input and method cell once per seed
  std::uint64_t reference_seed = 1000003;  // independent of the inputs' samples
  std::vector<SceneSpec> scenes;      // `scenes` then every [[scene]], config order
  std::vector<int> spp;               // input spp of the rendered scenes (empty when there are none)
  int reference_spp = 1024;
  // [reference.scene.NAME] spp = N: a scene whose reference needs more (or fewer) samples than
  // the others, such as one whose fireflies would otherwise hold most of every method's error.
  std::map<std::string, int> reference_scene_spp;
  int reference_spp_for(const std::string& scene) const {
    const auto it = reference_scene_spp.find(scene);
    return it == reference_scene_spp.end() ? reference_spp : it->second;
  }
  int reference_block_spp = 64;
  int max_depth = 8;
  std::vector<int> plain_spp;         // plain path tracing curve (speed-up claim)
  std::vector<MethodSpec> methods;    // methods then variants, config order
  int repeats = 3;                    // timing repeats of methods under a second
  double repeat_below_seconds = 1.0;
  int threads = 0;
  Table2Columns table2;               // [table2] filter_cpu, filter_opencl, irradiance_cache
  std::vector<std::string> plugins;   // plug-in folders (`plugins = [...]`, relative to the file)
  std::vector<std::string> renderers; // renderer back-end folders searched first (`renderers = [...]`)

  // The config as results.json records it.
  RunConfig recorded() const;
};

// Also registers the plug-ins the config's `plugins` folders, $DENOISEBENCH_PLUGINS and the
// repository's plugins/ hold (methods/plugins.h), so that its methods can name them.
ExperimentConfig load_config(const std::string& path);

}  // namespace dnb::experiment
