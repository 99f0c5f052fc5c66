// march.h: the single-scattering airlight of Gaussian fog along one view ray, marched.
//
// Eq. 2 (Fogshop's La, per unit I0) for a point light s and any phase (a spot's cone and a sun
// lamp below: gaussian_march_sun_rgb),
//   La = int_0^Dvp sigma_s(x) p(cos theta) / |x - s|^2 exp(-T(s, x) - T(v, x)) V(x) dt,
// sigma_s = beta0 albedo0 + sum_i albedo_i c_i e^{-a_i^2 |x - b_i|^2} (RGB; unit albedos: beta),
// V = 1 on the lit spans (volumetric shadows) and 0 between them, by composite Simpson over
// steps of a fraction of the narrowest Gaussian width the step holds, shortened to a tenth of the
// distance to the light (its 1 / d^2 peak) times the phase lobe's width, and growing with that
// distance outside the Gaussians; no step straddles a lit span's end. The density comes from a
// window of the ray's own Gaussians (those whose support, GaussianWindow, holds the step), the view depth
// T(v, x) from the same steps (Simpson, and the quadratic interpolant's integral to each
// midpoint), the light depth from a LightDepthMap (O(1) a point) or, without one, exactly
// (the medium's culled erf sums: the reference's cost). The march ends at Dvp, where the view
// depth passes 700 (what lies beyond reaches the eye attenuated below double's range), or, on
// an infinite ray past every Gaussian, where the uniform fog's rest falls below tail_tol of
// the sum. (A step's depth stays below 1/2, so a dense Gaussian's core ends it in ~1400 steps.)
//
// Against gaussian_airlight_quadrature (march_test.cpp): exact light depths ~1e-6 relative;
// with a 64 x 64 x 256 map 0.02-0.2 % on the 3000-Gaussian benchmark cloud, at 0.1-0.6 ms a
// ray against the quadrature's 0.6-10 s.
#pragma once

#include <limits>

#include "core/phase.h"
#include "core/scene.h"
#include "gaussian/airlight.h"
#include "gaussian/light_depth_map.h"
#include "gaussian/medium.h"
#include "gaussian/sun_depth_map.h"
#include "homogeneous/spot_light.h"

namespace airlight {

struct GaussianMarch {
    double step_widths = 0.35;  // the step inside Gaussians, in the widths 1/(a sqrt 2) of the narrowest it holds
    double tail_tol = 1e-7;     // an infinite ray stops where the uniform fog's rest is below this, relative
    double window = 20.0;       // a Gaussian's density is left out beyond a^2 (h^2 + (t - ts)^2) > window (medium.h GaussianWindow)
    double step_tol = 1e-3;     // a step's Simpson sum against its trapezoids, relative: over it, the step is halved
    // Coarser steps and tolerance for an accuracy target (relative; 0: these defaults, ~1e-6
    // against the quadrature with exact light depths).
    void set_accuracy(double target);
    // In: the hierarchy the ray's Gaussians are gathered from: the medium's windowed with this
    // march's window (GaussianMedium::windowed; its spheres hold only what the window keeps: a
    // march ~7 % faster at window 10), or null: the medium's own. Light depths take the medium.
    const GaussianMedium* gather = nullptr;
    // In: per-Gaussian albedos (3 a Gaussian; null: 1) and the uniform fog's (beta0's) albedo.
    const double* albedo = nullptr;
    RGB medium_albedo{1.0, 1.0, 1.0};
    // In: the lit spans of [0, Dvp] (sorted, disjoint; null: all of it).
    const RaySpans* lit = nullptr;
    // In: a spot light's cone (homogeneous/spot_light.h; null: a point light). The in-scattering
    // takes its emission profile, at most emission_max, and no step straddles the ray's
    // crossings of the cone and of its blend cone (nor, with Spread, its closest approach to
    // the axis): the profile's edges and kink, as the quadrature's breakpoints.
    const SpotCone* cone = nullptr;
    double emission_max = 1.0;
    // The march's work, in densities evaluated (one Gaussian's exp: ~7 ns on this machine's
    // cores): those of the steps, kPointWork for each point's light depth from the map and its
    // phase, or kTermWork for each Gaussian of an exact light depth (an erf in double; measured
    // with GaussianMarch.DISABLED_Profile3000 and the 34-Gaussian bench scene). In: past work_limit the march
    // stops (stopped: the result is partial).
    static constexpr long kPointWork = 4, kTermWork = 12;
    long work_limit = std::numeric_limits<long>::max();
    long steps = 0;   // out: the Simpson steps taken
    long work = 0;    // out
    bool stopped = false;  // out
};

// La of the ray origin + t r, t in [0, Dvp] (r unit; Dvp > 0, may be +inf), lit by a point
// light at _s_ of unit intensity (a spot with march.cone); the light depth from _map_ (its light must be _s_), or
// exact when _map_ is null. The RGB form takes the march's albedos; the scalar one is unit
// albedo throughout.
RGB gaussian_march_airlight_rgb(const GaussianMedium& medium, const Vec3& s, const PhaseFunction& phase,
                                const Vec3& origin, const Vec3& r, double Dvp, const LightDepthMap* map,
                                GaussianMarch& march);
double gaussian_march_airlight(const GaussianMedium& medium, const Vec3& s, const PhaseFunction& phase,
                               const Vec3& origin, const Vec3& r, double Dvp, const LightDepthMap* map,
                               GaussianMarch& march);

// The same for a sun lamp of unit irradiance seen towards unit direction _u_ (-w): the
// in-scattering sigma_s p(u . r) exp(-T_sun(x) - T(v, x)), no 1 / d^2, with T_sun the uniform
// fog's layer depth below _fog_top_ (sunlight_layer_depth; +inf: none) plus the Gaussians' on
// the half-line towards the sun (from _map_, or exact when null), and the uniform fog
// scattering inside its layer only (GaussianRefLight's sun). Inside the footprint of the
// Gaussians' shade (SunFootprint) the steps stay within the map's cells (or the narrowest
// width) and end at its sides; march.cone is not read.
RGB gaussian_march_sun_rgb(const GaussianMedium& medium, const Vec3& u, double fog_top, const PhaseFunction& phase,
                           const Vec3& origin, const Vec3& r, double Dvp, const SunDepthMap* map,
                           GaussianMarch& march);
double gaussian_march_sun(const GaussianMedium& medium, const Vec3& u, double fog_top, const PhaseFunction& phase,
                          const Vec3& origin, const Vec3& r, double Dvp, const SunDepthMap* map, GaussianMarch& march);

}  // namespace airlight
