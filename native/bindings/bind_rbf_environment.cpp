// bind_rbf_environment.cpp: environment lighting in Gaussian fog (gaussian/environment.h):
// Fogshop's average optical depth and the per-pixel environment irradiance.
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

#include "image/camera.h"
#include "gaussian/environment.h"
#include "bindings/numpy_util.h"

namespace airlight::bindings {

using namespace pybind11::literals;

namespace {

std::vector<double> column(const py::object& obj, const char* name, py::ssize_t n) {
    auto a = as_array<double>(obj, name);
    if (a.ndim() != 1 || a.shape(0) != n)
        throw py::value_error(std::string(name) + ": expected shape (" + std::to_string(n) + ",), got " + shape_str(a));
    return std::vector<double>(a.data(), a.data() + n);
}

GaussianMedium medium_of(const py::object& centres, const py::object& scales, const py::object& amplitudes, double beta0) {
    auto b = as_array<double>(centres, "centres");
    const py::ssize_t n = require_rows_of(b, 3, "centres");
    std::vector<double> bv(b.data(), b.data() + 3 * n);
    try {
        return GaussianMedium(std::move(bv), column(scales, "scales", n), column(amplitudes, "amplitudes", n), beta0);
    } catch (const std::invalid_argument& e) {
        throw py::value_error(e.what());
    }
}

RGB albedo_of(const py::object& obj) {
    auto alb = as_array<double>(obj, "albedo");
    if (alb.size() != 3) throw py::value_error("albedo: expected 3 values");
    const RGB a(alb.data()[0], alb.data()[1], alb.data()[2]);
    if (!(a.x >= 0 && a.y >= 0 && a.z >= 0 && std::isfinite(a.x + a.y + a.z)))
        throw py::value_error("albedo: must be finite and >= 0");
    return a;
}

py::dict stats_dict(const AverageDepthStats& s) {
    return py::dict("points"_a = s.points, "near_terms"_a = s.near_terms, "far_terms"_a = s.far_terms,
                    "linear_terms"_a = s.linear_terms, "far_linear_terms"_a = s.far_linear_terms);
}

}  // namespace

void bind_rbf_environment(py::module_& m) {
    m.def(
        "average_depth_unit",
        [](const py::object& u, bool exact) {
            auto a = as_array<double>(u, "u");
            std::vector<double> out(size_t(a.size()));
            const double* p = a.data();
            for (size_t i = 0; i < out.size(); ++i)
                if (!(p[i] >= 0.0)) throw py::value_error("u: must be >= 0 (not NaN)");
            {
                py::gil_scoped_release release;
                for (size_t i = 0; i < out.size(); ++i)
                    out[i] = exact ? average_depth_unit(p[i]) : average_depth_unit_fast(p[i]);
            }
            std::vector<py::ssize_t> shape(a.shape(), a.shape() + a.ndim());
            return to_numpy(std::move(out), shape);
        },
        "u"_a, "exact"_a = false,
        "Fogshop's T(u) = (1/4pi) int_S int_0^inf exp(-|u + t w|^2) dt dw = (sqrt(pi)/2) F(u)/u (F: Dawson's "
        "integral), the average optical depth around a point at distance u from a unit Gaussian (a = c = 1). "
        "exact=False: the kernel's table (< 1e-9 relative); exact=True: through Dawson's function.");
    m.def(
        "rbf_average_depth",
        [](const py::object& centres, const py::object& scales, const py::object& amplitudes,
           const py::object& points, double beta0, double distance, double tolerance, bool exact, int threads) {
            GaussianMedium medium = medium_of(centres, scales, amplitudes, beta0);
            auto pts = as_array<double>(points, "points");
            const size_t n = size_t(require_rows_of(pts, 3, "points"));
            static_assert(sizeof(Vec3) == 3 * sizeof(double), "Vec3 must be 3 packed doubles");
            const Vec3* p = reinterpret_cast<const Vec3*>(pts.data());  // numpy memory, no copy
            py::array_t<double> out(std::vector<py::ssize_t>{py::ssize_t(n)});
            double* o = out.mutable_data();
            AverageDepthStats stats;
            try {
                py::gil_scoped_release release;
                const GaussianAverageDepth avg(medium, distance);
                if (exact) {
                    avg.evaluate_brute(p, n, o, threads);
                    stats.points = n;
                    stats.near_terms = n * avg.size();
                } else {
                    stats = avg.evaluate(p, n, o, tolerance, threads);
                }
            } catch (const std::invalid_argument& e) {
                throw py::value_error(e.what());
            }
            return py::dict("average_depth"_a = out, "stats"_a = stats_dict(stats));
        },
        py::kw_only(), "centres"_a, "scales"_a, "amplitudes"_a, "points"_a, "beta0"_a = 0.0, "distance"_a = 0.0,
        "tolerance"_a = 1e-3, "exact"_a = false, "threads"_a = 0,
        "Fogshop eq. 26: the average optical depth Tbar(p) = beta0 distance + sum_i c_i T(a_i |p - b_i|) / a_i "
        "at points (N, 3). The far field uses a Barnes-Hut expansion whose error is at most tolerance x Tbar(p) "
        "(gaussian/environment.h); exact=True sums every Gaussian through Dawson's function. Returns dict("
        "average_depth=(N,), stats=dict(points, near_terms, far_terms, linear_terms, far_linear_terms)).");
    m.def(
        "psf_band_eigenvalues",
        [](const py::object& T) {
            auto a = as_array<double>(T, "T");
            const size_t n = size_t(a.size());
            std::vector<double> out(3 * n);
            const double* p = a.data();
            try {
                py::gil_scoped_release release;
                for (size_t i = 0; i < n; ++i) {
                    const std::array<double, 3> l = psf_band_eigenvalues(p[i]);
                    for (int k = 0; k < 3; ++k) out[3 * i + size_t(k)] = l[size_t(k)];
                }
            } catch (const std::invalid_argument& e) {
                throw py::value_error(e.what());
            }
            return to_numpy(std::move(out), {py::ssize_t(n), 3});
        },
        "T"_a,
        "The exact PSF's eigenvalues lambda_0..2 (as psf_eigenvalues(T, 2, 'exact')) from the kernel's table "
        "over T, for an array of optical depths T >= 0: shape (N, 3).");
    m.def(
        "environment_irradiance_varying",
        [](const py::object& sh_world, const py::object& albedo, const py::object& normals,
           const py::object& optical_depth, int threads) {
            auto sh = as_array<double>(sh_world, "sh_world");
            if (sh.size() != 27) throw py::value_error("sh_world: expected shape (9, 3)");
            ShCoefficients world;
            world.L = 2;
            world.c.resize(9);
            for (size_t i = 0; i < 9; ++i) world.c[i] = RGB(sh.data()[3 * i], sh.data()[3 * i + 1], sh.data()[3 * i + 2]);
            const RGB a = albedo_of(albedo);
            // Straight from and into numpy memory (an (N, 3) float64 C array is N glm::dvec3):
            // at 1080p the copies' page faults cost more than the arithmetic.
            static_assert(sizeof(Vec3) == 3 * sizeof(double), "Vec3 must be 3 packed doubles");
            auto n = as_array<double>(normals, "normals");
            const py::ssize_t rows = require_rows_of(n, 3, "normals");
            auto T = as_array<double>(optical_depth, "optical_depth");
            if (T.ndim() != 1 || T.shape(0) != rows)
                throw py::value_error("optical_depth: expected shape (" + std::to_string(rows) + ",), got " + shape_str(T));
            py::array_t<double> Ew({rows, py::ssize_t(3)}), Ef({rows, py::ssize_t(3)});
            const Vec3* np_ = reinterpret_cast<const Vec3*>(n.data());
            const double* Tp = T.data();
            RGB* ew = reinterpret_cast<RGB*>(Ew.mutable_data());
            RGB* ef = reinterpret_cast<RGB*>(Ef.mutable_data());
            try {
                py::gil_scoped_release release;
                environment_irradiance_varying(world, a, np_, Tp, size_t(rows), ew, ef, threads);
            } catch (const std::invalid_argument& e) {
                throw py::value_error(e.what());
            }
            return py::make_tuple(Ew, Ef);
        },
        "sh_world"_a, "albedo"_a, "normals"_a, "optical_depth"_a, "threads"_a = 0,
        "environment_irradiance() with one optical depth per surface (Fogshop eq. 27 with Tbar(p)): (E_world, "
        "E_fogged) of shape (N, 3) for normals (N, 3) and optical_depth (N,), the PSF's eigenvalues for each "
        "from the kernel's table.");
    m.def(
        "environment_rbf_view",
        [](const py::object& cam_to_world, const py::object& projection, int width, int height, double clip_start,
           double clip_end, const py::object& depth, const py::object& centres, const py::object& scales,
           const py::object& amplitudes, double beta0, double distance, double tolerance, bool average,
           int threads) {
            if (width <= 0 || height <= 0) throw py::value_error("width and height must be > 0");
            Camera cam;
            cam.cam_to_world = to_mat4(cam_to_world, "cam_to_world");
            cam.projection = to_mat4(projection, "projection");
            cam.width = width;
            cam.height = height;
            cam.clip_start = clip_start;
            cam.clip_end = clip_end;
            auto dep = as_array<float>(depth, "depth");
            if (dep.ndim() != 2 || dep.shape(0) != height || dep.shape(1) != width)
                throw py::value_error("depth: expected shape (height, width), got " + shape_str(dep));
            // The Gaussians alone for the rays' optical depth; beta0 enters Tbar only.
            const GaussianMedium gaussians = medium_of(centres, scales, amplitudes, 0.0);
            const GaussianMedium with_beta0 = medium_of(centres, scales, amplitudes, beta0);
            const size_t n = size_t(width) * size_t(height);
            std::vector<double> world_depth(n, 0.0), avg_depth(n, beta0 * distance);
            const float* dp = dep.data();
            AverageDepthStats stats;
            try {
                py::gil_scoped_release release;
                CameraRays rays(cam);
                std::vector<Vec3> miss_o, miss_d, hit_p;
                std::vector<size_t> miss_px, hit_px;
                size_t misses = 0;
                for (size_t px = 0; px < n; ++px) misses += std::isinf(dp[px]) ? 1 : 0;
                miss_o.reserve(misses);
                miss_d.reserve(misses);
                miss_px.reserve(misses);
                if (average) {
                    hit_p.reserve(n - misses);
                    hit_px.reserve(n - misses);
                }
                for (int j = 0; j < height; ++j)
                    for (int i = 0; i < width; ++i) {
                        const size_t px = size_t(j) * width + i;
                        const Ray ray = rays(i + 0.5, j + 0.5);
                        if (std::isinf(dp[px])) {
                            double t_near, t_far;
                            rays.clip_range(ray, t_near, t_far);
                            miss_o.push_back(ray.o + t_near * ray.d);
                            miss_d.push_back(ray.d);
                            miss_px.push_back(px);
                        } else if (average && std::isfinite(dp[px])) {
                            hit_p.push_back(ray.o + double(dp[px]) * ray.d);
                            hit_px.push_back(px);
                        }
                    }
                // The Gaussians' optical depth from the near plane to infinity where the ray misses.
                std::vector<double> tmax(miss_o.size(), std::numeric_limits<double>::infinity()), T(miss_o.size());
                gaussians.optical_depth_ray_batch(miss_o.data(), miss_d.data(), tmax.data(), miss_o.size(), T.data(),
                                                  true, threads);
                for (size_t k = 0; k < miss_px.size(); ++k) world_depth[miss_px[k]] = T[k];
                if (average) {
                    const GaussianAverageDepth avg(with_beta0, distance);
                    std::vector<double> Tbar(hit_p.size());
                    stats = avg.evaluate(hit_p.data(), hit_p.size(), Tbar.data(), tolerance, threads);
                    for (size_t k = 0; k < hit_px.size(); ++k) avg_depth[hit_px[k]] = Tbar[k];
                }
            } catch (const std::invalid_argument& e) {
                throw py::value_error(e.what());
            }
            return py::dict("world_optical_depth"_a = to_numpy(std::move(world_depth), {height, width}),
                            "average_depth"_a = to_numpy(std::move(avg_depth), {height, width}),
                            "stats"_a = stats_dict(stats));
        },
        py::kw_only(), "cam_to_world"_a, "projection"_a, "width"_a, "height"_a, "clip_start"_a = 0.0,
        "clip_end"_a = std::numeric_limits<double>::infinity(), "depth"_a, "centres"_a, "scales"_a, "amplitudes"_a,
        "beta0"_a, "distance"_a, "tolerance"_a = 1e-3, "average"_a = true, "threads"_a = 0,
        "The World and Gaussian fog per pixel of the bake's camera, from its depth pass (H, W) (distance along "
        "the pixel-centre ray, inf where it misses): world_optical_depth (H, W) = the Gaussians' optical depth "
        "from the near plane to infinity where the ray misses (0 elsewhere), and with average=True "
        "average_depth (H, W) = Fogshop's Tbar(p) = beta0 distance + sum_i Tbar_i(p) at the first hit (beta0 "
        "distance where none), to relative tolerance; stats = the terms evaluated.");
}

}  // namespace airlight::bindings
