// fog_evaluator.cpp: see fog_evaluator.h.
#include "bake/fog_evaluator.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <functional>
#include <sstream>
#include <stdexcept>

#include "core/build_progress.h"
#include "core/constants.h"
#include "core/parallel.h"
#include "core/target_clones.h"
#include "core/thread_scratch.h"
#include "gaussian/airlight.h"
#include "gaussian/march.h"
#include "homogeneous/sphere_light.h"
#include "homogeneous/sun05_batch.h"
#include "homogeneous/sunlight_layer.h"
#include "shadow/shadowed_quadrature.h"

namespace airlight {

namespace {

// A fog-object Gaussian's largest optical depth through its centre for the Fogshop models'
// float kernels (see the constructor).
constexpr double kMaxCentreDepth = 1e4;
// Relative tolerance of the spot-light quadrature (every model: spots have no closed form);
// far below the float passes' and Cycles' noise, and ~3x cheaper than 1e-8.
constexpr double kSpotRelTol = 1e-5;
// Spots of the models but Pegoraro 2010's take its closed form up to this phase order.
constexpr int kPegoraroSpotMaxOrder = 8;

// Relative tolerance of the shadowed reference (visibility inside the integrand: each node a
// shadow ray).
constexpr double kShadowRelTol = 1e-8;

// A point light whose unshadowed airlight on a ray is below this fraction of the ray's
// airlight from all point lights keeps it unshadowed there: its shadow cannot change the
// pixel by more (shadows only remove light), so its lit intervals are not traced.
constexpr double kShadowCull = 1e-3;

// The one span [t0, t1] of a ray lit all along.
bool fully_lit(const LitIntervals& lit, int v, double t0, double t1) {
    return lit.end[v] - lit.begin[v] == 1 && lit.spans[lit.begin[v]].first == t0 && lit.spans[lit.begin[v]].second == t1;
}

// Whether each of a light's _n_ shadow samples (volumes v .. v + n - 1) lights [t0, t1] all along.
bool samples_lit(const LitIntervals& lit, int v, int n, double t0, double t1) {
    for (int j = 0; j < n; ++j)
        if (!fully_lit(lit, v + j, t0, t1)) return false;
    return true;
}

// How many shadow samples of light _i_ (_counts_: per light its count, its volumes from _v_) the
// ray [t0, t1] needs: 1 without shadows or where every one lights it all along (they agree
// there), else them all.
int samples_needed(const LitIntervals* lit, int v, const std::vector<int>& counts, size_t i, double t0, double t1) {
    return v < 0 || !lit || samples_lit(*lit, v, counts[i], t0, t1) ? 1 : counts[i];
}

// The sun's factor over the lit span [a, b] of a ray from o, attenuated from the fog's start
// t_start (sunlight_layer_factor attenuates from the start of its own segment inside the layer).
double sunlight_span(double sigma, double h_top, double mu_s, const Vec3& o, const Vec3& d, double t_start, double a,
                     double b) {
    const double G = sunlight_layer_factor(sigma, h_top, mu_s, o.z, d.z, a, b);
    if (G == 0.0) return 0.0;
    // Where the ray enters the layer z <= h_top (-inf: it starts inside or never leaves).
    double enter = -std::numeric_limits<double>::infinity();
    if (std::isfinite(h_top) && d.z < 0.0 && o.z > h_top) enter = (h_top - o.z) / d.z;
    return G * std::exp(-sigma * (std::max(a, enter) - std::max(t_start, enter)));
}

// cos(gamma) of unit directions (dx, dy, dz)[k] with the unit vector _sv_ to a light.
AIRLIGHT_ROW_CLONES
void cos_to_light(const double* __restrict dx, const double* __restrict dy, const double* __restrict dz,
                  const Vec3& sv, int n, double* __restrict cos_gamma) {
    for (int k = 0; k < n; ++k) cos_gamma[k] = dx[k] * sv.x + dy[k] * sv.y + dz[k] * sv.z;
}

// The passes' part of accumulate_rgb: pass g of ray k, passes[3 (k G + g) + c] += w_c value[k].
void accumulate_pass(const float* value, const RGB& w, int n, int G, int g, float* passes) {
    const float wr = float(w.x), wg = float(w.y), wb = float(w.z);
    for (int k = 0; k < n; ++k) {
        float* p = passes + 3 * (size_t(k) * G + g);
        p[0] += wr * value[k];
        p[1] += wg * value[k];
        p[2] += wb * value[k];
    }
}

// sum_c[k] += w_c value[k] for the three colour channels.
AIRLIGHT_ROW_CLONES
void accumulate_rgb(const float* __restrict value, float wr, float wg, float wb, int n, float* __restrict r,
                    float* __restrict g, float* __restrict b) {
    for (int k = 0; k < n; ++k) {
        r[k] += wr * value[k];
        g[k] += wg * value[k];
        b[k] += wb * value[k];
    }
}

}  // namespace

FogEvaluator::FogEvaluator(const SceneDescription& scene, const BakeSettings& settings, const FogModel& model, bool shared_origin,
         const Vec3& origin)
    : model_(model),
      sigma_t_(scene.medium.sigma_t),
      phase_(scene.medium.phase),
      isotropic_(phase_is_isotropic(scene.medium.phase)),
      shared_origin_(shared_origin),
      origin_(origin) {
    const SpotMethod spot_method = model_.spot_method();
    if (spot_method != SpotMethod::Quadrature && !scene.spot_lights.empty()) {
        pegoraro_phase_ = pegoraro_phase_auto(phase_, kPegoraroPhaseTol, kPegoraroMaxOrder);
        // Spots: the closed form where the model asks for it, and for the other non-quadrature
        // models while the phase polynomial is of order <= kPegoraroSpotMaxOrder: there it costs
        // about what the 1e-5 quadrature does (bench_pegoraro.py, isotropic); at HG order 30 it
        // was ~5x slower, so those spots keep the quadrature.
        spot_closed_form_ = spot_method == SpotMethod::ClosedForm || pegoraro_phase_.order() <= kPegoraroSpotMaxOrder;
    }
    for (const PointLight& light : scene.point_lights) {
        if (!keeps_light(scene, light)) continue;
        RGB weight = scene.medium.albedo * light.I0;
        lights_.push_back(
            {light.position, weight, glm::length(light.position - origin), light.radius, nullptr, light.light_pass});
        if (light.radius > 0.0 && sigma_t_ > 0.0 && scene.gaussians.empty())
            lights_.back().falloff = std::make_shared<const SphereFalloff>(sigma_t_, light.radius);
        has_light_size_ = has_light_size_ || light.radius > 0.0;
    }
    for (const SpotLight& spot : scene.spot_lights) {
        RGB weight = scene.medium.albedo * spot.I0;
        if (weight.x == 0.0 && weight.y == 0.0 && weight.z == 0.0) continue;
        spots_.push_back({make_light_cone(spot), spot.position, weight, spot.radius, nullptr, spot.light_pass});
        if (spot.radius > 0.0 && sigma_t_ > 0.0 && scene.gaussians.empty())
            spots_.back().falloff = std::make_shared<const SphereFalloff>(sigma_t_, spot.radius);
        has_light_size_ = has_light_size_ || spot.radius > 0.0;
    }
    for (const SunLight& sun : scene.sun_lights) {
        const RGB weight = scene.medium.albedo * sun.E * sigma_t_;  // sigma_s E
        if (weight.x == 0.0 && weight.y == 0.0 && weight.z == 0.0) continue;
        const Vec3 w = glm::normalize(sun.direction);
        suns_.push_back({w, -w.z, weight, sun.light_pass});
    }
    fog_top_ = scene.fog_top;
    n_passes_ = scene.light_passes;
    if (!scene.gaussians.empty()) has_light_size_ = false;  // fog objects take their lights as points
    if (!(sigma_t_ > 0.0)) has_light_size_ = false;
    light_size_tol_ = settings.light_size_tolerance;
    if (!scene.gaussians.empty()) {
        const Gaussians& g = scene.gaussians;
        gaussian_ = std::make_unique<GaussianMedium>(g.centres, g.scales, g.amplitudes, sigma_t_);
        for (const LightData& light : lights_) gaussian_lights_.push_back(light.s);
        // Per-light I0 (the Gaussians' weights carry their own albedo), per-Gaussian albedo.
        medium_albedo_ = scene.medium.albedo;
        for (const PointLight& light : scene.point_lights)
            if (keeps_light(scene, light)) gaussian_I0_.push_back(light.I0);
        gaussian_albedo_ = g.albedo;
        if (gaussian_albedo_.empty())
            for (size_t i = 0; i < g.scales.size(); ++i)
                for (int c = 0; c < 3; ++c) gaussian_albedo_.push_back(scene.medium.albedo[c]);
        const GaussianNoise noise{g.noise_amplitude, g.noise_scale, g.noise_offset};
        if (noise.on() && !shared_origin_)
            throw std::invalid_argument("fog noise needs a perspective camera (orthographic cameras bake "
                                        "Gaussian fog without noise only)");
        // Spots and suns with Gaussians (after the point lights in gaussian_lights_ / gaussian_I0_).
        n_gaussian_points_ = gaussian_lights_.size();
        for (const SpotLight& spot : scene.spot_lights) {
            if (spot.I0.x == 0.0 && spot.I0.y == 0.0 && spot.I0.z == 0.0) continue;
            if (!spot.profile.empty())
                throw std::invalid_argument("fog objects: a light with an IES profile (spot_profiles) is not in "
                                            "Gaussian fog yet; turn its Scatter in Fog off, or remove its IES Texture");
            gaussian_lights_.push_back(spot.position);
            gaussian_I0_.push_back(spot.I0);
            gaussian_spots_.push_back({make_spot_cone(spot.axis, spot.spot_size, spot.spot_blend, spot.spread), spot.position,
                                  spot.I0});
        }
        for (const SunLight& sun : scene.sun_lights) {
            if (sun.E.x == 0.0 && sun.E.y == 0.0 && sun.E.z == 0.0) continue;
            const Vec3 w = glm::normalize(sun.direction);
            gaussian_suns_.push_back({w, -w.z, sun.E});
        }
        const bool fogshop = model_.gaussian_method() == GaussianMethod::Fogshop;
        const bool extended = !gaussian_spots_.empty() || !gaussian_suns_.empty() || !isotropic_ ||
                              model_.own_gaussian_background();
        if (fogshop && extended && !shared_origin_)
            throw std::invalid_argument("fog objects with spot or sun lamps, an anisotropic phase or model "
                                        "'biri06' / 'pegoraro10' need a perspective camera (or model "
                                        "'quadrature')");
        // Fogshop's per-(light, Gaussian) precomputation, once for the shared viewpoint,
        // and the tiled splatting (gaussian/splat.h) that evaluates it.
        if (fogshop && shared_origin_) {
            // The splat's float kernels take a Gaussian's optical depth on a segment as
            // (c sqrt(pi) / 2a) times a difference of erfc values, which cancels (both near
            // 1) on a segment that starts inside the Gaussian's core (the eye or a light
            // within ~1 / a of its centre) and is short against 1 / a: that loses c
            // sqrt(pi) / 2a times float's 1.2e-7. Such a Gaussian whose optical depth
            // through its centre, c sqrt(pi) / a, exceeds kMaxCentreDepth (1e4: <= ~1e-3
            // of transmittance; measured 2.9e-3 at 1.8e4, garbage and an infinite airlight
            // at 1.8e8) is refused with what to do. Elsewhere its segments' erfc values are
            // not both near 1 (a dense blob seen from outside: no loss).
            for (size_t i = 0; i < g.scales.size(); ++i) {
                const double a = g.scales[i];
                const double depth = g.amplitudes[i] * std::sqrt(kPi) / a;
                if (!(depth > kMaxCentreDepth)) continue;
                const Vec3 b(g.centres[3 * i], g.centres[3 * i + 1], g.centres[3 * i + 2]);
                bool inside = a * glm::length(b - origin_) < 2.0;
                for (const Vec3& s : gaussian_lights_) inside = inside || a * glm::length(b - s) < 2.0;
                if (inside) {
                    std::ostringstream os;
                    os << "fog objects: Gaussian " << i << " (amplitude " << g.amplitudes[i] << " /m, scale " << a
                       << " /m) holds the camera or a light in its core and has an optical depth of " << depth
                       << " through its centre, beyond the " << kMaxCentreDepth
                       << " the Fogshop models compute accurately there: give fog this wide and dense to "
                          "the scene's uniform Density, or use model 'quadrature'";
                    throw std::invalid_argument(os.str());
                }
            }
            GaussianSplatLights extra;
            if (extended) {
                extra.phase = phase_;
                const size_t L = gaussian_lights_.size();
                extra.spot.assign(L, 0);
                extra.cone.assign(L, SpotCone{});
                extra.custom_background.assign(L, 0);
                for (size_t l = 0; l < L; ++l) {
                    const bool is_spot = l >= n_gaussian_points_;
                    extra.spot[l] = is_spot;
                    if (is_spot) extra.cone[l] = gaussian_spots_[l - n_gaussian_points_].cone;
                    // The sun05 term of the splat is isotropic: other models and phases
                    // (and spots) use the bake's own model for the background.
                    extra.custom_background[l] = is_spot || !isotropic_ || model_.own_gaussian_background();
                }
                for (const GaussianSunData& sun : gaussian_suns_) {
                    extra.sun_w.push_back(sun.w);
                    extra.sun_E.push_back(sun.E);
                }
                extra.fog_top = fog_top_;
                extra.background = [this](size_t l, const Vec3& d, double t0, double Dvp) {
                    return gaussian_background(l, d, t0, Dvp);
                };
            }
            splat_ = std::make_unique<GaussianSplat>(*gaussian_, origin_, gaussian_lights_, gaussian_I0_, scene.medium.albedo,
                                                g.albedo, model_.f_table(), noise, std::max(0, settings.threads),
                                                extended ? &extra : nullptr);
        }
    }
    if (settings.shadows) set_up_shadows(scene, settings);
    if (settings.gaussian_accuracy > 0.0 && splat_ && !(scene.gaussians.noise_amplitude > 0.0))
        set_up_refinement(settings, scene.camera);
}

void FogEvaluator::set_up_refinement(const BakeSettings& settings, const Camera& camera) {
    // (projection[0][0] = the focal length over half the image width: model_choice.pixel_angle)
    pixel_angle_ = camera.width > 0 && camera.projection[0][0] != 0.0
                       ? 2.0 / (std::abs(camera.projection[0][0]) * camera.width)
                       : 0.0;
    std::vector<RefineLight> lights;
    for (size_t l = 0; l < gaussian_lights_.size(); ++l) {
        RefineLight light;
        light.s = gaussian_lights_[l];
        if (l >= n_gaussian_points_) {
            light.kind = GaussianRefLight::Kind::Spot;
            light.cone = gaussian_spots_[l - n_gaussian_points_].cone;
        }
        lights.push_back(light);
    }
    for (const GaussianSunData& sun : gaussian_suns_) {
        RefineLight light;
        light.kind = GaussianRefLight::Kind::Sun;
        light.w = sun.w;
        lights.push_back(light);
    }
    gaussians_end_ = 0.0;
    for (size_t j = 0; j < gaussian_->size(); ++j)
        gaussians_end_ = std::max(gaussians_end_, glm::length(gaussian_->centre(j) - origin_) + gaussian_->cull_radius(j));
    const int threads = std::max(0, settings.threads);
    // The accuracy's shares: the plan's pairs left to Fogshop, the pairs each ray leaves to it,
    // and the uniform fog's term (refine_gaussians).
    const bool background = gaussian_->beta0() > 0.0;
    refine_target_ = settings.gaussian_accuracy;
    refine_budget_ = std::uint64_t(std::max(0.0, settings.gaussian_refine_budget) / kRefineSecondsPerWork);
    const double pair_target = (background ? kPlanShare : kPlanShare + kBackgroundShare) * refine_target_;
    // (a light with a pair over the target is marched whole: plan_marches; for point and spot
    // lights the plan finds one by the light terms alone)
    std::vector<char> whole(lights.size(), 0);
    std::fill(whole.begin(), whole.begin() + std::ptrdiff_t(gaussian_lights_.size()), 1);
    GaussianRefinePlan plan =
        plan_gaussian_refinement(*gaussian_, origin_, lights, phase_, pair_target, threads, whole);
    refine_pairs_ = plan.pairs;
    refine_kept_bound_ = plan.kept_bound;
    refine_error_bound_ = plan.kept_bound + (kMarchedShare + (background ? kBackgroundShare : 0.0)) * refine_target_;
    plan_marches(plan, threads);
    if (!background && marched_.empty()) return;
    if (!eye_fogshop_) {
        std::vector<Vec3> sun_dirs;
        for (const GaussianSunData& sun : gaussian_suns_) sun_dirs.push_back(sun.w);
        eye_fogshop_ = std::make_unique<FogshopAirlight>(*gaussian_, origin_, gaussian_lights_, model_.f_table(),
                                                         threads, sun_dirs, fog_top_);
    }
    refiner_ = std::make_unique<GaussianRefiner>(*gaussian_, origin_, std::move(lights), phase_, fog_top_);
}

void FogEvaluator::plan_marches(GaussianRefinePlan& plan, int threads) {
    // A light with a pair to refine is marched whole: one march of every Gaussian near the ray
    // costs what a few exact pair terms do (each sums the Gaussians near the ray and the light
    // path at every node), and leaves no pair of that light to Fogshop.
    const size_t P = gaussian_lights_.size();
    std::vector<char> march(P + gaussian_suns_.size(), 0);
    for (const RefinePair& pair : plan.refined) march[pair.light] = 1;
    plan.refined.erase(std::remove_if(plan.refined.begin(), plan.refined.end(),
                                      [&](const RefinePair& pair) { return march[pair.light] != 0; }),
                       plan.refined.end());
    // The light depths from a map whose measured error fits the march's share of the accuracy
    // (kMarchedShare; the march's own error is far below it)
    // (march_map_error: the march with the map against exact light depths on rays from the eye
    // through the Gaussians). 64 grid points a side first, then twice and four times as many
    // while it errs more and the error's fall could still reach the need by the largest size.
    // The error falls as the square of the spacing or faster: 4x a doubling on the thick
    // benchmark cloud, 9.5x on the 1e5 one (64 errs 0.014, 128 0.0015), where predicting by
    // the square law skipped 128 for 256 (16x the cost of 64: two thirds of the frame's
    // set-up). Past the largest, or past kMarchMapMaxBytes for all the lights, the light depths
    // are exact (slow with many Gaussians: the budget decides).
    const double need = kMarchedShare * refine_target_;
    std::size_t bytes = 0;
    // Sets _marched_'s map to the first size (build(face) makes it) that fits, if any.
    auto search = [&](MarchedLight& marched, auto build, std::size_t bytes_per_face2, int max_face) {
        double last_error = 0.0;
        std::vector<double> exact;  // the check rays' exact marches, shared by the sizes
        for (int face = 64; face <= max_face;) {
            if (bytes + bytes_per_face2 * face * face > kMarchMapMaxBytes) return;
            build(face);
            const double error = march_map_error(marched, exact, threads);
            if (error <= need) {
                bytes += marched.bytes();
                return;
            }
            marched.map.reset(), marched.sun_map.reset();
            // The next size, if the error could fall to the need by the largest one: by the
            // fall measured from the last size, or before that by kMapFallBound a doubling.
            const double fall = last_error > 0.0 ? std::max(1.0, last_error / error) : kMapFallBound;
            last_error = error;
            if (error * std::pow(double(face) / max_face, std::log2(fall)) > need) return;
            face *= 2;
        }
    };
    for (size_t l = 0; l < march.size(); ++l) {
        if (!march[l]) continue;
        MarchedLight marched;
        marched.light = l;
        if (l >= P) {  // a sun: columns along it over the cloud's shade (a sixth of a point's bytes a face)
            const Vec3 u = -gaussian_suns_[l - P].w;
            search(marched, [&](int face) {
                       marched.sun_map = std::make_unique<SunDepthMap>(*gaussian_, u, face, kMarchMapRadial, threads);
                   },
                   std::size_t(kMarchMapRadial) * sizeof(float), kSunMapMaxFace);
        } else {
            // A spot's map holds its cone alone (a sixth of the sphere for a 60 degree one).
            const SpotCone* cone = l >= n_gaussian_points_ ? &gaussian_spots_[l - n_gaussian_points_].cone : nullptr;
            const Vec3 axis = cone ? cone->axis : Vec3(0.0, 0.0, -1.0);
            const double half_angle = cone ? std::acos(std::clamp(cone->cos_half_angle, -1.0, 1.0)) : kPi;
            search(marched, [&](int face) {
                       marched.map = std::make_unique<LightDepthMap>(*gaussian_, gaussian_lights_[l], axis, half_angle,
                                                                     face, kMarchMapRadial, threads);
                   },
                   std::size_t(6) * kMarchMapRadial * sizeof(float), kMarchMapMaxFace);
        }
        marched_.push_back(std::move(marched));
    }
    all_marched_ = marched_.size() == march.size();
}

RGB FogEvaluator::march_light(const MarchedLight& marched, bool mapped, const Vec3& o, const Vec3& d, double len,
                              GaussianMarch& march) const {
    const size_t l = marched.light, P = gaussian_lights_.size();
    march.set_accuracy(refine_target_);
    if (l >= P)
        return gaussian_march_sun_rgb(*gaussian_, -gaussian_suns_[l - P].w, fog_top_, phase_, o, d, len,
                                      mapped ? marched.sun_map.get() : nullptr, march);
    if (l >= n_gaussian_points_) {  // a spot (its profile at most 1, or a Spread's peak)
        const SpotCone& cone = gaussian_spots_[l - n_gaussian_points_].cone;
        march.cone = &cone;
        march.emission_max = cone.has_spread() ? std::max(1.0, cone.spread_a) : 1.0;
    }
    return gaussian_march_airlight_rgb(*gaussian_, gaussian_lights_[l], phase_, o, d, len,
                                       mapped ? marched.map.get() : nullptr, march);
}

double FogEvaluator::march_map_error(const MarchedLight& marched, std::vector<double>& exact, int threads) const {
    // Rays from the eye through kMapCheckRays Gaussians' centres (picked evenly through the
    // list of those the light reaches: a spot's, in its cone; to twice the centre's distance),
    // on which the fog is. A cone that holds fewer centres (a broad Gaussian through it, centred
    // elsewhere) is checked through points on its axis at the Gaussians' distances from the
    // light too: with none the check passed any map. And a point or spot light's map through
    // points 1/2, 1, 2 and 4 of its radial steps from the light (on a spot's axis, else across
    // the view of the light): a read there interpolates from the light's own 0, which errs
    // most where a Gaussian near the light is narrower than the step (a broad one, whose cull
    // sphere sets the map's reach, beside a small one: a spot's fog 1.7x too bright).
    constexpr int kMapCheckRays = 16;
    const size_t l = marched.light;
    const SpotCone* cone = l >= n_gaussian_points_ && l < gaussian_lights_.size()
                               ? &gaussian_spots_[l - n_gaussian_points_].cone
                               : nullptr;
    std::vector<Vec3> reached;
    for (size_t j = 0; j < gaussian_->size(); ++j) {
        const Vec3 u = cone ? gaussian_->centre(j) - gaussian_lights_[l] : Vec3(0.0);
        if (!cone || spot_profile(*cone, glm::dot(cone->axis, u) / std::max(glm::length(u), 1e-300)) > 0.0)
            reached.push_back(gaussian_->centre(j));
    }
    const size_t N = gaussian_->size();
    for (size_t k = 0; cone && reached.size() < size_t(kMapCheckRays) && k < std::min<size_t>(N, kMapCheckRays); ++k) {
        const Vec3& s = gaussian_lights_[l];
        reached.push_back(s + glm::length(gaussian_->centre(k * N / kMapCheckRays) - s) * cone->axis);
    }
    const size_t n = reached.size();
    std::vector<Vec3> targets;
    for (size_t k = 0; n > 0 && k < size_t(kMapCheckRays); ++k) targets.push_back(reached[k * n / kMapCheckRays]);
    if (marched.map && n > 0) {
        const Vec3& s = gaussian_lights_[l];
        Vec3 across = glm::cross(s - origin_, Vec3(0.0, 0.0, 1.0));
        if (!(glm::length(across) > 1e-9 * glm::length(s - origin_))) across = glm::cross(s - origin_, Vec3(1.0, 0.0, 0.0));
        const Vec3 u = cone ? cone->axis : glm::normalize(across);
        for (double steps : {0.5, 1.0, 2.0, 4.0}) targets.push_back(s + steps * marched.map->radial_step() * u);
    }
    const size_t rays = targets.size();
    const bool first = exact.empty();
    exact.resize(rays);
    std::vector<double> mapped(rays, 0.0);
    parallel_chunks(rays, threads, 1, [&](size_t begin, size_t end) {
        for (size_t k = begin; k < end; ++k) {
            const Vec3 to = targets[k] - origin_;
            const double D = glm::length(to);
            if (!(D > 0.0)) continue;
            build_progress_check();  // (the bake's bar and cancel through the check's marches)
            GaussianMarch with_map, exact_depths;  // (unit albedos: the channels agree)
            mapped[k] = march_light(marched, true, origin_, to / D, 2.0 * D, with_map).x;
            if (first) exact[k] = march_light(marched, false, origin_, to / D, 2.0 * D, exact_depths).x;
        }
    });
    double worst = 0.0;
    for (size_t k = 0; k < rays; ++k)
        if (exact[k] > 0.0) worst = std::max(worst, std::abs(mapped[k] - exact[k]) / exact[k]);
    return worst;
}

double FogEvaluator::uniform_fog_bound(const Vec3& d, double D1, double D2) const {
    const double beta0 = gaussian_->beta0();
    if (!(beta0 > 0.0) || !(D2 > D1)) return 0.0;
    const double p_max = std::max(phase_.eval(1.0), phase_.eval(-1.0));
    const RGB sigma_s = beta0 * medium_albedo_;
    const double fade = std::exp(-beta0 * D1);  // (the view's transmittance from D1 on is below it)
    double bound = 0.0;
    // A point or spot light: sigma_s I p e^{-beta0 D1} times the integral of 1 / |x(t) - s|^2
    // over [D1, D2], (atan((D2 - t_s) / h) - atan((D1 - t_s) / h)) / h at closest approach h.
    for (size_t l = 0; l < gaussian_lights_.size(); ++l) {
        double emission = 1.0;
        if (l >= n_gaussian_points_) {
            const SpotCone& cone = gaussian_spots_[l - n_gaussian_points_].cone;
            emission = cone.has_spread() ? std::max(1.0, cone.spread_a) : 1.0;
        }
        const Vec3 rel = gaussian_lights_[l] - origin_;
        const double t_s = glm::dot(rel, d), h = std::sqrt(std::max(0.0, glm::dot(rel, rel) - t_s * t_s));
        if (!(h > 0.0)) return std::numeric_limits<double>::infinity();
        const double a2 = std::isinf(D2) ? 0.5 * kPi : std::atan((D2 - t_s) / h);
        const double span = (a2 - std::atan((D1 - t_s) / h)) / h;
        bound += glm::dot(sigma_s, gaussian_I0_[l]) * p_max * emission * fade * span;
    }
    // A sun: sigma_s E p times the integral of e^{-beta0 t} over [D1, D2].
    for (const GaussianSunData& sun : gaussian_suns_)
        bound += glm::dot(sigma_s, sun.E) * p_max * (fade - (std::isinf(D2) ? 0.0 : std::exp(-beta0 * D2))) / beta0;
    return bound;
}

int FogEvaluator::gaussian_volume(size_t l) const {
    if (!shadows_) return -1;
    const size_t P = gaussian_lights_.size();
    if (l < n_gaussian_points_) return light_volume_[l];
    return l < P ? spot_volume_[l - n_gaussian_points_] : sun_volume_[l - P];
}

double FogEvaluator::gaussian_profile(size_t l, const Vec3& u) const {
    if (l < n_gaussian_points_ || l >= gaussian_lights_.size()) return 1.0;
    const SpotCone& cone = gaussian_spots_[l - n_gaussian_points_].cone;
    return spot_profile(cone, glm::dot(cone.axis, u));
}


void FogEvaluator::refine_gaussians(const Ray* rays, const float* Dvp, const float* t0, int n, RGB* La) const {
    if (!refiner_ || refine_abandoned_.load(std::memory_order_relaxed)) return;
    const std::uint64_t work_start = refine_work();
    // While the budget is counted, this call may do what is left of it (scaled by the
    // foresight's factor while that runs): past that the frame is over it whatever the other
    // threads do, and the refinement stops within one integrand evaluation.
    struct Limit {
        ~Limit() { refine_work_limit() = std::numeric_limits<std::uint64_t>::max(); }
    } reset_limit;
    if (refine_counting_.load(std::memory_order_relaxed)) {
        const double left = double(refine_budget_) / refine_scale_.load() - double(refine_spent_.load());
        if (!(left > 0.0)) {
            refine_abandoned_.store(true);
            return;
        }
        refine_work_limit() = work_start + std::uint64_t(std::min(left, 1e18));
    }
    try {
        refine_rays(rays, Dvp, t0, n, La);
    } catch (const RefineWorkExceeded&) {
        refine_spent_.fetch_add(refine_work() - work_start);
        refine_abandoned_.store(true);
        return;
    }
    if (refine_counting_.load(std::memory_order_relaxed)) {
        const std::uint64_t spent = refine_spent_.fetch_add(refine_work() - work_start) + (refine_work() - work_start);
        if (spent > refine_budget_) refine_abandoned_.store(true);
    }
}

void FogEvaluator::refine_rays(const Ray* rays, const float* Dvp, const float* t0, int n, RGB* La) const {
    const LitIntervals* lit = nullptr;
    thread_local GaussianRefiner::ViewDepth view;
    const bool background = gaussian_->beta0() > 0.0;
    if (shadows_) lit = lit_intervals(rays, t0, Dvp, n);
    for (int k = 0; k < n; ++k) {
        const double near = t0 ? double(t0[k]) : 0.0, end = double(Dvp[k]);
        if (!(end > near)) continue;
        const Vec3 d = rays[k].d;
        march_lights(d, near, end, lit ? &lit[k] : nullptr, La[k]);
        if (background)
            refine_background(d, near, end, eye_fogshop_->near_depth(d, near), lit ? &lit[k] : nullptr, view, La[k]);
    }
}

void FogEvaluator::march_lights(const Vec3& d, double near, double end, const LitIntervals* lit, RGB& La) const {
    const size_t A = gaussian_lights_.size() + gaussian_suns_.size();
    thread_local std::vector<RaySpans> spans;
    thread_local std::vector<std::pair<double, double>> shifted;
    const std::pair<double, double> whole(near, end);
    const Vec3 o = origin_ + near * d;
    spans.assign(A, RaySpans{});  // the marched lights' spans, for their Fogshop values in one sum
    bool any = false;
    RGB sum(0.0);
    for (const MarchedLight& light : marched_) {
        const size_t l = light.light;
        RaySpans lit_spans{&whole, 1};
        const int v = gaussian_volume(l);
        if (v >= 0 && lit && !fully_lit(*lit, v, near, end))
            lit_spans = RaySpans{lit->spans.data() + lit->begin[v], lit->end[v] - lit->begin[v]};
        if (lit_spans.count == 0) continue;  // (in the dark Fogshop's value is 0 too)
        GaussianMarch march;
        march.albedo = gaussian_albedo_.data();
        march.medium_albedo = medium_albedo_;
        // Its work in refine_work's units (one Gaussian's term of an integrand, kMarchWorkPerUnit
        // of the march's), stopped at the limit.
        const std::uint64_t left = refine_work_limit() - std::min(refine_work(), refine_work_limit());
        march.work_limit = long(std::min<double>(double(left) * kMarchWorkPerUnit, 9e18));
        RaySpans march_spans;
        if (lit_spans.spans != &whole) {  // (the march's t starts at the near plane)
            shifted.clear();
            for (int q = 0; q < lit_spans.count; ++q)
                shifted.emplace_back(lit_spans.spans[q].first - near, lit_spans.spans[q].second - near);
            march_spans = RaySpans{shifted.data(), int(shifted.size())};
            march.lit = &march_spans;
        }
        const size_t P = gaussian_lights_.size();
        const RGB weight = l < P ? gaussian_I0_[l] : gaussian_suns_[l - P].E;
        const RGB marched = weight * march_light(light, true, o, d, end - near, march);
        refine_work() += std::uint64_t(march.work / kMarchWorkPerUnit);
        if (march.stopped) throw RefineWorkExceeded{};
        spans[l] = lit_spans;
        any = true;
        sum += marched;
        marched_rays_.fetch_add(1, std::memory_order_relaxed);
    }
    // With every light marched the ray's airlight is theirs alone; else the marched lights'
    // replace the Fogshop values the splat added (in float as the splat's kernels have them:
    // the terms in double were a third of the refinement's time).
    if (all_marched_)
        La = sum;
    else if (any)
        La += sum - fogshop_spans(*eye_fogshop_, true, d, near, spans.data(), true);
}

RGB FogEvaluator::fogshop_spans(const FogshopAirlight& fogshop, bool at_eye, const Vec3& d, double near,
                                const RaySpans* spans, bool fast) const {
    const size_t P = gaussian_lights_.size(), S = gaussian_suns_.size();
    thread_local std::vector<RGB> weights;  // I0 of the positional lights, then the suns' E
    weights.assign(gaussian_I0_.begin(), gaussian_I0_.begin() + std::ptrdiff_t(P));
    for (size_t j = 0; j < S; ++j) weights.push_back(gaussian_suns_[j].E);
    // The splat's background term with the bake's model (its own for other phases and models).
    const bool own = !isotropic_ || model_.own_gaussian_background();
    // (Suns: sunlight_span's factor, attenuated from the fog's start as eval_rgb_spans asks.)
    const FogshopAirlight::SpanBackground background = [&](size_t l, double ta, double tb) {
        if (l < P) return gaussian_background(l, d, ta, tb);
        const GaussianSunData& sun = gaussian_suns_[l - P];
        return sigma_t_ * phase_.eval(-glm::dot(sun.w, d)) *
               sunlight_span(sigma_t_, fog_top_, sun.mu_s, origin_, d, near, ta, tb);
    };
    const bool spots = P > n_gaussian_points_;
    const FogshopAirlight::SpanBackground* bg = (own || spots || S > 0) && at_eye ? &background : nullptr;
    const FogshopAirlight::SpanProfile profile = [&](size_t l, const Vec3& u) { return gaussian_profile(l, u); };
    const PhaseFunction* phase = isotropic_ ? nullptr : &phase_;
    return fogshop.eval_rgb_spans(d, at_eye ? near : 0.0, spans, gaussian_albedo_.data(), weights.data(),
                                  medium_albedo_, phase, bg, spots ? &profile : nullptr, fast);
}

bool FogEvaluator::same_ratio_depths(const Vec3& d, double D1, double D2, double value, double tol) const {
    if (std::isinf(D1) || std::isinf(D2)) {
        if (std::isinf(D1) && std::isinf(D2)) return true;
    } else if (std::abs(1.0 / D1 - 1.0 / D2) <= 0.01 / D1) {
        return true;
    }
    const double near = std::min(D1, D2), far = std::max(D1, D2);
    return near >= gaussians_end_ && uniform_fog_bound(d, near, far) <= tol * value;
}

bool FogEvaluator::frame_ratio(const Vec3& d, double Dvp, const RGB& fogshop, RGB& ratio) const {
    // The four pixel centres around the sample: those on its surface give their ratios, which
    // must agree within half the asked accuracy (a shadow's or a spot's edge, a Gaussian's
    // centre crossing a cone, part them), at least two of them; a dark one among lit ones (no
    // Fogshop fog) is such an edge too. The sample takes their bilinear mean.
    const RefinedFrame& f = *refined_frame_;
    const Vec3 q = f.to_film * d;
    if (!(q.z > 0.0) || fogshop.x <= 0.0 || fogshop.y <= 0.0 || fogshop.z <= 0.0) return false;
    const double u = q.x / q.z - 0.5, v = q.y / q.z - 0.5;
    if (!(u >= 0.0 && v >= 0.0 && u < f.W - 1 && v < f.H - 1)) return false;
    const int i0 = int(u), j0 = int(v);
    const double fu = u - i0, fv = v - j0;
    const double tol = 0.5 * refine_target_;
    const double value = fogshop.x + fogshop.y + fogshop.z;
    RGB sum(0.0), lo(std::numeric_limits<double>::infinity()), hi(0.0);
    double weights = 0.0;
    int found = 0;
    for (int c = 0; c < 4; ++c) {
        const int i = i0 + (c & 1), j = j0 + (c >> 1);
        const size_t p = size_t(j) * f.W + i;
        const double w = (c & 1 ? fu : 1.0 - fu) * (c >> 1 ? fv : 1.0 - fv);
        const float* F = &f.fogshop[3 * p];
        const float* R = &f.refined[3 * p];
        if (!(F[0] > 0.0f && F[1] > 0.0f && F[2] > 0.0f)) return false;
        if (!same_ratio_depths(d, Dvp, double((*f.depth)[p]), value, 0.5 * tol)) continue;
        const RGB r(R[0] / F[0], R[1] / F[1], R[2] / F[2]);
        lo = glm::min(lo, r), hi = glm::max(hi, r);
        sum += w * r, weights += w, ++found;
    }
    if (found < 2 || !(weights > 0.0)) return false;
    for (int c = 0; c < 3; ++c)
        if (!(hi[c] - lo[c] <= tol * lo[c])) return false;
    ratio = sum / weights;
    return true;
}

void FogEvaluator::refine_samples(const Ray* rays, const float* Dvp, const float* t0, int n, RGB* La) const {
    if (!refiner_) return;
    // The refined / Fogshop ratio varies over several pixels (refine_pass interpolates it over
    // cells): a ray within kSampleReach pixels of one of the last refined ones, on the same
    // surface (inverse depths within 1 %, or both the sky), whose Fogshop value is within a
    // quarter of the asked accuracy of that ray's, takes its ratio. (Without the last test a
    // spot's edge, where Fogshop's value steps as Gaussians' centres cross the cone, carried
    // ratios 2 % off along the horizon whatever the accuracy.)
    constexpr double kSampleReach = 2.0;
    const double cos_reach = std::cos(kSampleReach * pixel_angle_);
    // The last few refined rays (the samples of an edge pixel alternate between surfaces).
    constexpr int kReps = 8;
    struct Rep {
        int k;
        RGB ratio, delta, fogshop;
    };
    Rep reps[kReps];
    int n_reps = 0, next = 0;
    auto close = [&](int k, const Rep& rep) {
        const int r = rep.k;
        if (glm::dot(rays[k].d, rays[r].d) < cos_reach) return false;
        for (int c = 0; c < 3; ++c) {
            const double fogshop = La[k][c], there = rep.fogshop[c];
            if (fogshop != there && !(std::abs(fogshop - there) <= 0.25 * refine_target_ * there)) return false;
        }
        if (std::isinf(Dvp[k]) || std::isinf(Dvp[r])) return std::isinf(Dvp[k]) && std::isinf(Dvp[r]);
        return std::abs(1.0 / Dvp[k] - 1.0 / Dvp[r]) <= 0.01 / Dvp[k];
    };
    for (int k = 0; k < n; ++k) {
        RGB ratio;
        if (refined_frame_ && frame_ratio(rays[k].d, Dvp[k], La[k], ratio)) {
            La[k] *= ratio;
            continue;
        }
        const Rep* match = nullptr;
        for (int q = 0; q < n_reps && !match; ++q)
            if (close(k, reps[q])) match = &reps[q];
        if (match) {
            for (int c = 0; c < 3; ++c) La[k][c] = La[k][c] * match->ratio[c] + match->delta[c];
            continue;
        }
        const RGB fogshop = La[k];
        refine_gaussians(rays + k, Dvp + k, t0 ? t0 + k : nullptr, 1, La + k);
        Rep& rep = reps[next];
        next = (next + 1) % kReps, n_reps = std::min(n_reps + 1, kReps);
        rep.k = k, rep.fogshop = fogshop;
        for (int c = 0; c < 3; ++c) {
            rep.ratio[c] = fogshop[c] > 0.0 ? La[k][c] / fogshop[c] : 1.0;
            rep.delta[c] = fogshop[c] > 0.0 ? 0.0 : La[k][c];
        }
    }
}

void FogEvaluator::refine_background(const Vec3& d, double near, double end, double Tg_near, const LitIntervals* lit,
                                     GaussianRefiner::ViewDepth& view, RGB& La) const {
    // Fogshop's uniform-fog term of light l is C_l times the homogeneous term H_l; the exact one
    // differs by at most H_l background_bound (refine.h). Rays where that stays under half the
    // asked accuracy of the ray's airlight keep Fogshop's; the others take the difference.
    const size_t P = gaussian_lights_.size(), A = P + gaussian_suns_.size();
    const double budget = kBackgroundShare * refine_target_ * (La.x + La.y + La.z);
    const std::pair<double, double> whole(near, end);
    constexpr double kInf = std::numeric_limits<double>::infinity();
    double T_view = kInf;
    for (size_t l = 0; l < A; ++l) {
        if (std::any_of(marched_.begin(), marched_.end(), [&](const MarchedLight& m) { return m.light == l; }))
            continue;  // (march_lights)
        RaySpans spans{&whole, 1};
        const int v = gaussian_volume(l);
        if (v >= 0 && lit && !fully_lit(*lit, v, near, end))
            spans = RaySpans{lit->spans.data() + lit->begin[v], lit->end[v] - lit->begin[v]};
        if (spans.count == 0) continue;
        const RGB w = medium_albedo_ * (l < P ? gaussian_I0_[l] : gaussian_suns_[l - P].E);
        const double weight = w.x + w.y + w.z;
        if (!(weight > 0.0)) continue;
        // (The splat's factor: C_l, less what it counts before the near plane.)
        const double C = eye_fogshop_->background_factor(l) * std::exp(Tg_near);
        const double H = refiner_->plain_background(l, d, near, spans, 0.1);
        if (!(H > 0.0)) continue;
        if (H * weight * refiner_->background_bound(T_view, C) <= budget) continue;
        if (std::isinf(T_view)) {  // the ray's own Gaussians: a tighter bound, and the correction's view side
            refiner_->gather(d, near, end, view);
            T_view = view.total();
            if (H * weight * refiner_->background_bound(T_view, C) <= budget) continue;
        }
        // To a tenth of the uniform fog's share of the accuracy, relative to its term here.
        La += w * refiner_->background_correction(l, d, near, spans, view, C, 0.05 * refine_target_ * H);
        background_rays_.fetch_add(1, std::memory_order_relaxed);
    }
}

void FogEvaluator::set_up_shadows(const SceneDescription& scene, const BakeSettings& settings) {
    const TriangleMesh& casters = scene.occluders_from_geometry ? scene.geometry : scene.occluders;
    if (casters.triangles.empty()) return;
    std::vector<ShadowLight> lights;
    // Per light of the scene: -1 in _scene_ (and nothing in _kept_) for a light the fog drops,
    // else its (first) volume (-1: Cast Shadow off) in both; _samples_ its volumes' count.
    auto place = [&](std::vector<int>& scene_list, std::vector<int>& kept, std::vector<int>* samples, bool keeps,
                     bool casts, const std::vector<ShadowLight>& light) {
        scene_list.push_back(-1);
        if (!keeps) return;
        kept.push_back(casts ? int(lights.size()) : -1);
        if (casts) lights.insert(lights.end(), light.begin(), light.end());
        if (samples) samples->push_back(casts ? int(light.size()) : 1);
        scene_list.back() = kept.back();
    };
    // A point or spot light's shadow samples: its centre, or points of its sphere.
    const std::vector<Vec3> offsets = sphere_light_shadow_samples(gaussian_ ? 1 : settings.shadow_samples);
    auto positional = [&](const Vec3& s, double radius) {
        std::vector<ShadowLight> out;
        for (const Vec3& q : radius > 0.0 ? offsets : std::vector<Vec3>{Vec3(0.0)}) {
            out.emplace_back();
            out.back().position = s + radius * q;
        }
        return out;
    };
    auto nonzero = [](const RGB& w) { return w.x != 0.0 || w.y != 0.0 || w.z != 0.0; };
    for (const PointLight& light : scene.point_lights)
        place(scene_point_volume_, light_volume_, &light_samples_, keeps_light(scene, light), light.casts_shadow,
              positional(light.position, light.radius));
    // (With Gaussians, spot_volume_ and sun_volume_ follow gaussian_spots_ and gaussian_suns_.)
    for (const SpotLight& spot : scene.spot_lights)
        place(scene_spot_volume_, spot_volume_, &spot_samples_,
              nonzero(gaussian_ ? spot.I0 : scene.medium.albedo * spot.I0), spot.casts_shadow,
              positional(spot.position, spot.radius));
    for (const SunLight& sun : scene.sun_lights) {
        // A sun's: its direction, or directions over its disk (Angle).
        std::vector<ShadowLight> samples;
        for (const Vec3& w : sun_shadow_directions(glm::normalize(sun.direction), sun.angle,
                                                   gaussian_ ? 1 : settings.shadow_samples)) {
            samples.emplace_back();
            samples.back().directional = true;
            samples.back().direction = w;
        }
        place(scene_sun_volume_, sun_volume_, &sun_samples_,
              nonzero(gaussian_ ? sun.E : scene.medium.albedo * sun.E * sigma_t_), sun.casts_shadow, samples);
    }
    if (lights.empty()) return;
    for (const LightData& light : lights_) light_peak_.push_back(std::max({light.weight.x, light.weight.y, light.weight.z}));
    // The casters the camera's rays end on: all of them, or the occluders' leading ones.
    const size_t seen = scene.occluders_from_geometry ? casters.triangles.size() / 3 : scene.occluders_seen_triangles;
    const auto volumes_start = std::chrono::steady_clock::now();
    shadows_ = ShadowVolumes::shared(casters, lights, origin_, seen, resolve_threads(settings.threads));
    seconds_shadow_volumes_ = std::chrono::duration<double>(std::chrono::steady_clock::now() - volumes_start).count();
    if (shared_origin_) {
        // An eye on a frustum boundary (in the plane of a light and a caster's edge) has no
        // one count for all its rays: each ray then counts at its own start (lit_intervals).
        for (int v = 0; v < shadows_->num_lights(); ++v) {
            bool ambiguous = false;
            origin_count_.push_back(shadows_->count_at(v, origin_, &ambiguous));
            origin_ambiguous_ = origin_ambiguous_ || ambiguous;
        }
        const CameraRays camera(scene.camera);
        if (!origin_ambiguous_ && camera.affine_perspective() && camera.position() == origin_) {
            Vec3 D0, Dx, Dy;
            camera.affine_direction(D0, Dx, Dy);
            // Casters that are the camera's geometry end the rays that meet them: their caps
            // count only within the near clip (from the eye to a ray's start, at most
            // clip_start over the smallest cosine of a film corner's ray to the view axis) and
            // past the far clip (a distance >= clip_end, the view-axis depth), where rays pass
            // surfaces they do not see. The film and the traced rays both leave the others out.
            if (seen > 0) {
                double cos_min = 1.0;
                const int W = scene.camera.width, H = scene.camera.height;
                for (const glm::dvec2 c : {glm::dvec2(-4, -4), glm::dvec2(W + 4, -4), glm::dvec2(-4, H + 4), glm::dvec2(W + 4, H + 4)})
                    cos_min = std::min(cos_min, glm::dot(glm::normalize(D0 + c.x * Dx + c.y * Dy), camera.forward()));
                if (cos_min > 0.0)
                    cap_cut_ = CapCut{2.0 * camera.clip_start() / cos_min, camera.clip_end(), origin_};
            }
            // The camera's own rays (all from origin_) take their crossings from the film.
            if (!settings.shadow_crossings_traced) {
                screen_ = std::make_unique<ScreenCrossings>(*shadows_, origin_, D0, Dx, Dy, scene.camera.width,
                                                            scene.camera.height, cap_cut_.reach, camera.clip_end(),
                                                            resolve_threads(settings.threads));
                if (!screen_->ready()) screen_.reset();
            }
        }
    }
    if (gaussian_ && model_.gaussian_method() == GaussianMethod::Fogshop && shared_origin_) {
        std::vector<Vec3> sun_dirs;
        for (const GaussianSunData& sun : gaussian_suns_) sun_dirs.push_back(sun.w);
        eye_fogshop_ = std::make_unique<FogshopAirlight>(*gaussian_, origin_, gaussian_lights_, model_.f_table(),
                                                         std::max(0, settings.threads), sun_dirs, fog_top_);
    }
}

void FogEvaluator::shadow_gaussians(const Ray* rays, const float* Dvp, const float* t0, int n, RGB* La) const {
    if (!shadows_ || !gaussian_ || model_.gaussian_method() != GaussianMethod::Fogshop) return;
    // The point lights, then (perspective: the splat takes spots and suns there only) the
    // spots and the suns.
    const size_t P = eye_fogshop_ ? gaussian_lights_.size() : n_gaussian_points_;
    const size_t S = eye_fogshop_ ? gaussian_suns_.size() : 0, A = P + S;
    auto volume = [&](size_t l) {
        return l < n_gaussian_points_ ? light_volume_[l] : l < P ? spot_volume_[l - n_gaussian_points_] : sun_volume_[l - P];
    };
    bool any = false;
    for (size_t l = 0; l < A; ++l) any = any || volume(l) >= 0;
    if (!any) return;
    const LitIntervals* lit = lit_intervals(rays, t0, Dvp, n);
    thread_local std::vector<RaySpans> with, whole;
    thread_local std::vector<std::pair<double, double>> lit_spans, full_spans;
    with.resize(A), whole.resize(A);
    for (int k = 0; k < n; ++k) {
        const double near = t0 ? double(t0[k]) : 0.0, end = double(Dvp[k]);
        if (!(end > near)) continue;
        bool partial = false;
        for (size_t l = 0; l < A; ++l) {
            const int v = volume(l);
            partial = partial || (v >= 0 && !fully_lit(lit[k], v, near, end));
        }
        if (!partial) continue;
        // Perspective: Fogshop at the eye, t from it; orthographic: set up at the near point.
        std::unique_ptr<FogshopAirlight> local;
        if (!eye_fogshop_)
            local = std::make_unique<FogshopAirlight>(*gaussian_, rays[k].o + near * rays[k].d,
                                                      std::vector<Vec3>(gaussian_lights_.begin(),
                                                                        gaussian_lights_.begin() + std::ptrdiff_t(P)),
                                                      model_.f_table(), 1);
        const FogshopAirlight& fogshop = eye_fogshop_ ? *eye_fogshop_ : *local;
        const double shift = eye_fogshop_ ? 0.0 : near;
        lit_spans.clear(), full_spans.clear();
        lit_spans.reserve(lit[k].spans.size()), full_spans.reserve(A);
        for (size_t l = 0; l < A; ++l) {
            const int v = volume(l);
            with[l] = whole[l] = RaySpans{};
            if (v < 0 || fully_lit(lit[k], v, near, end)) continue;
            const size_t first = lit_spans.size();
            for (int q = lit[k].begin[v]; q < lit[k].end[v]; ++q)
                lit_spans.emplace_back(lit[k].spans[q].first - shift, lit[k].spans[q].second - shift);
            with[l] = RaySpans{lit_spans.data() + first, int(lit_spans.size() - first)};
            full_spans.emplace_back(near - shift, end - shift);
            whole[l] = RaySpans{&full_spans.back(), 1};
        }
        const Vec3 d = rays[k].d;
        La[k] += fogshop_spans(fogshop, bool(eye_fogshop_), d, near, with.data()) -
                 fogshop_spans(fogshop, bool(eye_fogshop_), d, near, whole.data());
    }
}

const uint32_t* FogEvaluator::shadow_masks(const float* values, int m) const {
    struct Masks {
        std::vector<uint32_t> masks;
    };
    std::vector<uint32_t>& masks = thread_scratch<Masks>().masks;
    masks.assign(size_t(m), 0u);
    uint32_t always = 0;  // spots and suns: no unshadowed value to weigh them by
    for (size_t i = 0; i < spot_volume_.size(); ++i)
        if (spot_volume_[i] >= 0) always |= sample_mask(spot_volume_[i], spot_samples_[i]);
    for (size_t i = 0; i < sun_volume_.size(); ++i)
        if (sun_volume_[i] >= 0) always |= sample_mask(sun_volume_[i], sun_samples_[i]);
    const size_t L = lights_.size();
    for (int k = 0; k < m; ++k) {
        double total = 0.0;
        for (size_t l = 0; l < L; ++l) total += light_peak_[l] * double(values[l * size_t(m) + k]);
        uint32_t mask = always;
        for (size_t l = 0; l < L; ++l)
            if (light_volume_[l] >= 0 && light_peak_[l] * double(values[l * size_t(m) + k]) > kShadowCull * total)
                mask |= sample_mask(light_volume_[l], light_samples_[l]);
        masks[size_t(k)] = mask;
    }
    return masks.data();
}

void FogEvaluator::relight_spans(const LightData& light, int v, const double* cos_gamma, const float* near,
                                 const float* Dvp, int m, const LitIntervals* lit, float* value) const {
    // The batch's value stands where the ray is lit all along; elsewhere the lit spans [a, b]
    // of every ray go through the same SIMD kernel as segments from the eye (its near
    // distance a, attenuated from there), each times e^{-sigma_t (a - t_start)}.
    struct Spans {
        std::vector<double> cos;
        std::vector<float> a, b, value;
        std::vector<int> ray;
    };
    Spans& spans = thread_scratch<Spans>();
    std::vector<double>& span_cos = spans.cos;
    std::vector<float>&span_a = spans.a, &span_b = spans.b, &span_value = spans.value;
    std::vector<int>& span_ray = spans.ray;
    span_cos.clear(), span_a.clear(), span_b.clear(), span_ray.clear();
    for (int k = 0; k < m; ++k) {
        const double t_start = near ? double(near[k]) : 0.0;
        if (!(lit[k].partial & ShadowVolumes::light_mask(v)) || fully_lit(lit[k], v, t_start, double(Dvp[k])))
            continue;
        value[k] = 0.0f;
        for (int q = lit[k].begin[v]; q < lit[k].end[v]; ++q) {
            span_cos.push_back(cos_gamma[k]);
            span_a.push_back(float(lit[k].spans[q].first));
            span_b.push_back(float(lit[k].spans[q].second));
            span_ray.push_back(k);
        }
    }
    if (span_ray.empty()) return;
    const SpecialFTable& table = *model_.f_table();
    span_value.resize(span_ray.size());
    sun05_airlight_table_batch(table.data().data(), table.nu(), table.nT(), sigma_t_, light.Dsv, span_cos.data(),
                               span_b.data(), int(span_ray.size()), span_value.data(), span_a.data(), table.interp());
    for (size_t q = 0; q < span_ray.size(); ++q) {
        const int k = span_ray[q];
        const double t_start = near ? double(near[k]) : 0.0;
        value[k] += float(std::exp(-sigma_t_ * (double(span_a[q]) - t_start)) * double(span_value[q]));
    }
}

void FogEvaluator::relight_samples(const LightData& light, int v, int n, const double* cos_gamma, const float* near,
                                   const float* Dvp, int m, const LitIntervals* lit, float* value) const {
    if (n <= 1) return relight_spans(light, v, cos_gamma, near, Dvp, m, lit, value);
    struct Samples {
        std::vector<float> unshadowed, one;
        std::vector<double> sum;
    };
    Samples& s = thread_scratch<Samples>();
    s.unshadowed.assign(value, value + m);
    s.sum.assign(size_t(m), 0.0);
    for (int j = 0; j < n; ++j) {
        s.one = s.unshadowed;
        relight_spans(light, v + j, cos_gamma, near, Dvp, m, lit, s.one.data());
        for (int k = 0; k < m; ++k) s.sum[size_t(k)] += double(s.one[size_t(k)]);
    }
    for (int k = 0; k < m; ++k) value[k] = float(s.sum[size_t(k)] / n);
}

const LitIntervals* FogEvaluator::lit_intervals(const Ray* rays, const float* t0, const float* t1, int n,
                                                const uint32_t* masks, const glm::dvec2* film) const {
    struct Scratch {
        std::vector<LitIntervals> lit;
        std::vector<float> zeros;
        std::vector<int> counts;
        std::vector<std::vector<Crossing>> lists;
    };
    Scratch& scratch = thread_scratch<Scratch>();
    std::vector<LitIntervals>& lit = scratch.lit;
    std::vector<float>& zeros = scratch.zeros;
    std::vector<int>& counts = scratch.counts;
    if (lit.size() < size_t(n)) lit.resize(size_t(n));
    if (!t0) {
        zeros.assign(size_t(n), 0.0f);
        t0 = zeros.data();
    }
    const int L = shadows_->num_lights();
    if (screen_ && film && shared_origin_ && !origin_ambiguous_) {  // (each ray counts from the eye)
        std::vector<std::vector<Crossing>>& lists = scratch.lists;
        if (lists.size() < size_t(n)) lists.resize(size_t(n));
        if (screen_->crossings(film, rays, t1, n, lists.data(), masks)) {
            for (int k = 0; k < n; ++k) {
                const uint32_t mask = masks ? masks[k] : 0xFFFFFFFFu;
                if (!(t1[k] > 0.0f) || mask == 0) lists[k].clear();  // not traced either
                ShadowVolumes::lit_from_crossings(lists[k], L, t0[k], t1[k], origin_count_.data(), mask, lit[k]);
            }
            return lit.data();
        }
    }
    const int* count0 = nullptr;
    if (shared_origin_ && !origin_ambiguous_) {
        counts.resize(size_t(n) * L);
        for (int k = 0; k < n; ++k) std::copy(origin_count_.begin(), origin_count_.end(), counts.begin() + size_t(k) * L);
        count0 = counts.data();
    }
    shadows_->lit_intervals(rays, t0, t1, n, count0, lit.data(), masks, cap_cut_);
    return lit.data();
}

std::vector<double> FogEvaluator::span_ends(const LitIntervals& lit, int v, double t_start) {
    std::vector<double> ends;
    for (int k = lit.begin[v]; k < lit.end[v]; ++k) {
        ends.push_back(lit.spans[k].first - t_start);
        ends.push_back(lit.spans[k].second - t_start);
    }
    return ends;
}

double FogEvaluator::point_airlight_lit(const LightData& light, int v, const Vec3& o, const Vec3& d, double t_start,
                                        double t_end, const LitIntervals& lit) const {
    if (model_.visibility_in_integrand()) {
        const Vec3 start = t_start > 0.0 ? o + t_start * d : o;
        const std::vector<double> jumps = span_ends(lit, v, t_start);
        return point_airlight_visible(phase_, sigma_t_, light.s, start, d, t_end - t_start,
                                      [&](const Vec3& p) { return visible(v, p); }, kShadowRelTol, &jumps);
    }
    double sum = 0.0;
    for (int k = lit.begin[v]; k < lit.end[v]; ++k) {
        const double a = lit.spans[k].first, b = lit.spans[k].second;
        const Vec3 x = o + a * d, sv = light.s - x;
        const double Dsv = glm::length(sv);
        const double cos_gamma = Dsv > 0.0 ? std::clamp(glm::dot(d, sv) / Dsv, -1.0, 1.0) : 1.0;
        sum += std::exp(-sigma_t_ * (a - t_start)) * airlight(Dsv, cos_gamma, b - a);
    }
    return sum;
}

double FogEvaluator::gaussian_background(size_t l, const Vec3& d, double t0, double Dvp) const {
    if (sigma_t_ == 0.0 || !(Dvp > t0)) return 0.0;
    const size_t L = gaussian_lights_.size();
    const Vec3 start = t0 > 0.0 ? origin_ + t0 * d : origin_;
    const double seg = Dvp - t0;  // inf stays inf
    if (l < n_gaussian_points_) {
        const Vec3 sv = gaussian_lights_[l] - start;
        const double Dsv = glm::length(sv);
        const double cos_gamma = Dsv > 0.0 ? std::clamp(glm::dot(d, sv) / Dsv, -1.0, 1.0) : 1.0;
        return airlight(Dsv, cos_gamma, seg);
    }
    if (l < L) {
        const GaussianSpotData& spot = gaussian_spots_[l - n_gaussian_points_];
        return spot_closed_form_
                   ? pegoraro10_spot_airlight(pegoraro_phase_, spot.cone, spot.s, sigma_t_, start, d, seg)
                   : spot_airlight_quadrature(spot.cone, spot.s, phase_, sigma_t_, start, d, seg, kSpotRelTol);
    }
    const GaussianSunData& sun = gaussian_suns_[l - L];
    return sigma_t_ * phase_.eval(-glm::dot(sun.w, d)) *
           sunlight_layer_factor(sigma_t_, fog_top_, sun.mu_s, origin_.z, d.z, t0, Dvp);
}

double FogEvaluator::transmittance(const Ray& r, double t0, double depth) const {
    if (!gaussian_) return std::exp(-sigma_t_ * (depth - t0));
    const double seg = std::max(0.0, depth - t0);
    return std::exp(-gaussian_->optical_depth_ray(t0 > 0.0 ? r.o + t0 * r.d : r.o, r.d, seg));
}

void FogEvaluator::transmittance_soa(const float* Dvp, const float* t0, int n, float* Tr) const {
    constexpr int kChunk = 256;
    float seg[kChunk];
    for (int k0 = 0; k0 < n; k0 += kChunk) {
        const int m = std::min(kChunk, n - k0);
        if (t0) {
            for (int k = 0; k < m; ++k) seg[k] = Dvp[k0 + k] - t0[k0 + k];
            transmittance_batch(float(sigma_t_), seg, m, Tr + k0);
        } else {
            transmittance_batch(float(sigma_t_), Dvp + k0, m, Tr + k0);
        }
    }
}

void FogEvaluator::eval_soa(const double* dx, const double* dy, const double* dz, const float* Dvp, const float* t0, int n,
              float* Tr, float* rgb, const glm::dvec2* film, float* passes) const {
    constexpr int kChunk = 256;
    const int G = passes ? n_passes_ : 0;
    // One ray's passes in double, for the per-ray terms (spots, suns, the lights' Radius).
    struct RayPasses {
        std::vector<RGB> passes;
    };
    std::vector<RGB>& ray_passes = thread_scratch<RayPasses>().passes;
    ray_passes.resize(size_t(G));
    // Adds _term_ (the per-ray function, given the ray's passes) to ray k's total and passes.
    auto add_ray_term = [&](float* out, float* grp, auto term) {
        std::fill(ray_passes.begin(), ray_passes.end(), RGB(0.0));
        const RGB La = term(G ? ray_passes.data() : nullptr);
        for (int c = 0; c < 3; ++c) out[c] = float(double(out[c]) + La[c]);
        for (int g = 0; g < G; ++g)
            for (int c = 0; c < 3; ++c) grp[3 * g + c] = float(double(grp[3 * g + c]) + ray_passes[size_t(g)][c]);
    };
    double cos_gamma[kChunk];
    float sum_r[kChunk], sum_g[kChunk], sum_b[kChunk], value[kChunk], seg[kChunk];
    const SpecialFTable& table = *model_.f_table();
    const float* data = table.data().data();
    const int nu = table.nu(), nT = table.nT();
    for (int k0 = 0; k0 < n; k0 += kChunk) {
        const int m = std::min(kChunk, n - k0);
        const float* near = t0 ? t0 + k0 : nullptr;
        if (near) {
            for (int k = 0; k < m; ++k) seg[k] = Dvp[k0 + k] - near[k];
            transmittance_batch(float(sigma_t_), seg, m, Tr + k0);
        } else {
            transmittance_batch(float(sigma_t_), Dvp + k0, m, Tr + k0);
        }
        for (int k = 0; k < m; ++k) sum_r[k] = sum_g[k] = sum_b[k] = 0.0f;
        float* grp = G ? passes + 3 * size_t(G) * size_t(k0) : nullptr;  // the chunk's passes
        if (grp) std::fill(grp, grp + 3 * size_t(G) * size_t(m), 0.0f);
        const LitIntervals* lit = nullptr;
        if (!shadows_) {
            for (const LightData& light : lights_) {
                const Vec3 sv = (light.s - origin_) * (light.Dsv > 0.0 ? 1.0 / light.Dsv : 0.0);
                const bool at_light = !(light.Dsv > 0.0);
                if (at_light) std::fill(cos_gamma, cos_gamma + m, 1.0);
                else cos_to_light(dx + k0, dy + k0, dz + k0, sv, m, cos_gamma);
                sun05_airlight_table_batch(data, nu, nT, sigma_t_, light.Dsv, cos_gamma, Dvp + k0, m, value, near,
                                           table.interp());
                accumulate_rgb(value, float(light.weight.x), float(light.weight.y), float(light.weight.z), m, sum_r,
                               sum_g, sum_b);
                if (grp && light.pass >= 0) accumulate_pass(value, light.weight, m, G, light.pass, grp);
            }
        } else {
            // Volumetric shadows: every light's unshadowed airlight first, then the lit intervals
            // of the lights that matter on each ray (shadow_mask), then the lit spans of the rays
            // a shadow crosses.
            struct Values {
                std::vector<float> values;
                std::vector<double> cosines;
            };
            Values& scratch = thread_scratch<Values>();
            std::vector<float>& values = scratch.values;
            std::vector<double>& cosines = scratch.cosines;
            const size_t L = lights_.size();
            values.resize(L * size_t(m));
            cosines.resize(L * size_t(m));
            for (size_t l = 0; l < L; ++l) {
                const LightData& light = lights_[l];
                double* c = &cosines[l * size_t(m)];
                const Vec3 sv = (light.s - origin_) * (light.Dsv > 0.0 ? 1.0 / light.Dsv : 0.0);
                if (!(light.Dsv > 0.0)) std::fill(c, c + m, 1.0);
                else cos_to_light(dx + k0, dy + k0, dz + k0, sv, m, c);
                sun05_airlight_table_batch(data, nu, nT, sigma_t_, light.Dsv, c, Dvp + k0, m, &values[l * size_t(m)],
                                           near, table.interp());
            }
            Ray rays[kChunk];
            for (int k = 0; k < m; ++k) rays[k] = {origin_, Vec3(dx[k0 + k], dy[k0 + k], dz[k0 + k])};
            lit = lit_intervals(rays, near, Dvp + k0, m, shadow_masks(values.data(), m), film ? film + k0 : nullptr);
            for (size_t l = 0; l < L; ++l) {
                const LightData& light = lights_[l];
                float* v_l = &values[l * size_t(m)];
                if (light_volume_[l] >= 0)
                    relight_samples(light, light_volume_[l], light_samples_[l], &cosines[l * size_t(m)], near,
                                    Dvp + k0, m, lit, v_l);
                accumulate_rgb(v_l, float(light.weight.x), float(light.weight.y), float(light.weight.z), m, sum_r,
                               sum_g, sum_b);
                if (grp && light.pass >= 0) accumulate_pass(v_l, light.weight, m, G, light.pass, grp);
            }
        }
        float* out = rgb + 3 * size_t(k0);
        for (int k = 0; k < m; ++k) {
            out[3 * k] = sum_r[k];
            out[3 * k + 1] = sum_g[k];
            out[3 * k + 2] = sum_b[k];
        }
        if (!spots_.empty()) {
            for (int k = 0; k < m; ++k) {
                const Vec3 d(dx[k0 + k], dy[k0 + k], dz[k0 + k]);
                const double t_near = near ? double(near[k]) : 0.0;
                add_ray_term(out + 3 * k, grp ? grp + 3 * size_t(G) * k : nullptr, [&](RGB* p) {
                    return spot_airlight(origin_, d, t_near, double(Dvp[k0 + k]), lit ? &lit[k] : nullptr, p);
                });
            }
        }
        if (!suns_.empty()) {
            for (int k = 0; k < m; ++k) {
                const Vec3 d(dx[k0 + k], dy[k0 + k], dz[k0 + k]);
                add_ray_term(out + 3 * k, grp ? grp + 3 * size_t(G) * k : nullptr, [&](RGB* p) {
                    return sun_airlight(origin_, d, near ? double(near[k]) : 0.0, double(Dvp[k0 + k]),
                                        lit ? &lit[k] : nullptr, p);
                });
            }
        }
        if (has_light_size_) {
            for (int k = 0; k < m; ++k) {
                const Vec3 d(dx[k0 + k], dy[k0 + k], dz[k0 + k]);
                float* o = out + 3 * k;
                float* gk = grp ? grp + 3 * size_t(G) * k : nullptr;
                RGB La(o[0], o[1], o[2]);
                for (int g = 0; g < G; ++g) ray_passes[size_t(g)] = RGB(gk[3 * g], gk[3 * g + 1], gk[3 * g + 2]);
                add_light_size(origin_, d, near ? double(near[k]) : 0.0, double(Dvp[k0 + k]), lit ? &lit[k] : nullptr,
                               La, G ? ray_passes.data() : nullptr);
                for (int c = 0; c < 3; ++c) o[c] = float(La[c]);
                for (int g = 0; g < G; ++g)
                    for (int c = 0; c < 3; ++c) gk[3 * g + c] = float(ray_passes[size_t(g)][c]);
            }
        }
    }
}

void FogEvaluator::add_light_size(const Vec3& o, const Vec3& d, double t_near, double Dvp, const LitIntervals* lit,
                                  RGB& La, RGB* passes) const {
    // The passes' excess apart, then each sum clipped.
    struct Excess {
        std::vector<RGB> passes;
    };
    std::vector<RGB>& excess = thread_scratch<Excess>().passes;
    excess.assign(passes ? size_t(n_passes_) : 0, RGB(0.0));
    La = glm::max(RGB(0.0), La + light_size_airlight(o, d, t_near, Dvp, lit, passes ? excess.data() : nullptr));
    for (size_t g = 0; g < excess.size(); ++g) passes[g] = glm::max(RGB(0.0), passes[g] + excess[g]);
}

void FogEvaluator::eval_many(const Ray* rays, const float* Dvp, const float* t0, int n, double* Tr, RGB* La,
                             const glm::dvec2* film, RGB* passes) const {
    const int G = passes ? n_passes_ : 0;
    if (G) std::fill(passes, passes + size_t(G) * size_t(n), RGB(0.0));
    if (soa()) {
        constexpr int kChunk = 256;
        double dx[kChunk], dy[kChunk], dz[kChunk];
        float Tr_f[kChunk], rgb[3 * kChunk];
        struct Passes {
            std::vector<float> passes;
        };
        std::vector<float>& chunk_passes = thread_scratch<Passes>().passes;
        chunk_passes.resize(3 * size_t(G) * kChunk);
        for (int k0 = 0; k0 < n; k0 += kChunk) {
            const int m = std::min(kChunk, n - k0);
            for (int k = 0; k < m; ++k) {
                dx[k] = rays[k0 + k].d.x;
                dy[k] = rays[k0 + k].d.y;
                dz[k] = rays[k0 + k].d.z;
            }
            eval_soa(dx, dy, dz, Dvp + k0, t0 ? t0 + k0 : nullptr, m, Tr_f, rgb, film ? film + k0 : nullptr,
                     G ? chunk_passes.data() : nullptr);
            for (int k = 0; k < m; ++k) {
                Tr[k0 + k] = Tr_f[k];
                La[k0 + k] = RGB(rgb[3 * k], rgb[3 * k + 1], rgb[3 * k + 2]);
            }
            for (size_t q = 0; q < size_t(G) * size_t(m); ++q)
                passes[size_t(G) * size_t(k0) + q] =
                    RGB(chunk_passes[3 * q], chunk_passes[3 * q + 1], chunk_passes[3 * q + 2]);
        }
        return;
    }
    if (gaussian_) {
        eval_gaussians(rays, Dvp, t0, n, Tr, La);
        return;
    }
    for (int k = 0; k < n; ++k) {
        const double near = t0 ? double(t0[k]) : 0.0;
        const double seg = std::max(0.0, double(Dvp[k]) - near);  // inf stays inf
        La[k] = RGB(0.0);
        Tr[k] = sigma_t_ == 0.0 ? 1.0 : std::isinf(seg) ? 0.0 : std::exp(-sigma_t_ * seg);
    }
    if (sigma_t_ == 0.0) return;
    const LitIntervals* lit = shadows_ ? lit_intervals(rays, t0, Dvp, n, nullptr, film) : nullptr;
    for (size_t l = 0; l < lights_.size(); ++l) {
        const LightData& light = lights_[l];
        const int v = lit ? light_volume_[l] : -1, n_samples = lit ? light_samples_[l] : 1;
        for (int k = 0; k < n; ++k) {
            const double near = t0 ? double(t0[k]) : 0.0;
            RGB term;
            if (v >= 0 &&
                (model_.visibility_in_integrand() || !samples_lit(lit[k], v, n_samples, near, double(Dvp[k])))) {
                term = light.weight * sample_mean(v, n_samples, [&](int u) {
                    return point_airlight_lit(light, u, rays[k].o, rays[k].d, near, Dvp[k], lit[k]);
                });
            } else {
                const Vec3 o = near > 0.0 ? rays[k].o + near * rays[k].d : rays[k].o;
                const Vec3 sv = light.s - o;
                const double Dsv = shared_origin_ && !(near > 0.0) ? light.Dsv : glm::length(sv);
                const double cos_gamma = Dsv > 0.0 ? std::clamp(glm::dot(rays[k].d, sv) / Dsv, -1.0, 1.0) : 1.0;
                const double seg = std::max(0.0, double(Dvp[k]) - near);
                term = light.weight * airlight(Dsv, cos_gamma, seg);
            }
            La[k] += term;
            if (G && light.pass >= 0) passes[size_t(k) * G + size_t(light.pass)] += term;
        }
    }
    // Ray k's passes (null without).
    auto ray_passes = [&](int k) { return G ? passes + size_t(k) * G : nullptr; };
    if (!spots_.empty())
        for (int k = 0; k < n; ++k)
            La[k] += spot_airlight(rays[k].o, rays[k].d, t0 ? double(t0[k]) : 0.0, double(Dvp[k]), lit ? &lit[k] : nullptr,
                                   ray_passes(k));
    if (!suns_.empty())
        for (int k = 0; k < n; ++k)
            La[k] += sun_airlight(rays[k].o, rays[k].d, t0 ? double(t0[k]) : 0.0, double(Dvp[k]), lit ? &lit[k] : nullptr,
                                  ray_passes(k));
    if (has_light_size_)
        for (int k = 0; k < n; ++k)
            add_light_size(rays[k].o, rays[k].d, t0 ? double(t0[k]) : 0.0, double(Dvp[k]), lit ? &lit[k] : nullptr, La[k],
                           ray_passes(k));
}

RGB FogEvaluator::light_size_airlight(const Vec3& o, const Vec3& d, double t_near, double Dvp,
                                      const LitIntervals* lit, RGB* passes) const {
    RGB La(0.0);
    if (!has_light_size_) return La;
    // The disk's airlight less the point's over [a, b]: from the expansion far from the light,
    // else the disk's less the point's with the bake's own model (so that it cancels the part
    // of the whole segment's term it replaces).
    // _h_: the ray's closest approach to the light (closest below).
    auto excess = [&](const Vec3& s, double r, double h, const SphereFalloff* falloff, double a, double b,
                      const std::function<double()>& point, const std::function<double(const Vec3&)>& profile,
                      const std::vector<double>& cuts) {
        if (sphere_light_series_applies(sigma_t_, r, h))
            return sphere_light_excess_series(phase_, sigma_t_, s, r, o, d, a, b, t_near, profile, cuts);
        return sphere_light_airlight(phase_, sigma_t_, s, r, o, d, a, b, t_near, profile, cuts, falloff) -
               std::exp(-sigma_t_ * (a - t_near)) * point();
    };
    // The ray's closest approach to the light at _s_; rays that pass too far from a light for
    // its radius to matter skip it (sphere_light_matters).
    auto closest = [&](const Vec3& s) {
        const Vec3 so = s - o;
        const double tc = glm::dot(so, d);
        return std::sqrt(std::max(0.0, glm::dot(so, so) - tc * tc));
    };
    // [a, b] within each lit span of light volume _v_ (-1, or lit all along: [a, b] itself).
    auto for_spans = [&](int v, double a, double b, auto fn) {
        if (v < 0 || !lit || fully_lit(*lit, v, a, b)) return fn(a, b);
        double sum = 0.0;
        for (int k = lit->begin[v]; k < lit->end[v]; ++k) {
            const double lo = std::max(a, lit->spans[k].first), hi = std::min(b, lit->spans[k].second);
            if (hi > lo) sum += fn(lo, hi);
        }
        return sum;
    };
    for (size_t l = 0; l < lights_.size(); ++l) {
        const LightData& light = lights_[l];
        double a = 0.0, b = 0.0;
        const double h = closest(light.s);
        if (!sphere_light_matters(sigma_t_, light.radius, h, light_size_tol_) ||
            !sphere_light_window(sigma_t_, light.s, light.radius, o, d, t_near, Dvp, a, b, light_size_tol_))
            continue;
        const int v = lit ? light_volume_[l] : -1;
        const int n = samples_needed(lit, v, light_samples_, l, t_near, Dvp);
        const RGB term = light.weight * sample_mean(v, n, [&](int u) {
            return for_spans(u, a, b, [&](double lo, double hi) {
                const Vec3 x = o + lo * d, sx = light.s - x;
                const double Dsx = glm::length(sx);
                const double cos_gamma = Dsx > 0.0 ? std::clamp(glm::dot(d, sx) / Dsx, -1.0, 1.0) : 1.0;
                return excess(light.s, light.radius, h, light.falloff.get(), lo, hi,
                              [&] { return airlight(Dsx, cos_gamma, hi - lo); }, nullptr, {});
            });
        });
        La += term;
        if (passes && light.pass >= 0) passes[light.pass] += term;
    }
    for (size_t i = 0; i < spots_.size(); ++i) {
        const SpotData& spot = spots_[i];
        double a = 0.0, b = 0.0;
        const double h = closest(spot.s);
        if (!sphere_light_matters(sigma_t_, spot.radius, h, light_size_tol_) ||
            !sphere_light_window(sigma_t_, spot.s, spot.radius, o, d, t_near, Dvp, a, b, light_size_tol_))
            continue;
        // The cone's profile towards x from the disk's centre, its edges (and the smoothstep's
        // inner edge, Spread's kink on the axis) as breakpoints.
        auto profile = [&](const Vec3& x) {
            const Vec3 u = x - spot.s;
            const double len = glm::length(u);
            return len > 0.0 ? spot_profile(spot.cone, glm::dot(spot.cone.axis, u) / len) : 0.0;
        };
        std::vector<double> cuts = ray_cone_crossings(o, d, spot.s, spot.cone.axis, spot.cone.cos_half_angle, a, b);
        if (spot.cone.smooth > 0.0 && spot.cone.cos_half_angle + spot.cone.smooth < 1.0) {
            const std::vector<double> inner = ray_cone_crossings(o, d, spot.s, spot.cone.axis,
                                                                 spot.cone.cos_half_angle + spot.cone.smooth, a, b);
            cuts.insert(cuts.end(), inner.begin(), inner.end());
        }
        if (spot.cone.has_spread()) {
            const double x = ray_axis_approach(o, d, spot.s, spot.cone.axis, a, b);
            if (x >= 0.0) cuts.push_back(x);
        }
        const int v = lit ? spot_volume_[i] : -1;
        const int n = samples_needed(lit, v, spot_samples_, i, t_near, Dvp);
        const RGB term = spot.weight * sample_mean(v, n, [&](int u) {
            return for_spans(u, a, b, [&](double lo, double hi) {
                return excess(spot.s, spot.radius, h, spot.falloff.get(), lo, hi,
                              [&] { return spot_segment(spot, o + lo * d, d, hi - lo); }, profile, cuts);
            });
        });
        La += term;
        if (passes && spot.pass >= 0) passes[spot.pass] += term;
    }
    return La;
}

RGB FogEvaluator::sun_airlight(const Vec3& o, const Vec3& d, double t_near, double Dvp, const LitIntervals* lit,
                               RGB* passes) const {
    RGB La(0.0);
    if (sigma_t_ == 0.0 || !(Dvp > t_near)) return La;
    for (size_t i = 0; i < suns_.size(); ++i) {
        const SunData& sun = suns_[i];
        const double p = phase_.eval(-glm::dot(sun.w, d));
        const int v0 = lit ? sun_volume_[i] : -1;
        // The geometric factor with the lit spans of volume _v_ (the airlight takes the sun's
        // centre; a soft shadow's samples differ in their spans alone).
        auto factor = [&](int v) {
            if (v >= 0 && model_.visibility_in_integrand()) {
                const std::vector<double> jumps = span_ends(*lit, v, t_near);
                return sunlight_factor_visible(sigma_t_, fog_top_, sun.mu_s, o + t_near * d, d, Dvp - t_near,
                                               [&](const Vec3& x) { return visible(v, x); }, kShadowRelTol, &jumps);
            }
            if (v >= 0 && !fully_lit(*lit, v, t_near, Dvp)) {
                double sum = 0.0;
                for (int k = lit->begin[v]; k < lit->end[v]; ++k)
                    sum += sunlight_span(sigma_t_, fog_top_, sun.mu_s, o, d, t_near, lit->spans[k].first,
                                         lit->spans[k].second);
                return sum;
            }
            return model_.sun_quadrature()
                       ? sunlight_layer_factor_quadrature(sigma_t_, fog_top_, sun.mu_s, o.z, d.z, t_near, Dvp,
                                                          kQuadratureRelTol)
                       : sunlight_layer_factor(sigma_t_, fog_top_, sun.mu_s, o.z, d.z, t_near, Dvp);
        };
        const double G = sample_mean(v0, samples_needed(lit, v0, sun_samples_, i, t_near, Dvp), factor);
        const RGB term = sun.weight * (p * G);
        La += term;
        if (passes && sun.pass >= 0) passes[sun.pass] += term;
    }
    return La;
}

double FogEvaluator::spot_segment(const SpotData& spot, const Vec3& from, const Vec3& d, double len) const {
    return !spot_closed_form_ ? spot_airlight_quadrature(spot.cone, spot.s, phase_, sigma_t_, from, d, len, kSpotRelTol)
                              : pegoraro10_spot_airlight(pegoraro_phase_, spot.cone, spot.s, sigma_t_, from, d, len);
}

RGB FogEvaluator::spot_airlight(const Vec3& o, const Vec3& d, double t_near, double Dvp, const LitIntervals* lit,
                                RGB* passes) const {
    RGB La(0.0);
    if (sigma_t_ == 0.0) return La;
    const double seg = std::max(0.0, Dvp - t_near);  // inf stays inf
    if (!(seg > 0.0)) return La;
    const Vec3 start = t_near > 0.0 ? o + t_near * d : o;
    auto segment = [&](const SpotData& spot, const Vec3& from, double len) { return spot_segment(spot, from, d, len); };
    for (size_t i = 0; i < spots_.size(); ++i) {
        const SpotData& spot = spots_[i];
        const int v0 = lit ? spot_volume_[i] : -1;
        // Per unit weight, with the lit spans of volume _v_.
        auto value = [&](int v) {
            if (v >= 0 && model_.visibility_in_integrand()) {
                const std::vector<double> jumps = span_ends(*lit, v, t_near);
                return spot_airlight_visible(spot.cone, phase_, sigma_t_, spot.s, start, d, seg,
                                             [&](const Vec3& x) { return visible(v, x); }, kShadowRelTol, &jumps);
            }
            if (v < 0 || fully_lit(*lit, v, t_near, Dvp)) return segment(spot, start, seg);
            double sum = 0.0;
            for (int k = lit->begin[v]; k < lit->end[v]; ++k) {
                const double a = lit->spans[k].first, b = lit->spans[k].second;
                sum += std::exp(-sigma_t_ * (a - t_near)) * segment(spot, o + a * d, b - a);
            }
            return sum;
        };
        const RGB term = spot.weight * sample_mean(v0, samples_needed(lit, v0, spot_samples_, i, t_near, Dvp), value);
        La += term;
        if (passes && spot.pass >= 0) passes[spot.pass] += term;
    }
    return La;
}

bool FogEvaluator::keeps_light(const SceneDescription& scene, const PointLight& light) {
    const RGB weight = scene.medium.albedo * light.I0;
    if (weight.x != 0.0 || weight.y != 0.0 || weight.z != 0.0) return true;
    return !scene.gaussians.albedo.empty() && (light.I0.x != 0.0 || light.I0.y != 0.0 || light.I0.z != 0.0);
}

void FogEvaluator::eval_gaussians(const Ray* rays, const float* Dvp, const float* t0, int n, double* Tr, RGB* La) const {
    if (splat_) {  // perspective: rays from the shared eye (gaussian/splat.h)
        thread_local std::vector<Vec3> dirs;
        dirs.resize(size_t(n));
        for (int k = 0; k < n; ++k) dirs[k] = rays[k].d;
        splat_->eval_rays(dirs.data(), Dvp, t0, n, Tr, La);
        shadow_gaussians(rays, Dvp, t0, n, La);
        refine_samples(rays, Dvp, t0, n, La);
        return;
    }
    const size_t L = lights_.size();
    const bool quadrature = model_.gaussian_method() == GaussianMethod::Quadrature;
    const LitIntervals* lit = shadows_ && quadrature ? lit_intervals(rays, t0, Dvp, n) : nullptr;
    // The reference's visibility of shadow volume _v_ (-1: none) on ray k: shadow rays at its
    // nodes, the lit spans' ends as breakpoints.
    auto shadowed = [&](GaussianRefLight& ref, int v, int k, double near) {
        if (!lit || v < 0) return;
        ref.visible = [this, v](const Vec3& x) { return visible(v, x); };
        ref.jumps = span_ends(lit[k], v, near);
    };
    for (int k = 0; k < n; ++k) {
        const Ray& ray = rays[k];
        const double near = t0 ? double(t0[k]) : 0.0;
        const double seg = std::max(0.0, double(Dvp[k]) - near);  // inf stays inf
        const Vec3 o = near > 0.0 ? ray.o + near * ray.d : ray.o;
        Tr[k] = std::exp(-gaussian_->optical_depth_ray(o, ray.d, seg));
        La[k] = RGB(0.0);
        if (!(seg > 0.0) || (L == 0 && gaussian_spots_.empty() && gaussian_suns_.empty())) continue;
        if (quadrature) {
            constexpr GaussianSums kSums = GaussianSums::Culled;  // (airlight.h)
            for (size_t l = 0; l < L; ++l) {
                GaussianRefLight ref;  // a point light
                ref.s = lights_[l].s;
                shadowed(ref, lit ? light_volume_[l] : -1, k, near);
                // Unshadowed: the march with exact light depths (gaussian/march.h: 2e-5 of the
                // adaptive quadrature in its tests, hundreds of times faster with thousands of
                // Gaussians); the lit intervals' visibility takes the adaptive quadrature.
                GaussianMarch march;
                La[k] += lights_[l].weight *
                         (!ref.visible ? gaussian_march_airlight(*gaussian_, lights_[l].s, phase_, o, ray.d, seg, nullptr, march)
                                       : gaussian_airlight_quadrature(*gaussian_, ref, phase_, o, ray.d, seg, kQuadratureRelTol, kSums));
            }
            for (size_t i = 0; i < gaussian_spots_.size(); ++i) {
                const GaussianSpotData& spot = gaussian_spots_[i];
                GaussianRefLight ref;
                ref.kind = GaussianRefLight::Kind::Spot;
                ref.s = spot.s;
                ref.cone = spot.cone;
                shadowed(ref, lit ? spot_volume_[i] : -1, k, near);
                La[k] += medium_albedo_ * spot.I0 *
                         gaussian_airlight_quadrature(*gaussian_, ref, phase_, o, ray.d, seg, kQuadratureRelTol, kSums);
            }
            for (size_t i = 0; i < gaussian_suns_.size(); ++i) {
                const GaussianSunData& sun = gaussian_suns_[i];
                GaussianRefLight ref;
                ref.kind = GaussianRefLight::Kind::Sun;
                ref.w = sun.w;
                ref.fog_top = fog_top_;
                shadowed(ref, lit ? sun_volume_[i] : -1, k, near);
                // (Unshadowed: the march with exact light depths, as for point lights: 2e-7 of
                // the adaptive quadrature in GaussianMarch.SunMatchesTheQuadrature.)
                GaussianMarch march;
                const double La_sun =
                    !ref.visible
                        ? gaussian_march_sun(*gaussian_, -sun.w, fog_top_, phase_, o, ray.d, seg, nullptr, march)
                        : gaussian_airlight_quadrature(*gaussian_, ref, phase_, o, ray.d, seg, kQuadratureRelTol, kSums);
                La[k] += medium_albedo_ * sun.E * La_sun;
            }
            continue;
        }
        const FogshopAirlight local(*gaussian_, o, gaussian_lights_, model_.f_table(), 1);
        La[k] = local.eval_rgb(ray.d, seg, gaussian_albedo_.data(), gaussian_I0_.data(), medium_albedo_);
    }
    if (!quadrature) shadow_gaussians(rays, Dvp, t0, n, La);
}

}  // namespace airlight
