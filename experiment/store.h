// The results folder's record of finished work (docs/design.md, "Results"): results.json and
// results.csv list the cells of this run's config, in the order visited; finished_cells.json
// keeps every cell ever finished in the folder, by cell key, so that a run that stops early
// (killed, or a config listing fewer cells) does not forget the cells it had not reached. All
// three are rewritten atomically after every cell: an interrupted run resumes from them.
// The store holds the folder's lock (DIR/.lock) for its lifetime: a second run into the same
// folder waits for the first, then starts from every cell the first finished, so no finished
// cell is lost to two runs rewriting finished_cells.json at once.
#pragma once

#include <map>
#include <string>

#include "core/atomic_file.h"
#include "experiment/results.h"

namespace dnb::experiment {

inline constexpr const char* kFinishedCellsFormat = "denoisebench-finished-cells";

class ResultsStore {
 public:
  // Takes DIR's lock (waiting, with a warning naming the holder, while another run has it),
  // removes the temporary files of writers that died, then reads finished cells from DIR's
  // finished_cells.json and results.json when they exist (an InputError naming the file when
  // one cannot be resumed from). `header` is this run's document without records.
  ResultsStore(std::string dir, ResultsDocument header);

  // The finished record of `cell_key` (this run's or an earlier one's), or nullptr.
  const CellRecord* finished(const std::string& cell_key) const;
  // A newly computed cell: kept, listed, and every file rewritten.
  void add(CellRecord record);
  // A finished cell of an earlier run, listed again in this run's results (no write).
  void reuse(const CellRecord& record);
  // A cell of this run that failed: listed in results.json's failures, not kept as finished (the
  // next run tries it again); every file rewritten.
  void fail(FailedCell failure);
  // A cell of this run's config that cannot be computed (results.json's skipped); every file rewritten.
  void skip(SkippedCell skipped);
  // A sequence's scores (computed once all its frames are done), replacing any it had; every file rewritten.
  void set_sequence(const std::string& name, std::vector<SequenceRecord> records);
  void write();
  const ResultsDocument& document() const { return doc_; }

 private:
  std::string dir_;
  FolderLock lock_;
  ResultsDocument doc_;
  std::map<std::string, CellRecord> cells_;
};

// results.csv: one row per record, metrics and timings as columns.
std::string results_csv(const ResultsDocument& results);

}  // namespace dnb::experiment
