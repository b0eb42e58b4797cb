#include "core/aov_frame.h"

#include <algorithm>

#include <fmt/format.h>
#include <fmt/ranges.h>

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

const std::vector<layer::Info>& layer::table() {
  //                                     name               ch  level0 levels halves importable
  static const std::vector<Info> t = {{kColor, 3, true, false, true, true},
                                      {kDirect, 3, true, true, true, true},
                                      {kIndirect, 3, true, true, true, true},
                                      {kAlbedo, 3, true, true, true, true},
                                      {kReflection, 3, true, true, false, true},
                                      {kEmission, 3, true, true, false, true},
                                      {kNormal, 3, true, true, true, true},
                                      {kDepth, 1, true, true, true, true},
                                      {kVariance, 3, true, false, false, true},
                                      {kDirectVariance, 3, true, false, false, true},
                                      {kIndirectVariance, 3, true, false, false, true},
                                      {kEdge, 1, true, false, false, false},
                                      {kSamples, 1, true, false, false, false},
                                      {kTint, 3, false, true, false, false},
                                      {kGlossDirect, 3, true, false, false, true},
                                      {kGlossIndirect, 3, true, false, false, true},
                                      {kGlossColor, 3, true, false, false, true},
                                      {kTransDirect, 3, true, false, false, true},
                                      {kTransIndirect, 3, true, false, false, true},
                                      {kTransColor, 3, true, false, false, true},
                                      {kMotion, 2, true, false, false, false, true}};
  return t;
}

const layer::Info* layer::find(const std::string& name) {
  const auto dot = name.find('.');
  const std::string base = dot == std::string::npos ? name : name.substr(dot + 1);
  const auto it = std::find_if(table().begin(), table().end(), [&](const Info& i) { return base == i.name; });
  if (it == table().end()) return nullptr;
  if (dot == std::string::npos) return it->level0 ? &*it : nullptr;
  const std::string where = name.substr(0, dot);
  if (where == "half0" || where == "half1") return it->halves ? &*it : nullptr;
  for (int k = 1; k <= kMaxLevels; ++k)
    if (where == fmt::format("refl{}", k)) return it->levels ? &*it : nullptr;
  return nullptr;
}

std::string layer::names_help() {
  std::vector<std::string> own, levels, halves;
  for (const Info& i : table()) {
    if (i.level0) own.push_back(i.name);
    if (i.levels) levels.push_back(i.name);
    if (i.halves) halves.push_back(i.name);
  }
  return fmt::format("{}; refl<k>.<name> for k 1..{} and <name> one of {}; half0.<name> and half1.<name> for <name> one "
                     "of {}",
                     fmt::join(own, ", "), kMaxLevels, fmt::join(levels, ", "), fmt::join(halves, ", "));
}

int default_channels(const std::string& name) {
  const std::string base = base_name(name);
  for (const layer::Info& i : layer::table())
    if (base == i.name) return i.channels;
  return 3;
}

std::vector<std::string> channel_names(const std::string& name, int channels) {
  const std::string base = base_name(name);
  std::vector<std::string> suffixes;
  if (base == layer::kNormal && channels == 3) suffixes = {"X", "Y", "Z"};
  else if (base == layer::kDepth && channels == 1) suffixes = {"Z"};
  else if (base == layer::kMotion && channels == 2) suffixes = {"X", "Y"};
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
