// environment_test.cpp: Fogshop's average optical depth (section 4.2) against quadrature
// of its definition, the Barnes-Hut far field against the brute-force sum and its stated
// bound, and the per-point environment irradiance against the homogeneous one.
#include "core/constants.h"
#include "gaussian/environment.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <stdexcept>

#include "core/quadrature.h"

namespace airlight {
namespace {

TEST(GaussianEnvironment, DawsonAgainstMpmath) {
    // sqrt(pi)/2 e^{-x^2} erfi(x) with mpmath at 30 digits.
    const double x[] = {0.1, 0.5, 1.0, 2.0, 5.0, 10.0, 40.0};
    const double F[] = {0.099335992397852866508, 0.42443638350202229593, 0.53807950691276841914,
                        0.30134038892379196603,  0.10213407442427683544, 0.050253847187598528033,
                        0.012503909917843973199};
    for (int k = 0; k < 7; ++k) {
        EXPECT_NEAR(dawson(x[k]) / F[k], 1.0, 2e-15) << x[k];
        EXPECT_NEAR(dawson(-x[k]) / -F[k], 1.0, 2e-15) << x[k];
    }
    EXPECT_EQ(dawson(0.0), 0.0);
}

// T(u) = (1/4pi) int_S int_0^inf exp(-|u + t w|^2) dt dw with u on the z axis: the azimuth
// integrates to 2 pi, leaving (1/2) int_{-1}^{1} int_0^inf exp(-(u^2 + 2 u t mu + t^2)) dt dmu.
double average_depth_by_quadrature(double u) {
    return 0.5 * integrate_adaptive(
                     [u](double mu) {
                         return integrate_adaptive(
                             [u, mu](double t) { return std::exp(-(u * u + 2.0 * u * t * mu + t * t)); }, 0.0,
                             INFINITY, 1e-12);
                     },
                     -1.0, 1.0, 1e-11);
}

TEST(GaussianEnvironment, UnitAverageDepthAgainstQuadratureAndLimits) {
    for (double u : {0.0, 0.05, 0.3, 1.0, 2.0, 4.0, 7.9, 8.1, 15.0}) {
        const double ref = average_depth_by_quadrature(u);
        EXPECT_NEAR(average_depth_unit(u) / ref, 1.0, 1e-9) << u;
        EXPECT_NEAR(average_depth_unit_fast(u) / ref, 1.0, 1e-9) << u;
    }
    EXPECT_DOUBLE_EQ(average_depth_unit(0.0), 0.5 * kSqrtPi);
    EXPECT_NEAR(average_depth_unit(1e4) / (kSqrtPi / (4e8)), 1.0, 1e-8);
    EXPECT_EQ(average_depth_unit_fast(INFINITY), 0.0);
    EXPECT_THROW(average_depth_unit(-1.0), std::invalid_argument);
}

TEST(GaussianEnvironment, FastTableError) {
    // Dense scan (incl. between the table's nodes and across the switch at u = 32).
    double worst = 0.0;
    for (int k = 0; k <= 200000; ++k) {
        const double u = 40.0 * k / 200000.0 + 1e-7 * (k % 7);
        worst = std::max(worst, std::abs(average_depth_unit_fast(u) / average_depth_unit(u) - 1.0));
    }
    EXPECT_LT(worst, 2e-10);
}

GaussianMedium random_cloud(std::mt19937& rng, int n, double beta0, int blobs, double spread) {
    std::uniform_real_distribution<double> U(-1.0, 1.0), A(0.7, 3.0), C(0.0, 0.8);
    std::vector<Vec3> blob(static_cast<std::size_t>(blobs));
    for (Vec3& b : blob) b = Vec3(U(rng), U(rng), U(rng)) * spread;
    std::vector<double> centres, scales, amps;
    for (int i = 0; i < n; ++i) {
        const Vec3 b = blob[static_cast<std::size_t>(i % blobs)] + Vec3(U(rng), U(rng), U(rng)) * 1.5;
        centres.insert(centres.end(), {b.x, b.y, b.z});
        scales.push_back(A(rng));
        amps.push_back(i % 13 == 0 ? 0.0 : C(rng));
    }
    return GaussianMedium(centres, scales, amps, beta0);
}

TEST(GaussianEnvironment, AverageDepthAgainstDirectionalQuadrature) {
    // (1/4pi) int_S int_0^D beta(p + t w) dt dw with the exact erf line integrals on a
    // Gauss-Legendre (mu) x trapezoid (phi) grid: independent of Dawson's function.
    const GaussianMedium m({0.0, 0.0, 0.0, 1.5, 0.3, -0.2, -0.4, 1.0, 0.7}, {1.0, 2.0, 0.6}, {0.8, 1.5, 0.3}, 0.02);
    const double D = 1e4;
    const GaussianAverageDepth avg(m, D);
    std::vector<double> x, w;
    gauss_legendre(96, x, w);
    for (const Vec3& p : {Vec3(0.0), Vec3(0.3, -0.5, 0.2), Vec3(4.0, 1.0, -2.0), Vec3(1.5, 0.3, -0.1)}) {
        double sum = 0.0;
        constexpr int kPhi = 192;
        for (std::size_t j = 0; j < x.size(); ++j) {
            const double st = std::sqrt(1.0 - x[j] * x[j]);
            for (int k = 0; k < kPhi; ++k) {
                const double phi = 2.0 * kPi * (k + 0.5) / kPhi;
                const Vec3 dir(st * std::cos(phi), st * std::sin(phi), x[j]);
                sum += w[j] * (2.0 * kPi / kPhi) * m.optical_depth_all(p, p + D * dir);
            }
        }
        const double ref = sum / (4.0 * kPi);
        double got = 0.0, brute = 0.0;
        avg.evaluate(&p, 1, &got, 0.0, 1);
        avg.evaluate_brute(&p, 1, &brute, 1);
        EXPECT_NEAR(brute / ref, 1.0, 1e-6) << p.x;
        EXPECT_NEAR(got / ref, 1.0, 1e-6) << p.x;
    }
}

TEST(GaussianEnvironment, FarFieldWithinItsBound) {
    std::mt19937 rng(7);
    for (double beta0 : {0.0, 0.01}) {
        const GaussianMedium m = random_cloud(rng, 3000, beta0, 12, 25.0);
        const GaussianAverageDepth avg(m, 50.0);
        std::uniform_real_distribution<double> U(-1.0, 1.0);
        std::vector<Vec3> p(4000);
        for (std::size_t k = 0; k < p.size(); ++k) {
            const double scale = k < 2000 ? 30.0 : 200.0;  // inside the cloud and far from it
            p[k] = Vec3(U(rng), U(rng), U(rng)) * scale;
        }
        std::vector<double> ref(p.size()), got(p.size());
        avg.evaluate_brute(p.data(), p.size(), ref.data());
        for (double tol : {1e-2, 1e-3, 1e-4}) {
            const AverageDepthStats stats = avg.evaluate(p.data(), p.size(), got.data(), tol);
            EXPECT_GT(stats.far_terms, 0u) << "the far field was never used";
            double worst = 0.0;
            for (std::size_t k = 0; k < p.size(); ++k) worst = std::max(worst, std::abs(got[k] / ref[k] - 1.0));
            EXPECT_LE(worst, tol + 1e-9) << "tol " << tol << " beta0 " << beta0;
            // Cheaper than brute force.
            EXPECT_LT(stats.near_terms + stats.far_terms, p.size() * m.size()) << tol;
        }
        // tol = 0: every Gaussian exact (through the table).
        avg.evaluate(p.data(), p.size(), got.data(), 0.0);
        for (std::size_t k = 0; k < p.size(); ++k) EXPECT_NEAR(got[k] / ref[k], 1.0, 1e-9);
    }
}

TEST(GaussianEnvironment, LinearNearFieldWithinItsBound) {
    // Dense points on two planes through a cloud (as a rendered surface gives them): groups are
    // small, so near Gaussians go through the per-group linear model; the total error stays
    // within tol Tbar.
    std::mt19937 rng(11);
    const GaussianMedium m = random_cloud(rng, 800, 0.0, 6, 8.0);
    const GaussianAverageDepth avg(m, 50.0);
    std::vector<Vec3> p;
    for (int j = 0; j < 100; ++j)
        for (int i = 0; i < 100; ++i) {
            p.emplace_back(-1.0 + 0.02 * i, -2.0, -1.0 + 0.02 * j);
            p.emplace_back(-1.0 + 0.02 * i, -1.0 + 0.02 * j, 3.0 + 0.005 * i);
        }
    std::vector<double> ref(p.size()), got(p.size());
    avg.evaluate_brute(p.data(), p.size(), ref.data());
    for (double tol : {1e-2, 1e-3}) {
        const AverageDepthStats stats = avg.evaluate(p.data(), p.size(), got.data(), tol);
        EXPECT_GT(stats.linear_terms, stats.points) << "the linear model was hardly used, tol " << tol;
        double worst = 0.0;
        for (std::size_t k = 0; k < p.size(); ++k) worst = std::max(worst, std::abs(got[k] / ref[k] - 1.0));
        EXPECT_LE(worst, tol + 1e-9) << "tol " << tol;
    }
}

TEST(GaussianEnvironment, LinearisedFarFieldWithinItsBound) {
    // A compact cloud seen from dense patches in a plane through it (displacements along the
    // line of sight, where the Hessian of 1/r^2 is largest: 6 / r^4): far nodes go through the
    // blocks' and groups' linear models only where the Taylor remainder H rho^2 / 2 of their
    // expansion fits. Patches of coarse spacing have blocks whose linearisation would be off by
    // several percent (3 (rho / r)^2 of the node), far beyond tol.
    std::mt19937 rng(5);
    std::uniform_real_distribution<double> U(-1.0, 1.0), A(2.0, 4.0), Cc(0.1, 0.5);
    std::vector<double> centres, scales, amps;
    for (int i = 0; i < 600; ++i) {
        centres.insert(centres.end(), {U(rng), 0.5 * U(rng), U(rng)});
        scales.push_back(A(rng));
        amps.push_back(Cc(rng));
    }
    const GaussianMedium m(centres, scales, amps, 0.0);
    const GaussianAverageDepth avg(m, 50.0);
    std::vector<Vec3> p;
    for (double D : {9.0, 14.0, 22.0})
        for (double spacing : {0.01, 0.06, 0.25})
            for (int j = 0; j < 48; ++j)
                for (int i = 0; i < 48; ++i)
                    p.emplace_back(D + spacing * (i - 23.5), 0.0, (D - 12.0) + spacing * (j - 23.5));
    std::vector<double> ref(p.size()), got(p.size());
    avg.evaluate_brute(p.data(), p.size(), ref.data());
    for (double tol : {1e-2, 1e-3}) {
        const AverageDepthStats stats = avg.evaluate(p.data(), p.size(), got.data(), tol);
        EXPECT_GT(stats.far_linear_terms, stats.points) << "far nodes were hardly linearised, tol " << tol;
        EXPECT_GT(stats.far_terms, 0u) << "every far node was linearised, tol " << tol;
        double worst = 0.0;
        for (std::size_t k = 0; k < p.size(); ++k) worst = std::max(worst, std::abs(got[k] / ref[k] - 1.0));
        EXPECT_LE(worst, tol + 1e-9) << "tol " << tol;
    }
}

TEST(GaussianEnvironment, BadInput) {
    const GaussianMedium m({0.0, 0.0, 0.0}, {1.0}, {1.0}, 0.0);
    EXPECT_THROW(GaussianAverageDepth(m, -1.0), std::invalid_argument);
    EXPECT_THROW(GaussianAverageDepth(m, INFINITY), std::invalid_argument);
    const GaussianAverageDepth avg(m, 10.0);
    const Vec3 bad(NAN, 0.0, 0.0);
    double out = 0.0;
    EXPECT_THROW(avg.evaluate(&bad, 1, &out, 1e-3), std::invalid_argument);
    const Vec3 good(1.0, 0.0, 0.0);
    EXPECT_THROW(avg.evaluate(&good, 1, &out, -1.0), std::invalid_argument);
    EXPECT_THROW(psf_band_eigenvalues(NAN), std::invalid_argument);
    // No Gaussians: beta0 D only.
    const GaussianAverageDepth empty(GaussianMedium({}, {}, {}, 0.05), 40.0);
    empty.evaluate(&good, 1, &out, 1e-3);
    EXPECT_DOUBLE_EQ(out, 2.0);
}

TEST(GaussianEnvironment, PsfBandTableAgainstExactEigenvalues) {
    double worst_rel = 0.0, worst_ratio = 0.0;
    for (double T : {1e-4, 3e-3, 0.02, 0.1, 0.37, 1.0, 2.2, 5.5, 13.0, 41.0, 120.0}) {
        const std::vector<double> ref = psf_eigenvalues(T, 2, PsfKind::Exact);
        const std::array<double, 3> got = psf_band_eigenvalues(T);
        for (int l = 0; l < 3; ++l) {
            worst_rel = std::max(worst_rel, std::abs(got[size_t(l)] / ref[size_t(l)] - 1.0));
            // Its effect on E_fogged / E_world (lambda_l <= 1 of the World's band l).
            worst_ratio = std::max(worst_ratio, std::abs(got[size_t(l)] - ref[size_t(l)]));
        }
    }
    EXPECT_LT(worst_rel, 1e-3);  // worst as T -> 0, where lambda ~ T (0.86e-3 at T = 1e-4)
    EXPECT_LT(worst_ratio, 2e-6);
    EXPECT_EQ(psf_band_eigenvalues(0.0)[0], 0.0);
    EXPECT_TRUE(std::isfinite(psf_band_eigenvalues(1e6)[0]));
}

TEST(GaussianEnvironment, VaryingIrradianceEqualsHomogeneousAtUniformDepth) {
    // A World with a bright spot: per-point irradiance at a uniform T equals the homogeneous
    // environment_irradiance() with the exact eigenvalues of that T.
    EnvironmentMap world;
    world.width = 64;
    world.height = 32;
    world.rgb.assign(size_t(3) * 64 * 32, 0.2f);
    for (int j = 4; j < 9; ++j)
        for (int i = 10; i < 16; ++i)
            for (int c = 0; c < 3; ++c) world.rgb[size_t(3 * (j * 64 + i) + c)] = 30.0f + 5.0f * c;
    const RGB albedo(0.9, 0.8, 0.7);
    std::mt19937 rng(3);
    std::normal_distribution<double> N(0.0, 1.0);
    std::vector<Vec3> normals(50);
    for (Vec3& n : normals) n = glm::normalize(Vec3(N(rng), N(rng), N(rng)));
    for (double T : {0.05, 0.8, 2.5, 9.0}) {
        const EnvironmentFog fog = environment_fog(world, T / 40.0, 40.0, 2, 8, 4, PsfKind::Exact);
        std::vector<double> Tk(normals.size(), T);
        std::vector<RGB> Ew(normals.size()), Ef(normals.size());
        environment_irradiance_varying(fog.sh_world, albedo, normals.data(), Tk.data(), normals.size(), Ew.data(),
                                       Ef.data(), 2);
        for (std::size_t k = 0; k < normals.size(); ++k) {
            RGB ew, ef;
            environment_irradiance(fog, albedo, normals[k], ew, ef);
            for (int c = 0; c < 3; ++c) {
                EXPECT_NEAR(Ew[k][c], ew[c], 1e-12 * std::abs(ew[c]) + 1e-12);
                EXPECT_NEAR(Ef[k][c] / Ew[k][c], ef[c] / ew[c], 2e-6) << "T " << T;
            }
        }
    }
    const std::vector<double> bad_T = {-1.0};
    std::vector<RGB> e0(1), e1(1);
    EXPECT_THROW(environment_irradiance_varying(environment_fog(world, 0.1, 10.0, 2, 8, 4).sh_world, albedo,
                                                normals.data(), bad_T.data(), 1, e0.data(), e1.data()),
                 std::invalid_argument);
}

}  // namespace
}  // namespace airlight
