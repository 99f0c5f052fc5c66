// sphere_light_test.cpp: a light's radius: the disk falloff against a brute-force integral
// over the disk, the ray rule against adaptive quadrature, and the limits (r -> 0, far away).
#include "homogeneous/sphere_light.h"

#include <gtest/gtest.h>

#include <cmath>

#include "core/constants.h"
#include "core/quadrature.h"

namespace airlight {
namespace {

// (1 / (pi r^2)) int_disk cos e^{-sigma rho} / rho^2 dA by adaptive quadrature over the
// disk's radius s (the disk faces the point: rho^2 = d^2 + s^2, cos = d / rho).
double disk_brute(double sigma, double d, double r) {
    auto f = [&](double s) {
        const double rho = std::sqrt(d * d + s * s);
        return 2.0 * kPi * s * (d / rho) * std::exp(-sigma * rho) / (rho * rho);
    };
    return integrate_adaptive(f, 0.0, r, 1e-12) / (kPi * r * r);
}

TEST(SphereLightFalloff, MatchesTheDiskIntegral) {
    for (double sigma : {0.0, 0.01, 0.3, 2.0, 20.0})
        for (double r : {0.01, 0.5, 3.0})
            for (double d : {1e-3, 0.1, 0.5, 1.0, 4.0, 30.0, 300.0}) {
                const double ref = disk_brute(sigma, d, r);
                if (ref < 1e-250) continue;
                EXPECT_NEAR(sphere_light_falloff(sigma, d, r) / ref, 1.0, 1e-9)
                    << "sigma " << sigma << " d " << d << " r " << r;
            }
}

TEST(SphereLightFalloff, Limits) {
    // r -> 0: the point's e^{-sigma d} / d^2; r = 0 exactly too.
    for (double sigma : {0.0, 0.2, 5.0}) {
        const double point = std::exp(-sigma * 2.0) / 4.0;
        EXPECT_NEAR(sphere_light_falloff(sigma, 2.0, 1e-6) / point, 1.0, 1e-10);
        EXPECT_EQ(sphere_light_falloff(sigma, 2.0, 0.0), point);
        // At the light: 2 / r^2 whatever sigma; finite just beside it.
        EXPECT_DOUBLE_EQ(sphere_light_falloff(sigma, 0.0, 0.5), 8.0);
        EXPECT_NEAR(sphere_light_falloff(sigma, 1e-12, 0.5), 8.0, 1e-6);
    }
    // The reach: there within kSphereTol of the point (the expansion
    // 1 - (r^2 / 4)(3 / d^2 + sigma / d)), and closer beyond it.
    EXPECT_NEAR(sphere_light_reach(0.0, 0.1), kSphereReach * 0.1, 1e-6);
    for (double sigma : {0.0, 0.1, 1.0, 30.0}) {
        const double r = 0.1, d = sphere_light_reach(sigma, r);
        EXPECT_GE(d, kSphereReach * r - 1e-9);
        const double point = std::exp(-sigma * d) / (d * d);
        const double rel = 1.0 - sphere_light_falloff(sigma, d, r) / point;
        EXPECT_GT(rel, 0.0);
        if (sigma * r < 0.2) EXPECT_NEAR(rel, kSphereTol, 5e-6) << sigma;
        else EXPECT_DOUBLE_EQ(d, std::max(kSphereReach * r, 10.0 / sigma));  // cut at 10 optical depths
        const double rel2 = 1.0 - sphere_light_falloff(sigma, 2.0 * d, r) * (4.0 * d * d) / std::exp(-sigma * 2.0 * d);
        EXPECT_LT(rel2, 0.6 * rel) << sigma;
    }
    // Dense fog about a big light: cut at 10 optical depths.
    EXPECT_NEAR(sphere_light_reach(2.0, 1.0), std::max(kSphereReach, 5.0), 1e-9);
}

TEST(SphereFalloffTable, MatchesTheClosedForm) {
    for (double sigma : {0.0, 0.05, 0.5, 5.0})
        for (double r : {0.02, 0.5, 2.0}) {
            const SphereFalloff table(sigma, r);
            const double reach = sphere_light_reach(sigma, r);
            double worst = 0.0;
            for (int i = 0; i <= 4000; ++i) {
                const double rho = reach * (i / 4000.0) * (i / 4000.0);
                const double exact = sphere_light_falloff(sigma, rho, r);
                if (exact > 0.0) worst = std::max(worst, std::abs(table(rho) / exact - 1.0));
            }
            EXPECT_LT(worst, sigma * r <= 1.0 ? 2e-5 : 2e-4) << sigma << " " << r;  // 1.3e-4 at sigma r = 10
            EXPECT_EQ(table(2.0 * reach), sphere_light_falloff(sigma, 2.0 * reach, r));  // beyond: the closed form
        }
}

TEST(SphereLightAirlight, MatchesQuadrature) {
    const Vec3 s(0.3, -0.2, 10.0);
    for (PhaseFunction phase : {PhaseFunction{}, PhaseFunction{PhaseKind::HenyeyGreenstein, 0.6},
                                PhaseFunction{PhaseKind::HenyeyGreenstein, -0.4},
                                PhaseFunction{PhaseKind::HenyeyGreenstein, 0.9}})
        for (double sigma : {0.05, 0.5, 3.0})
            for (double r : {0.05, 0.5, 2.0})
                for (double h : {0.0, 0.3 * r, r, 4.0 * r, 20.0 * r}) {
                    const Vec3 o(0.0), d = glm::normalize(Vec3(s.x + h, s.y, s.z));  // closest approach ~h
                    double a = 0.0, b = 0.0;
                    if (!sphere_light_window(sigma, s, r, o, d, 0.0, 40.0, a, b)) continue;
                    for (double end : {b, 0.5 * (a + b), glm::dot(s, d) + 0.5 * r}) {
                        if (!(end > a)) continue;
                        const SphereFalloff table(sigma, r);
                        const double got = sphere_light_airlight(phase, sigma, s, r, o, d, a, end, 0.0, nullptr, {},
                                                                 h == r ? &table : nullptr);
                        const double ref = sphere_light_airlight_quadrature(phase, sigma, s, r, o, d, a, end, 0.0, 1e-10);
                        EXPECT_NEAR(got / ref, 1.0, 5e-5) << "g " << phase.g << " sigma " << sigma << " r " << r
                                                          << " h " << h << " end " << end;
                    }
                }
}

// The point light's airlight over [a, b] by adaptive quadrature (phase p).
double point_quadrature(const PhaseFunction& phase, double sigma, const Vec3& s, const Vec3& o, const Vec3& d,
                        double a, double b) {
    auto f = [&](double t) {
        const Vec3 sx = s - (o + t * d);
        const double rho = glm::length(sx);
        return phase.eval(glm::dot(sx, d) / rho) * std::exp(-sigma * (t + rho)) / (rho * rho);
    };
    return sigma * integrate_cut(f, a, b, {glm::dot(s - o, d)}, 1e-12);
}

TEST(SphereLightSeries, MatchesTheDiskLessThePoint) {
    const Vec3 s(0.3, -0.2, 10.0);
    for (PhaseFunction phase : {PhaseFunction{}, PhaseFunction{PhaseKind::HenyeyGreenstein, 0.7}})
        for (double sigma : {0.02, 0.3, 2.0})
            for (double r : {0.05, 0.5})
                for (double h_r : {4.0, 8.0, 19.0}) {
                    const double h = h_r * r;
                    if (!sphere_light_series_applies(sigma, r, h)) continue;
                    const Vec3 o(0.0), d = glm::normalize(Vec3(s.x + h * 10.0 / glm::length(s), s.y, s.z));
                    const Vec3 so = s - o;
                    const double tc = glm::dot(so, d), hh = std::sqrt(glm::dot(so, so) - tc * tc);
                    double a = 0.0, b = 0.0;
                    ASSERT_TRUE(sphere_light_window(sigma, s, r, o, d, 0.0, 40.0, a, b));
                    const double point = point_quadrature(phase, sigma, s, o, d, a, b);
                    const double exact = sphere_light_airlight_quadrature(phase, sigma, s, r, o, d, a, b, 0.0, 1e-12) - point;
                    const double got = sphere_light_excess_series(phase, sigma, s, r, o, d, a, b, 0.0);
                    EXPECT_LT(exact, 0.0);
                    EXPECT_NEAR(got / point, exact / point, 2e-4)
                        << "g " << phase.g << " sigma " << sigma << " r " << r << " h/r " << hh / r;
                }
    // Close to the light or in dense fog about a big one, the series is not used.
    EXPECT_FALSE(sphere_light_series_applies(0.1, 1.0, 3.9));
    EXPECT_FALSE(sphere_light_series_applies(10.0, 1.0, 5.0));
    // Rays beyond the reach (27.4 radii in clear fog at kSphereTol) are left to the point: the
    // bound r^2 (3 + sigma h) / (4 h^2) on the relative change anywhere on the ray.
    EXPECT_TRUE(sphere_light_matters(0.0, 1.0, 27.3));
    EXPECT_FALSE(sphere_light_matters(0.0, 1.0, 27.5));
    EXPECT_TRUE(sphere_light_matters(0.3, 0.4, 5.0, 5e-3));   // 7.2e-3: dense fog raises the bound
    EXPECT_FALSE(sphere_light_matters(0.3, 0.4, 6.5, 5e-3));  // 4.7e-3
}

TEST(SphereLightAirlight, TinyRadiusIsThePoint) {
    // A small disk far (in radii) from the ray: the point light's airlight (Sun 2005 eq. 5).
    const Vec3 s(1.0, 0.0, 8.0), o(0.0), d(0.0, 0.0, 1.0);
    const double sigma = 0.4, r = 1e-3;
    const double got = sphere_light_airlight(PhaseFunction{}, sigma, s, r, o, d, 0.0, 16.0, 0.0);
    const double Dsv = glm::length(s), cos_gamma = s.z / Dsv;
    EXPECT_NEAR(got / sun05_airlight_quadrature(sigma, Dsv, cos_gamma, 16.0, 1e-12), 1.0, 1e-6);
}

TEST(SphereLightWindow, ClipsToTheReach) {
    const Vec3 s(0.0, 1.0, 5.0), o(0.0), d(0.0, 0.0, 1.0);
    double a = 0.0, b = 0.0;
    EXPECT_FALSE(sphere_light_window(0.0, s, 0.999 / kSphereReach, o, d, 0.0, 10.0, a, b));  // h just beyond the reach
    EXPECT_FALSE(sphere_light_window(0.0, s, 0.0, o, d, 0.0, 10.0, a, b));  // a point light
    ASSERT_TRUE(sphere_light_window(0.0, s, 0.1, o, d, 0.0, 10.0, a, b));
    const double reach = sphere_light_reach(0.0, 0.1), half = std::sqrt(reach * reach - 1.0);
    EXPECT_NEAR(a, 5.0 - half, 1e-12);
    EXPECT_NEAR(b, 5.0 + half, 1e-12);
    ASSERT_TRUE(sphere_light_window(0.0, s, 0.1, o, d, 4.0, 5.5, a, b));  // the segment's own ends
    EXPECT_EQ(a, 4.0);
    EXPECT_EQ(b, 5.5);
    EXPECT_FALSE(sphere_light_window(0.0, s, 0.1, o, d, 9.0, 10.0, a, b));
}

// The shadow samples project onto the disk facing any direction uniformly: across many
// directions and chords, the share of samples beyond a chord is the disk's area share there, to
// within a few times the stratified set's error (about 0.7 / n^0.7 r.m.s., half of random
// points' ~0.4 / sqrt(n) at n = 32); and E|x|^2 is the design density's 3/4.
TEST(SphereLightShadowSamples, ProjectUniformlyOntoTheFacingDisk) {
    EXPECT_EQ(sphere_light_shadow_samples(1).size(), 1u);
    EXPECT_EQ(sphere_light_shadow_samples(1)[0], Vec3(0.0));
    for (int n : {4, 8, 16, 32, 64}) {
        const std::vector<Vec3> q = sphere_light_shadow_samples(n);
        ASSERT_EQ(q.size(), size_t(n));
        double r2 = 0.0;
        Vec3 mean(0.0);
        for (const Vec3& p : q) {
            EXPECT_LE(glm::length(p), 1.0);
            r2 += glm::dot(p, p) / n;
            mean += p / double(n);
        }
        EXPECT_NEAR(r2, 0.75, 0.6 / n) << n;
        EXPECT_LT(glm::length(mean), 1e-12) << n;  // mirrored pairs
        for (const Vec3& p : q) EXPECT_LE(glm::length(q[0]), glm::length(p)) << n;  // nearest the centre first
        double sq = 0.0;
        int trials = 0;
        for (int i = 0; i < 40; ++i) {
            // Directions on a spiral over the sphere, chords at offsets c across the disk.
            const double z = 1.0 - (2.0 * i + 1.0) / 40.0, phi = 2.399963 * i;
            const Vec3 d(std::sqrt(1.0 - z * z) * std::cos(phi), std::sqrt(1.0 - z * z) * std::sin(phi), z);
            const Vec3 a = glm::normalize(glm::cross(d, std::abs(d.z) < 0.9 ? Vec3(0, 0, 1) : Vec3(1, 0, 0)));
            for (double c = -0.9; c < 0.95; c += 0.1) {
                int beyond = 0;
                for (const Vec3& p : q) beyond += glm::dot(p, a) > c;
                const double exact = (std::acos(c) - c * std::sqrt(1.0 - c * c)) / kPi;
                sq += std::pow(double(beyond) / n - exact, 2);
                ++trials;
            }
        }
        EXPECT_LT(std::sqrt(sq / trials), 1.5 * 0.7 * std::pow(n, -0.7)) << n;
    }
}

// A sun's shadow directions lie within its disk, spread over it: their tangent-plane points'
// mean is near the centre and their mean squared radius the disk's 1/2.
TEST(SunShadowDirections, CoverTheDisk) {
    const Vec3 w = glm::normalize(Vec3(0.3, -0.2, -1.0));
    EXPECT_EQ(sun_shadow_directions(w, 0.1, 1)[0], w);
    EXPECT_EQ(sun_shadow_directions(w, 0.0, 16).size(), 1u);
    for (int n : {8, 16, 32}) {
        const double angle = 0.2, t = std::tan(0.5 * angle);
        const std::vector<Vec3> d = sun_shadow_directions(w, angle, n);
        ASSERT_EQ(d.size(), size_t(n));
        Vec3 mean(0.0);
        double r2 = 0.0;
        for (const Vec3& v : d) {
            EXPECT_NEAR(glm::length(v), 1.0, 1e-12);
            EXPECT_LE(std::acos(std::min(1.0, glm::dot(v, w))), 0.5 * angle + 1e-12);
            const Vec3 q = v / glm::dot(v, w) - w;  // the point in the tangent plane
            mean += q / (t * n);
            r2 += glm::dot(q, q) / (t * t * n);
        }
        EXPECT_LT(glm::length(mean), 0.15) << n;
        EXPECT_NEAR(r2, 0.5, 0.5 / n) << n;
    }
}

}  // namespace
}  // namespace airlight
