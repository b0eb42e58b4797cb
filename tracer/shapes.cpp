// Tessellation of the procedural shapes (tracer/shapes.h).
#include "tracer/shapes.h"

#include <algorithm>
#include <cmath>
#include <utility>
#include <vector>

namespace dnb::rt {

void build_box(MeshBuilder& b, Vec3 size, const Transform& x, float su, float sv, unsigned mat) {
  Vec3 h = size * 0.5f;
  auto P = [&](float sx, float sy, float sz) { return x.point(Vec3(sx * h.x, sy * h.y, sz * h.z)); };
  // Outward faces, counter-clockwise seen from outside.
  b.quad(P(-1, -1, 1), P(1, -1, 1), P(1, 1, 1), P(-1, 1, 1), su, sv, mat);      // +z
  b.quad(P(1, -1, -1), P(-1, -1, -1), P(-1, 1, -1), P(1, 1, -1), su, sv, mat);  // -z
  b.quad(P(1, -1, 1), P(1, -1, -1), P(1, 1, -1), P(1, 1, 1), su, sv, mat);      // +x
  b.quad(P(-1, -1, -1), P(-1, -1, 1), P(-1, 1, 1), P(-1, 1, -1), su, sv, mat);  // -x
  b.quad(P(-1, 1, 1), P(1, 1, 1), P(1, 1, -1), P(-1, 1, -1), su, sv, mat);      // +y
  b.quad(P(-1, -1, -1), P(1, -1, -1), P(1, -1, 1), P(-1, -1, 1), su, sv, mat);  // -y
}

void build_sphere(MeshBuilder& b, Vec3 c, float r, int seg, const Transform& x, float su, float sv, unsigned mat,
                  bool inward, bool smooth) {
  b.smooth = smooth;
  int rings = std::max(4, seg / 2);
  auto pt = [&](int i, int j, Vec3& p, Vec3& n, float& u, float& v) {
    float th = kPi * i / rings, ph = 2 * kPi * j / seg;
    Vec3 d(std::sin(th) * std::cos(ph), std::cos(th), -std::sin(th) * std::sin(ph));
    p = x.point(c + d * r);
    n = x.normal(inward ? -d : d);
    u = su * float(j) / seg;
    v = sv * (1 - float(i) / rings);
  };
  for (int i = 0; i < rings; ++i)
    for (int j = 0; j < seg; ++j) {
      Vec3 p[4], n[4];
      float u[4], v[4];
      pt(i, j, p[0], n[0], u[0], v[0]);
      pt(i + 1, j, p[1], n[1], u[1], v[1]);
      pt(i + 1, j + 1, p[2], n[2], u[2], v[2]);
      pt(i, j + 1, p[3], n[3], u[3], v[3]);
      // Counter-clockwise from outside (or inside when inward).
      int a = 0, bb = 1, cc = 2, d = 3;
      if (inward) std::swap(bb, d);
      b.tri(p[a], p[bb], p[cc], u[a], v[a], u[bb], v[bb], u[cc], v[cc], mat, n[a], n[bb], n[cc]);
      b.tri(p[a], p[cc], p[d], u[a], v[a], u[cc], v[cc], u[d], v[d], mat, n[a], n[cc], n[d]);
    }
}

void build_cylinder(MeshBuilder& b, Vec3 base, float r, float height, int seg, bool capped, const Transform& x,
                    float su, float sv, unsigned mat) {
  // Side with smooth normals, caps flat: a separate builder would be cleaner, but the normals
  // of a cap are simply its face normal, so they are written explicitly here.
  b.smooth = true;
  for (int j = 0; j < seg; ++j) {
    float a0 = 2 * kPi * j / seg, a1 = 2 * kPi * (j + 1) / seg;
    Vec3 d0(std::cos(a0), 0, -std::sin(a0)), d1(std::cos(a1), 0, -std::sin(a1));
    Vec3 p0 = x.point(base + d0 * r), p1 = x.point(base + d1 * r);
    Vec3 q0 = x.point(base + d0 * r + Vec3(0, height, 0)), q1 = x.point(base + d1 * r + Vec3(0, height, 0));
    Vec3 n0 = x.normal(d0), n1 = x.normal(d1);
    float u0 = su * float(j) / seg, u1 = su * float(j + 1) / seg;
    b.tri(p0, p1, q1, u0, 0, u1, 0, u1, sv, mat, n0, n1, n1);
    b.tri(p0, q1, q0, u0, 0, u1, sv, u0, sv, mat, n0, n1, n0);
    if (capped) {
      Vec3 top = x.point(base + Vec3(0, height, 0)), bot = x.point(base);
      Vec3 nt = x.normal(Vec3(0, 1, 0)), nb = x.normal(Vec3(0, -1, 0));
      b.tri(top, q0, q1, 0.5f, 0.5f, 0.5f + 0.5f * d0.x, 0.5f + 0.5f * d0.z, 0.5f + 0.5f * d1.x,
            0.5f + 0.5f * d1.z, mat, nt, nt, nt);
      b.tri(bot, p1, p0, 0.5f, 0.5f, 0.5f + 0.5f * d1.x, 0.5f + 0.5f * d1.z, 0.5f + 0.5f * d0.x,
            0.5f + 0.5f * d0.z, mat, nb, nb, nb);
    }
  }
}

// The arch's angles include the two corners of the rectangle, so that every outer face is flat.
void build_arch(MeshBuilder& b, float r, float height, float depth, int seg, const Transform& x, float su, float sv,
                unsigned mat) {
  std::vector<float> angles;
  for (int i = 0; i <= seg; ++i) angles.push_back(kPi * i / seg);
  const float corner = std::atan2(height, r);
  angles.push_back(corner);
  angles.push_back(kPi - corner);
  std::sort(angles.begin(), angles.end());
  const float hz = depth / 2, w = 2 * r;
  auto outer = [&](float a) {
    float c = std::cos(a), s = std::sin(a);
    float t = 1e30f;
    if (std::fabs(c) > 1e-6f) t = std::min(t, r / std::fabs(c));
    if (s > 1e-6f) t = std::min(t, height / s);
    return Vec3(t * c, t * s, 0);
  };
  auto P = [&](Vec3 p, float z) { return x.point(Vec3(p.x, p.y, z)); };
  auto U = [&](Vec3 p) { return su * (p.x / w + 0.5f); };
  auto V = [&](Vec3 p) { return sv * (p.y / height); };
  for (std::size_t i = 0; i + 1 < angles.size(); ++i) {
    float a0 = angles[i], a1 = angles[i + 1];
    if (a1 - a0 < 1e-6f) continue;
    Vec3 c0(r * std::cos(a0), r * std::sin(a0), 0), c1(r * std::cos(a1), r * std::sin(a1), 0);
    Vec3 o0 = outer(a0), o1 = outer(a1);
    // Front and back faces, texture coordinates following the wall's x, y.
    const Vec3 f[4] = {c0, o0, o1, c1}, k[4] = {c1, o1, o0, c0};
    const Vec3 pf[4] = {P(f[0], hz), P(f[1], hz), P(f[2], hz), P(f[3], hz)};
    const Vec3 pk[4] = {P(k[0], -hz), P(k[1], -hz), P(k[2], -hz), P(k[3], -hz)};
    const float uf[8] = {U(f[0]), V(f[0]), U(f[1]), V(f[1]), U(f[2]), V(f[2]), U(f[3]), V(f[3])};
    const float uk[8] = {U(k[0]), V(k[0]), U(k[1]), V(k[1]), U(k[2]), V(k[2]), U(k[3]), V(k[3])};
    b.quad_uv(pf, uf, mat);
    b.quad_uv(pk, uk, mat);
    float l = r * (a1 - a0);
    b.quad(P(c1, hz), P(c1, -hz), P(c0, -hz), P(c0, hz), su * depth / w, sv * l / height, mat);
  }
  Vec3 tl(-r, height, 0), tr(r, height, 0);
  b.quad(P(tr, hz), P(tr, -hz), P(tl, -hz), P(tl, hz), su, sv * depth / height, mat);
}

void repeat_mesh(Mesh& mesh, int copies, Vec3 step) {
  if (copies <= 1) return;
  Mesh one = mesh;
  for (int k = 1; k < copies; ++k) {
    for (const Vec3& p : one.positions) mesh.positions.push_back(p + step * float(k));
    mesh.normals.insert(mesh.normals.end(), one.normals.begin(), one.normals.end());
    mesh.uvs.insert(mesh.uvs.end(), one.uvs.begin(), one.uvs.end());
    mesh.material.insert(mesh.material.end(), one.material.begin(), one.material.end());
  }
}

int motion_steps(const Transform& start, const Transform& end) {
  const Vec3 dr = end.rot_deg - start.rot_deg;
  const float turn = std::max(std::fabs(dr.x), std::max(std::fabs(dr.y), std::fabs(dr.z)));
  // A chord of a 5-degree arc is within 0.1% of the radius of the arc (1 - cos 2.5 degrees).
  return 1 + int(std::clamp(std::ceil(turn / 5.0f), 1.0f, 128.0f));
}

void add_motion(Mesh& mesh, const Transform& start, const Transform& end) {
  const int steps = motion_steps(start, end);
  mesh.later_positions.assign(std::size_t(steps - 1), {});
  mesh.later_normals.assign(mesh.normals.empty() ? 0 : std::size_t(steps - 1), {});
  for (int k = 1; k < steps; ++k) {
    const Transform x = start.towards(end, float(k) / float(steps - 1));
    auto& pos = mesh.later_positions[std::size_t(k - 1)];
    pos.reserve(mesh.positions.size());
    for (const Vec3& p : mesh.positions) pos.push_back(x.point(start.unpoint(p)));
    if (mesh.normals.empty()) continue;
    auto& nrm = mesh.later_normals[std::size_t(k - 1)];
    nrm.reserve(mesh.normals.size());
    for (const Vec3& n : mesh.normals) nrm.push_back(x.normal(start.unrotate(n)));
  }
}

}  // namespace dnb::rt
