// fog_evaluator.cpp: see fog_evaluator.h.
#include "bake/fog_evaluator.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <functional>
#include <sstream>
#include <stdexcept>

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

// Whether each of a light's _n_ shadow samples (volumes v .. v + n - 1) lights [t0, t1] all along.
bool samples_lit(const LitIntervals& lit, int v, int n, double t0, double t1) {
    for (int j = 0; j < n; ++j)
        if (!lit.fully_lit(v + j, t0, t1)) return false;
    return true;
}

// How many shadow samples of light _i_ (_counts_: per light its count, its volumes from _v_) the
// ray [t0, t1] needs: 1 without shadows or where every one lights it all along (they agree
// there), else them all.
int samples_needed(const LitIntervals* lit, int v, const std::vector<int>& counts, size_t i, double t0, double t1) {
    return v < 0 || !lit || samples_lit(*lit, v, counts[i], t0, t1) ? 1 : counts[i];
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
                           const Vec3& origin, std::vector<ViewRay> views)
    : model_(model),
      sigma_t_(scene.medium.sigma_t),
      phase_(scene.medium.phase),
      isotropic_(phase_is_isotropic(scene.medium.phase)),
      shared_origin_(shared_origin),
      views_(std::move(views)),
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
            partial = partial || (v >= 0 && !lit[k].fully_lit(v, near, end));
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
            if (v < 0 || lit[k].fully_lit(v, near, end)) continue;
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
        if (!(lit[k].partial & ShadowVolumes::light_mask(v)) || lit[k].fully_lit(v, t_start, double(Dvp[k])))
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
        if (v < 0 || !lit || lit->fully_lit(v, a, b)) return fn(a, b);
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
            if (v >= 0 && !lit->fully_lit(v, t_near, Dvp)) {
                double sum = 0.0;
                for (int k = lit->begin[v]; k < lit->end[v]; ++k)
                    sum += sunlight_span(sigma_t_, fog_top_, sun.mu_s, o.z, d.z, t_near, lit->spans[k].first,
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
            if (v < 0 || lit->fully_lit(v, t_near, Dvp)) return segment(spot, start, seg);
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
