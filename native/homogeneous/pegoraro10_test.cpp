// pegoraro10_test.cpp: the complex E1 at known values and on both sides of its cut, the
// Pegoraro closed form against Sun 2005's exact F path (isotropic), the phase-aware
// quadrature (Rayleigh, murky Mie, HG at order 64) and the spot quadrature.
#include "core/constants.h"
#include "homogeneous/pegoraro10.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "homogeneous/biri06.h"
#include "core/complex_e1.h"
#include "core/quadrature.h"
#include "homogeneous/spot_light.h"
#include "homogeneous/sun05.h"

namespace airlight {
namespace {


TEST(ComplexE1, KnownValuesAndBranch) {
    // E1(1) and Ei(1) (Abramowitz & Stegun table 5.1): E1(-1 +- i0) = -Ei(1) -+ i pi.
    EXPECT_NEAR(complex_e1(cplx(1.0, 0.0)).real(), 0.21938393439552027368, 1e-15);
    const cplx up = complex_e1(cplx(-1.0, 0.0)), down = complex_e1(cplx(-1.0, -0.0));
    EXPECT_NEAR(up.real(), -1.89511781635593675547, 1e-14);
    EXPECT_NEAR(up.imag(), -kPi, 1e-14);
    EXPECT_NEAR(down.imag(), kPi, 1e-14);
    // Continued fraction region: E1(10) = 4.156968929685324e-06.
    EXPECT_NEAR(complex_e1(cplx(10.0, 0.0)).real() / 4.156968929685324277e-06, 1.0, 1e-13);
    // Difference form equals the plain difference where that does not cancel.
    const cplx za(0.7, -0.4), zb(3.0, -0.4);
    const cplx plain = std::exp(za) * (complex_e1(za) - complex_e1(zb));
    EXPECT_NEAR(std::abs(complex_e1_difference_scaled(za, zb) - plain) / std::abs(plain), 0.0, 1e-13);
}

TEST(Pegoraro10, IsotropicEqualsSun05Exact) {
    const PegoraroPhase iso = pegoraro_phase(PhaseFunction{}, 0);
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    for (int i = 0; i < 200; ++i) {
        const double s = std::pow(10.0, -2.0 + 2.5 * u(rng)), D = std::pow(10.0, -1.0 + 2.5 * u(rng));
        const double c = 2.0 * u(rng) - 1.0, V = u(rng) < 0.3 ? INFINITY : std::pow(10.0, -1.0 + 3.0 * u(rng));
        const double ref = sun05_airlight(s, D, c, V, nullptr, FEval::Exact);
        EXPECT_NEAR(pegoraro10_airlight(iso, s, D, c, V) / ref, 1.0, 1e-9) << s << " " << D << " " << c << " " << V;
    }
}

TEST(Pegoraro10, PolynomialPhasesMatchQuadrature) {
    PhaseFunction ray{PhaseKind::Rayleigh, 0.0}, murky{PhaseKind::MurkyMie, 0.0}, hg{PhaseKind::HenyeyGreenstein, 0.6};
    for (const PhaseFunction& ph : {ray, murky, hg}) {
        const PegoraroPhase poly = pegoraro_phase(ph, 64);
        for (double c : {-0.9, -0.2, 0.4, 0.95})
            for (double V : {2.0, 30.0, double(INFINITY)}) {
                const double ref = phase_airlight_quadrature(ph, 0.3, 5.0, c, V, 1e-12);
                EXPECT_NEAR(pegoraro10_airlight(poly, 0.3, 5.0, c, V) / ref, 1.0, 1e-9) << c << " " << V;
            }
    }
}

TEST(Pegoraro10, SpotMatchesQuadrature) {
    const SpotCone cone = make_spot_cone(glm::dvec3(0.2, -1.0, 0.1), kPi / 4.0, 0.15);
    const glm::dvec3 s(0.0, 3.0, -5.0), o(0.0);
    const PegoraroPhase iso = pegoraro_phase(PhaseFunction{}, 0);
    int lit = 0;
    for (int i = -10; i <= 10; ++i)
        for (int j = -10; j <= 10; ++j) {
            const glm::dvec3 d = glm::normalize(glm::dvec3(0.05 * i, 0.05 * j, -1.0));
            for (double V : {6.0, double(INFINITY)}) {
                const double ref = spot_airlight_quadrature(cone, s, PhaseFunction{}, 0.2, o, d, V, 1e-11);
                const double got = pegoraro10_spot_airlight(iso, cone, s, 0.2, o, d, V);
                if (ref == 0.0) {
                    EXPECT_EQ(got, 0.0);
                    continue;
                }
                ++lit;
                EXPECT_NEAR(got / ref, 1.0, 1e-7) << i << " " << j << " " << V;
            }
        }
    EXPECT_GT(lit, 50);
}

TEST(Pegoraro10, MomentRegimesAgree) {
    // H just below and above the switch from the forward recurrence to Olver's algorithm.
    cplx a[41], b[41];
    pegoraro_moments(1.5, 0.2, 3.0, 40, a);
    pegoraro_moments(1.5 * (1.0 + 1e-12), 0.2, 3.0, 40, b);
    for (int m = 0; m <= 40; ++m) EXPECT_NEAR(std::abs(a[m] - b[m]) / std::abs(a[0]), 0.0, 1e-8) << m;
}

}  // namespace
}  // namespace airlight
