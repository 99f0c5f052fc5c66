// phase_test.cpp: phase functions integrate to 1, HG limits, and the angle convention.
#include "core/constants.h"
#include "core/phase.h"

#include <gtest/gtest.h>

#include <cmath>

#include "homogeneous/biri06.h"
#include "core/quadrature.h"

namespace airlight {
namespace {


// 2 pi int_{-1}^{1} p(mu) dmu, integrated in theta (sin theta dtheta) so peaked lobes are resolved.
double sphere_integral(const PhaseFunction& p) {
    auto f = [&](double theta) { return 2.0 * kPi * p.eval(std::cos(theta)) * std::sin(theta); };
    double sum = 0.0, lo = 0.0;
    for (double cut = 1e-3; cut < kPi; cut *= 2.0) {
        sum += integrate_adaptive(f, lo, cut, 1e-13);
        lo = cut;
    }
    return sum + integrate_adaptive(f, lo, kPi, 1e-13);
}

TEST(Phase, IntegratesToOne) {
    for (const char* name : {"isotropic", "rayleigh", "hazy_mie", "murky_mie"})
        EXPECT_NEAR(sphere_integral(phase_from_name(name)), 1.0, 1e-12) << name;
    for (double g : {-0.99, -0.9, -0.5, 0.0, 0.3, 0.9, 0.99})
        EXPECT_NEAR(sphere_integral(phase_from_name("hg", g)), 1.0, 1e-10) << "g = " << g;
}

TEST(Phase, KnownValues) {
    EXPECT_DOUBLE_EQ(phase_from_name("rayleigh").eval(1.0), 6.0 / (16.0 * kPi));
    EXPECT_DOUBLE_EQ(phase_from_name("rayleigh").eval(0.0), 3.0 / (16.0 * kPi));
    EXPECT_DOUBLE_EQ(phase_from_name("hazy_mie").eval(1.0), 10.0 / (8.0 * kPi));
    EXPECT_DOUBLE_EQ(phase_from_name("murky_mie").eval(-1.0), 33.0 / (332.0 * kPi));
    EXPECT_NEAR(phase_from_name("murky_mie").eval(1.0), 33.0 * 51.0 / (332.0 * kPi), 1e-14);
    // HG with g = 0 is isotropic; g > 0 is forward: p(1) = (1 + g) / (4 pi (1 - g)^2).
    EXPECT_NEAR(phase_from_name("hg", 0.0).eval(0.3), 1.0 / (4.0 * kPi), 1e-16);
    EXPECT_NEAR(phase_from_name("hg", 0.5).eval(1.0), 1.5 / (4.0 * kPi * 0.25), 1e-14);
    EXPECT_GT(phase_from_name("hg", 0.5).eval(1.0), phase_from_name("hg", 0.5).eval(-1.0));
    // The mean cosine of HG is g.
    const PhaseFunction hg = phase_from_name("hg", 0.7);
    auto f = [&](double mu) { return 2.0 * kPi * mu * hg.eval(mu); };
    EXPECT_NEAR(integrate_adaptive(f, -1.0, 1.0, 1e-13), 0.7, 1e-10);
}

TEST(Phase, BadNames) {
    EXPECT_THROW(phase_from_name("mie"), std::invalid_argument);
    EXPECT_THROW(phase_from_name("hg", 1.0), std::invalid_argument);
    EXPECT_THROW(phase_from_name("hg", NAN), std::invalid_argument);
}

// Angle convention: with g > 0 (forward), a view ray toward the light collects more light
// than with g < 0, and a view ray away from it less (light in front of the viewer at 5 m, the
// surface at 4 m so that the segment never passes the light: theta < 50 deg toward it).
TEST(Phase, ForwardScatteringBrightensTheViewTowardTheLight) {
    const PhaseFunction fwd = phase_from_name("hg", 0.6), bwd = phase_from_name("hg", -0.6);
    const double toward = 0.98, away = -0.98;  // cos gamma
    EXPECT_GT(phase_airlight_quadrature(fwd, 0.1, 5.0, toward, 4.0),
              3.0 * phase_airlight_quadrature(bwd, 0.1, 5.0, toward, 4.0));
    EXPECT_LT(phase_airlight_quadrature(fwd, 0.1, 5.0, away, 4.0),
              0.5 * phase_airlight_quadrature(bwd, 0.1, 5.0, away, 4.0));
    // A ray toward the light stopping before it sees theta ~ 0 everywhere: p ~ p(1).
    const double La = phase_airlight_quadrature(fwd, 1e-6, 10.0, 1.0 - 1e-12, 5.0);
    const double iso = phase_airlight_quadrature(phase_from_name("isotropic"), 1e-6, 10.0, 1.0 - 1e-12, 5.0);
    EXPECT_NEAR(La / iso, fwd.eval(1.0) / (1.0 / (4.0 * kPi)), 1e-4);
}

}  // namespace
}  // namespace airlight
