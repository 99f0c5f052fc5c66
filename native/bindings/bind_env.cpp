// bind_env.cpp: Sun 2005's point-spread function and the World seen through fog (sun05_psf.h).
#include <cmath>
#include <string>

#include "image/camera.h"
#include "homogeneous/sun05_psf.h"
#include "bindings/numpy_util.h"

namespace airlight::bindings {

using namespace pybind11::literals;

namespace {

PsfKind psf_kind(const std::string& name) {
    if (name == "factorised") return PsfKind::Factorised;
    if (name == "exact") return PsfKind::Exact;
    throw py::value_error("kind: expected 'factorised' or 'exact', got '" + name + "'");
}

// (H, W, 3) array -> EnvironmentMap (row 0 = top).
EnvironmentMap to_map(const py::object& obj, const char* name) {
    auto a = as_array<float>(obj, name);
    if (a.ndim() != 3 || a.shape(2) != 3)
        throw py::value_error(std::string(name) + ": expected shape (height, width, 3), got " + shape_str(a));
    EnvironmentMap map;
    map.height = int(a.shape(0));
    map.width = int(a.shape(1));
    map.rgb.assign(a.data(), a.data() + a.size());
    return map;
}

py::array_t<float> map_to_numpy(EnvironmentMap&& map) {
    const int h = map.height, w = map.width;
    return to_numpy(std::move(map.rgb), {h, w, 3});
}

}  // namespace

void bind_env(py::module_& m) {
    m.def(
        "sun05_psf",
        [](double Tsv, const py::object& cos_gamma) {
            auto c = as_array<double>(cos_gamma, "cos_gamma");
            std::vector<double> out(size_t(c.size()));
            const double* p = c.data();
            {
                py::gil_scoped_release release;
                for (size_t i = 0; i < out.size(); ++i) out[i] = sun05_psf(Tsv, p[i]);
            }
            std::vector<py::ssize_t> shape(c.shape(), c.shape() + c.ndim());
            return to_numpy(std::move(out), shape);
        },
        "Tsv"_a, "cos_gamma"_a,
        "Sun 2005 eq. 20: the airlight PSF for a source at optical distance Tsv (Dvp = inf), per unit "
        "albedo, at the angles with the given cosines (array).");
    m.def(
        "sun05_npsf",
        [](const py::object& cos_gamma) {
            auto c = as_array<double>(cos_gamma, "cos_gamma");
            std::vector<double> out(size_t(c.size()));
            const double* p = c.data();
            {
                py::gil_scoped_release release;
                for (size_t i = 0; i < out.size(); ++i) out[i] = sun05_npsf(p[i]);
            }
            std::vector<py::ssize_t> shape(c.shape(), c.shape() + c.ndim());
            return to_numpy(std::move(out), shape);
        },
        "cos_gamma"_a, "Sun 2005 eq. 21: the normalised PSF (PSF ~ Tsv e^-Tsv NPSF, eq. 22).");
    m.def(
        "psf_eigenvalues",
        [](double Tsv, int L, const std::string& kind) {
            std::vector<double> out;
            const PsfKind k = psf_kind(kind);
            {
                py::gil_scoped_release release;
                out = psf_eigenvalues(Tsv, L, k);
            }
            return to_numpy(std::move(out), {py::ssize_t(L) + 1});
        },
        "Tsv"_a, "L"_a, "kind"_a = "factorised",
        "Funk-Hecke eigenvalues lambda_l = 2 pi int PSF(mu) P_l(mu) dmu, l = 0..L, of the exact PSF "
        "('exact') or of the factorised one ('factorised', eq. 22).");
    m.def(
        "environment_fog",
        [](const py::object& world, double sigma_t, double distance, const py::object& albedo, int sh_order,
           int out_width, int out_height, const std::string& kind, int threads) {
            EnvironmentMap map = to_map(world, "world");
            auto alb = as_array<double>(albedo, "albedo");
            if (alb.size() != 3) throw py::value_error("albedo: expected 3 values");
            const RGB a(alb.data()[0], alb.data()[1], alb.data()[2]);
            if (!(a.x >= 0 && a.y >= 0 && a.z >= 0 && std::isfinite(a.x + a.y + a.z)))
                throw py::value_error("albedo: must be finite and >= 0");
            const PsfKind k = psf_kind(kind);
            EnvironmentFog fog;
            {
                py::gil_scoped_release release;
                fog = environment_fog(map, sigma_t, distance, sh_order, out_width, out_height, k, threads);
                for (size_t i = 0; i < fog.glow.rgb.size(); ++i) fog.glow.rgb[i] *= float(a[int(i % 3)]);
            }
            std::vector<double> sh(size_t(27));
            for (size_t i = 0; i < 9; ++i)
                for (int c = 0; c < 3; ++c) sh[3 * i + c] = fog.sh_world.c[i][c];
            const py::ssize_t nl = py::ssize_t(fog.lambda.size());
            return py::dict("glow"_a = map_to_numpy(std::move(fog.glow)), "transmittance"_a = fog.transmittance,
                            "sh_world"_a = to_numpy(std::move(sh), {9, 3}),
                            "eigenvalues"_a = to_numpy(std::move(fog.lambda), {nl}));
        },
        py::kw_only(), "world"_a, "sigma_t"_a, "distance"_a, "albedo"_a, "sh_order"_a = 16, "out_width"_a = 256,
        "out_height"_a = 128, "kind"_a = "factorised", "threads"_a = 0,
        "The World (equirectangular (H, W, 3) float array, Blender's mapping, row 0 = top) seen through "
        "homogeneous fog (Sun 2005 eq. 25-27): 'glow' = the airlight La(w) (times albedo) as an (out_height, "
        "out_width, 3) map, 'transmittance' = e^(-sigma_t distance) for the World itself, 'sh_world' = its "
        "l <= 2 spherical-harmonic coefficients and 'eigenvalues' = the PSF's lambda_l. sh_order < 0: direct "
        "convolution with the exact PSF (reference, small maps only).");
    m.def(
        "environment_view",
        [](const py::object& cam_to_world, const py::object& projection, int width, int height,
           const py::object& glow) {
            if (width <= 0 || height <= 0) throw py::value_error("width and height must be > 0");
            Camera cam;
            cam.cam_to_world = to_mat4(cam_to_world, "cam_to_world");
            cam.projection = to_mat4(projection, "projection");
            cam.width = width;
            cam.height = height;
            EnvironmentMap map = to_map(glow, "glow");
            std::vector<float> out(size_t(3) * width * height);
            {
                py::gil_scoped_release release;
                CameraRays rays(cam);
                for (int j = 0; j < height; ++j)
                    for (int i = 0; i < width; ++i) {
                        const RGB v = environment_lookup(map, rays(i + 0.5, j + 0.5).d);
                        float* o = &out[3 * (size_t(j) * width + i)];
                        o[0] = float(v.x);
                        o[1] = float(v.y);
                        o[2] = float(v.z);
                    }
            }
            return to_numpy(std::move(out), {height, width, 3});
        },
        py::kw_only(), "cam_to_world"_a, "projection"_a, "width"_a, "height"_a, "glow"_a,
        "Looks up the equirectangular map _glow_ along every pixel-centre camera ray (the bake's rays): "
        "(height, width, 3), row 0 = top.");
    m.def(
        "environment_irradiance",
        [](const py::object& sh_world, const py::object& eigenvalues, double transmittance,
           const py::object& albedo, const py::object& normals) {
            auto sh = as_array<double>(sh_world, "sh_world");
            if (sh.size() != 27) throw py::value_error("sh_world: expected shape (9, 3)");
            auto lam = as_array<double>(eigenvalues, "eigenvalues");
            if (lam.size() < 3) throw py::value_error("eigenvalues: need at least 3");
            auto alb = as_array<double>(albedo, "albedo");
            if (alb.size() != 3) throw py::value_error("albedo: expected 3 values");
            auto n = as_array<double>(normals, "normals");
            const py::ssize_t rows = require_rows_of(n, 3, "normals");
            EnvironmentFog fog;
            fog.transmittance = transmittance;
            fog.sh_world.L = 2;
            fog.sh_world.c.resize(9);
            for (size_t i = 0; i < 9; ++i) fog.sh_world.c[i] = RGB(sh.data()[3 * i], sh.data()[3 * i + 1], sh.data()[3 * i + 2]);
            fog.lambda.assign(lam.data(), lam.data() + 3);
            const RGB a(alb.data()[0], alb.data()[1], alb.data()[2]);
            std::vector<double> Ew(size_t(3 * rows)), Ef(size_t(3 * rows));
            const double* p = n.data();
            {
                py::gil_scoped_release release;
                for (py::ssize_t i = 0; i < rows; ++i) {
                    RGB e0, e1;
                    environment_irradiance(fog, a, Vec3(p[3 * i], p[3 * i + 1], p[3 * i + 2]), e0, e1);
                    for (int c = 0; c < 3; ++c) {
                        Ew[size_t(3 * i + c)] = e0[c];
                        Ef[size_t(3 * i + c)] = e1[c];
                    }
                }
            }
            return py::make_tuple(to_numpy(std::move(Ew), {rows, 3}), to_numpy(std::move(Ef), {rows, 3}));
        },
        "sh_world"_a, "eigenvalues"_a, "transmittance"_a, "albedo"_a, "normals"_a,
        "Irradiance (E_world, E_fogged) of surfaces with the given normals (N, 3) from the World without fog "
        "and through it (eq. 26-27, bands l <= 2), from environment_fog()'s sh_world / eigenvalues / "
        "transmittance.");
}

}  // namespace airlight::bindings
