// bake_surface.h: the surface-shading pass of the bake (Sun et al. 2005 eq. 13-19).
//
// Per pixel centre and per fogged light l it writes what the compositor needs to turn
// Cycles' fog-free light-group pass of l into the fog-aware surface radiance:
//   attenuation_l = e^{-T(s_l, p)}   (eq. 14: the direct term through the fog; any BRDF)
// and, summed over the point lights, the Lambert glow per unit diffuse colour
//   glow = (1 / pi) sum_l albedo I0_l sigma_t G(T_l, theta_l, 1) / (2 pi D_l)
// (eq. 17's scattered term with f_r = DiffCol / pi), so that
//   surface = sum_l LightGroup_l attenuation_l + DiffCol glow + (lights outside the fog).
// With settings.surface_phong_exponent = n > 0 it also writes the glossy glow of eq. 18 for
// a normalised Phong lobe (n + 2)/(2 pi) cos^n about the mirrored view direction r:
//   gloss_glow = (n + 2)/(2 pi) sum_l albedo I0_l sigma_t Gn(T_l, theta'_l) / (2 pi D_l),
// theta'_l the angle between the light and r (per unit glossy colour; the paper's
// reparameterisation drops the cos(theta_i) factor). Not wired into the add-on.
// p is the first hit of the pixel-centre camera ray, the normal its geometric normal (the
// triangle's, not interpolated) turned towards the camera (Cycles shades both sides).
// Sun lamps come after the positional lights: attenuation e^{-sigma_t (h_top - z_p) / mu_s}
// through the fog layer above p (scene.fog_top; 1 without a top or above it), and their
// Lambert glow E albedo Q(sigma_t (h_top - z_p), n) (sun_layer_glow.h: the sun's light
// scattered once in the homogeneous fog of the layer, or of unbounded fog without a top,
// for the medium's phase function) added to surface_glow, and with a Phong exponent n their
// glossy glow E albedo (n + 2)/2 Q_n(tau, r) about the mirrored view direction r.
// Limits (documented, not hidden): the glow assumes unbounded unshadowed fog around p (the
// paper's assumption); spot lights get the attenuation but no glow (G assumes an isotropic
// point light); with fog objects (Gaussians) the attenuation uses the exact optical depth
// from the light to p, the glow only the homogeneous background sigma_t.
#pragma once

#include "bake.h"
#include "camera.h"
#include "raycast.h"

namespace airlight {

// Fills result.surface_attenuation / surface_glow (see bake.h) for _scene_ with
// _n_threads_ threads. Thread safe; the shared Lambert G table is built on first use.
void bake_surface_pass(const SceneDescription& scene, const BakeSettings& settings, const CameraRays& rays,
                       const RayCaster& caster, int n_threads, BakeResult& result);

// The G table of exponent _m_ (1: Lambert) the bake uses, built once per (m, size) for the
// process.
std::shared_ptr<const class SurfaceGTable> shared_surface_G_table(int nT, int ntheta, double m = 1.0);

}  // namespace airlight
