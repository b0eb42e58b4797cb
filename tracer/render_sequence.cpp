// Frames of animated sequences (docs/sequences.md): the frame's seed and the motion layer.
#include <fmt/format.h>

#include "core/errors.h"
#include "tracer/animation.h"
#include "tracer/render.h"
#include "tracer/render_internal.h"
#include "tracer/scene.h"

namespace dnb {
using namespace rt;
using render_pass::for_each_tile;

namespace {

// Where a motion layer points for a surface the previous camera cannot see at all (behind it):
// far outside any image, so that every reprojection finds no history there (a disocclusion)
// instead of taking it for a point at rest.
constexpr float kNoPrevious = -1e6f;

void check_same_geometry(const Scene& current, const Scene& previous) {
  if (previous.meshes.size() != current.meshes.size())
    throw WorkError(fmt::format("motion layer of '{}' frame {}: the previous frame has {} meshes, this one {}", current.name,
                                current.frame, previous.meshes.size(), current.meshes.size()));
  for (std::size_t i = 0; i < current.meshes.size(); ++i)
    if (previous.meshes[i].triangles() != current.meshes[i].triangles())
      throw WorkError(fmt::format("motion layer of '{}' frame {}: mesh '{}' has {} triangles there and {} here", current.name,
                                  current.frame, current.meshes[i].name, previous.meshes[i].triangles(),
                                  current.meshes[i].triangles()));
}

// The barycentric coordinates (b1, b2) of point p in triangle (c0, c1, c2): p = c0 + b1 (c1 - c0)
// + b2 (c2 - c0), solved in the triangle's plane. Computed here, from the hit point, rather than
// carried in every SurfaceHit of the render's hot path for this one use.
void barycentrics(const Vec3* c, Vec3 p, float& b1, float& b2) {
  const Vec3 e1 = c[1] - c[0], e2 = c[2] - c[0], d = p - c[0];
  const float d11 = dot(e1, e1), d12 = dot(e1, e2), d22 = dot(e2, e2), dp1 = dot(d, e1), dp2 = dot(d, e2);
  const float det = d11 * d22 - d12 * d12;
  b1 = det != 0 ? (d22 * dp1 - d12 * dp2) / det : 0.0f;
  b2 = det != 0 ? (d11 * dp2 - d12 * dp1) / det : 0.0f;
}

}  // namespace

Image motion_layer(const Scene& current, const Scene& previous, int width, int height, int threads) {
  check_same_geometry(current, previous);
  Image out(width, height, 2);
  for_each_tile(width, height, threads, [&](int x0, int y0, int x1, int y1) {
    for (int y = y0; y < y1; ++y)
      for (int x = x0; x < x1; ++x) {
        const float cx = float(x) + 0.5f, cy = float(y) + 0.5f;
        // The pinhole ray at the frame's instant (time 0 of its interval: where its keys put it).
        const Ray ray = current.camera.generate_ray_at(cx, cy, width, height, 0.5f, 0.5f, 0.0f);
        SurfaceHit hit;
        float qx = kNoPrevious, qy = kNoPrevious;
        bool seen;
        if (current.intersect(ray, hit)) {
          // The same point of the same triangle in the previous frame's geometry (step 0: its
          // instant), then through the previous camera.
          const std::size_t corner = 3 * std::size_t(hit.prim);
          float b1, b2;
          barycentrics(&current.meshes[hit.geom].positions[corner], hit.p, b1, b2);
          const Vec3* c = &previous.meshes[hit.geom].positions[corner];
          const Vec3 p = c[0] * (1.0f - b1 - b2) + c[1] * b1 + c[2] * b2;
          seen = previous.camera.project(p, width, height, qx, qy);
        } else {
          seen = previous.camera.project_direction(ray.dir, width, height, qx, qy);
        }
        out.at(x, y, 0) = seen ? qx - cx : kNoPrevious;
        out.at(x, y, 1) = seen ? qy - cy : kNoPrevious;
      }
  });
  return out;
}

AovFrame render_sequence_frame(const Scene& scene, const Scene* previous, const RenderSettings& settings) {
  RenderSettings s = settings;
  s.seed = frame_seed(settings.seed, scene.frame);
  AovFrame frame = render_frame(scene, s);
  // Thin lens or not, the motion layer is the pinhole's: it says where each pixel's surface was.
  frame.set(layer::kMotion, previous ? motion_layer(scene, *previous, s.width, s.height, s.threads)
                                     : Image(s.width, s.height, 2));
  frame.meta.extra["frame"] = std::to_string(scene.frame);
  frame.meta.extra["frames"] = std::to_string(scene.frames);
  frame.meta.extra["sequence_seed"] = std::to_string(settings.seed);
  return frame;
}

}  // namespace dnb
