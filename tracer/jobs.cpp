#include "tracer/jobs.h"

#include <algorithm>
#include <filesystem>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "core/errors.h"
#include "core/exr_io.h"
#include "core/progress.h"
#include "distributed/mpi_context.h"

namespace dnb {

AovFrame render_frame_file(const RenderJob& job) {
  require_exr_output(job.output);  // before the render, not after it
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
