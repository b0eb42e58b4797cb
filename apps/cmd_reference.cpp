// denoisebench reference SCENE --spp N --size WxH -o REF.exr [--checkpoint DIR] [--seed S]
//                          [--block-spp B] [--max-depth D] [--threads T] [--no-checkpoint]
//                          [--no-cache] [--cache-dir DIR]
// A converged reference (tracer/reference.h): cached by content, checkpointed after every pass,
// distributed over the ranks of `mpirun -np N denoisebench reference ...`. Writes REF.exr
// (R,G,B, variance.R/G/B, metadata) and REF.convergence.csv beside it.
#include "apps/args.h"
#include "apps/commands.h"
#include "tracer/jobs.h"

namespace dnb::app {

void add_reference(CLI::App& app, Action& action) {
  struct ReferenceArgs {
    ReferenceJob job;
    std::string size = "1024x768";
    bool no_cache = false, no_checkpoint = false;
  };
  auto a = std::make_shared<ReferenceArgs>();
  auto* cmd = app.add_subcommand("reference", "Render a converged reference: cached, checkpointed, MPI-distributed");
  cmd->add_option("scene", a->job.scene, "built-in scene name or scene file")->required();
  cmd->add_option("-o,--output", a->job.output, "output EXR (R,G,B, variance.R/G/B); REF.convergence.csv is written beside it")
      ->required();
  cmd->add_option("--spp", a->job.settings.spp, "samples per pixel")
      ->capture_default_str()
      ->check(in_bounds(bounds::kSpp));
  cmd->add_option("--size", a->size, "WIDTHxHEIGHT")->capture_default_str();
  cmd->add_option("--seed", a->job.settings.seed, "random seed")->capture_default_str()->check(in_bounds(bounds::kSeed));
  cmd->add_option("--block-spp", a->job.settings.block_spp,
                  "samples per pixel of one block: the unit of checkpoints and MPI work (part of the cache key)")
      ->capture_default_str()
      ->check(in_bounds(bounds::kBlockSpp));
  cmd->add_option("--max-depth", a->job.settings.max_depth, "path length")
      ->capture_default_str()
      ->check(in_bounds(bounds::kMaxDepth));
  add_threads_option(*cmd, a->job.settings.threads,
                     "worker threads per process (0: all cores); the image does not depend on it")
      ->capture_default_str();
  cmd->add_option("--checkpoint", a->job.options.checkpoint_dir,
                  "checkpoint folder (one per reference; default: inside the cache folder)");
  cmd->add_flag("--no-checkpoint", a->no_checkpoint, "write no checkpoints (a crash loses the render)")
      ->excludes(cmd->get_option("--checkpoint"));
  cmd->add_option("--cache-dir", a->job.options.cache_dir,
                  "reference cache (default: $DENOISEBENCH_CACHE, else ~/.cache/denoisebench)");
  cmd->add_flag("--no-cache", a->no_cache, "render even when the cache holds this reference (the cache entry is replaced)");
  cmd->add_option("--scenes-dir", a->job.load.scenes_dir, "folder of the McGuire scenes");
  cmd->callback([&action, a] {
    action = [a] {
      ReferenceJob job = a->job;
      std::tie(job.settings.width, job.settings.height) = parse_size(a->size);
      job.options.use_cache = !a->no_cache;
      job.options.checkpoints = !a->no_checkpoint;
      reference_file(job);
      return 0;
    };
  });
}

}  // namespace dnb::app
