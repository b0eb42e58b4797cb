#include "tracer/jobs.h"

#include <algorithm>
#include <filesystem>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "core/errors.h"
#include "core/exr_io.h"
#include "core/progress.h"
#include "distributed/mpi_context.h"
#include "tracer/scene.h"

namespace dnb {

std::string sequence_frame_path(const std::string& output, int frame) {
  const std::filesystem::path p(output);
  return (p.parent_path() / fmt::format("{}_{:04d}{}", p.stem().string(), frame, p.extension().string())).string();
}

std::pair<int, int> parse_frame_range(const std::string& text, const std::string& what) {
  const auto colon = text.find(':');
  int a = -1, b = -1;
  std::size_t used_a = 0, used_b = 0;
  try {
    if (colon != std::string::npos) {
      a = std::stoi(text.substr(0, colon), &used_a);
      b = std::stoi(text.substr(colon + 1), &used_b);
    }
  } catch (const std::exception&) {
    a = b = -1;
  }
  if (colon == std::string::npos || used_a != colon || used_b != text.size() - colon - 1 || a < 0 || b <= a)
    throw InputError(fmt::format("{}: '{}': expected FIRST:END, frame indices with 0 <= FIRST < END (frames FIRST .. END - 1)",
                                 what, text));
  return {a, b};
}

namespace {

// Frames [first, end) of an animated scene, each written as it finishes (an interrupted render
// keeps the frames it wrote).
AovFrame render_sequence_files(const RenderJob& job) {
  const auto [first, end] = *job.frames;
  SceneLoadOptions load = job.load;
  load.frame = first;
  auto scene = load_scene(job.scene, load);
  if (!scene->animated())
    throw InputError(fmt::format("--frames {}:{}: scene '{}' is a still (no [animation] table)", first, end, job.scene));
  if (end > scene->frames)
    throw InputError(fmt::format("--frames {}:{}: scene '{}' has {} frames (0 .. {})", first, end, job.scene, scene->frames,
                                 scene->frames - 1));
  std::shared_ptr<const Scene> previous;
  if (first > 0) {
    load.frame = first - 1;
    previous = load_scene(job.scene, load);
  }
  AovFrame frame;
  for (int t = first; t < end; ++t) {
    if (t > first) {
      previous = scene;
      load.frame = t;
      scene = load_scene(job.scene, load);
    }
    RenderSettings s = job.settings;
    Progress progress(fmt::format("render {} frame {} {}x{} {} spp", scene_name(*scene), t, s.width, s.height, s.spp),
                      std::int64_t(s.width) * s.height * s.spp, "samples", 5.0);
    s.on_progress = [&progress](std::int64_t n) { progress.add(n); };
    frame = render_sequence_frame(*scene, previous.get(), s);
    progress.finish();
    const std::string path = sequence_frame_path(job.output, t);
    write_frame(frame, path);
    spdlog::info("wrote {} (frame {} of {}, {:.2f} s)", path, t, scene->frames, frame.meta.render_seconds);
  }
  return frame;
}

}  // namespace

AovFrame render_frame_file(const RenderJob& job) {
  require_exr_output(job.output);  // before the render, not after it
  if (job.frames) return render_sequence_files(job);
  RenderSettings s = job.settings;
  auto scene = load_scene(job.scene, job.load);
  Progress progress(fmt::format("render {} {}x{} {} spp", scene_name(*scene), s.width, s.height, s.spp),
                    std::int64_t(s.width) * s.height * s.spp, "samples", 5.0);
  s.on_progress = [&progress](std::int64_t n) { progress.add(n); };
  AovFrame frame = render_frame(*scene, s);
  progress.finish();
  write_frame(frame, job.output);
  spdlog::info("wrote {} ({} layers, {} edge pixels, {} dropped samples, {:.2f} s)", job.output, frame.layers().size(),
               frame.edges ? frame.edges->size() : 0, frame.meta.dropped_samples, frame.meta.render_seconds);
  return frame;
}

std::string convergence_path(const std::string& exr) {
  std::filesystem::path p(exr);
  return (p.parent_path() / (p.stem().string() + ".convergence.csv")).string();
}

void reference_file(const ReferenceJob& job) {
  mpi::Session mpi_session;  // MPI_Init when started by mpirun
  try {
    // Rank 0 speaks for the job (one progress report); other ranks only warn.
    if (!mpi::is_root()) spdlog::set_level(std::max(spdlog::get_level(), spdlog::level::warn));
    require_exr_output(job.output);
    auto scene = load_scene(job.scene, job.load);
    Reference ref = reference_image(*scene, job.settings, job.options);
    if (mpi::is_root()) {
      const std::string csv = convergence_path(job.output);
      write_reference(ref, job.output, csv);
      spdlog::info("wrote {} and {}", job.output, csv);
    }
  } catch (const std::exception& e) {
    if (mpi::size() > 1) {
      spdlog::error("rank {}: {}", mpi::rank(), e.what());
      mpi::abort_job(dynamic_cast<const InputError*>(&e) ? 2 : 1);
    }
    throw;
  }
}

}  // namespace dnb
