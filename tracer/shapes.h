// Procedural shapes of scene files, tessellated into triangle meshes: the affine Transform of
// an object, a MeshBuilder that appends triangles and quads with texture coordinates, and the
// box, sphere, cylinder and arch of [[objects]] / [[lights]] (configs/scenes/README.md), plus
// the `repeat` copies of a mesh. Nothing here reads a scene file: tracer/scene_loader.cpp reads
// and checks the keys, then calls these.
//
// Conventions (tracer/scene.h): faces wind counter-clockwise seen from their front (outside,
// or inside for an inward sphere); uv of every face spans [0, su] x [0, sv] (`uv_scale`).
#pragma once

#include <cmath>
#include <vector>

#include "tracer/math.h"
#include "tracer/scene.h"

namespace dnb::rt {

// An affine transform: scale (uniform), then rotations about x, y, z (degrees), then translate.
struct Transform {
  float scale = 1;
  Vec3 rot_deg;
  Vec3 translate;
  Vec3 rotate(Vec3 v) const {
    auto rx = rot_deg.x * kPi / 180, ry = rot_deg.y * kPi / 180, rz = rot_deg.z * kPi / 180;
    v = {v.x, v.y * std::cos(rx) - v.z * std::sin(rx), v.y * std::sin(rx) + v.z * std::cos(rx)};
    v = {v.x * std::cos(ry) + v.z * std::sin(ry), v.y, -v.x * std::sin(ry) + v.z * std::cos(ry)};
    v = {v.x * std::cos(rz) - v.y * std::sin(rz), v.x * std::sin(rz) + v.y * std::cos(rz), v.z};
    return v;
  }
  Vec3 point(Vec3 p) const { return rotate(p * scale) + translate; }
  Vec3 normal(Vec3 n) const { return normalize(rotate(n)); }
  // The inverses: rotations about z, then y, then x by minus the angles; point() undone.
  Vec3 unrotate(Vec3 v) const {
    auto rx = -rot_deg.x * kPi / 180, ry = -rot_deg.y * kPi / 180, rz = -rot_deg.z * kPi / 180;
    v = {v.x * std::cos(rz) - v.y * std::sin(rz), v.x * std::sin(rz) + v.y * std::cos(rz), v.z};
    v = {v.x * std::cos(ry) + v.z * std::sin(ry), v.y, -v.x * std::sin(ry) + v.z * std::cos(ry)};
    v = {v.x, v.y * std::cos(rx) - v.z * std::sin(rx), v.y * std::sin(rx) + v.z * std::cos(rx)};
    return v;
  }
  Vec3 unpoint(Vec3 p) const { return unrotate(p - translate) * (1.0f / scale); }
  // The transform a fraction t of the way from this one to `end` (each part linearly).
  Transform towards(const Transform& end, float t) const {
    Transform x;
    x.scale = scale + (end.scale - scale) * t;
    x.rot_deg = rot_deg + (end.rot_deg - rot_deg) * t;
    x.translate = translate + (end.translate - translate) * t;
    return x;
  }
};

// Motion blur of a mesh built with transform `start`: its later time steps (Mesh::later_positions
// and later_normals) for an object whose transform goes linearly from `start` at time 0 to `end`
// at time 1. Enough steps that Embree's linear interpolation between them stays within a degree
// of the true rotation (one step per 5 degrees of the largest angle change, at least one).
void add_motion(Mesh& mesh, const Transform& start, const Transform& end);
// The number of time steps add_motion gives a motion from `start` to `end` (2 to 129).
int motion_steps(const Transform& start, const Transform& end);

// Builds meshes of primitives. uv of every face spans [0, uv_scale].
struct MeshBuilder {
  Mesh mesh;
  bool smooth = false;
  void tri(Vec3 a, Vec3 b, Vec3 c, float ua, float va, float ub, float vb, float uc, float vc, unsigned mat,
           Vec3 na = {}, Vec3 nb = {}, Vec3 nc = {}) {
    if (!(length(cross(b - a, c - a)) > 0)) return;  // degenerate (sphere poles)
    mesh.positions.insert(mesh.positions.end(), {a, b, c});
    mesh.uvs.insert(mesh.uvs.end(), {ua, va, ub, vb, uc, vc});
    mesh.material.push_back(mat);
    if (smooth) mesh.normals.insert(mesh.normals.end(), {na, nb, nc});
  }
  // Quad p0 p1 p2 p3 (counter-clockwise seen from the front), uv (0,0) (1,0) (1,1) (0,1).
  void quad(Vec3 p0, Vec3 p1, Vec3 p2, Vec3 p3, float su, float sv, unsigned mat) {
    tri(p0, p1, p2, 0, 0, su, 0, su, sv, mat);
    tri(p0, p2, p3, 0, 0, su, sv, 0, sv, mat);
  }
  // Quad with explicit texture coordinates per corner.
  void quad_uv(const Vec3 (&p)[4], const float (&uv)[8], unsigned mat) {
    tri(p[0], p[1], p[2], uv[0], uv[1], uv[2], uv[3], uv[4], uv[5], mat);
    tri(p[0], p[2], p[3], uv[0], uv[1], uv[4], uv[5], uv[6], uv[7], mat);
  }
};

// The six outward faces of a box of `size` centred at the origin, transformed.
void build_box(MeshBuilder& b, Vec3 size, const Transform& x, float su, float sv, unsigned mat);
// A UV sphere of `seg` segments and seg / 2 (at least 4) rings about c; inward: faces and
// normals point inside (a sky dome, a room); smooth: interpolated shading normals.
void build_sphere(MeshBuilder& b, Vec3 c, float r, int seg, const Transform& x, float su, float sv, unsigned mat,
                  bool inward, bool smooth);
// A cylinder of radius r standing on `base`, height along +y, smooth side, flat caps if capped.
void build_cylinder(MeshBuilder& b, Vec3 base, float r, float height, int seg, bool capped, const Transform& x,
                    float su, float sv, unsigned mat);
// An arch: the wall piece between a rectangle [-r, r] x [0, height] and the semicircle of
// radius r about the origin (the opening), extruded over z in [-depth/2, depth/2]. Front, back,
// intrados (the curved underside) and top faces; the sides meet the columns.
void build_arch(MeshBuilder& b, float r, float height, float depth, int seg, const Transform& x, float su, float sv,
                unsigned mat);
// Appends copies 1 .. copies - 1 of the mesh's triangles, copy k moved by k * step (`repeat`).
void repeat_mesh(Mesh& mesh, int copies, Vec3 step);

}  // namespace dnb::rt
