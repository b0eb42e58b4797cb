// denoisebench reference SCENE --spp N --size WxH -o REF.exr [--checkpoint DIR] [--seed S]
//                          [--block-spp B] [--max-depth D] [--threads T] [--no-checkpoint]
//                          [--no-cache] [--cache-dir DIR]
// A converged reference (tracer/reference.h): cached by content, checkpointed after every pass,
// distributed over the ranks of `mpirun -np N denoisebench reference ...`. Writes REF.exr
// (R,G,B, variance.R/G/B, metadata) and REF.convergence.csv beside it.
#include <filesystem>
#include <regex>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "apps/commands.h"
#include "core/errors.h"
#include "tracer/mpi_context.h"
#include "tracer/reference.h"
#include "tracer/scene_loader.h"

namespace dnb::app {

namespace {

struct ReferenceArgs {
  std::string scene;
  std::string size = "1024x768";
  std::string output;
  std::string scenes_dir;
  ReferenceSettings settings;
  ReferenceOptions options;
  bool no_cache = false;
  bool no_checkpoint = false;
};

std::pair<int, int> parse_size(const std::string& s) {
  std::smatch m;
  static const std::regex re("([0-9]{1,5})x([0-9]{1,5})");
  if (!std::regex_match(s, m, re) || std::stoi(m[1]) == 0 || std::stoi(m[2]) == 0)
    throw InputError(fmt::format("--size '{}': expected WIDTHxHEIGHT, e.g. 1024x768", s));
  return {std::stoi(m[1]), std::stoi(m[2])};
}

// REF.exr -> REF.convergence.csv
std::string convergence_path(const std::string& exr) {
  std::filesystem::path p(exr);
  return (p.parent_path() / (p.stem().string() + ".convergence.csv")).string();
}

int run_reference(const ReferenceArgs& a) {
  mpi::Session mpi_session;  // MPI_Init when started by mpirun
  try {
    // Rank 0 speaks for the job (DESIGN: one progress report); other ranks only warn.
    if (!mpi::is_root()) spdlog::set_level(std::max(spdlog::get_level(), spdlog::level::warn));
    ReferenceSettings s = a.settings;
    std::tie(s.width, s.height) = parse_size(a.size);
    ReferenceOptions o = a.options;
    o.use_cache = !a.no_cache;
    o.checkpoints = !a.no_checkpoint;
    SceneLoadOptions load;
    load.scenes_dir = a.scenes_dir;
    auto scene = load_scene(a.scene, load);
    Reference ref = reference_image(*scene, s, o);
    if (mpi::is_root()) {
      const std::string csv = convergence_path(a.output);
      write_reference(ref, a.output, csv);
      spdlog::info("wrote {} and {}", a.output, csv);
    }
    return 0;
  } catch (const std::exception& e) {
    // An error on one rank would leave the others waiting in a transfer: end the whole job.
    if (mpi::size() > 1) {
      spdlog::error("rank {}: {}", mpi::rank(), e.what());
      mpi::abort_job(dynamic_cast<const InputError*>(&e) ? 2 : 1);
    }
    throw;
  }
}

}  // namespace

void add_reference(CLI::App& app, Action& action) {
  auto a = std::make_shared<ReferenceArgs>();
  auto* cmd = app.add_subcommand("reference", "Render a converged reference: cached, checkpointed, MPI-distributed");
  cmd->add_option("scene", a->scene, "built-in scene name or scene file")->required();
  cmd->add_option("-o,--output", a->output, "output EXR (R,G,B, variance.R/G/B); REF.convergence.csv is written beside it")
      ->required();
  cmd->add_option("--spp", a->settings.spp, "samples per pixel")->capture_default_str()->check(CLI::Range(1, 1 << 24));
  cmd->add_option("--size", a->size, "WIDTHxHEIGHT")->capture_default_str();
  cmd->add_option("--seed", a->settings.seed, "random seed")->capture_default_str();
  cmd->add_option("--block-spp", a->settings.block_spp,
                  "samples per pixel of one block: the unit of checkpoints and MPI work (part of the cache key)")
      ->capture_default_str()
      ->check(CLI::Range(1, 1 << 24));
  cmd->add_option("--max-depth", a->settings.max_depth, "path length")->capture_default_str()->check(CLI::Range(1, 1024));
  cmd->add_option("--threads", a->settings.threads, "worker threads per process (0: all cores); the image does not depend on it")
      ->capture_default_str()
      ->check(CLI::Range(0, 4096));
  cmd->add_option("--checkpoint", a->options.checkpoint_dir,
                  "checkpoint folder (one per reference; default: inside the cache folder)");
  cmd->add_flag("--no-checkpoint", a->no_checkpoint, "write no checkpoints (a crash loses the render)")
      ->excludes(cmd->get_option("--checkpoint"));
  cmd->add_option("--cache-dir", a->options.cache_dir,
                  "reference cache (default: $DENOISEBENCH_CACHE, else ~/.cache/denoisebench)");
  cmd->add_flag("--no-cache", a->no_cache, "render even when the cache holds this reference (the cache entry is replaced)");
  cmd->add_option("--scenes-dir", a->scenes_dir, "folder of the McGuire scenes");
  cmd->callback([&action, a] { action = [a] { return run_reference(*a); }; });
}

}  // namespace dnb::app
