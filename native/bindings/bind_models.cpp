// bind_models.cpp: phase functions, Biri 2006 airlight for any phase, its quadrature
// reference, and Hoffman-Preetham sun fog, vectorised over numpy arrays (GIL released).
#include <cmath>
#include <stdexcept>

#include "core/table_cache.h"
#include "homogeneous/biri06.h"
#include "homogeneous/hoffman02.h"
#include "core/phase.h"
#include "homogeneous/sun05.h"
#include "bindings/numpy_util.h"

namespace airlight::bindings {

using namespace pybind11::literals;

namespace {

PhaseFunction parse_phase(const std::string& name, double g) {
    try {
        return phase_from_name(name, g);
    } catch (const std::invalid_argument& e) {
        throw py::value_error(e.what());
    }
}

py::array_t<double> empty_like(const CArray<double>& a) {
    return py::array_t<double>(std::vector<py::ssize_t>(a.shape(), a.shape() + a.ndim()));
}

py::array_t<double> phase_py(const std::string& name, const py::object& mu, double g) {
    const PhaseFunction p = parse_phase(name, g);
    auto args = broadcast_doubles({{mu, "mu"}});
    py::array_t<double> out = empty_like(args[0]);
    const double* pm = args[0].data();
    double* po = out.mutable_data();
    const py::ssize_t n = args[0].size();
    for (py::ssize_t i = 0; i < n; ++i)
        if (!(pm[i] >= -1.0 && pm[i] <= 1.0)) throw py::value_error("phase: mu must be in [-1, 1]");
    py::gil_scoped_release release;
    for (py::ssize_t i = 0; i < n; ++i) po[i] = p.eval(pm[i]);
    return out;
}

// Shared driver of the point-light models: validates everything, then evaluates without the GIL.
template <typename Fn>
py::array_t<double> point_light(const py::object& sigma_t, const py::object& Dsv, const py::object& cos_gamma,
                                const py::object& Dvp, Fn&& fn) {
    auto args = broadcast_doubles({{sigma_t, "sigma_t"}, {Dsv, "Dsv"}, {cos_gamma, "cos_gamma"}, {Dvp, "Dvp"}});
    py::array_t<double> out = empty_like(args[0]);
    const double *ps = args[0].data(), *pD = args[1].data(), *pc = args[2].data(), *pd = args[3].data();
    double* po = out.mutable_data();
    const py::ssize_t n = args[0].size();
    try {
        for (py::ssize_t i = 0; i < n; ++i) sun05_check_inputs(ps[i], pD[i], pc[i], pd[i]);
    } catch (const std::invalid_argument& e) {
        throw py::value_error(e.what());
    }
    py::gil_scoped_release release;
    for (py::ssize_t i = 0; i < n; ++i) po[i] = fn(ps[i], pD[i], pc[i], pd[i]);
    return out;
}

py::dict hoffman02_py(const py::object& cos_theta, const py::object& s, const py::object& beta_R,
                      const py::object& beta_M, double g, const py::object& E_sun) {
    auto three = [](const py::object& o, const char* name, double out[3]) {
        auto a = as_array<double>(o, name);
        if (a.size() != 3) throw py::value_error(std::string(name) + ": expected 3 numbers (RGB)");
        for (int c = 0; c < 3; ++c) {
            out[c] = a.data()[c];
            if (!std::isfinite(out[c]) || out[c] < 0.0) throw py::value_error(std::string(name) + ": must be finite and >= 0");
        }
    };
    Hoffman02Medium m;
    double E[3];
    three(beta_R, "beta_R", m.beta_R);
    three(beta_M, "beta_M", m.beta_M);
    three(E_sun, "E_sun", E);
    if (!(std::abs(g) < 1.0)) throw py::value_error("hoffman02: g must be finite with |g| < 1");
    m.g = g;
    auto args = broadcast_doubles({{cos_theta, "cos_theta"}, {s, "s"}});
    const double *pc = args[0].data(), *ps = args[1].data();
    const py::ssize_t n = args[0].size();
    for (py::ssize_t i = 0; i < n; ++i) {
        if (!(pc[i] >= -1.0 && pc[i] <= 1.0)) throw py::value_error("hoffman02: cos_theta must be in [-1, 1]");
        if (!(ps[i] >= 0.0)) throw py::value_error("hoffman02: s must be >= 0 (may be inf)");
    }
    // The broadcast shape as numpy gives it (scalars stay 0-d, so the result is (3,)).
    std::vector<py::ssize_t> shape;
    const py::tuple bshape = py::module_::import("numpy").attr("broadcast")(args[0], args[1]).attr("shape");
    if (py::array::ensure(cos_theta).ndim() + py::array::ensure(s).ndim() > 0)
        for (size_t k = 0; k < bshape.size(); ++k) shape.push_back(bshape[k].cast<py::ssize_t>());
    shape.push_back(3);
    py::array_t<double> F(shape), L(shape);
    double *pF = F.mutable_data(), *pL = L.mutable_data();
    {
        py::gil_scoped_release release;
        for (py::ssize_t i = 0; i < n; ++i) hoffman02(m, E, pc[i], ps[i], pF + 3 * i, pL + 3 * i);
    }
    return py::dict("F_ex"_a = F, "L_in"_a = L);
}

}  // namespace

void bind_models(py::module_& m) {
    m.def(
        "set_table_cache_dir", [](const std::string& dir) {
            if (dir.find('\0') != std::string::npos) throw py::value_error("set_table_cache_dir: NUL byte in the path");
            set_table_cache_dir(dir);
        },
        "dir"_a,
        "Keep the models' tables (F, surface G, Gamma, sun glow) in this folder across processes "
        "(core/table_cache.h); \"\" turns the cache off. Default: $AIRLIGHT_TABLE_CACHE, else off.");
    m.def("table_cache_dir", [] { return table_cache_dir(); }, "The table cache's folder (\"\": off).");
    m.def(
        "table_cache_counts",
        [] {
            const TableCacheCounts c = table_cache_counts();
            return py::dict("built"_a = c.built, "loaded"_a = c.loaded, "refused"_a = c.refused);
        },
        "This process's tables: built (cache missed or off), loaded from the cache, and cache files "
        "refused (corrupt, truncated or from another build; rebuilt with a note on stderr).");
    m.def(
        "table_cache_record",
        [](const std::string& key, size_t count) -> py::object {
            std::vector<double> data(count);
            bool found;
            {
                py::gil_scoped_release release;
                found = read_record(key, data);
            }
            if (!found) return py::none();
            return py::array_t<double>(py::ssize_t(count), data.data());
        },
        "key"_a, "count"_a,
        "The _count_ values kept under _key_ in the table cache's folder (table_cache_store_record), "
        "or None: none kept, the cache off, or a file refused (corrupt, another build's; a note on stderr).");
    m.def(
        "table_cache_store_record",
        [](const std::string& key, py::array_t<double, py::array::c_style | py::array::forcecast> values) {
            const std::vector<double> data(values.data(), values.data() + values.size());
            py::gil_scoped_release release;
            write_record(key, data);
        },
        "key"_a, "values"_a,
        "Keeps _values_ under _key_ in the table cache's folder (written whole, atomically; nothing "
        "where the cache is off or the folder cannot be written). Not counted in table_cache_counts.");
    m.def("phase", &phase_py, "name"_a, "mu"_a, "g"_a = 0.0,
          R"doc(Phase function p(mu) in 1/sr, normalised to 1 over the sphere.

name: "isotropic", "hg" (Henyey-Greenstein, Cycles sign: g > 0 forward), "rayleigh",
"hazy_mie", "murky_mie" (Nishita). mu = cos theta, theta between the light's propagation
direction and the scattered direction (mu = 1: looking straight into the light).
ValueError on an unknown name, |g| >= 1 or mu outside [-1, 1].)doc");

    m.def(
        "biri06_airlight",
        [](const py::object& sigma_t, const py::object& Dsv, const py::object& cos_gamma, const py::object& Dvp,
           const std::string& phase, double g, bool exact) {
            const PhaseFunction p = parse_phase(phase, g);
            std::shared_ptr<const Biri06Table> table;
            if (!exact) {
                py::gil_scoped_release release;
                table = shared_biri06_table(p);
            }
            return point_light(sigma_t, Dsv, cos_gamma, Dvp, [&](double s, double D, double c, double d) {
                return biri06_airlight(p, s, D, c, d, table.get(), exact ? GammaEval::Exact : GammaEval::Table);
            });
        },
        "sigma_t"_a, "Dsv"_a, "cos_gamma"_a, "Dvp"_a, "phase"_a = "hg", "g"_a = 0.0, "exact"_a = false,
        R"doc(Biri et al. 2006 single-scattering airlight of a point light for any phase function,
per unit I0 and albedo (same arguments as sun05_airlight; broadcast arrays; Dvp may be inf).

exact=False: the 256 x 256 Gamma table of that phase (per g for HG, built on first use,
~40 ms, cached), falling back to the exact difference where the lookup would cancel;
exact=True: the exact Gamma difference by adaptive quadrature. Multiply by albedo * I0.
The table path refuses HG g < -0.99 (ValueError; the "quadrature" model takes it).)doc");

    m.def(
        "airlight_quadrature",
        [](const py::object& sigma_t, const py::object& Dsv, const py::object& cos_gamma, const py::object& Dvp,
           const std::string& phase, double g) {
            const PhaseFunction p = parse_phase(phase, g);
            return point_light(sigma_t, Dsv, cos_gamma, Dvp, [&](double s, double D, double c, double d) {
                return phase_airlight_quadrature(p, s, D, c, d);
            });
        },
        "sigma_t"_a, "Dsv"_a, "cos_gamma"_a, "Dvp"_a, "phase"_a = "hg", "g"_a = 0.0,
        R"doc(Reference: adaptive quadrature (1e-10) of sigma_t int_0^Dvp p(cos theta(x)) e^{-sigma_t (d + x)} / d^2 dx
with cos theta(x) = (Dsv cos_gamma - x) / d(x), per unit I0 and albedo. Slow.)doc");

    m.def("hoffman02", &hoffman02_py, "cos_theta"_a, "s"_a, "beta_R"_a, "beta_M"_a, "g"_a = 0.0,
          "E_sun"_a = py::make_tuple(1.0, 1.0, 1.0),
          R"doc(Hoffman & Preetham 2002 sun fog. cos_theta = -dot(sun_dir, view_dir) (sun_dir = the lamp's
-Z axis), s = view segment length (may be inf); beta_R, beta_M: RGB scattering = extinction
coefficients (1/m); g: Mie HG anisotropy (Cycles sign); E_sun = lamp colour * strength (W/m^2).
Returns dict(F_ex=(..., 3), L_in=(..., 3)); composite L = L0 * F_ex + L_in.)doc");

    m.def(
        "hoffman02_rayleigh_rgb",
        [](double beta_550) {
            double b[3];
            hoffman02_rayleigh_rgb(beta_550, b);
            return py::make_tuple(b[0], b[1], b[2]);
        },
        "beta_R_550"_a, "Rayleigh coefficients for R, G, B (650, 570, 475 nm) from the one at 550 nm (1/lambda^4).");

    // Preview: the Biri 2006 table itself, for the GPU (shaders/biri06_airlight.glsl).
    m.def(
        "biri06_table",
        [](const std::string& phase, double g, int nl, int nT) {
            if (nl < 2 || nT < 2 || nl > 16384 || nT > 16384)
                throw py::value_error("biri06_table: nl and nT must be in [2, 16384]");
            const PhaseFunction p = parse_phase(phase, g);
            std::shared_ptr<const Biri06Table> table;
            {
                py::gil_scoped_release release;
                table = shared_biri06_table(p, nl, nT);
            }
            py::array_t<float> arr({py::ssize_t(nl), py::ssize_t(nT)});
            std::copy(table->data().begin(), table->data().end(), arr.mutable_data());
            return py::dict("data"_a = arr, "nl"_a = nl, "nT"_a = nT, "K"_a = table->K(), "k"_a = table->k(),
                            "phase"_a = phase_name(p.kind), "g"_a = p.g);
        },
        "phase"_a = "hg", "g"_a = 0.0, "nl"_a = 256, "nT"_a = 256,
        R"doc(The Biri 2006 G table the bake's "biri06" model uses for this phase function (the same
shared instance): dict(data=(nl, nT) float32 array of Q(s, w), nl, nT, K, k, phase, g).
Rows i over s = sqrt(lambda / (lambda + k)), columns j over w = tau / (1 + tau),
tau = T (K + lambda); G(lambda, T) = Q w / (K + lambda) by bilinear interpolation
(native/homogeneous/biri06.cpp). ValueError on an unknown phase, |g| >= 1, HG g < -0.99 (a
backward lobe sharper than the table resolves) or bad sizes.)doc");
}

}  // namespace airlight::bindings
