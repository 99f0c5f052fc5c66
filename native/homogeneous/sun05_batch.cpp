// sun05_batch.cpp: float SIMD version of sun05_airlight_table for many rays, with the
// scalar double path for the lanes it does not take (see sun05_batch.h).
//
// Written as plain loops that GCC if-converts and vectorises (table lookups become
// gathers). Compiled with -O3 -fno-math-errno -fno-trapping-math, never -ffast-math:
// Dvp = inf is a legal input and is carried through as inf (w1 = 1 - h / (h + m1) = 1,
// h / n1 = 0), which -ffinite-math-only would break. target_clones builds AVX-512,
// AVX2 and baseline versions of the hot loop; the loader picks one per CPU.
#include "homogeneous/sun05_batch.h"

#include <cmath>
#include <cstdint>
#include <cstring>

#include "core/special_f.h"
#include "homogeneous/sun05_inline.h"

namespace airlight {

namespace {

// Lanes per block: the fast loop fills out[] and fallback flags for a block, then the
// flagged lanes are redone in double.
constexpr int kBlock = 256;
// The batch keeps a lane only if G > kCancelMargin kCancel F1 (see sun05_batch.h).
constexpr float kCancelMargin = 1.01f;
// e^{-sigma_t a} with a < 0 (light behind the viewer) is only needed up to e^{~5} on
// well-conditioned lanes; beyond e^60 a lane goes to the scalar path (float overflow).
constexpr float kMaxExponent = 60.0f;

#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__) && !defined(AIRLIGHT_NO_CLONES)
#define AIRLIGHT_SIMD_CLONES __attribute__((target_clones("arch=x86-64-v4", "arch=x86-64-v3", "default")))
#else
#define AIRLIGHT_SIMD_CLONES
#endif

inline float bits_to_float(int32_t i) {
    float f;
    std::memcpy(&f, &i, sizeof f);
    return f;
}

// e^x in float for x <= 88, ~1 ulp (Cephes expf polynomial); 0 for x < -87.3.
inline float exp_float(float x) {
    const float kLog2e = 1.44269504088896341f, kLn2Hi = 0.693359375f, kLn2Lo = -2.12194440e-4f;
    const bool under = x < -87.3f;
    x = x > -87.3f ? x : -87.3f;  // also maps NaN to -87.3 (masked below)
    x = x < 88.0f ? x : 88.0f;
    const float k = std::nearbyint(x * kLog2e);
    const float r = (x - k * kLn2Hi) - k * kLn2Lo;
    float p = 1.9875691500e-4f;
    p = p * r + 1.3981999507e-3f;
    p = p * r + 8.3334519073e-3f;
    p = p * r + 4.1665795894e-2f;
    p = p * r + 1.6666665459e-1f;
    p = p * r + 5.0000001201e-1f;
    p = p * r * r + r + 1.0f;
    const float scale = bits_to_float((static_cast<int32_t>(k) + 127) << 23);
    return under ? 0.0f : p * scale;
}

// Bilinear lookup of Q at (x, y) in index units, clamped into the table (NaN -> 0).
inline float table_Q(const float* __restrict table, int nu, int nT, float x, float y) {
    x = x > 0.0f ? x : 0.0f;
    y = y > 0.0f ? y : 0.0f;
    x = x < float(nu - 1) ? x : float(nu - 1);
    y = y < float(nT - 1) ? y : float(nT - 1);
    int i = static_cast<int>(x), j = static_cast<int>(y);
    i = i < nu - 2 ? i : nu - 2;
    j = j < nT - 2 ? j : nT - 2;
    const float fx = x - float(i), fy = y - float(j);
    const int b = i * nT + j;
    const float q00 = table[b], q01 = table[b + 1], q10 = table[b + nT], q11 = table[b + nT + 1];
    const float r0 = q00 + fy * (q01 - q00), r1 = q10 + fy * (q11 - q10);
    return r0 + fx * (r1 - r0);
}

// Nearest-neighbour lookup of Q at (x, y) in index units, clamped into the table (NaN -> 0),
// the same sample as special_F_table_Q_nearest (up to float rounding of x, y at a cell edge).
inline float table_Q_nearest(const float* __restrict table, int nu, int nT, float x, float y) {
    x = x > 0.0f ? x : 0.0f;
    y = y > 0.0f ? y : 0.0f;
    x = x < float(nu - 1) ? x : float(nu - 1);
    y = y < float(nT - 1) ? y : float(nT - 1);
    const int i = static_cast<int>(x + 0.5f), j = static_cast<int>(y + 0.5f);
    return table[i * nT + j];
}

template <Interp kInterp>
inline float table_Q_of(const float* __restrict table, int nu, int nT, float x, float y) {
    if constexpr (kInterp == Interp::Nearest) return table_Q_nearest(table, nu, nT, x, y);
    else return table_Q(table, nu, nT, x, y);
}

// The double part of the geometry for a block, in its own loop (GCC 12 does not
// vectorise loops mixing double and float masks): cos(gamma) clamped, 1 - cos(gamma),
// sin^2(gamma) and dx = Dvp - Dsv cos(gamma), computed in double where cancellation
// would cost float digits (omc near the light, dx where the surface is near the point
// of closest approach), then rounded to float.
// With a near distance t0 the viewer moves to o + t0 d (sun05_geometry_shift): a, n0
// and the viewer-light distance Dsv become per lane, and V = Dvp - t0 is the segment.
struct BlockAngles {
    float sin2[kBlock], dx[kBlock], a[kBlock], n0[kBlock], Dsv[kBlock], V[kBlock];
};

AIRLIGHT_SIMD_CLONES
void block_angles(double Dsv, const double* __restrict cos_gamma, const float* __restrict Dvp, int n,
                  BlockAngles& __restrict out) {
    for (int k = 0; k < n; ++k) {
        double c = cos_gamma[k];
        c = c > -1.0 ? c : -1.0;
        c = c < 1.0 ? c : 1.0;
        const double omc = 1.0 - c;
        out.sin2[k] = float(omc * (1.0 + c));
        out.dx[k] = float(double(Dvp[k]) - Dsv * c);  // inf for Dvp = inf
        out.a[k] = float(Dsv * c);
        out.n0[k] = float(Dsv * omc);
        out.Dsv[k] = float(Dsv);
        out.V[k] = Dvp[k];
    }
}

// The same from the near distances t0[k] >= 0 on (n(t0) cancellation-free, like n1).
AIRLIGHT_SIMD_CLONES
void block_angles_near(double Dsv, const double* __restrict cos_gamma, const float* __restrict Dvp,
                       const float* __restrict t0, int n, BlockAngles& __restrict out) {
    for (int k = 0; k < n; ++k) {
        double c = cos_gamma[k];
        c = c > -1.0 ? c : -1.0;
        c = c < 1.0 ? c : 1.0;
        const double omc = 1.0 - c, sin2 = omc * (1.0 + c);
        const double h2 = Dsv * Dsv * sin2, a = Dsv * c, t = t0[k];
        const double dx0 = t - a, d0 = std::sqrt(h2 + dx0 * dx0);
        const double n0 = dx0 >= 0.0 ? d0 + dx0 : h2 / (d0 - dx0);
        out.sin2[k] = float(sin2);
        out.dx[k] = float(double(Dvp[k]) - a);  // inf for Dvp = inf
        out.a[k] = float(-dx0);
        out.n0[k] = float(n0);
        out.Dsv[k] = float(d0);
        out.V[k] = float(double(Dvp[k]) - t);
    }
}

// Float geometry of one lane (sun05_geometry, shifted by t0 where given).
struct LaneGeometry {
    float a, h, n0, n1, d_p, sin_g;
};

inline LaneGeometry lane_geometry(float Dsv, const BlockAngles& ang, int k) {
    LaneGeometry g;
    const float dx = ang.dx[k];
    g.sin_g = std::sqrt(ang.sin2[k]);
    g.a = ang.a[k];
    g.h = Dsv * g.sin_g;
    g.n0 = ang.n0[k];
    g.d_p = std::sqrt(g.h * g.h + dx * dx);
    g.n1 = dx >= 0.0f ? g.d_p + dx : g.h * g.h / (g.d_p - dx);  // inf for Dvp = inf
    return g;
}

// Pass 1, the table path on every lane of a block: out[k] and fallback[k] = 0 where the
// F difference is well conditioned with a margin; 1 where it is clearly not (the
// scalar path would not use it either) or the lane is degenerate; 2 inside the margin
// band around the scalar test (only the scalar path gives the scalar path's result).
// (One body for both interpolations, instantiated below into two cloned functions.)
template <Interp kInterp>
__attribute__((always_inline)) inline int table_block_impl(const float* __restrict table, int nu, int nT,
                                                           float sigma_t, float Dsv_f,
                                                           const BlockAngles& __restrict ang, int n,
                                                           float* __restrict out, int* __restrict fallback) {
    const float prefactor = sigma_t / float(2.0 * kPi);
    const float kCancel = float(sun05::kCancel) * kCancelMargin;
    const float kSinMin = float(sun05::kSinGammaMin);
    const float kTableK = float(kSpecialFTableK);
    const float su = float(nu - 1), sT = float(nT - 1);
    // GCC 12 does not vectorise gathers next to stores through a pointer it cannot
    // prove distinct (even __restrict): results go to a local array first.
    float result[kBlock];
    int n_flagged = 0;
    for (int k = 0; k < n; ++k) {
        const float V = ang.V[k];
        const LaneGeometry g = lane_geometry(Dsv_f, ang, k);
        // F(u, t0), F(u, t1) from the table (special_F_table_pair), inf-safe forms.
        const float h = g.h, u = sigma_t * h, opu = 1.0f + u;
        const float s = std::sqrt(u / (u + kTableK));
        const float m0 = g.n0 * opu, m1 = g.n1 * opu;
        const float r0 = 1.0f / (h + m0), r1 = 1.0f / (h + m1);
        const float w0 = m0 * r0, w1 = 1.0f - h * r1;
        const float F0 = table_Q_of<kInterp>(table, nu, nT, s * su, w0 * sT) * g.n0 * r0;
        const float F1 = table_Q_of<kInterp>(table, nu, nT, s * su, w1 * sT) / (opu + h / g.n1);
        const float G = F1 - F0;
        const float x = -sigma_t * g.a;
        const float La = prefactor / h * exp_float(x) * G;
        const bool ok = G > kCancel * F1 && g.sin_g >= kSinMin && V > 0.0f && x < kMaxExponent &&
                        La <= 3.0e38f && La >= 0.0f;
        const bool ambiguous = !ok && G * kCancelMargin > kCancel * F1;
        result[k] = ok ? La : 0.0f;
        fallback[k] = ok ? 0 : ambiguous ? 2 : 1;
        n_flagged += ok ? 0 : 1;
    }
    for (int k = 0; k < n; ++k) out[k] = result[k];
    return n_flagged;
}

AIRLIGHT_SIMD_CLONES
int table_block_bilinear(const float* __restrict table, int nu, int nT, float sigma_t, float Dsv_f,
                         const BlockAngles& __restrict ang, int n, float* __restrict out, int* __restrict fallback) {
    return table_block_impl<Interp::Bilinear>(table, nu, nT, sigma_t, Dsv_f, ang, n, out, fallback);
}

AIRLIGHT_SIMD_CLONES
int table_block_nearest(const float* __restrict table, int nu, int nT, float sigma_t, float Dsv_f,
                        const BlockAngles& __restrict ang, int n, float* __restrict out, int* __restrict fallback) {
    return table_block_impl<Interp::Nearest>(table, nu, nT, sigma_t, Dsv_f, ang, n, out, fallback);
}

// Pass 2 on the lanes _idx_ that pass 1 flagged 1: short view segments (the common reason
// for a poorly conditioned F difference) take sun05_direct_E's first branch, 4-point
// Gauss-Legendre in n, in float; with a 1 % margin on its criterion, so that the
// scalar path would take the same branch. value[m] is valid where done[m] = 1.
AIRLIGHT_SIMD_CLONES
void short_block(float sigma_t, float Dsv_f, const BlockAngles& __restrict ang, const int* __restrict idx, int n,
                 float* __restrict value, int* __restrict done) {
    const float prefactor = sigma_t / float(2.0 * kPi);
    const float kSinMin = float(sun05::kSinGammaMin);
    const float kMargin = 1.0f / kCancelMargin;
    for (int m = 0; m < n; ++m) {
        const int k = idx[m];
        const float V = ang.V[k];
        const float Dsv_k = ang.Dsv[k];  // from the (shifted) viewer
        const LaneGeometry g = lane_geometry(Dsv_f, ang, k);
        const float Dsv_exp = exp_float(-sigma_t * Dsv_k);
        // dn = n1 - n0 without cancellation (sun05_geometry_dn).
        const float dn = V * (g.n0 + g.n1) / (g.d_p + Dsv_k);
        const float scale = g.n0 > g.h ? g.n0 : g.h;
        const float h2 = g.h * g.h;
        auto node = [&](int q) {  // one Gauss-Legendre node (written out: GCC 12 leaves
                                  // a counted inner loop as control flow)
            const float l = float(sun05::kGL4x[q]) * dn, nq = g.n0 + l;
            return float(sun05::kGL4w[q]) * exp_float(-sigma_t * l) / (h2 + nq * nq);
        };
        const float sum = (node(0) + node(1)) + (node(2) + node(3));
        const float La = prefactor * Dsv_exp * sum * dn;
        // Bitwise & keeps the test free of branches.
        const bool ok = (dn <= kMargin * scale) & (sigma_t * dn <= kMargin) & (g.sin_g >= kSinMin) &
                        (V > 0.0f) & (V < 3.0e38f) & (La <= 3.0e38f) & (La >= 0.0f);
        value[m] = La;
        done[m] = ok ? 1 : 0;
    }
}

AIRLIGHT_SIMD_CLONES
void transmittance_block(float sigma_t, const float* __restrict Dvp, int n, float* __restrict Tr) {
    for (int k = 0; k < n; ++k) Tr[k] = exp_float(-sigma_t * Dvp[k]);  // -inf -> 0
}

}  // namespace

int sun05_airlight_table_batch(const float* table, int nu, int nT, double sigma_t, double Dsv,
                               const double* cos_gamma, const float* Dvp, int n, float* out, const float* t0,
                               Interp interp) {
    if (!(sigma_t > 0.0)) {
        for (int k = 0; k < n; ++k) out[k] = 0.0f;
        return 0;
    }
    Dsv = std::max(Dsv, sun05::kDsvMin);
    // Float geometry needs h^2 and sigma_t h in range: far outside any scene, go scalar.
    const bool float_ok = Dsv < 1e15 && sigma_t * Dsv < 1e15 && sigma_t > 1e-30;
    int fallback[kBlock], done[kBlock], idx[kBlock];  // see table_block, short_block
    float value[kBlock];
    BlockAngles angles;
    const float Dsv_f = float(Dsv);
    int n_fallback = 0;
    for (int k0 = 0; k0 < n; k0 += kBlock) {
        const int m = std::min(kBlock, n - k0);
        const double* c = cos_gamma + k0;
        const float* V = Dvp + k0;
        const float* near = t0 ? t0 + k0 : nullptr;
        float* o = out + k0;
        int n_left = 0;
        if (float_ok) {
            if (near) block_angles_near(Dsv, c, V, near, m, angles);
            else block_angles(Dsv, c, V, m, angles);
            // Most blocks have no flagged lane: skip passes 2 and 3 then.
            const int n_flagged =
                interp == Interp::Nearest
                    ? table_block_nearest(table, nu, nT, float(sigma_t), Dsv_f, angles, m, o, fallback)
                    : table_block_bilinear(table, nu, nT, float(sigma_t), Dsv_f, angles, m, o, fallback);
            if (n_flagged == 0) continue;
            for (int k = 0; k < m; ++k)
                if (fallback[k] == 1) idx[n_left++] = k;
            short_block(float(sigma_t), Dsv_f, angles, idx, n_left, value, done);
            for (int q = 0; q < n_left; ++q)
                if (done[q]) {
                    o[idx[q]] = value[q];
                    fallback[idx[q]] = 0;
                }
        } else {
            for (int k = 0; k < m; ++k) fallback[k] = 1;
        }
        // Pass 3: the scalar double path for whatever is left.
        for (int k = 0; k < m; ++k) {
            if (!fallback[k]) continue;
            o[k] = float(sun05_airlight_table(table, nu, nT, sigma_t, Dsv, c[k], double(V[k]),
                                              near ? double(near[k]) : 0.0, interp));
            ++n_fallback;
        }
    }
    return n_fallback;
}

void transmittance_batch(float sigma_t, const float* Dvp, int n, float* Tr) {
    if (sigma_t == 0.0f) {
        for (int k = 0; k < n; ++k) Tr[k] = 1.0f;
        return;
    }
    transmittance_block(sigma_t, Dvp, n, Tr);
}

}  // namespace airlight
