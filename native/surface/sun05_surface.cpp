// sun05_surface.cpp: G(T, theta_s, m) of Sun et al. 2005 eq. 16-18, exact and tabulated.
//
// Exact evaluator: adaptive Gauss-Kronrod over gamma with breakpoints where the hemisphere
// boundary crosses the azimuth circle (gamma = |pi/2 - theta_s|, pi - |pi/2 - theta_s|: W_m
// has kinks there) and a geometric ladder of cuts at gamma ~ 1/T (H falls from pi/2 at
// gamma = 0 to ~1/(T gamma) there); H itself by adaptive quadrature with cuts at its
// boundary layer xi - gamma/2 ~ 1/(2 T tan(gamma/2)).
//
// Table layout
//   rows    i over x = sqrt(log(1 + T) / log(1 + T_max)) in [0, 1], T_max = 64; the square
//           root resolves the T ln T behaviour at small T, the log the slow (~T^-0.7) decay
//           of e^T G at large T (with x = sqrt(T / (T + 1)) the last rows spanned T = 27..64
//           and the error was 2 %)
//   columns j over theta_s uniform in [0, pi]
//   stored  Q = e^{T} G(T, theta_s, m), O(1) (e^T G(64, 0, 1) = 0.36)
//   lookup  bilinear in (x, theta_s); beyond T_max the tail grid (sun05_surface.h: the
//           large-T asymptotics T e^T G = c ln T + B(theta) tabulated to T = 1e8).
//   build   per row, one Gauss-Legendre rule (8 nodes per panel) over panels whose ends are
//           the kinks of W_m(., theta_j) of every column (they all lie on the grid gamma =
//           (2k + 1) pi / (2 (ntheta - 1))) plus cuts at the 1/T layer, so H is evaluated once
//           per node for the whole row; nodes agree with the exact evaluator to ~1e-7.
// MEASURED (sun05_surface_test.cpp asserts these bounds; relative error vs the exact
// evaluator over 300 random points, T log-uniform in [1e-3, 60] plus T = 0, theta_s uniform
// in [0, pi] where G > 1e-6 G(T, 0)):
//     m = 1,  128 x 128 (the bake's): max 3.1e-3, mean 1.1e-4 (build 3-5 s on 2 busy cores,
//                                      benchmarks/bench_surface.py; once per process)
//     m = 1,   96 x 64:               max 1.3e-2, mean 3.6e-4 (build ~2 s)
//     m = 20,  64 x 64:               max 1.4e-2, mean 1.2e-3
//   The worst case sits at theta_s just below pi/2 and T ~ 16: at large T the glow comes
//   from a cone ~1/T wide around the light, so G bends sharply where that cone crosses the
//   horizon.
// The exact evaluator agrees with the brute-force single-scattering integral
// (sun05_surface_glow_reference) to ~1e-11.
#include "surface/sun05_surface.h"
#include "core/table_cache.h"
#include "core/build_progress.h"
#include "core/parallel.h"
#include "core/constants.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <thread>

#include "surface/biri06_surface.h"
#include "core/quadrature.h"

namespace airlight {

namespace {


void require_args(double T, double theta_s, double m) {
    if (!(T >= 0.0) || !(theta_s >= 0.0 && theta_s <= kPi + 1e-12) || !(m >= 1.0) || std::isinf(m))
        throw std::invalid_argument("sun05_surface_G: need T >= 0, theta_s in [0, pi], finite m >= 1 (got T = " +
                                    std::to_string(T) + ", theta_s = " + std::to_string(theta_s) +
                                    ", m = " + std::to_string(m) + ")");
}

}  // namespace

double sun05_surface_H_scaled(double T, double gamma) {
    const double width = kHalfPi - 0.5 * gamma;  // eta = xi - gamma/2 in [0, width]
    if (!(width > 0.0)) return 0.0;
    if (T == 0.0) return width;
    const double k = 2.0 * T * std::sin(0.5 * gamma);
    if (k == 0.0) return width;
    const double half = 0.5 * gamma;
    auto f = [=](double eta) {
        const double c = std::cos(eta + half);
        if (c <= 0.0) return 0.0;
        return std::exp(-k * std::sin(eta) / c);
    };
    // Boundary layer at eta ~ cos(gamma/2) / k: cuts there and geometrically beyond.
    std::vector<double> cuts;
    for (double cut = std::cos(half) / k; cut < width; cut *= 8.0) cuts.push_back(cut);
    return integrate_cut(f, 0.0, width, cuts, 1e-10);
}

double sun05_surface_W(double gamma, double theta_s, double m) {
    const double a = std::cos(gamma) * std::cos(theta_s);
    const double b = std::abs(std::sin(gamma) * std::sin(theta_s));
    if (a >= b) {
        if (m == 1.0) return 2.0 * kPi * a;
        if (b == 0.0) return 2.0 * kPi * std::pow(a, m);
        return 2.0 * integrate_adaptive([=](double psi) { return std::pow(a + b * std::cos(psi), m); }, 0.0, kPi,
                                        1e-12, 0.0, 40);
    }
    if (a <= -b) return 0.0;
    const double psi0 = std::acos(-a / b);  // cos(theta_i) = 0 there
    if (m == 1.0) return 2.0 * (a * psi0 + b * std::sin(psi0));
    return 2.0 * integrate_adaptive(
                     [=](double psi) {
                         const double c = a + b * std::cos(psi);
                         return c > 0.0 ? std::pow(c, m) : 0.0;
                     },
                     0.0, psi0, 1e-12, 0.0, 40);
}

double sun05_surface_G_scaled_exact(double T, double theta_s, double m) {
    require_args(T, theta_s, m);
    theta_s = std::min(theta_s, kPi);
    auto f = [=](double gamma) { return sun05_surface_H_scaled(T, gamma) * sun05_surface_W(gamma, theta_s, m); };
    const double edge = std::abs(kHalfPi - theta_s);
    std::vector<double> cuts{edge, kPi - edge};
    if (T > 1.0)
        for (double cut = 1.0 / T; cut < kPi; cut *= 4.0) cuts.push_back(cut);
    return integrate_cut(f, 0.0, kPi, cuts, 1e-10);
}

double sun05_surface_G_exact(double T, double theta_s, double m) {
    const double scaled = sun05_surface_G_scaled_exact(T, theta_s, m);
    return scaled == 0.0 ? 0.0 : scaled * std::exp(-T);
}

namespace {

// W_m by a fixed Gauss-Legendre rule in the azimuth (table build; smooth integrand on
// [0, psi0], vanishing there like (psi0 - psi)^m).
double W_fixed(double gamma, double theta_s, double m, const std::vector<double>& x, const std::vector<double>& w) {
    if (m == 1.0) return sun05_surface_W(gamma, theta_s, m);
    const double a = std::cos(gamma) * std::cos(theta_s);
    const double b = std::abs(std::sin(gamma) * std::sin(theta_s));
    if (a <= -b) return 0.0;
    const double psi0 = a >= b ? kPi : std::acos(-a / b);
    double sum = 0.0;
    for (size_t k = 0; k < x.size(); ++k) {
        const double c = a + b * std::cos(0.5 * psi0 * (x[k] + 1.0));
        if (c > 0.0) sum += w[k] * std::pow(c, m);
    }
    return psi0 * sum;  // 2 * (psi0 / 2) * sum
}

}  // namespace

SurfaceGGrid::SurfaceGGrid(int nT, int ntheta, double m, int threads,
                           const std::function<void(double, std::vector<double>&)>& row_cuts,
                           const std::function<double(double, double)>& H_scaled, double forward_weight,
                           const std::string& cache_key)
    : nT_(nT), ntheta_(ntheta), m_(m), forward_weight_(forward_weight), threads_(threads), row_cuts_(row_cuts),
      H_scaled_(H_scaled), cache_key_(cache_key) {
    if (nT < 2 || ntheta < 2) throw std::invalid_argument("surface G table: need at least 2 x 2 samples");
    data_.assign(size_t(nT) * size_t(ntheta), 0.0);
    auto build = [&] {
        parallel_for(nT, resolve_threads(threads), [&](int i) {
            integrate_row(row_T(i, nT), &data_[size_t(i) * ntheta]);
            build_progress_check();  // progress and cancel of the bake building it
        });
    };
    if (cache_key_.empty()) build();
    else load_or_build(grid_key("body"), data_, build);
}

std::string SurfaceGGrid::grid_key(const char* part) const {
    return cache_key_ + " " + part + " nT=" + std::to_string(nT_) + " ntheta=" + std::to_string(ntheta_) +
           " m=" + key_number(m_) + " fw=" + key_number(forward_weight_);
}

void SurfaceGGrid::integrate_row(double T, double* out) const {
    // The kinks of W_m(., theta_j) for every column theta_j = pi j / (ntheta - 1) lie on the
    // grid gamma = (2 k + 1) pi / (2 (ntheta - 1)): panels between them (plus the row's cuts)
    // with 8 Gauss-Legendre nodes each integrate every column, and H is evaluated once per
    // node for the whole row.
    static const std::vector<double> glx = [] { std::vector<double> x, w; gauss_legendre(8, x, w); return x; }();
    static const std::vector<double> glw = [] { std::vector<double> x, w; gauss_legendre(8, x, w); return w; }();
    static const std::vector<double> psx = [] { std::vector<double> x, w; gauss_legendre(48, x, w); return x; }();
    static const std::vector<double> psw = [] { std::vector<double> x, w; gauss_legendre(48, x, w); return w; }();
    const int ntheta = ntheta_;
    std::vector<double> cuts{0.0, kPi};
    for (int k = 0; k < ntheta - 1; ++k) cuts.push_back((2 * k + 1) * kPi / (2.0 * (ntheta - 1)));
    row_cuts_(T, cuts);
    std::sort(cuts.begin(), cuts.end());
    std::vector<double> nodes, weights, H;
    for (size_t k = 0; k + 1 < cuts.size(); ++k) {
        const double a = cuts[k], b = cuts[k + 1];
        if (!(b > a)) continue;
        for (size_t q = 0; q < glx.size(); ++q) {
            const double g = 0.5 * (a + b) + 0.5 * (b - a) * glx[q];
            nodes.push_back(g);
            weights.push_back(0.5 * (b - a) * glw[q]);
            H.push_back(H_scaled_(T, g));
        }
    }
    for (int j = 0; j < ntheta; ++j) {
        const double theta = kPi * j / (ntheta - 1);
        double sum = 0.0;
        for (size_t q = 0; q < nodes.size(); ++q) sum += weights[q] * H[q] * W_fixed(nodes[q], theta, m_, psx, psw);
        out[j] = sum;
    }
}

double SurfaceGGrid::row_T(int i, int nT) {
    const double x = double(i) / (nT - 1);
    return i == nT - 1 ? kTMax : std::expm1(x * x * std::log1p(kTMax));
}

double SurfaceGGrid::row_position(double T, int nT) {
    return std::min(std::sqrt(std::log1p(T) / std::log1p(kTMax)), 1.0) * (nT - 1);
}

namespace {

// Row i of the tail: T = kTMax (kTTail / kTMax)^(i / (rows - 1)).
double tail_row_T(int i) {
    const double u = double(i) / (SurfaceGGrid::kTailRows - 1);
    return i == SurfaceGGrid::kTailRows - 1 ? SurfaceGGrid::kTTail
                                             : SurfaceGGrid::kTMax * std::pow(SurfaceGGrid::kTTail / SurfaceGGrid::kTMax, u);
}

// The tail's log coefficient c(theta) = forward_weight W_m(0, theta) = forward_weight 2 pi cos+^m.
double tail_log_coefficient(double forward_weight, double theta, double m) {
    const double c = std::cos(theta);
    return c > 0.0 ? forward_weight * 2.0 * kPi * std::pow(c, m) : 0.0;
}

}  // namespace

void SurfaceGGrid::build_tail() const {
    const int rows = kTailRows, ntheta = ntheta_;
    tail_.assign(size_t(rows) * size_t(ntheta), 0.0);
    auto build = [&] {
        parallel_for(rows, resolve_threads(threads_), [&](int i) {
            const double T = tail_row_T(i);
            double* q = &tail_[size_t(i) * ntheta];
            integrate_row(T, q);
            for (int j = 0; j < ntheta; ++j)
                q[j] = T * q[j] - tail_log_coefficient(forward_weight_, kPi * j / (ntheta - 1), m_) * std::log(T);
        });
    };
    if (cache_key_.empty()) build();
    else load_or_build(grid_key("tail"), tail_, build);
}

double SurfaceGGrid::lookup(double T, double theta_s) const {
    return T > kTMax ? lookup_tail(T, theta_s) : lookup_body(T, theta_s);
}

double SurfaceGGrid::lookup_body(double T, double theta_s) const {
    const double fi = row_position(T, nT_);
    const double fj = std::min(theta_s / kPi, 1.0) * (ntheta_ - 1);
    const int i = std::min(int(fi), nT_ - 2), j = std::min(int(fj), ntheta_ - 2);
    const double di = fi - i, dj = fj - j;
    const double* r0 = &data_[size_t(i) * ntheta_ + j];
    const double* r1 = r0 + ntheta_;
    return (1.0 - di) * ((1.0 - dj) * r0[0] + dj * r0[1]) + di * ((1.0 - dj) * r1[0] + dj * r1[1]);
}

double SurfaceGGrid::lookup_tail(double T, double theta_s) const {
    if (std::isinf(T)) return 0.0;  // ~ ln T / T
    std::call_once(tail_once_, [this] { build_tail(); });
    const double lnT = std::log(T);
    const double fi = std::clamp((lnT - std::log(kTMax)) / std::log(kTTail / kTMax), 0.0, 1.0) * (kTailRows - 1);
    const double theta = std::min(theta_s, kPi);
    const double fj = theta / kPi * (ntheta_ - 1);
    const int i = std::min(int(fi), kTailRows - 2), j = std::min(int(fj), ntheta_ - 2);
    const double di = fi - i, dj = fj - j;
    const double* r0 = &tail_[size_t(i) * ntheta_ + j];
    const double* r1 = r0 + ntheta_;
    const double Q = (1.0 - di) * ((1.0 - dj) * r0[0] + dj * r0[1]) + di * ((1.0 - dj) * r1[0] + dj * r1[1]);
    return std::max(0.0, (Q + tail_log_coefficient(forward_weight_, theta, m_) * lnT) / T);
}

namespace {
void check_table_exponent(double m) { require_args(0.0, 0.0, m); }
}  // namespace

SurfaceGTable::SurfaceGTable(double m, int nT, int ntheta, int threads)
    : m_((check_table_exponent(m), m)),
      grid_(nT, ntheta, m, threads,
            [](double T, std::vector<double>& cuts) {
                // The 1/T layer of H near gamma = 0.
                if (T > 1.0)
                    for (double c = 0.0625 / T; c < 0.5; c *= 2.0) cuts.push_back(c);
            },
            [](double T, double gamma) { return sun05_surface_H_scaled(T, gamma); }, 1.0, "surface_G v1 sun05") {}

double SurfaceGTable::eval(double T, double theta_s) const {
    const double scaled = eval_scaled(T, theta_s);
    return scaled == 0.0 ? 0.0 : scaled * std::exp(-T);
}

double SurfaceGTable::eval_scaled(double T, double theta_s) const {
    if (!(T >= 0.0) || !(theta_s >= 0.0)) require_args(T, theta_s, m_);
    return grid_.lookup(T, theta_s);
}

double sun05_surface_glow_reference(double beta, double D, double theta_s, double m, double rel_tol) {
    // The brute-force reference for any phase function (biri06_surface.h: the line integral
    // to infinity along each incident direction, the azimuth numerically), isotropic here.
    return biri06_surface_glow_reference(PhaseFunction{}, beta, D, theta_s, m, rel_tol);
}

}  // namespace airlight
