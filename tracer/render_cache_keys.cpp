// The cache keys of references and input frames (tracer/render_cache_keys.h). Both start with the
// parts of a render that every product shares, in one order, and end with the tracer version.
#include "tracer/render_cache_keys.h"

#include "tracer/reference.h"
#include "tracer/render.h"
#include "tracer/scene.h"
#include "tracer/scene_loader.h"

namespace dnb {

namespace {

// scene, width, height, spp, seed, max_depth: the first parts of every render product's key.
CacheKey render_key(const char* kind, const Scene& scene, int width, int height, int spp, std::uint64_t seed,
                    int max_depth) {
  CacheKey key(kind);
  key.add("scene", scene_content_hash(scene))
      .add("width", width)
      .add("height", height)
      .add("spp", spp)
      .add("seed", seed)
      .add("max_depth", max_depth);
  // Only the images of scenes with a sun changed (kSunVersion): the others stay cached.
  if (scene.sun.enabled) key.add("sun", kSunVersion);
  return key;
}

}  // namespace

CacheKey reference_cache_key(const Scene& scene, const ReferenceSettings& s) {
  CacheKey key = render_key("reference", scene, s.width, s.height, s.spp, s.seed, s.max_depth);
  // The block size fixes the order of the floating-point additions, hence the exact bits.
  key.add("block_spp", s.block_spp).add("tracer", kTracerVersion);
  return key;
}

CacheKey frame_cache_key(const Scene& scene, const RenderSettings& s) {
  CacheKey key = render_key("frame", scene, s.width, s.height, s.spp, s.seed, s.max_depth);
  key.add("reflection_levels", s.reflection_levels)
      .add("edge_subpixels", s.edge_subpixels ? 1 : 0)
      .add("tracer", kTracerVersion)
      .add("layers", kFrameLayers);
  return key;
}

CacheKey curve_cache_key(const Scene& scene, const RenderSettings& s, const std::vector<int>& prefixes) {
  CacheKey key = render_key("curve", scene, s.width, s.height, s.spp, s.seed, s.max_depth);
  std::string list;
  for (int p : prefixes) {
    if (!list.empty()) list += ',';
    list += std::to_string(p);
  }
  key.add("prefixes", list).add("tracer", kTracerVersion);
  return key;
}

}  // namespace dnb
