// biri06.cpp: Biri et al. 2006 airlight for any phase function (derivation in biri06.h).
//
// Table layout (one per phase function; HG one per g)
//   rows    i over s = sqrt(lambda / (lambda + k)) in [0, 1] (s = 1 is lambda = inf), as
//           special_f.cpp (the square root resolves the lambda ln lambda term at small lambda);
//   columns j over w = tau / (1 + tau), tau = T (K + lambda) in [0, 1] (w = 1 is T = inf);
//           K stretches the forward lobe of a peaked phase function over the first columns
//           (HG g > 0: K = 1 / (1 - g); murky Mie: K = 4) or its backward lobe over the last
//           ones (HG g < 0: K = 1 - |g|); lambda follows the 1/lambda extinction layer;
//           k = max(K, 1) puts the lambda ~ K transition mid-table;
//   stored  Q = G (K + lambda) / w: Q = 2 p(1) at w = 0 (G ~ 2 p(1) T) and
//           Q = 2 p(1) (1 - e^{-tau}) / w on the lambda = inf row (G ~ 2 p(1)(1 - e^{-lambda T})
//           / lambda): O(1), smooth, and proportional to G, so bilinear error is relative.
//   build   per row, G accumulated over the column cells by adaptive GK15 (exact per cell).
//   lookup  G = Q(s, w) w / (K + lambda): one sqrt, three divisions.
//
// MEASURED (biri06_test prints these; 4000 random points per phase, lambda log-uniform in
// [1e-4, 1e4] (5 % zero), T log-uniform in [1e-5, 1e5] (5 % inf); relative error of the
// 256 x 256 bilinear table G against the exact G):
//     phase            mean      p99       max
//     isotropic        8.5e-6    1.6e-4    2.6e-4
//     rayleigh         1.8e-5    2.1e-4    3.4e-4
//     hazy_mie         3.4e-5    2.4e-4    2.5e-4
//     murky_mie        1.3e-5    8.9e-5    1.6e-4
//     hg g = -0.9      2.4e-5    3.2e-4    8.9e-4
//     hg g = 0.5       1.5e-5    9.0e-5    9.3e-5
//     hg g = 0.9       2.3e-5    1.6e-4    1.6e-4
//     hg g = 0.99      1.4e-5    1.6e-4    1.8e-4
//     hg g = -0.99     2.2e-4    4.2e-3    6.1e-3   (backward lobe squeezed into 1 - w ~ 1e-2)
//     hg g = 0.999     3.6e-6    2.4e-5    5.0e-5   (1000 points; Biri06.SharpLobeTables...)
//     hg g = 0.9999    2.6e-6    1.1e-5    1.2e-5
//     hg g = -0.999    3.0e-3    8.8e-2    1.5e-1   (refused: g < kBiri06MinG = -0.99)
// The build evaluates the phase from the half angle (phase.h eval_half_angle): from cos theta
// a lobe with |g| >= 0.998 was too noisy for its 1e-12 quadrature, which then never finished.
// Airlight table path vs the quadrature reference (400 rays, Tsv in [1e-3, 3], all gamma,
// 10 % Dvp = inf): max 7.5e-4 (isotropic, rayleigh), <= 4e-4 for the others.
// COST (2-core dev box): 1.56 us per table-path evaluation on that sweep, because 50 % of its
// rays take the exact fallback (3.7 us): light behind the viewer or far off the ray with
// large lambda, where G1 - G0 < G1/16. With kCancel = 1/256 the fallback drops to 7.5 % and
// the cost to 274 ns, but the max error rises to 1.3e-2 (mean 1e-4). Known gap: a second,
// complementary table of the scaled tail e^{lambda T} int_T^inf would remove that fallback.
// Table build: ~38 ms per phase function (per g for HG), cached.
#include "homogeneous/biri06.h"
#include "core/table_cache.h"
#include "core/constants.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <mutex>
#include <stdexcept>
#include <tuple>

#include "core/build_progress.h"
#include "core/quadrature.h"
#include "homogeneous/sun05.h"

namespace airlight {

namespace {

// The table difference G1 - G0 is used only where it keeps >= 1/kCancel of G1 (the lookup
// error of G1 and G0, ~1e-4 relative, is amplified by G1 / (G1 - G0)); else the exact path.
#ifndef AIRLIGHT_BIRI_CANCEL
#define AIRLIGHT_BIRI_CANCEL 0.0625
#endif
constexpr double kCancel = AIRLIGHT_BIRI_CANCEL;

// Column stretch K of the table for _phase_ (see the layout above).
double column_stretch(const PhaseFunction& phase) {
    if (phase.kind == PhaseKind::HenyeyGreenstein) return phase.g >= 0.0 ? 1.0 / (1.0 - phase.g) : 1.0 + phase.g;
    if (phase.kind == PhaseKind::MurkyMie) return 4.0;
    return 1.0;
}

// Integrand of G without the scale: p(cos theta) exp(-lambda [tan(theta/2) - tan(theta0/2)]),
// the bracket as sin((theta - theta0)/2) / (cos(theta/2) cos(theta0/2)) (no cancellation).
// _c0_ = cos(theta0/2).
// The phase is evaluated from the half angle (PhaseFunction::eval_half_angle): from
// cos theta, a sharp HG lobe is noisy to ~1e-16 / (1 - |g|)^2 and the adaptive rule never met
// its tolerance (|g| = 0.999: every cell hit the panel limit, the table build did not finish in 60 s).
struct GIntegrand {
    const PhaseFunction& phase;
    double lambda, theta0, c0;
    double operator()(double theta) const {
        const double c = std::cos(0.5 * theta), s = std::sin(0.5 * theta);
        const double p = phase.eval_half_angle(s * s, c * c);
        if (lambda == 0.0) return p;
        if (c <= 0.0) return 0.0;
        return p * std::exp(-lambda * std::sin(0.5 * (theta - theta0)) / (c * c0));
    }
};

// The same integrand in eps = pi - theta, for theta > pi/2: cos(theta/2) = sin(eps/2) keeps
// its digits as theta -> pi (in theta, cos(theta/2) near pi carries an absolute rounding of
// 1e-16, so with the light right behind the viewer the exponent was noisy to 1e-8 and the
// adaptive rule never converged: 6e5 evaluations, 1 ms a call). _eps0_ = pi - theta0.
struct GIntegrandBack {
    const PhaseFunction& phase;
    double lambda, eps0, c0;
    double operator()(double eps) const {
        const double c = std::sin(0.5 * eps), s = std::cos(0.5 * eps);  // cos, sin of theta/2
        const double p = phase.eval_half_angle(s * s, c * c);
        if (lambda == 0.0) return p;
        if (c <= 0.0) return 0.0;
        return p * std::exp(-lambda * std::sin(0.5 * (eps0 - eps)) / (c * c0));
    }
};

// The G difference over [theta0, theta1], each end also given as eps = pi - theta (the
// caller's accurate complement, e.g. atan2(sin gamma, -cos gamma)), to _rel_tol_.
double G_diff(const PhaseFunction& phase, double lambda, double theta0, double eps0, double theta1, double eps1,
              double rel_tol) {
    if (!(theta1 > theta0)) return 0.0;
    if (std::isinf(lambda)) return 0.0;
    const double c0 = theta0 <= 0.5 * kPi ? std::cos(0.5 * theta0) : std::sin(0.5 * eps0);
    // Breakpoints: the extinction layer at theta0 (width 2 cos^2(theta0/2) / lambda) as a
    // geometric ladder, the phase lobe at theta = 0 (forward) or pi (backward), and pi/2,
    // where the integration variable changes from theta to eps.
    std::vector<double> cuts{theta0, theta1};
    if (theta0 < 0.5 * kPi && theta1 > 0.5 * kPi) cuts.push_back(0.5 * kPi);
    if (lambda > 0.0)
        for (double w = 2.0 * c0 * c0 / lambda; theta0 + w < theta1 && w < kPi; w *= 8.0) cuts.push_back(theta0 + w);
    const double lobe = phase.lobe_width();
    if (lobe < 1.0) {
        for (double w = lobe; w < kPi; w *= 4.0) {
            if (w > theta0 && w < theta1) cuts.push_back(w);
            if (kPi - w > theta0 && kPi - w < theta1) cuts.push_back(kPi - w);
        }
    }
    std::sort(cuts.begin(), cuts.end());
    const GIntegrand forward{phase, lambda, theta0, c0};
    const GIntegrandBack back{phase, lambda, eps0, c0};
    // eps of a breakpoint: the caller's at the ends, pi - theta (exact: Sterbenz) between.
    auto eps_of = [&](double theta) { return theta == theta0 ? eps0 : theta == theta1 ? eps1 : kPi - theta; };
    double sum = 0.0;
    for (size_t i = 0; i + 1 < cuts.size(); ++i) {
        const double a = cuts[i], b = cuts[i + 1];
        if (!(b > a)) continue;
        sum += b <= 0.5 * kPi ? integrate_adaptive(forward, a, b, rel_tol, 0.0, 80)
                              : integrate_adaptive(back, eps_of(b), eps_of(a), rel_tol, 0.0, 80);
    }
    return sum;
}

// The table path's fallback needs no more than the table's own accuracy (~1e-4).
constexpr double kFallbackRelTol = 1e-9;

// Thick fog: the G difference in t = tan(theta/2) is int_{T0}^{T1} f(t) e^{-lambda (t - T0)} dt,
// f(t) = 2 p(cos theta(t)) / (1 + t^2), cos theta = (1 - t^2) / (1 + t^2), which is
// L(T0) - e^{-lambda (T1 - T0)} L(T1) with the scaled tail L(T) = int_0^inf f(T + s) e^{-lambda s} ds,
// a 16-point Gauss-Laguerre sum (1/lambda) sum w_i f(T + x_i / lambda). f is analytic in a disc of
// radius rho(T) = sqrt(T^2 + r^2) about T, r the distance of the phase's nearest complex
// singularity from t = 0 (1 for the poles of 1 / (1 + t^2); HG g > 0: (1 - g) / (1 + g); murky
// Mie's cos^64 lobe: its width). Measured against scipy quadrature (1e-12): relative error below
// 1e-10 wherever lambda rho >= 10 (HG g = -0.99 ... 0.99, hazy and murky Mie; lambda up to 1e5),
// 1e-4 at lambda rho ~ 1. Used where lambda rho(T0) >= kLaguerreMin and lambda (T1 - T0) >= 1
// (the subtraction then loses at most a factor 1.6): the exact quadrature's cost grows with lambda
// (25 s for a 960 x 540 street bake at sigma_t = 1e4 /m), this one's does not.
constexpr int kLaguerreNodes = 16;
constexpr double kLaguerreMin = 10.0;

double singularity_distance(const PhaseFunction& phase) {
    if (phase.kind == PhaseKind::HenyeyGreenstein && phase.g > 0.0) return (1.0 - phase.g) / (1.0 + phase.g);
    return std::min(1.0, phase.lobe_width());
}

struct LaguerreRule {
    std::vector<double> x, w;
    LaguerreRule() { gauss_laguerre(kLaguerreNodes, x, w); }
};

// The scaled tail L(T) above.
double laguerre_tail(const PhaseFunction& phase, double lambda, double T) {
    static const LaguerreRule rule;
    double sum = 0.0;
    for (int i = 0; i < kLaguerreNodes; ++i) {
        const double t = T + rule.x[size_t(i)] / lambda, t2 = t * t;
        // t = tan(theta/2): sin^2(theta/2) = t^2 / (1 + t^2), cos^2(theta/2) = 1 / (1 + t^2).
        const double p = std::isinf(t2) ? phase.eval(-1.0) : phase.eval_half_angle(t2 / (1.0 + t2), 1.0 / (1.0 + t2));
        sum += rule.w[size_t(i)] * 2.0 * p / (1.0 + t2);
    }
    return sum / lambda;
}

}  // namespace

double biri06_G_diff_exact(const PhaseFunction& phase, double lambda, double theta0, double theta1) {
    return G_diff(phase, lambda, theta0, kPi - theta0, theta1, kPi - theta1, 1e-13);
}

double biri06_G_exact(const PhaseFunction& phase, double lambda, double T) {
    return biri06_G_diff_exact(phase, lambda, 0.0, std::isinf(T) ? kPi : 2.0 * std::atan(T));
}

double biri06_Gamma_paper(const PhaseFunction& phase, double lambda, double g) {
    auto f = [&](double alpha) {
        return phase.eval(std::cos(alpha + 0.5 * kPi)) * std::exp(-lambda * (std::sin(alpha) + 1.0) / std::cos(alpha));
    };
    return integrate_adaptive(f, 0.0, g, 1e-12);
}

void biri06_check_phase(const PhaseFunction& phase) {
    // Compared in float: Blender stores -0.99 as the float -0.99000001.
    if (phase.kind == PhaseKind::HenyeyGreenstein && float(phase.g) < float(kBiri06MinG))
        throw std::invalid_argument("biri06: Henyey-Greenstein g = " + std::to_string(phase.g) +
                                    " is a backward lobe sharper than its Gamma table resolves (g >= -0.99); "
                                    "use model 'quadrature'");
}

Biri06Table::Biri06Table(const PhaseFunction& phase, int nl, int nT)
    : phase_(phase), nl_(nl), nT_(nT), K_(column_stretch(phase)), k_(std::max(column_stretch(phase), 1.0)) {
    if (nl < 2 || nT < 2) throw std::invalid_argument("Biri06Table: need at least 2 x 2 samples");
    biri06_check_phase(phase);
    data_.resize(static_cast<size_t>(nl) * nT);
    const std::string key = "biri06_gamma v1 phase=" + std::to_string(int(phase.kind)) + " g=" + key_number(phase.g) +
                            " nl=" + std::to_string(nl) + " nT=" + std::to_string(nT);
    load_or_build(key, data_, [&] {
        const double q0 = 2.0 * phase.eval(1.0);
        for (int i = 0; i < nl; ++i) {
            const double s = static_cast<double>(i) / (nl - 1);
            float* row = &data_[static_cast<size_t>(i) * nT];
            row[0] = static_cast<float>(q0);
            if (i == nl - 1) {  // lambda = inf
                for (int j = 1; j < nT; ++j) {
                    const double w = static_cast<double>(j) / (nT - 1);
                    row[j] = static_cast<float>(j == nT - 1 ? q0 : -q0 * std::expm1(-w / (1.0 - w)) / w);
                }
                continue;
            }
            const double lambda = k_ * s * s / (1.0 - s * s);
            const GIntegrand f{phase, lambda, 0.0, 1.0};
            double G = 0.0, theta_prev = 0.0;
            for (int j = 1; j < nT; ++j) {
                const double w = static_cast<double>(j) / (nT - 1);
                const double theta = (j == nT - 1) ? kPi : 2.0 * std::atan(w / ((1.0 - w) * (K_ + lambda)));
                G += integrate_adaptive(f, theta_prev, theta, 1e-12, 1e-15 * G, 60);
                theta_prev = theta;
                row[j] = static_cast<float>(G * (K_ + lambda) / w);
            }
            build_progress_check();  // progress and cancel of the bake building it
        }
    });
}

double Biri06Table::eval(double lambda, double T) const {
    if (!(lambda >= 0.0) || !(T >= 0.0)) throw std::invalid_argument("Biri06Table: need lambda >= 0 and T >= 0");
    if (std::isinf(lambda)) return 0.0;
    const double s = std::sqrt(lambda / (lambda + k_));
    const double tau = T * (K_ + lambda);
    const double w = std::isinf(T) ? 1.0 : tau / (1.0 + tau);
    const double x = s * (nl_ - 1), y = w * (nT_ - 1);
    const int i = std::min(static_cast<int>(x), nl_ - 2), j = std::min(static_cast<int>(y), nT_ - 2);
    const double fx = x - i, fy = y - j;
    const float* r0 = &data_[static_cast<size_t>(i) * nT_ + j];
    const float* r1 = r0 + nT_;
    const double Q = (1.0 - fx) * ((1.0 - fy) * r0[0] + fy * r0[1]) + fx * ((1.0 - fy) * r1[0] + fy * r1[1]);
    return Q * w / (K_ + lambda);
}

std::shared_ptr<const Biri06Table> shared_biri06_table(const PhaseFunction& phase, int nl, int nT) {
    using Key = std::tuple<int, double, int, int>;
    static std::mutex mutex;
    static std::map<Key, std::shared_ptr<const Biri06Table>> cache;
    const Key key{static_cast<int>(phase.kind), phase.kind == PhaseKind::HenyeyGreenstein ? phase.g : 0.0, nl, nT};
    std::lock_guard<std::mutex> lock(mutex);
    auto it = cache.find(key);
    if (it != cache.end()) return it->second;
    if (cache.size() >= 64) cache.clear();  // bounded: a g slider sweep must not grow it forever
    auto table = std::make_shared<const Biri06Table>(phase, nl, nT);
    cache.emplace(key, table);
    return table;
}

double biri06_airlight(const PhaseFunction& phase, double sigma_t, double Dsv, double cos_gamma, double Dvp,
                       const Biri06Table* table, GammaEval how, bool* used_exact) {
    if (used_exact) *used_exact = how == GammaEval::Exact;
    sun05_check_inputs(sigma_t, Dsv, cos_gamma, Dvp);
    if (sigma_t == 0.0 || Dvp == 0.0) return 0.0;
    Dsv = std::max(Dsv, 1e-6);
    const double c = std::clamp(cos_gamma, -1.0, 1.0);
    const double sin_gamma = std::max(std::sqrt((1.0 - c) * (1.0 + c)), 1e-8);
    const double h = Dsv * sin_gamma, a = Dsv * c, lambda = sigma_t * h;
    const bool far = std::isinf(Dvp);
    const double am = a - Dvp;                          // a - Dvp (-inf when Dvp = inf)
    const double d1 = far ? INFINITY : std::hypot(am, h);  // light-surface distance
    auto exact = [&](double rel_tol) {
        // Phase angles at the viewer and the surface, and their complements pi - theta.
        const double theta0 = std::atan2(sin_gamma, c), eps0 = std::atan2(sin_gamma, -c);
        const double theta1 = far ? kPi : std::atan2(h, am), eps1 = far ? 0.0 : std::atan2(h, -am);
        return sigma_t / h * std::exp(-sigma_t * Dsv) * G_diff(phase, lambda, theta0, eps0, theta1, eps1, rel_tol);
    };
    if (how == GammaEval::Exact) return exact(1e-13);
    if (!table) throw std::invalid_argument("biri06_airlight: the table path needs a table");
    // T = tan(theta/2) = sin/(1 + cos) or (1 - cos)/sin, whichever does not cancel.
    const double T0 = c >= 0.0 ? sin_gamma / (1.0 + c) : (1.0 - c) / sin_gamma;
    const double T1 = far ? INFINITY : (am >= 0.0 ? h / (d1 + am) : (d1 - am) / h);
    const double G1 = table->eval(lambda, T1), G0 = table->eval(lambda, T0);
    const double D = G1 - G0;
    const double La = sigma_t / h * std::exp(-sigma_t * a) * D;
    if (D > kCancel * G1 && std::isfinite(La)) return La;
    if (used_exact) *used_exact = true;
    const double rho = std::hypot(T0, singularity_distance(phase));
    if (lambda * rho >= kLaguerreMin && lambda * (T1 - T0) >= 1.0) {
        const double tail1 = far ? 0.0 : std::exp(-lambda * (T1 - T0)) * laguerre_tail(phase, lambda, T1);
        return sigma_t / h * std::exp(-sigma_t * Dsv) * (laguerre_tail(phase, lambda, T0) - tail1);
    }
    return exact(kFallbackRelTol);
}

double phase_airlight_quadrature(const PhaseFunction& phase, double sigma_t, double Dsv, double cos_gamma,
                                 double Dvp, double rel_tol) {
    if (sigma_t == 0.0 || Dvp == 0.0) return 0.0;
    const double c = std::clamp(cos_gamma, -1.0, 1.0);
    const double a = Dsv * c;
    // Regularised as sun05 (sin gamma >= 1e-8): a ray through the light gave NaN (stability suite).
    const double h = Dsv * std::max(std::sqrt((1.0 - c) * (1.0 + c)), 1e-8);
    // Single-scattering integrand; cos theta = (a - x) / d (phase.h convention).
    auto integrand = [=, &phase](double x) {
        const double dx = x - a;
        const double d2 = dx * dx + h * h;
        const double d = std::sqrt(d2);
        return phase.eval(-dx / d) * std::exp(-sigma_t * (d + x)) / d2;
    };
    // Breakpoints: geometric ladders around the closest approach a (scale h, and h / lobe
    // for the phase lobe, which in x spans ~h / lobe_width before a).
    const double end = std::isinf(Dvp) ? std::numeric_limits<double>::infinity() : Dvp;
    std::vector<double> cuts{0.0};
    if (a > 0.0 && a < end) cuts.push_back(a);
    for (double w = std::max(h, 1e-12 * Dsv); w < 4.0 * Dsv / phase.lobe_width(); w *= 4.0) {
        if (a - w > 0.0 && a - w < end) cuts.push_back(a - w);
        if (a + w > 0.0 && a + w < end) cuts.push_back(a + w);
    }
    std::sort(cuts.begin(), cuts.end());
    const double sum = integrate_piecewise(integrand, cuts, end, Dsv, rel_tol);
    return sigma_t * sum;
}

}  // namespace airlight
