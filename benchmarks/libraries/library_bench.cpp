// library_bench.cpp: the kernels' own numerics against the libraries Debian ships for the
// same job (SLEEF's vectorised expf/erfcf, Boost.Math's Gauss-Kronrod and Gauss-Legendre),
// speed and accuracy in one run. Prints figures; see benchmarks/README.md.
//
//   benchmarks/libraries/build.sh && build-libraries/library_bench
#include <immintrin.h>
#include <sleef.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <functional>
#include <random>
#include <vector>

#include <boost/math/quadrature/gauss.hpp>
#include <boost/math/quadrature/gauss_kronrod.hpp>

#include "core/fast_erf.h"
#include "core/quadrature.h"

using namespace airlight;
using Clock = std::chrono::steady_clock;

namespace {

template <typename F>
double best_ns_per_item(F&& f, size_t items, int reps = 15) {
    double best = 1e300;
    for (int r = 0; r < reps; ++r) {
        const auto t0 = Clock::now();
        f();
        best = std::min(best, std::chrono::duration<double, std::nano>(Clock::now() - t0).count() / items);
    }
    return best;
}

volatile float sink;

void compare_float_functions() {
    constexpr size_t n = 1 << 16;
    std::mt19937 rng(1);
    std::vector<float> x_exp(n), x_erf(n), out(n);
    std::uniform_real_distribution<float> ue(-80.0f, 0.0f), uf(0.0f, 9.0f);
    for (size_t i = 0; i < n; ++i) x_exp[i] = ue(rng), x_erf[i] = uf(rng);
    auto rel_err = [&](const std::vector<float>& x, const std::function<double(double)>& exact) {
        double worst = 0.0;
        for (size_t i = 0; i < n; ++i) {
            const double e = exact(double(x[i]));
            if (e > 1e-30) worst = std::max(worst, std::abs(double(out[i]) / e - 1.0));
        }
        return worst;
    };
    std::printf("float functions over %zu arguments, AVX2 (8 lanes), best of 15 (ns per value; max rel error vs double libm)\n", n);
    // exp
    const double own_exp = best_ns_per_item([&] { for (size_t i = 0; i < n; ++i) out[i] = fast_expf_le88(x_exp[i]); }, n);
    const double own_exp_err = rel_err(x_exp, [](double x) { return std::exp(x); });
    const double sleef_exp = best_ns_per_item([&] {
        for (size_t i = 0; i < n; i += 8) _mm256_storeu_ps(&out[i], Sleef_expf8_u10avx2(_mm256_loadu_ps(&x_exp[i])));
    }, n);
    const double sleef_exp_err = rel_err(x_exp, [](double x) { return std::exp(x); });
    std::printf("  exp, x in [-80, 0]:   fast_expf_le88 %.3f ns (%.1e) | Sleef_expf8_u10avx2 %.3f ns (%.1e) | ratio %.2f\n",
                own_exp, own_exp_err, sleef_exp, sleef_exp_err, sleef_exp / own_exp);
    // erfc
    const double own_erfc = best_ns_per_item([&] { for (size_t i = 0; i < n; ++i) out[i] = fast_erfc_pos(x_erf[i]); }, n);
    const double own_erfc_err = rel_err(x_erf, [](double x) { return std::erfc(x); });
    const double sleef_erfc = best_ns_per_item([&] {
        for (size_t i = 0; i < n; i += 8) _mm256_storeu_ps(&out[i], Sleef_erfcf8_u15avx2(_mm256_loadu_ps(&x_erf[i])));
    }, n);
    const double sleef_erfc_err = rel_err(x_erf, [](double x) { return std::erfc(x); });
    std::printf("  erfc, x in [0, 9]:    fast_erfc_pos  %.3f ns (%.1e) | Sleef_erfcf8_u15avx2 %.3f ns (%.1e) | ratio %.2f\n",
                own_erfc, own_erfc_err, sleef_erfc, sleef_erfc_err, sleef_erfc / own_erfc);
    // erfcx = exp(x^2) erfc(x): SLEEF has no erfcx; its erfc times exp(x^2) overflows past x ~ 9.4
    const double own_erfcx = best_ns_per_item([&] { for (size_t i = 0; i < n; ++i) out[i] = fast_erfcx_pos(x_erf[i]); }, n);
    const double own_erfcx_err = rel_err(x_erf, [](double x) { return std::exp(x * x) * std::erfc(x); });
    const double sleef_erfcx = best_ns_per_item([&] {
        for (size_t i = 0; i < n; i += 8) {
            const __m256 x = _mm256_loadu_ps(&x_erf[i]);
            _mm256_storeu_ps(&out[i], _mm256_mul_ps(Sleef_erfcf8_u15avx2(x), Sleef_expf8_u10avx2(_mm256_mul_ps(x, x))));
        }
    }, n);
    const double sleef_erfcx_err = rel_err(x_erf, [](double x) { return std::exp(x * x) * std::erfc(x); });
    std::printf("  erfcx, x in [0, 9]:   fast_erfcx_pos %.3f ns (%.1e) | SLEEF erfcf x expf  %.3f ns (%.1e) | ratio %.2f\n",
                own_erfcx, own_erfcx_err, sleef_erfcx, sleef_erfcx_err, sleef_erfcx / own_erfcx);
    sink = out[n / 2];
}

void compare_quadrature() {
    std::printf("\nquadrature (us per integral; relative error against the analytic value)\n");
    struct Case {
        const char* name;
        std::function<double(double)> f;
        double a, b, exact;
    };
    const double lam = 40.0;
    std::vector<Case> cases{
        {"smooth: cos on [0, pi/2]", [](double x) { return std::cos(x); }, 0.0, 1.5707963267948966, 1.0},
        {"peaked: e^{-40 x} on [0, 3]", [=](double x) { return std::exp(-lam * x); }, 0.0, 3.0, (1.0 - std::exp(-3.0 * lam)) / lam},
        {"kink: |x - 0.3| on [0, 1]", [](double x) { return std::abs(x - 0.3); }, 0.0, 1.0, 0.5 * (0.09 + 0.49)},
        {"singular: 1/sqrt(x) on [0, 1]", [](double x) { return x > 0.0 ? 1.0 / std::sqrt(x) : 0.0; }, 0.0, 1.0, 2.0},
    };
    for (const Case& c : cases) {
        long evals = 0;
        auto counted = [&](double x) { ++evals; return c.f(x); };
        double own = 0.0, boost_v = 0.0, err = 0.0;
        long own_evals = 0, boost_evals = 0;
        const double t_own = best_ns_per_item([&] { evals = 0; own = integrate_adaptive(counted, c.a, c.b, 1e-10); own_evals = evals; }, 1, 5);
        const double t_boost = best_ns_per_item([&] {
            evals = 0;
            boost_v = boost::math::quadrature::gauss_kronrod<double, 15>::integrate(counted, c.a, c.b, 30, 1e-10, &err);
            boost_evals = evals;
        }, 1, 5);
        std::printf("  %-30s integrate_adaptive %8.2f us %6ld evals %.1e | boost gauss_kronrod<15> %8.2f us %6ld evals %.1e\n",
                    c.name, 1e-3 * t_own, own_evals, std::abs(own / c.exact - 1.0), 1e-3 * t_boost, boost_evals,
                    std::abs(boost_v / c.exact - 1.0));
    }
    // Gauss-Legendre nodes: ours (Newton on the recurrence) against Boost's tabulated ones.
    std::printf("\nGauss-Legendre nodes: largest difference from Boost.Math's (in units of the last place)\n");
    auto ulps = [](double a, double b) { return std::abs(a - b) / std::max(std::nextafter(std::abs(b), 1e300) - std::abs(b), 1e-300); };
    auto compare_gl = [&](auto rule, int n) {
        std::vector<double> x, w;
        gauss_legendre(n, x, w);
        const auto& ax = rule.abscissa();
        const auto& aw = rule.weights();
        double worst_x = 0.0, worst_w = 0.0;
        // Boost stores the non-negative half (x[0] = 0 for odd n), ours runs from +1 down to -1.
        for (size_t k = 0; k < ax.size(); ++k) {
            const double bx = ax[ax.size() - 1 - k], bw = aw[aw.size() - 1 - k];
            worst_x = std::max(worst_x, ulps(x[k], bx));
            worst_w = std::max(worst_w, ulps(w[k], bw));
        }
        std::printf("  n = %2d: abscissae %.1f ulp, weights %.1f ulp\n", n, worst_x, worst_w);
    };
    compare_gl(boost::math::quadrature::gauss<double, 8>(), 8);
    compare_gl(boost::math::quadrature::gauss<double, 20>(), 20);
    compare_gl(boost::math::quadrature::gauss<double, 48>(), 48);
}

}  // namespace

int main() {
    compare_float_functions();
    compare_quadrature();
    return 0;
}
