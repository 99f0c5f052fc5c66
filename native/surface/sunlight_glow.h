// sunlight_glow.h: the glow of a sun lamp on a Lambert surface in a fog layer: the sun's
// light scattered once in the fog on its way to the surface (Sun et al. 2005's surface
// "glow", eq. 15, for a directional light, with the layer geometry of sunlight_layer.h and any
// phase function).
//
// A surface point p of normal n at height z_p, fog of extinction sigma below h_top (or
// everywhere without a top: the sun then reaches every point unattenuated, Hoffman-Preetham's
// assumption), a sun of irradiance E propagating along w_s, l = -w_s (towards the sun),
// mu_s = l.z. Along the incident direction w (looking out from p) the fog scatters towards p
//   L_in(w) = sigma_s p(l.w) E G(w),   G(w) = sunlight_layer_factor(sigma, h_top, mu_s, z_p, w.z, 0, inf)
// (cos theta = l.w: theta = 0 looking into the sun). sigma G depends on the geometry only
// through tau = sigma (h_top - z_p) (the optical depth of p below the top; every height
// above the top behaves as tau = 0: no fog between p and the layer) and w.z. The surface's
// glow per unit diffuse colour (the bake's SurfaceGlow convention: DiffCol x SurfaceGlow
// is the reflected radiance) is
//   SurfaceGlow = (1 / pi) int_{n.w > 0} L_in(w) (n.w) dw = albedo E Q(tau, n),
//   Q(tau, n) = (1 / pi) int_{n.w > 0} p(l.w) sigma G(w) (n.w) dw            (dimensionless).
// With an exponent m the weight (n.w) becomes max(0, n.w)^m about an axis n: m = 1 is the
// Lambert glow above; Sun 2005's Phong glow (eq. 18, Gn) is the lobe about the mirrored view
// direction r, SurfaceGloss = (m + 2)/(2 pi) int L_in(w) max(0, r.w)^m dw = albedo E (m + 2)/2 Q_m(tau, r).
// Like the paper, the fog around p is unshadowed and unbounded below (every ray that does
// not leave the layer through its top goes on forever in fog).
//
// Isotropic checks: without a top Q = 1 / (4 pi) for every n; at the top (tau = 0) an
// up-facing surface gets Q = 0 and a down-facing one (mu_s / 2 pi)(1 - mu_s ln((1 + mu_s)/mu_s)).
#pragma once

#include <vector>

#include <glm/glm.hpp>

#include "core/phase.h"

namespace airlight {

// Exact Q(tau, n) by adaptive quadrature over incident directions (about 1e-9 relative):
// _to_sun_ l (unit), _tau_ >= 0 the optical depth of p below the top (ignored when
// _has_top_ is false), _normal_ n (unit). 0 when the sun is at or below the horizon of a
// layer with a top (its light crosses infinitely much fog).
// _m_ in [1, 10000]: the lobe exponent (1: Lambert).
double sunlight_glow_exact(const PhaseFunction& phase, const glm::dvec3& to_sun, bool has_top, double tau,
                            const glm::dvec3& normal, double m = 1.0, double rel_tol = 1e-9);

// The same integral with the fog factor sigma G(w) from sunlight_layer_factor_quadrature (the
// path integral along each incident ray written out from the geometry): an independent,
// slow reference for tests.
double sunlight_glow_reference(const PhaseFunction& phase, const glm::dvec3& to_sun, bool has_top, double tau,
                                const glm::dvec3& normal, double m = 1.0, double rel_tol = 1e-6);

// Q tabulated for one sun direction and phase function: over the normal (polar angle from
// +Z, azimuth from the sun's, folded by the mirror symmetry about the sun's vertical plane)
// and, with a top, over s = tau / (1 + tau) (stored as e^{tau} Q, which stays bounded).
// Trilinear interpolation; layout and measured error in sunlight_glow.cpp.
class SunlightGlowTable {
  public:
    SunlightGlowTable(const PhaseFunction& phase, const glm::dvec3& to_sun, bool has_top, double m = 1.0, int n_tau = 48,
                      int n_theta = 49, int n_phi = 25, int threads = 0);
    // Q_m(tau, n); tau < 0 (above the top) is taken as 0; _normal_ unit.
    double eval(double tau, const glm::dvec3& normal) const;
    bool has_top() const { return has_top_; }

  private:
    void frame(const glm::dvec3& n, double& theta, double& phi) const;
    PhaseFunction phase_;
    double m_;
    glm::dvec3 to_sun_, e1_, e2_;
    bool has_top_;
    bool lit_;
    int n_tau_, n_theta_, n_phi_;
    std::vector<double> data_;  // [i_tau][i_theta][i_phi]
};

}  // namespace airlight
