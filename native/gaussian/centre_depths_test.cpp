// centre_depths_test.cpp: the optical depths from a point to every Gaussian centre
// (centre_depths.h) against the exact double line integrals (eq. 31 with erf_diff), by each
// of their ways to the same sums; the sun lamps' half-line depths; bad input refused (here
// and by their users, the splat's set-up and the preview factors).
#include "gaussian/centre_depths.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <limits>
#include <random>
#include <stdexcept>

#include "gaussian/preview_factors.h"
#include "gaussian/splat.h"

namespace airlight {
namespace {

// The optical depths behind the per-(light, Gaussian) factors (gaussian_depths_to_centres), by
// each of its three ways (per target, per candidate, binned by direction), against the
// exact double line integrals of every other Gaussian (eq. 31 with erf_diff, no culling).
// The medium is built to hit the binning's corners: sources inside the cloud, cull spheres
// holding a source (every direction), Gaussians exactly on the cube map's face diagonals
// and edges seen from source 0 (direction ties between faces), one centred on source 1
// (a zero-length segment: T = 0), faint ones without a cull sphere (R = 0: skipped), and
// a few large faint ones whose spheres cover many cells.
const std::vector<Vec3> kStarSources = {Vec3(0.0), Vec3(2.0, 1.0, 9.0), Vec3(-6.0, 5.0, 20.0)};

GaussianMedium star_cloud(int n, unsigned seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> U(0.0, 1.0);
    std::vector<double> b, a, c;
    auto add = [&](const Vec3& p, double aa, double cc) {
        b.insert(b.end(), {p.x, p.y, p.z});
        a.push_back(aa);
        c.push_back(cc);
    };
    for (int i = 0; i < n; ++i)
        add(Vec3(-12.0 + 24.0 * U(rng), -4.0 + 12.0 * U(rng), -4.0 + 30.0 * U(rng)), 1.0 / (0.4 + 1.6 * U(rng)),
            0.02 + 0.2 * U(rng));
    for (int sx = -1; sx <= 1; sx += 2)
        for (int sy = -1; sy <= 1; sy += 2)
            for (int sz = -1; sz <= 1; sz += 2) add(Vec3(5.0 * sx, 5.0 * sy, 5.0 * sz), 1.2, 0.3);  // diagonals
    add(Vec3(7.0, 7.0, 0.5), 1.0, 0.2);                                                     // an edge
    add(Vec3(0.0, 0.0, 6.0), 0.8, 0.25);                                                    // a face centre
    add(Vec3(0.3, -0.2, 0.4), 0.7, 0.3);                                                    // holds source 0
    add(Vec3(2.0, 1.0, 9.0), 1.5, 0.3);                                                     // on source 1
    add(Vec3(-5.0, 4.5, 19.0), 0.15, 0.01);                                                 // large, holds source 2
    add(Vec3(3.0, 2.0, 4.0), 1.0, 1e-9);                                                    // no cull sphere
    add(Vec3(-3.0, 0.0, 12.0), 2.0, 0.0);                                                   // c = 0
    return GaussianMedium(b, a, c, 0.01);
}

// Exact sum over j in [c0, c1), j != i, on s -> b_i: all of them (culled = false) or those
// the medium's own cull test reaches (for_each_near, in double).
double exact_others(const GaussianMedium& m, const Vec3& s, std::size_t i, std::size_t c0, std::size_t c1, bool culled) {
    const Vec3 d = m.centre(i) - s;
    const double D = glm::length(d);
    if (!(D > 0.0)) return 0.0;
    double T = 0.0;
    auto add = [&](std::size_t j) {
        if (j != i && j >= c0 && j < c1) T += m.gaussian_optical_depth(j, s, d / D, 0.0, D);
    };
    if (culled)
        m.for_each_near(s, d / D, D, add);
    else
        for (std::size_t j = c0; j < c1; ++j) add(j);
    return T;
}

TEST(GaussianFactors, EveryMethodMatchesExactSums) {
    const GaussianMedium m = star_cloud(700, 17);
    const std::size_t n = m.size();
    // Full (every target, every candidate) and the incremental split (targets and
    // candidates in different ranges, as rbf_preview_factors uses them).
    const struct {
        std::size_t t0, t1, c0, c1;
    } cases[] = {{0, n, 0, n}, {0, 500, 500, n}, {500, n, 0, n}};
    for (const auto& cs : cases) {
        std::vector<double> ref(kStarSources.size() * (cs.t1 - cs.t0)), all(ref.size());
        for (std::size_t r = 0; r < kStarSources.size(); ++r)
            for (std::size_t i = cs.t0; i < cs.t1; ++i) {
                ref[r * (cs.t1 - cs.t0) + i - cs.t0] = exact_others(m, kStarSources[r], i, cs.c0, cs.c1, true);
                all[r * (cs.t1 - cs.t0) + i - cs.t0] = exact_others(m, kStarSources[r], i, cs.c0, cs.c1, false);
            }
        // Against the double cull (the same Gaussians, up to those the float test's 2e-4
        // inflation adds at < cull_eps each): float kernels ~1e-5 relative, and 20 such
        // extra Gaussians; any Gaussian missed that integrates to more than ~2e-6 fails.
        // Against no culling: < cull_eps per skipped Gaussian.
        const double extra = 20.0 * m.cull_eps(), cull = m.cull_eps() * double(cs.c1 - cs.c0);
        std::vector<std::vector<double>> got;
        for (int method = 1; method <= 3; ++method) {
            got.push_back(gaussian_depths_to_centres(m, kStarSources, cs.t0, cs.t1, cs.c0, cs.c1, 2, method));
            const std::vector<double>& T = got.back();
            ASSERT_EQ(T.size(), ref.size());
            double worst = 0.0, worst_all = 0.0, biggest = 0.0;
            for (std::size_t k = 0; k < ref.size(); ++k) {
                worst = std::max(worst, std::abs(T[k] - ref[k]) / (2e-5 * ref[k] + extra));
                worst_all = std::max(worst_all, std::abs(T[k] - all[k]) / (2e-5 * all[k] + cull));
                biggest = std::max(biggest, ref[k]);
            }
            std::printf("targets [%zu, %zu), candidates [%zu, %zu), method %d: worst error / bound %.3f (culled "
                        "reference), %.3f (all Gaussians); T up to %.2f\n",
                        cs.t0, cs.t1, cs.c0, cs.c1, method, worst, worst_all, biggest);
            EXPECT_GT(biggest, 1.0);  // the Gaussians matter
            EXPECT_LE(worst, 1.0) << "method " << method;
            EXPECT_LE(worst_all, 1.0) << "method " << method;
        }
        // The three ways agree to float rounding.
        for (std::size_t k = 0; k < ref.size(); ++k) {
            EXPECT_NEAR(got[1][k], got[0][k], 1e-5 * ref[k] + 1e-9);
            EXPECT_NEAR(got[2][k], got[0][k], 1e-5 * ref[k] + 1e-9);
        }
    }
    // The Gaussian centred on source 1 (index n - 4): a zero-length segment.
    const std::vector<double> T = gaussian_depths_to_centres(m, {kStarSources[1]}, n - 4, n - 3, 0, n, 1, 3);
    EXPECT_EQ(T[0], 0.0);
}

// Sun lamps' half-line depths (gaussian_sun_depths) against the exact double ones: the culled
// per-ray walk of the hierarchy (optical_depth_ray, the previous path) and every Gaussian.
TEST(GaussianFactors, SunDepthsMatchExact) {
    const GaussianMedium m = star_cloud(1500, 23);
    const double inf = std::numeric_limits<double>::infinity();
    for (const Vec3& u : {glm::normalize(Vec3(0.3, 0.8, -0.5)), Vec3(0.0, 1.0, 0.0), Vec3(0.0, 0.0, -1.0)}) {
        const std::vector<double> T = gaussian_sun_depths(m, u, 2);
        ASSERT_EQ(T.size(), m.size());
        double worst = 0.0, worst_all = 0.0, biggest = 0.0;
        for (std::size_t i = 0; i < m.size(); ++i) {
            const double ref = m.optical_depth_ray(m.centre(i), u, inf, i, false);
            double all = 0.0;
            for (std::size_t j = 0; j < m.size(); ++j)
                if (j != i) all += m.gaussian_optical_depth(j, m.centre(i), u, 0.0, inf);
            worst = std::max(worst, std::abs(T[i] - ref) / (2e-5 * ref + 20.0 * m.cull_eps()));
            worst_all = std::max(worst_all, std::abs(T[i] - all) / (2e-5 * all + m.cull_eps() * double(m.size())));
            biggest = std::max(biggest, ref);
        }
        std::printf("sun (%.2f, %.2f, %.2f): worst error / bound %.3f (culled reference), %.3f (all); T up to %.2f\n",
                    u.x, u.y, u.z, worst, worst_all, biggest);
        EXPECT_GT(biggest, 1.0);
        EXPECT_LE(worst, 1.0);
        EXPECT_LE(worst_all, 1.0);
    }
    EXPECT_THROW(gaussian_sun_depths(m, Vec3(0.0, 2.0, 0.0)), std::invalid_argument);
}

TEST(GaussianFactors, BadInput) {
    const GaussianMedium m = star_cloud(20, 3);
    const double nan = std::numeric_limits<double>::quiet_NaN();
    EXPECT_THROW(gaussian_depths_to_centres(m, {Vec3(0.0, nan, 1.0)}, 0, m.size(), 0, m.size()), std::invalid_argument);
    EXPECT_THROW(gaussian_depths_to_centres(m, {Vec3(0.0)}, 0, m.size() + 1, 0, m.size()), std::invalid_argument);
    EXPECT_THROW(gaussian_depths_to_centres(m, {Vec3(0.0)}, 0, m.size(), 3, 2), std::invalid_argument);
    EXPECT_THROW(gaussian_depths_to_centres(m, {Vec3(0.0)}, 0, m.size(), 0, m.size(), 1, 4), std::invalid_argument);
    // The bake's constructor and the preview factors refuse a non-finite light too.
    EXPECT_THROW(GaussianSplat(m, Vec3(0.0), {Vec3(nan, 0.0, 0.0)}, {RGB(1.0)}, RGB(0.9), {}, nullptr, GaussianNoise{}, 1),
                 std::invalid_argument);
    EXPECT_THROW(rbf_preview_factors(m, Vec3(0.0), {Vec3(0.0, 0.0, nan)}), std::invalid_argument);
}
}  // namespace
}  // namespace airlight
