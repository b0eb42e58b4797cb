// Converged references: progressive, checkpointed, cached by content, distributed with MPI.
//
// A reference of `spp` samples per pixel is rendered in blocks of `block_spp` samples
// (block b holds the sample indices [b * block_spp, min((b + 1) * block_spp, spp))). The
// per-pixel double sums of each block (render_color_sums) are added to the running total in
// block order, always: the total is a left fold over blocks 0, 1, 2, ..., so the image depends
// only on (scene, settings, block_spp), never on how many processes or threads rendered the
// blocks, nor on where a render was interrupted and resumed.
//
//  - Passes: a pass renders the next mpi::size() blocks, one per rank; rank 0 receives them,
//    adds them in block order, then writes a checkpoint (running total, blocks done, a header
//    with every parameter, SHA-256 checksums) atomically. Killed at any moment, a run started
//    again with the same arguments resumes from it and ends bit-identical to an uninterrupted
//    render. A checkpoint written for other parameters is refused (InputError); a damaged one
//    is reported and ignored (the render starts over).
//  - Cache: the finished reference (reference.exr: R,G,B and variance.R/G/B, the variance of
//    the mean, plus metadata; convergence.csv) is stored in the content-keyed cache
//    (tracer/render_cache.h) under reference_cache_key() (tracer/render_cache_keys.h); a later request is a
//    verified cache hit.
//  - Convergence log: after every pass, spp and the estimated relative error of the mean,
//    from the per-pixel variance (ConvergenceRow).
#pragma once

#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "core/aov_frame.h"
#include "core/image.h"
#include "tracer/render_cache.h"
#include "tracer/render.h"

namespace dnb {

struct ReferenceSettings {
  int width = 1024;
  int height = 768;
  int spp = 4096;            // samples per pixel in all
  std::uint64_t seed = 1;
  int max_depth = 8;         // path length (RenderSettings::max_depth)
  int block_spp = 64;        // samples per pixel of one block: the unit of checkpoints, of MPI
                             // work and of the reduction order (part of the cache key)
  int threads = 0;           // 0: all cores (the image does not depend on it)
};

struct ReferenceOptions {
  std::string cache_dir;       // empty: Cache::default_dir()
  bool use_cache = true;       // false: do not look up the cache, render (the result still
                               // replaces the cache entry, so a damaged one is repaired)
  std::string checkpoint_dir;  // empty: <cache_dir>/checkpoints/<key digest>/
  bool checkpoints = true;     // false: no checkpoints (a crash loses the render)
  bool progress = true;        // progress lines (rank 0)
};

// One line of the convergence log, written after every pass.
struct ConvergenceRow {
  std::int64_t spp = 0;      // samples per pixel accumulated
  double seconds = 0;        // render time so far (all sessions of a resumed render)
  double rel_error = 0;      // sqrt(sum var / sum mean^2) over pixels and channels: the relative
                             // RMS error of the mean image
  double est_relmse = 0;     // mean of var / (mean^2 + 0.01): the expected `relmse` (docs/design.md)
                             // of this reference against the fully converged image
};

struct Reference {
  Image color;               // 3 channels: the mean of F
  Image variance;            // 3 channels: per-pixel sample variance of the mean
  FrameMeta meta;
  std::vector<ConvergenceRow> convergence;
  std::string path;          // reference.exr in the cache entry
  bool cache_hit = false;    // true: nothing was rendered
  int blocks_rendered = 0;   // blocks rendered in this call (all ranks)
  int blocks_resumed = 0;    // blocks taken from a checkpoint
  double render_seconds = 0;       // this call's wall time in the block driver
  double checkpoint_seconds = 0;   // of which writing checkpoints
};

// The cached reference, or a fresh render (resumed from its checkpoint when one exists),
// stored in the cache. Collective under MPI: every rank calls it with the same arguments; rank
// 0 gets the reference, other ranks get an empty Reference (color.empty()).
Reference reference_image(const Scene& scene, const ReferenceSettings& settings,
                          const ReferenceOptions& options = {});

// Writes a reference as an EXR (R,G,B, variance.R/G/B, metadata) and, when `csv_path` is not
// empty, its convergence log, both atomically.
void write_reference(const Reference& ref, const std::string& exr_path, const std::string& csv_path);
std::string convergence_csv(const std::vector<ConvergenceRow>& rows);
// Reads convergence_csv's text back; InputError naming `path` and the line when malformed.
std::vector<ConvergenceRow> parse_convergence_csv(const std::string& text, const std::string& path);

// ---------------------------------------------------------------------------------------------
// The block driver underneath reference_image, independent of the tracer so that it can be
// tested with synthetic sums. `render` returns the sums of the sample range [begin, end) and
// reports finished pixel-samples through on_progress (from any thread).

using BlockRenderer = std::function<ColorSums(int sample_begin, int sample_end,
                                              const std::function<void(std::int64_t)>& on_progress)>;

struct BlockJob {
  int width = 0, height = 0;
  int spp = 0;
  int block_spp = 64;
  std::string identity;          // canonical text of everything that determines the sums; a
                                 // checkpoint is only resumed when its identity is equal
  std::string checkpoint_path;   // empty: no checkpoints
  bool progress = false;
  std::string what = "reference";  // progress label
};

struct BlockResult {
  ColorSums sums;                // on rank 0; empty elsewhere
  std::vector<ConvergenceRow> convergence;
  int blocks_rendered = 0, blocks_resumed = 0;
  double seconds = 0;            // render time, all sessions
  int checkpoints_written = 0;   // in this call, rank 0
  double checkpoint_seconds = 0; // time spent writing them (included in `seconds`)
};

// Collective under MPI (every rank calls it with the same job).
BlockResult accumulate_blocks(const BlockJob& job, const BlockRenderer& render);

// The element-wise sum of two ranges' sums (the fold step).
void add_block(ColorSums& total, const ColorSums& block);
// The relative error of the sums' mean, from ColorSums::variance_of_mean (the sample groups).
ConvergenceRow convergence_of(const ColorSums& sums);

// Checkpoint files: "DNBCKPT3" header line, a line with the JSON header's length and SHA-256,
// the JSON header (identity, blocks done, sizes, group counts, convergence log, payload SHA-256), then
// the payload (sum and group_sum as raw doubles).
struct Checkpoint {
  std::string identity;
  int blocks_done = 0;
  ColorSums sums;
  std::vector<ConvergenceRow> convergence;
  double seconds = 0;
};
void write_checkpoint(const std::string& path, const Checkpoint& checkpoint);
// Nothing when the file is absent; nothing and `damage` set when it is damaged (truncated,
// checksum mismatch, malformed).
std::optional<Checkpoint> read_checkpoint(const std::string& path, std::string* damage = nullptr);

}  // namespace dnb
