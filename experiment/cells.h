// One cell pipeline for every kind of cell of an experiment (plain path tracing, the input
// frame, a method or variant; plug-in and imported-frame cells are new plans, not new code
// paths). A CellPlan says what the cell is and how to compute its image; run_cell() does what
// every cell does:
//
//   key      the SHA-256 of the plan's identity (everything that determines the result)
//   reuse    a finished record with that key whose image is still there: listed again, done
//   compute  the plan's compute(): the image and its times
//   write    the image as EXR under images/<scene>/<stem>.exr
//   score    every metric against the scene's reference, and the error maps the report shows
//   fail     (method cells) a compute() that throws: a FailedCell, and the run goes on
//   store    the record into results.json / results.csv / finished_cells.json (ResultsStore)
//   progress one more cell done
#pragma once

#include <functional>
#include <map>
#include <optional>
#include <string>

#include <nlohmann/json.hpp>

#include "core/image.h"
#include "core/progress.h"
#include "experiment/results.h"
#include "experiment/store.h"
#include "tracer/reference.h"

namespace dnb::experiment {

// What every cell of one scene shares: the scene's identity and its reference.
struct SceneCells {
  std::string scene;        // the name the config gives
  std::string scene_hash;   // scene_content_hash
  std::string image_dir;    // images/<scene>, relative to the results folder
  const Reference* reference = nullptr;
  ReferenceInfo reference_info;  // as every record of the scene carries it
};

// What a plan's compute() returns.
struct CellOutput {
  Image image;
  CellTimes times;  // times.reference is filled in by run_cell
  std::optional<bool> input_cache_hit;
  std::optional<std::map<std::string, double>> phases, counters;
};

struct CellPlan {
  Role role = Role::Method;
  std::string method;           // the column name ("input", "path_tracing", a method name)
  int spp = 0;
  nlohmann::json identity;      // hashed into the cell key
  std::string stem;             // file name stem of the cell's images, e.g. "proposed_256"
  std::string base_method, kind;                          // method cells
  std::optional<std::map<std::string, std::string>> params;  // method cells: validated values
  std::function<CellOutput()> compute;
  // Method cells: a compute() that throws (a plug-in that crashed, a method that failed on this
  // frame) fails this cell only: it is recorded as a FailedCell and the run goes on.
  bool contain_failures = false;
};

// The settings every record repeats (from the config).
struct CellContext {
  std::string out_dir;  // the results folder
  int width = 0, height = 0;
  std::uint64_t seed = 0;
  ResultsStore* store = nullptr;
  Progress* progress = nullptr;
};

// Runs one plan through the steps above; returns its record (reused or new), or nullopt when the
// cell failed and was recorded as failed (contain_failures).
std::optional<CellRecord> run_cell(const CellPlan& plan, const SceneCells& scene, const CellContext& context);

// Scores `image` against the reference with every metric and writes the error maps the report
// shows (flip, relmse) beside the image; their paths go into `files`.
std::map<std::string, std::optional<double>> score_image(const Image& image, const Reference& reference,
                                                         const std::string& out_dir, const std::string& stem,
                                                         std::map<std::string, std::string>& files);

// `s` with every character other than letters, digits, '-', '_' and '.' replaced by '_'.
std::string safe_file_name(const std::string& s);

}  // namespace dnb::experiment
