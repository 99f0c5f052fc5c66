// surface_pass.h: the surface-shading pass of the bake (Sun et al. 2005 eq. 13-19).
//
// Per pixel centre and per fogged light l it writes what the compositor needs to turn
// Cycles' fog-free light-group pass of l into the fog-aware surface radiance:
//   attenuation_l = e^{-T(s_l, p)}   (eq. 14: the direct term through the fog; any BRDF)
// and, summed over the point and spot lights, the Lambert glow per unit diffuse colour
//   glow = (1 / pi) sum_l albedo I0_l profile_l beta_l G(T_l, theta_l, 1) / (2 pi D_l)
// (eq. 17's scattered term with f_r = DiffCol / pi), so that
//   surface = sum_l LightGroup_l attenuation_l + DiffCol glow + (lights outside the fog).
// With settings.surface_phong_exponent = n > 0 it also writes the glossy glow of eq. 18 for
// a normalised Phong lobe (n + 2)/(2 pi) cos^n about the mirrored view direction r:
//   gloss_glow = (n + 2)/(2 pi) sum_l albedo I0_l profile_l beta_l Gn(T_l, theta'_l) / (2 pi D_l),
// theta'_l the angle between the light and r (per unit glossy colour; the paper's
// reparameterisation drops the cos(theta_i) factor).
// G by phase and model:
//   isotropic phase (HG g = 0 included), every model: Sun's G0 / Gn tables (sun05_surface.h);
//   anisotropic phase: the phase-aware G_p tables (biri06_surface.h, Biri 2006 eq. 8-13 with the
//     hemisphere clamped), except model biri06: Biri's own Lambert model eq. 10, G_B = 4 pi^2
//     cos(theta_s) Gamma_L(T) (the unclamped cosine over the whole sphere), clamped at 0 so it
//     never subtracts light, and eq. 12 (= G_p with m = n) for the gloss.
// beta_l and T_l: homogeneous fog sigma_t and sigma_t D_l; with fog objects (Gaussians) the exact
// optical depth T(s_l, p) and beta_l = T / D_l (Fogshop eq. 25 "replaces Tsp with T(s, p)").
// profile_l: 1 for point lights; for spots SpotGlowModel's factor (spot_surface.h: the share
// of the point light's glow that comes from fog the spot lights; exact for a surface facing the
// light, measured for others in spot_surface_test.cpp).
// p is the first hit of the pixel-centre camera ray, the normal its geometric normal (the
// triangle's, not interpolated) turned towards the camera (Cycles shades both sides).
// Sun lamps come after the positional lights: attenuation e^{-sigma_t (h_top - z_p) / mu_s}
// through the fog layer above p (scene.fog_top; 1 without a top or above it), and their
// Lambert glow E albedo Q(sigma_t (h_top - z_p), n) (sunlight_glow.h: the sun's light
// scattered once in the homogeneous fog of the layer, or of unbounded fog without a top,
// for the medium's phase function) added to surface_glow, and with a Phong exponent n their
// glossy glow E albedo (n + 2)/2 Q_n(tau, r) about the mirrored view direction r.
// Limits (documented, not hidden): the glow assumes unbounded fog around p (the paper's
// assumption), lit but for the volumetric shadows' share (glow_shadow.h); with fog objects the glow takes the fog along s -> p as uniform of mean
// extinction T / D (Fogshop's approximation).
#pragma once

#include "bake/bake.h"
#include "image/camera.h"
#include "image/raycast.h"
#include "surface/spot_surface.h"

namespace airlight {

// Fills result.surface_attenuation / surface_glow (see bake.h) for _scene_ with
// _n_threads_ threads. Thread safe; the shared Lambert G table is built on first use.
// _glow_shadow_ (volumetric shadows; null: none): each light's glow times the lit share of
// it (glow_shadow.h), taken on a grid (16 px at 1080p) and interpolated on a surface.
void bake_surface_pass(const SceneDescription& scene, const BakeSettings& settings, const CameraRays& rays,
                       const RayCaster& caster, int n_threads, BakeResult& result,
                       const class GlowShadow* glow_shadow = nullptr);

// The G table of exponent _m_ (1: Lambert) the bake uses, built once per (m, size) for the
// process.
std::shared_ptr<const class SurfaceGTable> shared_surface_G_table(int nT, int ntheta, double m = 1.0);

// The spot glow model for a cone's angle and blend (the axis does not enter its table) and a
// phase, built once per process and shared (thread safe; ~50-100 ms to build).
std::shared_ptr<const SpotGlowModel> shared_spot_glow_model(const SpotCone& cone,
                                                                  const PhaseFunction& phase);

}  // namespace airlight
