// sun05_test.cpp: Sun 2005 airlight against the quadrature of eq. 5 and analytic limits;
// the quadrature itself against closed forms; the model registry.
#include "core/constants.h"
#include "models/registry.h"
#include "core/quadrature.h"
#include "homogeneous/sun05.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <stdexcept>
#include <vector>

namespace airlight {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();


const SpecialFTable& table() {
    static const SpecialFTable tab(256, 256);
    return tab;
}
double La_table(double s, double D, double c, double V) { return sun05_airlight(s, D, c, V, &table(), FEval::Table); }
double La_exact(double s, double D, double c, double V) { return sun05_airlight(s, D, c, V, nullptr, FEval::Exact); }

// sigma_t -> 0: La / sigma_t -> (1/4pi) int_0^Dvp dx / d^2.
double thin_limit_per_sigma(double Dsv, double c, double Dvp) {
    const double s = std::sqrt((1 - c) * (1 + c));
    const double upper = std::isinf(Dvp) ? kPi / 2 : std::atan((Dvp - Dsv * c) / (Dsv * s));
    return (upper + std::atan(c / s)) / (4 * kPi * Dsv * s);
}

TEST(Models, Registry) {
    const auto& r = model_registry();
    ASSERT_EQ(r.size(), 7u);
    EXPECT_EQ(r[0].name, "sun05");
    EXPECT_EQ(model_from_name("sun05"), ModelId::Sun05Table);
    EXPECT_EQ(model_from_name("sun05_exact"), ModelId::Sun05Exact);
    EXPECT_EQ(model_from_name("quadrature"), ModelId::Quadrature);
    EXPECT_EQ(model_from_name("biri06"), ModelId::Biri06);
    EXPECT_EQ(model_from_name("baseline"), ModelId::Baseline);
    EXPECT_EQ(model_from_name("pegoraro10"), ModelId::Pegoraro10);
    EXPECT_EQ(model_from_name("hoffman02"), ModelId::Hoffman02);
    try {
        model_from_name("sun06");
        FAIL() << "no exception";
    } catch (const std::invalid_argument& e) {
        const std::string msg = e.what();
        EXPECT_NE(msg.find("sun06"), std::string::npos);
        EXPECT_NE(msg.find("sun05_exact"), std::string::npos);
        EXPECT_NE(msg.find("quadrature"), std::string::npos);
    }
}

TEST(Sun05, CheckInputs) {
    EXPECT_NO_THROW(sun05_check_inputs(0.1, 1.0, 1.0 + 1e-10, kInf));
    EXPECT_NO_THROW(sun05_check_inputs(0.0, 0.0, -1.0, 0.0));
    EXPECT_THROW(sun05_check_inputs(NAN, 1, 0, 1), std::invalid_argument);
    EXPECT_THROW(sun05_check_inputs(-0.1, 1, 0, 1), std::invalid_argument);
    EXPECT_THROW(sun05_check_inputs(0.1, -1, 0, 1), std::invalid_argument);
    EXPECT_THROW(sun05_check_inputs(0.1, NAN, 0, 1), std::invalid_argument);
    EXPECT_THROW(sun05_check_inputs(0.1, 1, 1.001, 1), std::invalid_argument);
    EXPECT_THROW(sun05_check_inputs(0.1, 1, NAN, 1), std::invalid_argument);
    EXPECT_THROW(sun05_check_inputs(0.1, 1, 0, -2), std::invalid_argument);
    EXPECT_THROW(sun05_check_inputs(0.1, 1, 0, NAN), std::invalid_argument);
}

TEST(Quadrature, ClosedForms) {
    EXPECT_NEAR(integrate_adaptive([](double x) { return std::exp(-x); }, 0, kInf), 1.0, 1e-12);
    EXPECT_NEAR(integrate_adaptive([](double x) { return std::sin(x); }, 0, kPi), 2.0, 1e-12);
    EXPECT_NEAR(integrate_adaptive([](double x) { return 1 / (1 + x * x); }, 0, kInf), kPi / 2, 1e-12);
    EXPECT_NEAR(integrate_adaptive([](double x) { return std::sqrt(x); }, 0, 1), 2.0 / 3.0, 1e-11);
    // A peak of width 1e-6: int_{-1}^{1} dx / (x^2 + 1e-12) = 2 atan(1e6) / 1e-6.
    const double peak = 2 * std::atan(1e6) / 1e-6;
    EXPECT_NEAR(integrate_adaptive([](double x) { return 1 / (x * x + 1e-12); }, -1, 1), peak, 1e-9 * peak);
    EXPECT_NEAR(integrate_adaptive([](double x) { return std::exp(x); }, 1, 0), 1 - std::exp(1.0), 1e-12);
}

TEST(Quadrature, ThinMediumLimit) {
    // sigma_t = 1e-9: La / sigma_t matches the closed form to O(sigma_t D).
    for (double c : {-0.99, -0.3, 0.0, 0.5, 0.9999})
        for (double Dvp : {0.3, 5.0, 40.0, kInf}) {
            const double ref = thin_limit_per_sigma(10.0, c, Dvp);
            if (std::isinf(Dvp)) continue;  // int dx/d^2 converges but e^{-sigma x} matters at x ~ 1/sigma
            EXPECT_NEAR(sun05_airlight_quadrature(1e-9, 10.0, c, Dvp) / 1e-9, ref, 1e-6 * ref) << c << " " << Dvp;
        }
}

TEST(Sun05, PrefactorAgainstQuadrature) {
    // The A0 = sigma_t^2 e^{-Tsv cos g} / (2 pi Tsv sin g) normalisation of eq. 7 (I0 = 1).
    const double q = sun05_airlight_quadrature(0.2, 7.0, 0.3, 12.0, 1e-12);
    EXPECT_NEAR(La_exact(0.2, 7.0, 0.3, 12.0), q, 1e-11 * q);
}

struct Sample {
    double sigma_t, Dsv, c, Dvp;
};
std::vector<Sample> random_samples(int n, unsigned seed) {
    // The bake's range: Dsv 0.5..50 m, sigma_t 0.001..1, any gamma, Dvp 0.01..inf.
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> U(0.0, 1.0);
    std::vector<Sample> out(n);
    for (Sample& s : out) {
        s.sigma_t = std::pow(10.0, -3 + 3 * U(rng));
        s.Dsv = 0.5 + 49.5 * U(rng);
        s.c = std::cos(kPi * U(rng));
        s.Dvp = U(rng) < 0.1 ? kInf : std::pow(10.0, -2 + 5 * U(rng));
    }
    return out;
}

TEST(Sun05, ExactMatchesQuadratureRandom) {
    for (const Sample& s : random_samples(1000, 5)) {
        const double q = sun05_airlight_quadrature(s.sigma_t, s.Dsv, s.c, s.Dvp, 1e-11);
        EXPECT_NEAR(La_exact(s.sigma_t, s.Dsv, s.c, s.Dvp), q, 1e-9 * q)
            << s.sigma_t << " " << s.Dsv << " " << s.c << " " << s.Dvp;
    }
}

TEST(Sun05, TableMatchesQuadratureRandom) {
    // Measured (200000 points): max 1.9e-3, p99 5.0e-4 relative.
    std::vector<double> err;
    for (const Sample& s : random_samples(4000, 6)) {
        const double q = sun05_airlight_quadrature(s.sigma_t, s.Dsv, s.c, s.Dvp, 1e-10);
        const double t = La_table(s.sigma_t, s.Dsv, s.c, s.Dvp);
        ASSERT_TRUE(std::isfinite(t));
        err.push_back(std::abs(t / q - 1));
    }
    std::sort(err.begin(), err.end());
    EXPECT_LE(err[err.size() * 99 / 100], 1e-3);
    EXPECT_LE(err.back(), 4e-3);
}

TEST(Sun05, SigmaZeroIsZero) {
    EXPECT_EQ(La_table(0.0, 3.0, 0.2, 5.0), 0.0);
    EXPECT_EQ(La_exact(0.0, 3.0, 1.0, kInf), 0.0);
}

TEST(Sun05, ThinMediumLimit) {
    for (double c : {-1.0 + 1e-9, -0.7, 0.0, 0.6, 0.999})
        for (double Dvp : {0.05, 3.0, 30.0}) {
            const double ref = 1e-9 * thin_limit_per_sigma(4.0, c, Dvp);
            EXPECT_NEAR(La_exact(1e-9, 4.0, c, Dvp), ref, 1e-7 * ref) << c << " " << Dvp;
            EXPECT_NEAR(La_table(1e-9, 4.0, c, Dvp), ref, 2e-3 * ref) << c << " " << Dvp;
        }
}

TEST(Sun05, GammaZeroLightBehindSurface) {
    // Finite limit sigma_t e^{-Tsv} Dvp / (4 pi Dsv (Dsv - Dvp)).
    const double s = 0.3, D = 8.0;
    for (double Dvp : {0.01, 2.0, 7.9}) {
        const double ref = s * std::exp(-s * D) * Dvp / (4 * kPi * D * (D - Dvp));
        for (double c : {1.0, 1.0 - 1e-12}) {  // O(gamma^2 D^2 / (D - Dvp)^2) from the limit
            EXPECT_NEAR(La_exact(s, D, c, Dvp), ref, 1e-7 * ref) << c << " " << Dvp;
            EXPECT_NEAR(La_table(s, D, c, Dvp), ref, 1e-3 * ref) << c << " " << Dvp;
        }
        const double q = sun05_airlight_quadrature(s, D, 1.0 - 1e-12, Dvp);
        EXPECT_NEAR(q, ref, 1e-7 * ref);
        const double q9 = sun05_airlight_quadrature(s, D, 1.0 - 1e-9, Dvp);
        EXPECT_NEAR(La_exact(s, D, 1.0 - 1e-9, Dvp), q9, 1e-9 * q9);
        EXPECT_NEAR(La_table(s, D, 1.0 - 1e-9, Dvp), q9, 1e-3 * q9);
    }
}

TEST(Sun05, RayThroughTheLightIsFinite) {
    // Physically divergent (1/gamma); regularised to sin(gamma) >= 1e-8.
    for (double c : {1.0, 1.0 - 1e-16, 1.0 - 1e-14}) {
        const double t = La_table(0.1, 5.0, c, 20.0), e = La_exact(0.1, 5.0, c, 20.0);
        EXPECT_TRUE(std::isfinite(t) && t > 0);
        EXPECT_TRUE(std::isfinite(e) && e > 0);
        EXPECT_NEAR(t, e, 1e-3 * e);
        EXPECT_GT(e, La_exact(0.1, 5.0, std::cos(1e-4), 20.0));
    }
    // Close to the light but resolvable: both paths agree with the quadrature.
    for (double g : {1e-6, 1e-4, 1e-2}) {
        const double q = sun05_airlight_quadrature(0.1, 5.0, std::cos(g), 20.0);
        EXPECT_NEAR(La_exact(0.1, 5.0, std::cos(g), 20.0), q, 1e-8 * q) << g;
        EXPECT_NEAR(La_table(0.1, 5.0, std::cos(g), 20.0), q, 1e-3 * q) << g;
    }
}

TEST(Sun05, GammaPi) {
    for (double c : {-1.0, -1.0 + 1e-12, -1.0 + 1e-6})
        for (double Dvp : {0.02, 3.0, 100.0, kInf}) {
            const double q = sun05_airlight_quadrature(0.05, 6.0, c, Dvp);
            EXPECT_NEAR(La_exact(0.05, 6.0, c, Dvp), q, 1e-9 * q) << c << " " << Dvp;
            EXPECT_NEAR(La_table(0.05, 6.0, c, Dvp), q, 1e-3 * q) << c << " " << Dvp;
        }
}

TEST(Sun05, ShortViewRayIsLinearInDvp) {
    // La ~ sigma_t e^{-Tsv} Dvp / (4 pi Dsv^2) for Dvp -> 0 (relative correction O(Dvp / Dsv)).
    for (double c : {-0.5, 0.2, 0.95})
        for (double Dvp : {1e-6, 1e-9}) {
            const double ref = 0.2 * std::exp(-0.2 * 3.0) * Dvp / (4 * kPi * 9.0);
            EXPECT_NEAR(La_exact(0.2, 3.0, c, Dvp), ref, 3 * Dvp / 3.0 * ref + 1e-12 * ref);
            EXPECT_NEAR(La_table(0.2, 3.0, c, Dvp), ref, 3 * Dvp / 3.0 * ref + 1e-6 * ref);
        }
}

TEST(Sun05, InfiniteDvp) {
    for (double c : {-0.9, 0.0, 0.7, 0.9999}) {
        const double q = sun05_airlight_quadrature(0.1, 10.0, c, kInf);
        EXPECT_NEAR(La_exact(0.1, 10.0, c, kInf), q, 1e-9 * q) << c;
        EXPECT_NEAR(La_table(0.1, 10.0, c, kInf), q, 1e-3 * q) << c;
        // and continuity from a far but finite surface
        EXPECT_NEAR(La_table(0.1, 10.0, c, 1e6), La_table(0.1, 10.0, c, kInf), 1e-6 * q);
    }
}

TEST(Sun05, LargeOpticalDepth) {
    // sigma_t D up to 100: relative accuracy holds where the values are ~e^{-100}.
    for (double c : {-1.0, -0.5, 0.0, 0.5, 0.999})
        for (double Dvp : {1.0, 50.0, kInf}) {
            const double q = sun05_airlight_quadrature(2.0, 50.0, c, Dvp);
            const double e = La_exact(2.0, 50.0, c, Dvp), t = La_table(2.0, 50.0, c, Dvp);
            ASSERT_TRUE(std::isfinite(t) && std::isfinite(e) && q > 0);
            EXPECT_NEAR(e, q, 1e-8 * q) << c << " " << Dvp;
            EXPECT_NEAR(t, q, 1e-3 * q) << c << " " << Dvp;
        }
}

TEST(Sun05, ViewerAtTheLightIsFinite) {
    // Dsv -> 0 diverges like 1/Dsv; Dsv is clamped to 1e-6.
    for (double c : {-1.0, 0.0, 1.0}) {
        const double t0 = La_table(0.1, 0.0, c, 5.0), e0 = La_exact(0.1, 0.0, c, 5.0);
        EXPECT_TRUE(std::isfinite(t0) && t0 > 0);
        EXPECT_TRUE(std::isfinite(e0) && e0 > 0);
        EXPECT_EQ(e0, La_exact(0.1, 1e-9, c, 5.0));
    }
    const double q = sun05_airlight_quadrature(0.1, 1e-3, 0.3, 5.0);
    EXPECT_NEAR(La_table(0.1, 1e-3, 0.3, 5.0), q, 1e-3 * q);
}

}  // namespace
}  // namespace airlight
