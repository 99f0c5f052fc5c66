// fog_refinement.cpp: FogEvaluator's Gaussian refinement (fog_evaluator.h; the model:
// docs/models.md, "Gaussian refinement"): its set-up (the plan, the marched lights and their
// light-depth maps, checked by measurement), the marched and uniform-fog terms of a refined
// ray, and the ratios the refine pass's frame lends the edge pass's samples.
#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "bake/fog_evaluator.h"
#include "core/build_progress.h"
#include "core/constants.h"
#include "core/parallel.h"
#include "gaussian/march.h"
#include "homogeneous/sunlight_layer.h"

namespace airlight {

namespace {
// Two depths along nearby rays on one surface: inverse depths within 1 %, or both the sky.
bool one_surface(double D1, double D2) {
    if (std::isinf(D1) || std::isinf(D2)) return std::isinf(D1) && std::isinf(D2);
    return std::abs(1.0 / D1 - 1.0 / D2) <= 0.01 / D1;
}

// The width 1 / a that 5 % of _medium_'s Gaussians (those with a cull sphere) are narrower
// than; 0 with none.
double narrow_width(const GaussianMedium& medium) {
    std::vector<double> widths;
    for (std::size_t j = 0; j < medium.size(); ++j)
        if (medium.cull_radius(j) > 0.0) widths.push_back(1.0 / medium.scale(j));
    if (widths.empty()) return 0.0;
    const auto at = widths.begin() + std::ptrdiff_t(widths.size() / 20);
    std::nth_element(widths.begin(), at, widths.end());
    return *at;
}
}  // namespace

int FogEvaluator::map_radial(double extent, double width, int most) const {
    // A read interpolates linearly between distances, whose error in an erf step of width w
    // falls as (spacing / w)^2, and near the light from its own 0. Measured by the map's check
    // at 1 %, 64 a face (need 0.0025): 3000 Gaussians 1-3 m wide, 0.00127 at 256 distances,
    // 0.00130 at 192 (0.35 w apart), 0.00135 at 128 (0.41 w); 34 3-10 m wide, alike at 64 and
    // 256; 150 Gaussians of the refine tests' ground scene, 0.00319 at 64 (0.5 w), 0.00176 at
    // 96; 1e5 0.3-1 m wide (at 128 a face), 0.00147 at 256 (0.66 w), 0.00237 at 128. So
    // kMapRadialWidths w apart at 1 %, scaled as the face's spacing is with the accuracy (its
    // square root, plan_marches) above. Below 1 % every map takes the most (at 0.1 %, 0.16 w
    // apart erred 0.00068 against the 0.00025 asked on the ground scene: the error near the
    // light falls slower). Rounded up to 32, within [kMarchMapMinRadial, _most_].
    if (refine_target_ < 0.01) return most;
    const double spacing = kMapRadialWidths * width * std::sqrt(refine_target_ / 0.01);
    if (!(spacing > 0.0) || !(extent > 0.0) || !std::isfinite(extent)) return most;
    const double need = std::ceil((extent / spacing + 1.0) / 32.0) * 32.0;
    return int(std::clamp(need, double(kMarchMapMinRadial), double(most)));
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
    // through the Gaussians, and on a spread of the frame's rays to their surfaces). The error
    // falls as the square of the grid's spacing or faster: with bilinear reads 4x a doubling on
    // the thick benchmark cloud, 9.5x on the 1e5 one (64 errs 0.014, 128 0.0015). The first
    // size is kMapFace1 a side at 1 % for a point or spot (bicubic reads: the 3000-Gaussian
    // cloud's 48 errs 0.00105 on the frame's rays, 0.00027 on those through the Gaussians,
    // against the need of 0.0025; bilinear, 64 erred 0.011 and 0.0013) and kSunMapFace1 for a
    // sun, scaled to the target by the square law (a point's 32 at 5 %, 152 at 0.1 %; with
    // bilinear reads at 0.1 % the cloud took 64, 128 and 256, 21x the cost of 64, where one
    // map of 203 fitted at 10x). A size that errs more is followed by the one its fall
    // predicts, with a tenth to spare: by the fall measured between the last two sizes, or
    // after the first by the cube of the spacing (the 1e5 cloud's 128; the square law asked
    // 168), while the error could still reach the need by the largest size. Past the largest, or past
    // kMarchMapMaxBytes for all the lights, the light depths are exact (slow with many
    // Gaussians: the budget decides).
    const double need = kMarchedShare * refine_target_;
    GaussianMarch tuned;  // (the maps leave out what its marches do: its window)
    tuned.set_accuracy(refine_target_);
    const double window = tuned.window;
    windowed_ = std::make_unique<GaussianMedium>(gaussian_->windowed(window));
    std::size_t bytes = 0;
    // Sets _marched_'s map to the first size (build(face) makes it) that fits, if any, from
    // _face1_ at 1 % (scaled to the target). (_radial_: the map's distances, map_radial, and
    // _most_ after a map that erred too much.)
    auto search = [&](MarchedLight& marched, auto build, int& radial, int most, std::size_t bytes_per_radial,
                      int face1, int max_face) {
        double last_error = 0.0, last_face = 0.0;
        std::vector<double> exact;  // the check rays' exact marches, shared by the sizes
        const int first = int(std::ceil(face1 * std::sqrt(0.01 / std::max(refine_target_, 1e-9))));
        for (int face = std::clamp(first, kMapMinFace, max_face);;) {
            if (bytes + bytes_per_radial * radial * face * face > kMarchMapMaxBytes) return;
            build(face);
            const double error = march_map_error(marched, exact, threads);
            if (error <= need) {
                bytes += marched.bytes();
                return;
            }
            marched.map = CachedMap{};
            if (!std::isfinite(error)) return;  // (no fall to predict from)
            if (radial != most) exact.clear();  // (the checks near the light move with the steps)
            radial = most;
            // The error as (spacing)^order: measured, or the cube before a second size; the
            // largest size must reach the need by kMapFallBound a doubling or the measured order.
            const double order =
                last_error > 0.0 ? std::clamp(std::log(last_error / error) / std::log((face - 1.0) / (last_face - 1.0)),
                                              0.0, std::log2(kMapFallBound))
                                 : 3.0;
            const double best = last_error > 0.0 ? order : std::log2(kMapFallBound);
            if (face >= max_face || error * std::pow((face - 1.0) / (max_face - 1.0), best) > need) return;
            last_error = error, last_face = face;
            const double spacing = order > 0.0 ? std::pow(error / need, 1.0 / order) : 2.0;
            const int next = 8 * int(std::ceil((1.0 + kMapFaceMargin * (face - 1.0) * spacing) / 8.0));
            face = std::min(max_face, std::max(next, face + 8));
        }
    };
    // (A map the last bake built from the same Gaussians, light, size and window is taken as it
    // is: map_cache.h. take_cached: the held map of _face_ into _marched_, or false, and the
    // build that follows counted.)
    MapKey key;
    key.medium = gaussian_->fingerprint(), key.window = window;
    const double width = narrow_width(*windowed_);
    auto take_cached = [&](MarchedLight& marched, int face) {
        key.face = face;
        marched.map = find_cached_map(key);
        marched.map.key = key;
        if (marched.bytes() > 0) return true;
        count_map_build();
        return false;
    };
    for (size_t l = 0; l < march.size(); ++l) {
        if (!march[l]) continue;
        MarchedLight marched;
        marched.light = l;
        if (l >= P) {  // a sun: columns along it over the cloud's shade (a sixth of a point's bytes a face)
            const Vec3 u = -gaussian_suns_[l - P].w;
            const SunFootprint print(*windowed_, u);
            int radial = map_radial(print.hi[2] - print.lo[2], width, kSunMapMaxRadial);
            key.sun = true, key.s = key.axis = Vec3(0.0), key.u = u, key.half_angle = 0.0;
            search(marched, [&](int face) {
                       key.radial = radial;
                       if (!take_cached(marched, face))
                           marched.map.sun_map =
                               std::make_shared<const SunDepthMap>(*windowed_, u, face, radial, threads, window);
                   },
                   radial, kSunMapMaxRadial, sizeof(float), kSunMapFace1, kSunMapMaxFace);
        } else {
            // A spot's map holds its cone alone (a sixth of the sphere for a 60 degree one).
            const SpotCone* cone = l >= n_gaussian_points_ ? &gaussian_spots_[l - n_gaussian_points_].cone : nullptr;
            const Vec3 axis = cone ? cone->axis : Vec3(0.0, 0.0, -1.0);
            const double half_angle = cone ? std::acos(std::clamp(cone->cos_half_angle, -1.0, 1.0)) : kPi;
            // (512 distances below 1 %, where the linear reads between them were the error's
            // floor; 256 above, where the face's is: with 512 the 1e5 cloud's set-up at 1 %
            // took 4.9 s instead of 4.6)
            const int most = refine_target_ < 0.01 ? kMarchMapMaxRadial : kMarchMapMaxRadial / 2;
            int radial = map_radial(LightDepthMap::reach(*windowed_, gaussian_lights_[l]), width, most);
            key.sun = false, key.s = gaussian_lights_[l], key.axis = axis, key.u = Vec3(0.0), key.half_angle = half_angle;
            search(marched, [&](int face) {
                       key.radial = radial;
                       if (!take_cached(marched, face))
                           marched.map.map = std::make_shared<const LightDepthMap>(
                               *windowed_, gaussian_lights_[l], axis, half_angle, face, radial, threads, window);
                   },
                   radial, most, std::size_t(6) * sizeof(float), kMapFace1, kMarchMapMaxFace);
        }
        marched_.push_back(std::move(marched));
    }
    all_marched_ = marched_.size() == march.size();
    std::vector<CachedMap> kept;
    for (const MarchedLight& m : marched_)
        if (m.bytes() > 0) kept.push_back(m.map);
    keep_maps(std::move(kept));
}

RGB FogEvaluator::march_light(const MarchedLight& marched, bool mapped, const Vec3& o, const Vec3& d, double len,
                              GaussianMarch& march) const {
    const size_t l = marched.light, P = gaussian_lights_.size();
    march.set_accuracy(refine_target_);
    march.gather = windowed_.get();
    if (l >= P)
        return gaussian_march_sun_rgb(*gaussian_, -gaussian_suns_[l - P].w, fog_top_, phase_, o, d, len,
                                      mapped ? marched.map.sun_map.get() : nullptr, march);
    if (l >= n_gaussian_points_) {  // a spot (its profile at most 1, or a Spread's peak)
        const SpotCone& cone = gaussian_spots_[l - n_gaussian_points_].cone;
        march.cone = &cone;
        march.emission_max = cone.has_spread() ? std::max(1.0, cone.spread_a) : 1.0;
    }
    return gaussian_march_airlight_rgb(*gaussian_, gaussian_lights_[l], phase_, o, d, len,
                                       mapped ? marched.map.map.get() : nullptr, march);
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
    if (marched.map.map && n > 0) {
        const Vec3& s = gaussian_lights_[l];
        Vec3 across = glm::cross(s - origin_, Vec3(0.0, 0.0, 1.0));
        if (!(glm::length(across) > 1e-9 * glm::length(s - origin_))) across = glm::cross(s - origin_, Vec3(1.0, 0.0, 0.0));
        const Vec3 u = cone ? cone->axis : glm::normalize(across);
        for (double steps : {0.5, 1.0, 2.0, 4.0}) targets.push_back(s + steps * marched.map.map->radial_step() * u);
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
    return std::max(worst, view_map_error(marched, threads));
}

double FogEvaluator::view_map_error(const MarchedLight& marched, int threads) const {
    // Each ray's airlight, per unit I0, as a sum over kNodes midpoints to its surface (or to
    // twice the Gaussians' end): sigma e^{-T_view} profile / d^2 times e^{-T_light}, with the
    // map's light depth and with the exact depth of the windowed Gaussians the map tabulates;
    // the relative difference of the two sums is the map's error on that ray, the nodes' own
    // error cancelling. The rays through the Gaussians above run to twice their distance and
    // average the map's error over the cloud, where a short ray (the ground near the camera)
    // sees only points whose light paths cross the cloud far from the light, where a map's
    // cell is widest: with bilinear reads, +1.2 % at 1 % on the 3000-Gaussian benchmark's
    // ground, which those rays measured at 0.13 % (these, 1.1 %). 84 rays of 32 nodes: ~20 ms.
    constexpr int kNodes = 32;
    const LightDepthMap* map = marched.map.map.get();
    if (!map || views_.empty()) return 0.0;
    const size_t l = marched.light;
    const Vec3& s = gaussian_lights_[l];
    const double beta0 = gaussian_->beta0();
    // (the light depths of the windowed Gaussians the map holds: its interpolation's error)
    const GaussianMedium& light = windowed_ ? *windowed_ : *gaussian_;
    std::vector<double> error(views_.size(), 0.0);
    parallel_chunks(views_.size(), threads, 1, [&](size_t begin, size_t end) {
        for (size_t k = begin; k < end; ++k) {
            const ViewRay& v = views_[k];
            const double t1 = std::min(v.depth, 2.0 * gaussians_end_);
            if (!(t1 > v.near)) continue;
            build_progress_check();
            const double dt = (t1 - v.near) / kNodes;
            double Tv = 0.0, with_map = 0.0, exact = 0.0;
            for (int n = 0; n < kNodes; ++n) {
                const Vec3 x = origin_ + (v.near + (n + 0.5) * dt) * v.d;
                const double sigma = gaussian_->density_near(x);
                const Vec3 sx = x - s;
                const double d = glm::length(sx);
                if (!(d > 0.0)) continue;
                const Vec3 u = sx / d;
                const double w = sigma * std::exp(-(Tv + 0.5 * sigma * dt)) * gaussian_profile(l, u) / (d * d);
                Tv += sigma * dt;
                if (!(w > 0.0)) continue;
                const double T = light.optical_depth_ray(s, u, d, GaussianMedium::npos, false);
                exact += w * std::exp(-(beta0 * d + T));
                with_map += w * std::exp(-(beta0 * d + (*map)(x)));
            }
            if (exact > 0.0) error[k] = std::abs(with_map - exact) / exact;
        }
    });
    return *std::max_element(error.begin(), error.end());
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

bool FogEvaluator::surface_cuts_gaussian(const Vec3 d[4], const double D[4]) const {
    const GaussianMedium& medium = windowed_ ? *windowed_ : *gaussian_;
    Vec3 axis(0.0);
    for (int k = 0; k < 4; ++k) axis += d[k];
    if (!(glm::length(axis) > 0.0)) return true;
    axis = glm::normalize(axis);
    double cos_half = 1.0;
    for (int k = 0; k < 4; ++k) cos_half = std::min(cos_half, glm::dot(d[k], axis));
    bool cut = false;
    medium.for_each_in_cone(origin_, axis, std::max(0.0, cos_half - 1e-9), [&](std::size_t g) {
        if (cut) return;
        bool before = false, past = false, reached = false;
        for (int k = 0; k < 4; ++k) {
            const double t = glm::dot(medium.centre(g) - origin_, d[k]);
            (D[k] < t ? before : past) = true;
            reached = reached || medium.segment_reaches(g, origin_, d[k], D[k]);
        }
        cut = before && past && reached;
    });
    return cut;
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
        if (v >= 0 && lit && !lit->fully_lit(v, near, end))
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
               sunlight_span(sigma_t_, fog_top_, sun.mu_s, origin_.z, d.z, near, ta, tb);
    };
    const bool spots = P > n_gaussian_points_;
    const FogshopAirlight::SpanBackground* bg = (own || spots || S > 0) && at_eye ? &background : nullptr;
    const FogshopAirlight::SpanProfile profile = [&](size_t l, const Vec3& u) { return gaussian_profile(l, u); };
    const PhaseFunction* phase = isotropic_ ? nullptr : &phase_;
    return fogshop.eval_rgb_spans(d, at_eye ? near : 0.0, spans, gaussian_albedo_.data(), weights.data(),
                                  medium_albedo_, phase, bg, spots ? &profile : nullptr, fast);
}

bool FogEvaluator::same_ratio_depths(const Vec3& d, double D1, double D2, double value, double tol) const {
    if (one_surface(D1, D2)) return true;
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
        return one_surface(Dvp[k], Dvp[r]);
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
        if (v >= 0 && lit && !lit->fully_lit(v, near, end))
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

}  // namespace airlight
