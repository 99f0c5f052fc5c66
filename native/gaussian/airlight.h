// airlight.h: airlight of point lights in a Gaussian (RBF) medium
// (Fogshop, Zhou et al. 2007, section 3), per unit I0 and albedo like sun05.h, plus
// its exact reference by quadrature.
//
// View ray x(t) = v + t r, t in [0, Dvp] (Dvp may be inf), light at s, isotropic phase:
//   La = int_0^Dvp beta(x) / (4 pi) / d(x)^2 exp(-T(s, x) - T(v, x)) dt      (eq. 2, 5)
//      = sum_i L_i + L_0                                                       (eq. 8)
// Fogshop approximation (airlight.cpp):
//   L_i ~ f0(b_i^r) f1(b_i) T_i(v, p)                                          (eq. 11)
//   b_i^r = projection of b_i on the view ray, clamped to [v, p]               (eq. 10)
//   f0 = 1/(4 pi) / |b_i^r - s|^2 exp(-T_i(s, b_i^r) - T_i(v, b_i^r) + T_i(s, b_i) + T_i(v, b_i))
//   f1 = exp(-T(s, b_i) - T(v, b_i))     (T over all Gaussians and beta0)      (eq. 12, 13)
//   L_0 = C_sv La_sun05(beta0, Dsv, gamma, Dvp),  C_sv = exp(-T(s, v) + beta0 Dsv)  (eq. 15-17)
// i.e. Gaussian i itself is attenuated along the true path s -> b_i^r -> v, everything
// else along s -> b_i -> v, and the homogeneous term by the medium on the segment s -> v.
#pragma once

#include <cstddef>
#include <functional>
#include <utility>
#include <vector>

#include <limits>

#include "core/phase.h"
#include "gaussian/medium.h"
#include "core/scene.h"
#include "core/special_f.h"
#include "homogeneous/spot_light.h"

namespace airlight {

// The lit spans of one view ray for one light (volumetric shadows): [first, second] in t from
// the view origin, sorted and disjoint; _count_ 0: the light adds nothing to the ray.
struct RaySpans {
    const std::pair<double, double>* spans = nullptr;
    int count = 0;
};

enum class GaussianAirlightModel {
    Fogshop,     // the paper's approximation (L_0 through the F table if one is given)
    Quadrature,  // adaptive quadrature of eq. 2 with exact optical depths (reference, slow)
};

// Fogshop airlight for one viewpoint and a set of point lights. Construction does the
// per-(light, Gaussian) work of the paper's section 5.1 (f1, C_sv); eval() is per ray.
class FogshopAirlight {
  public:
    // _table_: F table for the homogeneous term (nullptr = exact F). The medium and the
    // table must outlive this object. Throws std::invalid_argument on non-finite points.
    // _sun_dirs_: sun lamps (unit propagation directions w) after the positional _lights_, for
    // eval_rgb_spans only (light index lights.size() + j; their I0 is the irradiance E), with
    // the homogeneous medium's layer top _fog_top_ (sunlight_layer.h; +inf: none).
    FogshopAirlight(const GaussianMedium& medium, const Vec3& origin, const std::vector<Vec3>& lights,
                       const SpecialFTable* table, int threads = 0, const std::vector<Vec3>& sun_dirs = {},
                       double fog_top = std::numeric_limits<double>::infinity());

    // Writes the airlight of light l to out[l], per unit I0 and albedo, for the view ray
    // origin + t r, t in [0, Dvp]; r unit, Dvp > 0 (may be inf).
    void eval(const Vec3& r, double Dvp, double* out) const;
    // The same in RGB with per-Gaussian albedo (3 per Gaussian) and the lights' I0:
    // out = sum_l [medium_albedo I0_l L_0,l + sum_i albedo_i I0_l L_i,l].
    RGB eval_rgb(const Vec3& r, double Dvp, const double* albedo, const RGB* I0, const RGB& medium_albedo) const;
    // eval_rgb over each light's lit spans only (spans[l] for every light; Biri 2006 eq. 14):
    // Gaussian i's term takes its optical depth on the lit spans, a sum of erf differences,
    // in place of T_i(v, p) (eq. 11), and the homogeneous term is sun05's airlight of each
    // span, attenuated to its start, times C_sv (eq. 17). The fog starts at t_start (the near
    // plane) for the view-side attenuation. _phase_ (null: isotropic) scales each Gaussian's
    // term at b_i^r, as the splat does; _background_ (null: sun05 as above) gives light l's
    // homogeneous airlight per unit albedo I0 on [ta, tb], attenuated from ta (times C_sv here).
    // _profile_ (null: 1) scales light l's Gaussian terms by its emission profile towards the
    // unit direction u from the light to b_i^r (a spot's cone, spot_light.h). _fast_: the
    // Gaussian terms as gaussian_term's fast form.
    // Suns (index num_lights() + j in _spans_ and _I0_ = E): Gaussian i's term is
    // p(u . r) exp(-T_i(b_i^r, towards the sun) - T_i(v, b_i^r)) f1_sun(b_i) T_i(lit spans),
    // f1_sun = exp(-(T(v, b_i) + the other Gaussians' and the layer's depth from b_i towards the
    // sun)), as the splat's sun term (splat.h); the homogeneous term is _background_ (required
    // with suns) of each span, here already attenuated from t_start, times C_sun (the
    // Gaussians on the half-line from v towards the sun).
    using SpanBackground = std::function<double(std::size_t l, double ta, double tb)>;
    using SpanProfile = std::function<double(std::size_t l, const Vec3& u)>;
    RGB eval_rgb_spans(const Vec3& r, double t_start, const RaySpans* spans, const double* albedo, const RGB* I0,
                       const RGB& medium_albedo, const PhaseFunction* phase = nullptr,
                       const SpanBackground* background = nullptr, const SpanProfile* profile = nullptr,
                       bool fast = false) const;

    // Gaussian i's term in eval_rgb_spans for light l (l >= num_lights(): sun l - num_lights())
    // on its lit spans, per unit albedo and I0 (E): what the sum takes times albedo_i I0_l.
    // _Tg_near_: near_depth(r, t_start), which the term's eye side (f1, from the eye) sheds
    // with beta0 t_start, as the splat's exp(T(v, t0)) does.
    // _fast_: the erf differences and exps in float (the splat's kernels, core/fast_erf.h),
    // ~1e-5 relative: ~5x cheaper, for sums that stand in for the splat's own float values.
    double gaussian_term(std::size_t i, std::size_t l, const Vec3& r, double t_start, const RaySpans& lit,
                         const PhaseFunction* phase = nullptr, const SpanProfile* profile = nullptr,
                         double Tg_near = 0.0, bool fast = false) const;
    // The Gaussians' optical depth from the viewpoint to t_start along r (before the near plane).
    double near_depth(const Vec3& r, double t_start) const;

    std::size_t num_lights() const { return lights_.size(); }
    // The factor by which the Gaussians attenuate light l's homogeneous term (eq. 17): C_sv, or
    // for sun j = l - num_lights() C_sun.
    double background_factor(std::size_t l) const { return l < lights_.size() ? Csv_[l] : Csun_[l - lights_.size()]; }
    std::size_t num_suns() const { return sun_u_.size(); }

  private:
    // eval_rgb_spans's fast form of light l's Gaussian terms (a point or spot light, or sun l -
    // num_lights()) over the Gaussians _near_ the ray (airlight_batch.h), times their albedos
    // (per unit I0 or E).
    RGB light_terms(std::size_t l, const Vec3& r, double t_start, const RaySpans& lit, const PhaseFunction* phase,
                    const SpanProfile* profile, const std::vector<std::size_t>& near, double near_depth,
                    const double* albedo) const;
    template <typename Math>
    double term(std::size_t i, std::size_t l, const Vec3& r, double t_start, const RaySpans& lit,
                const PhaseFunction* phase, const SpanProfile* profile, double Tg_near) const;
    // Calls homogeneous(l, L_0) and gaussian(l, i, L_i) for every term of the ray.
    template <typename H, typename G>
    void eval_terms(const Vec3& r, double Dvp, H&& homogeneous, G&& gaussian) const;

    const GaussianMedium& medium_;
    const SpecialFTable* table_;
    Vec3 v_;
    std::vector<Vec3> lights_;
    std::vector<double> Dsv_, Csv_;
    // f1(b_i) exp(T_i(s, b_i) + T_i(v, b_i)) = exp(-(T(s, b_i) + T(v, b_i) without Gaussian i)),
    // light-major [l][i].
    std::vector<double> f1_;
    std::vector<Vec3> sun_u_;      // per sun: the unit direction towards it (-w)
    std::vector<double> Csun_;     // per sun: exp(-the Gaussians on v + t u, t >= 0)
    std::vector<double> f1_sun_;   // sun-major [j][i]: f1_sun(b_i) without Gaussian i
};

// Which Gaussians the quadratures below sum at each point: every one (the reference), or
// those the medium's hierarchy finds near the ray and the light path, every skipped one
// adding less than its cull_eps() to an optical depth (medium.h). Culled is what the bake's
// QUADRATURE model runs: with thousands of Gaussians, most of them far from both paths,
// it does the same integral tens of times faster (airlight_test.cpp holds the two together).
enum class GaussianSums { All, Culled };

// Reference: adaptive Gauss-Kronrod quadrature of eq. 2 (per unit I0 and albedo) with
// exact optical depths, split at the Gaussians' projections on the ray and around the
// light's closest approach. ~1e-8 relative.
double gaussian_airlight_quadrature(const GaussianMedium& medium, const Vec3& light, const Vec3& origin, const Vec3& r,
                               double Dvp, double rel_tol = 1e-8, GaussianSums sums = GaussianSums::All);

// A light of the generalised reference below: point, spot (Cycles profile, spot_light.h,
// per unit on-axis I0) or sun (per unit irradiance E, propagation direction w; fog_top: the
// homogeneous medium's layer top of sunlight_layer.h, +inf: none).
struct GaussianRefLight {
    enum class Kind { Point, Spot, Sun };
    Kind kind = Kind::Point;
    Vec3 s{0.0};
    SpotCone cone;
    Vec3 w{0.0, 0.0, -1.0};
    double fog_top = std::numeric_limits<double>::infinity();
    // Volumetric shadows (empty: lit everywhere): whether a point sees the light, and the t
    // where that changes along the ray (the breakpoints of the quadrature).
    std::function<bool(const Vec3&)> visible;
    std::vector<double> jumps;
};

// The reference for any light and phase: adaptive quadrature of
//   La = int_0^Dvp beta_s(x) p(cos theta(x)) F(x) exp(-T_light(x) - T(v, x)) dt
// with exact optical depths (_sums_ above). Point / spot: F = profile / |x - s|^2 (profile 1 for
// points), T_light = T(s, x), beta_s = beta. Sun: F = 1, T_light = the Gaussians' half-line
// depth from x towards the sun (to infinity) plus beta0 (fog_top - z) / mu_s below a finite
// top (0 above it, or without a top: Hoffman-Preetham's unattenuated sun; infinite for mu_s
// <= 0 in the layer), and beta_s = Gaussians + beta0 inside the layer only (all z without a
// top): sunlight_layer.h's medium; the view side T(v, x) is beta0 t + Gaussians, as the bake's
// Gaussian path (camera inside the layer for the two to agree). Isotropic point lights: the
// same as gaussian_airlight_quadrature above.
double gaussian_airlight_quadrature(const GaussianMedium& medium, const GaussianRefLight& light, const PhaseFunction& phase,
                               const Vec3& origin, const Vec3& r, double Dvp, double rel_tol = 1e-8,
                               GaussianSums sums = GaussianSums::All);

// Batch over rays: out[j * L + l] for ray j (unit dirs[j], Dvp[j] > 0 or inf) and light l.
// Validates all inputs first (std::invalid_argument), then runs on _threads_ threads.
void gaussian_airlight(const GaussianMedium& medium, const std::vector<Vec3>& lights, const Vec3& origin,
                  const Vec3* dirs, const double* Dvp, std::size_t n, double* out, GaussianAirlightModel model,
                  const SpecialFTable* table, int threads = 0);

}  // namespace airlight
