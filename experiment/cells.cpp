#include "experiment/cells.h"

#include <cctype>
#include <cmath>
#include <filesystem>
#include <tuple>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "core/atomic_file.h"
#include "core/errors.h"
#include "core/exr_io.h"
#include "core/hash.h"
#include "core/line_worker.h"
#include "methods/plugins.h"
#include "metrics/metrics.h"

namespace fs = std::filesystem;

namespace dnb::experiment {

std::map<std::string, std::optional<double>> score_image(
    const Image& image, const Reference& reference, const std::string& out_dir, const std::string& stem,
    std::map<std::string, std::string>& files, const std::vector<std::pair<std::string, std::string>>& attributes) {
  std::map<std::string, std::optional<double>> m;
  const Image* variance = reference.variance.empty() ? nullptr : &reference.variance;
  for (const auto& info : metrics::all_metrics()) {
    metrics::MetricResult r = info.compute(image, reference.color, variance);
    m[info.name] = std::isfinite(r.value) ? std::optional<double>(r.value) : std::nullopt;
    if (info.run_keeps_map) {
      Image rgb(r.map.width(), r.map.height(), 3);
      for (std::size_t p = 0; p < r.map.pixel_count(); ++p)
        for (int c = 0; c < 3; ++c) rgb.data()[3 * p + c] = r.map.data()[p];
      const std::string rel = stem + ".err_" + info.name + ".exr";
      write_rgb(rgb, out_dir + "/" + rel, attributes);
      files["error_" + info.name] = rel;
    }
  }
  return m;
}

void keep_frame(const std::string& frame_file, const std::string& out_dir, const std::string& rel,
                std::map<std::string, std::string>& files) {
  const std::string dest = out_dir + "/" + rel;
  // The edge file first: read_frame checks it against the frame's header, and a frame committed
  // beside another frame's edge file would not read.
  if (fs::exists(edges_path(frame_file))) {
    keep_file(edges_path(frame_file), edges_path(dest));
    files["frame_edges"] = edges_path(rel);
  } else {
    fs::remove(edges_path(dest));
  }
  const Kept how = keep_file(frame_file, dest);
  spdlog::debug("input frame '{}' {} as '{}'", frame_file, to_string(how), dest);
  files["frame"] = rel;
}

namespace {

// The fields every record of the cell has, whether it is computed or not.
CellRecord base_record(const CellPlan& plan, const SceneCells& scene) {
  CellRecord r;
  std::tie(r.scene, r.scene_hash, r.method, r.role) = std::tie(scene.scene, scene.scene_hash, plan.method, plan.role);
  std::tie(r.spp, r.width, r.height, r.seed) = std::tuple(plan.spp, scene.width, scene.height, plan.seed ? plan.seed : scene.seed);
  r.reference = scene.reference_info;
  r.base_method = plan.base_method;
  r.kind = plan.kind;
  r.params = plan.params;
  return r;
}

}  // namespace

std::string cell_key(const CellPlan& plan) { return sha256_hex(plan.identity.dump()); }

const CellRecord* reusable(const std::string& key, const CellPlan& plan, const CellContext& c) {
  const CellRecord* old = c.store->finished(key);
  if (!old) return nullptr;
  for (const auto& name : plan.required_files)
    if (old->file(name).empty()) return nullptr;
  for (const auto& [name, rel] : old->files) {
    const std::string path = c.out_dir + "/" + rel;
    if (!fs::exists(path)) return nullptr;
    // The cell's own images must still be the ones it wrote: a cell of the same name and spp with
    // another key (other parameters in another config, or the method's code as it was before a
    // change that was then undone) writes the same file names into the folder.
    if (name == "image" || name.rfind("error_", 0) == 0) {
      try {
        const auto attrs = read_rgb_attributes(path);
        const auto it = attrs.find("cell_key");
        if (it == attrs.end() || it->second != key) {
          spdlog::debug("{}: written by another cell than {}; computing it again", path, key);
          return nullptr;
        }
      } catch (const InputError&) {  // damaged: compute the cell again
        return nullptr;
      }
    }
  }
  return old;
}

void skip_cell(const CellContext& c, SkippedCell skip) {
  spdlog::warn("cell {} / {} / {} spp skipped: {}", skip.scene, skip.method, skip.spp, skip.reason);
  c.store->skip(std::move(skip));
  c.progress->add(1);
}

ComputedCell compute_cell(const CellPlan& plan, const std::string& scene_name, const std::string& key) {
  if (plan.skip_reason) return SkippedCell{scene_name, plan.method, plan.spp, *plan.skip_reason};
  try {
    return plan.compute();
  } catch (const MethodUnavailable& e) {
    if (!plan.contain_failures) throw;
    // Not a failure: the method cannot run on this machine (its message says how to make it).
    return SkippedCell{scene_name, plan.method, plan.spp, e.what()};
  } catch (const std::exception& e) {
    if (!plan.contain_failures || !(dynamic_cast<const WorkError*>(&e) || dynamic_cast<const InputError*>(&e))) throw;
    FailedCell f{scene_name, plan.method, plan.spp, key, e.what(), {}};
    // A plug-in's or a renderer back-end's program: the reason apart from its last lines.
    if (auto* pe = dynamic_cast<const WorkerError*>(&e)) f.reason = pe->reason(), f.log_tail = pe->log_tail();
    spdlog::error("cell {} / {} / {} spp failed: {}", scene_name, plan.method, plan.spp, e.what());
    return f;
  }
}

std::optional<CellRecord> store_cell(const CellPlan& plan, const SceneCells& scene, const CellContext& c,
                                     const std::string& key, ComputedCell computed) {
  if (auto* skipped = std::get_if<SkippedCell>(&computed)) {
    skip_cell(c, std::move(*skipped));
    return std::nullopt;
  }
  if (auto* failed = std::get_if<FailedCell>(&computed)) {
    c.store->fail(std::move(*failed));
    c.progress->add(1);
    return std::nullopt;
  }
  CellOutput& out = std::get<CellOutput>(computed);
  CellRecord r = base_record(plan, scene);
  const std::string stem = scene.image_dir + "/" + plan.stem;
  // Every image the cell writes names the cell's key in its header (checked by `reusable`).
  const std::vector<std::pair<std::string, std::string>> owner = {{"cell_key", key}};
  write_rgb(out.image, c.out_dir + "/" + stem + ".exr", owner);
  r.files["image"] = stem + ".exr";
  if (!out.frame_file.empty()) keep_frame(out.frame_file, c.out_dir, scene.frame_dir + "/" + plan.stem + ".exr", r.files);
  r.metrics = score_image(out.image, *scene.reference, c.out_dir, stem, r.files, owner);
  if (out.baseline) {
    const metrics::WorseBlocks b = metrics::worse_blocks(out.image, *out.baseline, scene.reference->color);
    r.blocks = {{"block", b.block}, {"count", b.count}, {"worse", b.worse}, {"worse_twice", b.worse_twice}};
    for (const auto& t : b.tiles) r.worse_tiles.push_back({double(t.x), double(t.y), double(t.w), double(t.h), t.ratio});
  }
  static_cast<CellMeasurement&>(r) = std::move(out.measured);
  r.times.reference = scene.reference_info.seconds;
  r.cell_key = key;
  c.store->add(r);
  c.progress->add(1);
  return r;
}

std::optional<CellRecord> run_cell(const CellPlan& plan, const SceneCells& scene, const CellContext& c) {
  const std::string key = cell_key(plan);
  if (plan.skip_reason) return store_cell(plan, scene, c, key, compute_cell(plan, scene.scene, key));
  if (const CellRecord* old = reusable(key, plan, c)) {
    c.store->reuse(*old);
    c.progress->add(1);
    return *old;
  }
  return store_cell(plan, scene, c, key, compute_cell(plan, scene.scene, key));
}

// ---- the spool of a distributed run ----

std::string spool_dir(const std::string& out_dir) { return out_dir + "/.spool"; }

namespace {

std::string spooled(const std::string& out_dir, const std::string& key, const char* suffix) {
  return spool_dir(out_dir) + "/" + key + suffix;
}

}  // namespace

bool is_spooled(const std::string& out_dir, const std::string& key) {
  return fs::exists(spooled(out_dir, key, ".json"));
}

void write_spooled(const std::string& out_dir, const std::string& key, const ComputedCell& computed) {
  nlohmann::json j = nlohmann::json::object();
  if (auto* skipped = std::get_if<SkippedCell>(&computed)) j["skipped"] = skipped->to_json();
  if (auto* failed = std::get_if<FailedCell>(&computed)) j["failed"] = failed->to_json();
  if (auto* out = std::get_if<CellOutput>(&computed)) {
    // Images as float EXR: read back bit for bit. The JSON last: it marks the entry complete.
    write_rgb(out->image, spooled(out_dir, key, ".exr"));
    if (out->baseline) write_rgb(*out->baseline, spooled(out_dir, key, ".baseline.exr"));
    nlohmann::json o = {{"frame_file", out->frame_file}, {"baseline", out->baseline.has_value()}};
    out->measured.write_json(o);  // the record's own keys for what was measured
    j["output"] = std::move(o);
  }
  write_text_atomic(spooled(out_dir, key, ".json"), j.dump());
}

std::optional<ComputedCell> read_spooled(const std::string& out_dir, const std::string& key) {
  const std::string path = spooled(out_dir, key, ".json");
  if (!fs::exists(path)) return std::nullopt;
  try {
    const nlohmann::json j = nlohmann::json::parse(read_text_file(path));
    if (int(j.contains("skipped")) + int(j.contains("failed")) + int(j.contains("output")) != 1)
      throw InputError(fmt::format("'{}': a spooled cell holds exactly one of 'output', 'failed', 'skipped'", path));
    if (j.contains("skipped")) return SkippedCell::from_json(j.at("skipped"), path);
    if (j.contains("failed")) return FailedCell::from_json(j.at("failed"), path);
    const nlohmann::json& o = j.at("output");
    CellOutput out;
    out.image = read_rgb(spooled(out_dir, key, ".exr"));
    if (o.at("baseline").get<bool>()) out.baseline = read_rgb(spooled(out_dir, key, ".baseline.exr"));
    out.measured = CellMeasurement::read_json(o, path);
    out.frame_file = o.at("frame_file").get<std::string>();
    return out;
  } catch (const nlohmann::json::exception& e) {
    throw InputError(fmt::format("'{}': not a spooled cell of this build ({}); remove it to compute the cell again", path, e.what()));
  }
}

void remove_spooled(const std::string& out_dir, const std::string& key) {
  // The JSON first: without it the entry no longer counts, whatever else is left.
  for (const char* suffix : {".json", ".exr", ".baseline.exr"}) fs::remove(spooled(out_dir, key, suffix));
}

}  // namespace dnb::experiment
