// surface_pass.cpp: per-pixel surface attenuation and Lambert glow (see surface_pass.h).
#include "bake/surface_pass.h"
#include "bake/glow_shadow.h"
#include "core/parallel.h"
#include "core/constants.h"

#include <algorithm>
#include <cstdint>
#include <cmath>
#include <limits>
#include <map>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <thread>
#include <tuple>
#include <vector>

#include "surface/biri06_surface.h"
#include "gaussian/medium.h"
#include "homogeneous/spot_light.h"
#include "surface/spot_surface.h"
#include "surface/sun05_surface.h"
#include "surface/sunlight_glow.h"

namespace airlight {

namespace {

// An image of _n_ floats set to _value_, on recycled warm pages where the pool has some
// (bake.h acquire_image_buffer: 4 KiB page faults cost ~10 us each here, more than the whole
// pass at 1080p with several lights).
void allocate_filled(std::vector<float>& v, size_t n, float value) { acquire_image_buffer(v, n, value); }

// The glow's lit share (glow_shadow.h) on a grid of nodes every glow_shadow_step pixels (and
// the last row and column), interpolated bilinearly from the cell's nodes that see the same
// surface as the pixel (the pixel on the node's plane, normals within ~18 degrees); where those carry
// under 5 % of the weights (a silhouette or crease in the cell), the pixel's own.
// The grid's spacing: 1/64 of the image's shorter side, 4 to 32 pixels (16 at 1080p).
int glow_shadow_step(int W, int H) { return std::clamp(std::min(W, H) / 64, 4, 32); }

class GlowShadowGrid {
  public:
    GlowShadowGrid(const GlowShadow& shadow, const CameraRays& rays, const RayCaster& caster, int W, int H,
                   int n_threads)
        : shadow_(shadow), caster_(caster), L_(shadow.num_lights()), step_(glow_shadow_step(W, H)) {
        for (int i = 0; i < W; i += step_) xs_.push_back(i);
        if (xs_.back() != W - 1) xs_.push_back(W - 1);
        for (int j = 0; j < H; j += step_) ys_.push_back(j);
        if (ys_.back() != H - 1) ys_.push_back(H - 1);
        const size_t nx = xs_.size(), ny = ys_.size();
        point_.assign(nx * ny, Vec3(0.0));
        normal_.assign(nx * ny, Vec3(0.0));
        ratio_.assign(nx * ny * L_, 1.0);
        parallel_for(int(ny), n_threads, [&](int b) {
            std::vector<Ray> row(nx);
            std::vector<float> t_near(nx), t_far(nx), t(nx), ng(3 * nx);
            for (size_t a = 0; a < nx; ++a) {
                row[a] = rays(xs_[a] + 0.5, ys_[size_t(b)] + 0.5);
                double tn, tf;
                rays.clip_range(row[a], tn, tf);
                t_near[a] = float(tn);
                t_far[a] = std::isinf(tf) ? std::numeric_limits<float>::infinity()
                                          : float(std::min(tf, double(std::numeric_limits<float>::max())));
            }
            caster.first_hits_normals(row.data(), t_near.data(), t_far.data(), int(nx), t.data(), ng.data());
            for (size_t a = 0; a < nx; ++a) {
                if (std::isinf(t[a])) continue;
                const size_t node = size_t(b) * nx + a;
                Vec3 n(ng[3 * a], ng[3 * a + 1], ng[3 * a + 2]);
                if (glm::dot(n, row[a].d) > 0.0) n = -n;
                point_[node] = row[a].o + double(t[a]) * row[a].d;
                normal_[node] = n;
                shadow_.ratios(row[a].o + double(t[a]) * row[a].d, n, caster_, &ratio_[node * L_]);
            }
        });
    }

    // The lit shares at pixel (i, j), whose surface point is _p_ (depth _t_, normal _n_).
    void at(int i, int j, const Vec3& p, float t, const Vec3& n, double* out) const {
        const size_t a = std::min(size_t(i / step_), xs_.size() - 2 + (xs_.size() < 2));
        const size_t b = std::min(size_t(j / step_), ys_.size() - 2 + (ys_.size() < 2));
        const size_t a1 = std::min(a + 1, xs_.size() - 1), b1 = std::min(b + 1, ys_.size() - 1);
        const size_t nx = xs_.size();
        const size_t nodes[4] = {b * nx + a, b * nx + a1, b1 * nx + a, b1 * nx + a1};
        const double fx = a1 > a ? double(i - xs_[a]) / double(xs_[a1] - xs_[a]) : 0.0;
        const double fy = b1 > b ? double(j - ys_[b]) / double(ys_[b1] - ys_[b]) : 0.0;
        double w[4] = {(1 - fx) * (1 - fy), fx * (1 - fy), (1 - fx) * fy, fx * fy};
        double total = 0.0;
        for (int k = 0; k < 4; ++k) {
            const size_t node = nodes[k];
            // On the node's plane (to 2 % of the pixel's depth) and facing its way.
            const bool same = glm::dot(normal_[node], n) > 0.95 &&
                              std::abs(glm::dot(normal_[node], p - point_[node])) < 0.02 * double(t);
            if (!same) w[k] = 0.0;
            total += w[k];
        }
        // The nodes on the pixel's surface, reweighted; none (a pixel alone on its surface in
        // the cell, or one next to the nodes' edge): the pixel's own.
        if (!(total > 0.05)) {
            shadow_.ratios(p, n, caster_, out);
            return;
        }
        for (size_t l = 0; l < L_; ++l) {
            double r = 0.0;
            for (int k = 0; k < 4; ++k) r += w[k] * ratio_[nodes[k] * L_ + l];
            out[l] = r / total;
        }
    }

  private:
    const GlowShadow& shadow_;
    const RayCaster& caster_;
    size_t L_;
    int step_;
    std::vector<int> xs_, ys_;
    std::vector<Vec3> point_, normal_;  // per node its surface point and normal (0: none)
    std::vector<double> ratio_;
};
}  // namespace

std::shared_ptr<const SpotGlowModel> shared_spot_glow_model(const SpotCone& cone, const PhaseFunction& phase) {
    // The table depends on the cone's angle, blend, Spread and profile and on the phase, not on the axis.
    static std::mutex mutex;
    static std::map<std::tuple<double, double, double, int, double, std::vector<double>, bool>,
                    std::shared_ptr<const SpotGlowModel>>
        cache;
    std::lock_guard<std::mutex> lock(mutex);
    const double g = phase.kind == PhaseKind::HenyeyGreenstein ? phase.g : 0.0;
    auto& slot =
        cache[{cone.cos_half_angle, cone.smooth, cone.spread_b, int(phase.kind), g, cone.profile, cone.profile_alone}];
    if (!slot) slot = std::make_shared<const SpotGlowModel>(cone, phase);
    return slot;
}

std::shared_ptr<const SurfaceGTable> shared_surface_G_table(int nT, int ntheta, double m) {
    static std::mutex mutex;
    static std::map<std::tuple<int, int, double>, std::shared_ptr<const SurfaceGTable>> cache;
    std::lock_guard<std::mutex> lock(mutex);
    auto& slot = cache[{nT, ntheta, m}];
    if (!slot) slot = std::make_shared<const SurfaceGTable>(m, nT, ntheta, 0);
    return slot;
}

// The sun-glow table for one sun direction and phase function, built once and shared
// across bakes (an animation with a fixed sun builds it once; ~0.2-0.6 s on one thread).
std::shared_ptr<const SunlightGlowTable> shared_sun_glow_table(const PhaseFunction& phase, const Vec3& to_sun,
                                                              bool has_top, double m) {
    static std::mutex mutex;
    static std::map<std::tuple<int, double, double, double, double, bool, double>,
                    std::shared_ptr<const SunlightGlowTable>>
        cache;
    std::lock_guard<std::mutex> lock(mutex);
    if (cache.size() > 64) cache.clear();  // a sun animated over many frames: keep memory bounded
    auto& slot = cache[{int(phase.kind), phase.g, to_sun.x, to_sun.y, to_sun.z, has_top, m}];
    if (!slot) slot = std::make_shared<const SunlightGlowTable>(phase, to_sun, has_top, m);
    return slot;
}

void bake_surface_pass(const SceneDescription& scene, const BakeSettings& settings, const CameraRays& rays,
                       const RayCaster& caster, int n_threads, BakeResult& result, const GlowShadow* glow_shadow) {
    const int W = scene.camera.width, H = scene.camera.height;
    const size_t n_pixels = size_t(W) * size_t(H);
    const size_t n_point = scene.point_lights.size(), n_positional = n_point + scene.spot_lights.size();
    // Sun lamps follow the positional lights: their light reaches the surface through the fog
    // layer above it (sunlight_layer.h): e^{-sigma_t (h_top - z) / mu_s}, 1 above the top or without
    // one (Hoffman-Preetham's unattenuated sun), 0 for a sun shining up into an unbounded layer.
    const size_t n_lights = n_positional + scene.sun_lights.size();
    std::vector<double> sun_mu;
    for (const SunLight& sun : scene.sun_lights) sun_mu.push_back(-glm::normalize(sun.direction).z);
    const double sigma_t = scene.medium.sigma_t;
    // The suns' glow on Lambert surfaces (sunlight_glow.h): the light each sun scatters in
    // the homogeneous fog (the layer below fog_top, or unbounded) towards the surface.
    const bool has_top = std::isfinite(scene.fog_top);
    std::vector<std::shared_ptr<const SunlightGlowTable>> sun_glow, sun_gloss;
    const RGB albedo = scene.medium.albedo;
    result.surface_lights = int(n_lights);
    allocate_filled(result.surface_attenuation, n_lights * 3 * n_pixels, 1.0f);
    allocate_filled(result.surface_glow, 3 * n_pixels, 0.0f);
    const double n_phong = settings.surface_phong_exponent;
    if (!(n_phong == 0.0 || (n_phong >= 1.0 && n_phong <= 10000.0)))
        throw std::invalid_argument("surface_phong_exponent: must be 0 (off) or in [1, 10000], got " +
                                    std::to_string(n_phong));
    if (n_phong > 0.0) allocate_filled(result.surface_gloss_glow, 3 * n_pixels, 0.0f);
    if (sigma_t > 0.0)
        for (const SunLight& sun : scene.sun_lights) {
            const Vec3 to_sun = -glm::normalize(sun.direction);
            sun_glow.push_back(shared_sun_glow_table(scene.medium.phase, to_sun, has_top, 1.0));
            if (n_phong > 0.0) sun_gloss.push_back(shared_sun_glow_table(scene.medium.phase, to_sun, has_top, n_phong));
        }
    allocate_filled(result.surface_normals, 3 * n_pixels, 0.0f);

    // Light positions (point lights first, then spots), the spots' cones.
    std::vector<Vec3> positions;
    std::vector<SpotCone> cones;
    for (const PointLight& l : scene.point_lights) positions.push_back(l.position);
    for (const SpotLight& l : scene.spot_lights) {
        positions.push_back(l.position);
        cones.push_back(make_light_cone(l));
    }
    std::unique_ptr<GaussianMedium> gaussians;
    if (!scene.gaussians.empty())
        gaussians = std::make_unique<GaussianMedium>(scene.gaussians.centres, scene.gaussians.scales,
                                          scene.gaussians.amplitudes, sigma_t);
    // No fog: attenuation 1, glow 0 (normals are still written below: they do not depend on it).
    const bool fog = sigma_t > 0.0 || gaussians;
    // The glow's G tables (see surface_pass.h): Sun's isotropic ones, the phase-aware G_p of
    // biri06_surface.h for an anisotropic phase, and with settings.surface_glow_biri_eq10 Biri's own Lambert model
    // (eq. 10, Gamma_L x cos, clamped at 0) with eq. 12 (= G_p, m = n) for the gloss.
    const PhaseFunction& phase = scene.medium.phase;
    const bool isotropic = phase_is_isotropic(phase);
    std::shared_ptr<const SurfaceGTable> table;
    std::shared_ptr<const SurfaceGTable> phong;
    std::shared_ptr<const PhaseSurfaceGTable> phase_table, phase_phong;
    std::shared_ptr<const Biri06LambertTable> biri_lambert;
    if (fog && n_positional > 0) {
        if (isotropic) {
            if (settings.surface_glow_biri_eq10) biri_lambert = shared_biri06_lambert_table(phase);
            else table = shared_surface_G_table(settings.surface_table_nT, settings.surface_table_ntheta);
            if (n_phong > 0.0)
                phong = shared_surface_G_table(settings.surface_phong_table_n, settings.surface_phong_table_n, n_phong);
        } else {
            if (settings.surface_glow_biri_eq10)
                biri_lambert = shared_biri06_lambert_table(phase);
            else
                phase_table = shared_phase_surface_G_table(phase, settings.surface_table_nT,
                                                           settings.surface_table_ntheta);
            if (n_phong > 0.0)
                phase_phong = shared_phase_surface_G_table(phase, settings.surface_phong_table_n,
                                                           settings.surface_phong_table_n, n_phong);
        }
    }
    const bool glow_on = table || phase_table || biri_lambert;
    // Spots: the point-light glow times SpotGlowModel's factor (spot_surface.h), per spot.
    std::vector<std::shared_ptr<const SpotGlowModel>> spot_models;
    if (glow_on)
        for (const SpotCone& cone : cones) spot_models.push_back(shared_spot_glow_model(cone, phase));

    std::unique_ptr<GlowShadowGrid> shadow_grid;
    if (glow_shadow && glow_shadow->any() && glow_on && fog)
        shadow_grid = std::make_unique<GlowShadowGrid>(*glow_shadow, rays, caster, W, H, n_threads);
    // Rows interleaved over the threads; each row casts its centre rays with normals.
    auto work = [&](int first) {
        std::vector<double> lit_share(glow_shadow ? glow_shadow->num_lights() : 0, 1.0);
        std::vector<Ray> row(W);
        std::vector<float> t_near(W), t_far(W), t(W), ng(3 * size_t(W));
        for (int j = first; j < H; j += n_threads) {
            for (int i = 0; i < W; ++i) {
                row[i] = rays(i + 0.5, j + 0.5);
                double tn, tf;
                rays.clip_range(row[i], tn, tf);
                t_near[i] = float(tn);
                t_far[i] = float(std::min(tf, double(std::numeric_limits<float>::max()))) ;
                if (std::isinf(tf)) t_far[i] = std::numeric_limits<float>::infinity();
            }
            caster.first_hits_normals(row.data(), t_near.data(), t_far.data(), W, t.data(), ng.data());
            for (int i = 0; i < W; ++i) {
                if (std::isinf(t[i])) continue;
                const size_t px = size_t(j) * W + i;
                const Vec3 p = row[i].o + double(t[i]) * row[i].d;
                Vec3 n(ng[3 * i], ng[3 * i + 1], ng[3 * i + 2]);
                if (glm::dot(n, row[i].d) > 0.0) n = -n;  // facing the camera
                for (int c = 0; c < 3; ++c) result.surface_normals[3 * px + c] = float(n[c]);
                if (!fog) continue;
                if (shadow_grid) shadow_grid->at(i, j, p, t[i], n, lit_share.data());
                // Light l's share of its glow from lit fog (1 without volumetric shadows).
                auto lit_of = [&](size_t l) { return lit_share.empty() ? 1.0 : lit_share[l]; };
                RGB glow(0.0), gloss(0.0);
                const Vec3 mirror = row[i].d - 2.0 * glm::dot(row[i].d, n) * n;  // r about n
                for (size_t k = 0; k < sun_mu.size(); ++k) {
                    double att = 1.0;
                    if (std::isfinite(scene.fog_top) && p.z < scene.fog_top)
                        att = sun_mu[k] > 0.0 ? std::exp(-sigma_t * (scene.fog_top - p.z) / sun_mu[k]) : 0.0;
                    float* a = &result.surface_attenuation[((n_positional + k) * n_pixels + px) * 3];
                    a[0] = a[1] = a[2] = float(att);
                    const double tau = has_top ? sigma_t * (scene.fog_top - p.z) : 0.0;
                    const double share = lit_of(n_positional + k);
                    if (!sun_glow.empty()) glow += scene.sun_lights[k].E * (share * sun_glow[k]->eval(tau, n));
                    // Phong: (n + 2)/(2 pi) int L_in cos^n = albedo E (n + 2)/2 Q_n(tau, r).
                    if (!sun_gloss.empty())
                        gloss += scene.sun_lights[k].E *
                                 (share * 0.5 * (n_phong + 2.0) * sun_gloss[k]->eval(tau, mirror));
                }
                for (size_t l = 0; l < n_positional; ++l) {
                    const Vec3 v = positions[l] - p;
                    const double D = glm::length(v);
                    const double T = gaussians ? gaussians->optical_depth(positions[l], p) : sigma_t * D;
                    const double att_d = std::exp(-T);
                    const float att = float(att_d);
                    float* a = &result.surface_attenuation[(l * n_pixels + px) * 3];
                    a[0] = a[1] = a[2] = att;
                    if (!glow_on || !(D > 0.0)) continue;
                    // Beyond T = 64 the G tables take their large-T tails (sun05_surface.h), so
                    // every density costs the same. Biri's eq. 10 table (a comparison model) has
                    // no tail: there the glow, below e^{-64} of the light's, is left out.
                    if (biri_lambert && T > 64.0) continue;
                    // A spot's glow: the point-light glow times its model factor (spot_surface.h).
                    RGB I0 = l < n_point ? scene.point_lights[l].I0 : scene.spot_lights[l - n_point].I0;
                    if (l >= n_point) {
                        const double factor = spot_models[l - n_point]->factor(T, glm::dot(cones[l - n_point].axis, -v) / D);
                        if (!(factor > 0.0)) continue;
                        I0 *= factor;
                    }
                    // Lambert glow of light l. Homogeneous fog: T = sigma_t D. With fog objects,
                    // Fogshop eq. 25: the exact optical depth T(s, p) in place of sigma_t D and the
                    // mean extinction T / D in place of sigma_t.
                    const double beta_bar = gaussians ? T / D : sigma_t;
                    const double cos_s = std::clamp(glm::dot(n, v) / D, -1.0, 1.0);
                    // e^{-T} G from the scaled table.
                    double G;
                    if (table) G = att_d * table->eval_scaled(T, std::acos(cos_s));
                    else if (phase_table) G = att_d * phase_table->eval_scaled(T, std::acos(cos_s));
                    else G = att_d * std::max(0.0, biri_lambert->eval_G_scaled(T, cos_s));
                    I0 *= lit_of(l);
                    glow += I0 * (beta_bar * G / (2.0 * kPi * D * kPi));
                    if (phong || phase_phong) {
                        // Glossy: angles from the mirrored view direction (Ramamoorthi-Hanrahan).
                        const double cos_r = std::clamp(glm::dot(mirror, v) / D, -1.0, 1.0);
                        const double Gn = phong ? phong->eval(T, std::acos(cos_r)) : phase_phong->eval(T, std::acos(cos_r));
                        gloss += I0 * ((n_phong + 2.0) / (2.0 * kPi) * beta_bar * Gn / (2.0 * kPi * D));
                    }
                }
                for (int c = 0; c < 3; ++c) result.surface_glow[3 * px + c] = float(albedo[c] * glow[c]);
                if (n_phong > 0.0)
                    for (int c = 0; c < 3; ++c) result.surface_gloss_glow[3 * px + c] = float(albedo[c] * gloss[c]);
            }
        }
    };
    parallel_for(n_threads, n_threads, work);  // one stripe of rows per item
}

}  // namespace airlight
