// sun05_batch_test.cpp: the SIMD batch table path against the scalar double table path
// (same branch, float rounding only), against quadrature, and its transmittance exp.
#include "core/constants.h"
#include "core/quadrature.h"
#include "core/special_f.h"
#include "homogeneous/sun05_batch.h"
#include "homogeneous/sun05_inline.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <random>
#include <vector>

namespace airlight {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// Float vs double on the kept lanes: ~3e-7 per F value, amplified by F1 / G < 1 / kCancel
// (sun05_batch.h). Measured max over the sweep below: see BatchMatchesScalarSweep.
const double kFloatTol = 4e-6 / sun05::kCancel;

const SpecialFTable& table() {
    static const SpecialFTable tab(256, 256);
    return tab;
}

double scalar(double sigma_t, double Dsv, double c, double Dvp) {
    const SpecialFTable& t = table();
    return sun05_airlight_table(t.data().data(), t.nu(), t.nT(), sigma_t, Dsv, c, Dvp);
}

int batch(double sigma_t, double Dsv, const std::vector<double>& c, const std::vector<float>& Dvp,
          std::vector<float>& out) {
    const SpecialFTable& t = table();
    out.assign(c.size(), -1.0f);
    return sun05_airlight_table_batch(t.data().data(), t.nu(), t.nT(), sigma_t, Dsv, c.data(), Dvp.data(),
                                      int(c.size()), out.data());
}

// One group of rays sharing (sigma_t, Dsv), covering the extremes of gamma and Dvp.
void random_group(std::mt19937_64& rng, double Dsv, std::vector<double>& c, std::vector<float>& Dvp, int n) {
    std::uniform_real_distribution<double> U(0.0, 1.0);
    c.resize(n);
    Dvp.resize(n);
    for (int k = 0; k < n; ++k) {
        const double r = U(rng);
        if (r < 0.05) c[k] = 1.0;
        else if (r < 0.1) c[k] = -1.0;
        else if (r < 0.25) c[k] = 1.0 - std::pow(10.0, -16 + 15 * U(rng));   // near the light
        else if (r < 0.35) c[k] = -1.0 + std::pow(10.0, -16 + 15 * U(rng));  // light behind
        else c[k] = std::cos(kPi * U(rng));
        const double q = U(rng);
        if (q < 0.1) Dvp[k] = float(kInf);
        else if (q < 0.15) Dvp[k] = float(Dsv * std::pow(10.0, -7 + 3 * U(rng)));  // tiny
        else Dvp[k] = float(Dsv * std::pow(10.0, -3 + 5 * U(rng)));
    }
}

}  // namespace

TEST(Sun05Batch, BatchMatchesScalarSweep) {
    std::mt19937_64 rng(11);
    std::uniform_real_distribution<double> U(0.0, 1.0);
    std::vector<double> c;
    std::vector<float> Dvp, out;
    double worst = 0.0;
    long lanes = 0, fell_back = 0;
    for (int g = 0; g < 3000; ++g) {
        const double sigma_t = std::pow(10.0, -9 + 10 * U(rng));  // 1e-9 .. 10
        const double Dsv = std::pow(10.0, -3 + 6 * U(rng));       // 1 mm .. 1 km
        random_group(rng, Dsv, c, Dvp, 1 + int(U(rng) * 300));     // odd sizes: loop tails
        fell_back += batch(sigma_t, Dsv, c, Dvp, out);
        lanes += long(c.size());
        for (size_t k = 0; k < c.size(); ++k) {
            const double ref = scalar(sigma_t, Dsv, c[k], double(Dvp[k]));
            ASSERT_TRUE(std::isfinite(out[k]) && out[k] >= 0.0f)
                << sigma_t << " " << Dsv << " " << c[k] << " " << Dvp[k];
            // Below FLT_MIN-ish magnitudes float flushes to (near) zero: absolute floor.
            const double err = std::abs(out[k] - ref) / std::max(std::abs(ref), 1e-30);
            if (ref > 1e-30) worst = std::max(worst, err);
            EXPECT_LE(std::abs(out[k] - ref), kFloatTol * ref + 1e-30)
                << sigma_t << " " << Dsv << " " << c[k] << " " << Dvp[k] << " batch " << out[k] << " scalar " << ref;
        }
    }
    std::printf("batch vs scalar: max rel %.3g over %ld lanes, %.1f %% scalar fallback\n", worst, lanes,
                100.0 * fell_back / lanes);
}

TEST(Sun05Batch, TypicalRaysStayOnTheFastPath) {
    // Rays toward the light's hemisphere in the bake's range: the table and short-segment
    // SIMD paths cover almost all of them (measured 0.2 %; on the bench_sun05.py street
    // scene 0.14 % of pixel*light pairs go scalar). Rays pointing away from the light
    // with long segments do go scalar (poorly conditioned F difference, long interval).
    std::mt19937_64 rng(3);
    std::uniform_real_distribution<double> U(0.0, 1.0);
    std::vector<double> c(4096);
    std::vector<float> Dvp(4096), out;
    for (size_t k = 0; k < c.size(); ++k) {
        c[k] = std::cos(0.5 * kPi * U(rng));
        Dvp[k] = U(rng) < 0.2 ? float(kInf) : float(std::pow(10.0, -1 + 3 * U(rng)));
    }
    EXPECT_LT(batch(0.05, 20.0, c, Dvp, out), int(c.size()) / 50);
    // Every lane through the light itself takes the scalar path.
    std::fill(c.begin(), c.end(), 1.0);
    EXPECT_EQ(batch(0.05, 20.0, c, Dvp, out), int(c.size()));
}

TEST(Sun05Batch, MatchesQuadrature) {
    // Same sampling and bound as Sun05.TableMatchesQuadratureRandom (sun05_test.cpp):
    // the batch path may not add error beyond the table's.
    std::mt19937_64 rng(6);
    std::uniform_real_distribution<double> U(0.0, 1.0);
    std::vector<double> err;
    std::vector<double> c(1);
    std::vector<float> Dvp(1), out;
    for (int i = 0; i < 4000; ++i) {
        const double sigma_t = std::pow(10.0, -3 + 3 * U(rng));
        const double Dsv = 0.5 + 49.5 * U(rng);
        c[0] = std::cos(kPi * U(rng));
        Dvp[0] = U(rng) < 0.1 ? float(kInf) : float(std::pow(10.0, -2 + 5 * U(rng)));
        batch(sigma_t, Dsv, c, Dvp, out);
        const double q = sun05_airlight_quadrature(sigma_t, Dsv, c[0], double(Dvp[0]), 1e-10);
        ASSERT_TRUE(std::isfinite(out[0]));
        err.push_back(std::abs(out[0] / q - 1));
    }
    std::sort(err.begin(), err.end());
    std::printf("batch vs quadrature: p99 %.3g max %.3g\n", err[err.size() * 99 / 100], err.back());
    EXPECT_LE(err[err.size() * 99 / 100], 1e-3);
    EXPECT_LE(err.back(), 4e-3);
}

TEST(Sun05Batch, Limits) {
    std::vector<double> c = {0.3, 1.0, -1.0, 0.9};
    std::vector<float> Dvp = {5.0f, 2.0f, float(kInf), 0.0f};
    std::vector<float> out;
    // sigma_t = 0: no fog.
    batch(0.0, 10.0, c, Dvp, out);
    for (float v : out) EXPECT_EQ(v, 0.0f);
    // gamma = 0 with the light behind the surface: the closed form.
    batch(0.1, 10.0, c, Dvp, out);
    EXPECT_NEAR(out[1], sun05_behind_limit(0.1, 10.0, 2.0), 1e-6 * out[1]);
    EXPECT_EQ(out[3], 0.0f);  // zero-length view ray
    // Thin medium: La / sigma_t -> (1/4pi) int_0^Dvp dx / d^2 (exact geometry).
    const double sigma_t = 1e-9, Dsv = 3.0, cg = 0.3, V = 5.0;
    const double s = std::sqrt((1 - cg) * (1 + cg));
    const double thin =
        (std::atan((V - Dsv * cg) / (Dsv * s)) + std::atan(cg / s)) / (4 * kPi * Dsv * s);
    batch(sigma_t, Dsv, c, Dvp, out);
    EXPECT_NEAR(out[0] / sigma_t, thin, 1e-3 * thin);
}

// Reference for the segment [t0, Dvp] seen from the near point o + t0 d: the viewer moved
// there in double (its own Dsv and cos(gamma)), then quadrature of eq. 5.
double near_quadrature(double sigma_t, double Dsv, double c, double Dvp, double t0) {
    const double s = std::sqrt((1 - c) * (1 + c));
    const double x = Dsv * c - t0, h = Dsv * s;  // light at (x, h) from the near point
    const double d0 = std::hypot(x, h);
    return sun05_airlight_quadrature(sigma_t, d0, x / d0, Dvp - t0, 1e-11);
}

TEST(Sun05Batch, NearSegmentMatchesScalarAndQuadrature) {
    // t0 > 0: one evaluation of [t0, Dvp] (sun05_geometry_shift) in the batch and the
    // scalar path, against quadrature from the near point, including the light between
    // eye and near plane, near points close to the light, the sky (Dvp = inf), Dvp <= t0.
    std::mt19937_64 rng(21);
    std::uniform_real_distribution<double> U(0.0, 1.0);
    const SpecialFTable& t = table();
    std::vector<double> err_q;
    double worst_scalar = 0.0;
    for (int g = 0; g < 400; ++g) {
        const double sigma_t = std::pow(10.0, -3 + 3 * U(rng));
        const double Dsv = 0.2 + 50 * U(rng);
        const int n = 1 + int(U(rng) * 300);
        std::vector<double> c(n);
        std::vector<float> Dvp(n), t0(n), out(n);
        for (int k = 0; k < n; ++k) {
            c[k] = U(rng) < 0.1 ? 1.0 - std::pow(10.0, -8 + 7 * U(rng)) : std::cos(kPi * U(rng));
            t0[k] = float(U(rng) < 0.3 ? Dsv * U(rng) * 1.5 : 0.1 / std::max(0.3, U(rng)));
            const double q = U(rng);
            Dvp[k] = q < 0.1 ? float(kInf) : q < 0.15 ? t0[k] * float(U(rng)) : float(t0[k] + std::pow(10.0, -2 + 4 * U(rng)));
        }
        sun05_airlight_table_batch(t.data().data(), t.nu(), t.nT(), sigma_t, Dsv, c.data(), Dvp.data(), n,
                                   out.data(), t0.data());
        for (int k = 0; k < n; ++k) {
            const double ref = sun05_airlight_table(t.data().data(), t.nu(), t.nT(), sigma_t, Dsv, c[k],
                                                    double(Dvp[k]), double(t0[k]));
            if (!(Dvp[k] > t0[k])) {
                EXPECT_EQ(out[k], 0.0f);
                EXPECT_EQ(ref, 0.0);
                continue;
            }
            ASSERT_TRUE(std::isfinite(out[k]) && out[k] >= 0.0f) << sigma_t << " " << Dsv << " " << c[k];
            // Float a, n0 of the shifted viewer are rounded from double: same bound as
            // the unshifted sweep.
            EXPECT_LE(std::abs(out[k] - ref), kFloatTol * ref + 1e-30)
                << sigma_t << " " << Dsv << " " << c[k] << " " << Dvp[k] << " " << t0[k];
            if (ref > 1e-30) worst_scalar = std::max(worst_scalar, std::abs(out[k] - ref) / ref);
            if (k % 7 == 0) {
                const double q = near_quadrature(sigma_t, Dsv, c[k], double(Dvp[k]), double(t0[k]));
                err_q.push_back(std::abs(ref / q - 1));
            }
        }
    }
    std::sort(err_q.begin(), err_q.end());
    std::printf("near segment: batch vs scalar max rel %.3g; scalar vs quadrature p99 %.3g max %.3g (%zu)\n",
                worst_scalar, err_q[err_q.size() * 99 / 100], err_q.back(), err_q.size());
    EXPECT_LE(err_q[err_q.size() * 99 / 100], 1e-3);
    EXPECT_LE(err_q.back(), 4e-3);
}

TEST(Sun05Batch, NearZeroIsTheWholeRay) {
    // t0 = 0 everywhere gives the unshifted result (scalar: bit for bit).
    const SpecialFTable& t = table();
    std::vector<double> c = {0.3, 0.99, -0.7, 0.9, 1.0};
    std::vector<float> Dvp = {5.0f, 30.0f, float(kInf), 0.5f, 2.0f}, t0(c.size(), 0.0f), a(c.size()), b(c.size());
    sun05_airlight_table_batch(t.data().data(), t.nu(), t.nT(), 0.05, 10.0, c.data(), Dvp.data(), 5, a.data());
    sun05_airlight_table_batch(t.data().data(), t.nu(), t.nT(), 0.05, 10.0, c.data(), Dvp.data(), 5, b.data(),
                               t0.data());
    for (size_t k = 0; k < c.size(); ++k) {
        const double s0 = sun05_airlight_table(t.data().data(), t.nu(), t.nT(), 0.05, 10.0, c[k], Dvp[k]);
        EXPECT_EQ(sun05_airlight_table(t.data().data(), t.nu(), t.nT(), 0.05, 10.0, c[k], Dvp[k], 0.0), s0);
        EXPECT_NEAR(a[k], b[k], kFloatTol * a[k]);
        EXPECT_NEAR(a[k], s0, kFloatTol * s0);
    }
    // gamma = 0, light behind the surface, from a near point: the closed form moved.
    const double near = sun05_airlight_table(t.data().data(), t.nu(), t.nT(), 0.1, 10.0, 1.0, 2.0, 0.5);
    EXPECT_NEAR(near, sun05_behind_limit(0.1, 9.5, 1.5), 1e-12 * near);
}

TEST(Sun05Batch, Transmittance) {
    std::vector<float> Dvp = {0.0f, 1e-6f, 0.5f, 3.0f, 100.0f, 1e4f, float(kInf)};
    std::vector<float> Tr(Dvp.size());
    for (float sigma_t : {0.0f, 1e-4f, 0.05f, 0.7f, 10.0f}) {
        transmittance_batch(sigma_t, Dvp.data(), int(Dvp.size()), Tr.data());
        for (size_t k = 0; k < Dvp.size(); ++k) {
            const double x = double(sigma_t) * double(Dvp[k]);
            // The float product sigma_t Dvp is rounded: ~6e-8 x relative on top.
            if (sigma_t == 0.0f) EXPECT_EQ(Tr[k], 1.0f);
            else if (x <= 80.0) EXPECT_NEAR(Tr[k], std::exp(-x), (3e-7 + 6e-8 * x) * std::exp(-x)) << sigma_t << " " << Dvp[k];
            else EXPECT_LE(Tr[k], 1e-34f);
        }
    }
    // Dense sweep of the exponent against std::exp.
    std::vector<float> d(20001), t(d.size());
    for (size_t k = 0; k < d.size(); ++k) d[k] = float(k) * 0.004f;  // exponents 0 .. -80
    transmittance_batch(1.0f, d.data(), int(d.size()), t.data());
    double worst = 0.0;
    for (size_t k = 0; k < d.size(); ++k) worst = std::max(worst, std::abs(t[k] / std::exp(-double(d[k])) - 1));
    EXPECT_LE(worst, 3e-7);
}

}  // namespace airlight
