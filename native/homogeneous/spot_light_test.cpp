// spot_light_test.cpp: the spot airlight quadrature against an independent brute-force
// midpoint integration and analytic limits.
#include "core/constants.h"
#include "homogeneous/spot_light.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "core/quadrature.h"

namespace airlight {
namespace {


// Independent Cycles profile (NOTES.md), written out again here.
double profile_ref(glm::dvec3 axis, double size, double blend, glm::dvec3 dir) {
    axis = glm::normalize(axis);
    dir = glm::normalize(dir);
    const double c = glm::dot(axis, dir), ch = std::cos(size / 2.0);
    if (c <= ch) return 0.0;
    const double e1 = (1.0 - ch) * blend;
    if (e1 <= 0.0) return c;
    const double t = std::clamp((c - ch) / e1, 0.0, 1.0);
    return c * t * t * (3.0 - 2.0 * t);
}

// Brute-force composite midpoint rule over [0, Dvp] (finite), isotropic or HG phase.
double brute(glm::dvec3 s, glm::dvec3 axis, double size, double blend, double sigma, glm::dvec3 o, glm::dvec3 d,
             double Dvp, double g = 0.0, int n = 400000) {
    d = glm::normalize(d);
    double sum = 0.0;
    const double dx = Dvp / n;
    for (int i = 0; i < n; ++i) {
        const double x = (i + 0.5) * dx;
        const glm::dvec3 p = o + x * d;
        const glm::dvec3 u = p - s;
        const double r2 = glm::dot(u, u), r = std::sqrt(r2);
        const double mu = glm::dot(u / r, -d);
        const double ph = (1 - g * g) / (4 * kPi * std::pow(1 + g * g - 2 * g * mu, 1.5));
        sum += profile_ref(axis, size, blend, u) * ph * std::exp(-sigma * (r + x)) / r2;
    }
    return sigma * sum * dx;
}

TEST(SpotProfile, MatchesCyclesFormula) {
    const SpotCone cone = make_spot_cone({0, 0, -2}, 1.0, 0.3);
    for (double th = 0.0; th < 0.7; th += 0.01) {
        const glm::dvec3 dir(std::sin(th), 0.0, -std::cos(th));
        EXPECT_NEAR(spot_profile(cone, std::cos(th)), profile_ref({0, 0, -1}, 1.0, 0.3, dir), 1e-14) << th;
    }
    const SpotCone hard = make_spot_cone({0, 0, -1}, 1.0, 0.0);
    EXPECT_EQ(spot_profile(hard, std::cos(0.49)), std::cos(0.49));
    EXPECT_EQ(spot_profile(hard, std::cos(0.51)), 0.0);
}

TEST(SpotProfile, IesProfileInAConeOrAloneWithinItsExtent) {
    // A spot's IES (SpotLight::profile_in_cone): Cycles' factor times max(0, I(c)).
    SpotLight spot;
    spot.spot_size = 1.0;
    spot.spot_blend = 0.3;
    spot.profile = {0.5, -1.0, 2.0};
    spot.profile_in_cone = true;
    const SpotCone in_cone = make_light_cone(spot);
    for (double th : {0.0, 0.2, 0.4, 0.45, 0.49, 0.6}) {
        const double c = std::cos(th);
        const glm::dvec3 dir(std::sin(th), 0.0, -c);
        EXPECT_NEAR(spot_profile(in_cone, c), profile_ref({0, 0, -1}, 1.0, 0.3, dir) * std::max(0.0, 0.5 - c + 2 * c * c),
                    1e-14)
            << th;
    }
    // A point light's (profile alone): the polynomial over the sphere, clamped at 0, or dark
    // beyond its extent.
    spot.profile_in_cone = false;
    spot.spot_size = kPi;
    spot.spot_blend = 0.0;
    spot.profile = {0.1, 1.0};
    const SpotCone whole = make_light_cone(spot);
    EXPECT_NEAR(spot_profile(whole, -0.05), 0.05, 1e-15);
    EXPECT_EQ(spot_profile(whole, -0.5), 0.0);
    spot.profile_extent = 1.0;
    const SpotCone cut = make_light_cone(spot);
    EXPECT_NEAR(spot_profile(cut, std::cos(0.99)), 0.1 + std::cos(0.99), 1e-15);
    EXPECT_EQ(spot_profile(cut, std::cos(1.01)), 0.0);
}

TEST(SpotCrossings, PointsLieOnTheCone) {
    std::mt19937 rng(3);
    std::uniform_real_distribution<double> U(-1.0, 1.0);
    int found = 0;
    for (int trial = 0; trial < 200; ++trial) {
        const glm::dvec3 o(3 * U(rng), 3 * U(rng), 3 * U(rng)), d = glm::normalize(glm::dvec3(U(rng), U(rng), U(rng)));
        const glm::dvec3 s(U(rng), U(rng), U(rng)), axis = glm::normalize(glm::dvec3(U(rng), U(rng), U(rng)));
        const double ch = std::cos(0.2 + 1.3 * (U(rng) + 1.0) / 2.0);
        for (double x : ray_cone_crossings(o, d, s, axis, ch, 0.0, 100.0)) {
            const glm::dvec3 u = glm::normalize(o + x * d - s);
            EXPECT_NEAR(std::abs(glm::dot(u, axis)), ch, 1e-9);
            ++found;
        }
    }
    EXPECT_GT(found, 50);
}

struct Case {
    glm::dvec3 s, axis;
    double size, blend, sigma;
    glm::dvec3 o, d;
    double Dvp, g;
};

TEST(SpotAirlight, MatchesBruteForceMidpoint) {
    const Case cases[] = {
        // hard edge, ray crossing the cone below the lamp
        {{0, 0, 5}, {0, 0, -1}, 0.8, 0.0, 0.2, {-6, -1, 1}, {1, 0.1, 0}, 12.0, 0.0},
        // soft edge, ray passing under the lamp
        {{0, 0, 5}, {0, 0, -1}, 1.2, 0.4, 0.1, {-6, 1, 0}, {1, 0, 0.05}, 15.0, 0.0},
        // oblique spot, ray from inside the cone outward, thick fog
        {{1, 2, 3}, {0.3, -0.2, -1}, 1.0, 0.15, 0.5, {1, 2, 1}, {0.2, 1, 0.3}, 8.0, 0.0},
        // ray ending inside the cone
        {{0, 0, 4}, {0, 0.5, -1}, 0.9, 0.0, 0.3, {0, -5, 0}, {0, 1, 0.1}, 5.3, 0.0},
        // wide spot, viewer looking along the axis toward the lamp (the cone around the ray)
        {{0, 0, 6}, {0, 0, -1}, 2.5, 0.2, 0.15, {0.5, 0, 0}, {0, 0, 1}, 5.0, 0.0},
        // forward-scattering HG
        {{0, 0, 5}, {0, 0, -1}, 1.0, 0.2, 0.2, {-6, 0.5, 1}, {1, 0, 0.1}, 12.0, 0.6},
        // backward HG, hard edge
        {{0, 0, 5}, {0.2, 0, -1}, 0.7, 0.0, 0.2, {-6, 0.5, 1}, {1, 0, 0.1}, 12.0, -0.4},
    };
    for (const Case& c : cases) {
        const SpotCone cone = make_spot_cone(c.axis, c.size, c.blend);
        PhaseFunction phase;
        if (c.g != 0.0) phase = PhaseFunction{PhaseKind::HenyeyGreenstein, c.g};
        const glm::dvec3 d = glm::normalize(c.d);
        const double q = spot_airlight_quadrature(cone, c.s, phase, c.sigma, c.o, d, c.Dvp, 1e-9);
        const double b = brute(c.s, c.axis, c.size, c.blend, c.sigma, c.o, d, c.Dvp, c.g);
        EXPECT_GT(b, 0.0) << "size " << c.size;
        // The midpoint rule converges only O(h) at a hard step: 400k steps put it within ~1e-5.
        EXPECT_NEAR(q, b, 2e-5 * b) << "size " << c.size << " blend " << c.blend;
    }
}

TEST(SpotAirlight, DarkRayIsZero) {
    const SpotCone cone = make_spot_cone({0, 0, -1}, 0.5, 0.1);
    // A ray above the lamp never enters the downward cone.
    EXPECT_EQ(spot_airlight_quadrature(cone, {0, 0, 5}, PhaseFunction{}, 0.1, {-6, 0, 8}, {1, 0, 0}, INFINITY), 0.0);
}

// size = 180 deg, blend 0: a point light times cos(theta) on the lit half-space only.
// Reference: plain adaptive quadrature of that integrand split at the plane crossing.
TEST(SpotAirlight, HemisphereLimitEqualsCosineWeightedPointLight) {
    const glm::dvec3 s(0, 0, 5), axis(0, 0, -1);
    const SpotCone cone = make_spot_cone(axis, kPi, 0.0);
    const double sigma = 0.15;
    const glm::dvec3 o(-4, 0.3, 1), d = glm::normalize(glm::dvec3(1, 0, 0.9));  // crosses z = 5 at x ~ 4.4
    for (double Dvp : {3.0, 8.0, 30.0, double(INFINITY)}) {
        auto f = [&](double x) {
            const glm::dvec3 u = o + x * d - s;
            const double r = glm::length(u);
            const double c = glm::dot(u / r, axis);
            return c > 0.0 ? c * std::exp(-sigma * (r + x)) / (r * r) / (4 * kPi) : 0.0;
        };
        const double x_plane = (s.z - o.z) / d.z;
        double ref = sigma * integrate_adaptive(f, 0.0, std::min(Dvp, x_plane), 1e-12);
        const double q = spot_airlight_quadrature(cone, s, PhaseFunction{}, sigma, o, d, Dvp, 1e-9);
        EXPECT_NEAR(q, ref, 1e-8 * ref) << Dvp;
    }
}

// A spot whose cone contains the whole ray (wide cone, lamp far above, blend 0) and whose
// profile is nearly constant equals the point-light reference times that constant to the
// profile's variation.
TEST(SpotAirlight, FullyLitRayBoundedByPointLight) {
    const glm::dvec3 s(0, 0, 50), axis(0, 0, -1);
    const SpotCone cone = make_spot_cone(axis, 2.0, 0.0);
    const glm::dvec3 o(-2, 0, 0), d(1, 0, 0);
    const double sigma = 0.05, Dvp = 4.0;
    const double Dsv = glm::length(s - o), cg = glm::dot(d, (s - o) / Dsv);
    const double point = sun05_airlight_quadrature(sigma, Dsv, cg, Dvp, 1e-12);
    const double q = spot_airlight_quadrature(cone, s, PhaseFunction{}, sigma, o, d, Dvp, 1e-10);
    // cos(theta) along the ray lies in [cos(atan(2/50)), 1].
    EXPECT_LE(q, point);
    EXPECT_GE(q, point * std::cos(std::atan(2.0 / 50.0)));
}

}  // namespace
}  // namespace airlight
