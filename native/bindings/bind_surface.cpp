// bind_surface.cpp: the surface glow kernels (Sun 2005 G0/Gn for the isotropic phase, the
// phase-aware G_p and Biri 2006's Lambert Gamma_L, biri06_surface.h) over numpy arrays,
// validated first, evaluated with the GIL released.
#include <cmath>
#include <stdexcept>

#include "core/constants.h"
#include "bake/surface_pass.h"
#include "surface/biri06_surface.h"
#include "core/phase.h"
#include "core/scene.h"
#include "homogeneous/spot_light.h"
#include "surface/spot_surface.h"
#include "surface/sun05_surface.h"
#include "bindings/numpy_util.h"

namespace airlight::bindings {

using namespace pybind11::literals;

namespace {


PhaseFunction parse(const std::string& name, double g) {
    try {
        return phase_from_name(name, g);
    } catch (const std::invalid_argument& e) {
        throw py::value_error(e.what());
    }
}

py::array_t<double> shaped_like(const CArray<double>& a) {
    return py::array_t<double>(std::vector<py::ssize_t>(a.shape(), a.shape() + a.ndim()));
}

void check_T(const double* T, py::ssize_t n, const char* what) {
    for (py::ssize_t i = 0; i < n; ++i)
        if (!(std::isfinite(T[i]) && T[i] >= 0.0))
            throw py::value_error(std::string(what) + ": T must be finite and >= 0, got " + std::to_string(T[i]));
}

py::array_t<double> surface_G_py(const py::object& T, const py::object& theta_s, double m, const std::string& phase,
                                 double g, bool exact, int nT, int ntheta) {
    const PhaseFunction p = parse(phase, g);
    if (!(m >= 1.0 && m <= 10000.0)) throw py::value_error("surface_G: m must be in [1, 10000]");
    if (!exact && (nT < 2 || ntheta < 2 || nT > 4096 || ntheta > 4096))
        throw py::value_error("surface_G: nT and ntheta must be in [2, 4096]");
    auto args = broadcast_doubles({{T, "T"}, {theta_s, "theta_s"}});
    const double *pT = args[0].data(), *pth = args[1].data();
    const py::ssize_t n = args[0].size();
    check_T(pT, n, "surface_G");
    for (py::ssize_t i = 0; i < n; ++i)
        if (!(pth[i] >= 0.0 && pth[i] <= kPi)) throw py::value_error("surface_G: theta_s must be in [0, pi]");
    py::array_t<double> out = shaped_like(args[0]);
    double* po = out.mutable_data();
    py::gil_scoped_release release;
    if (exact) {
        for (py::ssize_t i = 0; i < n; ++i) po[i] = biri06_surface_G_exact(p, pT[i], pth[i], m);
    } else if (phase_is_isotropic(p)) {  // the bake's table for this phase (bake/surface_pass.h)
        auto table = shared_surface_G_table(nT, ntheta, m);
        for (py::ssize_t i = 0; i < n; ++i) po[i] = table->eval(pT[i], pth[i]);
    } else {
        auto table = shared_phase_surface_G_table(p, nT, ntheta, m);
        for (py::ssize_t i = 0; i < n; ++i) po[i] = table->eval(pT[i], pth[i]);
    }
    return out;
}

py::array_t<double> surface_H_py(const py::object& T, const py::object& gamma, const std::string& phase, double g) {
    const PhaseFunction p = parse(phase, g);
    auto args = broadcast_doubles({{T, "T"}, {gamma, "gamma"}});
    const double *pT = args[0].data(), *pg = args[1].data();
    const py::ssize_t n = args[0].size();
    check_T(pT, n, "surface_H");
    for (py::ssize_t i = 0; i < n; ++i)
        if (!(pg[i] >= 0.0 && pg[i] <= kPi)) throw py::value_error("surface_H: gamma must be in [0, pi]");
    py::array_t<double> out = shaped_like(args[0]);
    double* po = out.mutable_data();
    py::gil_scoped_release release;
    for (py::ssize_t i = 0; i < n; ++i) po[i] = biri06_surface_H_scaled(p, pT[i], pg[i]) * std::exp(-pT[i]);
    return out;
}

py::array_t<double> gamma_L_py(const py::object& lam, const std::string& phase, double g, bool exact) {
    const PhaseFunction p = parse(phase, g);
    auto args = broadcast_doubles({{lam, "lam"}});
    const double* pl = args[0].data();
    const py::ssize_t n = args[0].size();
    check_T(pl, n, "biri06_gamma_L");
    py::array_t<double> out = shaped_like(args[0]);
    double* po = out.mutable_data();
    py::gil_scoped_release release;
    std::shared_ptr<const Biri06LambertTable> table;
    if (!exact) table = shared_biri06_lambert_table(p);
    for (py::ssize_t i = 0; i < n; ++i)
        po[i] = (exact ? biri06_Gamma_L_scaled_exact(p, pl[i]) : table->eval_scaled(pl[i])) * std::exp(-pl[i]);
    return out;
}

py::array_t<double> spot_glow_factor_py(const py::object& T, const py::object& cos_psi, double spot_size,
                                        double spot_blend, const std::string& phase, double g) {
    const PhaseFunction p = parse(phase, g);
    if (!(spot_size > 0.0 && spot_size <= kPi)) throw py::value_error("spot_glow_factor: spot_size must be in (0, pi]");
    if (!(spot_blend >= 0.0 && spot_blend <= 1.0)) throw py::value_error("spot_glow_factor: spot_blend must be in [0, 1]");
    auto args = broadcast_doubles({{T, "T"}, {cos_psi, "cos_psi"}});
    const double *pT = args[0].data(), *pc = args[1].data();
    const py::ssize_t n = args[0].size();
    check_T(pT, n, "spot_glow_factor");
    for (py::ssize_t i = 0; i < n; ++i)
        if (!(pc[i] >= -1.0 && pc[i] <= 1.0)) throw py::value_error("spot_glow_factor: cos_psi must be in [-1, 1]");
    py::array_t<double> out = shaped_like(args[0]);
    double* po = out.mutable_data();
    py::gil_scoped_release release;
    const SpotGlowModel model(make_spot_cone(glm::dvec3(0.0, 0.0, -1.0), spot_size, spot_blend), p);
    for (py::ssize_t i = 0; i < n; ++i) po[i] = model.factor(pT[i], pc[i]);
    return out;
}

double spot_reference_py(const py::object& s, const py::object& axis, double spot_size, double spot_blend,
                         const py::object& p, const py::object& n, double sigma_t, const std::string& phase, double g,
                         double rel_tol) {
    const PhaseFunction ph = parse(phase, g);
    auto vec = [](const py::object& o, const char* name) {
        auto a = as_array<double>(o, name);
        if (a.size() != 3) throw py::value_error(std::string(name) + ": expected 3 numbers");
        const glm::dvec3 v(a.data()[0], a.data()[1], a.data()[2]);
        if (!std::isfinite(v.x + v.y + v.z)) throw py::value_error(std::string(name) + ": must be finite");
        return v;
    };
    const glm::dvec3 vs = vec(s, "s"), va = vec(axis, "axis"), vp = vec(p, "p"), vn = vec(n, "n");
    if (!(spot_size > 0.0 && spot_size <= kPi) || !(spot_blend >= 0.0 && spot_blend <= 1.0))
        throw py::value_error("spot_surface_glow_reference: spot_size in (0, pi], spot_blend in [0, 1]");
    if (!(sigma_t > 0.0 && std::isfinite(sigma_t))) throw py::value_error("spot_surface_glow_reference: sigma_t > 0");
    if (!(glm::length(va) > 0.0 && glm::length(vn) > 0.0 && glm::length(vs - vp) > 0.0))
        throw py::value_error("spot_surface_glow_reference: need a non-zero axis and normal, p != s");
    if (!(rel_tol > 0.0 && rel_tol < 1.0)) throw py::value_error("spot_surface_glow_reference: rel_tol in (0, 1)");
    py::gil_scoped_release release;
    return spot_surface_glow_reference(make_spot_cone(va, spot_size, spot_blend), vs, ph, sigma_t, vp,
                                       glm::normalize(vn), 1.0, rel_tol);
}

}  // namespace

void bind_surface(py::module_& m) {
    m.def("surface_G", &surface_G_py, "T"_a, "theta_s"_a, "m"_a = 1.0, "phase"_a = "isotropic", "g"_a = 0.0,
          "exact"_a = true, "nT"_a = 128, "ntheta"_a = 128,
          R"doc(G(T, theta_s, m) of the surface glow for any phase (biri06_surface.h): a point light of
unit intensity at distance D in fog of extinction beta (albedo 1) gives the irradiance
beta G(beta D, theta_s, m) / (2 pi D) weighted by a clamped cos^m lobe whose axis is theta_s
from the light (m = 1 about the normal: Lambert, Sun 2005 G0; m = n about the mirrored view
direction: Phong Gn). Isotropic: exactly Sun's G. exact=False: the bake's nT x ntheta table
(Sun's for the isotropic phase, the phase-aware one otherwise). Arrays broadcast; the GIL is
released.)doc");
    m.def("surface_H", &surface_H_py, "T"_a, "gamma"_a, "phase"_a = "isotropic", "g"_a = 0.0,
          R"doc(H_p(T, gamma) = 4 pi e^{-T cos gamma} int_{gamma/2}^{pi/2} p(cos 2 xi) e^{-T sin(gamma) tan xi} dxi:
sin(gamma) times the radiance arriving at a surface from the direction gamma off the light is
beta H_p / (2 pi D) (biri06_surface.h). Isotropic: Sun 2005's H.)doc");
    m.def("spot_glow_factor", &spot_glow_factor_py, "T"_a, "cos_psi"_a, "spot_size"_a, "spot_blend"_a,
          "phase"_a = "isotropic", "g"_a = 0.0,
          R"doc(The bake's spot glow factor (spot_surface.h, SpotGlowModel): a spot's glow on a surface
point at optical depth T from it, with cos_psi the cosine between the spot axis and the
direction light -> point, is this factor times the glow of a point light of the same I0.
Exact for a surface facing the light.)doc");
    m.def("spot_surface_glow_reference", &spot_reference_py, "s"_a, "axis"_a, "spot_size"_a, "spot_blend"_a, "p"_a,
          "n"_a, "sigma_t"_a, "phase"_a = "isotropic", "g"_a = 0.0, "rel_tol"_a = 1e-4,
          R"doc(Brute-force Lambert glow (irradiance, I0 = 1, albedo 1) at p with normal n from a spot at s
(Cycles profile about axis, spot_size, spot_blend) in fog sigma_t: incident directions by
composite Gauss-Legendre, the spot's single scattering along each by adaptive quadrature
(spot_surface.h). Compare with factor x sigma_t G / (2 pi D). Seconds.)doc");
    m.def("biri06_gamma_L", &gamma_L_py, "lam"_a, "phase"_a = "isotropic", "g"_a = 0.0, "exact"_a = true,
          R"doc(Biri 2006 eq. 11 Gamma_L(lambda) (exponent corrected: (cos(alpha - phi) + sin phi)/cos alpha;
p normalised to 1 over the sphere). Biri's Lambert glow (eq. 10, the unclamped cosine) is
beta 4 pi^2 cos(theta_s) Gamma_L(beta D) / (2 pi D) per unit intensity. exact=False: the
bake's 256-row table.)doc");
}

}  // namespace airlight::bindings
