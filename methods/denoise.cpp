#include "methods/denoise.h"

#include <memory>

#include <fmt/format.h>
#include <tbb/global_control.h>

#include "core/atomic_file.h"
#include "core/errors.h"
#include "core/exr_io.h"
#include "core/build_info.h"
#include "interop/import.h"
#include "methods/inputs.h"
#include "tracer/scene.h"

namespace dnb {

DenoiseOutcome denoise_file(const DenoiseRequest& q) {
  const MethodRegistry& registry = MethodRegistry::global();
  std::unique_ptr<Method> method = registry.create(q.method, q.settings);
  DenoiseOutcome out{registry.parse_params(q.method, q.settings), {}, 0, 0};
  std::unique_ptr<tbb::global_control> limit;
  if (q.threads > 0) limit = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, q.threads);

  require_output_is_not_input(q.output, {{"frame", q.frame}, {"frame's edge file", edges_path(q.frame)}});
  // Only the layers the method reads (FilterInvariants.ReadsNoLayerItDoesNotDeclare holds every
  // method to its lists): a 1920x1080 frame holds 109 channels, 0.9 GB, most of which a filter
  // never looks at.
  AovFrame frame = interop::read_frame_as(q.frame, q.input_format, {.layers = method->read_layers()});
  if (const auto missing = frame.missing_channels(method->required_layers()); !missing.empty()) {
    std::vector<std::string> layers;
    for (const auto& l : method->required_layers())
      if (!frame.has(l)) layers.push_back(l);
    // Which methods could run: from every layer of the frame (read again, on this error only).
    const auto can = methods_for_frame(interop::read_frame_as(q.frame, q.input_format));
    throw InputError(fmt::format("'{}': {} needs layer{} {} (channels {}), which the frame lacks; methods that can run on "
                                 "it: {}",
                                 q.frame, q.method, layers.size() > 1 ? "s" : "", fmt::join(layers, ", "),
                                 fmt::join(missing, ", "), can.empty() ? std::string("none") : fmt::format("{}", fmt::join(can, ", "))));
  }
  const auto scene = scene_for_method(registry.info(q.method), frame, q.scene, q.frame);
  try {
    out.result = run_method(*method, frame_input(frame, scene.get()));
  } catch (const InputError& e) {
    throw InputError(fmt::format("'{}': {}", q.frame, e.what()));
  }
  std::vector<std::pair<std::string, std::string>> attrs = {
      {"method", q.method}, {"source_frame", q.frame}, {"build_version", build_version_and_revision()}};
  for (const auto& [k, v] : out.params.as_strings()) attrs.emplace_back("param." + k, v);
  write_rgb(out.result.image, q.output, attrs);
  out.width = frame.width();
  out.height = frame.height();
  return out;
}

std::vector<std::string> methods_for_frame(const AovFrame& frame) {
  std::vector<std::string> out;
  const MethodRegistry& registry = MethodRegistry::global();
  for (const MethodInfo* info : registry.all()) {
    if (info->kind == MethodKind::Renderer && frame.meta.scene.empty()) continue;
    try {
      if (frame.missing_channels(registry.create(info->name)->required_layers()).empty()) out.push_back(info->name);
    } catch (const std::exception&) {
      // a method that cannot be created at its defaults here cannot run on the frame either
    }
  }
  return out;
}

}  // namespace dnb
