// Sequences in a run (docs/sequences.md): an animated scene's frames are rows of their own
// (sequence_row: "name.f03"), each with its input frames, reference and cells, planned by
// rendered_scene_plans frame by frame in order. What the frames of one sequence share lives here:
// - the sequence's input frames, rendered through the render cache (a frame's key holds the
//   scene's per-frame content hash and its motion layer's kind), loadable again by index;
// - the temporal methods' instances and history, one per (column, spp, seed), fed the frames in
//   order; a frame out of turn (a run resumed after frame t - 1 was finished) replays the
//   frames before it through a fresh instance first.
#pragma once

#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <tuple>

#include "core/aov_frame.h"
#include "denoisers/method.h"
#include "experiment/results.h"
#include "tracer/render.h"
#include "tracer/render_cache.h"
#include "tracer/scene.h"

namespace dnb::experiment {

// The render cache key of frame `scene.frame` of a sequence rendered with `settings` (the
// frame's own key plus the motion layer's kind: a still render of the same frame differs).
CacheKey sequence_frame_key(const Scene& scene, const RenderSettings& settings);

// Frame `scene.frame` of animated scene `name` (`scene`: that frame, loaded) as a run's input:
// through the render cache, rendered with its previous frame (loaded from `name` only when it
// must be rendered) for the motion layer. `hit` says whether the cache had it.
AovFrame sequence_input(Cache& cache, const Scene& scene, const std::string& name, const RenderSettings& settings,
                        bool use_cache, bool* hit = nullptr);

// One sequence of a run: its name and length, and its temporal methods' state.
class SequenceRun {
 public:
  // The replay reads the frames from `cache`: this run rendered them (or found them) already.
  SequenceRun(std::string name, int frames, Cache& cache) : name_(std::move(name)), frames_(frames), cache_(cache) {}
  const std::string& name() const { return name_; }
  int frames() const { return frames_; }

  // Runs temporal method `column` (created by `create`) on frame `t` of the sequence at
  // (settings.spp, settings.seed), whose input is `frame`: from its state when frame t - 1 was
  // the last it saw, else after replaying frames 0 .. t - 1 (from the render cache) through a
  // fresh instance. One run: a repeat would advance the history.
  MethodResult run_temporal(const std::string& column, const std::function<std::unique_ptr<Method>()>& create, int t,
                            const AovFrame& frame, const Scene* scene, const RenderSettings& settings);

 private:
  struct State {
    std::unique_ptr<Method> method;
    int next = 0;                    // the frame it expects
    std::optional<AovFrame> previous;  // the last frame it saw, its read layers only
  };
  MethodResult step(State& s, int t, const AovFrame& frame, const Scene* scene, std::uint64_t seed, int spp);

  std::string name_;
  int frames_;
  Cache& cache_;
  std::map<std::tuple<std::string, int, std::uint64_t>, State> states_;
};

// The sequence's scores from the results folder: for every column (input and methods) and input
// spp and seed whose record exists on every frame, the mean of each still metric over the
// frames, and tmse and disocclusion_mse (metrics/temporal.h) from the frames' images, references
// and the motion, depth and normal of the frames' inputs (the largest spp's, first seed's: one
// set of surfaces for every column). Columns missing a frame (a failed cell) are left out, with a
// warning naming the frame.
std::vector<SequenceRecord> score_sequence(const ResultsDocument& doc, const std::string& out_dir, const std::string& name,
                                           int frames);

}  // namespace dnb::experiment
