#include "experiment/sequences.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "experiment/frame_sources.h"
#include "methods/inputs.h"
#include "tracer/render_cache_keys.h"
#include "tracer/scene_loader.h"

namespace dnb::experiment {

CacheKey sequence_frame_key(const Scene& scene, const RenderSettings& settings) {
  CacheKey key = frame_cache_key(scene, settings);
  key.add("sequence_frame", "motion-1");  // render_sequence_frame: the frame's seed and the motion layer
  return key;
}

AovFrame sequence_input(Cache& cache, const std::string& name, int frame, const RenderSettings& settings, bool use_cache,
                        bool* hit) {
  SceneLoadOptions o;
  o.frame = frame;
  const auto scene = load_scene(name, o);
  const CacheKey key = sequence_frame_key(*scene, settings);
  if (!use_cache) cache.remove(key);
  return cached_frame(
      cache, key,
      [&] {
        std::shared_ptr<const Scene> previous;
        if (frame > 0) {
          o.frame = frame - 1;
          previous = load_scene(name, o);
        }
        return render_sequence_frame(*scene, previous.get(), settings);
      },
      hit);
}

InputFrame::InputFrame(Cache& cache, const Scene& frame_scene, const std::string& name, RenderSettings settings,
                       bool use_cache, int reference_spp)
    : use_cache_(use_cache) {
  const CacheKey key = sequence_frame_key(frame_scene, settings);
  identity_ = {{"input", key.digest()}, {"ref", reference_spp}};
  load_ = [this, &cache, name, t = frame_scene.frame, settings, key](bool* hit) {
    AovFrame f = sequence_input(cache, name, t, settings, use_cache_, hit);
    return std::pair(std::move(f), cache.entry_dir(key) + "/frame.exr");
  };
}

namespace {

// The layers of `frame` that `method` reads: what a temporal method may look at in the previous
// frame (a whole frame at 1024x768 is some 330 MB).
AovFrame reduced(const AovFrame& frame, const Method& method) {
  AovFrame out(frame.width(), frame.height());
  out.meta = frame.meta;
  for (const auto& name : method.read_layers())
    if (frame.has(name)) out.set(name, frame.layer(name));
  if (frame.has(layer::kColor)) out.set(layer::kColor, frame.layer(layer::kColor));
  return out;
}

}  // namespace

MethodResult SequenceRun::step(State& s, int t, const AovFrame& frame, const Scene* scene, std::uint64_t seed, int spp) {
  const SequenceFrame position{fmt::format("{}/{}spp/seed{}", name_, spp, seed), t, frames_,
                               t > 0 && s.previous ? &*s.previous : nullptr};
  MethodInput in = frame_input(frame, scene);
  in.sequence = &position;
  MethodResult r = run_method(*s.method, in);
  s.previous = reduced(frame, *s.method);
  s.next = t + 1;
  return r;
}

MethodResult SequenceRun::run_temporal(const std::string& column, const std::function<std::unique_ptr<Method>()>& create,
                                       int t, const AovFrame& frame, const Scene* scene, const RenderSettings& settings) {
  State& s = states_[{column, settings.spp, settings.seed}];
  if (!s.method || s.next != t) {
    s = State{};
    s.method = create();
    s.method->reset();
    if (t > 0)
      spdlog::info("{}: {} at frame {}: replaying frames 0 .. {} first (its history)", name_, column, t, t - 1);
    for (int k = 0; k < t; ++k) {
      SceneLoadOptions o;
      o.frame = k;
      const auto scene_k = scene ? load_scene(name_, o) : nullptr;
      step(s, k, sequence_input(cache_, name_, k, settings, true), scene_k.get(), settings.seed, settings.spp);
    }
  }
  return step(s, t, frame, scene, settings.seed, settings.spp);
}

}  // namespace dnb::experiment
