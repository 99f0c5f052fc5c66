// spot_surface.h: the glow of a spot light on a surface (single scattering in homogeneous
// fog onto a Lambert surface), the bake's approximation and its brute-force reference.
//
// The point-light glow of biri06_surface.h / sun05_surface.h assumes a light that shines
// equally in every direction. A Cycles spot (spot_light.h) shines with the profile
// I(theta) = I0 cos(theta) smoothstep(...) about its axis, so the fog near p is lit unevenly.
//
// The naive estimate, the point-light glow times the profile toward p, is exact only for the
// light scattered on the segment s -> p; measured (spot_surface_test.cpp) it overestimates a
// 45 deg spot's glow on its axis ~4.5x: most of a point light's glow comes from fog near the
// light in every direction, which the spot leaves dark.
//
// The bake's model (SpotGlowModel). On the incident ray from p at angle gamma from p -> s,
// the point at Biri's angle alpha sees the light in a direction u that turns uniformly with
// alpha from u_p = (p - s)/D (t = 0) toward the ray's own direction: u lies at the angle
// rho = alpha - gamma + pi/2 = theta - gamma from u_p (theta the phase angle) on the great
// circle through u_p in the ray's azimuth. The point light's integrand over (gamma, azimuth,
// rho) is then, with the prefactor e^{-T cos gamma - T sin gamma tan(gamma/2)} = e^{-T},
//   e^{-T} 4 pi p(cos(gamma + rho)) exp(-T sin gamma [tan((gamma + rho)/2) - tan(gamma/2)])
//   x cos(theta_i) (per dgamma dazimuth drho / (4 pi D)),
// and the spot multiplies it by profile(u). For a surface facing the light (theta_s = 0)
// cos(theta_i) = cos(gamma) does not depend on the azimuth, so the spot's glow is EXACTLY the
// point glow times
//   A(T, psi_p) = int_0^pi w_T(rho) a(rho, psi_p) drho / int_0^pi w_T(rho) drho,
//   w_T(rho) = int_0^{min(pi/2, pi - rho)} cos(gamma) 4 pi p(cos(gamma + rho))
//              exp(-T sin(gamma) [tan((gamma + rho)/2) - tan(gamma/2)]) dgamma,
//   a(rho, psi_p) = the profile averaged over the circle at angle rho around u_p, psi_p the
//                   angle between the spot axis and u_p,
// both tabulated per bake. For other orientations the bake uses the same factor (the
// azimuthal weighting of a tilted surface is left out: measured).
#pragma once

#include <vector>

#include <glm/glm.hpp>

#include "core/phase.h"
#include "homogeneous/spot_light.h"

namespace airlight {

// The naive factor: spot_profile toward _p_ (0 at the light itself).
double spot_glow_profile(const SpotCone& cone, const glm::dvec3& s, const glm::dvec3& p);

// The bake's factor A(T, psi_p) (see above) for one spot and phase, tabulated (~20-50 ms to
// build): _nT_ rows over T in [0, 64] (the SurfaceGTable axis; T beyond: the last row), _npsi_
// columns over psi_p in [0, pi], bilinear; _nrho_ midpoints in rho (and 128 in the azimuth) at
// build time.
class SpotGlowModel {
  public:
    SpotGlowModel(const SpotCone& cone, const PhaseFunction& phase, int nT = 48, int npsi = 128, int nrho = 384);
    // The spot's glow / the point light's glow for a surface point p at optical depth _T_ from
    // the light at _s_.
    double factor(double T, const glm::dvec3& s, const glm::dvec3& p) const;
    // The same from the cosine between the spot axis and the direction light -> p.
    double factor(double T, double cos_psi_p) const;

  private:
    SpotCone cone_;
    int nT_, npsi_, nrho_;
    std::vector<double> A_;  // [iT][ipsi]
};

// Reference for tests: irradiance weighted by max(0, cos theta_i)^m about the unit axis _n_
// at _p_ from the single scattering of a spot at _s_ (I0 = 1, albedo 1) in fog of extinction
// _beta_ with phase _phase_: composite Gauss-Legendre over incident directions (gamma about
// p -> s, 12 nodes x ~20 panels; azimuth over the lit arc, 12 x 16) of the adaptive
// spot_airlight_quadrature (to _rel_tol_) along each (the profile and the phase of the actual
// geometry on every ray). Comparable with beta G(T, theta_s, m) / (2 pi D). Seconds.
double spot_surface_glow_reference(const SpotCone& cone, const glm::dvec3& s, const PhaseFunction& phase,
                                   double beta, const glm::dvec3& p, const glm::dvec3& n, double m = 1.0,
                                   double rel_tol = 1e-5);

}  // namespace airlight
