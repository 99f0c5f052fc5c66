// sunlight_layer_test.cpp: the sun's closed form (sunlight_layer.h) against the quadrature of the
// same single-scattering integral, written out independently, to 1e-6 relative.
#include "homogeneous/sunlight_layer.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "homogeneous/hoffman02.h"
#include "core/phase.h"

namespace airlight {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

void expect_matches_quadrature(double sigma, double h, double mu_s, double oz, double dz, double t0, double t1) {
    const double G = sunlight_layer_factor(sigma, h, mu_s, oz, dz, t0, t1);
    const double Gq = sunlight_layer_factor_quadrature(sigma, h, mu_s, oz, dz, t0, t1);
    EXPECT_TRUE(std::isfinite(G));
    EXPECT_NEAR(G, Gq, 1e-6 * Gq + 1e-300) << "sigma " << sigma << " h " << h << " mu_s " << mu_s << " oz " << oz
                                             << " dz " << dz << " t0 " << t0 << " t1 " << t1;
}

// Random cameras inside and above the layer, rays up and down, finite and infinite.
TEST(SunlightLayer, ClosedFormMatchesQuadrature) {
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> U(0.0, 1.0);
    for (int k = 0; k < 400; ++k) {
        const double sigma = std::pow(10.0, -3.0 + 3.0 * U(rng));
        const double h = 50.0 * (U(rng) - 0.3);
        const double oz = h + 60.0 * (U(rng) - 0.7);  // 30 % above the top
        const double dz = 2.0 * U(rng) - 1.0;
        const double mu_s = std::pow(10.0, -3.0 * U(rng));
        const double t0 = U(rng) < 0.5 ? 0.0 : 2.0 * U(rng);
        const double t1 = U(rng) < 0.3 ? kInf : t0 + 200.0 * U(rng);
        expect_matches_quadrature(sigma, h, mu_s, oz, dz, t0, t1);
    }
}

// Grazing sun (mu_s -> 0): the lit fog is a skin of depth mu_s / sigma under the top.
TEST(SunlightLayer, GrazingSun) {
    for (double mu_s : {1e-2, 1e-4, 1e-6}) {
        for (double dz : {0.3, 0.0, -0.3, 1e-7}) {
            expect_matches_quadrature(0.1, 10.0, mu_s, 9.5, dz, 0.0, 100.0);
            if (dz <= 0.0) expect_matches_quadrature(0.1, 10.0, mu_s, 9.5, dz, 0.0, kInf);
        }
    }
    // Exactly horizontal or upward sun: no sunlight below the top.
    EXPECT_EQ(sunlight_layer_factor(0.1, 10.0, 0.0, 5.0, 0.2, 0.0, 100.0), 0.0);
    EXPECT_EQ(sunlight_layer_factor(0.1, 10.0, -0.5, 5.0, 0.2, 0.0, kInf), 0.0);
    // Continuity towards mu_s = 0 (no NaN, tends to 0).
    EXPECT_LT(sunlight_layer_factor(0.1, 10.0, 1e-300, 5.0, 0.2, 0.0, 100.0), 1e-200);
    EXPECT_LT(sunlight_layer_factor(0.1, 10.0, 1e-300, 5.0, 0.0, 0.0, kInf), 1e-200);
}

// Looking into the sun (d = -w, so d.z = mu_s): k = 0, G = e^{-tau_a} L, L to the top.
TEST(SunlightLayer, LookingIntoTheSun) {
    const double sigma = 0.05, h = 20.0, oz = 2.0, mu_s = 0.6;
    const double L = (h - oz) / mu_s;
    const double want = std::exp(-sigma * (h - oz) / mu_s) * L;
    EXPECT_NEAR(sunlight_layer_factor(sigma, h, mu_s, oz, mu_s, 0.0, kInf), want, 1e-14 * want);
    expect_matches_quadrature(sigma, h, mu_s, oz, mu_s, 0.0, kInf);
    expect_matches_quadrature(sigma, h, mu_s, oz, mu_s * (1.0 + 1e-9), 0.0, kInf);
}

// Camera above the layer: fog only from the entry point on, attenuated from there.
TEST(SunlightLayer, CameraAboveTheLayer) {
    const double sigma = 0.2, h = 0.0, mu_s = 0.8;
    // Straight down from 10 m above the top: entry at t = 10.
    const double k = sigma * (1.0 + 1.0 / mu_s);
    EXPECT_NEAR(sunlight_layer_factor(sigma, h, mu_s, 10.0, -1.0, 0.0, kInf), 1.0 / k, 1e-15);
    EXPECT_EQ(sunlight_layer_factor(sigma, h, mu_s, 10.0, 0.5, 0.0, kInf), 0.0);   // looks up: no fog
    EXPECT_EQ(sunlight_layer_factor(sigma, h, mu_s, 10.0, -1.0, 0.0, 9.0), 0.0);   // surface above the fog
    expect_matches_quadrature(sigma, h, mu_s, 10.0, -0.3, 0.0, 60.0);
}

// Without a top the factor is Hoffman-Preetham's: L_in = p E (1 - e^{-sigma s}) for albedo 1.
TEST(SunlightLayer, UnboundedIsHoffmanPreetham) {
    Hoffman02Medium m;
    for (double& b : m.beta_M) b = 0.03;
    m.g = 0.4;
    const double E[3] = {2.0, 2.0, 2.0}, sun[3] = {0.3, 0.1, -0.9}, view[3] = {0.5, -0.2, 0.1};
    const double cos_theta = hoffman02_cos_theta(sun, view);
    double F[3], L[3];
    for (double s : {7.0, kInf}) {
        hoffman02(m, E, cos_theta, s, F, L);
        const double La = 0.03 * phase_hg(cos_theta, 0.4) * 2.0 * sunlight_layer_factor(0.03, kInf, -0.9, 0.0, 0.1, 0.0, s);
        EXPECT_NEAR(La, L[0], 1e-14 * L[0]);
    }
    EXPECT_EQ(sunlight_layer_factor(0.0, kInf, 0.5, 0.0, 0.1, 1.0, 4.0), 3.0);  // no fog: length
}

}  // namespace
}  // namespace airlight
