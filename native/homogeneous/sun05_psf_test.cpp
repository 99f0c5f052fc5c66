// sun05_psf_test.cpp: PSF / NPSF against the airlight kernel and Fogshop's published
// coefficients; spherical harmonics against direct convolution and analytic identities.
#include "core/constants.h"
#include "homogeneous/sun05_psf.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "core/quadrature.h"
#include "homogeneous/sun05.h"

namespace airlight {
namespace {


TEST(Sun05Psf, EqualsScaledAirlight) {
    // eq. 20: PSF = Dsv^2 La / I0, with La from the Sun 2005 kernel (exact F), Dvp = inf.
    for (double Tsv : {0.05, 0.5, 1.0, 3.0, 12.0}) {
        for (double g : {1e-3, 0.05, 0.4, 1.0, 2.0, 3.0, 3.14}) {
            const double sigma = 0.2, Dsv = Tsv / sigma;
            const double La = sun05_airlight(sigma, Dsv, std::cos(g), INFINITY, nullptr, FEval::Exact);
            const double want = Dsv * Dsv * La;
            EXPECT_NEAR(sun05_psf(Tsv, std::cos(g)) / want, 1.0, 1e-8) << "Tsv " << Tsv << " gamma " << g;
        }
    }
}

TEST(Sun05Psf, LimitsAndFiniteness) {
    // Back side limit Tsv e^-Tsv / (4 pi) at gamma = pi (see sun05_psf.cpp).
    // gamma = pi: PSF = Tsv e^-Tsv / (4 pi) int_0^inf e^{-2 Tsv y} / (1 + y)^2 dy (the light right
    // behind the viewer; eq. 5 with x = Dsv y).
    const double h = integrate_adaptive([](double y) { return std::exp(-4.0 * y) / ((1 + y) * (1 + y)); }, 0.0, INFINITY, 1e-13);
    EXPECT_NEAR(sun05_psf(2.0, -1.0) / (2.0 * std::exp(-2.0) / (4.0 * kPi) * h), 1.0, 1e-9);
    EXPECT_NEAR(sun05_psf_angle(2.0, kPi - 1e-6) / sun05_psf(2.0, -1.0), 1.0, 1e-6);
    EXPECT_TRUE(std::isinf(sun05_psf(1.0, 1.0)));
    for (double g : {1e-300, 1e-12, 1e-6, 3.14159265358}) {
        EXPECT_TRUE(std::isfinite(sun05_psf_angle(1.0, g))) << g;
        EXPECT_TRUE(std::isfinite(sun05_npsf_angle(g))) << g;
    }
    for (double c : {1.0 - 1e-15, 1.0 - 1e-12, 0.999999, -0.999999999999}) {
        EXPECT_TRUE(std::isfinite(sun05_psf(1.0, c))) << c;
        EXPECT_TRUE(std::isfinite(sun05_npsf(c))) << c;
    }
    EXPECT_THROW(sun05_psf(-1.0, 0.5), std::invalid_argument);
    EXPECT_THROW(sun05_psf(1.0, NAN), std::invalid_argument);
    // NPSF is the PSF at Tsv = 1 over Tsv e^-Tsv (eq. 21 vs eq. 20), exactly.
    for (double g : {0.01, 0.5, 2.5}) EXPECT_NEAR(sun05_npsf(std::cos(g)), sun05_psf(1.0, std::cos(g)) * std::exp(1.0), 1e-12);
}

TEST(Sun05Psf, NpsfCoefficientsMatchFogshop) {
    // Fogshop (Zhou et al. 2007) lists the NPSF's first Y_l0 coefficients (NOTES.md).
    const double published[] = {0.332818, 0.332488, 0.302428, 0.275773, 0.254051, 0.236333};
    const std::vector<double> lambda = psf_eigenvalues(1.0, 5, PsfKind::Factorised);
    for (int l = 0; l <= 5; ++l) {
        const double c_l = lambda[size_t(l)] / (1.0 * std::exp(-1.0)) * std::sqrt((2.0 * l + 1.0) / (4.0 * kPi));
        // Agrees with an independent scipy quadrature of eq. 21 to 1e-6; the published values
        // drift by up to 1.2e-4 relative at l = 5 (their own numerics).
        EXPECT_NEAR(c_l / published[l], 1.0, 1.5e-4) << "l = " << l;
    }
}

TEST(Sun05Psf, EigenvaluesMatchAdaptiveQuadrature) {
    const double Tsv = 2.5;
    const std::vector<double> lambda = psf_eigenvalues(Tsv, 40, PsfKind::Exact);
    for (int l : {0, 1, 7, 40}) {
        auto f = [&](double g) { return sun05_psf_angle(Tsv, g) * std::sin(g) * std::legendre(l, std::cos(g)); };
        const double want = 2.0 * kPi * integrate_piecewise(f, {0.0, 1e-6, 1e-3, 0.05, 0.5, 1.5}, kPi, 1.0, 1e-10);
        EXPECT_NEAR(lambda[size_t(l)], want, 1e-8 * std::abs(lambda[0])) << "l = " << l;
    }
}

TEST(Sun05Psf, FactorisationErrorIsMeasured) {
    // eq. 22 is empirical: measure it. At Tsv = 1 it is exact by construction; elsewhere it
    // errs most at small angles and large Tsv. The bound asserted is what was measured.
    double worst = 0.0;
    for (double Tsv : {0.1, 0.5, 2.0}) {
        for (double g = 0.01; g < kPi; g += 0.01) {
            const double exact = sun05_psf(Tsv, std::cos(g));
            const double fact = Tsv * std::exp(-Tsv) * sun05_npsf(std::cos(g));
            worst = std::max(worst, std::abs(fact - exact) / exact);
        }
    }
    RecordProperty("factorisation_max_rel_error_Tsv_0.1_to_2", std::to_string(worst));
    std::printf("PSF factorisation (eq. 22) max rel error over gamma, Tsv in {0.1, 0.5, 2}: %.3g\n", worst);
    EXPECT_LT(worst, 0.8);
    EXPECT_GT(worst, 1e-3);  // it is an approximation: a zero here would mean the test compares nothing
}

EnvironmentMap smooth_map(int W, int H) {
    EnvironmentMap m;
    m.width = W;
    m.height = H;
    m.rgb.resize(size_t(3) * W * H);
    for (int j = 0; j < H; ++j)
        for (int i = 0; i < W; ++i) {
            const Vec3 d = equirect_direction((i + 0.5) / W, 1.0 - (j + 0.5) / H);
            const double sky = 1.0 + 0.5 * d.z + 0.3 * d.x * d.y;
            const double sun = std::exp(8.0 * (glm::dot(d, glm::normalize(Vec3(0.3, -0.5, 0.8))) - 1.0));
            float* t = &m.rgb[3 * (size_t(j) * W + i)];
            t[0] = float(sky + 4.0 * sun);
            t[1] = float(0.8 * sky + 3.0 * sun);
            t[2] = float(0.6 * sky + 1.0 * sun);
        }
    return m;
}

TEST(EnvironmentSh, RoundTripAndConstant) {
    EnvironmentMap c;
    c.width = 64;
    c.height = 32;
    c.rgb.assign(size_t(3) * 64 * 32, 2.0f);
    ShCoefficients sh = sh_project(c, 4);
    EXPECT_NEAR(sh.c[0].x, 2.0 * std::sqrt(4.0 * kPi), 1e-12);
    for (size_t i = 1; i < sh.c.size(); ++i) EXPECT_NEAR(sh.c[i].x, 0.0, 1e-12);
    // Constant irradiance: E = pi L for every normal.
    for (const Vec3& n : {Vec3(0, 0, 1), Vec3(1, 0, 0), Vec3(0.3, -0.4, -0.8)}) EXPECT_NEAR(sh_irradiance(sh, n).x, 2.0 * kPi, 1e-9);
    // A band-limited map survives projection + reconstruction.
    ShCoefficients band;
    band.L = 6;
    band.c.assign(49, RGB(0.0));
    std::mt19937 rng(3);
    std::uniform_real_distribution<double> U(-1.0, 1.0);
    for (auto& v : band.c) v = RGB(U(rng), U(rng), U(rng));
    band.c[0] = RGB(200.0);  // keep the map positive (radiance)
    const EnvironmentMap img = sh_reconstruct(band, 256, 128);
    const ShCoefficients back = sh_project(img, 6);
    for (size_t i = 0; i < band.c.size(); ++i) EXPECT_NEAR(back.c[i].y, band.c[i].y, 2e-3) << i;
}

TEST(EnvironmentSh, ConvolutionMatchesDirect) {
    // Funk-Hecke on a smooth kernel (von Mises): SH convolution == direct convolution.
    const EnvironmentMap map = smooth_map(64, 32);
    auto k = [](double c) { return std::exp(4.0 * (c - 1.0)); };
    std::vector<double> lambda = zonal_eigenvalues([&](double g) { return k(std::cos(g)); }, 24);
    ShCoefficients sh = sh_project(map, 24);
    sh_convolve(sh, lambda);
    const EnvironmentMap a = sh_reconstruct(sh, 32, 16);
    const EnvironmentMap b = convolve_direct(map, k, 32, 16, 2);
    double worst = 0.0;
    for (size_t i = 0; i < a.rgb.size(); ++i) worst = std::max(worst, double(std::abs(a.rgb[i] - b.rgb[i]) / b.rgb[i]));
    EXPECT_LT(worst, 2e-3);
}

TEST(EnvironmentFog, EnergyAndBadInput) {
    // The glow's integral over the sphere is lambda_0 times the World's (Funk-Hecke, l = 0), for
    // the SH path and for the direct path with the exact PSF.
    const EnvironmentMap map = smooth_map(32, 16);
    auto integral = [](const EnvironmentMap& m) {
        double s = 0.0;
        for (int j = 0; j < m.height; ++j) {
            const double dw = (std::cos(kPi * j / m.height) - std::cos(kPi * (j + 1.0) / m.height)) * 2.0 * kPi / m.width;
            for (int i = 0; i < m.width; ++i) s += dw * m.rgb[3 * (size_t(j) * m.width + i)];
        }
        return s;
    };
    const double sigma = 0.02, D = 100.0;
    const EnvironmentFog sh = environment_fog(map, sigma, D, 16, 96, 48, PsfKind::Exact);
    const EnvironmentFog direct = environment_fog(map, sigma, D, -1, 16, 8);
    const double want = sh.lambda[0] * integral(map);
    EXPECT_NEAR(integral(sh.glow) / want, 1.0, 2e-2);
    EXPECT_NEAR(integral(direct.glow) / want, 1.0, 3e-2);
    EXPECT_NEAR(sh.transmittance, std::exp(-2.0), 1e-15);
    // Irradiance of a constant World through fog: (e^-T + albedo lambda_0) pi L.
    EnvironmentMap c;
    c.width = 16;
    c.height = 8;
    c.rgb.assign(size_t(3) * 16 * 8, 1.0f);
    const EnvironmentFog cf = environment_fog(c, sigma, D, 4, 8, 4);
    RGB Ew, Ef;
    environment_irradiance(cf, RGB(0.5), Vec3(0, 0, 1), Ew, Ef);
    EXPECT_NEAR(Ew.x, kPi, 1e-9);
    EXPECT_NEAR(Ef.x, (std::exp(-2.0) + 0.5 * cf.lambda[0]) * kPi, 1e-9);
    // Bad input.
    EnvironmentMap bad = c;
    bad.rgb[5] = NAN;
    EXPECT_THROW(environment_fog(bad, sigma, D, 4, 8, 4), std::invalid_argument);
    bad.rgb[5] = -1.0f;
    EXPECT_THROW(environment_fog(bad, sigma, D, 4, 8, 4), std::invalid_argument);
    EXPECT_THROW(environment_fog(c, -1.0, D, 4, 8, 4), std::invalid_argument);
    EXPECT_THROW(environment_fog(c, sigma, 0.0, 4, 8, 4), std::invalid_argument);
    EXPECT_THROW(environment_fog(EnvironmentMap{}, sigma, D, 4, 8, 4), std::invalid_argument);
}

}  // namespace
}  // namespace airlight
