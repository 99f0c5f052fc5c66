// splat_kernels.cpp: the splat's float per-lane kernels (see splat_kernels.h). Each kernel
// is one loop over the lanes without branches (selects), so that GCC vectorises it in the
// AIRLIGHT_SIMD_CLONES versions; keep it that way when editing (the notes below say which
// forms stopped the vectoriser).
#include "gaussian/splat_kernels.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <type_traits>

#include "core/fast_erf.h"
#include "core/noise.h"
#include "core/target_clones.h"

namespace airlight {
namespace splat {

namespace {
constexpr float kMinD2f = 1e-12f;
}  // namespace

template <bool kInf, bool kFar>
AIRLIGHT_SIMD_CLONES void view_terms(const GaussF g, int n, const float* __restrict dx, const float* __restrict dy,
                                     const float* __restrict dz, const float* __restrict tend,
                                     float* __restrict Tvp_out, float* __restrict Tvr_out, float* __restrict tr_out) {
    for (int k = 0; k < n; ++k) {
        const float x = dx[k], y = dy[k], z = dz[k];
        const float ts = g.rx * x + g.ry * y + g.rz * z;
        const float cx = g.ry * z - g.rz * y, cy = g.rz * x - g.rx * z, cz = g.rx * y - g.ry * x;
        const float h2 = g.a2 * (cx * cx + cy * cy + cz * cz);
        const float e = g.k0 * fast_expf_le88(-h2);
        const float te = kInf ? std::numeric_limits<float>::infinity() : tend[k];
        const float x1 = -g.a * ts, x2 = g.a * (te - ts);
        // e erfc(|x1|), e erfc(|x2|) (erfcx form, fast_erf.h; x2 = inf gives 0 * 0)
        const float eE1 = kFar ? 0.0f : g.ke * fast_erfcx_pos(x1 < 0.0f ? -x1 : x1);
        const float eE2 = kInf ? 0.0f : g.k0 * fast_erfcx_pos(x2 < 0.0f ? -x2 : x2) * fast_expf_le88(-h2 - x2 * x2);
        const float Tvp = x1 >= 0.0f ? eE1 - eE2 : (x2 <= 0.0f ? eE2 - eE1 : 2.0f * e - eE1 - eE2);
        Tvr_out[k] = ts <= 0.0f ? 0.0f : (ts >= te ? Tvp : e - eE1);
        tr_out[k] = ts < 0.0f ? 0.0f : (ts > te ? te : ts);
        Tvp_out[k] = Tvp;
    }
}

AIRLIGHT_SIMD_CLONES void noise_dirs(float nscale, const float* eye, float ninv_scale, float nox, float noy,
                                     float noz, int n, const float* __restrict dx, const float* __restrict dy,
                                     const float* __restrict dz, const float* __restrict tr, float* __restrict qx_out,
                                     float* __restrict qy_out, float* __restrict qz_out) {
    for (int k = 0; k < n; ++k) {
        const float x = dx[k], y = dy[k], z = dz[k], t = tr[k];
        const float px = (eye[0] + t * x) * ninv_scale + nox;
        const float py = (eye[1] + t * y) * ninv_scale + noy;
        const float pz = (eye[2] + t * z) * ninv_scale + noz;
        float nx, ny, nz;
        gradient_noise3_inlined(px, py, pz, nx, ny, nz);
        const float qx = x + nscale * nx, qy = y + nscale * ny, qz = z + nscale * nz;
        const float inv = 1.0f / std::sqrt(std::max(qx * qx + qy * qy + qz * qz, 1e-30f));
        qx_out[k] = qx * inv;
        qy_out[k] = qy * inv;
        qz_out[k] = qz * inv;
    }
}

template <bool kFar>
AIRLIGHT_SIMD_CLONES void light_terms(const GaussF g, const GaussLightF gl, const LightF lf, int n,
                                      const float* __restrict dx, const float* __restrict dy,
                                      const float* __restrict dz, const float* __restrict Tvp,
                                      const float* __restrict Tvr, const float* __restrict tr, float* __restrict R,
                                      float* __restrict G, float* __restrict B) {
    for (int k = 0; k < n; ++k) {
        const float t = tr[k];
        const float sx = lf.vx + t * dx[k], sy = lf.vy + t * dy[k], sz = lf.vz + t * dz[k];
        const float d2 = std::max(sx * sx + sy * sy + sz * sz, kMinD2f);
        const float inv = 1.0f / std::sqrt(d2);
        const float ux = sx * inv, uy = sy * inv, uz = sz * inv;
        const float Ds = d2 * inv;
        const float ts = gl.sx * ux + gl.sy * uy + gl.sz * uz;
        const float cx = gl.sy * uz - gl.sz * uy, cy = gl.sz * ux - gl.sx * uz, cz = gl.sx * uy - gl.sy * ux;
        const float h2 = g.a2 * (cx * cx + cy * cy + cz * cz);
        const float e = g.k0 * fast_expf_le88(-h2);
        const float x1 = -g.a * ts, x2 = g.a * (Ds - ts);
        const float eE1 = kFar ? 0.0f : gl.ke * fast_erfcx_pos(x1 < 0.0f ? -x1 : x1);
        const float eE2 = g.k0 * fast_erfcx_pos(x2 < 0.0f ? -x2 : x2) * fast_expf_le88(-h2 - x2 * x2);
        const float Tsr = x1 >= 0.0f ? eE1 - eE2 : (x2 <= 0.0f ? eE2 - eE1 : 2.0f * e - eE1 - eE2);
        const float f = fast_expf_le88(-Tsr - Tvr[k]) * Tvp[k] / d2;
        R[k] += gl.wr * f;
        G[k] += gl.wg * f;
        B[k] += gl.wb * f;
    }
}

namespace {

// 4 pi p(mu) in float for the phase kind K (phase.h; mu clamped to [-1, 1]); g1 = g,
// g2 = 1 - g^2, g3 = 1 + g^2 for Henyey-Greenstein.
template <int K>
inline float phase4pi_f(float mu, float g1, float g2, float g3) {
    mu = mu < -1.0f ? -1.0f : (mu > 1.0f ? 1.0f : mu);
    if constexpr (K == int(PhaseKind::HenyeyGreenstein)) {
        const float d = g3 - 2.0f * g1 * mu;
        return g2 / (d * std::sqrt(d));
    } else if constexpr (K == int(PhaseKind::Rayleigh)) {
        return 0.75f * (1.0f + mu * mu);
    } else if constexpr (K == int(PhaseKind::HazyMie)) {
        const float h = 0.5f * (1.0f + mu), h2 = h * h, h4 = h2 * h2;
        return 0.5f * (1.0f + 9.0f * h4 * h4);
    } else if constexpr (K == int(PhaseKind::MurkyMie)) {
        const float h = 0.5f * (1.0f + mu), h2 = h * h, h4 = h2 * h2, h8 = h4 * h4, h16 = h8 * h8;
        return (33.0f / 83.0f) * (1.0f + 50.0f * h16 * h16);
    } else {
        return 1.0f;
    }
}

// light_terms_phase for the phase kind K and, if kSpot, the spot profile of light lf.
// Its first lines repeat light_terms' on purpose: factoring them into an inline helper
// returning a struct (or calling fast_erf_diff) stopped GCC vectorising both loops - measured
// 9x the CPU time of the whole bake on tests/native/test_bake_gaussians_resolution.py's scene.
template <int K, bool kSpot>
AIRLIGHT_SIMD_CLONES void light_terms_ext(const GaussF g, const GaussLightF gl, const LightF lf, float g1, float g2,
                                          float g3, int n, const float* __restrict dx, const float* __restrict dy,
                                          const float* __restrict dz, const float* __restrict Tvp,
                                          const float* __restrict Tvr, const float* __restrict tr,
                                          float* __restrict R, float* __restrict G, float* __restrict B) {
    for (int k = 0; k < n; ++k) {
        const float t = tr[k];
        const float sx = lf.vx + t * dx[k], sy = lf.vy + t * dy[k], sz = lf.vz + t * dz[k];
        const float d2 = std::max(sx * sx + sy * sy + sz * sz, kMinD2f);
        const float inv = 1.0f / std::sqrt(d2);
        const float ux = sx * inv, uy = sy * inv, uz = sz * inv;
        const float Ds = d2 * inv;
        const float ts = gl.sx * ux + gl.sy * uy + gl.sz * uz;
        const float cx = gl.sy * uz - gl.sz * uy, cy = gl.sz * ux - gl.sx * uz, cz = gl.sx * uy - gl.sy * ux;
        const float h2 = g.a2 * (cx * cx + cy * cy + cz * cz);
        const float e = g.k0 * fast_expf_le88(-h2);
        const float x1 = -g.a * ts, x2 = g.a * (Ds - ts);
        const float eE1 = gl.ke * fast_erfcx_pos(x1 < 0.0f ? -x1 : x1);
        const float eE2 = g.k0 * fast_erfcx_pos(x2 < 0.0f ? -x2 : x2) * fast_expf_le88(-h2 - x2 * x2);
        const float Tsr = x1 >= 0.0f ? eE1 - eE2 : (x2 <= 0.0f ? eE2 - eE1 : 2.0f * e - eE1 - eE2);
        // cos theta: propagation light -> b^r (u) against the direction to the eye (-d).
        float f = fast_expf_le88(-Tsr - Tvr[k]) * Tvp[k] / d2 *
                  phase4pi_f<K>(-(ux * dx[k] + uy * dy[k] + uz * dz[k]), g1, g2, g3);
        if constexpr (kSpot) {
            const float c = lf.ax * ux + lf.ay * uy + lf.az * uz;
            const float x = c - lf.cos_half;
            float u = lf.smooth > 0.0f ? x / lf.smooth : 1.0f;
            u = u < 0.0f ? 0.0f : (u > 1.0f ? 1.0f : u);
            const float s2 = 1.0f - c * c;
            const float spread = lf.spread_a * c - lf.spread_b * std::sqrt(s2 > 0.0f ? s2 : 0.0f);
            f *= x > 0.0f ? (lf.spread_b > 0.0f ? spread : c * u * u * (3.0f - 2.0f * u)) : 0.0f;
        }
        R[k] += gl.wr * f;
        G[k] += gl.wg * f;
        B[k] += gl.wb * f;
    }
}

// sun_terms_phase for the phase kind K.
template <int K>
AIRLIGHT_SIMD_CLONES void sun_terms(const GaussF g, const GaussLightF gl, float ux, float uy, float uz, float g1,
                                    float g2, float g3, int n, const float* __restrict dx, const float* __restrict dy,
                                    const float* __restrict dz, const float* __restrict Tvp,
                                    const float* __restrict Tvr, const float* __restrict tr, float* __restrict R,
                                    float* __restrict G, float* __restrict B) {
    for (int k = 0; k < n; ++k) {
        const float t = tr[k];
        const float bx = g.rx - t * dx[k], by = g.ry - t * dy[k], bz = g.rz - t * dz[k];
        const float ts = bx * ux + by * uy + bz * uz;
        const float cx = by * uz - bz * uy, cy = bz * ux - bx * uz, cz = bx * uy - by * ux;
        const float e = g.k0 * fast_expf_le88(-g.a2 * (cx * cx + cy * cy + cz * cz));
        const float x1 = -g.a * ts;
        const float E1 = fast_erfc_pos(x1 < 0.0f ? -x1 : x1);
        const float Tsr = e * (x1 >= 0.0f ? E1 : 2.0f - E1);
        // cos theta = w . (-d) = u . d
        const float f = fast_expf_le88(-Tsr - Tvr[k]) * Tvp[k] *
                        phase4pi_f<K>(ux * dx[k] + uy * dy[k] + uz * dz[k], g1, g2, g3);
        R[k] += gl.wr * f;
        G[k] += gl.wg * f;
        B[k] += gl.wb * f;
    }
}

// Calls fn(std::integral_constant<int, K>()) for the phase kind K (Isotropic for an unknown one).
template <class Fn>
void dispatch_phase(PhaseKind kind, Fn&& fn) {
    switch (int(kind)) {
        case int(PhaseKind::HenyeyGreenstein):
            fn(std::integral_constant<int, int(PhaseKind::HenyeyGreenstein)>());
            break;
        case int(PhaseKind::Rayleigh): fn(std::integral_constant<int, int(PhaseKind::Rayleigh)>()); break;
        case int(PhaseKind::HazyMie): fn(std::integral_constant<int, int(PhaseKind::HazyMie)>()); break;
        case int(PhaseKind::MurkyMie): fn(std::integral_constant<int, int(PhaseKind::MurkyMie)>()); break;
        default: fn(std::integral_constant<int, int(PhaseKind::Isotropic)>()); break;
    }
}

}  // namespace

void light_terms_phase(PhaseKind kind, bool spot, const GaussF g, const GaussLightF gl, const LightF lf, float g1,
                       float g2, float g3, int n, const float* dx, const float* dy, const float* dz, const float* Tvp,
                       const float* Tvr, const float* tr, float* R, float* G, float* B) {
    dispatch_phase(kind, [&](auto K) {
        constexpr int k = decltype(K)::value;
        if (spot) light_terms_ext<k, true>(g, gl, lf, g1, g2, g3, n, dx, dy, dz, Tvp, Tvr, tr, R, G, B);
        else light_terms_ext<k, false>(g, gl, lf, g1, g2, g3, n, dx, dy, dz, Tvp, Tvr, tr, R, G, B);
    });
}

void sun_terms_phase(PhaseKind kind, const GaussF g, const GaussLightF gl, float ux, float uy, float uz, float g1,
                     float g2, float g3, int n, const float* dx, const float* dy, const float* dz, const float* Tvp,
                     const float* Tvr, const float* tr, float* R, float* G, float* B) {
    dispatch_phase(kind, [&](auto K) {
        constexpr int k = decltype(K)::value;
        sun_terms<k>(g, gl, ux, uy, uz, g1, g2, g3, n, dx, dy, dz, Tvp, Tvr, tr, R, G, B);
    });
}

AIRLIGHT_SIMD_CLONES void add_to(const float* __restrict x, int n, float* __restrict acc) {
    for (int k = 0; k < n; ++k) acc[k] += x[k];
}

namespace {

// View side of lattice_gaussian_major for one ray (x, y, z): Tvp, Tvr, tr per Gaussian.
template <bool kFar>
AIRLIGHT_SIMD_CLONES void lattice_view_gm(int n, const float* __restrict rx, const float* __restrict ry,
                                          const float* __restrict rz, const float* __restrict ga,
                                          const float* __restrict ga2, const float* __restrict gk0,
                                          const float* __restrict gke, float x, float y, float z,
                                          float* __restrict Tvp, float* __restrict Tvr, float* __restrict tr) {
    for (int k = 0; k < n; ++k) {
        const float ts = rx[k] * x + ry[k] * y + rz[k] * z;
        const float cx = ry[k] * z - rz[k] * y, cy = rz[k] * x - rx[k] * z, cz = rx[k] * y - ry[k] * x;
        const float e = gk0[k] * fast_expf_le88(-ga2[k] * (cx * cx + cy * cy + cz * cz));
        const float x1 = -ga[k] * ts;
        const float eE1 = kFar ? 0.0f : gke[k] * fast_erfcx_pos(x1 < 0.0f ? -x1 : x1);
        Tvp[k] = x1 >= 0.0f ? eE1 : 2.0f * e - eE1;
        tr[k] = ts < 0.0f ? 0.0f : ts;
        Tvr[k] = ts <= 0.0f ? 0.0f : e - eE1;
    }
}

// Light side of lattice_gaussian_major for one ray and light (v = eye - s): sets (first)
// or adds the RGB terms per Gaussian.
template <bool kFirst, bool kFar>
AIRLIGHT_SIMD_CLONES void lattice_light_gm(int n, const float* __restrict ga, const float* __restrict ga2,
                                           const float* __restrict gk0, const float* __restrict gsx,
                                           const float* __restrict gsy, const float* __restrict gsz,
                                           const float* __restrict gwr, const float* __restrict gwg,
                                           const float* __restrict gwb, const float* __restrict gke, float vx,
                                           float vy, float vz, float x, float y, float z, const float* __restrict Tvp,
                                           const float* __restrict Tvr, const float* __restrict tr,
                                           float* __restrict aR, float* __restrict aG, float* __restrict aB) {
    for (int k = 0; k < n; ++k) {
        const float t = tr[k];
        const float sx = vx + t * x, sy = vy + t * y, sz = vz + t * z;
        const float d2 = std::max(sx * sx + sy * sy + sz * sz, kMinD2f);
        const float inv = 1.0f / std::sqrt(d2);
        const float ux = sx * inv, uy = sy * inv, uz = sz * inv;
        const float Ds = d2 * inv;
        const float ts = gsx[k] * ux + gsy[k] * uy + gsz[k] * uz;
        const float cx = gsy[k] * uz - gsz[k] * uy, cy = gsz[k] * ux - gsx[k] * uz, cz = gsx[k] * uy - gsy[k] * ux;
        const float h2 = ga2[k] * (cx * cx + cy * cy + cz * cz);
        const float e = gk0[k] * fast_expf_le88(-h2);
        const float x1 = -ga[k] * ts, x2 = ga[k] * (Ds - ts);
        const float eE1 = kFar ? 0.0f : gke[k] * fast_erfcx_pos(x1 < 0.0f ? -x1 : x1);
        const float eE2 = gk0[k] * fast_erfcx_pos(x2 < 0.0f ? -x2 : x2) * fast_expf_le88(-h2 - x2 * x2);
        const float Tsr = x1 >= 0.0f ? eE1 - eE2 : (x2 <= 0.0f ? eE2 - eE1 : 2.0f * e - eE1 - eE2);
        const float f = fast_expf_le88(-Tsr - Tvr[k]) * Tvp[k] / d2;
        if constexpr (kFirst) {
            aR[k] = gwr[k] * f;
            aG[k] = gwg[k] * f;
            aB[k] = gwb[k] * f;
        } else {
            aR[k] += gwr[k] * f;
            aG[k] += gwg[k] * f;
            aB[k] += gwb[k] * f;
        }
    }
}

// Sums of four arrays of n values (n a multiple of 16) in 16 lanes (vectorised without
// reassociation flags), added to *T, *R, *G, *B.
AIRLIGHT_SIMD_CLONES void sum4_16(int n, const float* __restrict a, const float* __restrict b,
                                  const float* __restrict c, const float* __restrict d, float* T, float* R, float* G,
                                  float* B) {
    float pT[16] = {}, pR[16] = {}, pG[16] = {}, pB[16] = {};
    for (int k = 0; k < n; k += 16)
        for (int u = 0; u < 16; ++u) {
            pT[u] += a[k + u];
            pR[u] += b[k + u];
            pG[u] += c[k + u];
            pB[u] += d[k + u];
        }
    float sT = 0.0f, sR = 0.0f, sG = 0.0f, sB = 0.0f;
    for (int u = 0; u < 16; ++u) {
        sT += pT[u];
        sR += pR[u];
        sG += pG[u];
        sB += pB[u];
    }
    *T += sT;
    *R += sR;
    *G += sG;
    *B += sB;
}

}  // namespace

template <bool kFar>
void lattice_gaussian_major(LatticeSoA& q, int L, const LightF* lf, int m, const float* lx, const float* ly,
                            const float* lz, float* T, float* R, float* G, float* B) {
    const int n = q.n;
    float* Tvp = q.scratch.data();
    float* Tvr = Tvp + n;
    float* tr = Tvr + n;
    float* aR = tr + n;
    float* aG = aR + n;
    float* aB = aG + n;
    for (int j = 0; j < m; ++j) {
        lattice_view_gm<kFar>(n, q.rx.data(), q.ry.data(), q.rz.data(), q.a.data(), q.a2.data(), q.k0.data(),
                              q.ke.data(), lx[j], ly[j], lz[j], Tvp, Tvr, tr);
        if (L == 0) {
            std::fill(aR, aR + n, 0.0f);
            std::fill(aG, aG + n, 0.0f);
            std::fill(aB, aB + n, 0.0f);
        }
        for (int l = 0; l < L; ++l) {
            const std::size_t o = std::size_t(l) * n;
            (l == 0 ? lattice_light_gm<true, kFar> : lattice_light_gm<false, kFar>)(
                n, q.a.data(), q.a2.data(), q.k0.data(), q.sx.data() + o, q.sy.data() + o, q.sz.data() + o,
                q.wr.data() + o, q.wg.data() + o, q.wb.data() + o, q.ske.data() + o, lf[l].vx, lf[l].vy, lf[l].vz,
                lx[j], ly[j], lz[j], Tvp, Tvr, tr, aR, aG, aB);
        }
        sum4_16(n, Tvp, aR, aG, aB, T + j, R + j, G + j, B + j);
    }
}

template void view_terms<false, false>(GaussF, int, const float*, const float*, const float*, const float*, float*,
                                       float*, float*);
template void view_terms<false, true>(GaussF, int, const float*, const float*, const float*, const float*, float*,
                                      float*, float*);
template void view_terms<true, false>(GaussF, int, const float*, const float*, const float*, const float*, float*,
                                      float*, float*);
template void view_terms<true, true>(GaussF, int, const float*, const float*, const float*, const float*, float*,
                                     float*, float*);
template void light_terms<false>(GaussF, GaussLightF, LightF, int, const float*, const float*, const float*,
                                 const float*, const float*, const float*, float*, float*, float*);
template void light_terms<true>(GaussF, GaussLightF, LightF, int, const float*, const float*, const float*,
                                const float*, const float*, const float*, float*, float*, float*);
template void lattice_gaussian_major<false>(LatticeSoA&, int, const LightF*, int, const float*, const float*,
                                            const float*, float*, float*, float*, float*);
template void lattice_gaussian_major<true>(LatticeSoA&, int, const LightF*, int, const float*, const float*,
                                           const float*, float*, float*, float*, float*);

}  // namespace splat
}  // namespace airlight
