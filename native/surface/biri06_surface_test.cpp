// biri06_surface_test.cpp: G_p(T, theta_s, m) for any phase against the brute-force surface
// single-scattering integral, its isotropic limit (Sun 2005's H and G, exactly), the table
// against the exact evaluator (measured error asserted), Biri's eq. 11 as printed against the
// H_p form, and the error of Biri's unclamped Lambert model (eq. 10) against the clamped G_p
// (printed: a reported figure).
#include "core/constants.h"
#include "surface/biri06_surface.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <random>
#include <string>
#include <vector>

#include "surface/sun05_surface.h"

namespace airlight {
namespace {


PhaseFunction hg(double g) { return PhaseFunction{PhaseKind::HenyeyGreenstein, g}; }
PhaseFunction of(PhaseKind k) { return PhaseFunction{k, 0.0}; }

std::string label(const PhaseFunction& p) {
    return std::string(phase_name(p.kind)) + (p.kind == PhaseKind::HenyeyGreenstein ? " g " + std::to_string(p.g) : "");
}

std::vector<PhaseFunction> anisotropic_phases() {
    return {hg(0.6), hg(-0.6), hg(0.9), hg(-0.9), of(PhaseKind::Rayleigh), of(PhaseKind::HazyMie),
            of(PhaseKind::MurkyMie)};
}

// With p = 1/(4 pi) H_p is Sun's H: the same integral, so to the quadrature's tolerance.
TEST(Biri06Surface, IsotropicHIsSunH) {
    const PhaseFunction iso;
    for (double T : {0.0, 1e-3, 0.3, 1.0, 4.0, 20.0, 60.0})
        for (double gamma : {0.0, 1e-6, 0.1, 0.8, 1.6, 2.5, kPi - 1e-6, kPi}) {
            const double sun = sun05_surface_H_scaled(T, gamma), ours = biri06_surface_H_scaled(iso, T, gamma);
            EXPECT_NEAR(ours, sun, 1e-10 * std::max(sun, 1e-300)) << "T " << T << " gamma " << gamma;
        }
    // HG with g = 0 is the same function.
    EXPECT_NEAR(biri06_surface_H_scaled(hg(0.0), 2.0, 0.7) / sun05_surface_H_scaled(2.0, 0.7), 1.0, 1e-10);
}

TEST(Biri06Surface, IsotropicGIsSunG) {
    const PhaseFunction iso;
    for (double T : {0.0, 0.05, 1.0, 8.0, 40.0})
        for (double theta : {0.0, 0.7, 1.5, 1.7, 2.6, kPi})
            for (double m : {1.0, 20.0}) {
                const double sun = sun05_surface_G_scaled_exact(T, theta, m);
                EXPECT_NEAR(biri06_surface_G_scaled_exact(iso, T, theta, m), sun, 1e-8 * std::max(sun, 1e-12))
                    << "T " << T << " theta " << theta << " m " << m;
            }
}

// The isotropic phase table equals Sun's G table (same grid, same H to 1e-10).
TEST(Biri06Surface, IsotropicTableIsSunTable) {
    const PhaseSurfaceGTable ours(PhaseFunction{}, 1.0, 32, 32, 0);
    const SurfaceGTable sun(1.0, 32, 32, 0);
    std::mt19937 rng(3);
    std::uniform_real_distribution<double> U(0.0, 1.0);
    for (int k = 0; k < 200; ++k) {
        const double T = 60.0 * U(rng) * U(rng), theta = kPi * U(rng);
        const double s = sun.eval_scaled(T, theta);
        EXPECT_NEAR(ours.eval_scaled(T, theta), s, 1e-8 * s + 1e-14) << "T " << T << " theta " << theta;
    }
}

// G_p (exact, and the bake's 128 x 128 Lambert table) against the brute-force integral, which shares no
// formula with it (no H, no W closed form, the phase angle from the geometry).
TEST(Biri06Surface, ExactAndTableMatchBruteForce) {
    struct Case {
        double beta, D, theta, m;
    };
    const std::vector<Case> cases{Case{0.5, 2.0, 0.6, 1.0}, Case{2.0, 4.0, 0.3, 1.0}, Case{0.3, 1.0, 2.2, 1.0},
                                  Case{0.5, 2.0, 0.6, 20.0}};
    for (const PhaseFunction& phase : anisotropic_phases()) {
        const auto lambert = shared_phase_surface_G_table(phase, 128, 128, 1.0);
        for (const Case& c : cases) {
            const double ref = biri06_surface_glow_reference(phase, c.beta, c.D, c.theta, c.m, 1e-6);
            const double T = c.beta * c.D, scale = c.beta / (2.0 * kPi * c.D);
            const double exact = scale * biri06_surface_G_exact(phase, T, c.theta, c.m);
            EXPECT_NEAR(exact / ref, 1.0, 1e-5) << label(phase) << " T " << T << " theta " << c.theta << " m " << c.m;
            if (c.m != 1.0) continue;  // the Phong tables: TableError
            const double table = scale * lambert->eval(T, c.theta);
            EXPECT_NEAR(table / ref, 1.0, 2e-2) << label(phase) << " T " << T << " theta " << c.theta;
        }
    }
}

// Table vs exact over random points (the bake's sizes: 128 x 128 Lambert, 64 x 64 Phong n = 20);
// prints the measured max / mean and build time; asserts them with headroom.
TEST(Biri06Surface, TableError) {
    std::vector<PhaseFunction> phases = anisotropic_phases();
    for (const PhaseFunction& phase : phases)
        for (double m : {1.0, 20.0}) {
            if (m != 1.0 && phase.kind != PhaseKind::HenyeyGreenstein) continue;  // Phong: HG only (time)
            const int n = m == 1.0 ? 128 : 64;
            const auto t0 = std::chrono::steady_clock::now();
            const PhaseSurfaceGTable table(phase, m, n, n, 0);
            const double build = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
            std::mt19937 rng(1);
            std::uniform_real_distribution<double> U(0.0, 1.0);
            double worst = 0.0, sum = 0.0;
            int count = 0;
            for (int k = 0; k < 80; ++k) {
                const double T = k % 10 == 0 ? 0.0 : std::exp(std::log(1e-3) + U(rng) * (std::log(60.0) - std::log(1e-3)));
                const double theta = U(rng) * kPi;
                const double exact = biri06_surface_G_scaled_exact(phase, T, theta, m);
                if (exact < 1e-6 * biri06_surface_G_scaled_exact(phase, T, 0.0, m)) continue;
                const double err = std::abs(table.eval_scaled(T, theta) / exact - 1.0);
                worst = std::max(worst, err);
                sum += err;
                ++count;
            }
            std::printf("G_p table %-16s m = %2g, %3d x %3d: max rel err %.3g, mean %.3g (%d points), build %.2f s\n",
                        label(phase).c_str(), m, n, n, worst, sum / count, count, build);
            EXPECT_LT(worst, m == 1.0 ? 3e-2 : 6e-2) << label(phase);
            EXPECT_LT(sum / count, m == 1.0 ? 2e-3 : 5e-3) << label(phase);
        }
}

// Thick fog: the phase-aware tables' tails (beyond T = 64; sun05_surface.h) against the exact
// evaluator for T log-uniform in [64, 1e5], away from the horizon (its kink: sun05_surface_test).
TEST(Biri06Surface, TailError) {
    for (const PhaseFunction& phase : anisotropic_phases()) {
        const PhaseSurfaceGTable table(phase, 1.0, 128, 128, 0);
        std::mt19937 rng(3);
        std::uniform_real_distribution<double> U(0.0, 1.0);
        double worst = 0.0;
        for (int k = 0; k < 12; ++k) {
            const double T = std::exp(std::log(64.0) + U(rng) * (std::log(1e5) - std::log(64.0)));
            const double theta = U(rng) * kPi;
            if (std::abs(theta - kPi / 2) < 0.05) continue;
            const double exact = biri06_surface_G_scaled_exact(phase, T, theta, 1.0);
            if (exact < 1e-6 * biri06_surface_G_scaled_exact(phase, T, 0.0, 1.0)) continue;
            worst = std::max(worst, std::abs(table.eval_scaled(T, theta) / exact - 1.0));
        }
        std::printf("G_p table %-16s tail: max rel err %.3g\n", label(phase).c_str(), worst);
        EXPECT_LT(worst, 3e-2) << label(phase);
    }
}

// Biri eq. 11 as printed (nested over phi and alpha, exponent corrected) equals the H_p form.
TEST(Biri06Surface, GammaLPaperMatchesHForm) {
    std::vector<PhaseFunction> phases = anisotropic_phases();
    phases.push_back(PhaseFunction{});
    for (const PhaseFunction& phase : phases)
        for (double lambda : {0.0, 0.1, 1.0, 5.0}) {
            const double paper = biri06_Gamma_L_paper(phase, lambda);
            const double ours = biri06_Gamma_L_scaled_exact(phase, lambda) * std::exp(-lambda);
            EXPECT_NEAR(ours, paper, 1e-7 * std::abs(paper) + 1e-12) << label(phase) << " lambda " << lambda;
        }
}

// Biri's Lambert (eq. 10, the unclamped cosine) against the clamped exact G_p: printed per
// phase over a T x theta_s grid (the bake clamps G_B at 0). Asserted: the table reproduces eq.
// 10, G_B <= G_p at theta_s = 0 (the back hemisphere counts negatively), and G_B < 0 past pi/2.
TEST(Biri06Surface, BiriLambertErrorTable) {
    std::vector<PhaseFunction> phases{PhaseFunction{}};
    for (const PhaseFunction& p : anisotropic_phases()) phases.push_back(p);
    const double Ts[] = {0.1, 1.0, 5.0, 10.0};
    const double thetas[] = {0.0, 0.5, 1.0, 1.4, 1.7, 2.8};
    for (const PhaseFunction& phase : phases) {
        const Biri06LambertTable table(phase, 256);
        std::printf("Biri eq. 10 vs clamped G_p, %s: rel err, rows T, cols theta_s", label(phase).c_str());
        for (double th : thetas) std::printf(" %5.2f", th);
        std::printf("\n");
        double worst = 0.0, sum = 0.0;
        int n = 0;
        for (double T : Ts) {
            std::printf("  T %5.2f:", T);
            const double gamma_L = biri06_Gamma_L_paper(phase, T);
            for (double th : thetas) {
                const double exact = biri06_surface_G_scaled_exact(phase, T, th, 1.0);
                const double biri = table.eval_G_scaled(T, std::cos(th));
                const double paper = 4.0 * kPi * kPi * std::cos(th) * gamma_L * std::exp(T);
                EXPECT_NEAR(biri, paper, 2e-3 * std::abs(paper) + 1e-9) << label(phase) << " T " << T;
                if (th == 0.0) EXPECT_LE(biri, exact * (1.0 + 1e-9));
                if (th > kPi / 2) EXPECT_LT(biri, 0.0);
                const double err = std::abs(std::max(biri, 0.0) / exact - 1.0);
                std::printf(" %5.3f", err);
                worst = std::max(worst, err);
                sum += err;
                ++n;
            }
            std::printf("\n");
        }
        std::printf("  mean %.3f max %.3f\n", sum / n, worst);
    }
}

// The 1D Gamma_L table against the exact evaluator.
TEST(Biri06Surface, LambertTableError) {
    for (const PhaseFunction& phase : {PhaseFunction{}, hg(0.9), hg(-0.9), of(PhaseKind::MurkyMie)}) {
        const Biri06LambertTable table(phase, 256);
        double worst = 0.0;
        for (int k = 0; k < 24; ++k) {
            const double T = std::exp(std::log(1e-3) + k * (std::log(60.0) - std::log(1e-3)) / 23.5);
            const double exact = biri06_Gamma_L_scaled_exact(phase, T);
            const double scale = std::abs(biri06_Gamma_L_scaled_exact(phase, 0.0)) * std::exp(0.0);
            worst = std::max(worst, std::abs(table.eval_scaled(T) - exact) / std::max(std::abs(exact), 1e-3 * scale));
        }
        std::printf("Gamma_L table %-16s 256: max rel err %.3g\n", label(phase).c_str(), worst);
        EXPECT_LT(worst, 5e-3) << label(phase);
    }
}

TEST(Biri06Surface, RejectsBadArguments) {
    const PhaseFunction p = hg(0.5);
    EXPECT_THROW(biri06_surface_G_exact(p, -1.0, 0.5, 1.0), std::invalid_argument);
    EXPECT_THROW(biri06_surface_G_exact(p, NAN, 0.5, 1.0), std::invalid_argument);
    EXPECT_THROW(biri06_surface_G_exact(p, 1.0, 4.0, 1.0), std::invalid_argument);
    EXPECT_THROW(biri06_surface_G_exact(p, 1.0, 0.5, 0.5), std::invalid_argument);
    EXPECT_THROW(biri06_Gamma_L_scaled_exact(p, -1.0), std::invalid_argument);
    EXPECT_THROW(PhaseSurfaceGTable(p, 1.0, 1, 8), std::invalid_argument);
}

// Finite everywhere at the edges: gamma = 0, pi, T = 0 and large, narrow lobes.
TEST(Biri06Surface, FiniteAtEdges) {
    for (const PhaseFunction& p : {hg(0.99), hg(-0.99), of(PhaseKind::MurkyMie)})
        for (double T : {0.0, 1e-9, 1.0, 100.0})
            for (double gamma : {0.0, 1e-9, kPi - 1e-9, kPi}) {
                const double h = biri06_surface_H_scaled(p, T, gamma);
                EXPECT_TRUE(std::isfinite(h) && h >= 0.0) << label(p) << " T " << T << " gamma " << gamma;
            }
}

}  // namespace
}  // namespace airlight
