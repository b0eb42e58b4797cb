#include "experiment/sequences.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <cmath>

#include "core/exr_io.h"
#include "experiment/frame_sources.h"
#include "metrics/temporal.h"
#include "methods/inputs.h"
#include "tracer/render_cache_keys.h"
#include "tracer/scene_loader.h"

namespace dnb::experiment {

CacheKey sequence_frame_key(const Scene& scene, const RenderSettings& settings) {
  CacheKey key = frame_cache_key(scene, settings);
  key.add("sequence_frame", "motion-1");  // render_sequence_frame: the frame's seed and the motion layer
  return key;
}

AovFrame sequence_input(Cache& cache, const Scene& scene, const std::string& name, const RenderSettings& settings,
                        bool use_cache, bool* hit) {
  const CacheKey key = sequence_frame_key(scene, settings);
  if (!use_cache) cache.remove(key);
  return cached_frame(
      cache, key,
      [&] {
        // The previous frame's geometry and camera, for the motion layer: loaded only to render.
        std::shared_ptr<const Scene> previous;
        if (scene.frame > 0) {
          SceneLoadOptions o;
          o.frame = scene.frame - 1;
          previous = load_scene(name, o);
        }
        return render_sequence_frame(scene, previous.get(), settings);
      },
      hit);
}

InputFrame::InputFrame(Cache& cache, const Scene& frame_scene, const std::string& name, RenderSettings settings,
                       bool use_cache, int reference_spp)
    : use_cache_(use_cache) {
  const CacheKey key = sequence_frame_key(frame_scene, settings);
  identity_ = {{"input", key.digest()}, {"ref", reference_spp}};
  load_ = [this, &cache, &frame_scene, name, settings, key](bool* hit) {
    AovFrame f = sequence_input(cache, frame_scene, name, settings, use_cache_, hit);
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
      const auto scene_k = load_scene(name_, o);
      // A renderer-type method gets the frame's scene, as in the run (`scene` set), a filter none.
      step(s, k, sequence_input(cache_, *scene_k, name_, settings, true), scene ? scene_k.get() : nullptr, settings.seed,
           settings.spp);
    }
  }
  return step(s, t, frame, scene, settings.seed, settings.spp);
}

}  // namespace dnb::experiment

namespace dnb::experiment {

namespace {

// The input record of row `row` whose frame gives the sequence's surfaces: the largest spp, then
// the first seed.
const CellRecord* surfaces_record(const ResultsDocument& doc, const std::string& row) {
  const CellRecord* best = nullptr;
  for (const auto& r : doc.records) {
    if (r.scene != row || r.role != Role::Input || r.file("frame").empty()) continue;
    if (!best || r.spp > best->spp || (r.spp == best->spp && r.seed.value_or(0) < best->seed.value_or(0))) best = &r;
  }
  return best;
}

struct Surfaces {
  Image motion, depth, normal;
};

}  // namespace

std::vector<SequenceRecord> score_sequence(const ResultsDocument& doc, const std::string& out_dir, const std::string& name,
                                           int frames) {
  // The columns of frame 0, in record order.
  std::vector<const CellRecord*> firsts;
  const std::string row0 = sequence_row(name, 0);
  for (const auto& r : doc.records)
    if (r.scene == row0 && r.role != Role::Plain) firsts.push_back(&r);
  // Every frame's surfaces and reference, read once.
  std::vector<Surfaces> surfaces(static_cast<std::size_t>(frames));
  std::vector<Image> references(static_cast<std::size_t>(frames));
  for (int t = 0; t < frames; ++t) {
    const std::string row = sequence_row(name, t);
    const CellRecord* in = surfaces_record(doc, row);
    if (!in) {
      spdlog::warn("{}: no input frame of {} in the results: the sequence is not scored", name, row);
      return {};
    }
    const AovFrame f = read_frame(out_dir + "/" + in->file("frame"), {layer::kMotion, layer::kDepth, layer::kNormal},
                                  std::vector<std::string>{layer::kMotion, layer::kDepth, layer::kNormal});
    surfaces[std::size_t(t)] = {f.layer(layer::kMotion), f.layer(layer::kDepth), f.layer(layer::kNormal)};
    references[std::size_t(t)] = read_rgb(out_dir + "/" + in->reference.image);
  }
  std::vector<SequenceRecord> out;
  for (const CellRecord* first : firsts) {
    // This column's record on every frame.
    std::vector<const CellRecord*> per_frame;
    for (int t = 0; t < frames; ++t) {
      const CellRecord* found = nullptr;
      for (const CellRecord* r : doc.find_all(sequence_row(name, t), first->method, first->spp))
        if (r->seed == first->seed) found = r;
      if (!found) {
        spdlog::warn("{}: '{}' at {} spp has no record of frame {}: its sequence scores are left out", name, first->method,
                     first->spp, t);
        break;
      }
      per_frame.push_back(found);
    }
    if (int(per_frame.size()) != frames) continue;
    SequenceRecord s;
    s.sequence = name;
    s.method = first->method;
    s.role = first->role;
    s.spp = first->spp;
    s.seed = first->seed;
    s.frames = frames;
    metrics::TemporalScorer scorer;
    std::map<std::string, std::pair<double, int>> sums;  // still metric -> (sum, frames with a value)
    for (int t = 0; t < frames; ++t) {
      const CellRecord& r = *per_frame[std::size_t(t)];
      s.images.push_back(r.image());
      for (const auto& [metric, value] : r.metrics)
        if (value && std::isfinite(*value)) {
          sums[metric].first += *value;
          sums[metric].second += 1;
        }
      s.per_frame["mse"].push_back(r.metric("mse"));
      const Image output = read_rgb(out_dir + "/" + r.image());
      const Surfaces& g = surfaces[std::size_t(t)];
      scorer.add({&output, &references[std::size_t(t)], &g.motion, &g.depth, &g.normal});
    }
    for (const auto& [metric, sn] : sums)
      if (sn.second == frames) s.metrics[metric] = sn.first / frames;  // a mean over every frame, or none
    const metrics::TemporalScores ts = scorer.scores();
    s.metrics["tmse"] = std::isfinite(ts.tmse) ? std::optional<double>(ts.tmse) : std::nullopt;
    s.metrics["disocclusion_mse"] =
        std::isfinite(ts.disocclusion_mse) ? std::optional<double>(ts.disocclusion_mse) : std::nullopt;
    auto finite = [](double v) { return std::isfinite(v) ? std::optional<double>(v) : std::nullopt; };
    for (double v : ts.tmse_per_frame) s.per_frame["tmse"].push_back(finite(v));
    for (double v : ts.disocclusion_mse_per_frame) s.per_frame["disocclusion_mse"].push_back(finite(v));
    out.push_back(std::move(s));
  }
  return out;
}

}  // namespace dnb::experiment
