#include "tracer/bsdf.h"

#include <cstring>

namespace dnb::rt {

float fresnel_dielectric(float cos_i, float eta, float* cos_t) {
  cos_i = std::clamp(cos_i, 0.0f, 1.0f);
  const float sin2_t = (1.0f - cos_i * cos_i) / (eta * eta);
  if (sin2_t >= 1.0f) {
    if (cos_t) *cos_t = 0.0f;
    return 1.0f;
  }
  const float ct = std::sqrt(1.0f - sin2_t);
  if (cos_t) *cos_t = ct;
  const float rs = (cos_i - eta * ct) / (cos_i + eta * ct);
  const float rp = (eta * cos_i - ct) / (eta * cos_i + ct);
  return 0.5f * (rs * rs + rp * rp);
}

Vec3 fresnel_conductor(float cos_i, Vec3 eta, Vec3 k) {
  // The exact unpolarised reflectance of a conductor (Born and Wolf's expressions for
  // the s and p components in terms of a^2 + b^2 = |(eta + ik)^2 - sin^2|).
  cos_i = std::clamp(cos_i, 0.0f, 1.0f);
  const float c2 = cos_i * cos_i, s2 = 1.0f - c2;
  Vec3 out;
  for (int ch = 0; ch < 3; ++ch) {
    const float e2 = eta[ch] * eta[ch], k2 = k[ch] * k[ch];
    const float t0 = e2 - k2 - s2;
    const float a2b2 = std::sqrt(std::max(0.0f, t0 * t0 + 4.0f * e2 * k2));
    const float a = std::sqrt(std::max(0.0f, 0.5f * (a2b2 + t0)));
    const float t1 = a2b2 + c2, t2 = 2.0f * cos_i * a;
    const float rs = (t1 - t2) / (t1 + t2);
    const float t3 = c2 * a2b2 + s2 * s2, t4 = t2 * s2;
    const float rp = rs * (t3 - t4) / (t3 + t4);
    out[ch] = std::clamp(0.5f * (rs + rp), 0.0f, 1.0f);
  }
  return out;
}

float fresnel_diffuse_reflectance(float eta) {
  // 2 int_0^1 F(c) c dc by the midpoint rule on 1024 intervals: F is smooth except at the
  // critical angle (eta < 1), where the rule's error is below 1e-4 at this count.
  constexpr int n = 1024;
  double sum = 0;
  for (int i = 0; i < n; ++i) {
    const float c = (float(i) + 0.5f) / n;
    sum += double(fresnel_dielectric(c, eta)) * c;
  }
  return float(2.0 * sum / n);
}

float Ggx::D(Vec3 m) const {
  if (m.z <= 0) return 0.0f;
  const float x = m.x / ax, y = m.y / ay;
  const float d = x * x + y * y + m.z * m.z;
  return 1.0f / (kPi * ax * ay * d * d);
}

float Ggx::lambda(Vec3 w) const {
  const float z2 = w.z * w.z;
  if (z2 <= 0) return 1e30f;
  const float t = (ax * ax * w.x * w.x + ay * ay * w.y * w.y) / z2;
  return 0.5f * (std::sqrt(1.0f + t) - 1.0f);
}

Vec3 Ggx::sample_visible(Vec3 wo, float u1, float u2) const {
  // Heitz 2018: stretch wo to the unit-roughness configuration, sample the projected
  // hemisphere there, unstretch.
  const Vec3 vh = normalize(Vec3(ax * wo.x, ay * wo.y, wo.z));
  const float len2 = vh.x * vh.x + vh.y * vh.y;
  const Vec3 t1 = len2 > 0 ? Vec3(-vh.y, vh.x, 0.0f) * (1.0f / std::sqrt(len2)) : Vec3(1, 0, 0);
  const Vec3 t2 = cross(vh, t1);
  const float r = std::sqrt(u1), phi = 2.0f * kPi * u2;
  const float p1 = r * std::cos(phi);
  float p2 = r * std::sin(phi);
  const float s = 0.5f * (1.0f + vh.z);
  p2 = (1.0f - s) * std::sqrt(std::max(0.0f, 1.0f - p1 * p1)) + s * p2;
  const Vec3 nh = t1 * p1 + t2 * p2 + vh * std::sqrt(std::max(0.0f, 1.0f - p1 * p1 - p2 * p2));
  return normalize(Vec3(ax * nh.x, ay * nh.y, std::max(1e-7f, nh.z)));
}

Vec3 conductor_fresnel(float cos_i, Vec3 eta, Vec3 k, bool schlick, Vec3 tint) {
  if (schlick) {
    const float m = 1.0f - std::clamp(cos_i, 0.0f, 1.0f);
    const float m5 = m * m * m * m * m;
    return tint + (Vec3(1.0f) - tint) * m5;
  }
  return fresnel_conductor(cos_i, eta, k) * tint;
}

float HardBsdf::plastic_spec_prob(float cos_o) const {
  const float f = fresnel_dielectric(cos_o, eta);
  const float s = f * std::max(1e-3f, luminance(tint));
  const float d = (1.0f - f) * std::max(1e-3f, luminance(albedo));
  return std::clamp(s / (s + d), 0.1f, 0.9f);
}

namespace {

// The half vector of a refraction pair (wo above, wi below), facing +z.
Vec3 refraction_half(Vec3 wo, Vec3 wi, float eta) {
  Vec3 m = wo + wi * eta;
  const float l = length(m);
  if (!(l > 0)) return Vec3(0.0f);
  m = m * (1.0f / l);
  return m.z < 0 ? -m : m;
}

}  // namespace

BsdfValue HardBsdf::eval(Vec3 wo, Vec3 wi) const {
  BsdfValue v;
  const float co = wo.z, ci = wi.z;
  if (co <= 0 || ci == 0 || (ggx.smooth() && type != HardType::kPlastic)) return v;
  if (ci > 0) {
    const Vec3 m = normalize(wo + wi);
    const float om = dot(wo, m);
    if (om <= 0) return v;
    const float dg = ggx.D(m) * ggx.G2(wo, wi) / (4.0f * co * ci);
    switch (type) {
      case HardType::kConductor: v.glossy = fresnel_conductor_at(om) * dg; break;
      case HardType::kDielectric: v.glossy = tint * (fresnel_dielectric(om, eta) * dg); break;
      case HardType::kPlastic: {
        if (!ggx.smooth()) v.glossy = tint * (fresnel_dielectric(om, eta) * dg);
        const float ti = 1.0f - fresnel_dielectric(ci, eta), to = 1.0f - fresnel_dielectric(co, eta);
        const float s = ti * to * base_inv_eta2 * kInvPi;
        for (int ch = 0; ch < 3; ++ch) v.diffuse_white[ch] = s / (1.0f - albedo[ch] * base_inner_reflectance);
        break;
      }
    }
    return v;
  }
  if (type != HardType::kDielectric || thin) return v;
  const Vec3 m = refraction_half(wo, wi, eta);
  const float om = dot(wo, m), im = dot(wi, m);
  if (m.z <= 0 || om <= 0 || im >= 0) return v;
  const float f = fresnel_dielectric(om, eta);
  const float denom = (im + om / eta) * (im + om / eta);
  if (!(denom > 0)) return v;
  const float val = (1.0f - f) * ggx.D(m) * ggx.G2(wo, wi) * std::fabs(im * om) / (std::fabs(ci) * co * denom) /
                    (eta * eta);
  v.glossy = transmittance * val;
  return v;
}

float HardBsdf::pdf(Vec3 wo, Vec3 wi) const {
  const float co = wo.z, ci = wi.z;
  if (co <= 0 || ci == 0) return 0.0f;
  if (type == HardType::kPlastic) {
    if (ci < 0) return 0.0f;
    const float ps = plastic_spec_prob(co);
    float p = (1.0f - ps) * ci * kInvPi;  // a smooth coat's reflection is a delta: not in the density
    if (!ggx.smooth()) {
      const Vec3 m = normalize(wo + wi);
      const float om = dot(wo, m);
      if (om > 0) p += ps * ggx.visible_pdf(wo, m) / (4.0f * om);
    }
    return p;
  }
  if (ggx.smooth()) return 0.0f;
  if (ci > 0) {
    const Vec3 m = normalize(wo + wi);
    const float om = dot(wo, m);
    if (om <= 0) return 0.0f;
    const float p = ggx.visible_pdf(wo, m) / (4.0f * om);
    return type == HardType::kDielectric ? p * fresnel_dielectric(om, eta) : p;
  }
  if (type != HardType::kDielectric || thin) return 0.0f;
  const Vec3 m = refraction_half(wo, wi, eta);
  const float om = dot(wo, m), im = dot(wi, m);
  if (m.z <= 0 || om <= 0 || im >= 0) return 0.0f;
  const float denom = (im + om / eta) * (im + om / eta);
  if (!(denom > 0)) return 0.0f;
  return ggx.visible_pdf(wo, m) * std::fabs(im) / denom * (1.0f - fresnel_dielectric(om, eta));
}

bool HardBsdf::sample(Vec3 wo, float u_lobe, float u1, float u2, BsdfSample& out) const {
  out = BsdfSample{};
  const float co = wo.z;
  if (co <= 0) return false;
  switch (type) {
    case HardType::kConductor: {
      if (ggx.smooth()) {
        out.wi = Vec3(-wo.x, -wo.y, wo.z);
        out.weight_glossy = fresnel_conductor_at(co);
        out.delta = true;
        return true;
      }
      const Vec3 m = ggx.sample_visible(wo, u1, u2);
      const float om = dot(wo, m);
      out.wi = reflect(wo, m);
      if (om <= 0 || out.wi.z <= 0) return false;
      out.weight_glossy = fresnel_conductor_at(om) * (ggx.G2(wo, out.wi) / ggx.G1(wo));
      out.pdf = ggx.visible_pdf(wo, m) / (4.0f * om);
      return out.pdf > 0;
    }
    case HardType::kDielectric: {
      if (ggx.smooth()) {
        float cos_t = 0;
        float f = fresnel_dielectric(co, eta, &cos_t);
        if (thin) f = thin_sheet_reflectance(f);
        out.delta = true;
        if (u_lobe < f) {
          out.wi = Vec3(-wo.x, -wo.y, wo.z);
          out.weight_glossy = tint;
        } else if (thin) {
          out.wi = -wo;
          out.weight_glossy = transmittance;
          out.transmitted = true;
        } else {
          out.wi = refract_dir(wo, Vec3(0, 0, 1), eta, cos_t);
          out.weight_glossy = transmittance * (1.0f / (eta * eta));
          out.transmitted = true;
        }
        return true;
      }
      const Vec3 m = ggx.sample_visible(wo, u1, u2);
      const float om = dot(wo, m);
      if (om <= 0) return false;
      float cos_t = 0;
      const float f = fresnel_dielectric(om, eta, &cos_t);
      const float vis = ggx.visible_pdf(wo, m);
      if (u_lobe < f) {
        out.wi = reflect(wo, m);
        if (out.wi.z <= 0) return false;
        out.weight_glossy = tint * (ggx.G2(wo, out.wi) / ggx.G1(wo));
        out.pdf = vis / (4.0f * om) * f;
      } else {
        out.wi = refract_dir(wo, m, eta, cos_t);
        const float im = dot(out.wi, m);
        if (out.wi.z >= 0 || im >= 0) return false;
        const float denom = (im + om / eta) * (im + om / eta);
        out.weight_glossy = transmittance * (ggx.G2(wo, out.wi) / (ggx.G1(wo) * eta * eta));
        out.pdf = vis * std::fabs(im) / denom * (1.0f - f);
        out.transmitted = true;
      }
      return out.pdf > 0;
    }
    case HardType::kPlastic: {
      const float ps = plastic_spec_prob(co);
      if (u_lobe < ps && ggx.smooth()) {
        // The smooth coat: a mirror reflection of F(cos_o), chosen with probability ps.
        out.wi = Vec3(-wo.x, -wo.y, wo.z);
        out.weight_glossy = tint * (fresnel_dielectric(co, eta) / ps);
        out.delta = true;
        return true;
      }
      if (ggx.smooth()) {
        out.wi = sample_cosine_hemisphere(u1, u2);
        if (out.wi.z <= 1e-7f) return false;
        out.pdf = (1.0f - ps) * out.wi.z * kInvPi;
        out.weight_diffuse_white = eval(wo, out.wi).diffuse_white * (out.wi.z / out.pdf);
        return true;
      }
      if (u_lobe < ps) {
        const Vec3 m = ggx.sample_visible(wo, u1, u2);
        if (dot(wo, m) <= 0) return false;
        out.wi = reflect(wo, m);
      } else {
        out.wi = sample_cosine_hemisphere(u1, u2);
      }
      if (out.wi.z <= 1e-7f) return false;
      out.pdf = pdf(wo, out.wi);
      if (!(out.pdf > 0)) return false;
      // One-sample MIS over the two lobes: the whole BSDF over the mixture's density.
      const BsdfValue v = eval(wo, out.wi);
      const float w = out.wi.z / out.pdf;
      out.weight_diffuse_white = v.diffuse_white * w;
      out.weight_glossy = v.glossy * w;
      return true;
    }
  }
  return false;
}

bool conductor_preset(const char* name, Vec3& eta, Vec3& k) {
  struct Preset {
    const char* name;
    Vec3 eta, k;
  };
  static const Preset presets[] = {
      {"Au", {0.143119f, 0.374957f, 1.44248f}, {3.98316f, 2.38572f, 1.60322f}},
      {"Ag", {0.155265f, 0.116723f, 0.138342f}, {4.82835f, 3.12225f, 2.14696f}},
      {"Cu", {0.200438f, 0.924033f, 1.10221f}, {3.91295f, 2.45285f, 2.14219f}},
      {"Al", {1.65746f, 0.880369f, 0.521229f}, {9.22387f, 6.26952f, 4.837f}},
  };
  for (const Preset& p : presets) {
    if (std::strcmp(p.name, name) == 0) {
      eta = p.eta;
      k = p.k;
      return true;
    }
  }
  return false;
}

}  // namespace dnb::rt
