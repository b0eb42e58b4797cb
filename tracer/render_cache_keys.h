// The cache keys of the tracer's render products (tracer/render_cache.h): each names every part that
// determines the product's bits, so that a cached product is only used where a render would
// give the same one. Changing a key's parts, their names or their order invalidates every
// cached product of its kind.
#pragma once

#include <vector>

#include "tracer/render_cache.h"

namespace dnb {

class Scene;                // tracer/scene.h
struct RenderSettings;      // tracer/render.h
struct ReferenceSettings;   // tracer/reference.h

// A converged reference (reference_image, tracer/reference.h): scene content
// (scene_content_hash: the scene file and every file it references), size, spp, seed, max
// depth, block size, tracer version.
CacheKey reference_cache_key(const Scene& scene, const ReferenceSettings& settings);

// The experiment runner's input frames (render_frame; use with cached_frame, tracer/render_cache.h):
// scene content, size, spp, seed, max depth, reflection levels, edge sub-pixels, tracer version.
CacheKey frame_cache_key(const Scene& scene, const RenderSettings& settings);

// The plain path-tracing curve of a run (render_color_prefixes): the colour of one progressive
// render at each of `prefixes` (rising; settings.spp is the last). Scene content, size, the
// largest spp, seed, max depth, the prefixes, tracer version.
CacheKey curve_cache_key(const Scene& scene, const RenderSettings& settings, const std::vector<int>& prefixes);

}  // namespace dnb
