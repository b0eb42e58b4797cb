// The tracer's two command-level jobs, each a request struct and one function, so that
// `denoisebench render` and `denoisebench reference` only parse arguments into the request.
#pragma once

#include <string>

#include "core/aov_frame.h"
#include "tracer/reference.h"
#include "tracer/render.h"
#include "tracer/scene_loader.h"

namespace dnb {

struct RenderJob {
  std::string scene;        // built-in name or scene file
  SceneLoadOptions load;
  RenderSettings settings;
  std::string output;       // FRAME.exr (its edge file FRAME.edges.exr is written beside it)
};
// Loads the scene, renders every AOV layer with a progress line, writes the frame atomically.
AovFrame render_frame_file(const RenderJob& job);

struct ReferenceJob {
  std::string scene;
  SceneLoadOptions load;
  ReferenceSettings settings;
  ReferenceOptions options;
  std::string output;  // REF.exr; REF.convergence.csv is written beside it
};
// REF.exr -> REF.convergence.csv
std::string convergence_path(const std::string& reference_exr);
// The reference, cached and checkpointed (tracer/reference.h), over every MPI rank when the
// program runs under mpirun (an MPI session for the call's duration); rank 0 writes REF.exr and
// its convergence log. An error on one rank ends the whole job (exit status 2 for bad input,
// 1 otherwise) rather than leave the other ranks waiting in a transfer.
void reference_file(const ReferenceJob& job);

}  // namespace dnb
