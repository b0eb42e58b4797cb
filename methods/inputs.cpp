#include "methods/inputs.h"

#include <fmt/format.h>

#include "core/errors.h"
#include "tracer/scene_loader.h"

namespace dnb {

MethodInput frame_input(const AovFrame& frame, const Scene* scene) {
  MethodInput in;
  in.frame = &frame;
  in.scene = scene;
  in.sample_budget = frame.meta.spp;
  in.width = frame.width();
  in.height = frame.height();
  in.seed = frame.meta.seed;
  return in;
}

MethodInput scene_input(const Scene& scene, int spp, int width, int height, std::uint64_t seed) {
  MethodInput in;
  in.scene = &scene;
  in.sample_budget = spp;
  in.width = width;
  in.height = height;
  in.seed = seed;
  return in;
}

std::shared_ptr<const Scene> scene_for_method(const MethodInfo& info, const AovFrame& frame,
                                              const std::string& scene_name, const std::string& frame_path) {
  if (info.kind != MethodKind::Renderer) return nullptr;
  const std::string name = scene_name.empty() ? frame.meta.scene : scene_name;
  if (name.empty())
    throw InputError(fmt::format("'{}' names no scene in its metadata: give --scene for method '{}'", frame_path, info.name));
  return load_scene(name);
}

}  // namespace dnb
