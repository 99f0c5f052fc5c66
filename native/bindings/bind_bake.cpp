// bind_bake.cpp: the whole-image bake and the multilayer EXR writer.
#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include "bake/bake.h"
#include "bake/map_cache.h"
#include "image/raycast.h"
#include "shadow/shadow_volumes.h"
#include "core/memory.h"
#include "image/exr_io.h"
#include "models/registry.h"
#include "core/phase.h"
#include "bindings/numpy_util.h"

namespace airlight::bindings {

using namespace pybind11::literals;

namespace {

// Triangle indices: any integer array of shape (M, 3) with values in [0, 2^32).
glm::dvec3 to_rgb(const py::object& obj, const char* name) {
    auto a = as_array<double>(obj, name);
    if (a.size() != 3) throw py::value_error(std::string(name) + ": expected 3 values, got " + shape_str(a));
    return {a.data()[0], a.data()[1], a.data()[2]};
}

// The medium's phase function from the bake's names ("mie_hazy" / "mie_murky", as the
// add-on spells them; phase.h's "hazy_mie" / "murky_mie" are accepted too).
PhaseFunction bake_phase(std::string name, double g) {
    if (name == "mie_hazy") name = "hazy_mie";
    else if (name == "mie_murky") name = "murky_mie";
    else if (name == "hazy_mie" || name == "murky_mie" || name == "isotropic" || name == "hg" || name == "rayleigh") {
    } else {
        throw py::value_error("phase: unknown phase function '" + name +
                              "'; valid: 'isotropic', 'hg', 'rayleigh', 'mie_hazy', 'mie_murky'");
    }
    if (!(std::abs(g) < 1.0)) throw py::value_error("g: must be finite with |g| < 1, got " + std::to_string(g));
    if (name != "hg" && g != 0.0)
        throw py::value_error("g: only the 'hg' phase takes an anisotropy, got g = " + std::to_string(g) +
                              " with phase '" + name + "'");
    return phase_from_name(name, g);
}

// A bake output image as a numpy array that owns it (no copy); when numpy frees it, its
// memory goes back to the bake's pool (bake.h recycle_image_buffer: warm pages for the next bake).
py::array_t<float> image_to_numpy(std::vector<float>&& data, std::vector<py::ssize_t> shape) {
    auto* owner = new std::vector<float>(std::move(data));
    py::capsule recycle(owner, [](void* p) {
        auto* v = static_cast<std::vector<float>*>(p);
        recycle_image_buffer(std::move(*v));
        delete v;
    });
    return py::array_t<float>(shape, owner->data(), recycle);
}

py::dict bake_py(int width, int height, const py::object& cam_to_world, const py::object& projection,
                 const py::object& vertices, const py::object& triangles,
                 const py::object& light_positions, const py::object& light_intensities, double sigma_t,
                 const py::object& albedo, const std::string& phase, double g, const std::string& model,
                 int threads, int aa_samples,
                 double filter_width, double clip_start, double clip_end, const py::object& progress,
                 const py::object& rbf_centres, const py::object& rbf_scales, const py::object& rbf_amplitudes,
                 const py::object& spot_positions, const py::object& spot_axes, const py::object& spot_intensities,
                 const py::object& spot_size, const py::object& spot_blend, const py::object& spot_spread,
                 const py::object& sun_directions,
                 const py::object& sun_irradiances, double fog_top, int table_size,
                 const std::string& table_interpolation, const py::object& rbf_albedo,
                 double noise_amplitude, double noise_scale, const py::object& noise_offset, bool surface,
                 double surface_phong_exponent, double rayleigh_density, const std::string& gaussian_resolution,
                 const std::string& surface_glow_model, const std::string& homogeneous_resolution,
                 double edge_cluster_tol, bool shadows, const py::object& light_shadows,
                 const py::object& spot_shadows, const py::object& sun_shadows, const py::object& occluder_vertices,
                 const py::object& occluder_triangles, double gaussian_accuracy, double gaussian_refine_budget,
                 const std::string& shadow_crossings, const py::object& light_radii, const py::object& spot_radii,
                 const py::object& spot_profiles, const py::object& spot_profile_in_cone,
                 const py::object& spot_profile_extent, double light_size_tolerance,
                 const py::object& light_pass_index, int shadow_samples, const py::object& sun_angles,
                 long long occluder_seen_triangles) {
    // Gather the scene description from the arrays (shapes checked here, values in bake()).
    SceneDescription scene;
    scene.camera.width = width;
    scene.camera.height = height;
    scene.camera.cam_to_world = to_mat4(cam_to_world, "cam_to_world");
    scene.camera.projection = to_mat4(projection, "projection");
    scene.camera.clip_start = clip_start;
    scene.camera.clip_end = clip_end;
    scene.medium.sigma_t = sigma_t;
    scene.medium.rayleigh_550 = rayleigh_density;
    scene.medium.albedo = to_rgb(albedo, "albedo");
    scene.medium.phase = bake_phase(phase, g);

    auto v = as_array<float>(vertices, "vertices");
    py::ssize_t n_vertices = require_rows_of(v, 3, "vertices");
    scene.geometry.vertices.assign(v.data(), v.data() + 3 * n_vertices);
    scene.geometry.triangles = to_triangles(triangles);

    auto lp = as_array<double>(light_positions, "light_positions");
    py::ssize_t n_lights = require_rows_of(lp, 3, "light_positions");
    auto li = as_array<double>(light_intensities, "light_intensities");
    require_rows_of(li, 3, "light_intensities", n_lights);
    for (py::ssize_t l = 0; l < n_lights; ++l) {
        PointLight light;
        light.position = {lp.at(l, 0), lp.at(l, 1), lp.at(l, 2)};
        light.I0 = {li.at(l, 0), li.at(l, 1), li.at(l, 2)};
        scene.point_lights.push_back(light);
    }
    // Per light its radius (values checked in bake()).
    // One value per light (radii, flags), or nothing where _values_ is None.
    auto per_light = [](const py::object& values, const char* name, const char* what, size_t n, auto set) {
        if (values.is_none()) return;
        auto r = as_array<double>(values, name);
        if (!(r.ndim() == 1 && size_t(r.shape(0)) == n))
            throw py::value_error(std::string(name) + ": expected one " + what + " per light (" + std::to_string(n) +
                                  "), got shape " + shape_str(r));
        for (size_t i = 0; i < n; ++i) set(i, r.data()[i]);
    };
    per_light(light_radii, "light_radii", "radius", scene.point_lights.size(),
          [&](size_t i, double r) { scene.point_lights[i].radius = r; });

    // Gaussian fog: all three arrays or none; values checked here so the errors name them.
    const int n_gaussian_given = int(!rbf_centres.is_none()) + int(!rbf_scales.is_none()) + int(!rbf_amplitudes.is_none());
    if (n_gaussian_given != 0 && n_gaussian_given != 3)
        throw py::value_error("rbf_centres, rbf_scales and rbf_amplitudes must be given together (or all None)");
    if (n_gaussian_given == 3) {
        auto bc = as_array<double>(rbf_centres, "rbf_centres");
        const py::ssize_t n = require_rows_of(bc, 3, "rbf_centres");
        auto a = as_array<double>(rbf_scales, "rbf_scales");
        auto c = as_array<double>(rbf_amplitudes, "rbf_amplitudes");
        if (!(a.ndim() == 1 && a.shape(0) == n))
            throw py::value_error("rbf_scales: expected shape (" + std::to_string(n) + ",) to match rbf_centres, got " +
                                  shape_str(a));
        if (!(c.ndim() == 1 && c.shape(0) == n))
            throw py::value_error("rbf_amplitudes: expected shape (" + std::to_string(n) +
                                  ",) to match rbf_centres, got " + shape_str(c));
        for (py::ssize_t i = 0; i < 3 * n; ++i)
            if (!std::isfinite(bc.data()[i])) throw py::value_error("rbf_centres: must be finite (found NaN or inf)");
        for (py::ssize_t i = 0; i < n; ++i) {
            if (!(std::isfinite(a.data()[i]) && a.data()[i] > 0.0))
                throw py::value_error("rbf_scales: must be finite and > 0, got " + std::to_string(a.data()[i]) +
                                      " at index " + std::to_string(i));
            if (!(std::isfinite(c.data()[i]) && c.data()[i] >= 0.0))
                throw py::value_error("rbf_amplitudes: must be finite and >= 0, got " + std::to_string(c.data()[i]) +
                                      " at index " + std::to_string(i));
        }
        scene.gaussians.centres.assign(bc.data(), bc.data() + 3 * n);
        scene.gaussians.scales.assign(a.data(), a.data() + n);
        scene.gaussians.amplitudes.assign(c.data(), c.data() + n);
        if (!rbf_albedo.is_none()) {
            auto al = as_array<double>(rbf_albedo, "rbf_albedo");
            require_rows_of(al, 3, "rbf_albedo", n);
            scene.gaussians.albedo.assign(al.data(), al.data() + 3 * n);
        }
    } else if (!rbf_albedo.is_none()) {
        throw py::value_error("rbf_albedo needs rbf_centres, rbf_scales and rbf_amplitudes");
    }
    scene.gaussians.noise_amplitude = noise_amplitude;
    scene.gaussians.noise_scale = noise_scale;
    {
        auto no = as_array<double>(noise_offset, "noise_offset");
        if (no.size() != 3) throw py::value_error("noise_offset: expected 3 numbers, got shape " + shape_str(no));
        scene.gaussians.noise_offset = {no.data()[0], no.data()[1], no.data()[2]};
    }

    // Spot lights: all five arrays or none; shapes here, values (finite, ranges) in bake().
    const int n_spot_given = int(!spot_positions.is_none()) + int(!spot_axes.is_none()) +
                             int(!spot_intensities.is_none()) + int(!spot_size.is_none()) + int(!spot_blend.is_none());
    if (n_spot_given != 0 && n_spot_given != 5)
        throw py::value_error(
            "spot_positions, spot_axes, spot_intensities, spot_size and spot_blend must be given together (or all None)");
    if (n_spot_given == 0 && !spot_spread.is_none())
        throw py::value_error("spot_spread needs the spot lights (spot_positions ...)");
    if (n_spot_given == 5) {
        auto sp = as_array<double>(spot_positions, "spot_positions");
        const py::ssize_t n = require_rows_of(sp, 3, "spot_positions");
        auto sa = as_array<double>(spot_axes, "spot_axes");
        require_rows_of(sa, 3, "spot_axes", n);
        auto si = as_array<double>(spot_intensities, "spot_intensities");
        require_rows_of(si, 3, "spot_intensities", n);
        auto ss = as_array<double>(spot_size, "spot_size");
        auto sb = as_array<double>(spot_blend, "spot_blend");
        if (!(ss.ndim() == 1 && ss.shape(0) == n))
            throw py::value_error("spot_size: expected shape (" + std::to_string(n) + ",) to match spot_positions, got " +
                                  shape_str(ss));
        if (!(sb.ndim() == 1 && sb.shape(0) == n))
            throw py::value_error("spot_blend: expected shape (" + std::to_string(n) +
                                  ",) to match spot_positions, got " + shape_str(sb));
        py::array_t<double> sd;
        if (!spot_spread.is_none()) {
            sd = as_array<double>(spot_spread, "spot_spread");
            if (!(sd.ndim() == 1 && sd.shape(0) == n))
                throw py::value_error("spot_spread: expected shape (" + std::to_string(n) +
                                      ",) to match spot_positions, got " + shape_str(sd));
        }
        for (py::ssize_t l = 0; l < n; ++l) {
            SpotLight spot;
            if (!spot_spread.is_none()) spot.spread = sd.data()[l];
            spot.position = {sp.at(l, 0), sp.at(l, 1), sp.at(l, 2)};
            spot.axis = {sa.at(l, 0), sa.at(l, 1), sa.at(l, 2)};
            spot.I0 = {si.at(l, 0), si.at(l, 1), si.at(l, 2)};
            spot.spot_size = ss.data()[l];
            spot.spot_blend = sb.data()[l];
            scene.spot_lights.push_back(spot);
        }
    }

    // Sun lamps: both arrays or none; shapes here, values in bake().
    if (sun_directions.is_none() != sun_irradiances.is_none())
        throw py::value_error("sun_directions and sun_irradiances must be given together (or both None)");
    if (!sun_directions.is_none()) {
        auto sd = as_array<double>(sun_directions, "sun_directions");
        const py::ssize_t n = require_rows_of(sd, 3, "sun_directions");
        auto se = as_array<double>(sun_irradiances, "sun_irradiances");
        require_rows_of(se, 3, "sun_irradiances", n);
        for (py::ssize_t l = 0; l < n; ++l) {
            SunLight sun;
            sun.direction = {sd.at(l, 0), sd.at(l, 1), sd.at(l, 2)};
            sun.E = {se.at(l, 0), se.at(l, 1), se.at(l, 2)};
            scene.sun_lights.push_back(sun);
        }
    }
    scene.fog_top = fog_top;
    if (!sun_angles.is_none() && scene.sun_lights.empty())
        throw py::value_error("sun_angles needs the sun lights (sun_directions ...)");
    per_light(sun_angles, "sun_angles", "angle", scene.sun_lights.size(),
              [&](size_t i, double a) { scene.sun_lights[i].angle = a; });
    if (!spot_radii.is_none() && scene.spot_lights.empty())
        throw py::value_error("spot_radii needs the spot lights (spot_positions ...)");
    per_light(spot_radii, "spot_radii", "radius", scene.spot_lights.size(),
          [&](size_t i, double r) { scene.spot_lights[i].radius = r; });
    if (!spot_profiles.is_none()) {
        if (scene.spot_lights.empty()) throw py::value_error("spot_profiles needs the spot lights (spot_positions ...)");
        auto pr = as_array<double>(spot_profiles, "spot_profiles");
        if (!(pr.ndim() == 2 && size_t(pr.shape(0)) == scene.spot_lights.size() && pr.shape(1) >= 1))
            throw py::value_error("spot_profiles: expected shape (" + std::to_string(scene.spot_lights.size()) +
                                  ", K + 1), one row of coefficients per spot, got " + shape_str(pr));
        for (size_t i = 0; i < scene.spot_lights.size(); ++i) {
            std::vector<double> row(pr.data() + i * pr.shape(1), pr.data() + (i + 1) * pr.shape(1));
            const bool any = std::any_of(row.begin(), row.end(), [](double c) { return c != 0.0; });
            if (any) scene.spot_lights[i].profile = std::move(row);  // an all-zero row: the spot's cone
        }
    }
    if (!spot_profile_in_cone.is_none() && spot_profiles.is_none())
        throw py::value_error("spot_profile_in_cone needs spot_profiles");
    per_light(spot_profile_in_cone, "spot_profile_in_cone", "flag", scene.spot_lights.size(),
              [&](size_t i, double f) { scene.spot_lights[i].profile_in_cone = f != 0.0; });
    if (!spot_profile_extent.is_none() && spot_profiles.is_none())
        throw py::value_error("spot_profile_extent needs spot_profiles");
    per_light(spot_profile_extent, "spot_profile_extent", "angle", scene.spot_lights.size(),
              [&](size_t i, double a) { scene.spot_lights[i].profile_extent = a; });

    // Volumetric shadows: per light its Cast Shadow (all cast by default), and the casters
    // when they are not the camera's geometry.
    auto cast_flags = [&](const py::object& flags, const char* name, size_t n, auto set) {
        per_light(flags, name, "flag", n, [&](size_t i, double f) { set(i, f != 0.0); });
    };
    cast_flags(light_shadows, "light_shadows", scene.point_lights.size(),
               [&](size_t i, bool on) { scene.point_lights[i].casts_shadow = on; });
    cast_flags(spot_shadows, "spot_shadows", scene.spot_lights.size(),
               [&](size_t i, bool on) { scene.spot_lights[i].casts_shadow = on; });
    cast_flags(sun_shadows, "sun_shadows", scene.sun_lights.size(),
               [&](size_t i, bool on) { scene.sun_lights[i].casts_shadow = on; });
    if (occluder_vertices.is_none() != occluder_triangles.is_none())
        throw py::value_error("occluder_vertices and occluder_triangles must be given together (or both None)");
    if (!occluder_vertices.is_none()) {
        auto ov = as_array<float>(occluder_vertices, "occluder_vertices");
        const py::ssize_t n = require_rows_of(ov, 3, "occluder_vertices");
        for (py::ssize_t i = 0; i < 3 * n; ++i)
            if (!std::isfinite(ov.data()[i])) throw py::value_error("occluder_vertices: must be finite (found NaN or inf)");
        scene.occluders.vertices.assign(ov.data(), ov.data() + 3 * n);
        scene.occluders.triangles = to_triangles(occluder_triangles);
        for (uint32_t i : scene.occluders.triangles)
            if (i >= uint32_t(n)) throw py::value_error("occluder_triangles: index " + std::to_string(i) + " out of range");
        scene.occluders_from_geometry = false;
    }
    if (occluder_seen_triangles < 0 || size_t(occluder_seen_triangles) > scene.occluders.triangles.size() / 3)
        throw py::value_error("occluder_seen_triangles: " + std::to_string(occluder_seen_triangles) +
                              " is not between 0 and the occluder triangles' count");
    scene.occluders_seen_triangles = size_t(occluder_seen_triangles);

    // Per-light passes: per light (points, spots, suns in order) its pass, -1 none.
    if (!light_pass_index.is_none()) {
        auto a = as_array<double>(light_pass_index, "light_pass_index");
        const size_t n_points = scene.point_lights.size(), n_spots = scene.spot_lights.size();
        const size_t n = n_points + n_spots + scene.sun_lights.size();
        if (a.ndim() != 1 || size_t(a.shape(0)) != n)
            throw py::value_error("light_pass_index: expected one value per light (" + std::to_string(n) +
                                  ": points, spots, suns), got shape " + shape_str(a));
        for (size_t i = 0; i < n; ++i) {
            const double v = a.data()[i];
            if (!(v == std::floor(v) && v >= -1.0 && v < 1e6))
                throw py::value_error("light_pass_index: " + std::to_string(v) +
                                      " is not a pass index (an integer >= 0, or -1: none)");
            const int pass = int(v);
            scene.light_passes = std::max(scene.light_passes, pass + 1);
            if (i < n_points) scene.point_lights[i].light_pass = pass;
            else if (i < n_points + n_spots) scene.spot_lights[i - n_points].light_pass = pass;
            else scene.sun_lights[i - n_points - n_spots].light_pass = pass;
        }
    }

    BakeSettings settings;
    settings.shadows = shadows;
    if (shadow_crossings != "film" && shadow_crossings != "traced")
        throw py::value_error("shadow_crossings must be 'film' or 'traced', not '" + shadow_crossings + "'");
    settings.shadow_crossings_traced = shadow_crossings == "traced";
    settings.shadow_samples = shadow_samples;
    if (!(gaussian_accuracy >= 0.0 && gaussian_accuracy < 1.0))
        throw py::value_error("gaussian_accuracy must be in [0, 1) (a relative error; 0: Fogshop alone)");
    settings.gaussian_accuracy = gaussian_accuracy;
    if (!(light_size_tolerance > 0.0 && light_size_tolerance <= 0.005))
        throw py::value_error("light_size_tolerance must be in (0, 0.005] (a relative change of a light's airlight; "
                              "the skip test's expansion holds beyond 8.7 radii)");
    settings.light_size_tolerance = light_size_tolerance;
    if (!(gaussian_refine_budget >= 0.0))
        throw py::value_error("gaussian_refine_budget must be >= 0 (nominal CPU seconds)");
    settings.gaussian_refine_budget = gaussian_refine_budget;
    settings.model = model_from_name(model);
    settings.threads = threads;
    settings.aa_samples = aa_samples;
    settings.filter_width = filter_width;
    settings.edge_cluster_tol = edge_cluster_tol;
    settings.surface = surface;
    settings.surface_phong_exponent = surface_phong_exponent;
    if (surface_glow_model == "biri06_eq10") settings.surface_glow_biri_eq10 = true;
    else if (surface_glow_model != "exact")
        throw py::value_error("surface_glow_model must be \"exact\" or \"biri06_eq10\", got \"" + surface_glow_model + "\"");
    if (table_size < 8 || table_size > 4096)
        throw py::value_error("table_size must be in [8, 4096], got " + std::to_string(table_size));
    settings.table_nu = settings.table_nT = table_size;
    if (table_interpolation == "bilinear") settings.table_interp = Interp::Bilinear;
    else if (table_interpolation == "nearest") settings.table_interp = Interp::Nearest;
    else throw py::value_error("table_interpolation must be \"bilinear\" or \"nearest\", got \"" +
                               table_interpolation + "\"");
    if (gaussian_resolution == "full") settings.gaussian_resolution = 1;
    else if (gaussian_resolution == "half") settings.gaussian_resolution = 2;
    else if (gaussian_resolution == "quarter") settings.gaussian_resolution = 4;
    else throw py::value_error("gaussian_resolution must be \"full\", \"half\" or \"quarter\", got \"" +
                               gaussian_resolution + "\"");
    if (homogeneous_resolution == "full") settings.homogeneous_resolution = 1;
    else if (homogeneous_resolution == "half") settings.homogeneous_resolution = 2;
    else if (homogeneous_resolution == "quarter") settings.homogeneous_resolution = 4;
    else throw py::value_error("homogeneous_resolution must be \"full\", \"half\" or \"quarter\", got \"" +
                               homogeneous_resolution + "\"");

    // The callback runs on this (the calling) thread between bands: take the GIL for it.
    ProgressFn progress_fn;
    if (!progress.is_none()) {
        if (!PyCallable_Check(progress.ptr())) throw py::value_error("progress must be callable or None");
        progress_fn = [&progress](double fraction) {
            py::gil_scoped_acquire acquire;
            py::object r = progress(fraction);
            return r.is_none() || r.cast<bool>();
        };
    }

    BakeResult result;
    {
        py::gil_scoped_release release;
        result = bake(scene, settings, progress_fn);
    }

    const py::ssize_t H = height, W = width;
    py::dict stats("seconds_raycast"_a = result.stats.seconds_raycast,
                   "seconds_airlight"_a = result.stats.seconds_airlight,
                   "supersampled_pixels"_a = result.stats.supersampled_pixels,
                   "samples"_a = result.stats.samples, "seconds_surface"_a = result.stats.seconds_surface,
                   "seconds_edges"_a = result.stats.seconds_edges, "seconds_bin"_a = result.stats.seconds_bin,
                   "seconds_fog_setup"_a = result.stats.seconds_fog_setup,
                   "seconds_geometry"_a = result.stats.seconds_geometry,
                   "seconds_shadow_volumes"_a = result.stats.seconds_shadow_volumes,
                   "gaussian_pairs"_a = result.stats.gaussian_pairs,
                   "gaussian_kept_bound"_a = result.stats.gaussian_kept_bound,
                   "seconds_refine"_a = result.stats.seconds_refine,
                   "gaussian_background_rays"_a = result.stats.gaussian_background_rays,
                   "gaussian_marched_lights"_a = result.stats.gaussian_marched_lights,
                   "gaussian_marched_rays"_a = result.stats.gaussian_marched_rays,
                   "gaussian_quadratic_pixels"_a = result.stats.gaussian_quadratic_pixels,
                   "gaussian_refine_abandoned"_a = result.stats.gaussian_refine_abandoned,
                   "gaussian_refine_work"_a = result.stats.gaussian_refine_work,
                   "gaussian_error_bound"_a = result.stats.gaussian_error_bound);
    // Surface shading: (L, H, W, 3) attenuation per light and (H, W, 3) glow, when asked for.
    py::dict extra;
    // The surface arrays exist only where the bake ran its surface pass (bake() refuses
    // surface=True where it would not); never wrap an array of the wrong size.
    const size_t n_px3 = size_t(3) * size_t(H) * size_t(W);
    if (surface && result.surface_glow.size() != n_px3)
        throw std::logic_error("bake: surface pass missing from the result");
    if (surface) {
        const py::ssize_t L = result.surface_lights;
        extra["surface_attenuation"] = image_to_numpy(std::move(result.surface_attenuation), {L, H, W, 3});
        extra["surface_glow"] = image_to_numpy(std::move(result.surface_glow), {H, W, 3});
        extra["surface_normals"] = image_to_numpy(std::move(result.surface_normals), {H, W, 3});
        if (surface_phong_exponent > 0.0)
            extra["surface_gloss_glow"] = image_to_numpy(std::move(result.surface_gloss_glow), {H, W, 3});
    }
    py::dict out("airlight"_a = image_to_numpy(std::move(result.airlight), {H, W, 3}),
                    "transmittance"_a = image_to_numpy(std::move(result.transmittance), {H, W, 3}),
                    "depth"_a = image_to_numpy(std::move(result.depth), {H, W}), "stats"_a = stats);
    for (const auto& item : extra) out[item.first] = item.second;
    if (scene.light_passes > 0)
        out["light_airlight"] = image_to_numpy(std::move(result.light_airlight), {scene.light_passes, H, W, 3});
    return out;
}

void write_exr_py(const std::string& path, const py::dict& passes, const std::string& layer_prefix, bool half,
                  const std::string& compression) {
    // Convert every pass to contiguous float32 (H, W, 3), all of one size.
    require_no_nul(path, "write_exr: path");
    require_no_nul(layer_prefix, "write_exr: layer_prefix");
    if (passes.size() == 0) throw py::value_error("write_exr: passes is empty");
    std::vector<std::string> names;
    std::vector<CArray<float>> arrays;
    py::ssize_t H = -1, W = -1;
    for (const auto& item : passes) {
        std::string name = py::str(item.first);
        require_no_nul(name, "write_exr: pass name");
        auto a = as_array<float>(item.second, ("pass '" + name + "'").c_str());
        if (a.ndim() != 3 || a.shape(2) != 3)
            throw py::value_error("write_exr: pass '" + name + "' must have shape (H, W, 3), got " + shape_str(a));
        if (H < 0) {
            H = a.shape(0);
            W = a.shape(1);
        } else if (a.shape(0) != H || a.shape(1) != W) {
            throw py::value_error("write_exr: pass '" + name + "' has shape " + shape_str(a) +
                                  ", other passes are (" + std::to_string(H) + ", " + std::to_string(W) + ", 3)");
        }
        names.push_back(name);
        arrays.push_back(a);
    }
    if (H == 0 || W == 0) throw py::value_error("write_exr: image size must be positive");
    std::vector<ExrPass> exr_passes;
    for (size_t i = 0; i < names.size(); ++i) exr_passes.push_back({names[i], arrays[i].data()});
    py::gil_scoped_release release;
    write_multilayer_exr(path, int(W), int(H), exr_passes, layer_prefix, half, compression);
}

}  // namespace

void bind_bake(py::module_& m) {
    m.def("bake", &bake_py, py::kw_only(), "width"_a, "height"_a, "cam_to_world"_a, "projection"_a,
          "vertices"_a, "triangles"_a, "light_positions"_a, "light_intensities"_a, "sigma_t"_a,
          "albedo"_a = py::make_tuple(1.0, 1.0, 1.0), "phase"_a = "isotropic", "g"_a = 0.0, "model"_a = "sun05", "threads"_a = 0,
          "aa_samples"_a = 4, "filter_width"_a = 1.5, "clip_start"_a = 0.0,
          "clip_end"_a = std::numeric_limits<double>::infinity(), "progress"_a = py::none(),
          "rbf_centres"_a = py::none(), "rbf_scales"_a = py::none(), "rbf_amplitudes"_a = py::none(),
          "spot_positions"_a = py::none(), "spot_axes"_a = py::none(), "spot_intensities"_a = py::none(),
          "spot_size"_a = py::none(), "spot_blend"_a = py::none(), "spot_spread"_a = py::none(),
          "sun_directions"_a = py::none(),
          "sun_irradiances"_a = py::none(), "fog_top"_a = std::numeric_limits<double>::infinity(),
          "table_size"_a = 256, "table_interpolation"_a = "bilinear", "rbf_albedo"_a = py::none(),
          "noise_amplitude"_a = 0.0, "noise_scale"_a = 1.0, "noise_offset"_a = py::make_tuple(0.0, 0.0, 0.0),
          "surface"_a = false, "surface_phong_exponent"_a = 0.0, "rayleigh_density"_a = 0.0,
          "gaussian_resolution"_a = "full", "surface_glow_model"_a = "exact", "homogeneous_resolution"_a = "full",
          "edge_cluster_tol"_a = BakeSettings().edge_cluster_tol, "shadows"_a = false,
          "light_shadows"_a = py::none(), "spot_shadows"_a = py::none(), "sun_shadows"_a = py::none(),
          "occluder_vertices"_a = py::none(), "occluder_triangles"_a = py::none(),
          "gaussian_accuracy"_a = 0.0, "gaussian_refine_budget"_a = BakeSettings().gaussian_refine_budget,
          "shadow_crossings"_a = "film", "light_radii"_a = py::none(), "spot_radii"_a = py::none(),
          "spot_profiles"_a = py::none(), "spot_profile_in_cone"_a = py::none(),
          "spot_profile_extent"_a = py::none(), "light_size_tolerance"_a = BakeSettings().light_size_tolerance,
          "light_pass_index"_a = py::none(), "shadow_samples"_a = BakeSettings().shadow_samples,
          "sun_angles"_a = py::none(), "occluder_seen_triangles"_a = 0,
          R"doc(Bake fog passes for one camera view (all arguments keyword-only).

width, height: render resolution in pixels.
cam_to_world: (4, 4) camera matrix_world; projection: (4, 4)
  camera.calc_matrix_camera(depsgraph, x=width, y=height, scale_x, scale_y).
vertices: (N, 3) float32 world-space positions; triangles: (M, 3) integer indices.
light_positions: (L, 3); light_intensities: (L, 3) radiant intensity in W/sr
  (= colour * power / (4 pi) for a Blender point light).
sigma_t: extinction 1/m (>= 0); albedo: 3 floats (scattering = albedo * sigma_t).
phase: the medium's phase function, "isotropic" (default), "hg" (Henyey-Greenstein with
  anisotropy g, Cycles' sign: g > 0 forward), "rayleigh", "mie_hazy", "mie_murky" (Nishita).
  g: HG asymmetry in (-1, 1); must be 0 for the other phases.
model: "sun05", "sun05_exact", "quadrature", "biri06" or "baseline" (see models()). The Sun 2005
  models are isotropic only: with an anisotropic phase (anything but "isotropic" or "hg"
  with g = 0) they raise ValueError; "biri06" (Gamma table of the phase) and
  "quadrature" (phase-aware reference) take any phase (biri06: HG g >= -0.99, a sharper
  backward lobe is refused; forward lobes up to g < 1). "baseline": constant-colour fog
  C (1 - transmittance), C per channel least-squares fitted to the sun05 (biri06 for an
  anisotropic phase) airlight of the same view: the bar every model must beat.
threads: worker threads in [0, 1024] (0: all hardware threads; ValueError outside).
aa_samples: per-axis samples on edge pixels;
filter_width: Blackman-Harris film filter width in pixels (Cycles' default 1.5).
clip_start, clip_end: the camera's clip range (view-axis depths, camera.data.clip_start
  / clip_end) as Cycles applies it: fog from the near plane on, surfaces beyond
  clip_end not seen (rays that miss get fog out to infinity). Default: from the eye,
  no far clip.
progress: optional callable(fraction) -> bool|None, called from this thread
  between row bands; returning False cancels and raises BakeCancelled.
rbf_centres (n, 3), rbf_scales (n,) > 0, rbf_amplitudes (n,) >= 0: optional Gaussian
  fog (Fogshop): density sigma_t + sum_i c_i exp(-a_i^2 |x - b_i|^2) in 1/m (sigma_t is
  the background). Isotropic phase only; models "sun05" / "sun05_exact" use the Fogshop
  approximation (Zhou et al. 2007), "quadrature" its exact reference. Transmittance is
  exact (culled to 1e-7 per Gaussian). Give all three or none; n = 0 is homogeneous fog.
  Perspective cameras evaluate it by tiled screen-space splatting in float (gaussian/splat.h).
rbf_albedo (n, 3) >= 0: optional per-Gaussian colour (scattering albedo) used instead of
  `albedo` for that Gaussian's airlight (not with model "quadrature").
gaussian_resolution: "full" (default), "half" or "quarter": perspective cameras evaluate the
  Gaussians that lie wholly in front of a 16x16 tile's surfaces on a ray lattice every 2 / 4
  pixels and interpolate them bilinearly (they do not depend on the depth there); the
  Gaussians a surface cuts stay exact per pixel (per sub-sample on supersampled depth-edge
  pixels; gaussian/splat.h). "full" is the plain per-pixel splat.
homogeneous_resolution: "full" (default: every pixel exact), "half" or "quarter": model "sun05"
  with a perspective camera and no spots or Gaussians evaluates the homogeneous airlight on a
  lattice every 2 / 4 pixels and interpolates it bilinearly where it is smooth; depth-edge
  cells, cells near a point light's image and cells whose centre pixel disagrees with the
  interpolation by more than 5e-4 of its value are exact per pixel (bake.cpp). The
  transmittance is always exact. Other cases ignore it (exact).
shadows (default False): volumetric shadows and light shafts: each light's in-scattering counts
  only where the light is not blocked by the shadow casters (shadow/shadow_volumes.h: exact to
  the triangles); light_shadows, spot_shadows, sun_shadows: one flag per light of each kind (its
  Cast Shadow; None: all cast); occluder_vertices (N, 3) float32, occluder_triangles (M, 3): the
  casters when they are not the camera's geometry (Blender's Ray Visibility > Shadow);
  occluder_seen_triangles (default 0): how many of the first occluder triangles are the camera's
  geometry too (the camera's rays end on them, so their own triangles cut no ray but within the
  near clip or past the far clip).
  Gaussian fog (fog objects): 'quadrature' shadows every light (visibility in its integrand);
  the Fogshop models restrict each point, spot and sun light's terms to its lit spans.
shadow_crossings (default 'film'): how the camera's rays find where they cross the shadow
  volumes: 'film' rasterizes the volumes' faces on the film (perspective cameras; exact to the
  faces, watertight: shadow/screen_crossings.h) where the faces are few enough for the film's
  pixels to pay for it, else traces them; 'traced' traces every ray through Embree (the same lit
  intervals but where Embree's float traversal loses a crossing; for checks).
gaussian_accuracy in [0, 1) (default 0): fog objects with the Fogshop models (perspective, no
  noise) to this relative accuracy: a point, spot or sun light with a (light, Gaussian) pair whose
  bound on Fogshop's error exceeds a quarter of it is marched whole on the refined rays
  (gaussian/march.h, its light depths from a light-space depth map whose measured error fits),
  and the uniform fog's term of the other lights takes the Gaussians' exact attenuation on every
  ray where its bound exceeds half of it (gaussian/refine.h); 0: Fogshop's approximation alone.
  stats gaussian_pairs, gaussian_kept_bound (the largest bound the plan leaves to Fogshop),
  gaussian_marched_lights and gaussian_marched_rays (the marched lights, ray x light marches),
  gaussian_quadratic_pixels (pixels between refined rays whose refined / Fogshop ratio came
  from a cell's biquadratic, not its corners' bilinear one),
  gaussian_background_rays (ray x light uniform-fog terms corrected), gaussian_error_bound (the
  relative error bound of the mix), seconds_refine, gaussian_refine_work (nominal CPU seconds).
gaussian_refine_budget >= 0 (default 60): the refinement's budget in nominal CPU seconds (work
  counted per Gaussian term of its integrands, 5.5e-8 s each): a frame whose centre samples
  need more (foreseen from every 4th pixel's, or counted) keeps Fogshop's approximation alone
  (stats gaussian_refine_abandoned True, gaussian_error_bound inf); the outcome depends on the
  frame's work, not on the machine's speed.
edge_cluster_tol >= 0 (default 0.1): edge pixels (aa_samples > 1) evaluate the fog once per
  cluster of their sub-samples (all misses; hits within a depth ratio of 1 + edge_cluster_tol),
  at the cluster's mean ray and depth, and per sample where a cluster's error estimate exceeds
  5e-4 of its airlight; 0 (and scenes with spot lights) evaluates every sub-sample (the
  reference). stats samples counts the fog evaluations.
noise_amplitude >= 0 (0: off), noise_scale > 0 (m), noise_offset (3,): Fogshop section 5.5
  noise: each Gaussian's optical depth along a view ray is taken along the ray direction
  perturbed by world-space gradient noise (cell size noise_scale, lookup point / scale +
  offset; animate the offset or amplitude). Perspective cameras and the Fogshop models only.
spot_positions (S, 3), spot_axes (S, 3) (spot direction, the lamp's -Z; normalised here),
  spot_intensities (S, 3) W/sr (= colour * power / (4 pi), as a point light), spot_size (S,)
  full cone angle in rad (0, pi], spot_blend (S,) in [0, 1]: optional Blender spot lights with
  Cycles' profile I0 cos(theta) smoothstep(...), evaluated by adaptive quadrature for every
  model (phase-aware; homogeneous fog only: ValueError with rbf_*). Give all five or none.
  spot_spread (S,) (optional, rad, [1 deg, pi], default pi): an area light's sample (spot_size
  pi, blend 0) with Cycles' Spread, profile sin(h - theta) / (sin h - h cos h), h = spread / 2.
light_radii (L,), spot_radii (S,) (optional, m, >= 0; default 0): each point and spot light's
  Radius (shadow_soft_size): Cycles' disk of that radius facing each point, which flattens the
  in-scattering within ~the radius of the light (homogeneous/sphere_light.h; within 1e-3 of
  the point's beyond 27 radii). Homogeneous fog; fog objects take their lights as points.
light_size_tolerance (default 1e-3, (0, 5e-3]): the Radius is taken on the rays where it
  changes that light's airlight by more than this relative amount (within sqrt(0.75 / tol)
  radii of the light in clear fog) and skipped beyond; the add-on's Automatic passes a quarter
  of its accuracy target.
shadow_samples (default 1, [1, 64]): with shadows, a point or spot light with a Radius casts
  them from this many points of its sphere, which give the fog the penumbrae of Cycles' sphere
  light (sphere_light_shadow_samples: their projection covers the disk facing any point
  uniformly); each is a shadow volume of its own (the shadows' cost times about this). 1: from
  the centre (hard shadows); a sun with an Angle from this many directions over its disk.
  Homogeneous fog.
sun_angles (U,) (optional, radians, [0, pi]; default 0): each sun's angular diameter (Blender's
  Angle), whose disk softens its shadows (shadow_samples); its airlight takes the centre.
light_pass_index (optional; one integer per light, the point lights, then the spots, then the
  suns): the per-light airlight pass each light adds to (-1: none); adds light_airlight=(G, H,
  W, 3) float32, G = the largest index + 1, each pass its lights' airlight from the same
  evaluation as the total (they sum to airlight but for float rounding). Homogeneous fog,
  models that evaluate per ray, homogeneous_resolution "full" (ValueError otherwise).
spot_profiles (S, K + 1) (optional): per spot a light distribution over the whole sphere
  instead of its cone (a point light's IES profile, fitted): I(c) = I0 sum_k row[k] c^k, c the
  cosine between spot_axes and the direction light -> point, clamped at 0 (the closed form of
  pegoraro10 integrates the polynomial itself); such a spot needs spot_size pi, spot_blend 0
  and no spread. An all-zero row keeps the spot's cone. Homogeneous fog only.
spot_profile_in_cone (S,) (optional, with spot_profiles; default False): per spot whether its
  profile multiplies the spot's own cone (a spot light's IES Texture, as Cycles multiplies it
  into the spot's emission: I0 cos(theta) smoothstep(...) max(0, I(c)) inside the cone) instead
  of replacing it (a point light's). The degree is at most 16; no Spread.
spot_profile_extent (S,) (optional, with spot_profiles; rad, (0, pi], default pi): per spot
  whose profile replaces its cone, the polar angle from spot_axes beyond which it is dark (an
  IES file's last lit angle): I0 max(0, I(c)) for c > cos(extent), 0 beyond; pi: the whole
  sphere. Rows in a cone take pi.
sun_directions (U, 3) (direction of propagation, the lamp's -Z; normalised here),
  sun_irradiances (U, 3) W/m^2 (= colour * strength, Cycles): optional sun lamps, closed
  form for every model ("quadrature": its quadrature), any phase (homogeneous/sunlight_layer.h).
  fog_top: world Z of the fog layer's top for the suns' light: the sun reaches a point at
  height z through (fog_top - z) / cos of fog; +inf (default): Hoffman & Preetham's
  unattenuated sun. Point/spot lights and the transmittance ignore fog_top.
  Homogeneous fog only (ValueError with rbf_*).
table_size: samples per axis of the model's 2D table (sun05's F table, biri06's Gamma
  table), in [8, 4096], default 256. table_interpolation: "bilinear" (default) or "nearest"
  lookup of sun05's F table (nearest: one load per lookup, ~20x the error; special_f.cpp
  lists both measured errors per size).
surface: also bake surface shading through the fog (Sun 2005 eq. 13-19, bake/surface_pass.h):
  adds surface_attenuation=(L, H, W, 3) float32, e^{-T(light, first hit)} per light (the
  point lights, then the spot lights, in argument order; 1 where no hit), and
  surface_glow=(H, W, 3) float32, the point and spot lights' scattered light on a Lambert
  surface per unit diffuse colour (multiply by Cycles' DiffCol pass; G by phase and model as
  bake/surface_pass.h: Sun's G0 for the isotropic phase, the phase-aware G_p otherwise, Biri's
  eq. 10 for model biri06 with an anisotropic phase), surface_normals=(H, W, 3)
  float32, the first hit's geometric normal facing the camera (0 where no hit), and stats
  seconds_surface.
rayleigh_density: Rayleigh scattering coefficient at 550 nm in 1/m for model "hoffman02"
  (Hoffman & Preetham 2002: beta_R ~ 1/lambda^4 per channel, sigma_t is the Mie part with the
  HG g; sun lamps only, per-channel transmittance; models/hoffman02_model.cpp). Ignored by
  other models.
surface_phong_exponent: with surface, n in [1, 10000] also adds surface_gloss_glow=(H, W, 3):
  the point and spot lights' scattered light on a normalised Phong lobe (n + 2)/(2 pi) cos^n about the
  mirrored view direction (Sun 2005 eq. 18, Gn), per unit glossy colour. 0: off.
surface_glow_model: with surface, "exact" (default: Sun 2005's G0 for the isotropic phase, the
  hemisphere-clamped phase-aware G_p of Biri 2006 eq. 8-13 otherwise) or "biri06_eq10" (Biri's
  own Lambert model, Gamma_L(T) cos theta_s clamped at 0: coarse, for comparison).

Returns dict(airlight=(H, W, 3) float32, transmittance=(H, W, 3) float32,
depth=(H, W) float32 (distance from the eye, or from the near plane for
orthographic cameras, to the first hit inside the clip range; inf where none), stats=dict(seconds_raycast,
seconds_airlight, supersampled_pixels, samples, seconds_surface, seconds_edges: the edge
supersampling's time summed over the worker threads, seconds_bin: fog objects' binning into
tiles and far-field grids, seconds_fog_setup: building the fog model between the raycast
and the airlight pass, seconds_geometry: the camera's BVH before the raycast (built for the
objects that changed since the last bake, shared for the others), seconds_shadow_volumes:
the shadow volumes and their casters' BVH inside seconds_fog_setup)); rows top first. Raises
ValueError on invalid input. The GIL is released while baking.)doc");

    m.def(
        "available_memory",
        [] {
            const size_t bytes = available_memory_bytes();
            return bytes == SIZE_MAX ? std::numeric_limits<double>::infinity() : double(bytes);
        },
        R"doc(Bytes of memory this process can still take (MemAvailable, or less where a cgroup
caps it; inf when unknown): what bake() and write_exr() check their images against before
allocating them (ValueError / RuntimeError naming both sizes when they would not fit).)doc");

    m.def("raycaster_builds", &RayCaster::shared_builds,
          "Embree BVHs the bakes of this process built for their geometry: a bake whose vertices "
          "and triangles equal the previous bake's shares its BVH (image/raycast.h, RayCaster::shared).");
    m.def("shadow_volume_builds", &ShadowVolumes::shared_builds,
          "Sets of shadow volumes the bakes of this process built: a bake whose casters, shadowed lights "
          "(or light samples) and camera position equal one of the last two bakes' shares its volumes "
          "(shadow/shadow_volumes.h, ShadowVolumes::shared).");
    m.def("light_depth_map_builds", &map_builds,
          "Light-depth maps of Gaussian fog the bakes of this process built: a bake whose Gaussians, marched light "
          "and map size equal the previous bake's takes that bake's map (bake/map_cache.h).");
    m.def("clear_light_depth_maps", &clear_cached_maps,
          "Drops the light-depth maps kept from the last bake for the next one (their memory is reused).");
    m.def(
        "geometry_blocks_built",
        [] {
            py::dict out;
            out["camera"] = RayCaster::shared_blocks_built();
            out["casters"] = ShadowVolumes::caster_blocks_built();
            out["volume_faces"] = ShadowVolumes::block_faces_built();
            return out;
        },
        "The Embree BVHs of single objects that the bakes of this process built, for the camera's rays and for "
        "the shadow casters' counts, and the shadow volumes' faces of single objects for single lights "
        "({'camera': n, 'casters': n, 'volume_faces': n}): a bake shares the BVH of every object (a run of the "
        "soup that indexes only its own vertices) equal to one of the previous bake's (image/embree_blocks.h), "
        "and the faces of every object and light equal to one of the recent bakes' (shadow/block_faces.h).");
    m.def(
        "clear_geometry_cache",
        [] {
            RayCaster::clear_shared();
            ShadowVolumes::clear_shared();
        },
        "Drops the geometry (and its Embree BVH) and the shadow volumes kept from the last bakes for the next ones.");
    m.def("write_exr", &write_exr_py, "path"_a, "passes"_a, "layer_prefix"_a = "", "half"_a = false,
          "compression"_a = "auto",
          R"doc(Write one multilayer EXR (32-bit float; half=True: 16-bit half floats, rounded
to nearest, relative error <= 2^-11 from 6.1e-5 up, a quarter to a third of the file).
compression: "auto" (PIZ for floats, ZIP for halves: benchmarks/bench_exr.py), or one of
"none", "rle", "zips", "zip", "piz", "pxr24", "b44", "b44a", "dwaa", "dwab" (the last five
lossy for floats); OpenEXR compresses on every hardware thread.

passes: dict name -> (H, W, 3) float32 array (top row first); channels are named
"<layer_prefix><name>.R/G/B" in dict order. Raises RuntimeError on I/O failure, ValueError
on a path, prefix or pass name with a NUL byte in it (it would be cut there).)doc");
}

}  // namespace airlight::bindings
