// biri06_surface.h: single scattering onto surfaces ("indirect single scattering", Biri,
// Arques, Michelin 2006 eq. 8-13) for ANY phase function, and Biri's own Lambert model.
//
// Geometry as sun05_surface.h: a surface point p, a point light s at distance D (I0 = 1,
// albedo 1), homogeneous unbounded fog of extinction beta, T = beta D. An incident direction
// w at angle gamma from p->s is the ray p + t w, t in [0, inf); the light's closest approach
// is at t = a = D cos gamma, at distance h = D sin gamma. With t - a = h tan(alpha), alpha in
// [gamma - pi/2, pi/2] (Biri eq. 4), the phase angle (phase.h: the light's propagation
// direction (x - s)/r against the scattered direction -w) is
//   cos theta = (a - t)/r = -sin(alpha),  theta = alpha + pi/2  (Biri's p(alpha + pi/2)),
// dt / r^2 = dalpha / h and t + r = a + h (1 + sin alpha)/cos alpha = a + h tan(theta/2). So the
// radiance arriving along w is
//   L(gamma) = (beta / h) e^{-T cos gamma} int_{gamma - pi/2}^{pi/2} p(alpha + pi/2)
//              exp(-T sin(gamma) (1 + sin alpha)/cos alpha) dalpha,
// and with xi = theta/2 in [gamma/2, pi/2] (alpha = 2 xi - pi/2) this is
//   sin(gamma) L(gamma) = beta H_p(T, gamma) / (2 pi D),
//   H_p(T, gamma) = 4 pi e^{-T cos gamma} int_{gamma/2}^{pi/2} p(cos 2 xi) exp(-T sin(gamma) tan xi) dxi,
// Sun's H (sun05_surface.h) with the phase weight 4 pi p (p = 1/(4 pi): H_p = H exactly). The
// irradiance weighted by a clamped cosine lobe cos^m about an axis at theta_s from p->s is
// then beta G_p(T, theta_s, m) / (2 pi D) with
//   G_p(T, theta_s, m) = int_0^pi H_p(T, gamma) W_m(gamma, theta_s) dgamma,
// W_m the azimuth integral of sun05_surface.h. m = 1 about the normal: Lambert (Sun's G0);
// m = n about the mirrored view direction: Phong (Sun's Gn; Biri eq. 12-13 is this with the
// lobe about the reflection axis u_r, phi' the angle between u_r and the light).
//
// Biri's Lambert model (eq. 9-11) integrates the UNclamped cosine over the whole sphere:
//   int_0^{2 pi} cos(theta_i) dpsi = 2 pi cos(phi_n) cos(gamma)   (phi_n = theta_s),
// which gives G_B(T, theta_s) = 2 pi cos(theta_s) int_0^pi H_p(T, gamma) cos(gamma) dgamma
//   = 4 pi^2 cos(theta_s) Gamma_L(T),
//   Gamma_L(lambda) = int_0^pi cos(phi) int_{phi - pi/2}^{pi/2} p(alpha + pi/2)
//                     exp(-lambda (cos(alpha - phi) + sin(phi)) / cos(alpha)) dalpha dphi
// with p normalised to 1 over the sphere. ERRATUM: the paper prints the exponent as
// (cos(alpha - phi) + 1)/cos(alpha); eq. 4 with t = l cos(phi), h = l sin(phi) gives
// l cos(phi) + l sin(phi) (sin alpha + 1)/cos alpha = l (cos(alpha - phi) + sin(phi))/cos alpha
// (biri06_surface_test.cpp checks Gamma_L so written against the H_p form). The paper's p
// carries 4 pi (its eq. 3 has an extra 1/(4 pi)): the two cancel. G_B is negative for
// theta_s > pi/2 (a surface facing away loses light) and counts the back hemisphere with a
// negative weight even at theta_s = 0: a coarse approximation; the bake clamps it at 0.
//
// Everything is per unit I0 and albedo; the glow on a surface per unit k_d / pi is
// beta G / (2 pi D), as in sun05_surface.h.
#pragma once

#include <memory>
#include <vector>

#include "core/phase.h"
#include "surface/sun05_surface.h"

namespace airlight {

// e^{T} H_p(T, gamma) (T >= 0, gamma in [0, pi]), ~1e-10 relative: no overflow at large T.
double biri06_surface_H_scaled(const PhaseFunction& phase, double T, double gamma);

// Exact G_p(T, theta_s, m) and e^{T} G_p (T >= 0, theta_s in [0, pi], finite m >= 1) by
// adaptive quadrature over gamma, ~1e-9 relative.
double biri06_surface_G_scaled_exact(const PhaseFunction& phase, double T, double theta_s, double m);
double biri06_surface_G_exact(const PhaseFunction& phase, double T, double theta_s, double m);

// Tabulated G_p for one (phase, m): the layout of SurfaceGTable (sun05_surface.cpp), measured
// error in biri06_surface.cpp.
class PhaseSurfaceGTable {
  public:
    PhaseSurfaceGTable(const PhaseFunction& phase, double m = 1.0, int nT = 128, int ntheta = 128, int threads = 0);
    // G_p(T, theta_s) for every T >= 0 (beyond T = 64 the grid's tail, SurfaceGGrid).
    double eval(double T, double theta_s) const;
    // e^{T} G_p(T, theta_s).
    double eval_scaled(double T, double theta_s) const;
    const PhaseFunction& phase() const { return phase_; }
    double exponent() const { return m_; }

  private:
    PhaseFunction phase_;
    double m_;
    SurfaceGGrid grid_;  // e^{T} G_p (sun05_surface.h's layout)
};

// The table for (phase, m, nT, ntheta), built once per process and shared (thread safe).
std::shared_ptr<const PhaseSurfaceGTable> shared_phase_surface_G_table(const PhaseFunction& phase, int nT, int ntheta,
                                                                       double m = 1.0);

// Biri eq. 11: Gamma_L(lambda) with the corrected exponent (see above), by direct nested
// quadrature over (phi, alpha) as printed (tests), and e^{lambda} Gamma_L through H_p (~1e-9).
double biri06_Gamma_L_paper(const PhaseFunction& phase, double lambda);
double biri06_Gamma_L_scaled_exact(const PhaseFunction& phase, double lambda);

// Biri's Lambert Gamma_L as the 1D table the paper stores (rows as SurfaceGTable's T axis,
// linear interpolation of e^{lambda} Gamma_L; the exact evaluator beyond lambda = 64).
class Biri06LambertTable {
  public:
    explicit Biri06LambertTable(const PhaseFunction& phase, int n = 256);
    double eval_scaled(double lambda) const;  // e^{lambda} Gamma_L(lambda)
    // Biri eq. 10 in G units: G_B(T, theta_s) = 4 pi^2 cos(theta_s) Gamma_L(T), e^{T} scaled,
    // from cos(theta_s) (UNclamped: negative for a surface facing away).
    double eval_G_scaled(double T, double cos_theta_s) const;

  private:
    PhaseFunction phase_;
    int n_;
    std::vector<double> data_;
};

std::shared_ptr<const Biri06LambertTable> shared_biri06_lambert_table(const PhaseFunction& phase, int n = 256);

// Reference for tests: the surface single-scattering integral by brute force, nested adaptive
// quadrature over incident directions (gamma, azimuth) and the distance t along each of
//   beta p(cos theta) e^{-beta (r + t)} / r^2 max(0, cos theta_i)^m,  cos theta = (D cos gamma - t) / r
// (I0 = 1, albedo 1), light at distance _D_, lobe axis at _theta_s_ from it. Equals
// beta G_p(beta D, theta_s, m) / (2 pi D). Slow (seconds).
double biri06_surface_glow_reference(const PhaseFunction& phase, double beta, double D, double theta_s, double m,
                                     double rel_tol = 1e-7);

}  // namespace airlight
