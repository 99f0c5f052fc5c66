// spot_surface.cpp: spot-light glow on surfaces (see spot_surface.h).
#include "surface/spot_surface.h"
#include "core/constants.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <stdexcept>
#include <vector>

#include "core/quadrature.h"

namespace airlight {

namespace {

}  // namespace

double spot_glow_profile(const SpotCone& cone, const glm::dvec3& s, const glm::dvec3& p) {
    const glm::dvec3 v = p - s;
    const double D = glm::length(v);
    if (!(D > 0.0)) return 0.0;
    return spot_profile(cone, glm::dot(cone.axis, v) / D);
}

namespace {
constexpr double kTableTMax = 64.0;
double row_T(int i, int n) {
    const double x = double(i) / (n - 1);
    return i == n - 1 ? kTableTMax : std::expm1(x * x * std::log1p(kTableTMax));
}
}  // namespace

SpotGlowModel::SpotGlowModel(const SpotCone& cone, const PhaseFunction& phase, int nT, int npsi, int nrho)
    : cone_(cone), nT_(nT), npsi_(npsi), nrho_(nrho) {
    if (nT < 2 || npsi < 2 || nrho < 2) throw std::invalid_argument("SpotGlowModel: need at least 2 samples per axis");
    // rho by the midpoint rule (a(rho, psi) has kinks and, for a hard cone, steps where the
    // circle at rho meets the cone's edge: a smooth rule would not converge faster).
    std::vector<double> rho(static_cast<size_t>(nrho));
    for (int k = 0; k < nrho; ++k) rho[size_t(k)] = kPi * (k + 0.5) / nrho;
    // w_T(rho_k) by Gauss-Legendre in gamma over [0, min(pi/2, pi - rho)], normalised per row.
    std::vector<double> gx, gw;
    gauss_legendre(32, gx, gw);
    std::vector<double> w(size_t(nT) * nrho, 0.0);
    for (int i = 0; i < nT; ++i) {
        const double T = row_T(i, nT);
        double total = 0.0;
        for (int k = 0; k < nrho; ++k) {
            const double r = rho[size_t(k)], top = std::min(kHalfPi, kPi - r);
            double sum = 0.0;
            for (size_t q = 0; q < gx.size(); ++q) {
                const double g = 0.5 * top * (gx[q] + 1.0);
                const double e = T * std::sin(g) * (std::tan(0.5 * (g + r)) - std::tan(0.5 * g));
                sum += gw[q] * std::cos(g) * 4.0 * kPi * phase.eval(std::cos(g + r)) * std::exp(-e);
            }
            w[size_t(i) * nrho + k] = 0.5 * top * sum;
            total += w[size_t(i) * nrho + k];
        }
        for (int k = 0; k < nrho; ++k) w[size_t(i) * nrho + k] /= total > 0.0 ? total : 1.0;
    }
    // a(rho_k, psi_j): the profile averaged over the circle at angle rho around u_p, u_p at psi_j
    // from the axis: cos(angle to axis) = cos(psi) cos(rho) + sin(psi) sin(rho) cos(phi), phi in
    // [0, pi] by symmetry (midpoint rule); then A = sum_k w a per (T row, psi column).
    const int nphi = 128;
    std::vector<double> cos_phi(static_cast<size_t>(nphi));
    for (int q = 0; q < nphi; ++q) cos_phi[size_t(q)] = std::cos(kPi * (q + 0.5) / nphi);
    A_.assign(size_t(nT) * npsi, 0.0);
    std::vector<double> a(static_cast<size_t>(nrho));
    for (int j = 0; j < npsi; ++j) {
        const double psi = kPi * j / (npsi - 1), cp = std::cos(psi), sp = std::sin(psi);
        for (int k = 0; k < nrho; ++k) {
            const double cr = std::cos(rho[size_t(k)]), sr = std::sin(rho[size_t(k)]);
            double sum = 0.0;
            for (int q = 0; q < nphi; ++q) sum += spot_profile(cone, cp * cr + sp * sr * cos_phi[size_t(q)]);
            a[size_t(k)] = sum / nphi;
        }
        for (int i = 0; i < nT; ++i) {
            double sum = 0.0;
            for (int k = 0; k < nrho; ++k) sum += w[size_t(i) * nrho + k] * a[size_t(k)];
            A_[size_t(i) * npsi + j] = sum;
        }
    }
}

double SpotGlowModel::factor(double T, double cos_psi_p) const {
    const double fi = std::min(std::sqrt(std::log1p(std::max(T, 0.0)) / std::log1p(kTableTMax)), 1.0) * (nT_ - 1);
    const double fj = std::acos(std::clamp(cos_psi_p, -1.0, 1.0)) / kPi * (npsi_ - 1);
    const int i = std::min(int(fi), nT_ - 2), j = std::min(int(fj), npsi_ - 2);
    const double di = fi - i, dj = fj - j;
    const double* r0 = &A_[size_t(i) * npsi_ + j];
    const double* r1 = r0 + npsi_;
    return (1.0 - di) * ((1.0 - dj) * r0[0] + dj * r0[1]) + di * ((1.0 - dj) * r1[0] + dj * r1[1]);
}

double SpotGlowModel::factor(double T, const glm::dvec3& s, const glm::dvec3& p) const {
    const glm::dvec3 v = p - s;
    const double D = glm::length(v);
    if (!(D > 0.0)) return 0.0;
    return factor(T, glm::dot(cone_.axis, v) / D);
}

double spot_surface_glow_reference(const SpotCone& cone, const glm::dvec3& s, const PhaseFunction& phase,
                                   double beta, const glm::dvec3& p, const glm::dvec3& n, double m, double rel_tol) {
    // Frame about z = p -> s: incident direction w = sin(gamma) (cos(psi) x + sin(psi) y) + cos(gamma) z.
    const double D = glm::length(s - p);
    const glm::dvec3 z = (s - p) / D;
    const glm::dvec3 helper = std::abs(z.x) < 0.9 ? glm::dvec3(1, 0, 0) : glm::dvec3(0, 1, 0);
    const glm::dvec3 x = glm::normalize(glm::cross(helper, z)), y = glm::cross(z, x);
    const double nz = glm::dot(n, z), nx = glm::dot(n, x), ny = glm::dot(n, y);
    const double theta_s = std::acos(std::clamp(nz, -1.0, 1.0));
    const double psi_n = std::atan2(ny, nx);  // azimuth of the normal
    // Outer integrals by composite Gauss-Legendre (an adaptive rule over the adaptive inner
    // quadrature's rounding noise did not terminate in reasonable time): 12 nodes per panel.
    std::vector<double> gx, gw;
    gauss_legendre(12, gx, gw);
    auto composite = [&](const std::function<double(double)>& f, std::vector<double> cuts) {
        std::sort(cuts.begin(), cuts.end());
        double sum = 0.0;
        for (size_t k = 0; k + 1 < cuts.size(); ++k) {
            const double a = cuts[k], b = cuts[k + 1];
            if (!(b > a)) continue;
            for (size_t q = 0; q < gx.size(); ++q) sum += 0.5 * (b - a) * gw[q] * f(0.5 * (a + b) + 0.5 * (b - a) * gx[q]);
        }
        return sum;
    };
    auto over_psi = [&](double gamma) {
        const double cg = std::cos(gamma), sg = std::sin(gamma);
        const double a = cg * nz, b = sg * std::sqrt(nx * nx + ny * ny);
        if (a <= -b) return 0.0;
        auto f = [&](double psi) {
            const double ci = a + b * std::cos(psi - psi_n);
            if (ci <= 0.0) return 0.0;
            const glm::dvec3 w = sg * (std::cos(psi) * x + std::sin(psi) * y) + cg * z;
            const double L = spot_airlight_quadrature(cone, s, phase, beta, p, w,
                                                      std::numeric_limits<double>::infinity(), rel_tol);
            return L * std::pow(ci, m);
        };
        // The lit arc of the azimuth circle, 16 panels.
        const double half = a >= b ? kPi : std::acos(-a / b);
        std::vector<double> cuts;
        for (int k = 0; k <= 16; ++k) cuts.push_back(psi_n - half + 2.0 * half * k / 16.0);
        return composite(f, cuts);
    };
    auto integrand = [&](double gamma) { return std::sin(gamma) * over_psi(gamma); };
    const double edge = std::abs(kHalfPi - theta_s);
    std::vector<double> cuts{0.0, edge, kPi - edge, kPi};
    for (double c = 1e-4; c < 0.5; c *= 4.0) cuts.push_back(c);
    for (int k = 1; k < 12; ++k) cuts.push_back(kPi * k / 12.0);
    return composite(integrand, cuts);
}

}  // namespace airlight
