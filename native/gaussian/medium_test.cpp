// medium_test.cpp: the Gaussian store's optical depth against quadrature of the
// density, the erf-difference numerics against analytic limits, culling against the
// brute-force sum, and input validation.
#include "gaussian/medium.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <stdexcept>

#include "core/constants.h"
#include "core/quadrature.h"

namespace airlight {
namespace {

GaussianMedium single(const Vec3& b, double a, double c, double beta0 = 0.0) {
    return GaussianMedium({b.x, b.y, b.z}, {a}, {c}, beta0);
}

// int_p^q beta(x) by adaptive quadrature of the density itself (split at the centre's
// projection and +-k/a so the peak is resolved).
double depth_by_quadrature(const GaussianMedium& m, const Vec3& p, const Vec3& q) {
    const double L = glm::length(q - p);
    const Vec3 r = (q - p) / L;
    std::vector<double> cuts{0.0, L};
    for (std::size_t i = 0; i < m.size(); ++i) {
        const double ts = glm::dot(m.centre(i) - p, r);
        for (double k : {-8.0, -4.0, -2.0, -1.0, 0.0, 1.0, 2.0, 4.0, 8.0}) {
            const double t = ts + k / m.scale(i);
            if (t > 0.0 && t < L) cuts.push_back(t);
        }
    }
    std::sort(cuts.begin(), cuts.end());
    double sum = 0.0;
    for (std::size_t j = 0; j + 1 < cuts.size(); ++j)
        sum += integrate_adaptive([&](double t) { return m.density(p + t * r); }, cuts[j], cuts[j + 1], 1e-13);
    return sum;
}

// erf_diff reproduces closed forms and stays accurate where the plain difference fails.
TEST(ErfDiff, LimitsAndTails) {
    EXPECT_DOUBLE_EQ(erf_diff(-INFINITY, INFINITY), 2.0);
    EXPECT_DOUBLE_EQ(erf_diff(0.0, INFINITY), 1.0);
    EXPECT_NEAR(erf_diff(-1.0, 1.0), 2.0 * std::erf(1.0), 1e-15);
    EXPECT_EQ(erf_diff(1.0, 1.0), 0.0);
    EXPECT_EQ(erf_diff(2.0, 1.0), 0.0);
    // Far tail: erf(11) - erf(10) rounds to 0 in double; the true value is ~erfc(10).
    EXPECT_NEAR(erf_diff(10.0, 11.0) / std::erfc(10.0), 1.0 - std::erfc(11.0) / std::erfc(10.0), 1e-14);
    EXPECT_NEAR(erf_diff(-11.0, -10.0) / std::erfc(10.0), 1.0 - std::erfc(11.0) / std::erfc(10.0), 1e-14);
    // Short interval: the derivative 2/sqrt(pi) e^{-x^2} times the width.
    // (w is the representable width (x + 1e-9) - x, not 1e-9.)
    const double x = 5.0, w = (x + 1e-9) - x;
    EXPECT_NEAR(erf_diff(x, x + w) / (2.0 / kSqrtPi * std::exp(-x * x) * w), 1.0, 1e-8);
    EXPECT_NEAR(erf_diff(-x - w, -x) / (2.0 / kSqrtPi * std::exp(-x * x) * w), 1.0, 1e-8);
}

// Infinite line through the centre: c sqrt(pi) / a exactly; ray from the centre: half.
TEST(GaussianMedium, ClosedFormsOnLines) {
    for (double a : {1e-3, 0.1, 1.0, 37.0, 1e3}) {
        const GaussianMedium m = single({1.0, 2.0, 3.0}, a, 0.7);
        const Vec3 r = glm::normalize(Vec3(1.0, -2.0, 0.5));
        const double full = 0.7 * kSqrtPi / a;
        const double far = 1e4 / a;
        EXPECT_NEAR(m.optical_depth_all(Vec3(1, 2, 3) - far * r, Vec3(1, 2, 3) + far * r) / full, 1.0, 1e-13);
        EXPECT_NEAR(m.optical_depth_ray(Vec3(1, 2, 3), r, INFINITY) / (0.5 * full), 1.0, 1e-13);
        // Line at distance h: the Gaussian factor exp(-a^2 h^2).
        const Vec3 off = glm::normalize(glm::cross(r, Vec3(0, 0, 1)));
        const double h = 2.5 / a;
        const Vec3 o = Vec3(1, 2, 3) + h * off - far * r;
        // (o lies 1e4 widths out, so h itself carries ~1e-12 relative rounding.)
        EXPECT_NEAR(m.optical_depth_ray(o, r, INFINITY) / (full * std::exp(-a * a * h * h)), 1.0, 1e-10);
    }
}

// Segments of every kind against quadrature of the density: through, beside, in the far
// tails on one side (where erf differences cancel), short and long, tiny and huge scales.
TEST(GaussianMedium, SegmentsMatchQuadratureOfDensity) {
    std::mt19937_64 rng(7);
    std::uniform_real_distribution<double> U(-1.0, 1.0);
    double worst = 0.0;
    int compared = 0;
    for (double a : {1e-3, 0.05, 1.0, 20.0, 1e3}) {
        const Vec3 b(0.3, -0.2, 0.1);
        const GaussianMedium m = single(b, a, 1.3);
        for (int k = 0; k < 60; ++k) {
            const double scale = 1.0 / a;
            const Vec3 dir = glm::normalize(Vec3(U(rng), U(rng), U(rng)));
            const Vec3 side = glm::normalize(glm::cross(dir, Vec3(U(rng), U(rng), U(rng))));
            const double h = scale * 3.0 * std::abs(U(rng));          // up to 3 widths off the centre
            const double t0 = scale * (k % 3 == 0 ? 2.0 + 6.0 * std::abs(U(rng)) : 8.0 * U(rng));  // tails
            const double len = scale * std::pow(10.0, 2.0 * U(rng));  // 0.01 .. 100 widths
            const Vec3 p = b + h * side + t0 * dir, q = p + len * dir;
            const double ref = depth_by_quadrature(m, p, q);
            if (ref < 1e-280) continue;  // underflow: nothing to compare
            ++compared;
            const double got = m.optical_depth_all(p, q);
            const double rel = std::abs(got - ref) / ref;
            worst = std::max(worst, rel);
            EXPECT_LT(rel, 1e-9) << "a=" << a << " h=" << h << " t0=" << t0 << " len=" << len;
        }
    }
    EXPECT_GT(compared, 250);
    std::printf("[ gaussians ] optical depth vs density quadrature: worst relative error %.2e over %d segments\n",
                worst, compared);
}

// beta0 adds beta0 L; an empty medium is homogeneous; T is symmetric in its ends.
TEST(GaussianMedium, BackgroundAndSymmetry) {
    const GaussianMedium empty({}, {}, {}, 0.02);
    EXPECT_DOUBLE_EQ(empty.optical_depth(Vec3(0.0), Vec3(3, 4, 0)), 0.1);
    EXPECT_TRUE(std::isinf(empty.optical_depth_ray(Vec3(0.0), Vec3(1, 0, 0), INFINITY)));
    const GaussianMedium none({}, {}, {}, 0.0);
    EXPECT_EQ(none.optical_depth_ray(Vec3(0.0), Vec3(1, 0, 0), INFINITY), 0.0);
    const GaussianMedium m({0, 0, 0, 1, 1, 0}, {1.0, 0.5}, {0.3, 0.2}, 0.01);
    const Vec3 p(-2, 0.3, 0.1), q(3, 0.5, -0.2);
    EXPECT_NEAR(m.optical_depth_all(p, q), m.optical_depth_all(q, p), 1e-14);
    EXPECT_NEAR(m.optical_depth_all(p, q), depth_by_quadrature(m, p, q), 1e-12);
}

// Culling: never drops more than eps per Gaussian skipped, on a random cloud of
// mixed scales; also reports the measured loss.
TEST(GaussianMedium, CullingErrorBound) {
    std::mt19937_64 rng(11);
    std::uniform_real_distribution<double> U(0.0, 1.0);
    const int n = 2000;
    std::vector<double> b, a, c;
    for (int i = 0; i < n; ++i) {
        for (int k = 0; k < 3; ++k) b.push_back(100.0 * U(rng) - 50.0);
        a.push_back(std::pow(10.0, -1.5 + 2.5 * U(rng)));  // 0.03 .. 10 /m
        c.push_back(U(rng));
    }
    const GaussianMedium m(b, a, c, 0.0, 1e-6);
    double worst_abs = 0.0, worst_ratio = 0.0;
    for (int k = 0; k < 400; ++k) {
        const Vec3 p(100 * U(rng) - 50, 100 * U(rng) - 50, 100 * U(rng) - 50);
        const Vec3 q(100 * U(rng) - 50, 100 * U(rng) - 50, 100 * U(rng) - 50);
        const double all = m.optical_depth_all(p, q), culled = m.optical_depth(p, q);
        int used = 0;
        const Vec3 r = glm::normalize(q - p);
        m.for_each_near(p, r, glm::length(q - p), [&](std::size_t) { ++used; });
        const double bound = m.cull_eps() * (n - used);
        EXPECT_LE(all - culled, bound + 1e-12 * all);
        EXPECT_GE(all - culled, -1e-12 * all);
        worst_abs = std::max(worst_abs, all - culled);
        worst_ratio = std::max(worst_ratio, (all - culled) / bound);
    }
    std::printf("[ gaussians ] culling (eps 1e-6, n %d): worst dropped optical depth %.2e (%.3f of the bound)\n", n,
                worst_abs, worst_ratio);
}

// The culled density at a point leaves out only Gaussians whose cull sphere misses it, each
// below eps a / sqrt(pi) there.
TEST(GaussianMedium, CulledDensity) {
    std::mt19937_64 rng(5);
    std::uniform_real_distribution<double> U(0.0, 1.0);
    std::vector<double> b, a, c;
    double a_max = 0.0;
    for (int i = 0; i < 1500; ++i) {
        for (int k = 0; k < 3; ++k) b.push_back(60.0 * U(rng) - 30.0);
        a.push_back(std::pow(10.0, -1.0 + 1.5 * U(rng)));
        a_max = std::max(a_max, a.back());
        c.push_back(2.0 * U(rng));
    }
    const GaussianMedium m(b, a, c, 0.01, 1e-6);
    for (int k = 0; k < 300; ++k) {
        const Vec3 x = k % 2 ? m.centre(std::size_t(k)) : Vec3(60 * U(rng) - 30, 60 * U(rng) - 30, 60 * U(rng) - 30);
        const double all = m.density(x), near = m.density_near(x);
        EXPECT_GE(all - near, -1e-12 * all);
        EXPECT_LE(all - near, 1500 * m.cull_eps() * a_max / std::sqrt(kPi) + 1e-12 * all);
    }
}

// The windowed hierarchy reaches exactly the Gaussians of the medium's whose window the segment
// enters (a^2 d^2 < W at the segment's closest point d, W = GaussianWindow): none it drops is in
// the window, none it keeps is outside it or outside the medium's own cull sphere; with no
// window it is the medium's.
TEST(GaussianMedium, WindowedReachesTheWindow) {
    std::mt19937_64 rng(3);
    std::uniform_real_distribution<double> U(0.0, 1.0);
    std::vector<double> b, a, c;
    for (int i = 0; i < 1500; ++i) {
        for (int k = 0; k < 3; ++k) b.push_back(60.0 * U(rng) - 30.0);
        a.push_back(std::pow(10.0, -1.0 + 1.5 * U(rng)));
        c.push_back(std::pow(10.0, -3.0 + 3.5 * U(rng)));  // thin (window 10) to dense (its own)
    }
    const GaussianMedium m(b, a, c, 0.01);
    for (double window : {10.0, 20.0, GaussianWindow::kNone}) {
        const GaussianMedium w = m.windowed(window);
        const GaussianWindow window_of(window);
        EXPECT_EQ(w.size(), m.size());
        // (no window: the same spheres, the same hierarchy)
        if (std::isinf(window)) EXPECT_EQ(w.fingerprint(), m.fingerprint());
        else EXPECT_NE(w.fingerprint(), m.fingerprint());
        int kept = 0, all = 0;
        for (int k = 0; k < 200; ++k) {
            const Vec3 o(60 * U(rng) - 30, 60 * U(rng) - 30, 60 * U(rng) - 30);
            const Vec3 r = glm::normalize(Vec3(U(rng) - 0.5, U(rng) - 0.5, U(rng) - 0.5));
            const double tmax = k % 3 ? 40.0 * U(rng) : std::numeric_limits<double>::infinity();
            std::vector<char> near_m(m.size(), 0), near_w(m.size(), 0);
            m.for_each_near(o, r, tmax, [&](std::size_t g) { near_m[g] = 1, ++all; });
            w.for_each_near(o, r, tmax, [&](std::size_t g) { near_w[g] = 1, ++kept; });
            for (std::size_t g = 0; g < m.size(); ++g) {
                const Vec3 rel = m.centre(g) - o;
                const double t = std::clamp(glm::dot(rel, r), 0.0, tmax);
                const Vec3 d = rel - t * r;
                const double ad2 = m.scale(g) * m.scale(g) * glm::dot(d, d);
                const double W = window_of(m.amplitude(g) * kSqrtPi / m.scale(g));
                if (near_w[g]) EXPECT_TRUE(near_m[g] && ad2 <= W * (1.0 + 1e-12)) << g;
                else if (near_m[g]) EXPECT_GE(ad2, W * (1.0 - 1e-12)) << g;
            }
        }
        // (window 20: every cull sphere here is within it)
        if (window > 10.0) EXPECT_EQ(kept, all);
        else EXPECT_LT(kept, 0.8 * all);
        std::printf("[ gaussians ] windowed %g: reaches %d of the medium's %d\n", window, kept, all);
    }
}

// A bundle of rays within a cone: the cone's walk, filtered by segment_reaches, is each ray's
// own walk, in its order (the light-depth map's tiles gather so).
TEST(GaussianMedium, ConeWalkHoldsEachRaysWalk) {
    std::mt19937_64 rng(9);
    std::uniform_real_distribution<double> U(0.0, 1.0);
    std::vector<double> b, a, c;
    for (int i = 0; i < 2000; ++i) {
        for (int k = 0; k < 3; ++k) b.push_back(60.0 * U(rng) - 30.0);
        a.push_back(std::pow(10.0, -0.5 + 1.5 * U(rng)));
        c.push_back(std::pow(10.0, -2.0 + 2.0 * U(rng)));
    }
    const GaussianMedium m(b, a, c, 0.0);
    std::size_t in_cone = 0, reached = 0;
    for (int k = 0; k < 100; ++k) {
        const Vec3 o(40 * U(rng) - 20, 40 * U(rng) - 20, 40 * U(rng) - 20);
        const Vec3 axis = glm::normalize(Vec3(U(rng) - 0.5, U(rng) - 0.5, U(rng) - 0.5));
        const double half = 0.3 * U(rng);
        std::vector<std::size_t> cone;
        m.for_each_in_cone(o, axis, std::cos(half), [&](std::size_t g) { cone.push_back(g); });
        in_cone += cone.size();
        const Vec3 e1 = glm::normalize(glm::cross(axis, std::abs(axis.x) < 0.9 ? Vec3(1, 0, 0) : Vec3(0, 1, 0)));
        const Vec3 e2 = glm::cross(axis, e1);
        for (int j = 0; j < 16; ++j) {
            const double th = half * std::sqrt(U(rng)), ph = 2.0 * kPi * U(rng);
            const Vec3 r = glm::normalize(std::cos(th) * axis + std::sin(th) * (std::cos(ph) * e1 + std::sin(ph) * e2));
            const double tmax = j % 2 ? 50.0 * U(rng) : 100.0;
            std::vector<std::size_t> own, kept;
            m.for_each_near(o, r, tmax, [&](std::size_t g) { own.push_back(g); });
            for (std::size_t g : cone)
                if (m.segment_reaches(g, o, r, tmax)) kept.push_back(g);
            EXPECT_EQ(kept, own);
            reached += own.size();
        }
    }
    std::printf("[ gaussians ] cone walks: %zu Gaussians a cone, %zu a ray\n", in_cone / 100, reached / 1600);
}

TEST(GaussianMedium, RejectsBadInput) {
    auto msg = [](auto&& make) {
        try {
            make();
        } catch (const std::invalid_argument& e) {
            return std::string(e.what());
        }
        return std::string("no exception");
    };
    EXPECT_NE(msg([] { GaussianMedium({NAN, 0, 0}, {1}, {1}, 0); }).find("not finite"), std::string::npos);
    EXPECT_NE(msg([] { GaussianMedium({INFINITY, 0, 0}, {1}, {1}, 0); }).find("not finite"), std::string::npos);
    EXPECT_NE(msg([] { GaussianMedium({0, 0, 0}, {0.0}, {1}, 0); }).find("scale"), std::string::npos);
    EXPECT_NE(msg([] { GaussianMedium({0, 0, 0}, {-1.0}, {1}, 0); }).find("scale"), std::string::npos);
    EXPECT_NE(msg([] { GaussianMedium({0, 0, 0}, {1}, {-0.1}, 0); }).find("amplitude"), std::string::npos);
    EXPECT_NE(msg([] { GaussianMedium({0, 0, 0}, {1}, {NAN}, 0); }).find("amplitude"), std::string::npos);
    EXPECT_NE(msg([] { GaussianMedium({0, 0, 0}, {1}, {1}, -0.1); }).find("beta0"), std::string::npos);
    EXPECT_NE(msg([] { GaussianMedium({0, 0, 0}, {1}, {1}, NAN); }).find("beta0"), std::string::npos);
    EXPECT_NE(msg([] { GaussianMedium({0, 0, 0}, {1, 2}, {1}, 0); }).find("must match"), std::string::npos);
}

}  // namespace
}  // namespace airlight
