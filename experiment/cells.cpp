#include "experiment/cells.h"

#include <cctype>
#include <cmath>
#include <filesystem>
#include <tuple>

#include <spdlog/spdlog.h>

#include "core/atomic_file.h"
#include "core/errors.h"
#include "core/exr_io.h"
#include "core/hash.h"
#include "methods/plugins.h"
#include "metrics/metrics.h"

namespace fs = std::filesystem;

namespace dnb::experiment {

std::string safe_file_name(const std::string& s) {
  std::string o = s;
  for (char& ch : o)
    if (!std::isalnum(static_cast<unsigned char>(ch)) && ch != '-' && ch != '_' && ch != '.') ch = '_';
  return o;
}

std::map<std::string, std::optional<double>> score_image(const Image& image, const Reference& reference,
                                                         const std::string& out_dir, const std::string& stem,
                                                         std::map<std::string, std::string>& files) {
  std::map<std::string, std::optional<double>> m;
  const Image* variance = reference.variance.empty() ? nullptr : &reference.variance;
  for (const auto& info : metrics::all_metrics()) {
    metrics::MetricResult r = info.compute(image, reference.color, variance);
    m[info.name] = std::isfinite(r.value) ? std::optional<double>(r.value) : std::nullopt;
    if (info.name == "flip" || info.name == "hdrflip" || info.name == "relmse") {
      Image rgb(r.map.width(), r.map.height(), 3);
      for (std::size_t p = 0; p < r.map.pixel_count(); ++p)
        for (int c = 0; c < 3; ++c) rgb.data()[3 * p + c] = r.map.data()[p];
      const std::string rel = stem + ".err_" + info.name + ".exr";
      write_rgb(rgb, out_dir + "/" + rel);
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

// A finished record that has the plan's required files and whose every file is still in the folder.
const CellRecord* reusable(const std::string& key, const CellPlan& plan, const CellContext& c) {
  const CellRecord* old = c.store->finished(key);
  if (!old) return nullptr;
  for (const auto& name : plan.required_files)
    if (old->file(name).empty()) return nullptr;
  for (const auto& [name, rel] : old->files)
    if (!fs::exists(c.out_dir + "/" + rel)) return nullptr;
  return old;
}

}  // namespace

void skip_cell(const CellContext& c, SkippedCell skip) {
  spdlog::warn("cell {} / {} / {} spp skipped: {}", skip.scene, skip.method, skip.spp, skip.reason);
  c.store->skip(std::move(skip));
  c.progress->add(1);
}

std::optional<CellRecord> run_cell(const CellPlan& plan, const SceneCells& scene, const CellContext& c) {
  const std::string key = sha256_hex(plan.identity.dump());
  if (const CellRecord* old = reusable(key, plan, c)) {
    c.store->reuse(*old);
    c.progress->add(1);
    return *old;
  }
  CellOutput out;
  try {
    out = plan.compute();
  } catch (const MethodUnavailable& e) {
    if (!plan.contain_failures) throw;
    // Not a failure: the method cannot run on this machine (its message says how to make it).
    skip_cell(c, SkippedCell{scene.scene, plan.method, plan.spp, e.what()});
    return std::nullopt;
  } catch (const std::exception& e) {
    if (!plan.contain_failures || !(dynamic_cast<const WorkError*>(&e) || dynamic_cast<const InputError*>(&e))) throw;
    FailedCell f{scene.scene, plan.method, plan.spp, key, e.what(), {}};
    if (auto* pe = dynamic_cast<const PluginError*>(&e)) f.reason = pe->reason(), f.log_tail = pe->log_tail();
    spdlog::error("cell {} / {} / {} spp failed: {}", scene.scene, plan.method, plan.spp, e.what());
    c.store->fail(std::move(f));
    c.progress->add(1);
    return std::nullopt;
  }
  CellRecord r = base_record(plan, scene);
  const std::string stem = scene.image_dir + "/" + plan.stem;
  write_rgb(out.image, c.out_dir + "/" + stem + ".exr");
  r.files["image"] = stem + ".exr";
  if (!out.frame_file.empty()) keep_frame(out.frame_file, c.out_dir, scene.frame_dir + "/" + plan.stem + ".exr", r.files);
  r.metrics = score_image(out.image, *scene.reference, c.out_dir, stem, r.files);
  if (out.baseline) {
    const metrics::WorseBlocks b = metrics::worse_blocks(out.image, *out.baseline, scene.reference->color);
    r.blocks = {{"block", b.block}, {"count", b.count}, {"worse", b.worse}, {"worse_twice", b.worse_twice}};
    for (const auto& t : b.tiles) r.worse_tiles.push_back({double(t.x), double(t.y), double(t.w), double(t.h), t.ratio});
  }
  r.times = out.times;
  r.times.reference = scene.reference_info.seconds;
  r.input_cache_hit = out.input_cache_hit;
  r.phases = out.phases;
  r.counters = out.counters;
  r.method_info = out.method_info;
  r.cell_key = key;
  c.store->add(r);
  c.progress->add(1);
  return r;
}

}  // namespace dnb::experiment
