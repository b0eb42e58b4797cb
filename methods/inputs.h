// How the harness hands a frame (or a scene) to a method: the one place that fills a
// MethodInput, for `denoise`, the experiment runner and the benchmarks alike.
#pragma once

#include <cstdint>
#include <memory>
#include <string>

#include "denoisers/method.h"

namespace dnb {

class Scene;

// A method's input for one AOV frame: the frame and its seed; for renderer-type methods also
// the scene, the frame's spp as the sample budget and its size (filters ignore those).
MethodInput frame_input(const AovFrame& frame, const Scene* scene = nullptr);
// A renderer-type method's input without a frame: the scene, the spp budget, the image size.
MethodInput scene_input(const Scene& scene, int spp, int width, int height, std::uint64_t seed = 1);

// The scene a renderer-type method renders for `frame`: `scene_name` when given, else the one
// the frame's metadata names (InputError naming `frame_path` when there is none). nullptr for
// filters, which need no scene.
std::shared_ptr<const Scene> scene_for_method(const MethodInfo& info, const AovFrame& frame,
                                              const std::string& scene_name, const std::string& frame_path);

}  // namespace dnb
