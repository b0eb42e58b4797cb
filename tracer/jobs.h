// The tracer's two command-level jobs, each a request struct and one function, so that
// `denoisebench render` and `denoisebench reference` only parse arguments into the request.
#pragma once

#include <optional>
#include <string>
#include <utility>

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
  // An animated scene's frames [first, end) (`--frames A:B`): FRAME_0000.exr ... one per frame,
  // each with its motion layer (docs/sequences.md). Unset: one still frame.
  std::optional<std::pair<int, int>> frames;
};
// Loads the scene, renders every AOV layer with a progress line, writes the frame atomically.
// With `frames`, every frame of the range in order (returns the last).
AovFrame render_frame_file(const RenderJob& job);
// FRAME.exr and frame 7 -> FRAME_0007.exr.
std::string sequence_frame_path(const std::string& output, int frame);
// "A:B" -> {A, B}: InputError naming `what` unless 0 <= A < B.
std::pair<int, int> parse_frame_range(const std::string& text, const std::string& what);

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
