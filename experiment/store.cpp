#include "experiment/store.h"

#include <filesystem>

#include <spdlog/spdlog.h>

#include "core/atomic_file.h"
#include "core/csv.h"
#include "core/json_file.h"
#include "metrics/metrics.h"

namespace fs = std::filesystem;
using nlohmann::json;

namespace dnb::experiment {

namespace {

// finished_cells.json: {"format", "schema_version", "records": [CellRecord...]}.
std::vector<CellRecord> read_finished_cells(const std::string& path) {
  const json j = json_file::read(path);
  const std::string where = "'" + path + "'";
  const int version = json_file::get_or<int>(j, "schema_version", 0, where);
  if (json_file::get_or<std::string>(j, "format", "", where) != kFinishedCellsFormat ||
      version < kOldestResultsSchemaVersion || version > kResultsSchemaVersion)
    throw InputError(fmt::format("{}: key 'format': expected \"{}\" with schema_version {} to {}", where, kFinishedCellsFormat,
                                 kOldestResultsSchemaVersion, kResultsSchemaVersion));
  const json records = json_file::get<json>(j, "records", where);
  std::vector<CellRecord> out;
  for (std::size_t i = 0; i < records.size(); ++i)
    out.push_back(CellRecord::from_json(records[i], fmt::format("{}: records[{}]", where, i)));
  return out;
}

}  // namespace

ResultsStore::ResultsStore(std::string dir, ResultsDocument header)
    : dir_(std::move(dir)),
      lock_(dir_, [this](const std::string& holder) {
        spdlog::warn("results folder '{}' is in use by {}: waiting for it to finish", dir_, holder);
      }),
      doc_(std::move(header)) {
  doc_.records.clear();
  doc_.failures.clear();
  doc_.skipped.clear();
  if (const std::size_t n = remove_stale_temporaries(dir_))
    spdlog::info("removed {} temporary files of runs that died in '{}'", n, dir_);
  for (const char* name : {"finished_cells.json", "results.json"}) {
    const std::string path = dir_ + "/" + name;
    if (!fs::exists(path)) continue;
    try {
      const auto records = std::string(name) == "results.json" ? ResultsDocument::load(path).records : read_finished_cells(path);
      for (const auto& r : records) cells_[r.cell_key] = r;
    } catch (const std::exception& e) {
      throw InputError(fmt::format("'{}' exists but cannot be resumed from ({}): remove it or choose another -o", path, e.what()));
    }
  }
}

const CellRecord* ResultsStore::finished(const std::string& key) const {
  auto it = cells_.find(key);
  return it == cells_.end() ? nullptr : &it->second;
}

void ResultsStore::add(CellRecord record) {
  cells_[record.cell_key] = record;
  doc_.records.push_back(std::move(record));
  write();
}

void ResultsStore::reuse(const CellRecord& record) { doc_.records.push_back(record); }

void ResultsStore::fail(FailedCell failure) {
  doc_.failures.push_back(std::move(failure));
  write();
}

void ResultsStore::skip(SkippedCell skipped) {
  doc_.skipped.push_back(std::move(skipped));
  write();
}

void ResultsStore::set_sequence(const std::string& name, std::vector<SequenceRecord> records) {
  std::erase_if(doc_.sequences, [&](const SequenceRecord& r) { return r.sequence == name; });
  for (auto& r : records) doc_.sequences.push_back(std::move(r));
  write();
}

void ResultsStore::write() {
  doc_.written = std::int64_t(std::time(nullptr));
  json_file::write(dir_ + "/results.json", doc_.to_json());
  write_text_atomic(dir_ + "/results.csv", results_csv(doc_));
  json cells = {{"format", kFinishedCellsFormat}, {"schema_version", kResultsSchemaVersion}, {"records", json::array()}};
  for (const auto& [key, r] : cells_) cells["records"].push_back(r.to_json());
  json_file::write(dir_ + "/finished_cells.json", cells, 1);
}

std::string results_csv(const ResultsDocument& results) {
  const std::vector<std::string> metric_cols = metrics::metric_names();
  const std::vector<std::string> time_cols = {"input_render", "filter", "total", "reference"};
  std::vector<std::string> header = {"scene", "method", "role", "spp", "width", "height"};
  for (const auto& m : metric_cols) header.push_back(m);
  for (const auto& t : time_cols) header.push_back("time_" + t);
  header.push_back("params");
  header.push_back("image");
  std::string out = csv::line(header) + "\n";
  for (const auto& r : results.records) {
    std::vector<std::string> row = {r.scene, r.method, to_string(r.role), std::to_string(r.spp), std::to_string(r.width),
                                    std::to_string(r.height)};
    for (const auto& m : metric_cols) {
      const auto v = r.metric(m);
      row.push_back(v ? fmt::format("{:.9g}", *v) : "");
    }
    const std::optional<double> times[] = {r.times.input_render, r.times.filter, r.times.total, r.times.reference};
    for (const auto& t : times) row.push_back(t ? fmt::format("{:.6g}", *t) : "");
    std::string params;
    if (r.params)
      for (const auto& [k, v] : *r.params) params += fmt::format("{}{}={}", params.empty() ? "" : ";", k, v);
    row.push_back(params);
    row.push_back(r.image());
    out += csv::line(row) + "\n";
  }
  return out;
}

}  // namespace dnb::experiment
