// biri06_surface.cpp: G_p(T, theta_s, m) for any phase function, Biri's Lambert Gamma_L, and
// the brute-force reference (see biri06_surface.h).
//
// H_p in the variable eta = xi - gamma/2 in [0, pi/2 - gamma/2] as sun05_surface.cpp does
// (exponent -2 T sin(gamma/2) sin(eta) / cos(eta + gamma/2) after the e^{T} scaling, no
// cancellation), the phase angle theta = 2 eta + gamma; breakpoints at the exponent's
// boundary layer and, for peaked phases (lobe width w = PhaseFunction::lobe_width() < 1), on
// geometric ladders where theta is w/4, w, 4 w, ... from the forward (theta = 0) and backward
// (theta = pi) peaks. The gamma integrals add the same ladders in gamma: H_p changes on the
// scale w near gamma = 0 (the forward lobe looks at the light) and near gamma = pi (the
// backward lobe is all that is left of [gamma, pi]).
//
// Table: the layout of SurfaceGTable (sun05_surface.cpp): rows over x = sqrt(log(1 + T) /
// log(1 + 64)), columns theta_s uniform in [0, pi], stored e^{T} G_p, bilinear; built per row
// with 8 Gauss-Legendre nodes per panel between the kinks of W_m of every column plus the 1/T
// and phase-lobe cuts, H_p evaluated once per node for the whole row.
// MEASURED (biri06_surface_test.cpp TableError prints these and asserts max < 3e-2 / 6e-2, mean
// < 2e-3 / 5e-3; relative error vs the exact evaluator over 80 random points, T log-uniform in
// [1e-3, 60] plus T = 0, theta_s uniform in [0, pi] where G_p > 1e-6 G_p(T, 0)):
//                      m = 1, 128 x 128 (max / mean)   m = 20, 64 x 64 (max / mean)
//     HG g = +0.6      1.2e-3 / 1.4e-4                  9.1e-3 / 1.6e-3
//     HG g = -0.6      4.3e-4 / 1.2e-4                  1.2e-2 / 1.5e-3
//     HG g = +0.9      1.0e-2 / 4.1e-4                  2.3e-2 / 3.1e-3
//     HG g = -0.9      8.8e-4 / 2.8e-4                  2.0e-2 / 3.3e-3
//     Rayleigh         4.2e-4 / 8.0e-5                  (6.9e-3 / 1.2e-3 at 150 points)
//     hazy Mie         6.1e-4 / 9.8e-5                  (8.2e-3 / 1.5e-3)
//     murky Mie        1.3e-3 / 1.2e-4                  (1.9e-2 / 2.1e-3)
//   (isotropic: Sun's table, 3.1e-3 / 1.1e-4.) Build, 2 threads on the shared 2-core machine
//   (benchmarks/bench_surface_phase.py): 1.3-2.5 s per 128 x 128 table (Sun's isotropic one
//   1.2 s in the same run), 2.0-2.4 s per 64 x 64 Phong table, 0.5-1.4 s per Gamma_L table;
//   each once per process and (phase, g, m). The worst case, HG g = 0.9, sits where the ~(1 - g)
//   wide forward lobe crosses the horizon (theta_s ~ pi/2), as Sun's table does at T ~ 16.
//   Gamma_L table (256 rows, linear): max 2.3e-4 relative (HG g = -0.9), <= 3e-5 otherwise.
#include "surface/biri06_surface.h"
#include "core/table_cache.h"
#include "core/parallel.h"
#include "core/constants.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <map>
#include <mutex>
#include <stdexcept>
#include <string>
#include <thread>
#include <tuple>

#include "core/quadrature.h"
#include "surface/sun05_surface.h"

namespace airlight {

namespace {

constexpr double kTableTMax = 64.0;

void require_args(double T, double theta_s, double m) {
    if (!(T >= 0.0) || !(theta_s >= 0.0 && theta_s <= kPi + 1e-12) || !(m >= 1.0) || std::isinf(m))
        throw std::invalid_argument("biri06_surface_G: need T >= 0, theta_s in [0, pi], finite m >= 1 (got T = " +
                                    std::to_string(T) + ", theta_s = " + std::to_string(theta_s) +
                                    ", m = " + std::to_string(m) + ")");
}

// Geometric ladder c0, 2 c0, 4 c0, ... below _end_ (none for smooth phases).
std::vector<double> lobe_ladder(const PhaseFunction& phase, double scale, double end, double factor = 2.0) {
    std::vector<double> out;
    const double w = phase.lobe_width();
    if (w >= 1.0 || phase.kind == PhaseKind::Isotropic) return out;
    for (double c = w * scale; c < end; c *= factor) out.push_back(c);
    return out;
}

// The gamma breakpoints shared by every G_p integral: hemisphere kinks of W_m (edge), the 1/T
// layer of H near gamma = 0, and the phase-lobe ladders at both ends.
std::vector<double> gamma_cuts(const PhaseFunction& phase, double T, double theta_s) {
    const double edge = std::abs(kHalfPi - theta_s);
    std::vector<double> cuts{edge, kPi - edge};
    if (T > 1.0)
        for (double cut = 1.0 / T; cut < kPi; cut *= 4.0) cuts.push_back(cut);
    for (double c : lobe_ladder(phase, 0.25, kHalfPi)) {
        cuts.push_back(c);
        cuts.push_back(kPi - c);
    }
    return cuts;
}

// Panel ends of a table row at _T_ (besides the table's own): the 1/T layer of H near gamma = 0
// and the phase-lobe ladders at both ends.
void add_row_cuts(const PhaseFunction& phase, double T, std::vector<double>& cuts) {
    if (T > 1.0)
        for (double c = 0.0625 / T; c < 0.5; c *= 2.0) cuts.push_back(c);
    for (double c : lobe_ladder(phase, 0.125, 0.5)) {
        cuts.push_back(c);
        cuts.push_back(kPi - c);
    }
}

double H_scaled(const PhaseFunction& phase, double T, double gamma, double rel_tol);

}  // namespace

double biri06_surface_H_scaled(const PhaseFunction& phase, double T, double gamma) {
    return H_scaled(phase, T, gamma, 1e-10);
}

namespace {

double H_scaled(const PhaseFunction& phase, double T, double gamma, double rel_tol) {
    const double width = kHalfPi - 0.5 * gamma;  // eta = xi - gamma/2 in [0, width]
    if (!(width > 0.0)) return 0.0;
    const double half = 0.5 * gamma;
    const double k = 2.0 * T * std::sin(half);
    const double four_pi = 4.0 * kPi;
    auto f = [=, &phase](double eta) {
        const double weight = four_pi * phase.eval(std::cos(2.0 * eta + gamma));
        if (k == 0.0) return weight;
        const double c = std::cos(eta + half);
        if (c <= 0.0) return 0.0;
        return weight * std::exp(-k * std::sin(eta) / c);
    };
    std::vector<double> cuts;
    if (k > 0.0)
        for (double cut = std::cos(half) / k; cut < width; cut *= 8.0) cuts.push_back(cut);
    // Phase lobes: theta = 2 eta + gamma at w/4, w, 4 w, ... from 0 and from pi.
    for (double c : lobe_ladder(phase, 0.25, kPi, 4.0)) {
        const double fwd = 0.5 * (c - gamma), back = width - 0.5 * c;
        if (fwd > 0.0 && fwd < width) cuts.push_back(fwd);
        if (back > 0.0 && back < width) cuts.push_back(back);
    }
    return integrate_cut(f, 0.0, width, cuts, rel_tol);
}

// Table nodes: H_p to 1e-8 (the tables' own error is >= 1e-5; halves the build time).
constexpr double kTableHTol = 1e-6;

}  // namespace

double biri06_surface_G_scaled_exact(const PhaseFunction& phase, double T, double theta_s, double m) {
    require_args(T, theta_s, m);
    theta_s = std::min(theta_s, kPi);
    auto f = [&](double gamma) {
        const double W = sun05_surface_W(gamma, theta_s, m);
        return W == 0.0 ? 0.0 : biri06_surface_H_scaled(phase, T, gamma) * W;
    };
    return integrate_cut(f, 0.0, kPi, gamma_cuts(phase, T, theta_s), 1e-9);
}

double biri06_surface_G_exact(const PhaseFunction& phase, double T, double theta_s, double m) {
    const double scaled = biri06_surface_G_scaled_exact(phase, T, theta_s, m);
    return scaled == 0.0 ? 0.0 : scaled * std::exp(-T);
}

PhaseSurfaceGTable::PhaseSurfaceGTable(const PhaseFunction& phase, double m, int nT, int ntheta, int threads)
    : phase_(phase),
      m_((require_args(0.0, 0.0, m), m)),
      grid_(nT, ntheta, m, threads,
            // The 1/T layer of H near gamma = 0 and the phase lobes.
            [this](double T, std::vector<double>& cuts) { add_row_cuts(phase_, T, cuts); },
            [this](double T, double gamma) { return H_scaled(phase_, T, gamma, kTableHTol); },
            4.0 * kPi * phase.eval(1.0),
            "surface_G v1 phase=" + std::to_string(int(phase.kind)) + " g=" + key_number(phase.g)) {}

double PhaseSurfaceGTable::eval(double T, double theta_s) const {
    const double scaled = eval_scaled(T, theta_s);
    return scaled == 0.0 ? 0.0 : scaled * std::exp(-T);
}

double PhaseSurfaceGTable::eval_scaled(double T, double theta_s) const {
    if (!(T >= 0.0) || !(theta_s >= 0.0)) require_args(T, theta_s, m_);
    return grid_.lookup(T, theta_s);  // beyond T = 64 the grid's tail (sun05_surface.h)
}

std::shared_ptr<const PhaseSurfaceGTable> shared_phase_surface_G_table(const PhaseFunction& phase, int nT, int ntheta,
                                                                       double m) {
    static std::mutex mutex;
    static std::map<std::tuple<int, double, int, int, double>, std::shared_ptr<const PhaseSurfaceGTable>> cache;
    std::lock_guard<std::mutex> lock(mutex);
    const double g = phase.kind == PhaseKind::HenyeyGreenstein ? phase.g : 0.0;
    auto& slot = cache[{int(phase.kind), g, nT, ntheta, m}];
    if (!slot) slot = std::make_shared<const PhaseSurfaceGTable>(phase, m, nT, ntheta, 0);
    return slot;
}

double biri06_Gamma_L_paper(const PhaseFunction& phase, double lambda) {
    if (!(lambda >= 0.0) || std::isinf(lambda))
        throw std::invalid_argument("biri06_Gamma_L: lambda must be finite and >= 0, got " + std::to_string(lambda));
    // Eq. 11 as printed (exponent corrected, see the header), p(alpha + pi/2) = p(cos(alpha + pi/2)).
    auto inner = [&](double phi) {
        const double sphi = std::sin(phi);
        auto g = [&](double alpha) {
            const double ca = std::cos(alpha);
            const double weight = phase.eval(std::cos(alpha + kHalfPi));
            if (lambda == 0.0) return weight;
            if (ca <= 0.0) return 0.0;
            return weight * std::exp(-lambda * (std::cos(alpha - phi) + sphi) / ca);
        };
        std::vector<double> cuts;
        for (double c : lobe_ladder(phase, 0.125, kPi)) {  // theta = alpha + pi/2 near 0 and pi
            cuts.push_back(c - kHalfPi);
            cuts.push_back(kHalfPi - c);
        }
        return std::cos(phi) * integrate_cut(g, phi - kHalfPi, kHalfPi, cuts, 1e-11);
    };
    std::vector<double> cuts{kHalfPi};
    for (double c : lobe_ladder(phase, 0.25, kHalfPi)) {
        cuts.push_back(c);
        cuts.push_back(kPi - c);
    }
    if (lambda > 1.0)
        for (double c = 1.0 / lambda; c < kPi; c *= 4.0) cuts.push_back(c);
    return integrate_cut(inner, 0.0, kPi, cuts, 1e-9);
}

double biri06_Gamma_L_scaled_exact(const PhaseFunction& phase, double lambda) {
    if (!(lambda >= 0.0) || std::isinf(lambda))
        throw std::invalid_argument("biri06_Gamma_L: lambda must be finite and >= 0, got " + std::to_string(lambda));
    // int_0^pi H_p cos(gamma) dgamma = 2 pi Gamma_L (sin(gamma) L = beta H_p / (2 pi D) and
    // Gamma_L's inner integral is (h / beta) e^{T cos gamma} L).
    auto f = [&](double gamma) { return biri06_surface_H_scaled(phase, lambda, gamma) * std::cos(gamma); };
    return integrate_cut(f, 0.0, kPi, gamma_cuts(phase, lambda, 0.0), 1e-10) / (2.0 * kPi);
}

Biri06LambertTable::Biri06LambertTable(const PhaseFunction& phase, int n) : phase_(phase), n_(n) {
    if (n < 2) throw std::invalid_argument("Biri06LambertTable: need at least 2 samples");
    data_.resize(size_t(n));
    // Per row, a Gauss-Legendre rule (8 nodes per panel) over 48 uniform panels in gamma plus the
    // 1/T and phase-lobe cuts of the G tables (the exact evaluator costs ~15-40 ms a row).
    std::vector<double> glx, glw;
    gauss_legendre(8, glx, glw);
    const int n_threads = std::min(resolve_threads(0), n);
    auto work = [&](int first) {
        for (int i = first; i < n; i += n_threads) {
            const double T = SurfaceGGrid::row_T(i, n);
            std::vector<double> cuts;
            for (int k = 0; k <= 48; ++k) cuts.push_back(kPi * k / 48.0);
            add_row_cuts(phase_, T, cuts);
            std::sort(cuts.begin(), cuts.end());
            double sum = 0.0;
            for (size_t k = 0; k + 1 < cuts.size(); ++k) {
                const double a = std::max(0.0, cuts[k]), b = std::min(kPi, cuts[k + 1]);
                if (!(b > a)) continue;
                for (size_t q = 0; q < glx.size(); ++q) {
                    const double g = 0.5 * (a + b) + 0.5 * (b - a) * glx[q];
                    sum += 0.5 * (b - a) * glw[q] * H_scaled(phase_, T, g, kTableHTol) * std::cos(g);
                }
            }
            data_[size_t(i)] = sum / (2.0 * kPi);
        }
    };
    parallel_for(n_threads, n_threads, work);  // one stripe of rows per item
}

double Biri06LambertTable::eval_scaled(double lambda) const {
    if (!(lambda >= 0.0)) throw std::invalid_argument("Biri06LambertTable: lambda must be >= 0");
    if (lambda > kTableTMax) return biri06_Gamma_L_scaled_exact(phase_, lambda);
    const double f = SurfaceGGrid::row_position(lambda, n_);
    const int i = std::min(int(f), n_ - 2);
    const double d = f - i;
    return (1.0 - d) * data_[size_t(i)] + d * data_[size_t(i) + 1];
}

double Biri06LambertTable::eval_G_scaled(double T, double cos_theta_s) const {
    return 4.0 * kPi * kPi * cos_theta_s * eval_scaled(T);
}

std::shared_ptr<const Biri06LambertTable> shared_biri06_lambert_table(const PhaseFunction& phase, int n) {
    static std::mutex mutex;
    static std::map<std::tuple<int, double, int>, std::shared_ptr<const Biri06LambertTable>> cache;
    std::lock_guard<std::mutex> lock(mutex);
    const double g = phase.kind == PhaseKind::HenyeyGreenstein ? phase.g : 0.0;
    auto& slot = cache[{int(phase.kind), g, n}];
    if (!slot) slot = std::make_shared<const Biri06LambertTable>(phase, n);
    return slot;
}

double biri06_surface_glow_reference(const PhaseFunction& phase, double beta, double D, double theta_s, double m,
                                     double rel_tol) {
    // Radiance arriving along an incident direction at angle gamma from the light: the
    // single-scattering line integral to infinity with the phase of the actual geometry.
    auto L = [&](double gamma) {
        const double cg = std::cos(gamma), sg = std::sin(gamma);
        auto f = [&](double t) {
            const double r2 = (t - D * cg) * (t - D * cg) + D * sg * D * sg;
            const double r = std::sqrt(r2);
            const double cos_theta = (D * cg - t) / r;  // (x - s)/r . (-w)
            return beta * phase.eval(cos_theta) * std::exp(-beta * (r + t)) / r2;
        };
        const double tc = std::max(0.0, D * cg), w = std::max(D * sg, 1e-300);
        std::vector<double> cuts{tc};
        for (double s = w; s < 64.0 * D; s *= 4.0) {
            cuts.push_back(tc + s);
            if (tc - s > 0.0) cuts.push_back(tc - s);
        }
        const double last = tc + 64.0 * D;
        cuts.push_back(last);
        return integrate_cut(f, 0.0, last, cuts, rel_tol * 1e-3) + integrate_adaptive(f, last, INFINITY, rel_tol * 1e-3);
    };
    // Azimuth about the light direction: cos(theta_i)^m over the hemisphere, numerically.
    auto azimuth = [=](double gamma) {
        const double a = std::cos(gamma) * std::cos(theta_s), b = std::sin(gamma) * std::sin(theta_s);
        auto g = [=](double psi) {
            const double c = a + b * std::cos(psi);
            return c > 0.0 ? std::pow(c, m) : 0.0;
        };
        std::vector<double> cuts;
        if (std::abs(b) > std::abs(a)) cuts.push_back(std::acos(-a / b));
        return 2.0 * integrate_cut(g, 0.0, kPi, cuts, rel_tol * 1e-3);
    };
    auto integrand = [&](double gamma) {
        const double az = azimuth(gamma);
        return az == 0.0 ? 0.0 : std::sin(gamma) * L(gamma) * az;
    };
    const double edge = std::abs(kHalfPi - theta_s);
    std::vector<double> cuts{edge, kPi - edge};
    for (double c = 1e-6; c < 0.5; c *= 4.0) cuts.push_back(c);
    for (double c : lobe_ladder(phase, 0.25, kHalfPi)) {
        cuts.push_back(c);
        cuts.push_back(kPi - c);
    }
    return integrate_cut(integrand, 0.0, kPi, cuts, rel_tol);
}

}  // namespace airlight
