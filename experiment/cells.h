// One cell pipeline for every kind of cell of an experiment (plain path tracing, the input
// frame, a method or variant; plug-in and imported-frame cells are new plans, not new code
// paths). A CellPlan says what the cell is and how to compute its image; run_cell() does what
// every cell does:
//
//   key      the SHA-256 of the plan's identity (everything that determines the result)
//   reuse    a finished record with that key whose files (and the plan's required ones) are
//            still there: listed again, done
//   compute  the plan's compute(): the image and its times
//   write    the image as EXR under images/<scene>/<stem>.exr; an input cell also keeps the
//            AOV frame file its scene's cells read under frames/<scene>/<stem>.exr (keep_file:
//            a hard link, else a copy), so that the folder re-scores alone
//   score    every metric against the scene's reference, and the error maps the report shows
//   fail     (method cells) a compute() that throws: a FailedCell, and the run goes on
//   store    the record into results.json / results.csv / finished_cells.json (ResultsStore)
//   progress one more cell done
#pragma once

#include <functional>
#include <map>
#include <optional>
#include <string>
#include <variant>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/image.h"
#include "core/progress.h"
#include "experiment/results.h"
#include "experiment/store.h"
#include "tracer/reference.h"

namespace dnb::experiment {

// What every cell of one scene shares: the scene's identity, size and reference.
struct SceneCells {
  std::string scene;        // the name the config gives
  std::string scene_hash;   // scene_content_hash; a file scene's: its files' contents
  std::string image_dir;    // images/<scene>, relative to the results folder
  std::string frame_dir;    // frames/<scene>: the input frames, relative to the results folder
  int width = 0, height = 0;
  std::optional<std::uint64_t> seed;  // the inputs' seed (none for a scene read from files)
  const Reference* reference = nullptr;
  ReferenceInfo reference_info;  // as every record of the scene carries it
};

// What a plan's compute() returns.
struct CellOutput {
  Image image;
  CellMeasurement measured;  // becomes the record's (times.reference is filled in by store_cell)
  // Input cells: the AOV frame file the scene's cells read (its edge file beside it, if any),
  // kept in the folder as files.frame (and files.frame_edges).
  std::string frame_file;
  // Method cells: the colour of the input frame the method ran on, for metrics::worse_blocks.
  std::optional<Image> baseline;
};

struct CellPlan {
  Role role = Role::Method;
  std::string method;           // the column name ("input", "path_tracing", a method name)
  int spp = 0;
  nlohmann::json identity;      // hashed into the cell key
  std::string stem;             // file name stem of the cell's images, e.g. "proposed_256"
  std::string base_method;                                   // method cells
  std::optional<MethodKind> kind;
  std::optional<std::map<std::string, std::string>> params;  // method cells: validated values
  std::function<CellOutput()> compute;
  // Method cells: a compute() that throws (a plug-in that crashed, a method that failed on this
  // frame) fails this cell only: it is recorded as a FailedCell and the run goes on.
  bool contain_failures = false;
  // files[] names a finished record must have to be reused (besides every file it names existing):
  // an input record of an older build, without its frame, is computed again to keep the frame.
  std::vector<std::string> required_files = {"image"};
  // The inputs' seed of this cell, when the run has several (else the scene's).
  std::optional<std::uint64_t> seed;
  // A cell of the config that cannot exist here (a renderer-type method on a scene read from
  // files): recorded as skipped with this reason, never computed.
  std::optional<std::string> skip_reason;
};

// What computing a plan came to: its output, or the failure or skip it is recorded as.
using ComputedCell = std::variant<CellOutput, FailedCell, SkippedCell>;

// Where every cell goes.
struct CellContext {
  std::string out_dir;  // the results folder
  ResultsStore* store = nullptr;
  Progress* progress = nullptr;
};

// Records a cell of the config that cannot run here as skipped (results.json "skipped", with
// its reason; logged), and counts it done.
void skip_cell(const CellContext& c, SkippedCell skip);

// The cell key of a plan: the SHA-256 of its identity.
std::string cell_key(const CellPlan& plan);
// A finished record of `key` that has the plan's required files and whose every file is still
// in the folder, or nullptr.
const CellRecord* reusable(const std::string& key, const CellPlan& plan, const CellContext& c);
// The compute step: the plan's compute(), with a contained failure (contain_failures) or a
// method unavailable here caught and returned as what it is recorded as. Other errors propagate.
ComputedCell compute_cell(const CellPlan& plan, const std::string& scene_name, const std::string& key);
// The write, score and store steps of a computed cell; returns its record, or nullopt for a
// failed or skipped one.
std::optional<CellRecord> store_cell(const CellPlan& plan, const SceneCells& scene, const CellContext& context,
                                     const std::string& key, ComputedCell computed);

// Runs one plan through the steps above (reuse, else compute and store); returns its record
// (reused or new), or nullopt when the cell failed or was skipped.
std::optional<CellRecord> run_cell(const CellPlan& plan, const SceneCells& scene, const CellContext& context);

// The spool of a distributed run (experiment/execute_mpi.cpp): a rank that computes a cell writes
// what it computed into the results folder's .spool/ (its image, and a method cell's baseline,
// as EXR; the rest as JSON, written last, so that an entry is complete when its JSON exists);
// rank 0 stores it with store_cell and removes it. A rank that dies loses only the cell it was
// computing: the next run finds the others in the spool.
std::string spool_dir(const std::string& out_dir);
void write_spooled(const std::string& out_dir, const std::string& key, const ComputedCell& computed);
bool is_spooled(const std::string& out_dir, const std::string& key);
// The entry of `key`, or nullopt when there is none. InputError naming the file when it is damaged.
std::optional<ComputedCell> read_spooled(const std::string& out_dir, const std::string& key);
void remove_spooled(const std::string& out_dir, const std::string& key);

// Scores `image` against the reference with every metric and writes the error maps the report
// shows (flip, relmse) beside the image, with `attributes` in their headers; their paths go into
// `files`.
std::map<std::string, std::optional<double>> score_image(
    const Image& image, const Reference& reference, const std::string& out_dir, const std::string& stem,
    std::map<std::string, std::string>& files, const std::vector<std::pair<std::string, std::string>>& attributes = {});

// Keeps `frame_file` (and its edge file, when it has one) in the results folder `out_dir` as
// `rel` (keep_file), naming them in files["frame"] (and files["frame_edges"]); an edge file left
// at the destination by another frame is removed.
void keep_frame(const std::string& frame_file, const std::string& out_dir, const std::string& rel,
                std::map<std::string, std::string>& files);

}  // namespace dnb::experiment
