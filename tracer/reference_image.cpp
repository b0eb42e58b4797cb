// reference_image: the cache lookup, the render through the block driver with the tracer's
// render_color_sums, and storing the result (tracer/reference.h; its key: tracer/render_cache_keys.h).
#include <algorithm>
#include <cmath>
#include <filesystem>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "core/atomic_file.h"
#include "core/errors.h"
#include "core/exr_io.h"
#include "core/timer.h"
#include "core/build_info.h"
#include "tracer/render_cache_keys.h"
#include "distributed/mpi_context.h"
#include "tracer/reference.h"
#include "tracer/scene_loader.h"

namespace dnb {
namespace fs = std::filesystem;

namespace {

Reference read_cached(const CacheEntry& entry) {
  Reference ref;
  ref.path = entry.file("reference.exr");
  AovFrame f = read_frame(ref.path, {layer::kColor, layer::kVariance},
                          std::vector<std::string>{layer::kColor, layer::kVariance});
  ref.color = f.layer(layer::kColor);
  ref.variance = f.layer(layer::kVariance);
  ref.meta = f.meta;
  ref.convergence = parse_convergence_csv(read_text_file(entry.file("convergence.csv")), entry.file("convergence.csv"));
  ref.cache_hit = true;
  return ref;
}

}  // namespace

Reference reference_image(const Scene& scene, const ReferenceSettings& settings, const ReferenceOptions& options) {
  if (settings.width <= 0 || settings.height <= 0 || settings.spp <= 0 || settings.block_spp <= 0)
    throw InputError(fmt::format("reference: size {}x{}, spp {} and block spp {} must be positive",
                                 settings.width, settings.height, settings.spp, settings.block_spp));
  const bool root = mpi::is_root();
  const CacheKey key = reference_cache_key(scene, settings);
  const std::string digest = key.digest();
  Cache cache(options.cache_dir.empty() ? Cache::default_dir() : options.cache_dir);
  const std::string label = fmt::format("reference {} {}x{} {} spp", scene_name(scene), settings.width,
                                        settings.height, settings.spp);

  // Rank 0 looks the cache up and tells the others whether there is anything to render.
  std::optional<Reference> cached;
  if (root && options.use_cache) {
    if (auto entry = cache.lookup(key)) {
      try {
        cached = read_cached(*entry);
      } catch (const InputError& e) {
        // Intact checksums but unreadable: written by an incompatible build. Rebuild it.
        spdlog::warn("cache entry '{}' cannot be read ({}); rendering again", entry->dir, e.what());
      }
    }
  }
  if (mpi::broadcast_int(cached ? 1 : 0) == 1) {
    if (!root) return {};
    spdlog::info("{}: cache hit ({}), nothing to render", label, digest.substr(0, 12));
    return std::move(*cached);
  }
  if (root)
    spdlog::info("{}: {} ({} rank{})", label, options.use_cache ? "cache miss, rendering" : "rendering (--no-cache)",
                 mpi::size(), mpi::size() > 1 ? "s" : "");

  BlockJob job;
  job.width = settings.width;
  job.height = settings.height;
  job.spp = settings.spp;
  job.block_spp = settings.block_spp;
  job.identity = key.canonical();
  if (options.checkpoints)
    job.checkpoint_path = ((options.checkpoint_dir.empty() ? fs::path(cache.dir()) / "checkpoints" / digest
                                                           : fs::path(options.checkpoint_dir)) /
                           "reference.ckpt")
                              .string();
  job.progress = options.progress;
  job.what = label;

  RenderSettings rs;
  rs.width = settings.width;
  rs.height = settings.height;
  rs.spp = settings.spp;
  rs.seed = settings.seed;
  rs.threads = settings.threads;
  rs.max_depth = settings.max_depth;
  Stopwatch clock;
  BlockResult blocks = accumulate_blocks(job, [&](int begin, int end, const std::function<void(std::int64_t)>& on_progress) {
    RenderSettings block_settings = rs;
    block_settings.on_progress = on_progress;
    return render_color_sums(scene, block_settings, begin, end);
  });
  if (!root) return {};

  Reference ref;
  ref.render_seconds = clock.seconds();
  ref.checkpoint_seconds = blocks.checkpoint_seconds;
  ref.color = blocks.sums.mean();
  ref.variance = blocks.sums.variance_of_mean();
  ref.convergence = blocks.convergence;
  ref.blocks_rendered = blocks.blocks_rendered;
  ref.blocks_resumed = blocks.blocks_resumed;
  FrameMeta& m = ref.meta;
  m.scene = scene_name(scene);
  m.spp = settings.spp;
  m.seed = settings.seed;
  m.tracer_version = kTracerVersion;
  m.build_version = build_version_and_revision();
  m.render_seconds = blocks.seconds;
  m.dropped_samples = blocks.sums.dropped;
  m.extra["reference"] = std::string("1");  // std::string: GCC 12 warns falsely on = "1" (PR 105329)
  m.extra["cache_key"] = digest;
  m.extra["scene_hash"] = key.parts().front().second;  // scene_content_hash, computed once
  m.extra["max_depth"] = std::to_string(settings.max_depth);
  m.extra["block_spp"] = std::to_string(settings.block_spp);
  if (!blocks.convergence.empty()) {
    m.extra["rel_error"] = fmt::format("{:.6g}", blocks.convergence.back().rel_error);
    m.extra["est_relmse"] = fmt::format("{:.6g}", blocks.convergence.back().est_relmse);
  }
  CacheEntry entry = cache.store(key, [&](const std::string& dir) {
    write_reference(ref, dir + "/reference.exr", dir + "/convergence.csv");
  });
  ref.path = entry.file("reference.exr");
  // The finished reference is safe in the cache: the checkpoint has served its purpose.
  std::error_code ec;
  if (!job.checkpoint_path.empty()) {
    fs::remove(job.checkpoint_path, ec);
    if (options.checkpoint_dir.empty()) fs::remove(fs::path(job.checkpoint_path).parent_path(), ec);
  }
  spdlog::info("{}: rendered {} blocks ({} resumed from a checkpoint) in {:.2f} s, relative error {:.3g}, stored in cache",
               label, ref.blocks_rendered, ref.blocks_resumed, ref.render_seconds,
               ref.convergence.empty() ? NAN : ref.convergence.back().rel_error);
  if (blocks.checkpoints_written > 0)
    spdlog::info("{}: {} checkpoints written in {:.3f} s ({:.2f}% of the render time)", label,
                 blocks.checkpoints_written, blocks.checkpoint_seconds,
                 100.0 * blocks.checkpoint_seconds / std::max(1e-9, ref.render_seconds));
  return ref;
}

}  // namespace dnb
