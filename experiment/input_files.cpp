#include "experiment/input_files.h"

#include <filesystem>

#include "core/exr_io.h"
#include "core/hash.h"
#include "interop/import.h"

namespace fs = std::filesystem;

namespace dnb::experiment {

AovFrame read_input_frame(const std::string& path, const std::string& format, int spp, const std::string& second) {
  AovFrame first = interop::read_frame_as(path, format, {.spp = spp}, {layer::kColor});
  if (second.empty()) return first;
  AovFrame other = interop::read_frame_as(second, format, {.spp = spp}, {layer::kColor});
  return interop::combine_halves({std::move(first), {}}, {std::move(other), {}}, path, second).frame;
}

std::string frame_file_hash(const std::string& path) {
  const std::string edges = edges_path(path);
  std::string parts = "frame=" + sha256_file(path) + "\n";
  if (fs::exists(edges)) parts += "edges=" + sha256_file(edges) + "\n";
  return sha256_hex(parts);
}

Reference file_reference(const std::string& path, const std::string& format) {
  AovFrame f = read_input_frame(path, format);
  Reference ref;
  ref.color = f.layer(layer::kColor);
  if (f.has(layer::kVariance)) ref.variance = f.layer(layer::kVariance);
  ref.meta = f.meta;
  ref.path = path;
  ref.render_seconds = f.meta.render_seconds;
  return ref;
}

}  // namespace dnb::experiment
