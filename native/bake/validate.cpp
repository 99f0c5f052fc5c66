// validate.cpp: the bake's checks of a scene and its settings (validate.h).
#include "bake/validate.h"

#include <cmath>
#include <cstdio>
#include <limits>
#include <stdexcept>
#include <string>

#include "core/constants.h"
#include "core/memory.h"
#include "core/parallel.h"
#include "gaussian/splat.h"
#include "homogeneous/spot_light.h"
#include "image/camera.h"
#include "models/registry.h"

namespace airlight {

namespace {

constexpr int kMaxResolution = 32768;

// Throw std::invalid_argument with _msg_ unless _ok_.
void require(bool ok, const std::string& msg) {
    if (!ok) throw std::invalid_argument(msg);
}
// The same with a literal, or a message made only when it is thrown: the per-element checks
// of a large mesh would otherwise make a string per element (1e7 triangles: 3e7 of them).
void require(bool ok, const char* msg) {
    if (!ok) throw std::invalid_argument(msg);
}
template <typename Make>
void require_that(bool ok, const Make& make_message) {
    if (!ok) throw std::invalid_argument(make_message());
}

bool finite3(const glm::dvec3& v) {
    return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}

// Sun lamps and the fog top (sunlight_layer.h).
void validate_suns(const SceneDescription& scene) {
    for (size_t i = 0; i < scene.sun_lights.size(); ++i) {
        const SunLight& sun = scene.sun_lights[i];
        const std::string name = "sun light " + std::to_string(i);
        require(finite3(sun.direction) && glm::length(sun.direction) > 0.0,
                name + ": direction must be finite and nonzero");
        require(std::isfinite(sun.angle) && sun.angle >= 0.0 && sun.angle <= kPi,
                name + ": angle must be in [0, pi] radians, got " + std::to_string(sun.angle));
        require(finite3(sun.E) && sun.E.x >= 0.0 && sun.E.y >= 0.0 && sun.E.z >= 0.0,
                name + ": irradiance must be finite and >= 0");
    }
    require(!std::isnan(scene.fog_top) && scene.fog_top != -std::numeric_limits<double>::infinity(),
            "fog_top must be a finite height or +inf (no top), got " + std::to_string(scene.fog_top));
}

// Per-light passes (SceneDescription::light_passes): each light's index in range, and a bake
// that evaluates every pixel's lights one by one (the whole-image models, the Gaussian splat
// and the homogeneous lattice sum them or interpolate their sum).
void validate_light_passes(const SceneDescription& scene, const BakeSettings& settings) {
    const int n = scene.light_passes;
    require(n >= 0, "light_passes must be >= 0");
    auto check = [&](int pass, const std::string& name) {
        require(pass >= -1 && pass < n, name + ": light pass " + std::to_string(pass) + " out of range (" +
                                            std::to_string(n) + " passes; -1: none)");
    };
    for (size_t i = 0; i < scene.point_lights.size(); ++i)
        check(scene.point_lights[i].light_pass, "light " + std::to_string(i));
    for (size_t i = 0; i < scene.spot_lights.size(); ++i)
        check(scene.spot_lights[i].light_pass, "spot light " + std::to_string(i));
    for (size_t i = 0; i < scene.sun_lights.size(); ++i)
        check(scene.sun_lights[i].light_pass, "sun light " + std::to_string(i));
    if (n == 0) return;
    require(scene.gaussians.empty(), "light passes in one bake: not with fog objects (bake each light alone)");
    require(model_entry(settings.model).bake == nullptr,
            "light passes in one bake: not with model '" + model_entry(settings.model).name +
                "', which bakes the whole image (bake each light alone)");
    require(settings.homogeneous_resolution == 1,
            "light passes in one bake: not with a homogeneous resolution below full (bake each light alone)");
}

// How close to the eye a light counts as at it: the models regularise the light's distance
// below this (sun05, biri06: D_sv >= 1e-6) and disagree there.
constexpr double kAtEyeDistance = 1e-6;

// A point or spot light at the eye of a perspective camera whose fog starts at the eye
// (clip_start = 0): along every ray the single scattering sigma_s p I0 e^{-2 sigma_t x} / x^2
// diverges like 1/x at x = 0, so every pixel's airlight is infinite. Refused, naming the light
// (Blender's cameras always start the fog at their Clip Start, where it is finite).
void validate_lights_at_eye(const SceneDescription& scene) {
    if (!(scene.medium.sigma_t > 0.0) && scene.gaussians.empty()) return;
    const CameraRays rays(scene.camera);
    if (rays.orthographic() || rays.clip_start() > 0.0) return;
    const Vec3 eye = rays.position();
    auto check = [&](const Vec3& position, const RGB& I0, const std::string& name) {
        const double d = glm::length(position - eye);
        if (d >= kAtEyeDistance || (I0.x == 0.0 && I0.y == 0.0 && I0.z == 0.0)) return;
        char distance[32];
        std::snprintf(distance, sizeof distance, "%.3g", d);
        throw std::invalid_argument(
            name + " is at the camera (" + distance + " m from the eye) and the fog starts at the eye "
            "(clip_start = 0): the light it scatters back diverges (the integral of 1/x^2 from the eye) on every "
            "pixel; move the light off the camera, or set clip_start > 0 (the fog then starts there, as in Cycles)");
    };
    for (size_t i = 0; i < scene.point_lights.size(); ++i)
        check(scene.point_lights[i].position, scene.point_lights[i].I0, "light " + std::to_string(i));
    for (size_t i = 0; i < scene.spot_lights.size(); ++i)
        check(scene.spot_lights[i].position, scene.spot_lights[i].I0, "spot light " + std::to_string(i));
}

}  // namespace

void validate(const SceneDescription& scene, const BakeSettings& settings) {
    const Camera& cam = scene.camera;
    require(cam.width > 0 && cam.height > 0,
            "resolution must be positive, got " + std::to_string(cam.width) + " x " +
                std::to_string(cam.height));
    require(cam.width <= kMaxResolution && cam.height <= kMaxResolution,
            "resolution must be at most " + std::to_string(kMaxResolution) + " per axis, got " +
                std::to_string(cam.width) + " x " + std::to_string(cam.height));
    const HomogeneousMedium& medium = scene.medium;
    require(std::isfinite(medium.sigma_t) && medium.sigma_t >= 0.0,
            "sigma_t (density) must be finite and >= 0, got " + std::to_string(medium.sigma_t));
    require(finite3(medium.albedo) && medium.albedo.x >= 0.0 && medium.albedo.y >= 0.0 &&
                medium.albedo.z >= 0.0,
            "albedo must be finite and >= 0");
    require(std::abs(medium.phase.g) < 1.0,
            "phase: g (anisotropy) must be finite with |g| < 1, got " + std::to_string(medium.phase.g));
    // The model's own checks (its phases, lights and fog objects: models/<paper>_model.cpp).
    const ModelEntry& entry = model_entry(settings.model);
    if (entry.validate) entry.validate(scene, settings);
    validate_suns(scene);
    require(std::isfinite(medium.rayleigh_550) && medium.rayleigh_550 >= 0.0,
            "rayleigh_density must be finite and >= 0, got " + std::to_string(medium.rayleigh_550));
    // Gaussian fog (Fogshop): the Fogshop approximation (sun05, sun05_exact: F table or exact
    // F for the background term; biri06, pegoraro10: their model for it, any phase) or its
    // quadrature reference; point, spot and sun lamps (gaussian/splat.h GaussianSplatLights).
    const Gaussians& gauss = scene.gaussians;
    if (!gauss.empty()) {
        const size_t n = gauss.scales.size();
        require(gauss.amplitudes.size() == n && gauss.centres.size() == 3 * n,
                "gaussians: centres (" + std::to_string(gauss.centres.size()) + " values), scales (" +
                    std::to_string(n) + ") and amplitudes (" + std::to_string(gauss.amplitudes.size()) +
                    ") must describe the same number of Gaussians (3 centre values each)");
        for (double x : gauss.centres) require(std::isfinite(x), "gaussians: centres must be finite");
        for (size_t i = 0; i < n; ++i) {
            require_that(std::isfinite(gauss.scales[i]) && gauss.scales[i] > 0.0, [&] {
                return "gaussians: scale " + std::to_string(i) + " must be finite and > 0, got " +
                       std::to_string(gauss.scales[i]);
            });
            require_that(std::isfinite(gauss.amplitudes[i]) && gauss.amplitudes[i] >= 0.0, [&] {
                return "gaussians: amplitude " + std::to_string(i) + " must be finite and >= 0, got " +
                       std::to_string(gauss.amplitudes[i]);
            });
        }
        require(gauss.albedo.empty() || gauss.albedo.size() == 3 * n,
                "gaussians: albedo must hold 3 values per Gaussian (" + std::to_string(3 * n) + "), got " +
                    std::to_string(gauss.albedo.size()));
        for (double x : gauss.albedo)
            require(std::isfinite(x) && x >= 0.0, "gaussians: albedo must be finite and >= 0");
        validate_noise({gauss.noise_amplitude, gauss.noise_scale, gauss.noise_offset});
    }
    for (size_t i = 0; i < scene.point_lights.size(); ++i) {
        const PointLight& light = scene.point_lights[i];
        require(finite3(light.position), "light " + std::to_string(i) + ": position must be finite");
        require(finite3(light.I0) && light.I0.x >= 0.0 && light.I0.y >= 0.0 && light.I0.z >= 0.0,
                "light " + std::to_string(i) + ": intensity must be finite and >= 0");
        require(std::isfinite(light.radius) && light.radius >= 0.0,
                "light " + std::to_string(i) + ": radius must be finite and >= 0, got " + std::to_string(light.radius));
    }
    for (size_t i = 0; i < scene.spot_lights.size(); ++i) {
        const SpotLight& spot = scene.spot_lights[i];
        const std::string name = "spot light " + std::to_string(i);
        require(finite3(spot.position), name + ": position must be finite");
        require(finite3(spot.axis) && glm::length(spot.axis) > 0.0, name + ": axis must be finite and nonzero");
        require(finite3(spot.I0) && spot.I0.x >= 0.0 && spot.I0.y >= 0.0 && spot.I0.z >= 0.0,
                name + ": intensity must be finite and >= 0");
        require(std::isfinite(spot.spot_size) && spot.spot_size > 0.0 && spot.spot_size <= kPi + 1e-9,
                name + ": spot_size must be in (0, pi] rad, got " + std::to_string(spot.spot_size));
        require(std::isfinite(spot.spot_blend) && spot.spot_blend >= 0.0 && spot.spot_blend <= 1.0,
                name + ": spot_blend must be in [0, 1], got " + std::to_string(spot.spot_blend));
        require(std::isfinite(spot.spread) && spot.spread >= kMinSpread && spot.spread <= kPi + 1e-9,
                name + ": spread must be in [1 deg, pi] rad, got " + std::to_string(spot.spread));
        require(spot.spread >= kPi - 1e-9 || (spot.spot_size >= kPi - 1e-9 && spot.spot_blend == 0.0),
                name + ": a spread below pi (an area light's sample) needs spot_size pi and spot_blend 0");
        require(std::isfinite(spot.radius) && spot.radius >= 0.0,
                name + ": radius must be finite and >= 0, got " + std::to_string(spot.radius));
        for (double c : spot.profile)
            require_that(std::isfinite(c), [&] { return name + ": profile coefficients must be finite"; });
        require(spot.profile.empty() || spot.profile.size() <= 17,
                name + ": a profile (spot_profiles) has at most 17 coefficients (degree 16)");
        require(spot.profile.empty() || spot.profile_in_cone ||
                    (spot.spot_size >= kPi - 1e-9 && spot.spot_blend == 0.0 && spot.spread >= kPi - 1e-9),
                name + ": a profile (spot_profiles) over the whole sphere needs spot_size pi, spot_blend 0 and no "
                       "spread (or spot_profile_in_cone)");
        require(std::isfinite(spot.profile_extent) && spot.profile_extent > 0.0 && spot.profile_extent <= kPi + 1e-9,
                name + ": profile_extent must be in (0, pi] rad, got " + std::to_string(spot.profile_extent));
        require(spot.profile_extent >= kPi - 1e-9 || (!spot.profile.empty() && !spot.profile_in_cone),
                name + ": a profile extent (spot_profile_extent) below pi needs a profile over the sphere "
                       "(spot_profiles, not in a cone)");
        require(spot.profile.empty() || spot.spread >= kPi - 1e-9,
                name + ": a profile (spot_profiles) cannot go with a spread (an area light's sample)");
    }
    validate_light_passes(scene, settings);
    const TriangleMesh& mesh = scene.geometry;
    require(mesh.vertices.size() % 3 == 0, "vertices must hold 3 floats per vertex");
    require(mesh.triangles.size() % 3 == 0, "triangles must hold 3 indices per triangle");
    for (float x : mesh.vertices) require(std::isfinite(x), "vertices must be finite (found NaN or inf)");
    const size_t n_vertices = mesh.vertices.size() / 3;
    for (uint32_t index : mesh.triangles)
        require_that(index < n_vertices, [&] {
            return "triangle index " + std::to_string(index) + " out of range (vertex count " +
                   std::to_string(n_vertices) + ")";
        });
    require(settings.threads >= 0 && settings.threads <= kMaxThreads, thread_count_error(settings.threads));
    require(settings.aa_samples >= 1 && settings.aa_samples <= 64, "aa_samples must be in [1, 64]");
    require(settings.shadow_samples >= 1 && settings.shadow_samples <= 64,
            "shadow_samples must be in [1, 64] (1: hard shadows), got " + std::to_string(settings.shadow_samples));
    require(std::isfinite(settings.filter_width) && settings.filter_width >= 0.0,
            "filter_width must be finite and >= 0");
    require(settings.edge_cluster_tol >= 0.0 && !std::isnan(settings.edge_cluster_tol),
            "edge_cluster_tol must be >= 0 (0: every sub-sample evaluated), got " +
                std::to_string(settings.edge_cluster_tol));
    require(settings.table_nu >= 2 && settings.table_nT >= 2 && settings.table_nu <= 16384 &&
                settings.table_nT <= 16384,
            "table size must be in [2, 16384] per axis");
    // The camera matrices are checked by CameraRays (finite, invertible), here for the
    // lights at the eye.
    validate_lights_at_eye(scene);
    const std::string size = std::to_string(cam.width) + " x " + std::to_string(cam.height);
    const std::string shortfall = memory_shortfall(
        bake_image_bytes(scene, settings), "the bake of " + size + " pixels",
        settings.surface ? "lower the resolution or bake a render region, or turn surface shading off"
                         : "lower the resolution or bake a render region");
    require(shortfall.empty(), shortfall);
}

double bake_image_bytes(const SceneDescription& scene, const BakeSettings& settings) {
    double floats = 9.0 + 3.0 * double(scene.light_passes);
    if (settings.surface) {
        const size_t lights = scene.point_lights.size() + scene.spot_lights.size() + scene.sun_lights.size();
        floats += 3.0 * double(lights) + 6.0 + (settings.surface_phong_exponent > 0.0 ? 3.0 : 0.0);
    }
    return floats * sizeof(float) * double(scene.camera.width) * double(scene.camera.height);
}

}  // namespace airlight
