// hoffman02_test.cpp: Hoffman-Preetham sun fog against the quadrature of the same
// single-scattering integral, the angle convention, and the baseline fog's error.
#include "homogeneous/hoffman02.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

#include "homogeneous/baseline_fog.h"
#include "homogeneous/biri06.h"
#include "core/phase.h"

namespace airlight {
namespace {

TEST(Hoffman02, RayleighColours) {
    double b[3];
    hoffman02_rayleigh_rgb(1e-5, b);
    EXPECT_NEAR(b[0], 1e-5 * std::pow(550.0 / 650.0, 4), 1e-20);
    EXPECT_GT(b[2], b[1]);
    EXPECT_GT(b[1], b[0]);  // blue scatters most
}

// The closed form is exact for constant density and an unshadowed sun: equal to ~1e-10.
TEST(Hoffman02, ClosedFormMatchesQuadrature) {
    std::mt19937 rng(2);
    std::uniform_real_distribution<double> U(-1.0, 1.0);
    for (int k = 0; k < 40; ++k) {
        Hoffman02Medium m;
        hoffman02_rayleigh_rgb(1e-3 * (1.5 + U(rng)), m.beta_R);
        for (double& b : m.beta_M) b = 2e-3 * (1.2 + U(rng));
        m.g = 0.9 * U(rng);
        const double E[3] = {1.0, 0.9, 0.8};
        const double sun[3] = {U(rng), U(rng), U(rng) - 1.0}, view[3] = {U(rng), U(rng), U(rng)};
        const double s = 1000.0 * (1.0 + U(rng));
        double F[3], L[3], Lq[3];
        hoffman02(m, E, hoffman02_cos_theta(sun, view), s, F, L);
        hoffman02_quadrature(m, E, sun, view, s, Lq);
        for (int c = 0; c < 3; ++c) {
            EXPECT_NEAR(L[c], Lq[c], 1e-10 * Lq[c]);
            EXPECT_NEAR(F[c], std::exp(-(m.beta_R[c] + m.beta_M[c]) * s), 1e-15);
        }
    }
}

// Looking into the sun (view = -sun_dir) with g > 0 must be much brighter than away from it.
TEST(Hoffman02, ForwardScatteringTowardTheSun) {
    Hoffman02Medium m;
    for (double& b : m.beta_M) b = 1e-3;
    m.g = 0.7;
    const double E[3] = {1, 1, 1}, sun[3] = {0, 0, -1}, toward[3] = {0, 0, 1}, away[3] = {0, 0, -1};
    double F[3], Lt[3], La[3];
    EXPECT_DOUBLE_EQ(hoffman02_cos_theta(sun, toward), 1.0);
    hoffman02(m, E, hoffman02_cos_theta(sun, toward), 500.0, F, Lt);
    hoffman02(m, E, hoffman02_cos_theta(sun, away), 500.0, F, La);
    EXPECT_GT(Lt[0], 100.0 * La[0]);
    // Infinite segment: L_in = p(theta) E (albedo 1, Mie only).
    hoffman02(m, E, 1.0, INFINITY, F, Lt);
    EXPECT_NEAR(Lt[0], phase_hg(1.0, 0.7), 1e-15);
    EXPECT_EQ(F[0], 0.0);
}

// The baseline (constant fog colour, least-squares fitted) against the exact point-light
// airlight over a 64 x 48 image: a wall at 20 m, a point light at (2, 1, -8), isotropic.
TEST(BaselineFog, ErrorOnAPointLightScene) {
    const int W = 64, H = 48;
    const double sigma = 0.05, light[3] = {2.0, 1.0, -8.0};
    const double Dsv = std::sqrt(light[0] * light[0] + light[1] * light[1] + light[2] * light[2]);
    const PhaseFunction iso = phase_from_name("isotropic"), hg = phase_from_name("hg", 0.5);
    const auto table = shared_biri06_table(hg);
    std::vector<double> D, La, Lh, base, biri;
    for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x) {
            // Pinhole camera at the origin looking down -z, 60 deg horizontal field of view.
            const double dx = (x + 0.5 - W / 2.0) / (W / 2.0) * std::tan(0.5236), dy = (H / 2.0 - y - 0.5) / (W / 2.0) * std::tan(0.5236);
            const double len = std::sqrt(dx * dx + dy * dy + 1.0);
            const double Dvp = 20.0 * len;  // wall z = -20
            const double c = (dx * light[0] + dy * light[1] - light[2]) / (len * Dsv);
            D.push_back(Dvp);
            La.push_back(phase_airlight_quadrature(iso, sigma, Dsv, c, Dvp));
            Lh.push_back(phase_airlight_quadrature(hg, sigma, Dsv, c, Dvp));
            biri.push_back(biri06_airlight(hg, sigma, Dsv, c, Dvp, table.get(), GammaEval::Table));
        }
    const size_t n = D.size();
    for (const auto* want : {&La, &Lh}) {
        const double C = baseline_fog_fit(want->data(), D.data(), n, sigma);
        base.clear();
        for (size_t i = 0; i < n; ++i) base.push_back(baseline_fog_airlight(C, sigma, D[i]));
        const ErrorStats e = relative_error_stats(base.data(), want->data(), n);
        std::printf("[baseline] %s: C_fog %.4g, relative error mean %.3f p99 %.3f max %.3f\n",
                    want == &La ? "isotropic" : "hg g=0.5", C, e.mean, e.p99, e.max);
        EXPECT_GT(e.mean, 0.1);  // the bar is low: a constant colour misses the light's halo
    }
    const ErrorStats eb = relative_error_stats(biri.data(), Lh.data(), n);
    std::printf("[baseline] biri06 table on the same image (hg g=0.5): mean %.2e p99 %.2e max %.2e\n", eb.mean,
                eb.p99, eb.max);
    EXPECT_LT(eb.max, 5e-3);
}

}  // namespace
}  // namespace airlight
