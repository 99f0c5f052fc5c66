// airlight_test.cpp: Fogshop airlight against the quadrature reference and analytic
// limits, and the measured error of the approximation on smooth fog and on the paper's
// failure cases (a light next to a Gaussian, a light shaft through a hole).
#include "core/constants.h"
#include "gaussian/airlight.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <stdexcept>

#include "homogeneous/biri06.h"
#include "homogeneous/spot_light.h"
#include "homogeneous/sun05.h"
#include "homogeneous/sunlight_layer.h"

namespace airlight {
namespace {


struct ErrorStats {
    double mean = 0.0, p99 = 0.0, max = 0.0;
};

ErrorStats stats(std::vector<double> e) {
    ErrorStats s;
    if (e.empty()) return s;
    for (double x : e) s.mean += x;
    s.mean /= e.size();
    std::sort(e.begin(), e.end());
    s.p99 = e[std::min(e.size() - 1, static_cast<std::size_t>(0.99 * e.size()))];
    s.max = e.back();
    return s;
}

// Rays from _v_ over a small image looking along +z (unit directions).
std::vector<Vec3> image_rays(int w, int h, double half_angle) {
    std::vector<Vec3> dirs;
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            const double u = ((x + 0.5) / w * 2.0 - 1.0) * std::tan(half_angle);
            const double v = ((y + 0.5) / h * 2.0 - 1.0) * std::tan(half_angle) * h / w;
            dirs.push_back(glm::normalize(Vec3(u, v, 1.0)));
        }
    return dirs;
}

// Relative errors of the approximation against the reference on a ray set.
ErrorStats compare(const GaussianMedium& m, const Vec3& light, const Vec3& v, const std::vector<Vec3>& dirs,
                   const std::vector<double>& Dvp, const char* label) {
    const std::size_t n = dirs.size();
    std::vector<double> fog(n), ref(n), err;
    gaussian_airlight(m, {light}, v, dirs.data(), Dvp.data(), n, fog.data(), GaussianAirlightModel::Fogshop, nullptr, 2);
    gaussian_airlight(m, {light}, v, dirs.data(), Dvp.data(), n, ref.data(), GaussianAirlightModel::Quadrature, nullptr, 2);
    double ref_max = 0.0;
    for (double r : ref) ref_max = std::max(ref_max, r);
    for (std::size_t j = 0; j < n; ++j) {
        EXPECT_TRUE(std::isfinite(fog[j])) << label << " ray " << j;
        EXPECT_GE(fog[j], 0.0) << label << " ray " << j;
        // Relative to the ray's own reference, ignoring rays 1e-6 below the image's peak.
        if (ref[j] > 1e-6 * ref_max) err.push_back(std::abs(fog[j] - ref[j]) / ref[j]);
    }
    const ErrorStats s = stats(err);
    std::printf("[ gaussians ] fogshop vs quadrature, %s: %zu rays, relative error mean %.4f p99 %.4f max %.4f\n", label,
                err.size(), s.mean, s.p99, s.max);
    return s;
}

// The reference reproduces Sun 2005 on a homogeneous medium (validates the quadrature).
TEST(GaussianAirlight, QuadratureMatchesSun05OnHomogeneous) {
    const GaussianMedium m({}, {}, {}, 0.05);
    const Vec3 v(0.0), s(3.0, 4.0, 2.0);
    for (Vec3 r : {Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(-1, -1, 0), Vec3(3, 4, 2.1)}) {
        r = glm::normalize(r);
        for (double Dvp : {0.5, 7.0, 100.0, double(INFINITY)}) {
            const double cg = glm::dot(r, s - v) / glm::length(s - v);
            const double ref = sun05_airlight(0.05, glm::length(s - v), cg, Dvp, nullptr, FEval::Exact);
            EXPECT_NEAR(gaussian_airlight_quadrature(m, s, v, r, Dvp) / ref, 1.0, 1e-7);
        }
    }
}

// The reference on a faint Gaussian far from the light: La -> T_i(v, p) / (4 pi D^2).
TEST(GaussianAirlight, QuadratureThinLimit) {
    const double a = 0.8, c = 1e-7, D = 1e5;
    const GaussianMedium m({0, 0, 5}, {a}, {c}, 0.0);
    const Vec3 v(0, 0, 0), s(D, 0, 5), r(0, 0, 1);
    const double expect = c * std::sqrt(kPi) / a / (4.0 * kPi * D * D);
    EXPECT_NEAR(gaussian_airlight_quadrature(m, s, v, r, INFINITY) / expect, 1.0, 1e-6);
}

// The generalised reference (GaussianRefLight, any phase) on a homogeneous medium against the
// homogeneous models' own references: HG point light (phase_airlight_quadrature), spot
// (spot_airlight_quadrature), sun with and without a fog top (sunlight_layer_factor, closed form).
TEST(GaussianAirlight, GeneralQuadratureHomogeneousLimits) {
    const double beta0 = 0.05;
    const GaussianMedium m({}, {}, {}, beta0);
    const Vec3 v(0.5, -0.2, 1.0), s(3.0, 4.0, 2.0);
    const PhaseFunction hg{PhaseKind::HenyeyGreenstein, 0.6};
    GaussianRefLight sun;
    sun.kind = GaussianRefLight::Kind::Sun;
    sun.w = glm::normalize(Vec3(0.3, -0.4, -0.8));
    GaussianRefLight spot{GaussianRefLight::Kind::Spot, s, make_spot_cone(Vec3(-0.3, -0.8, -0.2), 1.0, 0.3)};
    int lit = 0;  // rays the spot lights
    for (Vec3 r : {Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(-1, -1, 0), Vec3(3, 4, 0.5), Vec3(0.2, 0.1, -1)}) {
        r = glm::normalize(r);
        for (double Dvp : {0.5, 7.0, 100.0, double(INFINITY)}) {
            const double Dsv = glm::length(s - v), cg = glm::dot(r, s - v) / Dsv;
            const double point_ref = phase_airlight_quadrature(hg, beta0, Dsv, cg, Dvp, 1e-10);
            GaussianRefLight point{GaussianRefLight::Kind::Point, s};
            EXPECT_NEAR(gaussian_airlight_quadrature(m, point, hg, v, r, Dvp) / point_ref, 1.0, 1e-6);
            const double spot_ref = spot_airlight_quadrature(spot.cone, s, hg, beta0, v, r, Dvp, 1e-10);
            const double spot_q = gaussian_airlight_quadrature(m, spot, hg, v, r, Dvp);
            EXPECT_NEAR(spot_q, spot_ref, 1e-6 * spot_ref + 1e-15);
            lit += spot_ref > 0.0;
            for (double top : {double(INFINITY), 4.0}) {
                sun.fog_top = top;
                const double sun_ref = beta0 * hg.eval(-glm::dot(sun.w, r)) *
                                       sunlight_layer_factor(beta0, top, -sun.w.z, v.z, r.z, 0.0, Dvp);
                EXPECT_NEAR(gaussian_airlight_quadrature(m, sun, hg, v, r, Dvp) / sun_ref, 1.0, 1e-6)
                    << "top " << top << " Dvp " << Dvp;
            }
        }
    }
    EXPECT_GE(lit, 6);
}

// The culled sums (the bake's QUADRATURE) do the reference's integral: 250 Gaussians over a
// box with a point light, a spot and a sun among them, rays into and across the cloud, an HG
// phase. Every skipped Gaussian adds below cull_eps() (1e-7) to an optical depth, and as
// little to the ray's density integral: measured 2.2e-6 of a ray's airlight at most.
TEST(GaussianAirlight, CulledSumsMatchTheReference) {
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> ux(-12.0, 12.0), uy(-2.0, 4.0), uz(5.0, 40.0), ua(0.5, 2.0), uc(0.02, 0.3);
    std::vector<double> b, a, c;
    for (int i = 0; i < 250; ++i) {
        b.insert(b.end(), {ux(rng), uy(rng), uz(rng)});
        a.push_back(ua(rng));
        c.push_back(uc(rng));
    }
    const GaussianMedium m(b, a, c, 0.002);
    const PhaseFunction hg{PhaseKind::HenyeyGreenstein, 0.4};
    const Vec3 v(0.0, 0.5, 0.0);
    GaussianRefLight point{GaussianRefLight::Kind::Point, Vec3(-3.0, 1.0, 18.0)};
    GaussianRefLight spot{GaussianRefLight::Kind::Spot, Vec3(4.0, 5.0, 25.0),
                          make_spot_cone(Vec3(-0.2, -1.0, 0.1), 0.9, 0.2)};
    GaussianRefLight sun;
    sun.kind = GaussianRefLight::Kind::Sun;
    sun.w = glm::normalize(Vec3(0.3, -0.8, 0.4));
    int rays = 0;
    for (const Vec3& d : image_rays(4, 2, 0.5))
        for (double Dvp : {15.0, 60.0, double(INFINITY)})
            for (const GaussianRefLight* light : {&point, &spot, &sun}) {
                const double all = gaussian_airlight_quadrature(m, *light, hg, v, d, Dvp, 1e-8, GaussianSums::All);
                const double culled = gaussian_airlight_quadrature(m, *light, hg, v, d, Dvp, 1e-8, GaussianSums::Culled);
                EXPECT_NEAR(culled, all, 1e-5 * all + 1e-14) << "ray " << rays;
                rays += all > 0.0;
            }
    EXPECT_GE(rays, 50);
}

// No Gaussians: the Fogshop model is exactly Sun 2005 with beta0 (table and exact F).
TEST(GaussianAirlight, EmptyMediumIsSun05) {
    const GaussianMedium m({}, {}, {}, 0.03);
    const SpecialFTable table(256, 256);
    const Vec3 v(1, 2, 3);
    const std::vector<Vec3> lights{{4, 2, 7}, {-3, 5, 0}};
    const std::vector<Vec3> dirs = image_rays(16, 12, 0.6);
    std::vector<double> Dvp;
    for (std::size_t j = 0; j < dirs.size(); ++j) Dvp.push_back(j % 5 == 0 ? INFINITY : 1.0 + j * 0.3);
    for (const SpecialFTable* t : {static_cast<const SpecialFTable*>(nullptr), &table}) {
        std::vector<double> out(dirs.size() * lights.size());
        gaussian_airlight(m, lights, v, dirs.data(), Dvp.data(), dirs.size(), out.data(), GaussianAirlightModel::Fogshop, t, 2);
        for (std::size_t j = 0; j < dirs.size(); ++j)
            for (std::size_t l = 0; l < lights.size(); ++l) {
                const Vec3 sv = lights[l] - v;
                const double D = glm::length(sv);
                const double ref = sun05_airlight(0.03, D, std::clamp(glm::dot(dirs[j], sv) / D, -1.0, 1.0), Dvp[j], t,
                                                  t ? FEval::Table : FEval::Exact);
                EXPECT_DOUBLE_EQ(out[j * 2 + l], ref);
            }
    }
}

// One Gaussian, light well outside it: the approximation is close to the reference.
TEST(GaussianAirlight, SingleGaussianMatchesQuadrature) {
    // T through the centre c sqrt(pi) / a = 0.18.
    const GaussianMedium m({0, 0, 10}, {0.5}, {0.05}, 0.0);
    const Vec3 v(0.0), light(0, 12, 10);
    const std::vector<Vec3> dirs = image_rays(16, 16, 0.35);
    const std::vector<double> Dvp(dirs.size(), INFINITY);
    const ErrorStats s = compare(m, light, v, dirs, Dvp, "single Gaussian, light 12 m away");
    EXPECT_LT(s.mean, 0.02);
    EXPECT_LT(s.max, 0.05);
}

// Smooth fog: 30 broad overlapping Gaussians (1/a = 3.3 .. 6.7 m) over a thin background,
// light outside the cloud, at three optical thicknesses. The error grows with the optical
// depth of the cloud (the approximation assumes f(x) varies slowly across each Gaussian,
// and attenuates Gaussian i by the rest of the medium along s -> b_i -> v only), so the
// bound is asserted for the thin and moderate clouds and the thick one is reported.
ErrorStats smooth_fog(double amplitude_scale, const char* label) {
    std::mt19937_64 rng(3);
    std::uniform_real_distribution<double> U(0.0, 1.0);
    std::vector<double> b, a, c;
    for (int i = 0; i < 30; ++i) {
        b.insert(b.end(), {20.0 * U(rng) - 10.0, 6.0 * U(rng) - 3.0, 30.0 + 20.0 * U(rng) - 10.0});
        a.push_back(0.15 + 0.15 * U(rng));
        c.push_back(amplitude_scale * (0.02 + 0.04 * U(rng)));
    }
    const GaussianMedium m(b, a, c, 0.01);
    const Vec3 v(0.0), light(4.0, 40.0, 30.0);
    const std::vector<Vec3> dirs = image_rays(16, 12, 0.45);
    std::vector<double> Dvp;
    for (std::size_t j = 0; j < dirs.size(); ++j) Dvp.push_back(j % 3 == 0 ? 40.0 : INFINITY);
    double T = 0.0;
    for (const Vec3& d : dirs) T = std::max(T, m.optical_depth_ray(v, d, 60.0) - 0.6);
    std::printf("[ gaussians ] %s: max optical depth of the Gaussians along a ray %.2f\n", label, T);
    return compare(m, light, v, dirs, Dvp, label);
}

TEST(GaussianAirlight, SmoothFogErrorThin) {
    const ErrorStats s = smooth_fog(0.01, "smooth fog, thin (c 2e-4..6e-4 /m)");
    EXPECT_LT(s.mean, 0.01);
    EXPECT_LT(s.p99, 0.03);
}

TEST(GaussianAirlight, SmoothFogErrorModerate) {
    const ErrorStats s = smooth_fog(0.25, "smooth fog, moderate (c 0.005..0.015 /m)");
    EXPECT_LT(s.mean, 0.20);
    EXPECT_LT(s.p99, 0.50);
}

TEST(GaussianAirlight, SmoothFogErrorThickReported) {
    const ErrorStats s = smooth_fog(1.0, "smooth fog, thick (c 0.02..0.06 /m), reported only");
    EXPECT_TRUE(std::isfinite(s.max));
}

// Failure case 1: a light 0.5 widths from a Gaussian's centre (halo). Reported, not bounded.
TEST(GaussianAirlight, FailureHaloNearLight) {
    const GaussianMedium m({0, 0, 10}, {1.0}, {0.5}, 0.0);
    const Vec3 v(0.0), light(0.5, 0.0, 10.0);
    const std::vector<Vec3> dirs = image_rays(16, 16, 0.3);
    const std::vector<double> Dvp(dirs.size(), INFINITY);
    const ErrorStats s = compare(m, light, v, dirs, Dvp, "FAILURE CASE halo (light 0.5/a from a Gaussian)");
    EXPECT_TRUE(std::isfinite(s.max));
}

// Failure case 2 (paper Fig. 7): a dense wall of Gaussians with a hole between the light
// and a thin background fog; the shaft through the hole lights only part of each ray, but
// L_0 attenuates a whole ray by the one factor C_sv of the segment s -> v.
TEST(GaussianAirlight, FailureShaftThroughHole) {
    std::vector<double> b, a, c;
    const double spacing = 0.75;  // the paint brush's default spacing 0.75 / a, a = 1
    for (double x = -8.0; x <= 8.0; x += spacing)
        for (double y = -8.0; y <= 8.0; y += spacing) {
            if (x * x + y * y < 1.5 * 1.5) continue;  // the hole
            b.insert(b.end(), {x, y, 20.0});
            a.push_back(1.0);
            c.push_back(2.0);
        }
    const GaussianMedium m(b, a, c, 0.05);
    const Vec3 light(0.0, 0.0, 12.0);  // in front of the wall; shaft behind it, along +z
    const Vec3 v(-10.0, 0.0, 24.0);    // beside the shaft, behind the wall
    std::vector<Vec3> dirs;
    for (int k = 0; k < 32; ++k) {
        const double ang = -0.6 + 1.2 * (k + 0.5) / 32.0;
        dirs.push_back(glm::normalize(Vec3(std::cos(ang), 0.0, std::sin(ang))));
    }
    const std::vector<double> Dvp(dirs.size(), 30.0);
    const ErrorStats s = compare(m, light, v, dirs, Dvp, "FAILURE CASE light shaft through a hole (Fig. 7)");
    EXPECT_TRUE(std::isfinite(s.max));
}

// eval_rgb_spans's fast form (float erf differences and exps, airlight_batch.h) against the
// double one: a cloud with a light inside a Gaussian and one outside, a sun, a forward phase,
// several lit spans (one of them infinite) and a near plane inside a Gaussian.
TEST(GaussianAirlight, FastSpansMatchDouble) {
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> U(0.0, 1.0);
    std::vector<double> b, a, c;
    for (int i = 0; i < 300; ++i) {
        b.insert(b.end(), {-6.0 + 12.0 * U(rng), -4.0 + 8.0 * U(rng), 4.0 + 20.0 * U(rng)});
        a.push_back(0.5 + 1.5 * U(rng));
        c.push_back(i % 7 == 0 ? 2.0 : 0.02 + 0.1 * U(rng));
    }
    b.insert(b.end(), {0.1, 0.0, 0.2}), a.push_back(1.0), c.push_back(0.5);  // (around the near plane)
    const GaussianMedium m(b, a, c, 0.01);
    const std::vector<Vec3> lights{Vec3(b[0], b[1], b[2]), Vec3(3.0, 5.0, 12.0)};
    const FogshopAirlight fog(m, Vec3(0.0), lights, nullptr, 1, {glm::normalize(Vec3(0.3, -1.0, 0.2))});
    const PhaseFunction hg{PhaseKind::HenyeyGreenstein, 0.6};
    // (No uniform-fog term: the Gaussian terms alone.)
    const FogshopAirlight::SpanBackground background = [](std::size_t, double, double) { return 0.0; };
    const std::vector<double> albedo(3 * 301, 0.8);
    const std::vector<RGB> I0{RGB(1.0), RGB(2.0, 1.0, 0.5), RGB(0.3)};
    const std::vector<std::pair<double, double>> lit{{0.3, 7.0}, {9.0, 15.5}, {18.0, INFINITY}};
    const std::vector<std::pair<double, double>> whole{{0.3, 30.0}};
    int compared = 0;
    for (const Vec3& dir : image_rays(12, 8, 0.4)) {
        for (const auto* spans : {&lit, &whole}) {
            const RaySpans one{spans->data(), int(spans->size())};
            const RaySpans each[3] = {one, one, one};
            for (const PhaseFunction* phase : {static_cast<const PhaseFunction*>(nullptr), &hg}) {
                const RGB exact =
                    fog.eval_rgb_spans(dir, 0.3, each, albedo.data(), I0.data(), RGB(0.9), phase, &background);
                const RGB fast = fog.eval_rgb_spans(dir, 0.3, each, albedo.data(), I0.data(), RGB(0.9), phase,
                                                    &background, nullptr, true);
                ASSERT_GT(exact.x, 0.0);
                for (int ch = 0; ch < 3; ++ch) EXPECT_NEAR(fast[ch], exact[ch], 3e-5 * exact[ch]) << "channel " << ch;
                ++compared;
            }
        }
    }
    EXPECT_EQ(compared, 12 * 8 * 4);
}

TEST(GaussianAirlight, RejectsBadInput) {
    const GaussianMedium m({0, 0, 1}, {1.0}, {1.0}, 0.0);
    const Vec3 d(0, 0, 1), bad_d(0, 0, 2);
    double Dvp = 1.0, bad_Dvp = -1.0, nan = NAN, out[1];
    const std::vector<Vec3> lights{{1, 1, 1}};
    EXPECT_THROW(gaussian_airlight(m, lights, Vec3(0), &bad_d, &Dvp, 1, out, GaussianAirlightModel::Fogshop, nullptr),
                 std::invalid_argument);
    EXPECT_THROW(gaussian_airlight(m, lights, Vec3(0), &d, &bad_Dvp, 1, out, GaussianAirlightModel::Fogshop, nullptr),
                 std::invalid_argument);
    EXPECT_THROW(gaussian_airlight(m, lights, Vec3(0), &d, &nan, 1, out, GaussianAirlightModel::Fogshop, nullptr),
                 std::invalid_argument);
    EXPECT_THROW(gaussian_airlight(m, {Vec3(NAN)}, Vec3(0), &d, &Dvp, 1, out, GaussianAirlightModel::Fogshop, nullptr),
                 std::invalid_argument);
}

}  // namespace
}  // namespace airlight
