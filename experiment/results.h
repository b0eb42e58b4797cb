// The results document: the one schema of results.json (docs/design.md, "Results"), written by the
// runner (`denoisebench run`), read by the report (`denoisebench report`) and by the nightly
// gates (`denoisebench nightly`). Nothing else in the harness spells its keys.
//
//   {
//     "format": "denoisebench-results", "schema_version": 4,
//     "config":  {...},           what was run (RunConfig below)
//     "machine": {...},           hostname, cpu, hardware_threads, ranks (the MPI ranks the run
//                                 was spread over, 1 for one process; absent in older files)
//     "build":   {...},           version, git revision, compiler, build id (provenance)
//     "git_revision": "...", "written": <unix time>,
//     "records": [ CellRecord, ... ]   one per cell: scene x method x input spp, the input
//                                      itself, and the plain path-tracing curve
//     "failures": [ FailedCell, ... ]  cells of this run that failed (a plug-in that crashed,
//                                      timed out or wrote a bad image): no record, a reason
//     "skipped": [ SkippedCell, ... ]  cells that cannot exist (a renderer-type method on a
//                                      scene read from files): no record, a reason, not a failure
//   }
//
// A CellRecord's keys (absent keys are optional ones that the cell's role does not have):
//   scene, scene_hash, method (the column name), role (plain | input | method | ablation),
//   spp, width, height, seed, cell_key (the hash of everything that determines the cell),
//   metrics {name: value | null for a non-finite value}, times {input_render, filter, total,
//   reference[, filter_runs, setup_seconds]}, reference {spp, seed, seconds, cache_hit, image,
//   unconverged_share, unconverged_rse[, estimated_error {mse, mse_hdr, relmse}]}, files {image, error_flip, error_relmse; input cells
//   also frame and, when the frame has one, frame_edges}, input_cache_hit; method cells also
//   base_method, kind, params, phases, counters[, method_info {string: string}: what the method
//   reported about itself, e.g. a plug-in's library version]. reference.image is the reference file itself
//   (R,G,B, variance.*, metadata); files.frame is the AOV frame file every cell of that scene
//   and spp read, byte for byte (frame_edges its edge file): with them the folder re-scores
//   alone. Records of a scene read from files ([[scene]] frame = ...) have no seed.
//
// Reading is strict: a file of another format, of a schema_version outside
// kOldestResultsSchemaVersion..kResultsSchemaVersion, or with a missing or mistyped key is an
// InputError naming the file and the key (the record's index too). What each version holds, so
// that older files are read right: 1 (format "denoisebench-results-1", no schema_version: not
// read); 2 (the schema named and versioned); 3 (failures; times.setup_seconds of
// worker plug-ins); 4 (files.frame and files.frame_edges of input cells, reference.image with
// its variance layers and metadata, config.scene_files, skipped). Version 2 and 3 files are
// read as version 4 without what they lack.
#pragma once

#include <cstdint>
#include <ctime>
#include <array>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "denoisers/method_kind.h"

namespace dnb::experiment {

inline constexpr const char* kResultsFormat = "denoisebench-results";
inline constexpr int kResultsSchemaVersion = 4;
inline constexpr int kOldestResultsSchemaVersion = 2;  // still read

// What a record is a measurement of.
enum class Role {
  Plain,     // plain path tracing at some spp (the speed-up curve)
  Input,     // the unfiltered input frame, the baseline every method improves on
  Method,    // a method (or a config variant without a group) on the input frame
  Ablation,  // a [[variant]] with group = "ablation": one part of a method switched off
};
const char* to_string(Role r);                                  // "plain", "input", ...
Role role_from_string(const std::string& s, const std::string& where);  // InputError otherwise
// The role of a configured method: "" -> Method, "ablation" -> Ablation; else an InputError.
Role role_of_group(const std::string& group, const std::string& where);
// Method and Ablation: the roles whose records are method results (tables' columns, gates).
inline bool is_method_role(Role r) { return r == Role::Method || r == Role::Ablation; }

// Table 2's columns: which method is "the filter" on the CPU and on OpenCL ("" when none).
struct Table2Columns {
  std::string filter_cpu = "proposed";
  std::string filter_opencl = "";
  std::string irradiance_cache = "irradiance_cache";
};

struct MethodEntry {  // a configured method or variant, as recorded
  std::string name, method, group;
  std::map<std::string, std::string> params;
};

// A scene read from files instead of rendered, as recorded: the files the config named (absolute).
struct SceneFilesEntry {
  std::string frame, reference;
  std::string second;  // a second seed's render (`second`), or ""
  bool operator==(const SceneFilesEntry&) const = default;
};

// A scene rendered by a renderer back-end, as recorded: the back-end's name and the scene file.
struct SceneRendererEntry {
  std::string renderer, file;
  bool operator==(const SceneRendererEntry&) const = default;
};

// The config as the results record it (experiment/config.h is the config file itself).
struct RunConfig {
  std::string path, name;
  int width = 0, height = 0;
  std::uint64_t seed = 0;
  std::vector<std::uint64_t> seeds;  // the inputs' seeds (several: Table 1 gives intervals); [seed] when one
  int reference_spp = 0;
  std::map<std::string, int> reference_scene_spp;  // [reference.scene.NAME] spp: the scenes that differ
  std::vector<int> spp, plain_spp;
  std::vector<std::string> scenes;  // every scene's name, config order (file scenes by label)
  std::map<std::string, SceneFilesEntry> scene_files;  // the scenes read from files, by name
  std::map<std::string, SceneRendererEntry> scene_renderers;  // the scenes a back-end renders, by name
  // Animated scenes run as sequences (docs/sequences.md): name -> frames. Their frames are rows
  // of `scenes` named sequence_row(name, t) ("name.f03").
  std::map<std::string, int> sequences;
  int repeats = 0;
  Table2Columns table2;
  std::vector<MethodEntry> methods;
};

// A plain-curve cell's origin: the image is the first prefix_spp samples of one progressive render
// of rendered_spp samples per pixel (the curve's largest point; experiment/frame_sources.h), so the
// whole curve cost that one render. results.json "curve": {"rendered_spp", "prefix_spp"}.
struct CurveOrigin {
  int rendered_spp = 0, prefix_spp = 0;
  bool operator==(const CurveOrigin&) const = default;
};

struct CellTimes {
  double input_render = 0, filter = 0, total = 0;
  std::optional<double> reference;            // absent only in hand-written files
  std::optional<std::vector<double>> filter_runs;  // method cells: every timed run
  std::optional<double> setup;  // worker plug-ins: the worker's start-up, paid once per run ("setup_seconds")
};
// A record's "times" object, and back (strict: an InputError naming `where` and the key); also
// what a distributed run's spool keeps of a cell's times (cells.h).
nlohmann::json times_to_json(const CellTimes& times);
CellTimes times_from_json(const nlohmann::json& times, const std::string& where);
// A plain cell's "curve" object, and back (strict, as times_from_json).
nlohmann::json curve_to_json(const CurveOrigin& curve);
CurveOrigin curve_from_json(const nlohmann::json& curve, const std::string& where);

struct ReferenceInfo {
  int spp = 0;
  std::optional<std::uint64_t> seed;
  double seconds = 0;
  std::optional<bool> cache_hit;
  std::string image;                       // relative to the results folder
  std::optional<double> unconverged_share;  // null when the reference has no variance layers
  std::optional<double> unconverged_rse;
  // The reference's own expected error, what a perfect image would score against it
  // (metrics::reference_error: mse, mse_hdr, relmse); absent without variance layers.
  std::optional<std::map<std::string, double>> estimated_error;
};

// What computing a cell measured: the part of a record that the cell's compute() returns (the
// rest is the cell's identity and its scores). One struct, with one field list, fields(), that
// drives its keys in a record's JSON and in a distributed run's spool (experiment/cells.h):
// adding a field is its member and its line in fields().
struct CellMeasurement {
  CellTimes times;                    // times.reference is the scene's, filled in when stored
  std::optional<bool> input_cache_hit;
  std::optional<CurveOrigin> curve;   // plain-curve cells
  std::optional<std::map<std::string, double>> phases, counters;  // method cells
  std::optional<std::map<std::string, std::string>> method_info;  // what the method reported (MethodStats::info)

  // f(key, member) for every field, in the order they are written; `self` is a (const) CellMeasurement.
  template <class Self, class F>
  static void fields(Self& self, F&& f) {
    f("times", self.times);
    f("input_cache_hit", self.input_cache_hit);
    f("curve", self.curve);
    f("phases", self.phases);
    f("counters", self.counters);
    f("method_info", self.method_info);
  }
  // Adds its keys to `object` (an optional field that is unset is absent).
  void write_json(nlohmann::json& object) const;
  // Its keys of `object`, strictly (an InputError naming `where` and the key).
  static CellMeasurement read_json(const nlohmann::json& object, const std::string& where);
};

// A record: the cell's identity, what was measured (its CellMeasurement) and the scores.
struct CellRecord : CellMeasurement {
  std::string scene, scene_hash, method;
  Role role = Role::Method;
  int spp = 0, width = 0, height = 0;
  std::optional<std::uint64_t> seed;
  std::string cell_key;
  std::map<std::string, std::optional<double>> metrics;  // nullopt: non-finite (null in JSON)
  ReferenceInfo reference;
  std::map<std::string, std::string> files;  // image, error_<metric> (the maps a run keeps): relative paths
  // Method and ablation cells.
  std::string base_method;
  std::optional<MethodKind> kind;
  std::optional<std::map<std::string, std::string>> params;
  // Method cells: metrics::worse_blocks against the input frame ("block", "count", "worse",
  // "worse_twice": shares of tiles whose 8-bit mse is above the input's, and above twice it).
  std::optional<std::map<std::string, double>> blocks;
  // Method cells: the tiles where the method is worse than its input, worst first
  // (metrics::WorseBlocks::tiles: x, y, w, h in pixels, then mse / input's mse); for the viewer.
  std::vector<std::array<double, 5>> worse_tiles;

  // The metric's value, or nullopt when it is absent or non-finite.
  std::optional<double> metric(const std::string& name) const;
  std::string file(const std::string& name) const;  // files[name], or ""
  std::string image() const { return file("image"); }

  nlohmann::json to_json() const;
  static CellRecord from_json(const nlohmann::json& j, const std::string& where);
};

// A cell of the run that failed: the run went on without it and exits 1 naming it. Failed cells
// are not finished: the next run into the folder tries them again.
struct FailedCell {
  std::string scene, method;
  int spp = 0;
  std::string cell_key, reason;
  std::vector<std::string> log_tail;  // the last lines the method (a plug-in) printed on stderr

  nlohmann::json to_json() const;
  static FailedCell from_json(const nlohmann::json& j, const std::string& where);
};

// A cell of the config that cannot be computed on its scene (a renderer-type method, which
// renders the scene itself, on a scene read from files): listed with the reason, not a failure.
struct SkippedCell {
  std::string scene, method;
  int spp = 0;
  std::string reason;

  nlohmann::json to_json() const;
  static SkippedCell from_json(const nlohmann::json& j, const std::string& where);
};

// One method's scores over a whole sequence at one spp and seed (docs/temporal-metrics.md),
// computed by the run from the frames' images once every frame is done (experiment/sequences.h's
// score_sequence): the still metrics' means over the frames, tmse and disocclusion_mse, and the
// per-frame values the report plots.
struct SequenceRecord {
  std::string sequence, method;  // the sequence's name (rows sequence_row(sequence, t)), the column
  Role role = Role::Method;
  int spp = 0, frames = 0;
  std::optional<std::uint64_t> seed;
  std::map<std::string, std::optional<double>> metrics;  // mean over frames of each still metric, tmse, disocclusion_mse
  // Per frame, index t: mse, tmse, disocclusion_mse (null where a frame has none: frame 0's tmse).
  std::map<std::string, std::vector<std::optional<double>>> per_frame;
  std::vector<std::string> images;  // each frame's image, relative to the results folder (for the video)

  std::optional<double> metric(const std::string& name) const;
  nlohmann::json to_json() const;
  static SequenceRecord from_json(const nlohmann::json& j, const std::string& where);
};

struct ResultsDocument {
  RunConfig config;
  nlohmann::json machine = nlohmann::json::object();  // provenance, kept as written
  nlohmann::json build = nlohmann::json::object();
  std::string git_revision;
  std::optional<std::int64_t> written;
  std::vector<CellRecord> records;
  std::vector<FailedCell> failures;
  std::vector<SkippedCell> skipped;
  std::vector<SequenceRecord> sequences;  // runs with animated scenes (config.sequences)

  // Queries the tables and gates are written in.
  std::vector<std::string> scenes() const;  // the config's, else in record order
  int table_spp() const;                    // the input spp the tables are drawn for: the first
  std::vector<std::string> methods(Role role) const;  // names in record order
  const CellRecord* find(const std::string& scene, const std::string& method, int spp) const;
  // Every seed's record of the cell, in seed order of the records (one per input seed).
  std::vector<const CellRecord*> find_all(const std::string& scene, const std::string& method, int spp) const;
  const FailedCell* failure(const std::string& scene, const std::string& method, int spp) const;
  const SkippedCell* skip(const std::string& scene, const std::string& method, int spp) const;

  nlohmann::json to_json() const;
  static ResultsDocument from_json(const nlohmann::json& j, const std::string& where);
  // Reads `path`: InputError naming it when missing, not JSON, or not of this schema.
  static ResultsDocument load(const std::string& path);
};

}  // namespace dnb::experiment
