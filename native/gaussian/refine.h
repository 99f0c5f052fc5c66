// refine.h: Gaussian fog to an asked accuracy. Fogshop's approximation (airlight.h, eq. 11)
// samples everything but the Gaussian's own density at one point b_i^r of the ray; where
// that point does not stand for the Gaussian's support (a light next to or inside it, a
// thick Gaussian, the shadow of a dense neighbour across it, a sharp phase lobe or a spot's
// cone edge) its term is off by up to tens of percent (docs/models.md). This file
//  - bounds Fogshop's error on each (light, Gaussian) pair, relative to the pair's term, by
//    the second-order expansion of the integrand about b_i^r (plan_gaussian_refinement);
//    (the bake marches every light with a pair over the target whole: gaussian/march.h);
//  - integrates the uniform fog's term exactly where Fogshop's one factor of the Gaussians
//    for it cannot meet the target: adaptive Gauss-Kronrod (equiangular about a point or spot
//    light) with the Gaussians' erf optical depths towards the eye and the light, over the
//    lit spans (GaussianRefiner).
//
// The bound (constants measured against the exact term on single pairs, then doubled):
//   e = kGeo (sigma / (D - 2 sigma))^2 (1 + kPhase kappa_p)          point and spot lights
//     + kThick (beta(b_i) / a_i)^2                                   thickness at the centre
//     + kShade (G_light^2 + G_view^2)                                neighbours' shadows
// sigma = 1 / (a_i sqrt 2) (the Gaussian's standard deviation), D = |b_i - s|, kappa_p the
// phase's largest |(ln p)''| + (ln p)'^2 in theta, beta(b_i) the medium's density at the
// centre, G = sum over the other Gaussians j near the path to the light (the eye) of
// c_j sqrt(pi) sigma D_j / D (how much their optical depth changes across Gaussian i).
// A light within 3 sigma of b_i, or a spot cone's edge or blend band across the support,
// has no bound (inf): those pairs are always refined.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <limits>
#include <vector>

#include "core/phase.h"
#include "core/scene.h"
#include "gaussian/airlight.h"
#include "gaussian/medium.h"
#include "homogeneous/spot_light.h"

namespace airlight {

// The work of this thread's exact integrals so far: per integrand evaluation, the Gaussians
// whose optical depths it sums (the bake's refinement budget counts it; deterministic).
std::uint64_t& refine_work();
// This thread's limit on refine_work(): an integrand that would count past it throws
// RefineWorkExceeded (the bake's budget is spent; its caller drops the refinement).
std::uint64_t& refine_work_limit();
struct RefineWorkExceeded {};

// The refinement's lights are the reference's (GaussianRefLight, airlight.h): point, spot
// (its cone) or sun (unit propagation direction w); its shadow members are not read here.
using RefineLight = GaussianRefLight;

struct RefinePair {
    std::uint32_t light = 0, gaussian = 0;
    double bound = 0.0;  // Fogshop's estimated relative error on this pair's term
};

struct GaussianRefinePlan {
    std::vector<RefinePair> refined;  // the pairs whose bound exceeds the target
    double kept_bound = 0.0;          // the largest bound of a pair left to Fogshop
    std::size_t pairs = 0;            // (light, Gaussian) pairs that can light the fog
};

// Fogshop's error bound for Gaussian i lit by _light_ seen from _eye_ (the formula above).
double fogshop_pair_bound(const GaussianMedium& medium, std::size_t i, const RefineLight& light, const Vec3& eye,
                          double phase_curvature);
// kappa_p of the formula: max over theta of |(ln p)''| + (ln p)'^2 (0 for isotropic).
double phase_curvature(const PhaseFunction& phase);

// The pairs to refine for relative accuracy _target_ (> 0), every light against every
// Gaussian, on _threads_ threads. The lights flagged in _whole_ are refined whole once a pair
// of theirs is over the target (the bake marches them): for such a light the plan holds one
// pair over the target (the one with the largest bound's light term, found without the walks
// of the medium), or else all its pairs' bounds as for any light.
GaussianRefinePlan plan_gaussian_refinement(const GaussianMedium& medium, const Vec3& eye,
                                            const std::vector<RefineLight>& lights, const PhaseFunction& phase,
                                            double target, int threads = 0, const std::vector<char>& whole = {});

// The exact uniform-fog (beta0) terms of view rays from _eye_: Fogshop attenuates them by one
// factor of the Gaussians (eq. 17), these by the Gaussians' optical depths both ways.
class GaussianRefiner {
  public:
    // _fog_top_: the uniform fog's layer top for suns (sunlight_layer_depth; +inf: none). The
    // medium must outlive this object.
    GaussianRefiner(const GaussianMedium& medium, const Vec3& eye, std::vector<RefineLight> lights,
                    const PhaseFunction& phase, double fog_top);

    // The Gaussians near one view ray (its view-side optical depths), filled by gather().
    struct ViewLine {
        double ts, a, k;  // closest approach, scale, c sqrt(pi) / (2a) e^{-a^2 h^2}
    };
    // The view ray's Gaussian optical depth from t_start to t: the Gaussians within kReach / a
    // of t by their erf, those passed before it by prefix sums of their whole depth (sorted by
    // ts + kReach / a), the ones ahead not at all (< 2e-12 of each); per query the work is
    // the Gaussians whose support holds t, not every Gaussian near the ray.
    struct ViewDepth {
        static constexpr double kReach = 5.0;
        std::vector<ViewLine> lines;  // by ts
        std::vector<double> ts;       // their ts
        std::vector<double> ends;     // ts + kReach / a, sorted
        std::vector<double> passed;   // passed[m]: the whole depths of the first m ends
        double reach = 0.0;           // the largest kReach / a
        double t_start = 0.0;
        void build(double t_start);   // from lines
        double operator()(double t) const;
        double total() const { return passed.empty() ? 0.0 : passed.back(); }
    };
    // The Gaussians near the ray eye + t r, t in [0, t_end], for its optical depths from t_start.
    void gather(const Vec3& r, double t_start, double t_end, ViewDepth& view) const;

    // The uniform fog's (beta0) term of light l (the plan's light order) over the lit spans,
    // attenuated towards the eye from t_start, per unit medium albedo and I0 (E). Fogshop
    // (eq. 17) attenuates it by the Gaussians as the one factor _C_ (C_sv: the segment from the
    // light to the eye; suns: C_sun); the exact term takes their optical depths towards the eye
    // (_view_, from gather on this ray) and towards the light at every point.
    // plain_background: the term without the Gaussians (to relative _rel_tol_);
    // background_correction: exact less Fogshop, to _abs_tol_.
    double plain_background(std::size_t l, const Vec3& r, double t_start, const RaySpans& spans,
                            double rel_tol) const;
    double background_correction(std::size_t l, const Vec3& r, double t_start, const RaySpans& spans,
                                 const ViewDepth& view, double C, double abs_tol) const;
    // The bound |background_correction| <= plain_background * background_bound: the
    // Gaussians' transmittance along any path lies in [e^{-(T_view + T_line)}, 1] (T_view:
    // the ray's own Gaussian depth, view.total(); inf: not gathered, bounded by T_line),
    // and C in (0, 1]; T_line = the sum over the Gaussians of c sqrt(pi) / a, the most any
    // line can cross.
    double background_bound(double T_view, double C) const;
    double max_line_depth() const { return max_line_depth_; }

  private:
    // The Gaussians' optical depth on o + t u, t in [0, len] (len may be inf), by the cull hierarchy.
    double gaussians_on(const Vec3& o, const Vec3& u, double len) const;
    // Integrates f(t) over [lo, hi] of the ray for _light_, f / d^2 for a point or spot light
    // in the equiangular variable about its closest approach, split at _cuts_ (sorted or not),
    // the spot's cone and blend crossings and the closest approach.
    double integrate_light(const RefineLight& light, const Vec3& r, double lo, double hi, std::vector<double>& cuts,
                           const std::function<double(double)>& f, double rel_tol, double abs_tol) const;
    // Integrates f over the lit spans from t_start for light l (integrate_light), split also
    // at the thick Gaussians of _view_ (null: none) and a sun's layer top.
    double integrate_background(std::size_t l, const Vec3& r, double t_start, const RaySpans& spans,
                                const ViewDepth* view, const std::function<double(double)>& f, double rel_tol,
                                double abs_tol) const;
    // The uniform fog's integrand for light l at t (no Gaussians), with the unit direction
    // from the light's position to x (points, spots) or towards the sun in _u_.
    double background_integrand(std::size_t l, const Vec3& r, double t_start, double t, Vec3& u, double& D) const;

    const GaussianMedium& medium_;
    Vec3 eye_;
    std::vector<RefineLight> lights_;
    PhaseFunction phase_;
    double fog_top_;
    double max_line_depth_ = 0.0;
};

}  // namespace airlight
