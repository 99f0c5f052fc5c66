// bind_rbf.cpp: the Gaussian (RBF) medium: store, optical depth, Fogshop airlight.
#include <cmath>
#include <stdexcept>

#include "bake/bake.h"
#include "gaussian/airlight.h"
#include "gaussian/medium.h"
#include "gaussian/splat.h"
#include "bindings/numpy_util.h"

namespace airlight::bindings {

using namespace pybind11::literals;

namespace {

// (n, 3) float64 array -> Vec3 list; _normalise_ rescales each row to unit length.
std::vector<Vec3> to_vec3(const py::handle& obj, const char* name, py::ssize_t rows = -1, bool normalise = false) {
    auto a = as_array<double>(obj, name);
    const py::ssize_t n = require_rows_of(a, 3, name, rows);
    std::vector<Vec3> out(n);
    const double* p = a.data();
    for (py::ssize_t i = 0; i < n; ++i) {
        Vec3 v(p[3 * i], p[3 * i + 1], p[3 * i + 2]);
        if (!std::isfinite(v.x) || !std::isfinite(v.y) || !std::isfinite(v.z))
            throw py::value_error(std::string(name) + ": row " + std::to_string(i) + " is not finite");
        if (normalise) {
            const double len = glm::length(v);
            if (!(len > 0.0)) throw py::value_error(std::string(name) + ": row " + std::to_string(i) + " is zero");
            v /= len;
        }
        out[i] = v;
    }
    return out;
}

Vec3 to_point(const py::handle& obj, const char* name) {
    auto a = as_array<double>(obj, name);
    if (a.size() != 3) throw py::value_error(std::string(name) + ": expected 3 numbers, got shape " + shape_str(a));
    const Vec3 v(a.data()[0], a.data()[1], a.data()[2]);
    if (!std::isfinite(v.x) || !std::isfinite(v.y) || !std::isfinite(v.z))
        throw py::value_error(std::string(name) + ": not finite");
    return v;
}

std::vector<double> to_vector(const py::handle& obj, const char* name, py::ssize_t n) {
    auto a = as_array<double>(obj, name);
    if (a.ndim() != 1 || a.shape(0) != n)
        throw py::value_error(std::string(name) + ": expected shape (" + std::to_string(n) + ",), got " + shape_str(a));
    return std::vector<double>(a.data(), a.data() + n);
}

GaussianMedium make_medium(const py::object& centres, const py::object& scales, const py::object& amplitudes,
                      double beta0, double cull_eps) {
    auto b = as_array<double>(centres, "centres");
    const py::ssize_t n = require_rows_of(b, 3, "centres");
    std::vector<double> bv(b.data(), b.data() + 3 * n);
    try {
        return GaussianMedium(std::move(bv), to_vector(scales, "scales", n), to_vector(amplitudes, "amplitudes", n), beta0,
                         cull_eps);
    } catch (const std::invalid_argument& e) {
        throw py::value_error(e.what());
    }
}

py::array_t<double> optical_depth(const GaussianMedium& m, const py::object& p, const py::object& q, bool culled,
                                  int threads) {
    const std::vector<Vec3> P = to_vec3(p, "p");
    const std::vector<Vec3> Q = to_vec3(q, "q", static_cast<py::ssize_t>(P.size()));
    std::vector<double> out(P.size());
    {
        py::gil_scoped_release release;
        m.optical_depth_batch(P.data(), Q.data(), P.size(), out.data(), culled, threads);
    }
    return to_numpy(std::move(out), {static_cast<py::ssize_t>(P.size())});
}

py::array_t<double> optical_depth_ray(const GaussianMedium& m, const py::object& o, const py::object& d,
                                      const py::object& tmax, bool culled, int threads) {
    const std::vector<Vec3> O = to_vec3(o, "origins");
    const py::ssize_t n = static_cast<py::ssize_t>(O.size());
    const std::vector<Vec3> D = to_vec3(d, "directions", n, true);
    const std::vector<double> T = to_vector(tmax, "tmax", n);
    for (py::ssize_t j = 0; j < n; ++j)
        if (std::isnan(T[j]) || T[j] < 0.0)
            throw py::value_error("tmax: entry " + std::to_string(j) + " must be >= 0 (may be inf)");
    std::vector<double> out(n);
    {
        py::gil_scoped_release release;
        m.optical_depth_ray_batch(O.data(), D.data(), T.data(), O.size(), out.data(), culled, threads);
    }
    return to_numpy(std::move(out), {n});
}

py::array_t<double> airlight(const GaussianMedium& m, const py::object& light_positions, const py::object& origin,
                             const py::object& directions, const py::object& Dvp, const std::string& model,
                             int threads) {
    GaussianAirlightModel id;
    if (model == "fogshop") id = GaussianAirlightModel::Fogshop;
    else if (model == "quadrature") id = GaussianAirlightModel::Quadrature;
    else throw py::value_error("airlight: unknown model '" + model + "' (valid: 'fogshop', 'quadrature')");
    auto lp = as_array<double>(light_positions, "light_positions");
    const bool single_light = lp.ndim() == 1;
    std::vector<Vec3> lights;
    if (single_light) lights.push_back(to_point(lp, "light_positions"));
    else lights = to_vec3(lp, "light_positions");
    const Vec3 v = to_point(origin, "origin");
    const std::vector<Vec3> dirs = to_vec3(directions, "directions", -1, true);
    const py::ssize_t n = static_cast<py::ssize_t>(dirs.size());
    const std::vector<double> D = to_vector(Dvp, "Dvp", n);
    const std::size_t L = lights.size();
    std::vector<double> out(n * L);
    {
        py::gil_scoped_release release;
        std::shared_ptr<const SpecialFTable> table;
        if (id == GaussianAirlightModel::Fogshop) table = shared_special_F_table(256, 256);
        try {
            gaussian_airlight(m, lights, v, dirs.data(), D.data(), dirs.size(), out.data(), id, table.get(), threads);
        } catch (const std::invalid_argument& e) {
            py::gil_scoped_acquire acquire;
            throw py::value_error(e.what());
        }
    }
    if (single_light) return to_numpy(std::move(out), {n});
    return to_numpy(std::move(out), {n, static_cast<py::ssize_t>(L)});
}

py::dict preview_factors(const py::object& centres, const py::object& scales, const py::object& amplitudes,
                         double beta0, const py::object& eye, const py::object& light_positions, double cull_eps,
                         int threads, const py::object& previous, py::ssize_t first_new, bool eye_only) {
    GaussianMedium medium = make_medium(centres, scales, amplitudes, beta0, cull_eps);
    const Vec3 v = to_point(eye, "eye");
    auto lp = as_array<double>(light_positions, "lights");
    std::vector<Vec3> lights;
    if (!(lp.ndim() == 2 && lp.shape(0) == 0)) lights = to_vec3(lp, "lights");
    GaussianPreviewFactors prev;
    const bool incremental = !previous.is_none();
    if (eye_only && !incremental)
        throw py::value_error("eye_only=True needs previous= (the factors of the same Gaussians and lights)");
    // eye_only: the previous light rows must cover all the Gaussians.
    if (eye_only) first_new = static_cast<py::ssize_t>(medium.size());
    if (incremental) {
        const py::ssize_t m = static_cast<py::ssize_t>(lights.size());
        if (first_new < 0 || first_new > static_cast<py::ssize_t>(medium.size()))
            throw py::value_error("first_new must be in [0, number of Gaussians]");
        py::dict d = previous.cast<py::dict>();
        auto take = [&](const char* key, py::ssize_t rows) {
            if (!d.contains(key)) throw py::value_error(std::string("previous: missing '") + key + "'");
            auto a = as_array<double>(d[key], key);
            const py::ssize_t want = rows < 0 ? first_new : rows * first_new;
            if (a.size() != want)
                throw py::value_error(std::string("previous['") + key + "']: expected " + std::to_string(want) +
                                      " values (first_new Gaussians" + (rows < 0 ? "" : " x lights") + "), got " +
                                      shape_str(a));
            return std::vector<double>(a.data(), a.data() + a.size());
        };
        if (!eye_only) {  // (eye_only: the previous eye row is not needed)
            prev.T_vb = take("T_vb", -1);
            prev.own_vb = take("own_vb", -1);
        }
        prev.T_sb = take("T_sb", m);
        prev.own_sb = take("own_sb", m);
    }
    GaussianPreviewFactors f;
    {
        py::gil_scoped_release release;
        try {
            f = rbf_preview_factors(medium, v, lights, threads, incremental ? &prev : nullptr,
                                    static_cast<std::size_t>(first_new), eye_only);
        } catch (const std::invalid_argument& e) {
            py::gil_scoped_acquire acquire;
            throw py::value_error(e.what());
        }
    }
    const py::ssize_t n = static_cast<py::ssize_t>(medium.size()), m = static_cast<py::ssize_t>(lights.size());
    return py::dict("T_vb"_a = to_numpy(std::move(f.T_vb), {n}), "own_vb"_a = to_numpy(std::move(f.own_vb), {n}),
                    "T_sb"_a = to_numpy(std::move(f.T_sb), {m, n}), "own_sb"_a = to_numpy(std::move(f.own_sb), {m, n}),
                    "C_sv"_a = to_numpy(std::move(f.Csv), {m}), "D_sv"_a = to_numpy(std::move(f.Dsv), {m}),
                    "cull_radius"_a = to_numpy(std::move(f.radius), {n}));
}

}  // namespace

void bind_rbf(py::module_& m) {
    py::class_<GaussianMedium>(m, "RbfMedium", R"doc(Inhomogeneous medium as a sum of Gaussians (Fogshop, Zhou et al. 2007):
beta(x) = beta0 + sum_i c_i exp(-a_i^2 |x - b_i|^2), all in 1/m.

RbfMedium(centres (n, 3), scales (n,) a > 0, amplitudes (n,) c >= 0, beta0=0.0, cull_eps=1e-7)
Raises ValueError on NaN/inf, a <= 0, c < 0, beta0 < 0 or mismatched lengths.
cull_eps: per-Gaussian bound on the optical depth that culling may drop on a segment
(the culled sum is within cull_eps times the number of skipped Gaussians of the exact one).)doc")
        .def(py::init(&make_medium), "centres"_a, "scales"_a, "amplitudes"_a, "beta0"_a = 0.0,
             "cull_eps"_a = GaussianMedium::kDefaultCullEps)
        .def("__len__", &GaussianMedium::size)
        .def_property_readonly("beta0", &GaussianMedium::beta0)
        .def_property_readonly("cull_eps", &GaussianMedium::cull_eps)
        .def("optical_depth", &optical_depth, "p"_a, "q"_a, "culled"_a = true, "threads"_a = 0,
             R"doc(Optical depth T(p[j], q[j]) of the segments, p and q of shape (m, 3); returns (m,).
culled=False sums every Gaussian (the reference). Exact per Gaussian (erf/erfc, eq. 31).)doc")
        .def("optical_depth_ray", &optical_depth_ray, "origins"_a, "directions"_a, "tmax"_a, "culled"_a = true,
             "threads"_a = 0,
             R"doc(Optical depth along origins[j] + t directions[j], t in [0, tmax[j]]; tmax may be inf
(directions are normalised). Returns (m,); inf where beta0 > 0 and tmax = inf.)doc")
        .def(
            "density",
            [](const GaussianMedium& self, const py::object& x) {
                const std::vector<Vec3> X = to_vec3(x, "x");
                std::vector<double> out(X.size());
                for (std::size_t j = 0; j < X.size(); ++j) out[j] = self.density(X[j]);
                return to_numpy(std::move(out), {static_cast<py::ssize_t>(X.size())});
            },
            "x"_a, "Density beta(x) at points of shape (m, 3); returns (m,).")
        .def("airlight", &airlight, "light_positions"_a, "origin"_a, "directions"_a, "Dvp"_a,
             "model"_a = "fogshop", "threads"_a = 0,
             R"doc(Single-scattering airlight of point lights per unit I0 and albedo (like sun05_airlight).

light_positions: (3,) for one light (returns (m,)) or (L, 3) (returns (m, L));
origin: the viewpoint (3,); directions (m, 3) (normalised here); Dvp (m,) > 0, may be inf.
model: "fogshop" (the paper's approximation, eq. 8-17; homogeneous term through the F
table) or "quadrature" (adaptive quadrature of eq. 2 with exact optical depths; slow).
Multiply by albedo * I0 (W/sr). The GIL is released during the work.)doc");

    m.def("rbf_preview_factors", &preview_factors, "centres"_a, "scales"_a, "amplitudes"_a, "beta0"_a, "eye"_a,
          "lights"_a, "cull_eps"_a = GaussianMedium::kDefaultCullEps, "threads"_a = 0, "previous"_a = py::none(),
          "first_new"_a = 0, "eye_only"_a = false,
          R"doc(Per-edit Fogshop factors for a viewport preview that splats the Gaussians (section 5.1).

centres (n, 3), scales (n,) a > 0 (1/m), amplitudes (n,) c >= 0 (1/m), beta0 >= 0 (1/m,
the homogeneous background), eye (3,), lights (m, 3) point-light positions (m may be 0).
Builds the medium (cull hierarchy) and returns a dict of float64 arrays:
  T_vb (n,):        T(v, b_i), optical depth of the whole medium (beta0 and all Gaussians,
                    Gaussian i's own half included) on the segment eye -> b_i;
  own_vb (n,):      T_i(v, b_i), Gaussian i's own share of T_vb;
  T_sb (m, n):      T(s_l, b_i), the same from light l to b_i;
  own_sb (m, n):    T_i(s_l, b_i);
  C_sv (m,):        exp(-(T(s_l, v) - beta0 |s_l - v|)), the Gaussians alone on light -> eye (eq. 16);
  D_sv (m,):        |s_l - v|;
  cull_radius (n,): R_i, beyond which Gaussian i integrates to < cull_eps on any segment.
Paper eq. 13: f1 = exp(-T_sb - T_vb). The bake uses exp(-(T_sb - own_sb) - (T_vb - own_vb))
and attenuates Gaussian i by itself along light -> b_i^r -> eye (gaussian/airlight.h).
Culled optical depths (each skipped Gaussian < cull_eps), the other Gaussians summed in
float (fast_erf.h: ~1e-5 relative), the own halves exactly.
Incremental use after a brush stroke appended Gaussians: previous = the dict of an earlier
call whose Gaussians are the first first_new of these (unchanged, same eye, lights, beta0):
only the new ones are computed in full, the others add the new Gaussians' integrals.
View change (the viewport orbiting): eye_only=True with previous = the dict of an earlier
call with the same Gaussians, lights and beta0 (any eye; its T_sb, own_sb are used, first_new
is ignored): only T_vb, own_vb, C_sv and D_sv are computed (one segment per Gaussian instead
of 1 + m), T_sb and own_sb are copied; the same values as the full call.
Raises ValueError on bad input. The GIL is released during the work.)doc");

    m.def(
        "erf_diff",
        [](const py::object& x1, const py::object& x2) {
            auto args = broadcast_doubles({{x1, "x1"}, {x2, "x2"}});
            py::array_t<double> out(std::vector<py::ssize_t>(args[0].shape(), args[0].shape() + args[0].ndim()));
            double* po = out.mutable_data();
            for (py::ssize_t i = 0; i < args[0].size(); ++i) po[i] = erf_diff(args[0].data()[i], args[1].data()[i]);
            return out;
        },
        "x1"_a, "x2"_a,
        "erf(x2) - erf(x1) for x1 <= x2 (0 otherwise), without cancellation in the tails (the RBF line integral's core).");
}

}  // namespace airlight::bindings
