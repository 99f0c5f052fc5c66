// march_test.cpp: the light-space depth map against the exact optical depth, and the marched
// airlight against the adaptive quadrature (gaussian_airlight_quadrature), on random clouds
// with the light and the camera inside and outside Gaussians.
#include "gaussian/light_depth_map.h"
#include "gaussian/march.h"
#include "gaussian/sun_depth_map.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <random>

#include "gaussian/airlight.h"

namespace airlight {
namespace {

// _n_ Gaussians uniform in [-w, w] x [-2, 6] x [10, 10 + depth], widths 1/a in [w0, w1],
// amplitudes in [c0, c1] (the benchmark's cloud: 3000, 30, 70, 1, 3, 0.01, 0.05).
GaussianMedium cloud(int n, double w, double depth, double w0, double w1, double c0, double c1, double beta0,
                     unsigned seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> ux(-w, w), uy(-2.0, 6.0), uz(10.0, 10.0 + depth), uw(w0, w1), uc(c0, c1);
    std::vector<double> b, a, c;
    for (int i = 0; i < n; ++i) {
        b.insert(b.end(), {ux(rng), uy(rng), uz(rng)});
        a.push_back(1.0 / uw(rng));
        c.push_back(uc(rng));
    }
    return GaussianMedium(b, a, c, beta0);
}

struct DepthErrors {
    double mean = 0.0, max = 0.0;
};

DepthErrors map_errors(const GaussianMedium& m, const LightDepthMap& map, int points, unsigned seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> ux(-14.0, 14.0), uy(-2.0, 6.0), uz(8.0, 42.0);
    DepthErrors e;
    for (int k = 0; k < points; ++k) {
        const Vec3 x(ux(rng), uy(rng), uz(rng));
        const double exact = m.optical_depth(map.light(), x) - m.beta0() * glm::length(x - map.light());
        const double err = std::abs(map(x) - exact);
        e.mean += err / points;
        e.max = std::max(e.max, err);
    }
    return e;
}

// Interpolation converges at second order: a finer map errs about a quarter as much, and the
// 64 x 256 map's depths are within 1 % of a mean depth of ~1 (the cloud's light paths).
TEST(LightDepthMap, MatchesTheExactDepth) {
    const GaussianMedium m = cloud(400, 12.0, 30.0, 0.5, 2.0, 0.02, 0.1, 0.002, 11);
    const Vec3 s(-2.0, 1.5, 22.0);  // inside the cloud
    const LightDepthMap coarse(m, s, 32, 128, 2), fine(m, s, 64, 256, 2);
    const DepthErrors ec = map_errors(m, coarse, 3000, 5), ef = map_errors(m, fine, 3000, 5);
    std::printf("[ depth map ] 32x128: mean %.2e max %.2e; 64x256: mean %.2e max %.2e\n", ec.mean, ec.max, ef.mean,
                ef.max);
    EXPECT_LT(ef.mean, 0.4 * ec.mean);
    EXPECT_LT(ef.mean, 0.01);
    // The direction of a grid point itself (a corner of the +z face), at one of its
    // distances, is exact up to float and fast_erf_diff (1e-5).
    const double r = 30.0 * fine.max_radius() / 255.0;
    const Vec3 axis = s + r * glm::normalize(Vec3(-1.0, -1.0, 1.0));
    const double exact = m.optical_depth(s, axis) - m.beta0() * r;
    EXPECT_NEAR(fine(axis), exact, 2e-5 * exact + 1e-6);
}

TEST(LightDepthMap, EmptyAndDegenerate) {
    const GaussianMedium empty({}, {}, {}, 0.01);
    const LightDepthMap map(empty, Vec3(1.0, 2.0, 3.0), 8, 8, 1);
    EXPECT_EQ(map(Vec3(4.0, 5.0, 6.0)), 0.0);
    EXPECT_EQ(map(Vec3(1.0, 2.0, 3.0)), 0.0);  // the light itself
    EXPECT_THROW(LightDepthMap(empty, Vec3(0.0), 1, 8, 1), std::invalid_argument);
    EXPECT_THROW(LightDepthMap(empty, Vec3(NAN, 0.0, 0.0), 8, 8, 1), std::invalid_argument);
    // A light at a Gaussian's centre: every direction starts inside it.
    const GaussianMedium one({0.0, 0.0, 0.0}, {1.0}, {0.5}, 0.0);
    const LightDepthMap centred(one, Vec3(0.0), 48, 192, 1);
    for (const Vec3& x : {Vec3(0.3, 0.1, -0.2), Vec3(-2.0, 1.0, 0.5), Vec3(0.0, 0.0, 9.0)})
        EXPECT_NEAR(centred(x), one.optical_depth(Vec3(0.0), x), 2e-3 * one.optical_depth(Vec3(0.0), x));
}

double relative(double x, double ref) { return std::abs(x - ref) / ref; }

// Rays from outside and inside the cloud, to surfaces and to infinity; an HG phase; a light
// inside the cloud and one at a Gaussian's centre.
// A spot's map holds its cone and a margin: there it reads what the whole sphere's map does
// (the same grid points), beyond the margin 0; a 60 degree cone down the -y axis needs the -y
// face alone (its edge at 30 degrees off the axis, the face's at 35 at least).
TEST(LightDepthMap, SpotConeOnly) {
    const GaussianMedium m = cloud(400, 12.0, 30.0, 0.5, 2.0, 0.02, 0.1, 0.0, 11);
    const Vec3 s(0.0, 8.0, 25.0);
    const Vec3 axis(0.0, -1.0, 0.0);
    const double half = 30.0 * kPi / 180.0;
    const LightDepthMap whole(m, s, 64, 128, 2), spot(m, s, axis, half, 64, 128, 2);
    EXPECT_EQ(whole.faces_held(), 6);
    EXPECT_EQ(spot.faces_held(), 1);
    EXPECT_EQ(spot.bytes() * 6, whole.bytes());
    std::mt19937 rng(3);
    std::uniform_real_distribution<double> u(-1.0, 1.0), ur(1.0, 30.0);
    int inside = 0, outside = 0;
    for (int k = 0; k < 4000; ++k) {
        const Vec3 w = glm::normalize(Vec3(u(rng), u(rng), u(rng)));
        const Vec3 x = s + ur(rng) * w;
        const double angle = std::acos(std::clamp(glm::dot(w, axis), -1.0, 1.0));
        if (angle <= half) {
            ++inside;
            EXPECT_EQ(spot(x), whole(x)) << angle;
        } else if (angle > half + 6.0 * 2.0 / 63.0) {  // (the reach, 3 cells, and a read's 4 x 4 points)
            ++outside;
            EXPECT_EQ(spot(x), 0.0);
        }
    }
    EXPECT_GT(inside, 100);
    EXPECT_GT(outside, 100);
    // A wide cone (150 degrees) reaches five faces; an axis of zero length is refused.
    EXPECT_EQ(LightDepthMap(m, s, axis, 75.0 * kPi / 180.0, 16, 16, 1).faces_held(), 5);
    EXPECT_THROW(LightDepthMap(m, s, Vec3(0.0), half, 16, 16, 1), std::invalid_argument);
}

TEST(GaussianMarch, MatchesTheQuadrature) {
    const GaussianMedium m = cloud(150, 10.0, 25.0, 0.6, 2.0, 0.02, 0.15, 0.002, 3);
    const PhaseFunction iso{}, hg{PhaseKind::HenyeyGreenstein, 0.5};
    const Vec3 lights[] = {Vec3(-2.0, 1.5, 20.0), m.centre(17)};
    const Vec3 eyes[] = {Vec3(0.0, 0.5, 0.0), m.centre(40)};
    double worst_exact = 0.0, worst_map = 0.0, worst_coarse = 0.0;
    int rays = 0;
    for (const Vec3& s : lights) {
        const LightDepthMap map(m, s, 64, 256, 2);
        for (const Vec3& v : eyes)
            for (const Vec3& dir : {Vec3(0.1, 0.05, 1.0), Vec3(-0.25, 0.1, 1.0), Vec3(0.3, -0.1, 1.0), Vec3(0.0, 0.0, -1.0)})
                for (double Dvp : {12.0, double(INFINITY)})
                    for (const PhaseFunction* phase : {&iso, &hg}) {
                        const Vec3 r = glm::normalize(dir);
                        GaussianRefLight light{GaussianRefLight::Kind::Point, s};
                        const double ref =
                            gaussian_airlight_quadrature(m, light, *phase, v, r, Dvp, 1e-9, GaussianSums::Culled);
                        GaussianMarch march;
                        const double exact = gaussian_march_airlight(m, s, *phase, v, r, Dvp, nullptr, march);
                        const double mapped = gaussian_march_airlight(m, s, *phase, v, r, Dvp, &map, march);
                        ASSERT_GT(ref, 0.0);
                        EXPECT_LT(relative(exact, ref), 2e-5) << "ray " << rays;
                        EXPECT_LT(relative(mapped, ref), 5e-3) << "ray " << rays;
                        // For a 1 % target: a tenth of it.
                        GaussianMarch coarse;
                        coarse.set_accuracy(0.01);
                        const double fast = gaussian_march_airlight(m, s, *phase, v, r, Dvp, nullptr, coarse);
                        EXPECT_LT(relative(fast, ref), 1e-3) << "ray " << rays;
                        worst_coarse = std::max(worst_coarse, relative(fast, ref));
                        worst_exact = std::max(worst_exact, relative(exact, ref));
                        worst_map = std::max(worst_map, relative(mapped, ref));
                        ++rays;
                    }
    }
    std::printf("[ march ] %d rays: exact light depth %.2e, 64x256 map %.2e, 1 %% steps %.2e relative at most\n", rays,
                worst_exact, worst_map, worst_coarse);
}

// Thick Gaussians (optical depths ~20-60 through one): the steps shorten to the extinction and
// halve at the shadows' and rims' edges; the light beside and inside the thick ones. The
// coarser steps of a 1 % target (set_accuracy) stay within a tenth of it.
TEST(GaussianMarch, ThickFog) {
    const GaussianMedium m = cloud(40, 6.0, 15.0, 0.5, 1.5, 10.0, 30.0, 0.01, 9);
    double worst = 0.0, worst_coarse = 0.0;
    for (const Vec3& s : {Vec3(0.0, 1.0, 12.0), m.centre(5)})
        for (const Vec3& dir : {Vec3(0.1, 0.05, 1.0), Vec3(-0.2, 0.1, 1.0), Vec3(0.05, -0.02, 1.0)}) {
            const Vec3 r = glm::normalize(dir);
            const double ref = gaussian_airlight_quadrature(m, s, Vec3(0.0), r, 40.0, 1e-9, GaussianSums::Culled);
            GaussianMarch march, coarse;
            const double got = gaussian_march_airlight(m, s, PhaseFunction{}, Vec3(0.0), r, 40.0, nullptr, march);
            coarse.set_accuracy(0.01);
            const double fast = gaussian_march_airlight(m, s, PhaseFunction{}, Vec3(0.0), r, 40.0, nullptr, coarse);
            ASSERT_GT(ref, 0.0);
            EXPECT_LT(relative(got, ref), 1e-4) << s.x << " " << dir.x;
            EXPECT_LT(relative(fast, ref), 1e-3) << s.x << " " << dir.x << " (1 % steps)";
            EXPECT_LE(coarse.steps, march.steps);
            worst = std::max(worst, relative(got, ref));
            worst_coarse = std::max(worst_coarse, relative(fast, ref));
        }
    // One Gaussian of optical depth ~350 through its centre between the light and rays that
    // pass it at 0.3-2 widths: its shadow's edge crosses each ray within a fraction of a width.
    const GaussianMedium one({0.0, 0.0, 10.0}, {1.0}, {200.0}, 0.001);
    for (double offset : {0.4, 0.9, 1.6, 2.8})
        for (const Vec3& s : {Vec3(0.0, 0.0, 13.0), Vec3(0.3, 0.0, 10.0)}) {
            const Vec3 r = glm::normalize(Vec3(offset, 0.0, 10.0));
            const double ref = gaussian_airlight_quadrature(one, s, Vec3(0.0), r, 30.0, 1e-9, GaussianSums::Culled);
            GaussianMarch march;
            const double got = gaussian_march_airlight(one, s, PhaseFunction{}, Vec3(0.0), r, 30.0, nullptr, march);
            ASSERT_GT(ref, 0.0);
            EXPECT_LT(relative(got, ref), 1e-4) << "offset " << offset << " light x " << s.x;
            worst = std::max(worst, relative(got, ref));
        }
    std::printf("[ march ] thick fog: %.2e relative at most (1 %% steps in the cloud: %.2e)\n", worst, worst_coarse);
}

// Lit spans (volumetric shadows): the march over the spans equals the quadrature with the
// same visibility; albedos: each Gaussian's scatters in its own colour, the uniform fog in its.
TEST(GaussianMarch, LitSpansAndAlbedo) {
    const GaussianMedium m = cloud(60, 6.0, 15.0, 0.6, 1.5, 0.05, 0.4, 0.01, 21);
    const Vec3 s(0.5, 1.0, 16.0), v(0.0);
    const std::vector<std::pair<double, double>> spans = {{2.0, 11.5}, {13.0, 14.2}, {17.0, 30.0}};
    const RaySpans lit{spans.data(), int(spans.size())};
    for (Vec3 r : {Vec3(0.05, 0.05, 1.0), Vec3(-0.1, 0.1, 1.0)}) {
        r = glm::normalize(r);
        GaussianRefLight light{GaussianRefLight::Kind::Point, s};
        light.visible = [&](const Vec3& x) {
            const double t = glm::dot(x - v, r);
            for (const auto& span : spans)
                if (span.first <= t && t < span.second) return true;
            return false;
        };
        for (const auto& span : spans) light.jumps.insert(light.jumps.end(), {span.first, span.second});
        const double ref = gaussian_airlight_quadrature(m, light, PhaseFunction{}, v, r, 40.0, 1e-9, GaussianSums::Culled);
        GaussianMarch march;
        march.lit = &lit;
        const double got = gaussian_march_airlight(m, s, PhaseFunction{}, v, r, 40.0, nullptr, march);
        ASSERT_GT(ref, 0.0);
        EXPECT_LT(relative(got, ref), 2e-5);
        // Albedo: red Gaussians in green uniform fog are the sum of two marches, each with one
        // medium's albedo (linear in sigma_s with the extinction unchanged).
        std::vector<double> albedo;
        for (std::size_t i = 0; i < m.size(); ++i) albedo.insert(albedo.end(), {0.8, 0.0, 0.0});
        GaussianMarch coloured;
        coloured.albedo = albedo.data(), coloured.medium_albedo = RGB(0.0, 0.5, 0.0);
        const RGB La = gaussian_march_airlight_rgb(m, s, PhaseFunction{}, v, r, 40.0, nullptr, coloured);
        GaussianMarch plain;
        const double all = gaussian_march_airlight(m, s, PhaseFunction{}, v, r, 40.0, nullptr, plain);
        EXPECT_EQ(La.z, 0.0);
        EXPECT_NEAR(La.x / 0.8 + La.y / 0.5, all, 2e-5 * all);
        EXPECT_GT(La.x, 0.0);
        EXPECT_GT(La.y, 0.0);
    }
}

// A spot light (march.cone): hard-edged, blended and Spread cones over the cloud, rays that
// cross the cone and its blend cone, an HG phase; against the quadrature with the spot's
// breakpoints. With the 1 % steps too, and a map.
TEST(GaussianMarch, SpotMatchesTheQuadrature) {
    const GaussianMedium m = cloud(120, 8.0, 20.0, 0.6, 2.0, 0.03, 0.3, 0.005, 5);
    const Vec3 s(-1.0, 6.0, 14.0), v(0.0);
    const Vec3 axis = glm::normalize(Vec3(0.1, -1.0, 0.05));
    const PhaseFunction hg{PhaseKind::HenyeyGreenstein, 0.4};
    double worst = 0.0, worst_coarse = 0.0;
    int lit = 0;
    for (const SpotCone& cone : {make_spot_cone(axis, 0.8, 0.0), make_spot_cone(axis, 1.2, 0.4),
                                 make_spot_cone(axis, kPi, 0.0, 0.6)}) {
        // (the map of the cone alone, as the bake builds it)
        const LightDepthMap map(m, s, cone.axis, std::acos(cone.cos_half_angle), 64, 256, 2);
        for (Vec3 r : {Vec3(0.0, 0.2, 1.0), Vec3(-0.15, 0.25, 1.0), Vec3(0.2, 0.1, 1.0)}) {
            r = glm::normalize(r);
            for (double Dvp : {25.0, double(INFINITY)}) {
                GaussianRefLight light{GaussianRefLight::Kind::Spot, s};
                light.cone = cone;
                const double ref = gaussian_airlight_quadrature(m, light, hg, v, r, Dvp, 1e-9, GaussianSums::Culled);
                GaussianMarch march, coarse, mapped;
                march.cone = coarse.cone = mapped.cone = &cone;
                march.emission_max = coarse.emission_max = mapped.emission_max =
                    cone.has_spread() ? std::max(1.0, cone.spread_a) : 1.0;
                coarse.set_accuracy(0.01), mapped.set_accuracy(0.01);
                const double got = gaussian_march_airlight(m, s, hg, v, r, Dvp, nullptr, march);
                const double fast = gaussian_march_airlight(m, s, hg, v, r, Dvp, nullptr, coarse);
                const double with_map = gaussian_march_airlight(m, s, hg, v, r, Dvp, &map, mapped);
                if (ref == 0.0) {  // (a ray that misses the cone: it stops once past the cone's crossings)
                    EXPECT_EQ(got, 0.0);
                    EXPECT_LT(coarse.steps, 200);
                    continue;
                }
                ++lit;
                EXPECT_LT(relative(got, ref), 2e-5) << "cos " << cone.cos_half_angle << " ray " << r.x;
                EXPECT_LT(relative(fast, ref), 1e-3) << "cos " << cone.cos_half_angle << " ray " << r.x;
                EXPECT_LT(relative(with_map, ref), 5e-3) << "cos " << cone.cos_half_angle << " ray " << r.x;
                worst = std::max(worst, relative(got, ref));
                worst_coarse = std::max(worst_coarse, relative(fast, ref));
            }
        }
    }
    EXPECT_GE(lit, 8);
    std::printf("[ march ] spots: %d rays, %.2e relative at most (1 %% steps %.2e)\n", lit, worst, worst_coarse);
}

// An IES-like profile (profile alone, over the whole sphere) dark in a band between two lit
// lobes, I(c) = 4c^2 - 1 clamped at 0: no cone crossing bounds it, so a ray through the lobe,
// the band and the other lobe is marched through all three (a march that stopped in the dark
// band, as past a hard cone's last crossing, lost the second lobe).
TEST(GaussianMarch, ProfileDarkBandIsCrossed) {
    const GaussianMedium m = cloud(60, 8.0, 20.0, 0.6, 2.0, 0.03, 0.3, 0.01, 7);
    const Vec3 s(0.0, 2.0, 18.0), v(-20.0, 3.0, 18.0), r(1.0, 0.0, 0.0);
    const SpotCone cone = make_profile_cone(Vec3(1.0, 0.0, 0.0), {-1.0, 0.0, 4.0});
    GaussianRefLight light{GaussianRefLight::Kind::Spot, s};
    light.cone = cone;
    const PhaseFunction iso{};
    const double Dvp = 40.0;
    const double ref = gaussian_airlight_quadrature(m, light, iso, v, r, Dvp, 1e-9, GaussianSums::Culled);
    // (the second lobe's share: the same ray from the band on)
    const double second = gaussian_airlight_quadrature(m, light, iso, v + 21.0 * r, r, Dvp - 21.0, 1e-9,
                                                       GaussianSums::Culled);
    ASSERT_GT(second, 0.05 * ref);
    GaussianMarch march;
    march.cone = &cone;
    march.emission_max = 3.0;
    const double got = gaussian_march_airlight(m, s, iso, v, r, Dvp, nullptr, march);
    EXPECT_LT(relative(got, ref), 1e-4) << got << " " << ref;
    // From the band itself (no cone crossing, dark at the start) the ray still reaches the lobe.
    GaussianMarch from_band;
    from_band.cone = &cone;
    from_band.emission_max = 3.0;
    const double got2 = gaussian_march_airlight(m, s, iso, v + 20.0 * r, r, Dvp - 20.0, nullptr, from_band);
    const double ref2 = gaussian_airlight_quadrature(m, light, iso, v + 20.0 * r, r, Dvp - 20.0, 1e-9,
                                                     GaussianSums::Culled);
    EXPECT_LT(relative(got2, ref2), 1e-4) << got2 << " " << ref2;
}

// Without Gaussians the march is the uniform fog's airlight (Sun 2005's integral).
TEST(GaussianMarch, UniformFogLimit) {
    const GaussianMedium m({}, {}, {}, 0.05);
    const Vec3 s(3.0, 4.0, 2.0), v(0.5, -0.2, 1.0);
    for (Vec3 r : {Vec3(1, 0, 0), Vec3(3, 4, 0.5), Vec3(0.2, 0.1, -1)}) {
        r = glm::normalize(r);
        for (double Dvp : {0.5, 7.0, double(INFINITY)}) {
            const double ref = gaussian_airlight_quadrature(m, s, v, r, Dvp, 1e-10);
            GaussianMarch march;
            EXPECT_NEAR(gaussian_march_airlight(m, s, PhaseFunction{}, v, r, Dvp, nullptr, march) / ref, 1.0, 1e-5);
        }
    }
}

// The sun's map: its depth against the exact half-line depth towards the sun, converging at
// second order; 0 above and beside the cloud, the column's whole depth below it.
TEST(SunDepthMap, MatchesTheExactDepth) {
    const GaussianMedium m = cloud(400, 12.0, 30.0, 0.5, 2.0, 0.02, 0.1, 0.002, 11);
    const Vec3 u = glm::normalize(Vec3(0.3, 0.8, -0.5));  // towards the sun (w = -u)
    const SunDepthMap coarse(m, u, 64, 256, 2), fine(m, u, 128, 256, 2);
    auto exact = [&](const Vec3& x) { return m.optical_depth_ray(x, u, INFINITY, GaussianMedium::npos, false); };
    std::mt19937 rng(5);
    std::uniform_real_distribution<double> ux(-14.0, 14.0), uy(-6.0, 6.0), uz(8.0, 42.0);
    double ec = 0.0, ef = 0.0, depth = 0.0;
    const int points = 3000;
    for (int k = 0; k < points; ++k) {
        const Vec3 x(ux(rng), uy(rng), uz(rng));
        const double T = exact(x);
        ec += std::abs(coarse(x) - T) / points, ef += std::abs(fine(x) - T) / points, depth += T / points;
    }
    std::printf("[ sun depth map ] mean depth %.3f; 64x256: mean error %.2e; 128x256: %.2e\n", depth, ec, ef);
    EXPECT_GT(depth, 0.1);
    EXPECT_LT(ef, 0.4 * ec);
    EXPECT_LT(ef, 0.01 * depth);
    // Far above the cloud towards the sun, and far beside it: nothing; far below it (against
    // the light): the whole column.
    EXPECT_EQ(fine(Vec3(0.0, 2.0, 25.0) + 200.0 * u), 0.0);
    const Vec3 side = glm::normalize(glm::cross(u, Vec3(0.0, 0.0, 1.0)));
    EXPECT_EQ(fine(Vec3(0.0, 2.0, 25.0) + 200.0 * side), 0.0);
    const Vec3 below = Vec3(0.0, 2.0, 25.0) - 200.0 * u;
    EXPECT_NEAR(fine(below), exact(below), 0.01 * exact(below) + 1e-4);
    EXPECT_GT(exact(below), 0.1);
    // The footprint holds every point with depth: its clip of a ray holds the shaded part.
    const SunFootprint& f = fine.footprint();
    const Vec3 o(0.0, -20.0, 25.0), r = glm::normalize(Vec3(0.05, 1.0, 0.02));
    const auto [t0, t1] = f.clip(o, r);
    for (double t = 0.0; t < 60.0; t += 0.25)
        if (!(t >= t0 && t <= t1)) EXPECT_LT(exact(o + t * r), 1e-5) << t;
    EXPECT_LT(t0, t1);
    const GaussianMedium empty({}, {}, {}, 0.01);
    EXPECT_EQ(SunDepthMap(empty, u, 8, 8, 1)(Vec3(1.0)), 0.0);
    EXPECT_THROW(SunDepthMap(m, Vec3(0.0), 8, 8, 1), std::invalid_argument);
    EXPECT_THROW(SunDepthMap(m, u, 1, 8, 1), std::invalid_argument);
}

// A sun lamp: rays from outside and inside the cloud, to surfaces and to infinity, isotropic
// and HG phases, without and with the uniform fog's layer top (through the cloud, the
// camera inside the layer or above it); the sun oblique and straight overhead. Exact light depths, the
// map, and the 1 % steps against the quadrature (GaussianRefLight::Kind::Sun).
TEST(GaussianMarch, SunMatchesTheQuadrature) {
    const GaussianMedium m = cloud(150, 10.0, 25.0, 0.6, 2.0, 0.02, 0.15, 0.004, 3);
    const PhaseFunction iso{}, hg{PhaseKind::HenyeyGreenstein, 0.5};
    const Vec3 eyes[] = {Vec3(0.0, 0.5, 0.0), m.centre(40)};
    double worst_exact = 0.0, worst_map = 0.0, worst_coarse = 0.0;
    int rays = 0;
    for (const Vec3& w : {glm::normalize(Vec3(0.3, -0.8, -0.5)), Vec3(0.0, 0.0, -1.0)})
        for (double top : {double(INFINITY), 14.0}) {  // (the cloud spans z 10-35: rays cross the top)
            const Vec3 u = -w;
            const SunDepthMap map(m, u, 128, 256, 2);
            for (const Vec3& v : eyes)
                for (const Vec3& dir :
                     {Vec3(0.1, 0.05, 1.0), Vec3(-0.25, 0.1, 1.0), Vec3(0.3, -0.1, 1.0), Vec3(0.0, 0.4, 1.0)})
                    for (double Dvp : {12.0, double(INFINITY)})
                        for (const PhaseFunction* phase : {&iso, &hg}) {
                            const Vec3 r = glm::normalize(dir);
                            GaussianRefLight light;
                            light.kind = GaussianRefLight::Kind::Sun;
                            light.w = w, light.fog_top = top;
                            const double ref =
                                gaussian_airlight_quadrature(m, light, *phase, v, r, Dvp, 1e-9, GaussianSums::Culled);
                            GaussianMarch march;
                            const double exact = gaussian_march_sun(m, u, top, *phase, v, r, Dvp, nullptr, march);
                            const double mapped = gaussian_march_sun(m, u, top, *phase, v, r, Dvp, &map, march);
                            GaussianMarch coarse;
                            coarse.set_accuracy(0.01);
                            const double fast = gaussian_march_sun(m, u, top, *phase, v, r, Dvp, &map, coarse);
                            ASSERT_GT(ref, 0.0) << "ray " << rays;
                            EXPECT_LT(relative(exact, ref), 2e-5) << "ray " << rays;
                            EXPECT_LT(relative(mapped, ref), 5e-3) << "ray " << rays;
                            EXPECT_LT(relative(fast, ref), 5e-3) << "ray " << rays;
                            worst_exact = std::max(worst_exact, relative(exact, ref));
                            worst_map = std::max(worst_map, relative(mapped, ref));
                            worst_coarse = std::max(worst_coarse, relative(fast, ref));
                            ++rays;
                        }
        }
    std::printf("[ sun march ] %d rays: exact light depth %.2e, 128x256 map %.2e, with 1 %% steps %.2e relative at most\n",
                rays, worst_exact, worst_map, worst_coarse);
}

// The benchmark's 3000-Gaussian cloud (bench_gaussian_accuracy.py's "3000 x 1" drawn again
// here): the map's build, and per ray the quadrature, the exact march and the mapped march.
// ctest -R GaussianMarch.DISABLED_Profile3000 --gtest_also_run_disabled_tests -V
TEST(GaussianMarch, DISABLED_Profile3000) {
    using Clock = std::chrono::steady_clock;
    auto seconds = [](Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); };
    const GaussianMedium m = cloud(3000, 30.0, 70.0, 1.0, 3.0, 0.01, 0.05, 0.002, 2);
    const Vec3 s(-8.0, 4.0, 30.0), v(0.0);
    for (int face : {64, 128}) {
        auto t0 = Clock::now();
        const LightDepthMap map(m, s, face, 256, 2);
        std::printf("map %dx%dx256: %.2f s on 2 threads, %.0f MB\n", face, face, seconds(t0), map.bytes() * 1e-6);
        for (Vec3 r : {Vec3(0.1, 0.05, 1), Vec3(-0.25, 0.1, 1), Vec3(0.3, -0.1, 1), Vec3(-0.05, -0.05, 1)}) {
            r = glm::normalize(r);
            const double Dvp = r.y < 0.0 ? -2.0 / r.y : INFINITY;
            t0 = Clock::now();
            const double ref = gaussian_airlight_quadrature(m, s, v, r, Dvp, 1e-5, GaussianSums::Culled);
            const double t_ref = seconds(t0);
            GaussianMarch march;
            t0 = Clock::now();
            const double exact = gaussian_march_airlight(m, s, PhaseFunction{}, v, r, Dvp, nullptr, march);
            const double t_exact = seconds(t0);
            t0 = Clock::now();
            const double mapped = gaussian_march_airlight(m, s, PhaseFunction{}, v, r, Dvp, &map, march);
            const double t_map = seconds(t0);
            std::printf("  ray: quadrature %.3e in %.2f s; march exact %+.1e in %.3f s; mapped %+.1e in %.2f ms, %ld steps, "
                        "%.2g s a unit of density work\n",
                        ref, t_ref, exact / ref - 1.0, t_exact, mapped / ref - 1.0, 1e3 * t_map, march.steps,
                        t_map / double(march.work));
        }
    }
}

}  // namespace
}  // namespace airlight
