// bind_pegoraro.cpp: the complex exponential integral, the baseline fog term (for the stability suite), the Pegoraro et al. 2010 closed form
// (point and spot lights, any polynomial phase / light distribution) and the spot-light
// quadrature reference, over numpy arrays (GIL released around the loops).
#include <cmath>
#include <complex>
#include <stdexcept>

#include <glm/glm.hpp>
#include <pybind11/complex.h>
#include <pybind11/stl.h>

#include "homogeneous/baseline_fog.h"
#include "core/complex_e1.h"
#include "homogeneous/pegoraro10.h"
#include "homogeneous/spot_light.h"
#include "homogeneous/sun05.h"
#include "bindings/numpy_util.h"

namespace airlight::bindings {

using namespace pybind11::literals;

namespace {

// Phase polynomial from a name (phase.h names); order < 0: HG order from _rel_tol_.
PegoraroPhase make_phase(const std::string& name, double g, int order, double rel_tol) {
    try {
        const PhaseFunction p = phase_from_name(name, g);
        if (order < 0) {
            if (p.kind == PhaseKind::HenyeyGreenstein && pegoraro_hg_order(p.g, rel_tol) < 0)
                throw py::value_error("pegoraro10: Henyey-Greenstein g = " + std::to_string(g) +
                                      " needs a Legendre order above 96 for rel_tol; pass order= explicitly");
            return pegoraro_phase_auto(p, rel_tol);
        }
        return pegoraro_phase(p, order);
    } catch (const std::invalid_argument& e) {
        throw py::value_error(e.what());
    }
}

glm::dvec3 vec3(const py::object& o, const char* name) {
    auto a = as_array<double>(o, name);
    if (a.size() != 3) throw py::value_error(std::string(name) + ": expected 3 numbers");
    glm::dvec3 v(a.data()[0], a.data()[1], a.data()[2]);
    if (!std::isfinite(v.x) || !std::isfinite(v.y) || !std::isfinite(v.z))
        throw py::value_error(std::string(name) + ": must be finite");
    return v;
}

// Rays: origins (N, 3) or (3,), unit-normalised directions (N, 3), Dvp (N,) (inf allowed).
struct Rays {
    std::vector<glm::dvec3> o, d;
    std::vector<double> Dvp;
};

Rays make_rays(const py::object& origins, const py::object& directions, const py::object& Dvp) {
    auto D = as_array<double>(directions, "directions");
    const py::ssize_t n = require_rows_of(D, 3, "directions");
    auto O = as_array<double>(origins, "origins");
    const bool one = O.ndim() == 1 && O.size() == 3;
    if (!one) require_rows_of(O, 3, "origins", n);
    auto L = broadcast_doubles({{Dvp, "Dvp"}, {py::cast(std::vector<double>(n, 0.0)), "rays"}});
    Rays r;
    for (py::ssize_t i = 0; i < n; ++i) {
        const double* po = O.data() + (one ? 0 : 3 * i);
        glm::dvec3 o(po[0], po[1], po[2]), d(D.data()[3 * i], D.data()[3 * i + 1], D.data()[3 * i + 2]);
        const double len = glm::length(d), dv = L[0].data()[i];
        if (!std::isfinite(o.x + o.y + o.z) || !(len > 0.0) || !std::isfinite(len))
            throw py::value_error("rays: origins must be finite and directions finite and nonzero");
        if (!(dv >= 0.0)) throw py::value_error("Dvp must be >= 0 (may be inf)");
        r.o.push_back(o);
        r.d.push_back(d / len);
        r.Dvp.push_back(dv);
    }
    return r;
}

}  // namespace

void bind_pegoraro(py::module_& m) {
    m.def(
        "baseline_fog_airlight",
        [](const py::object& C_fog, const py::object& sigma_t, const py::object& D) {
            auto args = broadcast_doubles({{C_fog, "C_fog"}, {sigma_t, "sigma_t"}, {D, "D"}});
            py::array_t<double> out(std::vector<py::ssize_t>(args[0].shape(), args[0].shape() + args[0].ndim()));
            const double *pc = args[0].data(), *ps = args[1].data(), *pd = args[2].data();
            double* po = out.mutable_data();
            for (py::ssize_t i = 0; i < args[0].size(); ++i) {
                if (!std::isfinite(pc[i]) || !std::isfinite(ps[i]) || ps[i] < 0.0 || !(pd[i] >= 0.0))
                    throw py::value_error("baseline_fog_airlight: C_fog, sigma_t finite (sigma_t >= 0), D >= 0 (inf ok)");
                po[i] = baseline_fog_airlight(pc[i], ps[i], pd[i]);
            }
            return out;
        },
        "C_fog"_a, "sigma_t"_a, "D"_a,
        "Baseline fog (Blender Mist / OpenGL fog) airlight C_fog (1 - e^{-sigma_t D}) (baseline_fog.h); D may be inf.");

    m.def(
        "complex_e1",
        [](const py::object& z) {
            // Numbers only: numpy casts None (and other objects) to NaN without a word.
            py::array raw = py::array::ensure(z);
            if (!raw) throw py::value_error("z: cannot convert to a complex array");
            const char kind = raw.dtype().kind();
            if (!(kind == 'b' || kind == 'i' || kind == 'u' || kind == 'f' || kind == 'c'))
                throw py::type_error("z: expected real or complex numbers, got " +
                                     (z.is_none() ? std::string("None")
                                                  : "dtype " + std::string(py::str(raw.dtype()))));
            auto a = py::array_t<std::complex<double>, py::array::c_style | py::array::forcecast>::ensure(raw);
            if (!a) throw py::value_error("z: cannot convert to a complex array");
            py::array_t<std::complex<double>> out(std::vector<py::ssize_t>(a.shape(), a.shape() + a.ndim()));
            const std::complex<double>* pz = a.data();
            std::complex<double>* po = out.mutable_data();
            const py::ssize_t n = a.size();
            py::gil_scoped_release release;
            for (py::ssize_t i = 0; i < n; ++i) po[i] = complex_e1(pz[i]);
            return out;
        },
        "z"_a,
        R"doc(Complex exponential integral E1(z), principal branch (cut on the negative real axis;
the sign of Im z, including -0.0, picks the side). Power series |z| < 5, DLMF 6.9.1 continued fraction elsewhere.)doc");

    m.def(
        "pegoraro_legendre",
        [](const std::string& phase, double g, int order, double rel_tol) {
            return make_phase(phase, g, order, rel_tol).legendre;
        },
        "phase"_a = "hg", "g"_a = 0.0, "order"_a = -1, "rel_tol"_a = 1e-6,
        "Legendre coefficients a_n (4 pi p(mu) = sum a_n P_n(mu)) of the phase polynomial Pegoraro 2010 uses; "
        "order < 0: the Henyey-Greenstein order whose truncation bound meets rel_tol.");

    m.def(
        "pegoraro_moments",
        [](double H, double v0, double v1, int K) {
            if (!(H > 0.0) || !(v0 >= 0.0) || !(v1 > v0) || K < 0 || K > 132)
                throw py::value_error("pegoraro_moments: need H > 0, 0 <= v0 < v1 (inf ok), 0 <= K <= 132");
            std::vector<std::complex<double>> G(K + 1);
            pegoraro_moments(H, v0, v1, K, G.data());
            return G;
        },
        "H"_a, "v0"_a, "v1"_a, "K"_a,
        "G_m = int_{atan v0}^{atan v1} e^{2 i m psi} e^{-H (tan psi - v0)} dpsi for m = 0..K (pegoraro10.h).");

    m.def(
        "pegoraro10_airlight",
        [](const py::object& sigma_t, const py::object& Dsv, const py::object& cos_gamma, const py::object& Dvp,
           const std::string& phase, double g, int order, double rel_tol) {
            const PegoraroPhase p = make_phase(phase, g, order, rel_tol);
            auto args = broadcast_doubles({{sigma_t, "sigma_t"}, {Dsv, "Dsv"}, {cos_gamma, "cos_gamma"}, {Dvp, "Dvp"}});
            py::array_t<double> out(std::vector<py::ssize_t>(args[0].shape(), args[0].shape() + args[0].ndim()));
            const double *ps = args[0].data(), *pD = args[1].data(), *pc = args[2].data(), *pd = args[3].data();
            double* po = out.mutable_data();
            const py::ssize_t n = args[0].size();
            try {
                for (py::ssize_t i = 0; i < n; ++i) sun05_check_inputs(ps[i], pD[i], pc[i], pd[i]);
            } catch (const std::invalid_argument& e) {
                throw py::value_error(e.what());
            }
            py::gil_scoped_release release;
            for (py::ssize_t i = 0; i < n; ++i) po[i] = pegoraro10_airlight(p, ps[i], pD[i], pc[i], pd[i]);
            return out;
        },
        "sigma_t"_a, "Dsv"_a, "cos_gamma"_a, "Dvp"_a, "phase"_a = "hg", "g"_a = 0.0, "order"_a = -1,
        "rel_tol"_a = 1e-6,
        R"doc(Pegoraro et al. 2010 closed-form airlight of an isotropic point light with the phase polynomial
(exact for isotropic, rayleigh, hazy_mie, murky_mie; HG truncated at _order_, or chosen from rel_tol when
order < 0), per unit I0 and albedo; arguments as sun05_airlight (broadcast; Dvp may be inf).)doc");

    m.def(
        "pegoraro10_ray_airlight",
        [](const py::object& light_poly, const py::object& axis, const py::object& position, double sigma_t,
           const py::object& origins, const py::object& directions, const py::object& x0, const py::object& x1,
           const std::string& phase, double g, int order) {
            const PegoraroPhase p = make_phase(phase, g, order, 1e-6);
            std::vector<double> light = py::cast<std::vector<double>>(light_poly);
            if (light.empty() || light.size() > 9) throw py::value_error("light_poly: 1 to 9 coefficients");
            const glm::dvec3 A = glm::normalize(vec3(axis, "axis")), s = vec3(position, "position");
            if (!(sigma_t >= 0.0) || !std::isfinite(sigma_t)) throw py::value_error("sigma_t must be finite and >= 0");
            const Rays r = make_rays(origins, directions, x1);
            auto lo = broadcast_doubles({{x0, "x0"}, {py::cast(std::vector<double>(r.d.size(), 0.0)), "rays"}});
            std::vector<double> out(r.d.size());
            {
                py::gil_scoped_release release;
                for (size_t i = 0; i < r.d.size(); ++i)
                    out[i] = pegoraro10_airlight_poly(p, light, A, sigma_t, s, r.o[i], r.d[i], lo[0].data()[i], r.Dvp[i]);
            }
            return to_numpy(std::move(out), {py::ssize_t(r.d.size())});
        },
        "light_poly"_a, "axis"_a, "position"_a, "sigma_t"_a, "origins"_a, "directions"_a, "x0"_a, "x1"_a,
        "phase"_a = "isotropic", "g"_a = 0.0, "order"_a = -1,
        "Closed-form airlight over [x0, x1] of each ray for a light distribution I(c) = sum light_poly[k] c^k "
        "(c = cosine to _axis_), per unit I0 and albedo.");

    auto spot_args = [](const py::object& position, const py::object& axis, double spot_size, double spot_blend,
                        double sigma_t, double spread) {
        if (!(spot_size > 0.0 && spot_size <= 3.14159265358979323846 + 1e-9))
            throw py::value_error("spot_size must be in (0, pi]");
        if (!(spot_blend >= 0.0 && spot_blend <= 1.0)) throw py::value_error("spot_blend must be in [0, 1]");
        if (!(sigma_t >= 0.0) || !std::isfinite(sigma_t)) throw py::value_error("sigma_t must be finite and >= 0");
        const glm::dvec3 A = vec3(axis, "axis");
        if (!(glm::length(A) > 0.0)) throw py::value_error("axis must be nonzero");
        try {
            return std::make_pair(vec3(position, "position"), make_spot_cone(A, spot_size, spot_blend, spread));
        } catch (const std::invalid_argument& e) {
            throw py::value_error(e.what());
        }
    };

    m.def(
        "spot_cone",
        [](double spot_size, double spot_blend, double spread) {
            if (!(spot_size > 0.0 && spot_size <= kPi + 1e-9)) throw py::value_error("spot_size must be in (0, pi]");
            if (!(spot_blend >= 0.0 && spot_blend <= 1.0)) throw py::value_error("spot_blend must be in [0, 1]");
            try {
                const SpotCone c = make_spot_cone(glm::dvec3(0.0, 0.0, -1.0), spot_size, spot_blend, spread);
                return py::make_tuple(c.cos_half_angle, c.smooth, c.spread_a, c.spread_b);
            } catch (const std::invalid_argument& e) {
                throw py::value_error(e.what());
            }
        },
        "spot_size"_a, "spot_blend"_a, "spread"_a = kPi,
        "The profile constants (cos_half, smooth, spread_a, spread_b) of a spot or an area light's sample "
        "(SpotCone, spot_light.h), as the GPU preview's spot texture takes them.");

    m.def(
        "pegoraro10_spot_airlight",
        [spot_args](const py::object& position, const py::object& axis, double spot_size, double spot_blend,
                    double sigma_t, const py::object& origins, const py::object& directions, const py::object& Dvp,
                    const std::string& phase, double g, int order, double rel_tol, double spread) {
            const auto [s, cone] = spot_args(position, axis, spot_size, spot_blend, sigma_t, spread);
            const PegoraroPhase p = make_phase(phase, g, order, rel_tol);
            const Rays r = make_rays(origins, directions, Dvp);
            std::vector<double> out(r.d.size());
            {
                py::gil_scoped_release release;
                for (size_t i = 0; i < r.d.size(); ++i)
                    out[i] = pegoraro10_spot_airlight(p, cone, s, sigma_t, r.o[i], r.d[i], r.Dvp[i]);
            }
            return to_numpy(std::move(out), {py::ssize_t(r.d.size())});
        },
        "position"_a, "axis"_a, "spot_size"_a, "spot_blend"_a, "sigma_t"_a, "origins"_a, "directions"_a, "Dvp"_a,
        "phase"_a = "isotropic", "g"_a = 0.0, "order"_a = -1, "rel_tol"_a = 1e-6, "spread"_a = kPi,
        "Closed-form (Pegoraro 2010) airlight of a Blender spot light (Cycles profile, exact piecewise "
        "polynomial) along each ray, per unit I0 and albedo. _spread_ < pi: an area light's sample with "
        "Cycles' Spread (spot_size pi, blend 0; its pieces by quadrature).");

    m.def(
        "spot_airlight_quadrature",
        [spot_args](const py::object& position, const py::object& axis, double spot_size, double spot_blend,
                    double sigma_t, const py::object& origins, const py::object& directions, const py::object& Dvp,
                    const std::string& phase, double g, double rel_tol, double spread) {
            const auto [s, cone] = spot_args(position, axis, spot_size, spot_blend, sigma_t, spread);
            PhaseFunction p;
            try {
                p = phase_from_name(phase, g);
            } catch (const std::invalid_argument& e) {
                throw py::value_error(e.what());
            }
            const Rays r = make_rays(origins, directions, Dvp);
            std::vector<double> out(r.d.size());
            {
                py::gil_scoped_release release;
                for (size_t i = 0; i < r.d.size(); ++i)
                    out[i] = spot_airlight_quadrature(cone, s, p, sigma_t, r.o[i], r.d[i], r.Dvp[i], rel_tol);
            }
            return to_numpy(std::move(out), {py::ssize_t(r.d.size())});
        },
        "position"_a, "axis"_a, "spot_size"_a, "spot_blend"_a, "sigma_t"_a, "origins"_a, "directions"_a, "Dvp"_a,
        "phase"_a = "isotropic", "g"_a = 0.0, "rel_tol"_a = 1e-8, "spread"_a = kPi,
        "Reference: adaptive quadrature of the spot-light airlight (spot_light.h), per unit I0 and albedo; "
        "_spread_ as pegoraro10_spot_airlight.");
}

}  // namespace airlight::bindings
