#include "core/aov_frame.h"

#include <fmt/format.h>

#include "core/errors.h"

namespace dnb {

std::string layer::at_level(int level, const std::string& base) {
  return level == 0 ? base : fmt::format("refl{}.{}", level, base);
}

std::string layer::at_half(int half, const std::string& base) { return fmt::format("half{}.{}", half, base); }

static std::string base_name(const std::string& layer) {
  auto dot = layer.rfind('.');
  return dot == std::string::npos ? layer : layer.substr(dot + 1);
}

int default_channels(const std::string& name) {
  const std::string base = base_name(name);
  return (base == layer::kDepth || base == layer::kEdge || base == layer::kSamples) ? 1 : 3;
}

std::vector<std::string> channel_names(const std::string& name, int channels) {
  const std::string base = base_name(name);
  std::vector<std::string> suffixes;
  if (base == layer::kNormal && channels == 3) suffixes = {"X", "Y", "Z"};
  else if (base == layer::kDepth && channels == 1) suffixes = {"Z"};
  else if (channels == 3) suffixes = {"R", "G", "B"};
  else if (channels == 1) suffixes = {"Y"};
  else
    for (int c = 0; c < channels; ++c) suffixes.push_back(fmt::format("c{}", c));
  std::vector<std::string> out;
  for (auto& s : suffixes) out.push_back(name == layer::kColor ? s : name + "." + s);
  return out;
}

const Image& AovFrame::layer(const std::string& name) const {
  auto it = layers_.find(name);
  if (it == layers_.end())
    throw InputError(fmt::format("frame has no layer '{}' (channels {})", name,
                                 fmt::join(channel_names(name, default_channels(name)), ",")));
  return it->second;
}

Image& AovFrame::layer(const std::string& name) {
  return const_cast<Image&>(static_cast<const AovFrame&>(*this).layer(name));
}

Image& AovFrame::add(const std::string& name, int channels) {
  Image& img = layers_[name];
  img = Image(width_, height_, channels);
  return img;
}

void AovFrame::set(const std::string& name, Image image) {
  if (image.width() != width_ || image.height() != height_)
    throw WorkError(fmt::format("layer '{}' is {}x{}, frame is {}x{}", name, image.width(),
                                image.height(), width_, height_));
  layers_[name] = std::move(image);
}

std::vector<std::string> AovFrame::missing_channels(const std::vector<std::string>& names) const {
  std::vector<std::string> missing;
  for (const auto& n : names) {
    if (has(n)) continue;
    for (auto& c : channel_names(n, default_channels(n))) missing.push_back(c);
  }
  return missing;
}

}  // namespace dnb
