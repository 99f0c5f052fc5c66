// sphere_light.h: a point or spot light's Radius (Blender's shadow_soft_size) in uniform fog.
//
// Cycles 3.4 samples a point light of radius r as a disk of radius r facing the shading point,
// of uniform radiance with a cosine lobe about its normal (the light's power unchanged). At
// distance d through fog of extinction sigma it gives, per unit intensity,
//   F_r(d) = (1 / (pi r^2)) int_disk cos e^{-sigma rho} / rho^2 dA
//          = (2 / r^2) [e^{-sigma d} - (d / D) e^{-sigma D} - sigma d (E1(sigma d) - E1(sigma D))],
//   D = sqrt(d^2 + r^2),
// in place of a point's e^{-sigma d} / d^2: finite (2 / r^2 at sigma = 0) at the light, and
// e^{-sigma d} / d^2 [1 - (r^2 / 4)(3 / d^2 + sigma / d) + O(r^4 / d^4)] far from it. So the
// radius changes the in-scattering only near the light: by less than 0.75 (r / rho)^2 at a
// distance rho from it. The phase is taken at the disk's centre (exact for the isotropic phase).
#pragma once

#include <functional>
#include <vector>

#include "core/phase.h"
#include "core/scene.h"

namespace airlight {

// F_r(d) above; r = 0 gives the point's e^{-sigma d} / d^2.
double sphere_light_falloff(double sigma_t, double d, double r);

// F_r tabulated for one light and fog, out to the light's reach: q = F_r e^{sigma rho} r^2 / 2
// against u = sqrt(rho / r) (1 at the light, ~ 1 / (2 u^4) far away; smooth in u), 2048 nodes,
// linear: within 2e-5 of the closed form while sigma r <= 1 (1.3e-4 at 10; sphere_light_test.cpp);
// beyond the reach the closed form.
class SphereFalloff {
  public:
    SphereFalloff(double sigma_t, double r);
    double operator()(double rho) const;

  private:
    double sigma_t_, r_, u_max_, inv_du_;
    std::vector<double> q_;
};

// How far from the light the radius matters: beyond sphere_light_reach(sigma_t, r, tol) the
// in-scattering differs from the point's by less than _tol_ relative (the expansion above;
// sqrt(0.75 / tol) radii in clear fog, kSphereReach at kSphereTol), cut at 10 optical depths
// from the light (and at least that many radii) where sigma r is large.
constexpr double kSphereTol = 1e-3;
constexpr double kSphereReach = 27.386127875258307;  // sqrt(0.75 / kSphereTol)
double sphere_light_reach(double sigma_t, double r, double tol = kSphereTol);

// The part of the ray o + t d (unit d), t in [lo, hi], within sphere_light_reach of the light
// at _s_: [a, b] with a < b, or false when it does not come that close.
bool sphere_light_window(double sigma_t, const Vec3& s, double r, const Vec3& o, const Vec3& d, double lo, double hi,
                         double& a, double& b, double tol = kSphereTol);

// The disk light's airlight per unit albedo x intensity along o + t d over [a, b], attenuated
// from _t_start_ (e^{-sigma (t - t_start)}):
//   sigma_t int_a^b p(cos theta) profile(x) e^{-sigma (t - t_start)} F_r(|s - x|) dt,
// cos theta = (s - x).d / |s - x|, _profile_ the light's emission towards x (null: 1, a point
// light; a spot's cone), _cuts_ the t where it has a kink or a jump (a cone's edge).
// Gauss-Legendre in the angle phi of t = t_c + w tan phi about the closest approach t_c
// (w^2 = h^2 + r^2 / 2, which flattens F_r's peak), in panels narrow enough for the phase's
// lobe: within 5e-5 of adaptive quadrature (sphere_light_test.cpp; 1e-7 but in dense fog).
// _falloff_ (optional): the light's table, else the closed form.
double sphere_light_airlight(const PhaseFunction& phase, double sigma_t, const Vec3& s, double r, const Vec3& o,
                             const Vec3& d, double a, double b, double t_start,
                             const std::function<double(const Vec3&)>& profile = nullptr,
                             std::vector<double> cuts = {}, const SphereFalloff* falloff = nullptr);

// Far from the light (closest approach h >= kSphereSeriesRadii r, and sigma r^2 / h <= 1/4)
// the disk's airlight less the point's comes straight from the expansion
//   F_r = (e^{-sigma rho} / rho^2) [1 - eps (3 + sigma rho) / 4 + eps^2 (15 + 7 sigma rho +
//         sigma^2 rho^2) / 24 + O(eps^3)],  eps = r^2 / rho^2,
// whose remainder there is below 2e-4 of the point's in-scattering: a smooth integrand
// ~ 1 / rho^4, 16-point Gauss-Legendre in phi. The same arguments as sphere_light_airlight.
constexpr double kSphereSeriesRadii = 4.0;
bool sphere_light_series_applies(double sigma_t, double r, double h);
double sphere_light_excess_series(const PhaseFunction& phase, double sigma_t, const Vec3& s, double r, const Vec3& o,
                                  const Vec3& d, double a, double b, double t_start,
                                  const std::function<double(const Vec3&)>& profile = nullptr,
                                  std::vector<double> cuts = {});

// Whether the radius can change the airlight of a ray that passes the light at distance _h_
// by more than _tol_ of the light's: the expansion's relative change r^2 (3 + sigma rho) /
// (4 rho^2) at the closest approach (its largest on the ray, so a bound on the ray's whole
// airlight, whatever its ends) exceeds it; rays beyond skip the window (h >= the reach).
bool sphere_light_matters(double sigma_t, double r, double h, double tol = kSphereTol);

// Its adaptive-quadrature reference (same integral, rel_tol).
double sphere_light_airlight_quadrature(const PhaseFunction& phase, double sigma_t, const Vec3& s, double r,
                                        const Vec3& o, const Vec3& d, double a, double b, double t_start,
                                        double rel_tol, const std::function<double(const Vec3&)>& profile = nullptr,
                                        std::vector<double> cuts = {});

// Soft shadows: _n_ points in the unit ball whose projection along any direction covers the
// unit disk uniformly, so that the shadows cast from a light's centre + r times them average to
// those of the disk facing each point of the fog (Cycles' sphere light), whatever the point.
// Their density in the ball is 1 / (pi^2 sqrt(1 - rho^2)) (its X-ray transform is constant on
// the disk): radii at stratified quantiles of F(rho) = (2 asin rho - sin(2 asin rho)) / pi,
// directions on a Fibonacci sphere, the radii shuffled against them, in mirrored pairs (their
// mean is the centre; odd n adds the centre), the one nearest the centre first. n = 1: the
// centre (hard shadows).
std::vector<Vec3> sphere_light_shadow_samples(int n);

// A sun's soft shadows: _n_ unit directions of propagation over the disk of angular diameter
// _angle_ about _w_ (unit), as Cycles samples a distant light: w + tan(angle / 2) times points
// of the unit disk in its tangent plane, normalised; the points on a Fibonacci spiral (radii
// sqrt((k + 1/2) / n), equal area). n = 1 or angle 0: _w_ (hard shadows). angle <= pi.
std::vector<Vec3> sun_shadow_directions(const Vec3& w, double angle, int n);

}  // namespace airlight
