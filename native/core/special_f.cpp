// special_f.cpp: Sun et al. 2005's F(u, v) = int_0^v exp(-u tan xi) dxi, exact and tabulated.
//
// Exact evaluator
//   F(u, T) = int_0^{atan T} e^{-u tan theta} dtheta by adaptive Gauss-Kronrod 7-15 to
//   1e-13 relative; the adaptive bisection resolves the boundary layers (width ~1/u near
//   theta = 0 for large u, width ~u near pi/2 for small u). Differences are integrated
//   directly: e^{u t0} [F(u, t0 + dt) - F(u, t0)] = int_0^{dxi} exp(-u tau (1 + t0^2) /
//   (1 - t0 tau)) dtheta, tau = tan theta, dxi = atan(dt / (1 + t0 (t0 + dt))), which has
//   neither cancellation nor overflow. Checked against mpmath in special_f_test.cpp.
//
// Table layout (mirrored by sun05_inline.h and shaders/sun05_airlight.glsl)
//   rows    i = 0..nu-1 over s = sqrt(u / (u + k)), k = kSpecialFTableK = 1, s in [0, 1];
//           s = 1 is u = inf, so no u is ever out of range; the square root resolves
//           the u ln u term of F at small u (with s = u/(u+k) the error was first order:
//           1.8e-3 max at 256 x 256);
//   columns j = 0..nT-1 over w = tau / (1 + tau), tau = T (1 + u), w in [0, 1];
//           w = 1 is T = inf; stretching T by (1 + u) follows the 1/u boundary layer;
//   stored  Q = F (1 + u) / w, which is O(1) and smooth everywhere: Q = 1 at w = 0
//           (F ~ T), Q -> (1 - e^{-tau}) / w at s = 1 (F ~ (1 - e^{-uT}) / u), and
//           Q = atan(T) (1 + T) / T at u = 0. Storing a quantity proportional to F makes
//           the bilinear error a relative error of F, also where F -> 0.
//   lookup  F = Q(s, w) w / (1 + u): one sqrt and three divisions, no exp/atan.
//   The asymptotic form F ~ (1 - e^{-uT})/u - 2/u^3 + ... is the s = 1 row itself
//   (reached continuously: the correction is O(1/u^2) relative, smooth in 1 - s^2).
//
// MEASURED relative error of the table against special_F_exact over 100000 random
// points, u log-uniform in [1e-4, 1e5] (10 % u = 0), T log-uniform in [1e-6, 1e6]
// (10 % T = inf) (throwaway tool; special_f_test.cpp asserts these bounds):
//     size        bilinear max   bilinear p99   bilinear mean   nearest max   nearest p99
//     64 x 64       1.10e-3        5.4e-4          6.5e-5          2.3e-2        1.3e-2
//     128 x 128     5.29e-4        2.5e-4          2.0e-5          1.1e-2        6.9e-3
//     256 x 256     2.60e-4        1.2e-4          6.7e-6          5.8e-3        3.6e-3
//     512 x 512     1.28e-4        4.9e-5          2.3e-6          2.9e-3        1.8e-3
//   (nearest mean: 2.2e-3, 1.25e-3, 6.9e-4, 3.7e-4 from 64 to 512; 128 and 512 asserted by
//   sun05_nearest_test.cpp, which also measures the airlight error each choice gives)
//   The bilinear worst case sits at small u and T ~ 1/u (the u T ~ 1 corner, squeezed into
//   the last column for u < 1/nT) and is first order there, elsewhere second order.
//   (The uniform 64 x 64 layout over u in [0, 10], v in [0, pi/2] had 9 %.)
#include "core/special_f.h"
#include "core/table_cache.h"

#include "core/build_progress.h"
#include "core/parallel.h"
#include "core/constants.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <memory>
#include <mutex>
#include <tuple>
#include <stdexcept>
#include <thread>
#include <vector>

#include "core/quadrature.h"
#include "homogeneous/sun05_inline.h"

namespace airlight {

double special_F_diff_exact(double u, double t0, double dt) {
    if (!(dt > 0.0)) return 0.0;
    const double dxi = std::isinf(dt) ? std::atan2(1.0, t0) : std::atan2(dt, 1.0 + t0 * (t0 + dt));
    if (u == 0.0) return dxi;
    if (std::isinf(u)) return 0.0;
    const double scale = 1.0 + t0 * t0;
    auto f = [=](double theta) {
        const double tau = std::tan(theta);
        const double den = 1.0 - t0 * tau;
        if (den <= 0.0) return 0.0;
        return std::exp(-u * tau * scale / den);
    };
    // The integrand falls off within theta ~ 1 / (u (1 + t0^2)); cut there so that the
    // first panels cannot miss a layer narrower than their node spacing.
    const double layer = 1.0 / (u * scale);
    double result = 0.0, lo = 0.0;
    for (double cut = layer; cut < dxi && lo < dxi; cut *= 16.0) {
        result += integrate_adaptive(f, lo, cut, 1e-13, 0.0, 80);
        lo = cut;
    }
    return result + integrate_adaptive(f, lo, dxi, 1e-13, 0.0, 80);
}

double special_F_exact_tan(double u, double T) {
    if (std::isnan(u) || std::isnan(T) || u < 0.0 || T < 0.0)
        throw std::invalid_argument("special_F: need u >= 0 and T = tan(v) >= 0");
    return special_F_diff_exact(u, 0.0, T);
}

double special_F_exact(double u, double v) {
    if (std::isnan(v) || v < 0.0 || v > kHalfPi + 1e-12)
        throw std::invalid_argument("special_F: need v in [0, pi/2]");
    if (v >= kHalfPi) return special_F_exact_tan(u, INFINITY);
    return special_F_exact_tan(u, std::tan(v));
}

SpecialFTable::SpecialFTable(int nu, int nT, Interp interp) : nu_(nu), nT_(nT), interp_(interp) {
    if (nu < 2 || nT < 2) throw std::invalid_argument("SpecialFTable: need at least 2 x 2 samples");
    data_.resize(static_cast<size_t>(nu) * nT);
    // Rows are independent: built on up to 8 threads (256 x 256 costs ~90 ms on one core,
    // paid by the first bake of a process; the values do not depend on the split). One row
    // per work item, and a progress check after each (build_progress.h): a cancelled bake
    // stops the build within a row per thread (4096 x 4096 takes ~14 s on 2 cores).
    auto build_row = [this, nu, nT](int i) {
        {
            const double s = static_cast<double>(i) / (nu - 1);
            for (int j = 0; j < nT; ++j) {
                const double w = static_cast<double>(j) / (nT - 1);
                double Q;
                if (j == 0) {
                    Q = 1.0;  // F ~ T as T -> 0
                } else if (i == nu - 1) {
                    // u = inf at fixed tau: F (1 + u) -> 1 - e^{-tau}
                    Q = (j == nT - 1) ? 1.0 : -std::expm1(-w / (1.0 - w)) / w;
                } else {
                    const double u = kSpecialFTableK * s * s / (1.0 - s * s);
                    const double T = (j == nT - 1) ? INFINITY : w / ((1.0 - w) * (1.0 + u));
                    Q = special_F_exact_tan(u, T) * (1.0 + u) / w;
                }
                data_[static_cast<size_t>(i) * nT + j] = static_cast<float>(Q);
            }
        }
        build_progress_check();
    };
    const long long work = static_cast<long long>(nu) * nT;
    const int n_threads = work < 4096 ? 1 : std::clamp(int(std::thread::hardware_concurrency()), 1, std::min(8, nu));
    load_or_build("special_F v1 nu=" + std::to_string(nu) + " nT=" + std::to_string(nT), data_,
                  [&] { parallel_for(nu, n_threads, build_row); });
}

double SpecialFTable::eval_tan(double u, double T) const {
    if (!(u >= 0.0) || !(T >= 0.0)) throw std::invalid_argument("SpecialFTable: need u >= 0 and T >= 0");
    if (std::isinf(u)) return 0.0;
    const bool T_inf = std::isinf(T);
    if (interp_ == Interp::Bilinear) return special_F_table_eval(data_.data(), nu_, nT_, u, T, T_inf);
    const double s = special_F_table_s(u);
    const double tau = T * (1.0 + u);
    const double w = T_inf ? 1.0 : tau / (1.0 + tau);
    return special_F_table_Q_nearest(data_.data(), nu_, nT_, s, w) * w / (1.0 + u);
}

double SpecialFTable::eval(double u, double v) const {
    return eval_tan(u, v >= kHalfPi ? INFINITY : std::tan(v));
}

// F tables are deterministic and costly to build: keep one per (nu, nT, interp) for the process.
std::shared_ptr<const SpecialFTable> shared_special_F_table(int nu, int nT, Interp interp) {
    static std::mutex mutex;
    static std::map<std::tuple<int, int, Interp>, std::shared_ptr<const SpecialFTable>> cache;
    std::lock_guard<std::mutex> lock(mutex);
    auto& slot = cache[{nu, nT, interp}];
    if (!slot) slot = std::make_shared<const SpecialFTable>(nu, nT, interp);
    return slot;
}

}  // namespace airlight
