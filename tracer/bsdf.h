// The microfacet and Fresnel parts of the tracer's hard materials: rough and smooth conductors,
// rough and smooth (and thin) dielectrics, and a rough plastic (a GGX coat on a diffuse base).
// The older materials (diffuse, mirror, smooth coated) keep their own code in integrator.cpp;
// what they render does not change.
//
// Everything here works in the shading frame: the normal is +z and the outgoing direction wo
// (towards the previous vertex) is above the surface, wo.z > 0 (the tracer flips its normals to
// face the incoming ray). A transmitted wi has wi.z < 0. `eta` is the ratio n_below / n_above of
// the refractive indices across the surface in that frame (ior when the ray enters the glass,
// 1 / ior when it leaves).
//
// The distribution is GGX (Trowbridge-Reitz), anisotropic with roughness alpha_x along the
// frame's x and alpha_y along its y, with the height-correlated Smith masking-shadowing term
// (Heitz 2014, "Understanding the masking-shadowing function") and sampling of the visible
// normals (Heitz 2018, "Sampling the GGX distribution of visible normals"). Rough dielectrics
// follow Walter et al. 2007, "Microfacet models for refraction through rough surfaces", with
// exact (unpolarised) Fresnel; conductors use the complex-index Fresnel of eta + i k per channel.
// Radiance is transported (not importance): a refraction scales by 1 / eta^2.
//
// Written by hand: no library in Debian provides BSDFs on their own (pbrt, Mitsuba and Cycles
// keep theirs inside the renderer); the formulas are the cited papers'.
#pragma once

#include "tracer/math.h"

namespace dnb::rt {

// ---- Fresnel ------------------------------------------------------------------------------
// Unpolarised reflectance of a dielectric interface for a ray arriving at cos_i > 0 (from the side
// of the normal) with eta = n_transmitted / n_incident; 1 under total internal reflection.
// cos_t receives the cosine of the refracted direction (0 under total internal reflection).
float fresnel_dielectric(float cos_i, float eta, float* cos_t = nullptr);
// Reflectance of a conductor of complex index eta + i k (per channel) at cos_i in [0, 1].
Vec3 fresnel_conductor(float cos_i, Vec3 eta, Vec3 k);
// A conductor's reflectance with its tint: Schlick's curve from F0 = tint, or the complex-index
// Fresnel of (eta, k) times the tint.
Vec3 conductor_fresnel(float cos_i, Vec3 eta, Vec3 k, bool schlick, Vec3 tint);
// What a thin sheet (two parallel interfaces, nothing absorbed between) reflects in all when one
// interface reflects f: R + T^2 R / (1 - R^2) = 2R / (1 + R), its inter-reflections summed.
inline float thin_sheet_reflectance(float f) { return f < 1.0f ? 2.0f * f / (1.0f + f) : 1.0f; }
// The direction refracted from wo (on the side m faces) through a surface of normal m with
// eta = n_transmitted / n_incident, given cos_t from fresnel_dielectric.
inline Vec3 refract_dir(Vec3 wo, Vec3 m, float eta, float cos_t) {
  return normalize(-wo * (1.0f / eta) + m * (dot(wo, m) / eta - cos_t));
}
// Beer-Lambert transmittance over a distance t in a medium of absorption coefficient sigma.
inline Vec3 beer_transmittance(Vec3 sigma, float t) {
  return {std::exp(-sigma.x * t), std::exp(-sigma.y * t), std::exp(-sigma.z * t)};
}
// The hemispherical average of fresnel_dielectric weighted by the cosine, 2 int F(cos) cos dcos:
// the fraction of diffuse light that an interface of ratio eta reflects (for light leaving a
// plastic's base, eta = 1 / ior). Computed by quadrature; a material computes it once.
float fresnel_diffuse_reflectance(float eta);

// ---- GGX ----------------------------------------------------------------------------------
struct Ggx {
  float ax = 0.1f, ay = 0.1f;
  // Whether the lobe is treated as a perfect mirror/refraction (alpha below 1e-3: GGX's
  // density then exceeds float range near the peak; every renderer switches there).
  bool smooth() const { return ax < 1e-3f && ay < 1e-3f; }
  float D(Vec3 m) const;
  float lambda(Vec3 w) const;
  float G1(Vec3 w) const { return 1.0f / (1.0f + lambda(w)); }
  float G2(Vec3 wo, Vec3 wi) const { return 1.0f / (1.0f + lambda(wo) + lambda(wi)); }
  // A visible normal for wo (wo.z > 0) from (u1, u2); its density is visible_pdf(wo, m).
  Vec3 sample_visible(Vec3 wo, float u1, float u2) const;
  float visible_pdf(Vec3 wo, Vec3 m) const { return G1(wo) * std::max(0.0f, dot(wo, m)) * D(m) / wo.z; }
};

// ---- Materials in the shading frame --------------------------------------------------------
// One BSDF value split the way the tracer's layers need it: the diffuse part without its albedo
// (a white base, the paper's D and I) times the albedo gives the diffuse term; the glossy part
// (reflection and transmission through the microfacets or a coat) is whole.
struct BsdfValue {
  Vec3 diffuse_white;  // f of the diffuse base / albedo (0 when there is no base)
  Vec3 glossy;         // f of every other lobe
};

struct BsdfSample {
  Vec3 wi;
  // f cos / pdf split as BsdfValue is (diffuse_white x albedo is the base's share).
  Vec3 weight_diffuse_white, weight_glossy;
  float pdf = 0;        // solid-angle density (0 for a delta lobe)
  bool delta = false;   // a perfect reflection or refraction (no light sample can hit it)
  bool transmitted = false;
};

enum class HardType : unsigned char { kConductor, kDielectric, kPlastic };

struct HardBsdf {
  HardType type = HardType::kConductor;
  Ggx ggx;
  // conductor: complex index (eta_c, k_c), or when schlick is set the Schlick tint F0 = tint
  Vec3 eta_c{0.2f}, k_c{3.9f};
  bool schlick = false;
  Vec3 tint{1.0f};        // conductor: multiplies F; dielectric and plastic: the coat's reflectance
  Vec3 transmittance{1.0f};  // dielectric: multiplies the transmitted lobe
  float eta = 1.5f;       // dielectric, plastic: n_below / n_above (see the top)
  bool thin = false;      // dielectric: a thin sheet (no refraction: wi = -wo, inter-reflections summed)
  Vec3 albedo{0.5f};      // plastic: the base
  float base_inner_reflectance = 0;  // plastic: fresnel_diffuse_reflectance(1 / ior)
  float base_inv_eta2 = 1;           // plastic: 1 / ior^2

  Vec3 fresnel_conductor_at(float cos_i) const { return conductor_fresnel(cos_i, eta_c, k_c, schlick, tint); }
  BsdfValue eval(Vec3 wo, Vec3 wi) const;
  float pdf(Vec3 wo, Vec3 wi) const;
  // u_lobe picks the lobe, (u1, u2) the direction. False when the sample is lost (below the
  // surface, total internal reflection of a microfacet that cannot reflect, ...).
  bool sample(Vec3 wo, float u_lobe, float u1, float u2, BsdfSample& out) const;
  // Whether every lobe is a delta (no light sampling at such a vertex).
  bool all_delta() const { return ggx.smooth() && type != HardType::kPlastic; }

 private:
  float plastic_spec_prob(float cos_o) const;
};

// RGB complex indices of a few metals (the usual fits of their measured spectra to linear sRGB
// primaries, as renderers ship them): "Au", "Ag", "Cu", "Al". False for another name.
bool conductor_preset(const char* name, Vec3& eta, Vec3& k);

}  // namespace dnb::rt
