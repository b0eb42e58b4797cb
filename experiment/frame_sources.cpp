#include "experiment/frame_sources.h"

#include <algorithm>
#include <tuple>

#include <fmt/format.h>

#include "core/errors.h"
#include "core/exr_io.h"
#include "tracer/render_cache_keys.h"

namespace dnb::experiment {

RenderSettings input_settings(const ExperimentConfig& c, int spp, std::uint64_t seed) {
  RenderSettings s;
  std::tie(s.width, s.height, s.spp, s.seed, s.threads, s.max_depth) =
      std::tuple(c.width, c.height, spp, seed, c.threads, c.max_depth);
  return s;
}

void PlainCurve::load() {
  const RenderSettings settings = input_settings(config_, rendered_spp(), config_.seed);
  const CacheKey key = curve_cache_key(*scene_, settings, prefixes_);
  if (!use_cache_) cache_.remove(key);
  if (auto entry = cache_.lookup(key)) {
    for (int spp : prefixes_) {
      const std::string path = entry->file(point_file(spp));
      const auto attrs = read_rgb_attributes(path);
      const auto it = attrs.find("render_seconds");
      if (it == attrs.end()) throw InputError(fmt::format("'{}': no attribute 'render_seconds'", path));
      points_[spp] = {read_rgb(path), std::stod(it->second)};
    }
    hit_ = true;
    return;
  }
  render_color_prefixes(*scene_, settings, prefixes_, [&](std::size_t k, Image image, double seconds) {
    points_[prefixes_[k]] = {std::move(image), seconds};
  });
  hit_ = false;
  cache_.store(key, [&](const std::string& dir) {
    for (const auto& [spp, point] : points_)
      write_rgb(point.first, dir + "/" + point_file(spp), {{"render_seconds", fmt::format("{}", point.second)}});
  });
}

}  // namespace dnb::experiment
