// splat_test.cpp: the float fast paths against their double references: fast_erf.h
// against erf_diff / std::erfc, and the tiled splat (and its per-ray twin) against the
// exact Fogshop evaluation (FogshopAirlight, double) pixel by pixel; per-Gaussian
// colour; the noise perturbation (off = bit-identical, on = bounded change).
#include "gaussian/splat.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <ctime>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <random>

#include "core/fast_erf.h"
#include "core/noise.h"

namespace airlight {
namespace {

TEST(FastErf, ExpAndErfcRelativeError) {
    double worst_exp = 0.0, worst_erfc = 0.0;
    for (double x = -87.0; x <= 88.0; x += 0.00731) {
        const double ref = std::exp(double(float(x)));
        worst_exp = std::max(worst_exp, std::abs(double(fast_expf(float(x))) - ref) / ref);
    }
    for (double x = 0.0; x <= 9.0; x += 0.000977) {
        const float xf = float(x);
        const double ref = std::erfc(double(xf));
        const double tol = x <= 4.0 ? 2e-6 : 2e-6 + 1.2e-7 * x * x;
        const double rel = std::abs(double(fast_erfc_pos(xf)) - ref) / ref;
        worst_erfc = std::max(worst_erfc, rel);
        ASSERT_LE(rel, tol) << "erfc at x = " << x;
    }
    EXPECT_LE(worst_exp, 3e-7);
    EXPECT_EQ(fast_expf(-100.0f), 0.0f);
    EXPECT_EQ(fast_erfc_pos(std::numeric_limits<float>::infinity()), 0.0f);
    std::printf("fast_expf max rel %.2g, fast_erfc_pos max rel (x <= 9) %.2g\n", worst_exp, worst_erfc);
}

TEST(FastErf, ErfcxRelativeError) {
    // exp(x^2) erfc(x) in long double (erfcl underflows only beyond x ~ 106, where the
    // asymptotic series 1 / (x sqrt(pi)) (1 - 1 / (2 x^2) + 3 / (4 x^4)) is exact to 1e-12).
    const auto erfcx_ref = [](float xf) {
        const long double x = xf;
        if (x > 50.0L) {
            const long double r = 1.0L / (x * x);
            return double((1.0L - 0.5L * r + 0.75L * r * r) / (x * std::sqrt(3.14159265358979323846L)));
        }
        return double(std::exp(x * x) * std::erfc(x));
    };
    double worst = 0.0;
    for (double x = 0.0; x <= 1e6; x = x < 20.0 ? x + 0.000977 : x * 1.001) {
        const float xf = float(x);
        const double ref = erfcx_ref(xf);
        const double rel = std::abs(double(fast_erfcx_pos(xf)) - ref) / ref;
        worst = std::max(worst, rel);
        ASSERT_LE(rel, 1e-6) << "erfcx at x = " << x;
    }
    EXPECT_EQ(fast_erfcx_pos(std::numeric_limits<float>::infinity()), 0.0f);
    // The kernels' product form against erfc itself: k0 e^{-h} erfc(x) as k0 erfcx(x) e^{-(h + x^2)}.
    for (double x = 0.0; x <= 9.0; x += 0.0131)
        for (double h : {0.0, 0.3, 4.0, 30.0}) {
            const float xf = float(x), hf = float(h);
            const double ref = std::exp(-double(hf)) * std::erfc(double(xf));
            const double got = double(fast_erfcx_pos(xf) * fast_expf(-hf - xf * xf));
            ASSERT_LE(std::abs(got - ref), (2e-6 + 1.2e-7 * (x * x + h)) * ref + 1e-37) << "x " << x << " h " << h;
        }
    std::printf("fast_erfcx_pos max rel (x <= 1e6) %.2g\n", worst);
}

TEST(FastErf, ErfDiffBoundAgainstDouble) {
    // |fast - exact| <= 1e-5 exact + (4e-6 + 2.4e-7 m^2) max(erfc|x1|, erfc|x2|) + 1e-37, m the
    // larger finite one of |x1|, |x2| (fast_erf.h), on x1 < x2
    // in [-9, 9] and x2 = inf, arguments exactly representable in float.
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> U(-9.0, 9.0), W(-6.0, 1.0);
    double worst = 0.0;
    for (int k = 0; k < 200000; ++k) {
        const float x1 = float(U(rng));
        const float x2 = k % 10 == 0 ? std::numeric_limits<float>::infinity()
                                     : float(double(x1) + std::pow(10.0, W(rng)) * 4.0);
        if (!(x2 > x1)) continue;
        const double exact = erf_diff(double(x1), double(x2));
        const double fast = fast_erf_diff(x1, x2);
        const double big = std::max(std::erfc(std::abs(double(x1))), std::erfc(std::abs(double(x2))));
        const double mm = std::isinf(x2) ? std::abs(double(x1)) : std::max(std::abs(double(x1)), std::abs(double(x2)));
        const double bound = 1e-5 * exact + (4e-6 + 2.4e-7 * mm * mm) * big + 1e-37;
        ASSERT_LE(std::abs(fast - exact), bound) << "x1 " << x1 << " x2 " << x2 << " exact " << exact;
        if (exact > 1e-20) worst = std::max(worst, std::abs(fast - exact) / bound);
    }
    std::printf("fast_erf_diff: worst error / bound %.3f\n", worst);
}

TEST(Noise, DeterministicAndBounded) {
    EXPECT_EQ(gradient_noise(1.0f, 2.0f, 3.0f), 0.0f);  // lattice point
    float lo = 0.0f, hi = 0.0f;
    double mean = 0.0;
    std::mt19937 rng(3);
    std::uniform_real_distribution<float> U(-50.0f, 50.0f);
    for (int k = 0; k < 100000; ++k) {
        const float n = gradient_noise(U(rng), U(rng), U(rng));
        lo = std::min(lo, n);
        hi = std::max(hi, n);
        mean += n;
    }
    EXPECT_LE(hi, 1.7320508f);
    EXPECT_GE(lo, -1.7320508f);
    EXPECT_GT(hi - lo, 0.8f);  // not flat
    EXPECT_LT(std::abs(mean / 100000.0), 0.05);
    // Continuity: a small step changes the value a little.
    EXPECT_NEAR(gradient_noise(0.3f, 0.7f, 0.1f), gradient_noise(0.3001f, 0.7f, 0.1f), 1e-3f);
}

// A small camera: eye at the origin looking down +z, 60 degree horizontal view, film
// position (px, py) -> D0 + px Dx + py Dy (pixel rows downwards).
struct SmallCamera {
    int W = 72, H = 40;
    Vec3 D0, Dx, Dy, forward{0.0, 0.0, 1.0};
    SmallCamera(int w, int h) : W(w), H(h) {
        const double t = std::tan(30.0 * 3.14159265358979323846 / 180.0);
        Dx = Vec3(2.0 * t / W, 0.0, 0.0);
        Dy = Vec3(0.0, -2.0 * t / W, 0.0);
        D0 = Vec3(-t, t * H / W, 1.0);
    }
    Vec3 dir(int i, int j) const { return glm::normalize(D0 + (i + 0.5) * Dx + (j + 0.5) * Dy); }
};

// Gaussians in front of the camera, a ground plane y = -1.5 as the depth.
GaussianMedium cloud(int n, unsigned seed, double beta0) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> U(0.0, 1.0);
    std::vector<double> b, a, c;
    for (int i = 0; i < n; ++i) {
        b.insert(b.end(), {-8.0 + 16.0 * U(rng), -1.5 + 4.0 * U(rng), 4.0 + 16.0 * U(rng)});
        a.push_back(1.0 / (0.5 + 2.0 * U(rng)));
        c.push_back(0.05 + 0.3 * U(rng));
    }
    // One Gaussian around the eye (crosses the near plane: full-screen bin, near terms).
    b.insert(b.end(), {0.2, 0.1, 0.3});
    a.push_back(1.5);
    c.push_back(0.2);
    return GaussianMedium(b, a, c, beta0);
}

std::vector<float> ground_depth(const SmallCamera& cam) {
    std::vector<float> depth(size_t(cam.W) * cam.H);
    for (int j = 0; j < cam.H; ++j)
        for (int i = 0; i < cam.W; ++i) {
            const Vec3 d = cam.dir(i, j);
            depth[size_t(j) * cam.W + i] = d.y < -1e-6 ? float(-1.5 / d.y) : std::numeric_limits<float>::infinity();
        }
    return depth;
}

struct Image {
    std::vector<float> T, A;
};

Image splat_image(const GaussianSplat& s, const SmallCamera& cam, const std::vector<float>& depth) {
    Image im;
    im.T.assign(3 * depth.size(), -1.0f);
    im.A.assign(3 * depth.size(), -1.0f);
    for (int t = 0; t < s.num_tiles(); ++t) s.splat_tile(t, depth.data(), im.T.data(), im.A.data());
    return im;
}

const std::vector<Vec3> kLights = {Vec3(-3.0, 3.0, 8.0), Vec3(4.0, 1.0, 15.0)};
const std::vector<RGB> kI0 = {RGB(1.0, 0.8, 0.6), RGB(0.5, 0.5, 1.0)};

// The splat (float, tiles) against the exact double Fogshop path, no near clip.
TEST(GaussianSplat, MatchesExactPerRayPath) {
    const GaussianMedium m = cloud(40, 11, 0.01);
    const SmallCamera cam(72, 40);
    const RGB albedo(0.9, 0.8, 0.7);
    GaussianSplat s(m, Vec3(0.0), kLights, kI0, albedo, {}, nullptr, GaussianNoise{}, 2);
    s.bin(cam.D0, cam.Dx, cam.Dy, cam.forward, cam.W, cam.H, 0.0);
    const std::vector<float> depth = ground_depth(cam);
    const Image im = splat_image(s, cam, depth);
    double worst_A = 0.0, worst_T = 0.0, peak = 0.0, gauss_T = 0.0;
    for (int j = 0; j < cam.H; ++j)
        for (int i = 0; i < cam.W; ++i) {
            const size_t p = size_t(j) * cam.W + i;
            const Vec3 d = cam.dir(i, j);
            const RGB ref = s.eval_exact(d, double(depth[p]));
            const double T_ref = std::exp(-m.optical_depth_all_ray(Vec3(0.0), d, double(depth[p])));
            if (!std::isinf(depth[p]))
                gauss_T = std::max(gauss_T, m.optical_depth_all_ray(Vec3(0.0), d, double(depth[p])) - 0.01 * depth[p]);
            worst_T = std::max(worst_T, std::abs(double(im.T[3 * p]) - T_ref));
            for (int c = 0; c < 3; ++c) {
                peak = std::max(peak, ref[c]);
                worst_A = std::max(worst_A, std::abs(double(im.A[3 * p + c]) - ref[c]) / ref[c]);
            }
        }
    std::printf("splat vs exact: airlight max rel %.3g, transmittance max abs %.3g (Gaussian T up to %.2f)\n",
                worst_A, worst_T, gauss_T);
    EXPECT_GT(gauss_T, 0.5);  // the Gaussians matter
    EXPECT_LT(worst_A, 2e-4);
    EXPECT_LT(worst_T, 2e-5);
}

// Reduced resolution's coarse lattice (splat_reduced.cpp): broad Gaussians near the
// eye (smooth on 8 pixels) go on every other node of the quarter lattice, small far ones on
// the lattice itself; both against the full-resolution splat, sky and ground pixels.
TEST(GaussianSplat, CoarseLatticeAgainstFull) {
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> U(0.0, 1.0);
    std::vector<double> b, a, c;
    for (int i = 0; i < 12; ++i) {  // broad, 6..14 m away: 1 / (sqrt 2 a d) >= 0.23 rad
        b.insert(b.end(), {-6.0 + 12.0 * U(rng), -1.0 + 3.0 * U(rng), 6.0 + 8.0 * U(rng)});
        a.push_back(1.0 / (4.0 + 2.0 * U(rng)));
        c.push_back(0.02 + 0.03 * U(rng));
    }
    const std::size_t n_broad = a.size();
    for (int i = 0; i < 30; ++i) {  // small, 20..40 m away
        b.insert(b.end(), {-12.0 + 24.0 * U(rng), -1.0 + 4.0 * U(rng), 20.0 + 20.0 * U(rng)});
        a.push_back(1.0 / (0.5 + 1.0 * U(rng)));
        c.push_back(0.05 + 0.2 * U(rng));
    }
    const SmallCamera cam(640, 360);
    const std::vector<float> depth = ground_depth(cam);
    // The broad ones alone (all coarse), then all (both kinds).
    for (const bool all : {false, true}) {
        const std::size_t n = all ? a.size() : n_broad;
        const GaussianMedium m(std::vector<double>(b.begin(), b.begin() + 3 * n), std::vector<double>(a.begin(), a.begin() + n),
                          std::vector<double>(c.begin(), c.begin() + n), 0.005);
        GaussianSplat s(m, Vec3(0.0), {Vec3(40.0, 25.0, 70.0)}, {RGB(300.0, 250.0, 200.0)}, RGB(0.9), {}, nullptr,
                   GaussianNoise{}, 2);
        s.bin(cam.D0, cam.Dx, cam.Dy, cam.forward, cam.W, cam.H, 0.0, 1);
        const Image full = splat_image(s, cam, depth);
        s.bin(cam.D0, cam.Dx, cam.Dy, cam.forward, cam.W, cam.H, 0.0, 4);
        const Image quarter = splat_image(s, cam, depth);
        const GaussianSplat::ReducedCounts rc = s.reduced_counts();
        double worst_A = 0.0, worst_T = 0.0, mean_A = 0.0;
        for (size_t p = 0; p < depth.size(); ++p) {
            worst_T = std::max(worst_T,
                               std::abs(double(quarter.T[3 * p]) - double(full.T[3 * p])) / double(full.T[3 * p]));
            const double e = std::abs(double(quarter.A[3 * p]) - double(full.A[3 * p])) / double(full.A[3 * p]);
            worst_A = std::max(worst_A, e);
            mean_A += e / double(depth.size());
        }
        std::printf("%s: %zu of %zu lattice pairs coarse; quarter vs full: airlight max rel %.3g (mean %.3g), "
                    "transmittance max rel %.3g\n",
                    all ? "broad and small Gaussians" : "broad Gaussians", rc.coarse, rc.lattice, worst_A, mean_A,
                    worst_T);
        if (!all) {
            EXPECT_GT(double(rc.coarse), 0.9 * double(rc.lattice));  // nearly all on the coarse lattice
            EXPECT_GT(rc.coarse, 1000u);
            // measured: 1.5e-4 and 1.1e-3 (the lattice itself: 5.5e-5 and 2.6e-4; the small
            // Gaussians' lattice error below: 2.5e-3 and 1.8e-2)
            EXPECT_LT(worst_A, 5e-4);
            EXPECT_LT(worst_T, 3e-3);
        } else {
            EXPECT_GT(rc.coarse, 1000u);
            EXPECT_LT(rc.coarse, rc.lattice);  // the small ones on the lattice itself
        }
    }
}

// The far-field grids (splat_far_field.cpp): broad Gaussians' Dvp = inf terms on
// image-wide grids, cancelled where a Gaussian lies behind the ground, exact where the ground
// cuts it; small ones stay on the tile lattices. Quarter and half with the grids (bin()
// given the depth) against the full-resolution splat, and against the same resolution
// without them (the lattice's own error).
TEST(GaussianSplat, FarFieldGridsAgainstFull) {
    std::mt19937 rng(5);
    std::uniform_real_distribution<double> U(0.0, 1.0);
    std::vector<double> b, a, c;
    for (int i = 0; i < 60; ++i) {  // broad ones, some reaching below the ground y = -1.5
        b.insert(b.end(), {-10.0 + 20.0 * U(rng), -2.0 + 4.0 * U(rng), 8.0 + 20.0 * U(rng)});
        a.push_back(1.0 / (1.0 + 2.0 * U(rng)));
        c.push_back(0.02 + 0.08 * U(rng));
    }
    for (int i = 0; i < 60; ++i) {  // small, far
        b.insert(b.end(), {-14.0 + 28.0 * U(rng), -1.5 + 4.0 * U(rng), 25.0 + 20.0 * U(rng)});
        a.push_back(1.0 / (0.3 + 0.4 * U(rng)));
        c.push_back(0.05 + 0.2 * U(rng));
    }
    // Tiles a few degrees below the horizon see the ground at 10..35 m: in front of it,
    // Gaussians 5..7 m away; behind it, very broad ones 60..70 m away (cancelled there).
    for (int i = 0; i < 40; ++i) {
        b.insert(b.end(), {-4.0 + 8.0 * U(rng), -0.8 + 0.6 * U(rng), 5.0 + 2.0 * U(rng)});
        a.push_back(1.0 / (0.5 + 0.3 * U(rng)));
        c.push_back(0.05 + 0.1 * U(rng));
    }
    for (int i = 0; i < 6; ++i) {
        b.insert(b.end(), {-30.0 + 60.0 * U(rng), -2.0 + 4.0 * U(rng), 60.0 + 10.0 * U(rng)});
        a.push_back(1.0 / (6.0 + 2.0 * U(rng)));
        c.push_back(0.01 + 0.02 * U(rng));
    }
    const GaussianMedium m(b, a, c, 0.005);
    const SmallCamera cam(640, 360);
    const std::vector<float> depth = ground_depth(cam);
    GaussianSplat s(m, Vec3(0.0), {Vec3(5.0, 30.0, 15.0)}, {RGB(300.0, 250.0, 200.0)}, RGB(0.9), {}, nullptr,
               GaussianNoise{}, 2);
    s.bin(cam.D0, cam.Dx, cam.Dy, cam.forward, cam.W, cam.H, 0.1, 1);
    const Image full = splat_image(s, cam, depth);
    auto errors = [&](const Image& im, double& worst_A, double& worst_T) {
        worst_A = worst_T = 0.0;
        for (size_t p = 0; p < depth.size(); ++p) {
            worst_T = std::max(worst_T, std::abs(double(im.T[3 * p]) - double(full.T[3 * p])) / double(full.T[3 * p]));
            for (int k = 0; k < 3; ++k)
                worst_A = std::max(worst_A, std::abs(double(im.A[3 * p + k]) - double(full.A[3 * p + k])) /
                                                double(full.A[3 * p + k]));
        }
    };
    for (const int step : {4, 2}) {
        s.bin(cam.D0, cam.Dx, cam.Dy, cam.forward, cam.W, cam.H, 0.1, step);
        const Image plain = splat_image(s, cam, depth);
        s.bin(cam.D0, cam.Dx, cam.Dy, cam.forward, cam.W, cam.H, 0.1, step, depth.data());
        const Image grids = splat_image(s, cam, depth);
        const GaussianSplat::ReducedCounts rc = s.reduced_counts();
        double A0, T0, A1, T1, dA = 0.0, dT = 0.0;
        errors(plain, A0, T0);
        errors(grids, A1, T1);
        for (size_t p = 0; p < depth.size(); ++p) {  // against the lattice alone
            dT = std::max(dT, std::abs(double(grids.T[3 * p]) - double(plain.T[3 * p])) / double(plain.T[3 * p]));
            for (int k = 0; k < 3; ++k)
                dA = std::max(dA, std::abs(double(grids.A[3 * p + k]) - double(plain.A[3 * p + k])) /
                                      double(plain.A[3 * p + k]));
        }
        std::printf("step %d: grids vs lattice only: airlight max rel %.3g, transmittance %.3g\n", step, dA, dT);
        std::printf("step %d: %zu Gaussians on far-field grids (%zu nodes), %zu of %zu lattice pairs from them, "
                    "%zu behind (%zu cancelled); vs full: airlight max rel %.3g (lattice only %.3g), transmittance %.3g "
                    "(%.3g)\n",
                    step, rc.far_gaussians, rc.far_nodes, rc.far, rc.lattice, rc.behind, rc.far_cancelled, A1, A0, T1,
                    T0);
        EXPECT_GT(rc.far_gaussians, 20u);
        if (step == 4) EXPECT_GT(rc.far_cancelled, 50u);  // (at half, with its finer grids, none pays here)
        EXPECT_GT(rc.far, rc.lattice / 3);
        // The grids' own error (cubic interpolation; measured 8.6e-5 / 1.7e-4 at quarter,
        // 1.3e-5 / 1.4e-5 at half). Linear instead of cubic weights: 2.4e-3 / 1.0e-2 at
        // quarter; without the cancellation: 2.7e-2 / 0.32.
        EXPECT_LT(dA, 5e-4);
        EXPECT_LT(dT, 1e-3);
        EXPECT_LT(A1, A0 + 1e-4);
        EXPECT_LT(T1, T0 + 1e-4);
    }
}

// The cull spheres at reduced resolution (GaussianSplat::kReducedCullEps), Gaussian by Gaussian:
// one Gaussian beside the view whose tail alone reaches in (1e-7 .. 3e-3 of optical depth
// per ray), binned at full, half and quarter resolution. Every pixel of a tile it is not
// binned to must see less than eps of it (the exact line integral in double): culling never
// drops more than eps per Gaussian and ray. And the smaller spheres must bin fewer tiles
// (the point of them). With the radius 20 % short, 23 checks fail (up to 2.3e-4 dropped at
// quarter).
TEST(GaussianSplat, ReducedCullWithinItsBound) {
    const SmallCamera cam(320, 180);
    const std::vector<float> depth = ground_depth(cam);
    double tail_max = 0.0;
    for (int i = 0; i < 16; ++i) {
        const double z = 6.0 + 3.0 * (i / 2), side = i % 2 ? 1.0 : -1.0, inv_a = 0.6 + 0.1 * (i % 5);
        // The centre 2.2 .. 3.6 scale lengths beside the frustum's edge (x = 0.577 z).
        const Vec3 centre(side * (0.577 * z + (2.2 + 0.2 * (i % 8)) * inv_a * 1.155), 0.3 * (i % 3), z);
        const GaussianMedium m({centre.x, centre.y, centre.z}, {1.0 / inv_a}, {0.3}, 0.0);
        GaussianSplat s(m, Vec3(0.0), {Vec3(0.0, 6.0, 12.0)}, {RGB(100.0)}, RGB(0.9), {}, nullptr, GaussianNoise{}, 1);
        std::vector<double> tail(depth.size());
        for (int j = 0; j < cam.H; ++j)
            for (int k = 0; k < cam.W; ++k) {
                const size_t p = size_t(j) * cam.W + k;
                tail[p] = m.gaussian_optical_depth(0, Vec3(0.0), cam.dir(k, j), 0.0, double(depth[p]));
                tail_max = std::max(tail_max, tail[p]);
            }
        int binned[3] = {0, 0, 0};
        for (const int step : {1, 2, 4}) {
            const double eps = step == 1 ? m.cull_eps() : GaussianSplat::kReducedCullEps[step / 2 - 1];
            s.bin(cam.D0, cam.Dx, cam.Dy, cam.forward, cam.W, cam.H, 0.0, step);
            double dropped = 0.0;
            for (int t = 0; t < s.num_tiles(); ++t) {
                if (s.tile_pairs(t) > 0) {
                    ++binned[step / 2];
                    continue;
                }
                const int x0 = (t % ((cam.W + 15) / 16)) * 16, y0 = (t / ((cam.W + 15) / 16)) * 16;
                for (int j = y0; j < std::min(cam.H, y0 + 16); ++j)
                    for (int k = x0; k < std::min(cam.W, x0 + 16); ++k)
                        dropped = std::max(dropped, tail[size_t(j) * cam.W + k]);
            }
            EXPECT_LT(dropped, eps) << "Gaussian " << i << " step " << step;
        }
        EXPECT_LT(binned[2], binned[0]) << "Gaussian " << i;  // quarter bins fewer tiles than full
        EXPECT_LE(binned[2], binned[1]);
    }
    EXPECT_GT(tail_max, 1e-4);  // tails above the quarter's eps reach the view
    EXPECT_LT(tail_max, 1e-2);
}

// Noise (splat.h, Fogshop 5.5) against its definition, per Gaussian in double: the
// optical depth of Gaussian i along r'_i = normalize(r + amplitude R_i / |b_i - v|
// N(b_i^r / scale + offset)) over [0, Dvp] (b_i^r from the unperturbed ray, clamped to
// [0, Dvp]), summed with beta0 Dvp, at full resolution (measured 3.5e-6; with the noise
// left out of the reference 0.61, with its lookup point 0.3 m further along the ray 0.75).
TEST(GaussianSplat, NoiseMatchesItsDefinition) {
    const GaussianMedium m = cloud(25, 17, 0.01);
    const SmallCamera cam(64, 36);
    const std::vector<float> depth = ground_depth(cam);
    GaussianNoise noise;
    noise.amplitude = 0.4;
    noise.scale = 0.9;
    noise.offset = Vec3(0.3, -1.2, 2.5);
    GaussianSplat s(m, Vec3(0.0), kLights, kI0, RGB(1.0), {}, nullptr, noise, 2);
    s.bin(cam.D0, cam.Dx, cam.Dy, cam.forward, cam.W, cam.H, 0.0, 1);
    const Image im = splat_image(s, cam, depth);
    double worst = 0.0;
    int checked = 0;
    for (int j = 0; j < cam.H; ++j)
        for (int i = 0; i < cam.W; ++i) {
            const size_t p = size_t(j) * cam.W + i;
            const double Dvp = depth[p];
            if (!std::isfinite(Dvp)) continue;
            const Vec3 r = cam.dir(i, j);
            double T = 0.01 * Dvp;
            for (std::size_t g = 0; g < m.size(); ++g) {
                const Vec3 b = m.centre(g);
                const double tr = std::clamp(glm::dot(b, r), 0.0, Dvp);
                const Vec3 q = tr * r / noise.scale + noise.offset;
                float nx, ny, nz;
                gradient_noise3(float(q.x), float(q.y), float(q.z), nx, ny, nz);
                const double k = noise.amplitude * m.cull_radius(g) / glm::length(b);
                const Vec3 rp = glm::normalize(r + k * Vec3(nx, ny, nz));
                T += gaussian_line_integral(m.amplitude(g), m.scale(g), b, Vec3(0.0), rp, 0.0, Dvp);
            }
            const double got = -std::log(double(im.T[3 * p]));
            worst = std::max(worst, std::abs(got - T) / T);
            ++checked;
        }
    std::printf("noisy optical depth vs its definition: max rel %.3g over %d pixels\n", worst, checked);
    EXPECT_GT(checked, 500);
    EXPECT_LT(worst, 2e-4);  // float kernels (fast_erf) against double; culling < 1e-7 each
}

// Around a light's image: Gaussians whose b^r can come close to the light (around it, or
// at its depth beside it) stay exact per pixel, the others (before or behind it on its line
// of sight) take the lattice like anywhere else (GaussianSplat::light_clear). Before, every
// Gaussian within 64 px of the image was exact and those beside the light, further out,
// were interpolated (0.78 % airlight error 100 px from the image with them 2.5 m away).
TEST(GaussianSplat, LightImageTilesAgainstFull) {
    std::mt19937 rng(3);
    std::uniform_real_distribution<double> U(0.0, 1.0);
    const Vec3 light(1.0, 0.8, 20.0);
    const Vec3 to_light = glm::normalize(light);
    std::vector<double> b, a, c;
    for (int i = 0; i < 40; ++i) {  // on the line of sight to the light, before and behind it
        const double t = i % 2 == 0 ? 5.0 + 7.0 * U(rng) : 30.0 + 10.0 * U(rng);
        const Vec3 p = t * to_light + Vec3(0.3 * (U(rng) - 0.5) * t / 10.0, 0.3 * (U(rng) - 0.5) * t / 10.0, 0.0);
        b.insert(b.end(), {p.x, p.y, p.z});
        a.push_back(1.0 / (2.0 + 1.0 * U(rng)));
        c.push_back(0.02 + 0.05 * U(rng));
    }
    for (int i = 0; i < 4; ++i) {  // around the light itself
        const Vec3 p = light + Vec3(2.0 * (U(rng) - 0.5), 2.0 * (U(rng) - 0.5), 2.0 * (U(rng) - 0.5));
        b.insert(b.end(), {p.x, p.y, p.z});
        a.push_back(1.0 / (0.5 + 0.5 * U(rng)));
        c.push_back(0.1 + 0.2 * U(rng));
    }
    for (int i = 0; i < 4; ++i) {  // at the light's depth, 4 m beside it: b^r passes the light
        const double phi = 1.5707963267948966 * i;
        const Vec3 p = light + Vec3(4.0 * std::cos(phi), 4.0 * std::sin(phi), 0.0);
        b.insert(b.end(), {p.x, p.y, p.z});
        a.push_back(1.0 / 3.0);
        c.push_back(0.05);
    }
    const GaussianMedium m(b, a, c, 0.004);
    const SmallCamera cam(640, 360);
    const std::vector<float> depth = ground_depth(cam);
    GaussianSplat s(m, Vec3(0.0), {light}, {RGB(300.0, 250.0, 200.0)}, RGB(0.9), {}, nullptr, GaussianNoise{}, 2);
    s.bin(cam.D0, cam.Dx, cam.Dy, cam.forward, cam.W, cam.H, 0.0, 1);
    const Image full = splat_image(s, cam, depth);
    s.bin(cam.D0, cam.Dx, cam.Dy, cam.forward, cam.W, cam.H, 0.0, 4);
    const Image quarter = splat_image(s, cam, depth);
    const GaussianSplat::ReducedCounts rc = s.reduced_counts();
    // The light's image and the 96 px around it.
    const Vec3 q = light / light.z;
    const double lx = (q.x - cam.D0.x) / cam.Dx.x, ly = (q.y - cam.D0.y) / cam.Dy.y;
    double worst_A = 0.0, worst_T = 0.0;
    for (int j = 0; j < cam.H; ++j)
        for (int i = 0; i < cam.W; ++i) {
            if (std::abs(i + 0.5 - lx) > 96.0 || std::abs(j + 0.5 - ly) > 96.0) continue;
            const size_t p = size_t(j) * cam.W + i;
            worst_A = std::max(worst_A, std::abs(double(quarter.A[3 * p]) - double(full.A[3 * p])) / double(full.A[3 * p]));
            worst_T = std::max(worst_T, std::abs(double(quarter.T[3 * p]) - double(full.T[3 * p])) / double(full.T[3 * p]));
        }
    std::printf("next to the light's image: %zu lattice (%zu fine), %zu exact pairs; quarter vs full: airlight max "
                "rel %.3g, transmittance max rel %.3g\n", rc.lattice, rc.fine, rc.exact, worst_A, worst_T);
    EXPECT_GT(rc.lattice, 0u);  // the far ones take the lattice
    EXPECT_GT(rc.exact, 0u);    // the ones around the light do not
    EXPECT_GT(rc.fine, 0u);     // those clear of it at half the spacing take the fine lattice
    // measured 8.0e-4 and 9.2e-3 (the quarter lattice's own error on the Gaussians of ~20 px
    // 30-40 m away, as anywhere in the image); with every Gaussian on the lattice (light_clear
    // always true, those around and beside the light included): airlight 0.215
    EXPECT_LT(worst_A, 2e-3);
    EXPECT_LT(worst_T, 2e-2);
}

// Near clip: the segment [t0, Dvp] against the exact formula
// exp(T(v, t0)) (La(Dvp) - La(t0)), and the per-ray twin (edge samples) against the splat.
TEST(GaussianSplat, NearClipAndPerRayTwin) {
    const GaussianMedium m = cloud(30, 5, 0.02);
    const SmallCamera cam(48, 32);
    const double clip_start = 0.25;
    const RGB albedo(1.0);
    GaussianSplat s(m, Vec3(0.0), kLights, kI0, albedo, {}, nullptr, GaussianNoise{}, 2);
    s.bin(cam.D0, cam.Dx, cam.Dy, cam.forward, cam.W, cam.H, clip_start);
    const std::vector<float> depth = ground_depth(cam);
    const Image im = splat_image(s, cam, depth);
    std::vector<Vec3> dirs;
    std::vector<float> t0;
    for (int j = 0; j < cam.H; ++j)
        for (int i = 0; i < cam.W; ++i) {
            dirs.push_back(cam.dir(i, j));
            t0.push_back(float(clip_start / glm::dot(dirs.back(), cam.forward)));
        }
    std::vector<double> Tr(dirs.size());
    std::vector<RGB> La(dirs.size());
    s.eval_rays(dirs.data(), depth.data(), t0.data(), int(dirs.size()), Tr.data(), La.data());
    double worst_A = 0.0, worst_twin = 0.0, worst_T = 0.0;
    for (size_t p = 0; p < dirs.size(); ++p) {
        const double tn = double(t0[p]), Dvp = double(depth[p]);
        const double Tn = m.optical_depth_all_ray(Vec3(0.0), dirs[p], tn);
        const RGB ref = std::exp(Tn) * (s.eval_exact(dirs[p], Dvp) - s.eval_exact(dirs[p], tn));
        const double T_ref = std::exp(-m.optical_depth_all(dirs[p] * tn, std::isinf(Dvp) ? dirs[p] * 1e4 : dirs[p] * Dvp));
        if (!std::isinf(Dvp)) worst_T = std::max(worst_T, std::abs(double(im.T[3 * p]) - T_ref));
        for (int c = 0; c < 3; ++c) {
            worst_A = std::max(worst_A, std::abs(double(im.A[3 * p + c]) - ref[c]) / ref[c]);
            worst_twin = std::max(worst_twin, std::abs(double(im.A[3 * p + c]) - La[p][c]) / La[p][c]);
        }
        worst_twin = std::max(worst_twin, std::abs(double(im.T[3 * p]) - Tr[p]));
    }
    std::printf("near clip: splat vs exact airlight max rel %.3g, T max abs %.3g; splat vs per-ray twin %.3g\n",
                worst_A, worst_T, worst_twin);
    EXPECT_LT(worst_A, 5e-4);
    EXPECT_LT(worst_T, 2e-5);
    EXPECT_LT(worst_twin, 1e-5);
}

// Per-Gaussian colour: two Gaussians far apart, one red and one blue: each pixel's
// airlight takes its Gaussian's colour, and the splat matches the exact RGB path.
TEST(GaussianSplat, PerGaussianColour) {
    const GaussianMedium m({-3.0, 0.0, 10.0, 3.0, 0.0, 10.0}, {2.0, 2.0}, {0.5, 0.5}, 0.0);
    const SmallCamera cam(64, 32);
    const std::vector<double> colours = {1.0, 0.2, 0.0, 0.0, 0.3, 1.0};
    const std::vector<Vec3> light = {Vec3(0.0, 4.0, 10.0)};
    const std::vector<RGB> I0 = {RGB(1.0)};
    GaussianSplat s(m, Vec3(0.0), light, I0, RGB(1.0), colours, nullptr, GaussianNoise{}, 1);
    s.bin(cam.D0, cam.Dx, cam.Dy, cam.forward, cam.W, cam.H, 0.0);
    const std::vector<float> depth(size_t(cam.W) * cam.H, std::numeric_limits<float>::infinity());
    const Image im = splat_image(s, cam, depth);
    double worst = 0.0;
    for (int j = 0; j < cam.H; ++j)
        for (int i = 0; i < cam.W; ++i) {
            const size_t p = size_t(j) * cam.W + i;
            const RGB ref = s.eval_exact(cam.dir(i, j), std::numeric_limits<double>::infinity());
            for (int c = 0; c < 3; ++c)
                if (ref[c] > 0.0) worst = std::max(worst, std::abs(double(im.A[3 * p + c]) - ref[c]) / ref[c]);
        }
    EXPECT_LT(worst, 2e-4);
    // Through the left (red) Gaussian's centre: R : G : B = 1 : 0.2 : ~0; right: 0 : 0.3 : 1.
    const int jm = cam.H / 2;
    auto px = [&](double x) {  // pixel column looking at (x, 0, 10)
        return int((x / 10.0 - cam.D0.x) / cam.Dx.x);
    };
    const float* left = &im.A[3 * (size_t(jm) * cam.W + px(-3.0))];
    const float* right = &im.A[3 * (size_t(jm) * cam.W + px(3.0))];
    EXPECT_NEAR(left[1] / left[0], 0.2, 1e-3);
    EXPECT_LT(left[2], 1e-3 * left[0]);
    EXPECT_NEAR(right[1] / right[2], 0.3, 1e-3);
    EXPECT_LT(right[0], 1e-3 * right[2]);
    // With one colour for all, per-Gaussian albedo equal to the medium's gives the same image.
    GaussianSplat grey(m, Vec3(0.0), light, I0, RGB(0.5), {0.5, 0.5, 0.5, 0.5, 0.5, 0.5}, nullptr, GaussianNoise{}, 1);
    GaussianSplat plain(m, Vec3(0.0), light, I0, RGB(0.5), {}, nullptr, GaussianNoise{}, 1);
    grey.bin(cam.D0, cam.Dx, cam.Dy, cam.forward, cam.W, cam.H, 0.0);
    plain.bin(cam.D0, cam.Dx, cam.Dy, cam.forward, cam.W, cam.H, 0.0);
    EXPECT_EQ(splat_image(grey, cam, depth).A, splat_image(plain, cam, depth).A);
}

// Noise: amplitude 0 is the code path without noise (bit-identical images); a nonzero
// amplitude changes the image, deterministically, and each Gaussian's optical depth stays
// within its line-integral bound c sqrt(pi) / a (so T >= exp(-sum of the bounds)).
TEST(GaussianSplat, NoiseOffIdenticalOnBounded) {
    const GaussianMedium m = cloud(30, 9, 0.01);
    const SmallCamera cam(48, 32);
    const std::vector<float> depth = ground_depth(cam);
    auto render = [&](const GaussianNoise& noise) {
        GaussianSplat s(m, Vec3(0.0), kLights, kI0, RGB(1.0), {}, nullptr, noise, 1);
        s.bin(cam.D0, cam.Dx, cam.Dy, cam.forward, cam.W, cam.H, 0.1);
        return splat_image(s, cam, depth);
    };
    const Image base = render(GaussianNoise{});
    GaussianNoise zero;
    zero.scale = 0.37;
    zero.offset = Vec3(1.0, 2.0, 3.0);
    const Image off = render(zero);
    EXPECT_EQ(base.A, off.A);
    EXPECT_EQ(base.T, off.T);
    GaussianNoise on;
    on.amplitude = 0.5;
    on.scale = 0.7;
    const Image a = render(on), b = render(on);
    EXPECT_EQ(a.A, b.A);  // deterministic
    on.offset = Vec3(0.5, 0.0, 0.0);
    const Image shifted = render(on);
    double sum_bound = 0.0;
    for (std::size_t i = 0; i < m.size(); ++i) sum_bound += m.amplitude(i) * 1.7724538509 / m.scale(i);
    double mean_change = 0.0, mean_shift = 0.0, max_change = 0.0;
    int count = 0;
    for (size_t p = 0; p < depth.size(); ++p) {
        if (std::isinf(depth[p])) continue;
        const double tb = -std::log(double(base.T[3 * p])), tn = -std::log(double(a.T[3 * p]));
        const double bg = 0.01 * (double(depth[p]) - 0.1);
        EXPECT_LE(tn - bg, sum_bound * (1.0 + 1e-5));
        EXPECT_GE(tn - bg, -1e-5);
        mean_change += std::abs(tn - tb);
        mean_shift += std::abs(-std::log(double(shifted.T[3 * p])) - tn);
        max_change = std::max(max_change, std::abs(double(a.A[3 * p]) - base.A[3 * p]) / base.A[3 * p]);
        ++count;
    }
    mean_change /= count;
    mean_shift /= count;
    std::printf("noise 0.5: mean |dT| %.3g, with shifted offset %.3g, max airlight rel change %.3g\n", mean_change,
                mean_shift, max_change);
    EXPECT_GT(mean_change, 1e-3);
    EXPECT_GT(mean_shift, 1e-4);  // the offset animates it
    EXPECT_LT(max_change, 3.0);
}

}  // namespace
}  // namespace airlight

namespace airlight {
namespace {
// Profiling aid (not a timed test; run with --gtest_also_run_disabled_tests): the
// 3000-Gaussian benchmark cloud of bench_rbf.py (AIRLIGHT_PROFILE_34 set: its 34 broad
// Gaussians) at 1920 x 1080, one light, one thread; full, half and quarter resolution.
TEST(GaussianSplat, DISABLED_Profile3000) {
    std::mt19937 rng(2);
    std::uniform_real_distribution<double> U(0.0, 1.0);
    std::vector<double> b, a, c;
    const bool broad = std::getenv("AIRLIGHT_PROFILE_34") != nullptr;  // the 34 broad Gaussians instead
    for (int i = 0; i < (broad ? 34 : 3000); ++i) {
        b.insert(b.end(), {-30.0 + 60.0 * U(rng), -2.0 + 8.0 * U(rng), 10.0 + 70.0 * U(rng)});
        a.push_back(broad ? 1.0 / (3.0 + 7.0 * U(rng)) : 1.0 / (1.0 + 2.0 * U(rng)));
        c.push_back(broad ? 0.005 + 0.015 * U(rng) : 0.01 + 0.04 * U(rng));
    }
    const GaussianMedium m(b, a, c, 0.002);
    SmallCamera cam(1920, 1080);
    const SpecialFTable table(256, 256);
    // (the 34 with bench_rbf.py's 3 lights)
    const std::vector<Vec3> lights = broad ? std::vector<Vec3>{Vec3(-8.0, 4.0, 30.0), Vec3(6.0, 3.0, 45.0), Vec3(0.0, 8.0, 60.0)}
                                           : std::vector<Vec3>{Vec3(-8.0, 4.0, 30.0)};
    // (AIRLIGHT_PROFILE_THREADS=k: bin() and the splat's set-up on k threads; the tiles stay on one)
    const char* threads = std::getenv("AIRLIGHT_PROFILE_THREADS");
    GaussianSplat s(m, Vec3(0.0), lights, std::vector<RGB>(lights.size(), RGB(40.0)), RGB(0.9), {}, &table, GaussianNoise{},
               threads ? std::atoi(threads) : 1);
    s.bin(cam.D0, cam.Dx, cam.Dy, cam.forward, cam.W, cam.H, 0.1);
    std::vector<float> depth(size_t(cam.W) * cam.H);
    for (int j = 0; j < cam.H; ++j)
        for (int i = 0; i < cam.W; ++i) {
            const Vec3 d = cam.dir(i, j);
            depth[size_t(j) * cam.W + i] = d.y < -1e-6 ? float(-2.0 / d.y) : std::numeric_limits<float>::infinity();
        }
    std::vector<float> T(3 * depth.size()), A(3 * depth.size());
    // AIRLIGHT_PROFILE_STEP=s: only that step (for perf).
    const char* only = std::getenv("AIRLIGHT_PROFILE_STEP");
    if (only) {
        s.bin(cam.D0, cam.Dx, cam.Dy, cam.forward, cam.W, cam.H, 0.1, std::atoi(only), depth.data());
        for (int rep = 0; rep < 3; ++rep)
            for (int t = 0; t < s.num_tiles(); ++t) s.splat_tile(t, depth.data(), T.data(), A.data());
        return;
    }
    const std::clock_t t0 = std::clock();  // CPU time: the machine may be shared
    for (int t = 0; t < s.num_tiles(); ++t) s.splat_tile(t, depth.data(), T.data(), A.data());
    const double sec = double(std::clock() - t0) / CLOCKS_PER_SEC;
    std::printf("splat 1920x1080: %.3f s CPU, %zu (tile, Gaussian) pairs = %.1f per pixel, %.2f ns per pixel-Gaussian\n",
                sec, s.num_pairs(), double(s.num_pairs()) * GaussianSplat::kTile * GaussianSplat::kTile / depth.size(),
                sec * 1e9 / (double(s.num_pairs()) * GaussianSplat::kTile * GaussianSplat::kTile));
    for (int step : {2, 4}) {
        for (const bool grids : {false, true}) {
            const std::clock_t b0 = std::clock();
            s.bin(cam.D0, cam.Dx, cam.Dy, cam.forward, cam.W, cam.H, 0.1, step, grids ? depth.data() : nullptr);
            const double sec_b = double(std::clock() - b0) / CLOCKS_PER_SEC;
            const std::clock_t c0 = std::clock();
            for (int t = 0; t < s.num_tiles(); ++t) s.splat_tile(t, depth.data(), T.data(), A.data());
            const double sec_s = double(std::clock() - c0) / CLOCKS_PER_SEC;
            const GaussianSplat::ReducedCounts rc = s.reduced_counts();
            std::printf("step %d%s: bin %.3f s, splat %.3f s CPU (x%.2f), pairs lattice %zu (coarse %zu, far %zu), "
                        "exact %zu, behind %zu; far-field %zu Gaussians, %zu nodes\n",
                        step, grids ? " with far-field grids" : "", sec_b, sec_s, sec / sec_s, rc.lattice, rc.coarse,
                        rc.far, rc.exact, rc.behind, rc.far_gaussians, rc.far_nodes);
        }
    }
}
}  // namespace
}  // namespace airlight
