// gaussian_splat.cpp: tiled screen-space splatting of Gaussian fog (see gaussian_splat.h).
//
// Layout of the work: bin() computes each Gaussian's cull-sphere bounds in film
// coordinates (the sphere's tangent planes through the eye, exact for the projective map
// D0 + px Dx + py Dy, shift and sensor fit included) and lists it in every 16x16 tile the
// bounds touch; spheres that reach the plane through the eye parallel to the film go to
// every tile. splat_tile() then gathers the tile's rays in structure-of-arrays form and
// runs one branch-free loop over the tile's pixels per (Gaussian, light), which GCC
// vectorises (AVX-512 / AVX2 clones) with the float kernels of fast_erf.h and noise.h.
#include "gaussian/splat.h"
#include "core/constants.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <mutex>
#include <sstream>
#include <stdexcept>
#include <thread>
#include <type_traits>

#include "core/fast_erf.h"
#include "core/noise.h"
#include "core/phase.h"
#include "gaussian/centre_depths.h"
#include "gaussian/simd_clones.h"
#include "homogeneous/sun05.h"
#include "homogeneous/sun05_batch.h"

namespace airlight {

namespace {

constexpr double kSqrtPi = 1.77245385090551602729;
constexpr float kMinD2f = 1e-12f;
constexpr int kTilePixels = GaussianSplat::kTile * GaussianSplat::kTile;

// View-ray part of one Gaussian for n rays: optical depth over [0, tend] (Tvp), over
// [0, b^r] (Tvr) and the clamped projection tr. Noise (splat_gaussian): the same on the
// perturbed directions of noise_dirs gives the perturbed Tvp.
// kInf (reduced resolution's lattice rays): every tend is +inf, the far erfc term is 0.
// kFar (GaussianSplat::GaussF::far_eye): the ray's start lies >= kFarStart / a before the
// Gaussian, so its erfc E1 = erfc(a ts) < 2e-10 is left out (one erfc fewer per lane).
template <bool kInf = false, bool kFar = false>
AIRLIGHT_SIMD_CLONES void view_terms(const GaussianSplat::GaussF g, int n, const float* __restrict dx,
                                     const float* __restrict dy, const float* __restrict dz,
                                     const float* __restrict tend, float* __restrict Tvp_out,
                                     float* __restrict Tvr_out, float* __restrict tr_out) {
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

// The noise-perturbed view directions for n rays (Fogshop 5.5: lookup at b^r = eye + tr d
// in world space, the unperturbed ray's), in a loop of its own so that it vectorises;
// view_terms on these directions then gives the perturbed Tvp.
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

// Light part: adds w exp(-T_i(s, b^r) - Tvr) Tvp / |b^r - s|^2 to the RGB accumulators.
// kFar (GaussianSplat::GaussF::far_lights): the light lies >= kFarStart / a before the Gaussian
// along every path s -> b^r with b^r in the cull sphere, so the erfc at s is left out.
template <bool kFar = false>
AIRLIGHT_SIMD_CLONES void light_terms(const GaussianSplat::GaussF g, const GaussianSplat::GaussLightF gl,
                                      const GaussianSplat::LightF lf, int n, const float* __restrict dx,
                                      const float* __restrict dy, const float* __restrict dz,
                                      const float* __restrict Tvp, const float* __restrict Tvr,
                                      const float* __restrict tr, float* __restrict R, float* __restrict G,
                                      float* __restrict B) {
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

// light_terms with a phase function (K) and, if kSpot, the spot profile of light lf:
// adds w 4 pi p(cos theta) profile exp(-T_i(s, b^r) - Tvr) Tvp / |b^r - s|^2.
// Its first lines repeat light_terms' on purpose: factoring them into an inline helper
// returning a struct (or calling fast_erf_diff) stopped GCC vectorising both loops - measured
// 9x the CPU time of the whole bake on tests/native/test16_rbf_resolution.py's scene.
template <int K, bool kSpot>
AIRLIGHT_SIMD_CLONES void light_terms_ext(const GaussianSplat::GaussF g, const GaussianSplat::GaussLightF gl,
                                          const GaussianSplat::LightF lf, float g1, float g2, float g3, int n,
                                          const float* __restrict dx, const float* __restrict dy,
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
            f *= x > 0.0f ? c * u * u * (3.0f - 2.0f * u) : 0.0f;
        }
        R[k] += gl.wr * f;
        G[k] += gl.wg * f;
        B[k] += gl.wb * f;
    }
}

// Sun lamp term: w 4 pi p(cos theta) exp(-T_i(b^r -> sun) - Tvr) Tvp, with Gaussian i's
// half-line depth from b^r = eye + tr d towards the sun (unit (ux, uy, uz) = -w):
// k0 e^{-a^2 |(b - b^r) x u|^2} erfc(-a (b - b^r).u).
template <int K>
AIRLIGHT_SIMD_CLONES void sun_terms(const GaussianSplat::GaussF g, const GaussianSplat::GaussLightF gl, float ux, float uy,
                                    float uz, float g1, float g2, float g3, int n, const float* __restrict dx,
                                    const float* __restrict dy, const float* __restrict dz,
                                    const float* __restrict Tvp, const float* __restrict Tvr,
                                    const float* __restrict tr, float* __restrict R, float* __restrict G,
                                    float* __restrict B) {
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

// Reduced resolution (splat_tile_reduced): which of the n rays (segments [0, far[k]])
// Gaussian g's cull sphere (radius^2 R2) against the rays of a tile's pixels (dx, dy, dz,
// n of them, ending at far). A ray that misses the sphere is neither; one that crosses it
// is "not in front" unless the sphere's exit lies before far[k], and "not behind" unless
// its entry lies beyond far[k]. Per pixel into nf, nb (1: not in front, not behind); one
// loop over the tile (a call per 4x4 block spent ~40 % in its set-up), and without the
// square root: te >= ts + half as te - ts >= 0 and (te - ts)^2 >= R2 - h2.
AIRLIGHT_SIMD_CLONES void depth_classes(const GaussianSplat::GaussF g, float R2, int n, const float* __restrict dx,
                                        const float* __restrict dy, const float* __restrict dz,
                                        const float* __restrict far, unsigned char* __restrict nf,
                                        unsigned char* __restrict nb) {
    for (int k = 0; k < n; ++k) {
        const float x = dx[k], y = dy[k], z = dz[k];
        const float ts = g.rx * x + g.ry * y + g.rz * z;
        const float cx = g.ry * z - g.rz * y, cy = g.rz * x - g.rx * z, cz = g.rx * y - g.ry * x;
        const float q = R2 - (cx * cx + cy * cy + cz * cz);  // half^2, > 0 where the ray crosses
        const float u = far[k] - ts, u2 = u * u;
        // (inf - inf: far = inf with ts = inf does not occur, ts is finite)
        const bool cross = q > 0.0f;
        const bool front = u >= 0.0f && u2 >= q, behind = u <= 0.0f && u2 >= q;
        nf[k] = (cross && !front) ? 1 : 0;
        nb[k] = (cross && !behind) ? 1 : 0;
    }
}

// The lattice of a tile at reduced resolution in Gaussian-major order (plain path: isotropic
// point lights, no noise): for each of the m lattice rays (lx, ly, lz), the Dvp = inf terms
// of the n Gaussians gathered in structure-of-arrays form (n a multiple of 16, padded with
// k0 = 0 and zero weights), summed over the Gaussians into T, R, G, B. The same arithmetic
// as view_terms<true> and light_terms, one SIMD lane per Gaussian instead of per ray:
// long loops, no padding of the (16/s + 1)^2 rays, one call per tile instead of per pair.
// Per-(Gaussian, light) data at [l n + k]; ke is GaussF::ke, ske GaussLightF::ke; scratch: 6 n
// floats.
struct LatticeSoA {
    std::vector<float> rx, ry, rz, a, a2, k0, ke, sx, sy, sz, wr, wg, wb, ske, scratch;
    int n = 0;
};

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

// kFar: every Gaussian of q is far from the eye and the lights (GaussF::far_eye, far_lights).
template <bool kFar>
void lattice_gaussian_major(LatticeSoA& q, int L, const GaussianSplat::LightF* lf, int m, const float* lx,
                            const float* ly, const float* lz, float* T, float* R, float* G, float* B) {
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

// sub_interp for n pixels inside one lattice cell (top-left index a).
AIRLIGHT_SIMD_CLONES void sub_interp_cell(int n, int a, const float* __restrict wgt, int nu,
                                          const float* __restrict T, const float* __restrict R,
                                          const float* __restrict G, const float* __restrict B,
                                          float* __restrict aT, float* __restrict aR, float* __restrict aG,
                                          float* __restrict aB) {
    const int b = a + 1, c = a + nu, d = c + 1;
    const float t0 = T[a], t1 = T[b], t2 = T[c], t3 = T[d];
    const float r0 = R[a], r1 = R[b], r2 = R[c], r3 = R[d];
    const float g0 = G[a], g1 = G[b], g2 = G[c], g3 = G[d];
    const float b0 = B[a], b1 = B[b], b2 = B[c], b3 = B[d];
    for (int k = 0; k < n; ++k) {
        const float w0 = wgt[k], w1 = wgt[kTilePixels + k], w2 = wgt[2 * kTilePixels + k],
                    w3 = wgt[3 * kTilePixels + k];
        aT[k] -= w0 * t0 + w1 * t1 + w2 * t2 + w3 * t3;
        aR[k] -= w0 * r0 + w1 * r1 + w2 * r2 + w3 * r3;
        aG[k] -= w0 * g0 + w1 * g1 + w2 * g2 + w3 * g3;
        aB[k] -= w0 * b0 + w1 * b1 + w2 * b2 + w3 * b3;
    }
}

// Subtracts the bilinear interpolation of the lattice values (T, R, G, B; lattice rows of
// nu) at n pixels (top-left lattice index lat[k], weights wgt[j kTilePixels + k], j = 0..3)
// from the accumulators.
AIRLIGHT_SIMD_CLONES void sub_interp(int n, const int* __restrict lat, const float* __restrict wgt, int nu,
                                     const float* __restrict T, const float* __restrict R,
                                     const float* __restrict G, const float* __restrict B, float* __restrict aT,
                                     float* __restrict aR, float* __restrict aG, float* __restrict aB) {
    for (int k = 0; k < n; ++k) {
        const int a = lat[k], b = a + 1, c = a + nu, d = c + 1;
        const float w0 = wgt[k], w1 = wgt[kTilePixels + k], w2 = wgt[2 * kTilePixels + k],
                    w3 = wgt[3 * kTilePixels + k];
        aT[k] -= w0 * T[a] + w1 * T[b] + w2 * T[c] + w3 * T[d];
        aR[k] -= w0 * R[a] + w1 * R[b] + w2 * R[c] + w3 * R[d];
        aG[k] -= w0 * G[a] + w1 * G[b] + w2 * G[c] + w3 * G[d];
        aB[k] -= w0 * B[a] + w1 * B[b] + w2 * B[c] + w3 * B[d];
    }
}

// Bilinear interpolation of a tile's lattice sums (nodes every s pixels, nu per row) to its
// w x h pixel centres, added to T, R, G, B: per row, the sums interpolated along y at each
// node column, spread to the pixels' left and right nodes, then one vectorised blend along x
// (a free function so that the SIMD clones apply; the direct 4-tap form needed gathers).
AIRLIGHT_SIMD_CLONES void interp_lattice(int w, int h, int s, int nu, const float* __restrict cT,
                                         const float* __restrict cR, const float* __restrict cG,
                                         const float* __restrict cB, float* __restrict T, float* __restrict R,
                                         float* __restrict G, float* __restrict B) {
    constexpr int kMaxNodes = GaussianSplat::kTile + 1;
    const float inv_s = 1.0f / float(s);
    int ui[GaussianSplat::kTile];
    float wx[GaussianSplat::kTile];
    for (int i = 0; i < w; ++i) {
        const float fx = (float(i) + 0.5f) * inv_s;
        ui[i] = int(fx);
        wx[i] = fx - float(ui[i]);
    }
    const float* c[4] = {cT, cR, cG, cB};
    float* out[4] = {T, R, G, B};
    // Along x once per lattice row (the rows a pixel row needs: v and v + 1), then each
    // pixel row between two of those: the gathers run per lattice row, not per pixel row.
    const int nv = int((float(h) - 0.5f) * inv_s) + 2;
    for (int q = 0; q < 4; ++q) {
        float rows[kMaxNodes][GaussianSplat::kTile];
        for (int v = 0; v < nv; ++v) {
            const float* node = c[q] + v * nu;
            float lo[GaussianSplat::kTile], hi[GaussianSplat::kTile];
            for (int i = 0; i < w; ++i) {
                lo[i] = node[ui[i]];
                hi[i] = node[ui[i] + 1];
            }
            for (int i = 0; i < w; ++i) rows[v][i] = (1.0f - wx[i]) * lo[i] + wx[i] * hi[i];
        }
        for (int j = 0; j < h; ++j) {
            const float fy = (float(j) + 0.5f) * inv_s;
            const int v = int(fy);
            const float wy = fy - float(v);
            const float* top = rows[v];
            const float* bot = rows[v + 1];
            float* o = out[q] + j * w;
            for (int i = 0; i < w; ++i) o[i] += (1.0f - wy) * top[i] + wy * bot[i];
        }
    }
}

// bin()'s cone test for m consecutive tiles of a row (their cones: unit axes ax, ay, az, cos
// and sin of the half-angles) against one ball (unit direction u, sin and cos of its angular
// radius): hit[k] = 1 where the ball can meet tile k's rays. A loop of its own so that it
// vectorises; the count and the fill pass both call it (the same clone: the same answers).
AIRLIGHT_SIMD_CLONES void cone_hits(int m, const double* __restrict ax, const double* __restrict ay,
                                    const double* __restrict az, const double* __restrict ct,
                                    const double* __restrict st, double ux, double uy, double uz, double sin_r,
                                    double cos_r, unsigned char* __restrict hit) {
    for (int k = 0; k < m; ++k) {
        const double cos_sum = ct[k] * cos_r - st[k] * sin_r;  // cos(theta + rho)
        // theta + rho >= pi: every direction qualifies (sin of the sum < 0 with cos < 0)
        const bool wide = st[k] * cos_r + ct[k] * sin_r < 0.0;
        const bool close = ax[k] * ux + ay[k] * uy + az[k] * uz >= cos_sum;
        hit[k] = (unsigned char)(wide | close);
    }
}

// Cubic Lagrange weights of the nodes -1, 0, 1, 2 at f in [0, 1).
inline void cubic_weights(float f, float* w) {
    w[0] = -f * (f - 1.0f) * (f - 2.0f) * (1.0f / 6.0f);
    w[1] = (f + 1.0f) * (f - 1.0f) * (f - 2.0f) * 0.5f;
    w[2] = -(f + 1.0f) * f * (f - 2.0f) * 0.5f;
    w[3] = (f + 1.0f) * f * (f - 1.0f) * (1.0f / 6.0f);
}

// Adds a far-field grid (GaussianSplat::FarGrid: spacing h pixels, nx nodes per row, node (P, Q)
// at film (h (P - 1), h (Q - 1)); channels g[0..4)) at a tile's lattice nodes (film x0 + s u,
// y0 + s v, nu x nv) to c[0..4), by tensor cubic Lagrange interpolation: along x on the
// grid rows the stencils reach, then along y.
// The grid may be a window of the full one: its node (P0, Q0) first, nx per row.
AIRLIGHT_SIMD_CLONES void add_far_grid(const float* const* g, int h, int nx, int P0, int Q0, int x0, int y0, int s,
                                       int nu, int nv, float* const* c) {
    constexpr int kMax = GaussianSplat::kTile + 1;
    int pu[kMax], qv[kMax];
    float wu[kMax][4], wv[kMax][4];
    for (int u = 0; u < nu; ++u) {
        const int x = x0 + s * u;
        pu[u] = x / h;
        cubic_weights(float(x - pu[u] * h) / float(h), wu[u]);
    }
    for (int v = 0; v < nv; ++v) {
        const int y = y0 + s * v;
        qv[v] = y / h;
        cubic_weights(float(y - qv[v] * h) / float(h), wv[v]);
    }
    const int Qa = qv[0], Qb = qv[nv - 1] + 3;  // grid rows the stencils reach
    float rows[kMax + 3][kMax];
    for (int q = 0; q < 4; ++q) {
        for (int Q = Qa; Q <= Qb; ++Q) {
            const float* r = g[q] + std::size_t(Q - Q0) * nx;
            for (int u = 0; u < nu; ++u) {
                const float* p = r + (pu[u] - P0);
                rows[Q - Qa][u] = wu[u][0] * p[0] + wu[u][1] * p[1] + wu[u][2] * p[2] + wu[u][3] * p[3];
            }
        }
        for (int v = 0; v < nv; ++v) {
            const int o = qv[v] - Qa;
            float* out = c[q] + v * nu;
            for (int u = 0; u < nu; ++u)
                out[u] += wv[v][0] * rows[o][u] + wv[v][1] * rows[o + 1][u] + wv[v][2] * rows[o + 2][u] +
                          wv[v][3] * rows[o + 3][u];
        }
    }
}

// One row of a tile's rays: pixel i looks along A + i B (A, B film vectors, the row's first
// pixel centre and the pixel step), unit direction in double (dd*, the homogeneous term's
// angle to the light needs it near the light's image) and float (d*); t0 = clip / (d . f)
// (0 without near clip) and far = max(Dvp, t0). A loop of its own so that it vectorises
// (it was a fifth of a Gaussian bake's fixed cost as scalar glm code).
// kClip: near clip on (else t0 = 0); a template argument so that the loop has no branch
// and vectorises.
template <bool kClip>
AIRLIGHT_SIMD_CLONES void tile_row_rays(int n, double Ax, double Ay, double Az, double Bx, double By, double Bz,
                                        double fx, double fy, double fz, double clip, const float* __restrict depth,
                                        double* __restrict ddx, double* __restrict ddy, double* __restrict ddz,
                                        float* __restrict dx, float* __restrict dy, float* __restrict dz,
                                        float* __restrict t0, float* __restrict far) {
    for (int i = 0; i < n; ++i) {
        const double X = Ax + double(i) * Bx, Y = Ay + double(i) * By, Z = Az + double(i) * Bz;
        const double inv = 1.0 / std::sqrt(X * X + Y * Y + Z * Z);
        const double x = X * inv, y = Y * inv, z = Z * inv;
        ddx[i] = x;
        ddy[i] = y;
        ddz[i] = z;
        dx[i] = float(x);
        dy[i] = float(y);
        dz[i] = float(z);
        const float tn = kClip ? float(clip / (x * fx + y * fy + z * fz)) : 0.0f;
        t0[i] = tn;
        far[i] = std::max(depth[i], tn);
    }
}

// L0 (3 floats per pixel) += w value, for n pixels.
AIRLIGHT_SIMD_CLONES void add_weighted3(int n, float w0, float w1, float w2, const float* __restrict value,
                                        float* __restrict L0) {
    for (int k = 0; k < n; ++k) {
        L0[3 * k] += w0 * value[k];
        L0[3 * k + 1] += w1 * value[k];
        L0[3 * k + 2] += w2 * value[k];
    }
}

// One row of a tile at reduced resolution into the passes (3 floats per pixel each):
// transmittance Tr, airlight sc max(0, Gaussians) + sg L0 where the segment is not empty.
AIRLIGHT_SIMD_CLONES void write_row_reduced(int n, const float* __restrict far, const float* __restrict t0,
                                            const float* __restrict Tr, const float* __restrict sc,
                                            const float* __restrict sg, const float* __restrict Rf,
                                            const float* __restrict Gf, const float* __restrict Bf,
                                            const float* __restrict Rn, const float* __restrict Gn,
                                            const float* __restrict Bn, const float* __restrict L0,
                                            float* __restrict transmittance, float* __restrict airlight) {
    // The empty segment's 0 as a factor: GCC 12 leaves the loop scalar with a select there
    // (the terms are finite and >= 0, so the factor gives the same values).
    for (int k = 0; k < n; ++k) {
        const float seg = far[k] > t0[k] ? 1.0f : 0.0f;
        airlight[3 * k] = seg * (sc[k] * std::max(0.0f, Rf[k] - Rn[k]) + sg[k] * L0[3 * k]);
        airlight[3 * k + 1] = seg * (sc[k] * std::max(0.0f, Gf[k] - Gn[k]) + sg[k] * L0[3 * k + 1]);
        airlight[3 * k + 2] = seg * (sc[k] * std::max(0.0f, Bf[k] - Bn[k]) + sg[k] * L0[3 * k + 2]);
        transmittance[3 * k] = Tr[k];
        transmittance[3 * k + 1] = Tr[k];
        transmittance[3 * k + 2] = Tr[k];
    }
}

// Per pixel of a tile at reduced resolution: transmittance exp(-(beta0 (far - t0) +
// max(0, Tf - Tn))), the near-point attenuation scale_g = exp(Tn) and scale = scale_g
// exp(beta0 t0) (both 1 without near clip), as splat_tile's double loop, in float.
// The branches are template arguments (a conditional call left the loop scalar).
template <bool kNearClip, bool kBackground>
AIRLIGHT_SIMD_CLONES void finish_float_impl(int n, float beta0, const float* __restrict far,
                                            const float* __restrict t0, const float* __restrict Tf,
                                            const float* __restrict Tn, float* __restrict Tr, float* __restrict sg,
                                            float* __restrict sc) {
    for (int k = 0; k < n; ++k) {
        // beta0 seg: 0 for beta0 = 0 even when seg = inf (background_depth)
        const float bg = kBackground ? beta0 * (far[k] - t0[k]) : 0.0f;
        Tr[k] = fast_expf_le88(-(bg + std::max(0.0f, Tf[k] - Tn[k])));
        const float g = kNearClip ? fast_expf(Tn[k]) : 1.0f;
        sg[k] = g;
        sc[k] = kNearClip ? g * fast_expf(beta0 * t0[k]) : 1.0f;
    }
}

void finish_float(int n, float beta0, bool near_clip, const float* far, const float* t0, const float* Tf,
                  const float* Tn, float* Tr, float* sg, float* sc) {
    const bool bg = beta0 > 0.0f;
    if (near_clip)
        (bg ? finish_float_impl<true, true> : finish_float_impl<true, false>)(n, beta0, far, t0, Tf, Tn, Tr, sg, sc);
    else
        (bg ? finish_float_impl<false, true> : finish_float_impl<false, false>)(n, beta0, far, t0, Tf, Tn, Tr, sg,
                                                                                 sc);
}

// Reduced resolution, a Gaussian the surface cuts (cut_light_factor): adds Tvp times the
// bilinear interpolation of the lattice light factor (FR, FG, FB) at n pixels whose
// projection b^r lies before their surface (tr < far), nothing at the others.
AIRLIGHT_SIMD_CLONES void add_interp_factor(int n, const int* __restrict lat, const float* __restrict wgt, int nu,
                                            const float* __restrict FR, const float* __restrict FG,
                                            const float* __restrict FB, const float* __restrict Tvp,
                                            const float* __restrict tr, const float* __restrict far,
                                            float* __restrict aR, float* __restrict aG, float* __restrict aB) {
    for (int k = 0; k < n; ++k) {
        const int a = lat[k], b = a + 1, c = a + nu, d = c + 1;
        const float w0 = wgt[k], w1 = wgt[kTilePixels + k], w2 = wgt[2 * kTilePixels + k],
                    w3 = wgt[3 * kTilePixels + k];
        const float t = tr[k] < far[k] ? Tvp[k] : 0.0f;
        aR[k] += t * (w0 * FR[a] + w1 * FR[b] + w2 * FR[c] + w3 * FR[d]);
        aG[k] += t * (w0 * FG[a] + w1 * FG[b] + w2 * FG[c] + w3 * FG[d]);
        aB[k] += t * (w0 * FB[a] + w1 * FB[b] + w2 * FB[c] + w3 * FB[d]);
    }
}

// add_interp_factor for n pixels inside one lattice cell (top-left index a).
AIRLIGHT_SIMD_CLONES void add_interp_factor_cell(int n, int a, const float* __restrict wgt, int nu,
                                                 const float* __restrict FR, const float* __restrict FG,
                                                 const float* __restrict FB, const float* __restrict Tvp,
                                                 const float* __restrict tr, const float* __restrict far,
                                                 float* __restrict aR, float* __restrict aG, float* __restrict aB) {
    const int b = a + 1, c = a + nu, d = c + 1;
    const float r0 = FR[a], r1 = FR[b], r2 = FR[c], r3 = FR[d];
    const float g0 = FG[a], g1 = FG[b], g2 = FG[c], g3 = FG[d];
    const float b0 = FB[a], b1 = FB[b], b2 = FB[c], b3 = FB[d];
    for (int k = 0; k < n; ++k) {
        const float w0 = wgt[k], w1 = wgt[kTilePixels + k], w2 = wgt[2 * kTilePixels + k],
                    w3 = wgt[3 * kTilePixels + k];
        const float t = tr[k] < far[k] ? Tvp[k] : 0.0f;
        aR[k] += t * (w0 * r0 + w1 * r1 + w2 * r2 + w3 * r3);
        aG[k] += t * (w0 * g0 + w1 * g1 + w2 * g2 + w3 * g3);
        aB[k] += t * (w0 * b0 + w1 * b1 + w2 * b2 + w3 * b3);
    }
}

// Reduced resolution, a Gaussian the surface cuts (cut_light_factor): t = Tvp exp(-Tvr)
// for the n pixels whose surface lies before b^r (tr >= far), else 0.
AIRLIGHT_SIMD_CLONES void surface_weight(int n, const float* __restrict Tvp, const float* __restrict Tvr,
                                         const float* __restrict tr, const float* __restrict far,
                                         float* __restrict t) {
    for (int k = 0; k < n; ++k) {
        const float v = Tvp[k] * fast_expf_le88(-Tvr[k]);
        t[k] = tr[k] < far[k] ? 0.0f : v;
    }
}

// The number of the n pixels whose b^r lies before the surface (tr < far).
AIRLIGHT_SIMD_CLONES int count_before(int n, const float* __restrict tr, const float* __restrict far) {
    int c = 0;
    for (int k = 0; k < n; ++k) c += tr[k] < far[k] ? 1 : 0;
    return c;
}

// On one 4x4 block (16 pixels, row-major): adds t times the bilinear interpolation of the
// corner pixels' light factors (R4, G4, B4: corners (0,0), (3,0), (0,3), (3,3)).
AIRLIGHT_SIMD_CLONES void add_surface_factor16(const float* __restrict t, const float* __restrict R4,
                                               const float* __restrict G4, const float* __restrict B4,
                                               float* __restrict aR, float* __restrict aG, float* __restrict aB) {
    static constexpr float kU[16] = {0.0f, 1.0f / 3.0f, 2.0f / 3.0f, 1.0f, 0.0f, 1.0f / 3.0f, 2.0f / 3.0f, 1.0f,
                                     0.0f, 1.0f / 3.0f, 2.0f / 3.0f, 1.0f, 0.0f, 1.0f / 3.0f, 2.0f / 3.0f, 1.0f};
    static constexpr float kV[16] = {0.0f,        0.0f,        0.0f,        0.0f,        1.0f / 3.0f, 1.0f / 3.0f,
                                     1.0f / 3.0f, 1.0f / 3.0f, 2.0f / 3.0f, 2.0f / 3.0f, 2.0f / 3.0f, 2.0f / 3.0f,
                                     1.0f,        1.0f,        1.0f,        1.0f};
    const float r0 = R4[0], r1 = R4[1], r2 = R4[2], r3 = R4[3];
    const float g0 = G4[0], g1 = G4[1], g2 = G4[2], g3 = G4[3];
    const float b0 = B4[0], b1 = B4[1], b2 = B4[2], b3 = B4[3];
    for (int k = 0; k < 16; ++k) {
        const float u = kU[k], v = kV[k];
        const float w0 = (1.0f - u) * (1.0f - v), w1 = u * (1.0f - v), w2 = (1.0f - u) * v, w3 = u * v;
        aR[k] += t[k] * (w0 * r0 + w1 * r1 + w2 * r2 + w3 * r3);
        aG[k] += t[k] * (w0 * g0 + w1 * g1 + w2 * g2 + w3 * g3);
        aB[k] += t[k] * (w0 * b0 + w1 * b1 + w2 * b2 + w3 * b3);
    }
}

AIRLIGHT_SIMD_CLONES void add_to(const float* __restrict x, int n, float* __restrict acc) {
    for (int k = 0; k < n; ++k) acc[k] += x[k];
}

// T(from_row, b_i) without Gaussian i (beta0 included) for row 0 = the eye and rows 1..L
// = the lights, all Gaussians: out[row n + i].
std::vector<double> depths_to_centres(const GaussianMedium& m, const Vec3& eye, const std::vector<Vec3>& lights,
                                      int threads) {
    const std::size_t n = m.size();
    std::vector<Vec3> src{eye};
    src.insert(src.end(), lights.begin(), lights.end());
    std::vector<double> out = gaussian_depths_to_centres(m, src, 0, n, 0, n, threads);
    for (std::size_t row = 0; row < src.size(); ++row)
        for (std::size_t i = 0; i < n; ++i)
            out[row * n + i] += background_depth(m.beta0(), glm::length(m.centre(i) - src[row]));
    return out;
}

}  // namespace

namespace {
// The pair list's memory (bin_index_) kept from one GaussianSplat to the next: the bake builds
// a new one per frame, and fresh pages cost ~10-20 us per 4 KiB fault here (bake.h's image
// pool): ~20 ms of CPU for the 8.5 MB list of 3000 Gaussians at 1080p, in bin()'s serial
// part. One buffer of at most kPairPoolBytes is kept (the largest handed back).
constexpr std::size_t kPairPoolBytes = std::size_t(64) << 20;
struct PairPool {
    std::mutex mutex;
    std::vector<std::uint32_t> spare;
};
PairPool& pair_pool() {
    static PairPool pool;
    return pool;
}
}  // namespace

GaussianSplat::~GaussianSplat() {
    if (bin_index_.capacity() * sizeof(std::uint32_t) > kPairPoolBytes) return;
    PairPool& pool = pair_pool();
    std::lock_guard<std::mutex> lock(pool.mutex);
    if (bin_index_.capacity() > pool.spare.capacity()) pool.spare.swap(bin_index_);
}

void validate_noise(const GaussianNoise& noise) {
    if (!std::isfinite(noise.amplitude) || noise.amplitude < 0.0) {
        std::ostringstream os;
        os << "noise amplitude must be finite and >= 0, got " << noise.amplitude;
        throw std::invalid_argument(os.str());
    }
    if (!std::isfinite(noise.scale) || !(noise.scale > 0.0)) {
        std::ostringstream os;
        os << "noise scale must be finite and > 0 (m), got " << noise.scale;
        throw std::invalid_argument(os.str());
    }
    if (!std::isfinite(noise.offset.x) || !std::isfinite(noise.offset.y) || !std::isfinite(noise.offset.z))
        throw std::invalid_argument("noise offset must be finite");
}

GaussianSplat::GaussianSplat(const GaussianMedium& medium, const Vec3& eye, const std::vector<Vec3>& lights,
                   const std::vector<RGB>& I0, const RGB& medium_albedo, const std::vector<double>& albedo,
                   const SpecialFTable* table, const GaussianNoise& noise, int threads, const GaussianSplatLights* extra)
    : medium_(medium),
      table_(table),
      eye_(eye),
      lights_(lights),
      I0_(I0),
      medium_albedo_(medium_albedo),
      noise_(noise),
      threads_(threads) {
    validate_noise(noise);
    const std::size_t n = medium.size(), L = lights.size();
    if (I0.size() != L) throw std::invalid_argument("RbfSplat: one I0 per light expected");
    if (!albedo.empty() && albedo.size() != 3 * n) {
        std::ostringstream os;
        os << "gaussians: albedo has " << albedo.size() << " values, expected 3 per Gaussian (" << 3 * n << ")";
        throw std::invalid_argument(os.str());
    }
    for (double x : albedo)
        if (!std::isfinite(x) || x < 0.0) throw std::invalid_argument("gaussians: albedo must be finite and >= 0");
    albedo_.resize(3 * n);
    for (std::size_t i = 0; i < n; ++i)
        for (int c = 0; c < 3; ++c) albedo_[3 * i + c] = albedo.empty() ? medium_albedo[c] : albedo[3 * i + c];
    for (std::size_t l = 0; l < L; ++l) weight0_.push_back(medium_albedo * I0[l]);
    eye_f_[0] = float(eye.x);
    eye_f_[1] = float(eye.y);
    eye_f_[2] = float(eye.z);
    // C_sv and D_sv per light (exact, a few rays); f1 with Gaussian i's own terms removed,
    // exp(-T(s, b_i) - T(v, b_i)) without i, in float (fast_erf.h).
    for (const Vec3& s : lights) {
        const Vec3 d = eye - s;
        const double D = glm::length(d);
        Dsv_.push_back(D);
        Csv_.push_back(D > 0.0 ? std::exp(-medium.optical_depth_ray(s, d / D, D, GaussianMedium::npos, false)) : 1.0);
    }
    const std::size_t S = extra ? extra->sun_w.size() : 0;
    if (extra) {
        if ((!extra->spot.empty() && (extra->spot.size() != L || extra->cone.size() != L)) ||
            (!extra->custom_background.empty() && extra->custom_background.size() != L) ||
            extra->sun_E.size() != S)
            throw std::invalid_argument("RbfSplat: spot, cone and custom_background need one entry per point light, "
                                        "sun_E one per sun");
        for (const Vec3& w : extra->sun_w)
            if (!std::isfinite(w.x) || !std::isfinite(w.y) || !std::isfinite(w.z) ||
                std::abs(glm::length(w) - 1.0) > 1e-6)
                throw std::invalid_argument("RbfSplat: sun directions must be finite unit vectors");
        const bool any_custom = std::find(extra->custom_background.begin(), extra->custom_background.end(), 1) !=
                                extra->custom_background.end();
        if ((S > 0 || any_custom) && !extra->background)
            throw std::invalid_argument("RbfSplat: suns and custom backgrounds need a background function");
        extra_ = *extra;
        plain_ = phase_is_isotropic(extra->phase) && S == 0 &&
                 std::find(extra->spot.begin(), extra->spot.end(), 1) == extra->spot.end();
        if (!phase_is_isotropic(extra->phase) && !any_custom && L > 0)
            throw std::invalid_argument("RbfSplat: a non-isotropic phase needs a custom background for every light");
    }
    const std::vector<double> depth =
        L + S > 0 ? depths_to_centres(medium, eye, lights, threads) : std::vector<double>();
    g_.resize(n);
    gl_.resize(n * L);
    for (std::size_t i = 0; i < n; ++i) {
        const Vec3 rel = medium.centre(i) - eye;
        const double a = medium.scale(i), c = medium.amplitude(i);
        const double dist = glm::length(rel);
        GaussF& g = g_[i];
        g.rx = float(rel.x);
        g.ry = float(rel.y);
        g.rz = float(rel.z);
        g.a = float(a);
        g.a2 = float(a * a);
        g.k0 = float(c * kSqrtPi / (2.0 * a));
        g.ke = float(c * kSqrtPi / (2.0 * a) * std::exp(-a * a * dist * dist));
        g.nscale = dist > 0.0 ? float(noise.amplitude * medium.cull_radius(i) / dist) : 0.0f;
        g.near = false;
        g.dist = dist;
        g.radius = medium.cull_radius(i);
        for (std::size_t l = 0; l < L; ++l) {
            const Vec3 bs = medium.centre(i) - lights[l];
            const double f1 = std::exp(-depth[i] - depth[(l + 1) * n + i]) * kInv4Pi;
            GaussLightF& q = gl_[i * L + l];
            q.sx = float(bs.x);
            q.sy = float(bs.y);
            q.sz = float(bs.z);
            q.wr = float(albedo_[3 * i] * I0[l].x * f1);
            q.wg = float(albedo_[3 * i + 1] * I0[l].y * f1);
            q.wb = float(albedo_[3 * i + 2] * I0[l].z * f1);
            q.ke = float(c * kSqrtPi / (2.0 * a) * std::exp(-a * a * glm::dot(bs, bs)));
        }
    }
    for (std::size_t l = 0; l < L; ++l) {
        const Vec3 vs = eye - lights[l];
        lf_.push_back({float(vs.x), float(vs.y), float(vs.z)});
        if (extra && !extra->spot.empty() && extra->spot[l]) {
            const SpotCone& c = extra->cone[l];
            lf_[l].ax = float(c.axis.x);
            lf_[l].ay = float(c.axis.y);
            lf_[l].az = float(c.axis.z);
            lf_[l].cos_half = float(c.cos_half_angle);
            lf_[l].smooth = float(c.smooth);
        }
    }
    // Suns: f1 = exp(-T_sun(b_i) - T(v, b_i)) without Gaussian i (culled half-line depths in
    // float, gaussian_sun_depths) and C = the Gaussians' transmittance from the eye towards the sun.
    gs_.resize(n * S);
    for (std::size_t j = 0; j < S; ++j) {
        const Vec3 u = -extra->sun_w[j];  // towards the sun
        const double mu_s = u.z;
        Csun_.push_back(std::exp(-medium.optical_depth_ray(eye, u, std::numeric_limits<double>::infinity(),
                                                           GaussianMedium::npos, false)));
        const RGB E = extra->sun_E[j];
        const std::vector<double> Tg = gaussian_sun_depths(medium, u, threads);
        parallel_chunks(n, threads, 64, [&](std::size_t b, std::size_t e) {
            for (std::size_t i = b; i < e; ++i) {
                const Vec3 c = medium.centre(i);
                const double Tsun = Tg[i] + sunlight_layer_depth(medium.beta0(), extra->fog_top, mu_s, c.z);
                const double f1 = std::isinf(Tsun) ? 0.0 : std::exp(-depth[i] - Tsun) * kInv4Pi;
                GaussLightF& q = gs_[i * S + j];
                q.sx = q.sy = q.sz = 0.0f;
                q.wr = float(albedo_[3 * i] * E.x * f1);
                q.wg = float(albedo_[3 * i + 1] * E.y * f1);
                q.wb = float(albedo_[3 * i + 2] * E.z * f1);
                q.ke = 0.0f;
            }
        });
    }
}

double sunlight_layer_depth(double beta0, double h_top, double mu_s, double z) {
    if (!(beta0 > 0.0) || std::isinf(h_top)) return 0.0;
    if (mu_s > 0.0) return beta0 * std::max(0.0, h_top - z) / mu_s;
    if (mu_s == 0.0 && z > h_top) return 0.0;  // horizontal above the layer
    return std::numeric_limits<double>::infinity();
}

void GaussianSplat::bin(const Vec3& D0, const Vec3& Dx, const Vec3& Dy, const Vec3& forward, int W, int H,
                   double clip_start, int step, const float* depth) {
    if (step != 1 && step != 2 && step != 4) {
        std::ostringstream os;
        os << "Gaussian resolution step must be 1 (full), 2 (half) or 4 (quarter), got " << step;
        throw std::invalid_argument(os.str());
    }
    step_ = step;
    // Cull spheres (gaussian_medium.h: outside R_i a ray's T_i < eps): the medium's cull_eps at full
    // resolution (the reference path); at reduced resolution eps = kReducedCullEps (at least
    // the medium's), tied to the lattice's own error: with the default 1e-7, a quarter of the
    // tile-Gaussian pairs held terms below 1e-5 (see gaussian_splat.h).
    const double eps_cull =
        step == 1 ? medium_.cull_eps() : std::max(medium_.cull_eps(), kReducedCullEps[step / 2 - 1]);
    for (std::size_t i = 0; i < g_.size(); ++i) {
        const double R = step == 1 ? medium_.cull_radius(i)
                                   : GaussianMedium::cull_radius_for(medium_.amplitude(i), medium_.scale(i), eps_cull);
        g_[i].radius = R;
        // far_eye, far_lights (GaussF): a sqrt(D^2 - R^2) >= kFarStart for the eye and every
        // point light (plain path only: the extended light kernels keep both erfc terms).
        const double a = medium_.scale(i);
        auto far_from = [&](const Vec3& p) {
            const double D = glm::length(medium_.centre(i) - p);
            return D > R && a * std::sqrt(D * D - R * R) >= kFarStart;
        };
        g_[i].far_eye = far_from(eye_);
        bool lights_far = plain_;
        for (const Vec3& s : lights_) lights_far = lights_far && far_from(s);
        g_[i].far_lights = lights_far;
    }
    n_lattice_ = 0;
    n_coarse_ = 0;
    n_fine_ = 0;
    n_far_ = 0;
    n_cancelled_ = 0;
    n_exact_ = 0;
    n_behind_ = 0;
    W_ = W;
    H_ = H;
    D0_ = D0;
    Dx_ = Dx;
    Dy_ = Dy;
    forward_ = forward;
    clip_start_ = clip_start;
    tiles_x_ = (W + kTile - 1) / kTile;
    tiles_y_ = (H + kTile - 1) / kTile;
    const int n_tiles = tiles_x_ * tiles_y_;
    // Farthest near point: clip_start / cos(angle to the view axis), largest at a corner.
    double t0_max = 0.0;
    if (clip_start > 0.0)
        for (double px : {0.0, double(W)})
            for (double py : {0.0, double(H)}) {
                const Vec3 D = D0 + px * Dx + py * Dy;
                const double cosv = glm::dot(D, forward) / glm::length(D);
                t0_max = std::max(t0_max, cosv > 0.0 ? clip_start / cosv : std::numeric_limits<double>::infinity());
            }
    // (lambda, mu, nu) = Q (X - eye) with X - eye = lambda D0 + mu Dx + nu Dy: px = mu / lambda.
    const glm::dmat3 M(D0, Dx, Dy);
    const glm::dmat3 Qt = glm::transpose(glm::inverse(M));  // columns = rows of Q
    const Vec3 q0 = Qt[0], q1 = Qt[1], q2 = Qt[2];
    q0_ = q0;
    q1_ = q1;
    q2_ = q2;
    const std::size_t n = medium_.size();
    std::vector<int> rect(4 * n);  // tile range x0, x1, y0, y1 (x1 < x0: none)
    std::vector<std::uint32_t> count(n_tiles + 1, 0);
    // Each tile's cone of rays: unit axis through its centre, cos and sin of the largest
    // angle to its corner rays. A ball of angular radius rho around direction u can meet
    // the tile's rays only if angle(axis, u) <= theta + rho: cuts the bounding boxes'
    // corners and the tile rounding.
    struct Cone {
        Vec3 axis;
        double cos_t, sin_t;
    };
    std::vector<Cone> cones(n_tiles);
    // (the per-tile and per-Gaussian work below runs on threads_ threads: parallel_chunks)
    parallel_chunks(std::size_t(n_tiles), threads_, 256, [&](std::size_t tb, std::size_t te) {
        for (std::size_t tt = tb; tt < te; ++tt) {
            const int tx = int(tt) % tiles_x_, ty = int(tt) / tiles_x_;
            const double x0 = tx * kTile, x1 = std::min(W, (tx + 1) * kTile);
            const double y0 = ty * kTile, y1 = std::min(H, (ty + 1) * kTile);
            Cone& c = cones[ty * tiles_x_ + tx];
            c.axis = glm::normalize(D0 + 0.5 * (x0 + x1) * Dx + 0.5 * (y0 + y1) * Dy);
            double cmin = 1.0;
            for (double px : {x0, x1})
                for (double py : {y0, y1})
                    cmin = std::min(cmin, glm::dot(c.axis, glm::normalize(D0 + px * Dx + py * Dy)));
            cmin = std::clamp(cmin - 1e-9, -1.0, 1.0);  // rounding margin
            c.cos_t = cmin;
            c.sin_t = std::sqrt(std::max(0.0, 1.0 - cmin * cmin));
        }
    });
    // Reduced resolution: per (tile, light), bounds on the light factor's distance |b^r - s|
    // over the tile's rays (light_clear); tiles where some Gaussian could come closer to a
    // light than the lattice allows are flagged (exact_tile_: their Gaussians are checked
    // one by one in splat_tile_reduced, and their edge samples skip the lattice).
    exact_tile_.assign(step > 1 ? n_tiles : 0, 0);
    const std::size_t L = lights_.size();
    tile_light_.assign(step > 1 ? std::size_t(n_tiles) * L : 0, TileLight{});
    light_min_ = 0.0;
    if (step > 1) {
        // The lattice's light-factor criterion at spacing s (see bin()'s smooth_): |b^r - s|
        // >= light_min_ d_i, d_i the Gaussian's distance from the eye.
        const double f = glm::dot(D0, forward);
        const double pix = f > 0.0 ? std::max(glm::length(Dx), glm::length(Dy)) / f : 0.0;
        const double tau = 1e-3 * (step / 4.0) * (step / 4.0);
        light_min_ = step * std::sqrt(6.0 / (8.0 * tau)) * pix;
        double dist_max = 0.0;
        for (const GaussF& g : g_) dist_max = std::max(dist_max, g.dist);
        for (int t = 0; t < n_tiles; ++t) {
            const double half = std::acos(std::clamp(cones[t].cos_t, -1.0, 1.0));
            for (std::size_t l = 0; l < L; ++l) {
                TileLight& tl = tile_light_[std::size_t(t) * L + l];
                const Vec3 u = lights_[l] - eye_;
                const double D = glm::length(u);
                if (!(D > 0.0)) {  // a light at the eye: no bound
                    tl = TileLight{0.0f, 0.0f, 1.0f};
                    exact_tile_[t] = 1;
                    continue;
                }
                const double c = std::acos(std::clamp(glm::dot(cones[t].axis, u / D), -1.0, 1.0));
                const double a_min = std::max(0.0, c - half - 1e-9), a_max = c + half + 1e-9;
                // The ray's closest approach to s: D sin(angle), or D (the eye) past 90 degrees.
                tl.h_min = float((a_min >= 0.5 * kPi ? D : D * std::sin(a_min)) * (1.0 - 1e-6));
                if (a_max < 0.5 * kPi) tl.cos_max = float(std::cos(a_max)), tl.sin_max = float(std::sin(a_max));
                else tl.cos_max = 0.0f, tl.sin_max = 1.0f;
                if (double(tl.h_min) < light_min_ * dist_max) exact_tile_[t] = 1;
            }
        }
    }
    // Ball i (centre direction u, sin and cos of its angular radius) against tile t.
    // The tiles' cones in structure-of-arrays form for cone_hits (ball i against tile t).
    std::vector<double> cone_x(n_tiles), cone_y(n_tiles), cone_z(n_tiles), cone_c(n_tiles), cone_s(n_tiles);
    for (int t = 0; t < n_tiles; ++t) {
        cone_x[t] = cones[t].axis.x;
        cone_y[t] = cones[t].axis.y;
        cone_z[t] = cones[t].axis.z;
        cone_c[t] = cones[t].cos_t;
        cone_s[t] = cones[t].sin_t;
    }
    // Film-coordinate interval of the ball (c, R) along axis q: the two planes through
    // the eye with normal q - p q0 tangent to the ball. False: the ball reaches the plane
    // lambda = 0 (no finite bounds).
    auto interval = [&](const Vec3& c, double R, const Vec3& q, double& lo, double& hi) {
        const double A = glm::dot(q, c), B = glm::dot(q0, c);
        const double R2 = R * R;
        const double alpha = B * B - R2 * glm::dot(q0, q0);
        if (!(alpha > 1e-9 * B * B) || B <= 0.0) return false;
        const double beta = A * B - R2 * glm::dot(q0, q);
        const double gamma = A * A - R2 * glm::dot(q, q);
        const double disc = std::max(0.0, beta * beta - alpha * gamma);
        const double s = std::sqrt(disc);
        lo = (beta - s) / alpha;
        hi = (beta + s) / alpha;
        return std::isfinite(lo) && std::isfinite(hi);
    };
    // Per Gaussian: its tile rectangle and cone-test ball (direction u, sin and cos of its
    // angular radius; inside: the eye is in the ball, every tile of the rectangle).
    struct Ball {
        Vec3 u{0.0};
        double sin_r = 1.0, cos_r = 0.0;
        bool inside = true;
    };
    std::vector<Ball> balls(n);
    parallel_chunks(n, threads_, 256, [&](std::size_t ib, std::size_t ie) {
        for (std::size_t i = ib; i < ie; ++i) {
            int* r = &rect[4 * i];
            r[0] = 0;
            r[1] = -1;
            r[2] = 0;
            r[3] = -1;
            const double R = g_[i].radius;
            if (!(R > 0.0) || medium_.amplitude(i) == 0.0) continue;
            const Vec3 c = medium_.centre(i) - eye_;
            const double dist = glm::length(c);
            g_[i].near = clip_start > 0.0 && dist < R + t0_max;
            // Entirely behind the eye: no ray from the eye meets it.
            if (glm::dot(q0, c) + R * glm::length(q0) < 0.0) continue;
            double x_lo, x_hi, y_lo, y_hi;
            int tx0 = 0, tx1 = tiles_x_ - 1, ty0 = 0, ty1 = tiles_y_ - 1;
            if (interval(c, R, q1, x_lo, x_hi) && interval(c, R, q2, y_lo, y_hi)) {
                // Pixels whose centres (i + 0.5) lie in the interval, one pixel of margin.
                const double px0 = std::floor(x_lo - 0.5) - 1.0, px1 = std::ceil(x_hi - 0.5) + 1.0;
                const double py0 = std::floor(y_lo - 0.5) - 1.0, py1 = std::ceil(y_hi - 0.5) + 1.0;
                if (px1 < 0.0 || py1 < 0.0 || px0 > W - 1 || py0 > H - 1) continue;
                tx0 = int(std::max(0.0, px0)) / kTile;
                tx1 = int(std::min(double(W - 1), px1)) / kTile;
                ty0 = int(std::max(0.0, py0)) / kTile;
                ty1 = int(std::min(double(H - 1), py1)) / kTile;
            }
            r[0] = tx0;
            r[1] = tx1;
            r[2] = ty0;
            r[3] = ty1;
            // Cone test inside the rectangle (all tiles if the eye is inside the ball).
            Ball& ball = balls[i];
            ball.inside = dist <= R * (1.0 + 1e-9);
            ball.u = ball.inside ? Vec3(0.0) : c / dist;
            ball.sin_r = ball.inside ? 1.0 : R / dist;
            ball.cos_r = ball.inside ? 0.0 : std::sqrt(1.0 - ball.sin_r * ball.sin_r);
        }
    });
    // Counts per tile, then the lists, by tile rows in parallel (each row's tiles list their
    // Gaussians in index order, as a serial pass over the Gaussians would). The fill also
    // counts each far-field candidate's tiles in front / behind / cut (far_candidates).
    FarScratch far;  // far.counts allocated: there are far-field candidates
    auto rows = [&](bool fill_lists, std::uint32_t* fill) {
        parallel_chunks(std::size_t(tiles_y_), threads_, 1, [&](std::size_t yb, std::size_t ye) {
            std::vector<unsigned char> hit(std::size_t(tiles_x_), 1);
            for (int ty = int(yb); ty < int(ye); ++ty)
                for (std::size_t i = 0; i < n; ++i) {
                    const int* r = &rect[4 * i];
                    if (r[1] < r[0] || ty < r[2] || ty > r[3]) continue;
                    const Ball& ball = balls[i];
                    const int t0 = ty * tiles_x_ + r[0], m = r[1] - r[0] + 1;
                    if (ball.inside) std::fill(hit.begin(), hit.begin() + m, 1);
                    else
                        cone_hits(m, &cone_x[t0], &cone_y[t0], &cone_z[t0], &cone_c[t0], &cone_s[t0], ball.u.x,
                                  ball.u.y, ball.u.z, ball.sin_r, ball.cos_r, hit.data());
                    if (fill_lists) {
                        for (int k = 0; k < m; ++k)
                            if (hit[k]) bin_index_[fill[t0 + k]++] = std::uint32_t(i);
                        if (far.counts && far.cand[i]) {
                            const float lo = far.span[2 * i], hi = far.span[2 * i + 1];
                            std::uint32_t c[3] = {0, 0, 0};
                            for (int k = 0; k < m; ++k)
                                if (hit[k])
                                    ++c[hi <= far.tmin[t0 + k] ? 0 : (lo >= far.tmax[t0 + k] ? 1 : 2)];
                            for (int q = 0; q < 3; ++q)
                                if (c[q]) far.counts[3 * i + q].fetch_add(c[q], std::memory_order_relaxed);
                        }
                    } else {
                        for (int k = 0; k < m; ++k) count[t0 + k + 1] += hit[k];
                    }
                }
        });
    };
    rows(false, nullptr);
    // Coarse-lattice Gaussians (see splat_tile): H = 2 step pixels, tau = 1e-3 at quarter
    // resolution and 1e-3 / 4 at half (which errs ~4x less than quarter: keeps that); pix =
    // the largest angle of a pixel (at the film point nearest the eye: |Dx| / (D0 . forward)).
    smooth_.assign(step > 1 ? n : 0, 0);
    light_far_.assign(step > 1 ? n : 0, 0);
    if (step > 1) {
        const double f = glm::dot(D0, forward);
        const double pix = f > 0.0 ? std::max(glm::length(Dx), glm::length(Dy)) / f : 0.0;
        const double H = 2.0 * step, tau = 1e-3 * (step / 4.0) * (step / 4.0);
        const double sigma_min = H / (2.0 * std::sqrt(tau)) * pix;      // angle
        const double light_min = H * std::sqrt(6.0 / (8.0 * tau)) * pix;  // |b - s| - R per unit d
        for (std::size_t i = 0; i < n && pix > 0.0; ++i) {
            const double dist = std::max(g_[i].dist, 1e-12), a = medium_.scale(i);
            double clearance = std::numeric_limits<double>::infinity();  // least |b - s| - R over the lights
            for (const Vec3& s : lights_) clearance = std::min(clearance, glm::length(medium_.centre(i) - s) - g_[i].radius);
            // 2: everywhere; 1: where the tile's rays keep b^r far enough from the lights
            // (light_clear with factor H / s = 2: a light's image far from the tile).
            const bool wide = 1.0 / (std::sqrt(2.0) * a * dist) >= sigma_min;
            smooth_[i] = !wide ? 0 : (clearance >= light_min * dist ? 2 : 1);
            // The same light criterion on the lattice itself (step s, half of H: light_min_):
            // every b^r of the Gaussian's rays stays that far from every light, so its light
            // factor 1 / |b^r - s|^2 interpolates to tau over a lattice cell.
            light_far_[i] = clearance >= light_min_ * dist;
        }
    }
    for (int t = 0; t < n_tiles; ++t) count[t + 1] += count[t];
    bin_start_ = count;
    {
        // The pooled list when it holds these pairs (pair_pool; a later bin() of this
        // GaussianSplat keeps its own).
        PairPool& pool = pair_pool();
        std::lock_guard<std::mutex> lock(pool.mutex);
        if (bin_index_.capacity() < count[n_tiles] && pool.spare.capacity() >= count[n_tiles])
            bin_index_.swap(pool.spare);
    }
    bin_index_.resize(count[n_tiles]);
    std::vector<std::uint32_t> fill(count.begin(), count.end() - 1);
    const bool far_field = far_candidates(depth, rect, far);
    rows(true, fill.data());
    if (far_field) build_far_field(rect, far);
}

bool GaussianSplat::far_candidates(const float* depth, const std::vector<int>& rect, FarScratch& far) {
    const std::size_t n = g_.size();
    const int n_tiles = num_tiles();
    far_grids_.clear();
    level_.assign(step_ > 1 ? n : 0, 0);
    tile_far_.assign(step_ > 1 ? std::size_t(n_tiles) : 0, 0);
    tile_far_pairs_.clear();
    splat_end_.clear();
    far_gaussians_ = far_nodes_ = 0;
    if (step_ == 1 || !depth || !plain_ || noise_.on() || n == 0) return false;
    const double f = glm::dot(D0_, forward_);
    const double pix = f > 0.0 ? std::max(glm::length(Dx_), glm::length(Dy_)) / f : 0.0;
    if (!(pix > 0.0)) return false;
    // The level criteria (gaussian_splat.h): the cubic's error at the lattice's tau at quarter
    // resolution; at half a quarter of the lattice's (1e-3 / 16), so that half keeps its max
    // error against full at 0.1 % (bench_rbf.py's transmittance: 0.099 %; 0.101 % at 1e-3 / 8,
    // 0.109 % at the lattice's 1e-3 / 4).
    const double tau = step_ == 4 ? 1e-3 : 1e-3 / 16.0;
    const double cv = 0.28 * std::pow(tau / 1e-3, 0.25), cl = 6.0 * std::pow(1e-3 / tau, 0.25);
    const double q0_len = glm::length(q0_);
    std::vector<unsigned char>& cand = far.cand;
    cand.assign(n, 0);
    bool any = false;
    for (std::size_t i = 0; i < n; ++i) {
        const GaussF& g = g_[i];
        if (!light_far_[i] || g.near || !(g.radius > 0.0) || medium_.amplitude(i) == 0.0) continue;
        const int* r = &rect[4 * i];
        if (r[1] < r[0] || r[3] < r[2]) continue;
        const Vec3 c = medium_.centre(i) - eye_;
        if (!(glm::dot(q0_, c) > g.radius * q0_len * (1.0 + 1e-6))) continue;  // wholly before the eye's plane
        // (exp(-T_i(v, b^r)) on the light side adds a narrower bump of relative size k0 = half
        // the peak optical depth: the cubic's error grows by ~(1 + 4 k0), as from sigma / (1 + k0))
        const double sigma = 1.0 / (std::sqrt(2.0) * medium_.scale(i) * g.dist) / (1.0 + double(g.k0));
        double clearance = std::numeric_limits<double>::infinity();
        for (const Vec3& s : lights_) clearance = std::min(clearance, glm::length(medium_.centre(i) - s) - g.radius);
        for (int k = kMaxFarLevel; k >= 1; --k) {
            const double hw = double(step_ * kFarSpacing[k - 1]) * pix;
            if (hw <= cv * sigma && clearance >= cl * hw * g.dist) {
                cand[i] = (unsigned char)k;
                any = true;
                break;
            }
        }
    }
    if (!any) return false;
    // Each tile's depth range, and per candidate its depth interval, for the fill's counts of
    // its tiles in front / behind / cut (splat_tile_reduced's test by depth range; a cost
    // estimate only).
    std::vector<float>&tmin = far.tmin, &tmax = far.tmax;
    tmin.resize(n_tiles);
    tmax.resize(n_tiles);
    parallel_chunks(std::size_t(n_tiles), threads_, 64, [&](std::size_t tb, std::size_t te) {
        for (std::size_t t = tb; t < te; ++t) {
            const int x0 = int(t) % tiles_x_ * kTile, y0 = int(t) / tiles_x_ * kTile;
            const int x1 = std::min(W_, x0 + kTile), y1 = std::min(H_, y0 + kTile);
            float lo = std::numeric_limits<float>::infinity(), hi = 0.0f;
            for (int j = y0; j < y1; ++j)
                for (int i = x0; i < x1; ++i) {
                    const float d = depth[std::size_t(j) * W_ + i];
                    lo = std::min(lo, d);
                    hi = std::max(hi, d);
                }
            tmin[t] = lo;
            tmax[t] = hi;
        }
    });
    far.span.assign(2 * n, 0.0f);
    for (std::size_t i = 0; i < n; ++i)
        if (cand[i]) {
            far.span[2 * i] = float(g_[i].dist - g_[i].radius);
            far.span[2 * i + 1] = float(g_[i].dist + g_[i].radius);
        }
    far.counts.reset(new std::atomic<std::uint32_t>[3 * n]());
    return true;
}

void GaussianSplat::build_far_field(const std::vector<int>& rect, FarScratch& far) {
    const std::size_t n = g_.size();
    const int n_tiles = num_tiles();
    const std::vector<unsigned char>& cand = far.cand;
    const std::vector<float>& tmin = far.tmin;
    // Grid sizes: the tile lattices' nodes lie at film x in [0, kTile tiles_x_], whose cubic
    // stencils reach nodes P = x / h .. x / h + 3.
    auto grid_dims = [&](int k, int& h, int& nx, int& ny) {
        h = step_ * kFarSpacing[k - 1];
        nx = kTile * tiles_x_ / h + 5;
        ny = kTile * tiles_y_ / h + 5;
    };
    // Node rectangle of Gaussian i at level k: the stencils of its tile rectangle's lattices
    // (it is evaluated on the blocks of it whose rays meet its cull cone, below).
    auto node_range = [&](std::size_t i, int k, int& P0, int& P1, int& Q0, int& Q1) {
        int h, nx, ny;
        grid_dims(k, h, nx, ny);
        const int* r = &rect[4 * i];
        P0 = kTile * r[0] / h;
        P1 = std::min(nx - 1, kTile * (r[1] + 1) / h + 3);
        Q0 = kTile * r[2] / h;
        Q1 = std::min(ny - 1, kTile * (r[3] + 1) / h + 3);
    };
    std::vector<std::uint32_t> far_list;
    unsigned used = 0;
    double saved = 0.0;
    for (std::size_t i = 0; i < n; ++i) {
        if (!cand[i]) continue;
        const std::size_t front = far.counts[3 * i], behind = far.counts[3 * i + 1], cut = far.counts[3 * i + 2];
        int P0, P1, Q0, Q1;
        node_range(i, cand[i], P0, P1, Q0, Q1);
        // Evaluations: the grid's nodes near the cone (~0.8 of the rectangle), and a
        // share where tiles using the grid cancel it (behind) or replace it (cut), against
        // the lattice (or coarse lattice) of each tile it lies in front of.
        const double global = 0.8 * double(P1 - P0 + 1) * double(Q1 - Q0 + 1) + 8.0 * double(behind + cut);
        const double local = double(front) * double(lattice_evals(i));
        if (global < local) {
            level_[i] = cand[i];
            used |= 1u << (cand[i] - 1);
            far_list.push_back(std::uint32_t(i));
            saved += local - global;
        }
    }
    // Not worth the grids' fixed costs (their nodes' directions, the blocks' lists, a pass
    // over the tiles; ~1 ms) below ~1e5 evaluations saved (~0.3 ms).
    if (saved < 1e5) {
        std::fill(level_.begin(), level_.end(), 0);
        return;
    }
    // Per tile: which grids it reads (they save more evaluations than cancelling costs: its
    // Gaussians of that level wholly in front, by the depth range, cost nothing there; each
    // one wholly behind costs its share, ~36 nodes at quarter, to cancel, as does each one
    // the surface cuts, to replace it by its exact terms on the blocks it cuts). The pairs
    // wholly in front on a grid the tile reads then move to the end of its list, past
    // splat_end_: the splat does not walk them (at 3000 x 1, ~1.3 M of its ~2.1 M pairs).
    // eval_rays still gathers from the whole list: an edge sub-sample may end nearer.
    // (the pass reads all the pairs, ~2.1 M at 3000 x 1: per Gaussian its far reach and
    // evaluations in compact arrays, integer sums)
    tile_far_pairs_.assign(std::size_t(n_tiles), 0);
    splat_end_.assign(bin_start_.begin() + 1, bin_start_.end());
    std::vector<double> reach(n, 0.0);
    std::vector<std::uint32_t> lattice_cost(n, 0);
    for (std::uint32_t i : far_list) {
        reach[i] = g_[i].dist + g_[i].radius;
        lattice_cost[i] = std::uint32_t(lattice_evals(i));
    }
    parallel_chunks(std::size_t(n_tiles), threads_, 256, [&](std::size_t tb, std::size_t te) {
        std::vector<std::uint32_t> moved;
        for (std::size_t t = tb; t < te; ++t) {
            const std::uint32_t e0 = bin_start_[t], e1 = bin_start_[t + 1];
            const double far_lo = double(tmin[t]) * (1.0 - 1e-6);  // as splat_tile_reduced's
            auto front = [&](std::size_t i) { return reach[i] <= far_lo; };
            std::uint32_t save[kMaxFarLevel] = {}, spend[kMaxFarLevel] = {};
            unsigned bits = 0, pairs = 0;
            for (std::uint32_t e = e0; e < e1; ++e) {
                const std::size_t i = bin_index_[e];
                if (!level_[i]) continue;
                const int k = level_[i] - 1;
                bits |= 1u << k;
                ++pairs;
                if (front(i)) save[k] += lattice_cost[i];
                else spend[k] += 36;
            }
            unsigned use = 0;
            for (int k = 0; k < kMaxFarLevel; ++k)
                if ((bits >> k & 1u) && save[k] > spend[k] + 25) use |= 1u << k;
            tile_far_[t] = std::uint16_t(use);
            tile_far_pairs_[t] = pairs;
            if (use == 0) continue;
            moved.clear();
            std::uint32_t w = e0;
            for (std::uint32_t e = e0; e < e1; ++e) {
                const std::uint32_t i = bin_index_[e];
                if (level_[i] && (use >> (level_[i] - 1) & 1u) && front(i))
                    moved.push_back(i);
                else bin_index_[w++] = i;
            }
            std::copy(moved.begin(), moved.end(), bin_index_.begin() + w);
            splat_end_[t] = w;
        }
    });
    // The grid blocks (kBlock x kBlock nodes, below) that some tile reading their level
    // reaches with its lattice's cubic stencils (add_far_grid): only those are evaluated
    // (the others' nodes stay 0 and are never read; far_share reads only the directions).
    constexpr int kBlock = 8;
    std::vector<std::vector<char>> block_needed(kMaxFarLevel);
    for (int k = 1; k <= kMaxFarLevel; ++k) {
        if (!(used >> (k - 1) & 1u)) continue;
        int h, nx, ny;
        grid_dims(k, h, nx, ny);
        const int bx = (nx + kBlock - 1) / kBlock, by = (ny + kBlock - 1) / kBlock;
        std::vector<char>& needed = block_needed[k - 1];
        needed.assign(std::size_t(bx) * by, 0);
        for (int t = 0; t < n_tiles; ++t) {
            if (!(tile_far_[t] >> (k - 1) & 1u)) continue;
            const int x0 = (t % tiles_x_) * kTile, y0 = (t / tiles_x_) * kTile;
            const int w = std::min(W_, x0 + kTile) - x0, ht = std::min(H_, y0 + kTile) - y0;
            const int nu = int((w - 0.5) / step_) + 2, nv = int((ht - 0.5) / step_) + 2;
            const int P0 = x0 / h, P1 = std::min(nx - 1, (x0 + step_ * (nu - 1)) / h + 3);
            const int Q0 = y0 / h, Q1 = std::min(ny - 1, (y0 + step_ * (nv - 1)) / h + 3);
            for (int q = Q0 / kBlock; q <= Q1 / kBlock; ++q)
                for (int p = P0 / kBlock; p <= P1 / kBlock; ++p) needed[std::size_t(q) * bx + p] = 1;
        }
    }
    far_grids_.resize(kMaxFarLevel);
    for (int k = 1; k <= kMaxFarLevel; ++k) {
        if (!(used >> (k - 1) & 1u)) continue;
        FarGrid& grid = far_grids_[k - 1];
        grid_dims(k, grid.h, grid.nx, grid.ny);
        const std::size_t m = std::size_t(grid.nx) * grid.ny;
        for (auto* v : {&grid.T, &grid.R, &grid.G, &grid.B, &grid.dx, &grid.dy, &grid.dz}) v->assign(m, 0.0f);
        for (int Q = 0; Q < grid.ny; ++Q)
            for (int P = 0; P < grid.nx; ++P) {
                const Vec3 r = glm::normalize(D0_ + double(grid.h * (P - 1)) * Dx_ + double(grid.h * (Q - 1)) * Dy_);
                const std::size_t o = std::size_t(Q) * grid.nx + P;
                grid.dx[o] = float(r.x);
                grid.dy[o] = float(r.y);
                grid.dz[o] = float(r.z);
            }
    }
    // The grids in blocks of kBlock x kBlock nodes, each with the list of its level's
    // Gaussians whose cull cones meet its rays (the cone test of bin(), on the block's
    // corner nodes), evaluated Gaussian-major like the tile lattices (lattice_batch). A
    // Gaussian is on every node of its blocks: elsewhere its terms are < the cull eps.
    struct Unit {
        int k, P0, Q0, P1, Q1;
        std::vector<std::uint32_t> list;
    };
    std::vector<Unit> units;
    std::vector<int> unit_base(kMaxFarLevel + 1, 0);
    for (int k = 1; k <= kMaxFarLevel; ++k) {
        unit_base[k - 1] = int(units.size());
        const FarGrid& grid = far_grids_[k - 1];
        if (grid.T.empty()) continue;
        for (int Q = 0; Q < grid.ny; Q += kBlock)
            for (int P = 0; P < grid.nx; P += kBlock)
                units.push_back({k, P, Q, std::min(grid.nx, P + kBlock) - 1, std::min(grid.ny, Q + kBlock) - 1, {}});
    }
    unit_base[kMaxFarLevel] = int(units.size());
    // Each block's cone: axis through its centre node, cos and sin of its largest angle to
    // a corner node (the nodes' directions are those of a convex film quadrilateral).
    struct BlockCone {
        Vec3 axis;
        double cos_t, sin_t;
    };
    std::vector<BlockCone> block_cone(units.size());
    for (std::size_t u = 0; u < units.size(); ++u) {
        const Unit& un = units[u];
        const FarGrid& grid = far_grids_[un.k - 1];
        auto film = [&](int P, int Q) { return D0_ + double(grid.h * (P - 1)) * Dx_ + double(grid.h * (Q - 1)) * Dy_; };
        const Vec3 axis = glm::normalize(film(un.P0, un.Q0) + film(un.P1, un.Q1));
        double cmin = 1.0;
        for (int P : {un.P0, un.P1})
            for (int Q : {un.Q0, un.Q1}) cmin = std::min(cmin, glm::dot(axis, glm::normalize(film(P, Q))));
        cmin = std::clamp(cmin - 1e-9, -1.0, 1.0);
        block_cone[u] = {axis, cmin, std::sqrt(std::max(0.0, 1.0 - cmin * cmin))};
    }
    for (std::uint32_t i : far_list) {
        const int k = level_[i];
        const FarGrid& grid = far_grids_[k - 1];
        const int bx = (grid.nx + kBlock - 1) / kBlock;
        int P0, P1, Q0, Q1;
        node_range(i, k, P0, P1, Q0, Q1);
        const Vec3 u = Vec3(g_[i].rx, g_[i].ry, g_[i].rz) / g_[i].dist;
        const double sin_r = std::min(1.0, g_[i].radius / g_[i].dist), cos_r = std::sqrt(1.0 - sin_r * sin_r);
        for (int by = Q0 / kBlock; by <= Q1 / kBlock; ++by)
            for (int bxx = P0 / kBlock; bxx <= P1 / kBlock; ++bxx) {
                if (!block_needed[k - 1][std::size_t(by) * bx + bxx]) continue;
                const std::size_t un = std::size_t(unit_base[k - 1] + by * bx + bxx);
                const BlockCone& c = block_cone[un];
                const double cos_sum = c.cos_t * cos_r - c.sin_t * sin_r;
                if (c.sin_t * cos_r + c.cos_t * sin_r >= 0.0 && glm::dot(c.axis, u) < cos_sum) continue;
                units[un].list.push_back(i);
            }
    }
    far_gaussians_ = far_list.size();
    std::vector<std::size_t> order;
    for (std::size_t u = 0; u < units.size(); ++u)
        if (!units[u].list.empty()) order.push_back(u);
    // (costliest first)
    std::stable_sort(order.begin(), order.end(),
                     [&](std::size_t a, std::size_t b) { return units[a].list.size() > units[b].list.size(); });
    std::atomic<std::size_t> evals{0};
    parallel_chunks(order.size(), threads_, 1, [&](std::size_t ub, std::size_t ue) {
        for (std::size_t e = ub; e < ue; ++e) {
            const Unit& un = units[order[e]];
            FarGrid& grid = far_grids_[un.k - 1];
            const int wx = un.P1 - un.P0 + 1, m = wx * (un.Q1 - un.Q0 + 1);
            float lx[kBlock * kBlock], ly[kBlock * kBlock], lz[kBlock * kBlock];
            float T[kBlock * kBlock] = {}, R[kBlock * kBlock] = {}, G[kBlock * kBlock] = {}, B[kBlock * kBlock] = {};
            for (int Q = un.Q0; Q <= un.Q1; ++Q)
                for (int P = un.P0; P <= un.P1; ++P) {
                    const std::size_t o = std::size_t(Q) * grid.nx + P;
                    const int j = (Q - un.Q0) * wx + (P - un.P0);
                    lx[j] = grid.dx[o];
                    ly[j] = grid.dy[o];
                    lz[j] = grid.dz[o];
                }
            lattice_batch(un.list.data(), int(un.list.size()), m, lx, ly, lz, T, R, G, B);
            for (int Q = un.Q0; Q <= un.Q1; ++Q)
                for (int P = un.P0; P <= un.P1; ++P) {
                    const std::size_t o = std::size_t(Q) * grid.nx + P;
                    const int j = (Q - un.Q0) * wx + (P - un.P0);
                    grid.T[o] = T[j];
                    grid.R[o] = R[j];
                    grid.G[o] = G[j];
                    grid.B[o] = B[j];
                }
            evals.fetch_add(std::size_t(m) * un.list.size(), std::memory_order_relaxed);
        }
    });
    far_nodes_ = evals.load();
}

void GaussianSplat::far_share(std::size_t i, int x0, int y0, int s, int nu, int nv, float* const* out) const {
    const FarGrid& grid = far_grids_[level_[i] - 1];
    const int h = grid.h;
    const int P0 = x0 / h, P1 = (x0 + s * (nu - 1)) / h + 3, Q0 = y0 / h, Q1 = (y0 + s * (nv - 1)) / h + 3;
    const int wx = P1 - P0 + 1, wy = Q1 - Q0 + 1, m = wx * wy;
    constexpr int kMaxWindow = 96;  // (16 / h + 4)^2 <= 64 at h >= s 2
    float lx[kMaxWindow], ly[kMaxWindow], lz[kMaxWindow];
    float T[kMaxWindow], R[kMaxWindow], G[kMaxWindow], B[kMaxWindow];
    for (int Q = Q0; Q <= Q1; ++Q)
        for (int P = P0; P <= P1; ++P) {
            const std::size_t o = std::size_t(Q) * grid.nx + P;
            const int k = (Q - Q0) * wx + (P - P0);
            lx[k] = grid.dx[o];
            ly[k] = grid.dy[o];
            lz[k] = grid.dz[o];
        }
    const int m_pad = (m + 15) / 16 * 16;
    for (int k = m; k < m_pad; ++k) {
        lx[k] = lx[m - 1];
        ly[k] = ly[m - 1];
        lz[k] = lz[m - 1];
    }
    for (float* v : {T, R, G, B}) std::fill(v, v + m_pad, 0.0f);  // (not the whole arrays: a call per pair)
    splat_gaussian(i, m_pad, lx, ly, lz, nullptr, T, R, G, B);
    for (int q = 0; q < 4; ++q) std::fill(out[q], out[q] + nu * nv, 0.0f);
    const float* g[4] = {T, R, G, B};
    add_far_grid(g, h, wx, P0, Q0, x0, y0, s, nu, nv, out);
}

bool GaussianSplat::light_clear(std::size_t i, int t, double factor) const {
    // For a ray of unit direction d, b^r = eye + ((b - eye) . d) d (unclamped) and
    // |b^r - s|^2 = ((b - s) . d)^2 + h^2, h the ray's closest approach to s: so |b^r - s| is
    // at least h >= h_min and at least |(b - s) . d| >= |(b - s) . u| cos a - |b - s| sin a
    // for the tile's rays within angle a <= 90 degrees of the light's direction u. b^r
    // clamped at the eye is D >= h_min away. The lattice needs |b^r - s| >= light_min_ d_i.
    const std::size_t L = lights_.size();
    const Vec3 b = medium_.centre(i);
    const double need = factor * light_min_ * g_[i].dist;
    for (std::size_t l = 0; l < L; ++l) {
        const TileLight& tl = tile_light_[std::size_t(t) * L + l];
        if (double(tl.h_min) >= need) continue;
        const Vec3 u = glm::normalize(lights_[l] - eye_);
        const Vec3 bs = b - lights_[l];
        if (!(std::abs(glm::dot(bs, u)) * double(tl.cos_max) - glm::length(bs) * double(tl.sin_max) >= need))
            return false;
    }
    return true;
}

void GaussianSplat::splat_gaussian(std::size_t i, int n, const float* dx, const float* dy, const float* dz,
                              const float* tend, float* accT, float* accR, float* accG, float* accB) const {
    float Tvp[kTilePixels], Tvr[kTilePixels], tr[kTilePixels];
    const GaussF& g = g_[i];
    // (tend null: all inf, the reduced resolution's lattice)
    if (noise_.on()) {
        // Three vectorised passes: the unperturbed terms, the perturbed directions, the
        // optical depth along those (a fused loop, which the full resolution used, did not
        // vectorise: 3000 Gaussians with noise at 1080p took 122 s CPU).
        float qx[kTilePixels], qy[kTilePixels], qz[kTilePixels], s1[kTilePixels], s2[kTilePixels];
        if (tend) view_terms<false>(g, n, dx, dy, dz, tend, s1, Tvr, tr);
        else view_terms<true>(g, n, dx, dy, dz, tend, s1, Tvr, tr);
        noise_dirs(g.nscale, eye_f_, float(1.0 / noise_.scale), float(noise_.offset.x), float(noise_.offset.y),
                   float(noise_.offset.z), n, dx, dy, dz, tr, qx, qy, qz);
        if (tend) view_terms<false>(g, n, qx, qy, qz, tend, Tvp, s1, s2);
        else view_terms<true>(g, n, qx, qy, qz, tend, Tvp, s1, s2);
    } else if (tend) {
        if (g.far_eye) view_terms<false, true>(g, n, dx, dy, dz, tend, Tvp, Tvr, tr);
        else view_terms<false>(g, n, dx, dy, dz, tend, Tvp, Tvr, tr);
    } else {
        if (g.far_eye) view_terms<true, true>(g, n, dx, dy, dz, tend, Tvp, Tvr, tr);
        else view_terms<true>(g, n, dx, dy, dz, tend, Tvp, Tvr, tr);
    }
    add_to(Tvp, n, accT);
    const std::size_t L = lights_.size();
    if (!plain_) light_loop(i, n, dx, dy, dz, Tvp, Tvr, tr, accR, accG, accB);
    else
        for (std::size_t l = 0; l < L; ++l)
            (g.far_lights ? light_terms<true> : light_terms<false>)(g, gl_[i * L + l], lf_[l], n, dx, dy, dz, Tvp,
                                                                   Tvr, tr, accR, accG, accB);
}

void GaussianSplat::light_loop(std::size_t i, int n, const float* dx, const float* dy, const float* dz, const float* Tvp,
                          const float* Tvr, const float* tr, float* accR, float* accG, float* accB) const {
    const GaussF& g = g_[i];
    const std::size_t L = lights_.size();
    const double gd = extra_.phase.kind == PhaseKind::HenyeyGreenstein ? extra_.phase.g : 0.0;
    const float g1 = float(gd), g2 = float(1.0 - gd * gd), g3 = float(1.0 + gd * gd);
    const int kind = int(extra_.phase.kind);
    auto point = [&](auto K, std::size_t l) {
        constexpr int k = decltype(K)::value;
        if (!extra_.spot.empty() && extra_.spot[l])
            light_terms_ext<k, true>(g, gl_[i * L + l], lf_[l], g1, g2, g3, n, dx, dy, dz, Tvp, Tvr, tr, accR,
                                     accG, accB);
        else
            light_terms_ext<k, false>(g, gl_[i * L + l], lf_[l], g1, g2, g3, n, dx, dy, dz, Tvp, Tvr, tr, accR,
                                      accG, accB);
    };
    const std::size_t S = extra_.sun_w.size();
    auto sun = [&](auto K, std::size_t j) {
        constexpr int k = decltype(K)::value;
        const Vec3& w = extra_.sun_w[j];
        sun_terms<k>(g, gs_[i * S + j], float(-w.x), float(-w.y), float(-w.z), g1, g2, g3, n, dx, dy, dz, Tvp, Tvr,
                     tr, accR, accG, accB);
    };
    auto dispatch = [&](auto&& fn, std::size_t l) {
        switch (kind) {
            case int(PhaseKind::HenyeyGreenstein):
                fn(std::integral_constant<int, int(PhaseKind::HenyeyGreenstein)>(), l);
                break;
            case int(PhaseKind::Rayleigh): fn(std::integral_constant<int, int(PhaseKind::Rayleigh)>(), l); break;
            case int(PhaseKind::HazyMie): fn(std::integral_constant<int, int(PhaseKind::HazyMie)>(), l); break;
            case int(PhaseKind::MurkyMie): fn(std::integral_constant<int, int(PhaseKind::MurkyMie)>(), l); break;
            default: fn(std::integral_constant<int, int(PhaseKind::Isotropic)>(), l); break;
        }
    };
    for (std::size_t l = 0; l < L; ++l) dispatch(point, l);
    for (std::size_t j = 0; j < S; ++j) dispatch(sun, j);
}

void GaussianSplat::background_extra(const double* ddx, const double* ddy, const double* ddz, const float* far,
                                const float* t0, int n, float (*L0)[3]) const {
    if (plain_ && extra_.custom_background.empty()) return;
    if (!extra_.background) return;
    const std::size_t L = lights_.size(), S = extra_.sun_w.size();
    for (std::size_t l = 0; l < L + S; ++l) {
        if (l < L && (extra_.custom_background.empty() || !extra_.custom_background[l])) continue;
        const RGB w = l < L ? weight0_[l] * Csv_[l] : medium_albedo_ * extra_.sun_E[l - L] * Csun_[l - L];
        if (w.x == 0.0 && w.y == 0.0 && w.z == 0.0) continue;
        for (int k = 0; k < n; ++k) {
            const double near = t0 ? double(t0[k]) : 0.0;
            const double v = double(far[k]) > near
                                 ? extra_.background(l, Vec3(ddx[k], ddy[k], ddz[k]), near, double(far[k]))
                                 : 0.0;
            for (int c = 0; c < 3; ++c) L0[k][c] += float(w[c] * v);
        }
    }
}

void GaussianSplat::homogeneous(const double* cos_gamma, std::size_t l, const float* Dvp, const float* t0, int n,
                           float* out) const {
    const double beta0 = medium_.beta0();
    if (!(beta0 > 0.0)) {
        std::fill(out, out + n, 0.0f);
        return;
    }
    const double Dsv = Dsv_[l];
    if (table_) {
        sun05_airlight_table_batch(table_->data().data(), table_->nu(), table_->nT(), beta0, Dsv, cos_gamma, Dvp, n,
                                   out, t0);
        return;
    }
    for (int k = 0; k < n; ++k) {
        const double near = t0 ? double(t0[k]) : 0.0;
        const double far = double(Dvp[k]);
        if (!(far > near)) {
            out[k] = 0.0f;
            continue;
        }
        double v = sun05_airlight(beta0, Dsv, cos_gamma[k], far, nullptr, FEval::Exact);
        if (near > 0.0)
            v = std::exp(beta0 * near) *
                std::max(0.0, v - sun05_airlight(beta0, Dsv, cos_gamma[k], near, nullptr, FEval::Exact));
        out[k] = float(v);
    }
}

void GaussianSplat::splat_tile(int t, const float* depth, float* transmittance, float* airlight) const {
    const int tx = t % tiles_x_, ty = t / tiles_x_;
    const int x0 = tx * kTile, y0 = ty * kTile;
    const int x1 = std::min(W_, x0 + kTile), y1 = std::min(H_, y0 + kTile);
    const int w = x1 - x0;
    const int n = w * (y1 - y0);
    float dx[kTilePixels], dy[kTilePixels], dz[kTilePixels], far[kTilePixels], t0[kTilePixels];
    double ddx[kTilePixels], ddy[kTilePixels], ddz[kTilePixels];
    const bool near_clip = clip_start_ > 0.0;
    for (int j = y0; j < y1; ++j) {
        const int k = (j - y0) * w;
        const Vec3 A = D0_ + (x0 + 0.5) * Dx_ + (j + 0.5) * Dy_;
        (near_clip ? tile_row_rays<true> : tile_row_rays<false>)(
            w, A.x, A.y, A.z, Dx_.x, Dx_.y, Dx_.z, forward_.x, forward_.y, forward_.z, clip_start_,
            depth + size_t(j) * W_ + x0, ddx + k, ddy + k, ddz + k, dx + k, dy + k, dz + k, t0 + k, far + k);
    }
    float Tf[kTilePixels] = {}, Rf[kTilePixels] = {}, Gf[kTilePixels] = {}, Bf[kTilePixels] = {};
    float Tn[kTilePixels] = {}, Rn[kTilePixels] = {}, Gn[kTilePixels] = {}, Bn[kTilePixels] = {};
    if (step_ == 1) {
        for (std::uint32_t e = bin_start_[t]; e < bin_start_[t + 1]; ++e) {
            const std::size_t i = bin_index_[e];
            splat_gaussian(i, n, dx, dy, dz, far, Tf, Rf, Gf, Bf);
            if (near_clip && g_[i].near) splat_gaussian(i, n, dx, dy, dz, t0, Tn, Rn, Gn, Bn);
        }
    } else {
        splat_tile_reduced(t, x0, y0, w, y1 - y0, dx, dy, dz, far, t0, Tf, Rf, Gf, Bf, Tn, Rn, Gn, Bn);
    }
    // Homogeneous term per light.
    float L0[kTilePixels][3] = {};
    const std::size_t L = lights_.size();
    if (medium_.beta0() > 0.0) {
        double cos_gamma[kTilePixels];
        float value[kTilePixels];
        for (std::size_t l = 0; l < L; ++l) {
            const double D = Dsv_[l];
            const Vec3 sv = D > 0.0 ? (lights_[l] - eye_) / D : Vec3(0.0);
            for (int k = 0; k < n; ++k)
                cos_gamma[k] = D > 0.0 ? std::clamp(ddx[k] * sv.x + ddy[k] * sv.y + ddz[k] * sv.z, -1.0, 1.0) : 1.0;
            if (!extra_.custom_background.empty() && extra_.custom_background[l]) continue;
            homogeneous(cos_gamma, l, far, near_clip ? t0 : nullptr, n, value);
            const RGB w = weight0_[l] * Csv_[l];
            add_weighted3(n, float(w[0]), float(w[1]), float(w[2]), value, &L0[0][0]);
        }
        background_extra(ddx, ddy, ddz, far, near_clip ? t0 : nullptr, n, L0);
    }
    const double beta0 = medium_.beta0();
    if (step_ > 1) {
        // Reduced resolution: the same combination in float (fast_expf, vectorised).
        float Tr[kTilePixels], sg[kTilePixels], sc[kTilePixels];
        finish_float(n, float(beta0), near_clip, far, t0, Tf, Tn, Tr, sg, sc);
        for (int j = y0; j < y1; ++j) {
            const int k = (j - y0) * w;
            const size_t p = size_t(j) * W_ + x0;
            write_row_reduced(w, far + k, t0 + k, Tr + k, sc + k, sg + k, Rf + k, Gf + k, Bf + k, Rn + k, Gn + k,
                              Bn + k, L0[k], transmittance + 3 * p, airlight + 3 * p);
        }
        return;
    }
    for (int j = y0; j < y1; ++j)
        for (int i = x0; i < x1; ++i) {
            const int k = (j - y0) * w + (i - x0);
            const size_t p = size_t(j) * W_ + i;
            const double seg = double(far[k]) - double(t0[k]);
            const double T = background_depth(beta0, seg) + std::max(0.0, double(Tf[k]) - double(Tn[k]));
            const float Tr = float(std::exp(-T));
            const double scale_g = near_clip ? std::exp(double(Tn[k])) : 1.0;
            const double scale = near_clip ? scale_g * std::exp(beta0 * double(t0[k])) : 1.0;
            const double gauss[3] = {double(Rf[k]) - double(Rn[k]), double(Gf[k]) - double(Gn[k]),
                                     double(Bf[k]) - double(Bn[k])};
            for (int c = 0; c < 3; ++c) {
                transmittance[3 * p + c] = Tr;
                airlight[3 * p + c] =
                    seg > 0.0 ? float(scale * std::max(0.0, gauss[c]) + scale_g * double(L0[k][c])) : 0.0f;
            }
        }
}

void GaussianSplat::splat_tile_reduced(int t, int x0, int y0, int w, int h, const float* dx, const float* dy,
                                  const float* dz, const float* far, const float* t0, float* Tf, float* Rf, float* Gf,
                                  float* Bf, float* Tn, float* Rn, float* Gn, float* Bn) const {
    const int n = w * h, s = step_;
    const bool near_clip = clip_start_ > 0.0;
    // The tile's depth range (far = max(Dvp, t0); inf where no hit).
    float dmin = std::numeric_limits<float>::infinity(), dmax = 0.0f;
    for (int k = 0; k < n; ++k) {
        dmin = std::min(dmin, far[k]);
        dmax = std::max(dmax, far[k]);
    }
    // Lattice of rays at the film corners x0 + s u, y0 + s v covering the pixel centres,
    // padded to whole SIMD vectors with copies of the last ray.
    constexpr int kMaxLattice = 96;  // (16 / 2 + 1)^2 = 81 at step 2, rounded up to 16
    // (the rays of a lattice of spacing sp with nu x nv nodes: returns their count padded)
    auto lattice_rays = [&](int sp, int nu, int nv, float* lx, float* ly, float* lz) {
        const int m = nu * nv, m_pad = (m + 15) / 16 * 16;
        for (int v = 0; v < nv; ++v)
            for (int u = 0; u < nu; ++u) {
                const Vec3 d = glm::normalize(D0_ + double(x0 + sp * u) * Dx_ + double(y0 + sp * v) * Dy_);
                const int k = v * nu + u;
                lx[k] = float(d.x);
                ly[k] = float(d.y);
                lz[k] = float(d.z);
            }
        for (int k = m; k < m_pad; ++k) {
            lx[k] = lx[m - 1];
            ly[k] = ly[m - 1];
            lz[k] = lz[m - 1];
        }
        return m_pad;
    };
    const int nu = int((w - 0.5) / s) + 2, nv = int((h - 0.5) / s) + 2;
    const int m = nu * nv;
    float lx[kMaxLattice], ly[kMaxLattice], lz[kMaxLattice];
    const int m_pad = lattice_rays(s, nu, nv, lx, ly, lz);
    float cT[kMaxLattice] = {}, cR[kMaxLattice] = {}, cG[kMaxLattice] = {}, cB[kMaxLattice] = {};
    // Near segments on the lattice (near clip only): lattice t0 and sums.
    float lt0[kMaxLattice], nT[kMaxLattice] = {}, nR[kMaxLattice] = {}, nG[kMaxLattice] = {}, nB[kMaxLattice] = {};
    bool near_lattice = false;
    if (near_clip)
        for (int k = 0; k < m_pad; ++k)
            lt0[k] = float(clip_start_ / (double(lx[k]) * forward_.x + double(ly[k]) * forward_.y +
                                          double(lz[k]) * forward_.z));
    std::size_t lattice = 0, exact = 0, behind = 0, far_front = 0;
    // The tile's pixels regrouped into 4x4 blocks (one SIMD vector each), so that a
    // Gaussian the surface cuts is evaluated exactly only on the blocks it reaches.
    constexpr int kBlock = 4, kMaxBlocks = (GaussianSplat::kTile / kBlock) * (GaussianSplat::kTile / kBlock);
    // Set up on the first Gaussian that needs them (prepare_blocks): a tile whose Gaussians
    // all lie wholly in front of or behind its surface never does.
    int perm[kTilePixels], block_start[kMaxBlocks + 1];
    float bx[kTilePixels], by[kTilePixels], bz[kTilePixels], bfar[kTilePixels];
    int n_blocks = 0;
    // Per regrouped pixel: its lattice cell (top-left lattice index) and bilinear weights.
    int lat[kTilePixels];
    float wgt[4 * kTilePixels];
    float eT[kTilePixels], eR[kTilePixels], eG[kTilePixels], eB[kTilePixels];
    // Per 4x4 block (cut_light_factor): the size blk_h of its surface patch (corner pixels'
    // surface points, the larger diagonal) and the largest deviation blk_err of a pixel's
    // surface point from the bilinear patch of the corners'; inf where the block is not
    // 4x4, has no hit at a corner, or lies near a light (h > 0.05 |p - s|, err > 0.01 |p - s|).
    float blk_h[kMaxBlocks], blk_err[kMaxBlocks];
    bool blocks_ready = false;
    auto prepare_blocks = [&]() {
        if (blocks_ready) return;
        blocks_ready = true;
        {
            int k = 0;
            for (int by0 = 0; by0 < h; by0 += kBlock)
                for (int bx0 = 0; bx0 < w; bx0 += kBlock) {
                    block_start[n_blocks++] = k;
                    for (int j = by0; j < std::min(h, by0 + kBlock); ++j)
                        for (int i = bx0; i < std::min(w, bx0 + kBlock); ++i) {
                            const int q = j * w + i;
                            perm[k] = q;
                            bx[k] = dx[q];
                            by[k] = dy[q];
                            bz[k] = dz[q];
                            bfar[k] = far[q];
                            ++k;
                        }
                }
            block_start[n_blocks] = k;
        }
        for (int k = 0; k < n; ++k) {
            const int q = perm[k], j = q / w, i = q % w;
            const float fx = (float(i) + 0.5f) / float(s), fy = (float(j) + 0.5f) / float(s);
            const int u = int(fx), v = int(fy);
            const float wx = fx - float(u), wy = fy - float(v);
            lat[k] = v * nu + u;
            wgt[k] = (1.0f - wx) * (1.0f - wy);
            wgt[kTilePixels + k] = wx * (1.0f - wy);
            wgt[2 * kTilePixels + k] = (1.0f - wx) * wy;
            wgt[3 * kTilePixels + k] = wx * wy;
        }
        std::fill(eT, eT + n, 0.0f);
        std::fill(eR, eR + n, 0.0f);
        std::fill(eG, eG + n, 0.0f);
        std::fill(eB, eB + n, 0.0f);
        for (int b = 0; b < n_blocks; ++b) {
            constexpr float kInfF = std::numeric_limits<float>::infinity();
            blk_h[b] = blk_err[b] = kInfF;
            const int k0 = block_start[b];
            if (block_start[b + 1] - k0 != 16) continue;
            float px[16], py[16], pz[16];
            bool finite = true;
            for (int k = 0; k < 16; ++k) {
                px[k] = bfar[k0 + k] * bx[k0 + k];
                py[k] = bfar[k0 + k] * by[k0 + k];
                pz[k] = bfar[k0 + k] * bz[k0 + k];
                finite = finite && std::isfinite(bfar[k0 + k]);
            }
            if (!finite) continue;
            auto dist = [](float x, float y, float z) { return std::sqrt(x * x + y * y + z * z); };
            const float hb = std::max(dist(px[15] - px[0], py[15] - py[0], pz[15] - pz[0]),
                                      dist(px[12] - px[3], py[12] - py[3], pz[12] - pz[3]));
            // (the largest squared deviation, one square root per block)
            float err2 = 0.0f;
            for (int k = 0; k < 16; ++k) {
                const float u = float(k & 3) * (1.0f / 3.0f), v = float(k >> 2) * (1.0f / 3.0f);
                const float w0 = (1.0f - u) * (1.0f - v), w1 = u * (1.0f - v), w2 = (1.0f - u) * v, w3 = u * v;
                const float ex = px[k] - (w0 * px[0] + w1 * px[3] + w2 * px[12] + w3 * px[15]);
                const float ey = py[k] - (w0 * py[0] + w1 * py[3] + w2 * py[12] + w3 * py[15]);
                const float ez = pz[k] - (w0 * pz[0] + w1 * pz[3] + w2 * pz[12] + w3 * pz[15]);
                err2 = std::max(err2, ex * ex + ey * ey + ez * ez);
            }
            const float err = std::sqrt(err2);
            float dl = kInfF;
            for (const LightF& lf : lf_) dl = std::min(dl, dist(px[0] + lf.vx, py[0] + lf.vy, pz[0] + lf.vz));
            if (hb <= 0.05f * dl && err <= 0.01f * dl) {
                blk_h[b] = hb;
                blk_err[b] = err;
            }
        }
    };
    // Conservative margins for the float depths (relative 1e-6).
    const double far_lo = double(dmin) * (1.0 - 1e-6), far_hi = double(dmax) * (1.0 + 1e-6);
    // Next to a light's image the light terms peak (1 / |b^r - s|^2 along rays passing
    // close to the light): no interpolation there.
    const bool exact_tile = exact_tile_[t] != 0;
    // The Gaussians wholly in front go to the lattice in one Gaussian-major pass
    // (lattice_batch) on the plain path without noise.
    const bool batch = plain_ && !noise_.on();
    thread_local std::vector<std::uint32_t> batch_list, coarse_list, cancel_list, fine_list;
    fine_list.clear();
    const bool fine_ok = batch && exact_tile && s == 4;
    batch_list.clear();
    coarse_list.clear();
    cancel_list.clear();
    // Far-field grids (build_far_field): the levels whose grids the tile reads; its pairs
    // wholly in front on those lie past splat_end_ (they only count here).
    const unsigned use_far = far_grids_.empty() ? 0u : tile_far_[t];
    const std::uint32_t walk_end = splat_end_.empty() ? bin_start_[t + 1] : splat_end_[t];
    far_front = bin_start_[t + 1] - walk_end;
    const bool far_field = use_far != 0;
    // The coarse lattice: every other node (needs an odd number of nodes per row, column).
    const bool coarse_ok = batch && (nu - 1) % 2 == 0 && (nv - 1) % 2 == 0;
    auto to_lattice = [&](std::size_t i) {
        const bool coarse = coarse_ok && (smooth_[i] == 2 || (smooth_[i] == 1 && light_clear(i, t, 2.0)));
        (coarse ? coarse_list : batch_list).push_back(std::uint32_t(i));
    };
    for (std::uint32_t e = bin_start_[t]; e < walk_end; ++e) {
        const std::size_t i = bin_index_[e];
        const GaussF& g = g_[i];
        // A Gaussian far from every light (light_far_: the lattice's light-factor criterion)
        // or far from the lights whose image is next to the tile along their line of sight
        // (light_clear_) has no peak in its light terms here: classified as anywhere.
        const bool exact_here = exact_tile && !light_far_[i] && !light_clear(i, t);
        if (near_clip && g.near) {
            if (exact_here) {
                splat_gaussian(i, n, dx, dy, dz, far, Tf, Rf, Gf, Bf);
                splat_gaussian(i, n, dx, dy, dz, t0, Tn, Rn, Gn, Bn);
                ++exact;
                continue;
            }
            // The near segment [0, t0] (t0 = clip_start / cos, smooth in the direction) on
            // the lattice; the far segment is classified below like any other.
            splat_gaussian(i, m_pad, lx, ly, lz, lt0, nT, nR, nG, nB);
            near_lattice = true;
        }
        if (exact_here) {
            // Wholly behind the tile's surface: below the cull bound, as anywhere else.
            if (g.dist - g.radius >= far_hi) {
                ++behind;
                continue;
            }
            // Wholly in front and clear of the lights at half the lattice's spacing: on the
            // fine lattice (spacing s / 2, the same light-factor bound tau; quarter only).
            if (fine_ok && g.dist + g.radius <= far_lo && light_clear(i, t, 0.5)) {
                fine_list.push_back(std::uint32_t(i));
                continue;
            }
            splat_gaussian(i, n, dx, dy, dz, far, Tf, Rf, Gf, Bf);
            ++exact;
            continue;
        }
        // By the tile's depth range, else ray by ray (the sphere inflated by 1e-4 for
        // the float rounding of ts and h).
        const bool front = g.dist + g.radius <= far_lo, back = g.dist - g.radius >= far_hi;
        const bool on_grid = far_field && level_[i] != 0 && (use_far >> (level_[i] - 1) & 1u);
        if (back) {
            ++behind;
            if (on_grid) cancel_list.push_back(std::uint32_t(i));
            continue;
        }
        if (on_grid && front) {
            ++far_front;
            continue;
        }
        if (front) {
            if (batch) to_lattice(i);
            else splat_gaussian(i, m_pad, lx, ly, lz, nullptr, cT, cR, cG, cB);
            ++lattice;
            continue;
        }
        // Block by block: blocks wholly behind are skipped; if every block is in front the
        // Gaussian goes to the lattice, else the blocks not behind are evaluated exactly.
        prepare_blocks();
        const float R = float(g.radius * (1.0 + 1e-4));
        bool all_front = true, any_exact = false;
        unsigned live = 0, front_blocks = 0, cut = 0;  // blocks not wholly behind; in front; cut
        unsigned char nf[kTilePixels], nb[kTilePixels];
        depth_classes(g, R * R, n, bx, by, bz, bfar, nf, nb);
        // (any flag set in a block: a 4x4 block's 16 bytes as two 64-bit words)
        auto any = [](const unsigned char* p, int len) {
            if (len == 16) {
                std::uint64_t lo, hi;
                std::memcpy(&lo, p, 8);
                std::memcpy(&hi, p + 8, 8);
                return (lo | hi) != 0;
            }
            unsigned char r = 0;
            for (int k = 0; k < len; ++k) r |= p[k];
            return r != 0;
        };
        for (int b = 0; b < n_blocks; ++b) {
            const int k0 = block_start[b], len = block_start[b + 1] - k0;
            const bool not_front = any(nf + k0, len), not_behind = any(nb + k0, len);
            all_front = all_front && !not_front;
            if (not_behind) live |= 1u << b;
            if (!not_front) front_blocks |= 1u << b;
            else if (not_behind) cut |= 1u << b;
        }
        if (all_front && on_grid) {
            ++far_front;
            continue;
        }
        if (all_front) {
            if (batch) to_lattice(i);
            else splat_gaussian(i, m_pad, lx, ly, lz, nullptr, cT, cR, cG, cB);
            ++lattice;
            continue;
        }
        // Cheaper, when few blocks are cut: the Gaussian on the lattice like the ones in
        // front, and on the other blocks its interpolated lattice value replaced, by the
        // exact one on blocks it cuts and by nothing on blocks wholly behind.
        int cut_px = 0, live_px = 0, other_px = 0;
        for (int b = 0; b < n_blocks; ++b) {
            const int nb = block_start[b + 1] - block_start[b];
            if (live >> b & 1u) live_px += nb;
            if (cut >> b & 1u) cut_px += nb;
            if (!(front_blocks >> b & 1u)) other_px += nb;
        }
        // (a far-field Gaussian's lattice share is its grid's: always this form, without the
        // lattice terms' own addition)
        if (on_grid || m_pad + cut_px + other_px / 8 < live_px) {
            float gT[kMaxLattice], gR[kMaxLattice], gG[kMaxLattice], gB[kMaxLattice];
            for (float* v : {gT, gR, gG, gB}) std::fill(v, v + m_pad, 0.0f);  // (a call per pair)
            if (on_grid) {  // its grid share (cancels it exactly where subtracted)
                float* share[4] = {gT, gR, gG, gB};
                far_share(i, x0, y0, s, nu, nv, share);
            } else {
                splat_gaussian(i, m_pad, lx, ly, lz, nullptr, gT, gR, gG, gB);
                add_to(gT, m_pad, cT);
                add_to(gR, m_pad, cR);
                add_to(gG, m_pad, cG);
                add_to(gB, m_pad, cB);
            }
            if (batch && cut != 0)
                cut_light_factor(i, n_blocks, block_start, cut, m_pad, lx, ly, lz, nu, lat, wgt, blk_h, blk_err, bx,
                                 by, bz, bfar, eT, eR, eG, eB);
            for (int b = 0; b < n_blocks; ++b) {
                if (front_blocks >> b & 1u) continue;
                const int k0 = block_start[b], nb = block_start[b + 1] - k0;
                if (!batch && (cut >> b & 1u)) {
                    splat_gaussian(i, nb, bx + k0, by + k0, bz + k0, bfar + k0, eT + k0, eR + k0, eG + k0, eB + k0);
                }
                if (lat[k0] == lat[k0 + nb - 1])  // the block inside one cell (quarter resolution)
                    sub_interp_cell(nb, lat[k0], wgt + k0, nu, gT, gR, gG, gB, eT + k0, eR + k0, eG + k0, eB + k0);
                else
                    sub_interp(nb, lat + k0, wgt + k0, nu, gT, gR, gG, gB, eT + k0, eR + k0, eG + k0, eB + k0);
            }
            ++lattice;
            continue;
        }
        if (batch && live_px > 0) {
            cut_light_factor(i, n_blocks, block_start, live, m_pad, lx, ly, lz, nu, lat, wgt, blk_h, blk_err, bx, by,
                             bz, bfar, eT, eR, eG, eB);
            ++exact;
            continue;
        }
        for (int b = 0; b < n_blocks; ++b) {
            if (!(live >> b & 1u)) continue;
            // Runs of consecutive live blocks in one call.
            int e = b;
            while (e + 1 < n_blocks && (live >> (e + 1) & 1u)) ++e;
            const int k0 = block_start[b], k1 = block_start[e + 1];
            splat_gaussian(i, k1 - k0, bx + k0, by + k0, bz + k0, bfar + k0, eT + k0, eR + k0, eG + k0, eB + k0);
            any_exact = true;
            b = e;
        }
        if (any_exact) ++exact;
        else ++behind;
    }
    n_lattice_.fetch_add(lattice + far_front + fine_list.size(), std::memory_order_relaxed);
    n_fine_.fetch_add(fine_list.size(), std::memory_order_relaxed);
    n_far_.fetch_add(far_front, std::memory_order_relaxed);
    n_cancelled_.fetch_add(cancel_list.size(), std::memory_order_relaxed);
    n_exact_.fetch_add(exact, std::memory_order_relaxed);
    n_behind_.fetch_add(behind, std::memory_order_relaxed);
    for (int k = 0; blocks_ready && k < n; ++k) {
        const int q = perm[k];
        Tf[q] += eT[k];
        Rf[q] += eR[k];
        Gf[q] += eG[k];
        Bf[q] += eB[k];
    }
    // Gaussian-major (lattice_batch: lanes over the Gaussians, padded to 16, plus a call per
    // node) or ray-major (splat_gaussian per Gaussian on the nodes padded to 16), whichever
    // evaluates fewer terms: few Gaussians in a tile (e.g. 34 broad ones) go ray-major.
    auto lattice_sum = [&](const std::vector<std::uint32_t>& list, int mm, const float* x, const float* y,
                           const float* z, float* T, float* R, float* G, float* B) {
        const int nl = int(list.size()), nl_pad = (nl + 15) / 16 * 16, mm_pad = (mm + 15) / 16 * 16;
        if (mm * (nl_pad + 8) < nl * mm_pad) lattice_batch(list.data(), nl, mm, x, y, z, T, R, G, B);
        else
            for (std::uint32_t i : list) splat_gaussian(i, mm_pad, x, y, z, nullptr, T, R, G, B);
    };
    if (!batch_list.empty()) lattice_sum(batch_list, m, lx, ly, lz, cT, cR, cG, cB);
    if (!coarse_list.empty()) {
        // Every other node, then its bilinear interpolant spread onto the lattice (the
        // same function as interpolating the coarse nodes at the pixels).
        const int nuc = (nu + 1) / 2, nvc = (nv + 1) / 2, mc = nuc * nvc;
        float qx[kMaxLattice], qy[kMaxLattice], qz[kMaxLattice];
        float qT[kMaxLattice] = {}, qR[kMaxLattice] = {}, qG[kMaxLattice] = {}, qB[kMaxLattice] = {};
        for (int v = 0; v < nvc; ++v)
            for (int u = 0; u < nuc; ++u) {
                const int k = 2 * v * nu + 2 * u;
                qx[v * nuc + u] = lx[k];
                qy[v * nuc + u] = ly[k];
                qz[v * nuc + u] = lz[k];
            }
        for (int k = mc; k < (mc + 15) / 16 * 16; ++k) {  // padding for the ray-major form
            qx[k] = qx[mc - 1];
            qy[k] = qy[mc - 1];
            qz[k] = qz[mc - 1];
        }
        lattice_sum(coarse_list, mc, qx, qy, qz, qT, qR, qG, qB);
        for (int v = 0; v < nv; ++v)
            for (int u = 0; u < nu; ++u) {
                const int uc = u / 2, vc = v / 2;
                const float fu = (u & 1) ? 0.5f : 0.0f, fv = (v & 1) ? 0.5f : 0.0f;
                const int a = vc * nuc + uc, b = (u & 1) ? a + 1 : a, c = (v & 1) ? a + nuc : a,
                          d = (v & 1) ? b + nuc : b;
                const float w00 = (1.0f - fu) * (1.0f - fv), w10 = fu * (1.0f - fv), w01 = (1.0f - fu) * fv,
                            w11 = fu * fv;
                const int k = v * nu + u;
                cT[k] += w00 * qT[a] + w10 * qT[b] + w01 * qT[c] + w11 * qT[d];
                cR[k] += w00 * qR[a] + w10 * qR[b] + w01 * qR[c] + w11 * qR[d];
                cG[k] += w00 * qG[a] + w10 * qG[b] + w01 * qG[c] + w11 * qG[d];
                cB[k] += w00 * qB[a] + w10 * qB[b] + w01 * qB[c] + w11 * qB[d];
            }
        n_coarse_.fetch_add(coarse_list.size(), std::memory_order_relaxed);
    }
    if (far_field) {
        // The far-field grids at the lattice nodes, less the share of the Gaussians wholly
        // behind the surface here (far_share: the same interpolation of their own terms, so
        // it cancels to float rounding).
        float* c[4] = {cT, cR, cG, cB};
        for (int k = 0; k < kMaxFarLevel; ++k) {
            if (!(use_far >> k & 1u)) continue;
            const FarGrid& grid = far_grids_[k];
            const float* g[4] = {grid.T.data(), grid.R.data(), grid.G.data(), grid.B.data()};
            add_far_grid(g, grid.h, grid.nx, 0, 0, x0, y0, s, nu, nv, c);
        }
        for (std::uint32_t i : cancel_list) {
            float mT[kMaxLattice], mR[kMaxLattice], mG[kMaxLattice], mB[kMaxLattice];
            float* share[4] = {mT, mR, mG, mB};
            far_share(i, x0, y0, s, nu, nv, share);
            for (int k = 0; k < m; ++k) {
                cT[k] -= mT[k];
                cR[k] -= mR[k];
                cG[k] -= mG[k];
                cB[k] -= mB[k];
            }
        }
    }
    if (!fine_list.empty()) {
        // The fine lattice of an exact tile (spacing s / 2), interpolated to the pixels.
        const int sf = s / 2, nuf = int((w - 0.5) / sf) + 2, nvf = int((h - 0.5) / sf) + 2, mf = nuf * nvf;
        float qx[kMaxLattice], qy[kMaxLattice], qz[kMaxLattice];
        float qT[kMaxLattice] = {}, qR[kMaxLattice] = {}, qG[kMaxLattice] = {}, qB[kMaxLattice] = {};
        lattice_rays(sf, nuf, nvf, qx, qy, qz);
        lattice_sum(fine_list, mf, qx, qy, qz, qT, qR, qG, qB);
        interp_lattice(w, h, sf, nuf, qT, qR, qG, qB, Tf, Rf, Gf, Bf);
    }
    if (lattice == 0 && !near_lattice && !far_field) return;
    // Bilinear interpolation of the lattice sums to the pixel centres.
    if (lattice > 0 || far_field) interp_lattice(w, h, s, nu, cT, cR, cG, cB, Tf, Rf, Gf, Bf);
    if (near_lattice) interp_lattice(w, h, s, nu, nT, nR, nG, nB, Tn, Rn, Gn, Bn);
}

void GaussianSplat::cut_light_factor(std::size_t i, int n_blocks, const int* block_start, unsigned live, int m_pad,
                                const float* lx, const float* ly, const float* lz, int nu, const int* lat,
                                const float* wgt, const float* blk_h, const float* blk_err, const float* bx,
                                const float* by, const float* bz, const float* bfar, float* eT, float* eR, float* eG,
                                float* eB) const {
    constexpr int kMaxBlocks = kTilePixels / 16;
    const GaussF& g = g_[i];
    const std::size_t L = lights_.size();
    float Tvp[kTilePixels], Tvr[kTilePixels], tr[kTilePixels];
    // The view terms on the live blocks (runs of consecutive ones), as splat_gaussian.
    for (int b = 0; b < n_blocks; ++b) {
        if (!(live >> b & 1u)) continue;
        int e = b;
        while (e + 1 < n_blocks && (live >> (e + 1) & 1u)) ++e;
        const int k0 = block_start[b], nr = block_start[e + 1] - k0;
        (g.far_eye ? view_terms<false, true> : view_terms<false, false>)(g, nr, bx + k0, by + k0, bz + k0,
                                                                          bfar + k0, Tvp + k0, Tvr + k0, tr + k0);
        add_to(Tvp + k0, nr, eT + k0);
        b = e;
    }
    // The light terms block by block (no per-pixel gathering), each block one of:
    //  1: b^r = eye + max(ts, 0) d lies before the surface (ts < Dvp) at every pixel: the
    //     light side exp(-T_i(s, b^r) - T_i(v, b^r)) / |b^r - s|^2 does not depend on the
    //     depth; it is the lattice's (Dvp = inf), interpolated like it, times Tvp(Dvp);
    //  2: a 4x4 block whose surface points deviate little from the bilinear patch of its
    //     corner pixels' (blk_h, blk_err: splat_tile_reduced): where the surface lies before
    //     b^r (b^r = the surface point p) the light side is exp(-Tvp) G(p), G(p) = sum_l w
    //     exp(-T_i(s_l, p)) / |p - s_l|^2 smooth in p (scale 1/a, and |p - s_l|), evaluated
    //     at the 4 corner pixels and interpolated; the other pixels as in 1;
    //  0: exact.
    // The lattice (m_pad rays, view and light terms) only where it saves more light terms.
    int mode[kMaxBlocks], n_before[kMaxBlocks];
    int lattice_px = 0;
    for (int b = 0; b < n_blocks; ++b) {
        mode[b] = 0;
        if (!(live >> b & 1u)) continue;
        const int k0 = block_start[b], nb = block_start[b + 1] - k0;
        n_before[b] = count_before(nb, tr + k0, bfar + k0);
        if (n_before[b] == nb) mode[b] = 1;
        else if (nb == 16 && 16 - n_before[b] >= 4 && blk_h[b] * g.a <= 0.5f && blk_err[b] * g.a <= 0.05f)
            mode[b] = 2;
        if (mode[b] != 0) lattice_px += n_before[b];
    }
    const bool use_lattice = std::size_t(lattice_px) * L > std::size_t(m_pad) * (L + 1);
    for (int b = 0; b < n_blocks; ++b)
        if (!use_lattice && (mode[b] == 1 || (mode[b] == 2 && n_before[b] > 0))) mode[b] = 0;
    // Exact blocks, in runs.
    for (int b = 0; b < n_blocks; ++b) {
        if (!(live >> b & 1u) || mode[b] != 0) continue;
        int e = b;
        while (e + 1 < n_blocks && (live >> (e + 1) & 1u) && mode[e + 1] == 0) ++e;
        const int k0 = block_start[b], nr = block_start[e + 1] - k0;
        for (std::size_t l = 0; l < L; ++l)
            (g.far_lights ? light_terms<true> : light_terms<false>)(g, gl_[i * L + l], lf_[l], nr, bx + k0, by + k0,
                                                                   bz + k0, Tvp + k0, Tvr + k0, tr + k0, eR + k0,
                                                                   eG + k0, eB + k0);
        b = e;
    }
    if (use_lattice) {
        constexpr int kMaxLattice = 96;
        float lTvp[kMaxLattice], lTvr[kMaxLattice], ltr[kMaxLattice], ones[kMaxLattice];
        float FR[kMaxLattice], FG[kMaxLattice], FB[kMaxLattice];  // (zeroed to m_pad: a call per pair)
        for (float* v : {FR, FG, FB}) std::fill(v, v + m_pad, 0.0f);
        (g.far_eye ? view_terms<true, true> : view_terms<true, false>)(g, m_pad, lx, ly, lz, nullptr, lTvp, lTvr,
                                                                        ltr);
        std::fill(ones, ones + m_pad, 1.0f);
        for (std::size_t l = 0; l < L; ++l)
            (g.far_lights ? light_terms<true> : light_terms<false>)(g, gl_[i * L + l], lf_[l], m_pad, lx, ly, lz, ones,
                                                                   lTvr, ltr, FR, FG, FB);
        for (int b = 0; b < n_blocks; ++b) {
            if (mode[b] == 0 || n_before[b] == 0) continue;
            const int k0 = block_start[b], nb = block_start[b + 1] - k0;
            if (lat[k0] == lat[k0 + nb - 1])  // the block inside one cell (quarter resolution)
                add_interp_factor_cell(nb, lat[k0], wgt + k0, nu, FR, FG, FB, Tvp + k0, tr + k0, bfar + k0, eR + k0,
                                       eG + k0, eB + k0);
            else
                add_interp_factor(nb, lat + k0, wgt + k0, nu, FR, FG, FB, Tvp + k0, tr + k0, bfar + k0, eR + k0,
                                  eG + k0, eB + k0);
        }
    }
    // Surface blocks: G at the corner pixels (0,0), (3,0), (0,3), (3,3), in one batch.
    float gx[4 * kMaxBlocks], gy[4 * kMaxBlocks], gz[4 * kMaxBlocks], gtr[4 * kMaxBlocks], gone[4 * kMaxBlocks],
        gzero[4 * kMaxBlocks];
    int sblk[kMaxBlocks], n_sblk = 0;
    for (int b = 0; b < n_blocks; ++b) {
        if (mode[b] != 2) continue;
        static constexpr int kCorner[4] = {0, 3, 12, 15};
        for (int c = 0; c < 4; ++c) {
            const int q = block_start[b] + kCorner[c], o = 4 * n_sblk + c;
            gx[o] = bx[q];
            gy[o] = by[q];
            gz[o] = bz[q];
            gtr[o] = bfar[q];
            gone[o] = 1.0f;
            gzero[o] = 0.0f;
        }
        sblk[n_sblk++] = b;
    }
    if (n_sblk == 0) return;
    int nc = 4 * n_sblk;
    for (; nc % 16 != 0; ++nc) {  // whole SIMD vectors: copies of the first corner
        gx[nc] = gx[0];
        gy[nc] = gy[0];
        gz[nc] = gz[0];
        gtr[nc] = gtr[0];
        gone[nc] = 1.0f;
        gzero[nc] = 0.0f;
    }
    float GR[4 * kMaxBlocks], GG[4 * kMaxBlocks], GB[4 * kMaxBlocks];  // (zeroed to nc only)
    for (float* v : {GR, GG, GB}) std::fill(v, v + nc, 0.0f);
    // (both erfc terms: a corner's surface point may lie outside the cull sphere, where
    // far_lights does not hold)
    for (std::size_t l = 0; l < L; ++l)
        light_terms(g, gl_[i * L + l], lf_[l], nc, gx, gy, gz, gone, gzero, gtr, GR, GG, GB);
    for (int s = 0; s < n_sblk; ++s) {
        const int k0 = block_start[sblk[s]];
        float t[16];
        surface_weight(16, Tvp + k0, Tvr + k0, tr + k0, bfar + k0, t);
        add_surface_factor16(t, GR + 4 * s, GG + 4 * s, GB + 4 * s, eR + k0, eG + k0, eB + k0);
    }
}

void GaussianSplat::lattice_batch(const std::uint32_t* idx, int n, int m, const float* lx, const float* ly,
                             const float* lz, float* T, float* R, float* G, float* B) const {
    // The Gaussians far from the eye and the lights (GaussF::far_eye, far_lights: one erfc
    // fewer per lane and light, ~20 % of a lane's cost) in a batch of their own, unless the
    // padding of two batches to whole SIMD vectors costs more than that saves.
    thread_local std::vector<std::uint32_t> far, other;
    far.clear();
    other.clear();
    for (int k = 0; k < n; ++k) (g_[idx[k]].far_eye && g_[idx[k]].far_lights ? far : other).push_back(idx[k]);
    auto lanes = [](std::size_t c) { return double((c + 15) / 16 * 16); };
    if (!far.empty() && !other.empty() && 0.8 * lanes(far.size()) + lanes(other.size()) >= lanes(std::size_t(n))) {
        other.assign(idx, idx + n);
        far.clear();
    }
    thread_local LatticeSoA q;
    const int L = int(lights_.size());
    for (const bool kfar : {true, false}) {
        const std::vector<std::uint32_t>& list = kfar ? far : other;
        const int nl = int(list.size());
        if (nl == 0) continue;
        const int n_pad = (nl + 15) / 16 * 16;
        for (auto* v : {&q.rx, &q.ry, &q.rz, &q.a, &q.a2, &q.k0, &q.ke}) v->resize(n_pad);
        for (auto* v : {&q.sx, &q.sy, &q.sz, &q.wr, &q.wg, &q.wb, &q.ske}) v->resize(std::size_t(n_pad) * L);
        q.scratch.resize(6 * std::size_t(n_pad));
        q.n = n_pad;
        for (int k = 0; k < n_pad; ++k) {
            // Padding: k0 = 0 and zero weights (terms 0), a = 1 (finite arithmetic).
            const bool pad = k >= nl;
            const std::uint32_t i = pad ? list[0] : list[k];
            const GaussF& g = g_[i];
            q.rx[k] = g.rx;
            q.ry[k] = g.ry;
            q.rz[k] = g.rz;
            q.a[k] = pad ? 1.0f : g.a;
            q.a2[k] = pad ? 1.0f : g.a2;
            q.k0[k] = pad ? 0.0f : g.k0;
            q.ke[k] = pad ? 0.0f : g.ke;
            for (int l = 0; l < L; ++l) {
                const GaussLightF& w = gl_[std::size_t(i) * L + l];
                const std::size_t o = std::size_t(l) * n_pad + k;
                q.sx[o] = w.sx;
                q.sy[o] = w.sy;
                q.sz[o] = w.sz;
                q.wr[o] = pad ? 0.0f : w.wr;
                q.wg[o] = pad ? 0.0f : w.wg;
                q.wb[o] = pad ? 0.0f : w.wb;
                q.ske[o] = pad ? 0.0f : w.ke;
            }
        }
        if (kfar) lattice_gaussian_major<true>(q, L, lf_.data(), m, lx, ly, lz, T, R, G, B);
        else lattice_gaussian_major<false>(q, L, lf_.data(), m, lx, ly, lz, T, R, G, B);
    }
}

GaussianSplat::ReducedCounts GaussianSplat::reduced_counts() const {
    return {n_lattice_.load(), n_exact_.load(), n_behind_.load(), n_coarse_.load(),
            n_far_.load(),     n_cancelled_.load(), far_gaussians_, far_nodes_, n_fine_.load()};
}

void GaussianSplat::eval_rays(const Vec3* dirs, const float* Dvp, const float* t0, int n, double* Tr, RGB* La) const {
    // Chunks of up to kChunk rays (the bake passes each edge pixel's sub-samples together,
    // so a chunk's rays are close): the union of the Gaussians whose cull spheres the
    // chunk's segments reach, each evaluated over the whole chunk with the splat's kernels.
    // Reduced resolution gathers from the tile bins: 4 pixels' sub-samples per chunk
    // amortise the per-Gaussian call overhead (neighbouring edge pixels share tiles).
    constexpr int kChunk = 64;
    const int chunk = step_ > 1 && !bin_start_.empty() ? kChunk : 16;
    const std::size_t L = lights_.size();
    const double beta0 = medium_.beta0();
    thread_local std::vector<std::uint32_t> stamp;
    thread_local std::uint32_t generation = 0;
    if (stamp.size() != medium_.size()) {
        stamp.assign(medium_.size(), 0);
        generation = 0;
    }
    std::vector<std::uint32_t> gauss;
    for (int k0 = 0; k0 < n; k0 += chunk) {
        const int m = std::min(chunk, n - k0);
        float dx[kChunk], dy[kChunk], dz[kChunk], far[kChunk], tn[kChunk];
        double ddx[kChunk], ddy[kChunk], ddz[kChunk];
        bool any_near = false;
        if (++generation == 0) {  // wrapped: reset the stamps
            std::fill(stamp.begin(), stamp.end(), 0);
            generation = 1;
        }
        gauss.clear();
        // Reduced resolution: the Gaussians binned to the tiles the rays fall in (a
        // superset of each ray's cull; those wholly behind every segment left out) instead
        // of one hierarchy traversal per ray. Full resolution keeps the per-ray traversal.
        const bool from_bins = step_ > 1 && !bin_start_.empty();
        float far_max = 0.0f;
        for (int k = 0; k < m; ++k) {
            tn[k] = t0 ? t0[k0 + k] : 0.0f;
            far[k] = std::max(Dvp[k0 + k], tn[k]);
            far_max = std::max(far_max, far[k]);
        }
        const double far_hi = double(far_max) * (1.0 + 1e-6);
        // Reduced resolution, plain path: the Gaussians wholly in front of every segment of
        // the chunk come from the lattice as in splat_tile (interpolated at the rays' film
        // positions), unless a ray lies outside the image or in a tile kept exact.
        bool lattice_ok = from_bins && plain_ && !noise_.on();
        float fpx[kChunk], fpy[kChunk];
        float far_min = std::numeric_limits<float>::infinity();
        for (int k = 0; k < m; ++k) far_min = std::min(far_min, far[k]);
        int last_tile = -1;
        for (int k = 0; k < m; ++k) {
            const Vec3& d = dirs[k0 + k];
            ddx[k] = d.x;
            ddy[k] = d.y;
            ddz[k] = d.z;
            dx[k] = float(d.x);
            dy[k] = float(d.y);
            dz[k] = float(d.z);
            any_near = any_near || tn[k] > 0.0f;
            if (from_bins) {
                const double lam = glm::dot(q0_, d);
                const double px = lam > 0.0 ? glm::dot(q1_, d) / lam : -1.0, py = lam > 0.0 ? glm::dot(q2_, d) / lam : -1.0;
                if (px >= 0.0 && py >= 0.0 && px <= double(W_) && py <= double(H_)) {
                    const int tx = std::min(tiles_x_ - 1, int(px) / kTile), ty = std::min(tiles_y_ - 1, int(py) / kTile);
                    const int t = ty * tiles_x_ + tx;
                    fpx[k] = float(px);
                    fpy[k] = float(py);
                    if (exact_tile_[t]) lattice_ok = false;
                    // (the chunk's rays mostly share a tile: its list is gathered once)
                    if (t == last_tile) continue;
                    last_tile = t;
                    for (std::uint32_t e = bin_start_[t]; e < bin_start_[t + 1]; ++e) {
                        const std::uint32_t i = bin_index_[e];
                        if (stamp[i] == generation) continue;
                        stamp[i] = generation;
                        // (a Gaussian reaching a near segment [0, t0] is not behind either)
                        if (g_[i].dist - g_[i].radius < far_hi) gauss.push_back(i);
                    }
                    continue;
                }
            }
            lattice_ok = false;
            medium_.for_each_near(eye_, d, double(far[k]), [&](std::size_t i) {
                if (stamp[i] != generation) {
                    stamp[i] = generation;
                    gauss.push_back(std::uint32_t(i));
                }
            });
        }
        float Tf[kChunk] = {}, Rf[kChunk] = {}, Gf[kChunk] = {}, Bf[kChunk] = {};
        float Tn[kChunk] = {}, Rn[kChunk] = {}, Gn[kChunk] = {}, Bn[kChunk] = {};
        if (lattice_ok) {
            // The lattice nodes (film s u, s v, as splat_tile_reduced's) around the rays.
            const int s = step_;
            float xmin = fpx[0], xmax = fpx[0], ymin = fpy[0], ymax = fpy[0];
            for (int k = 1; k < m; ++k) {
                xmin = std::min(xmin, fpx[k]);
                xmax = std::max(xmax, fpx[k]);
                ymin = std::min(ymin, fpy[k]);
                ymax = std::max(ymax, fpy[k]);
            }
            const int u0 = int(xmin) / s, v0 = int(ymin) / s;
            const int nu = int(xmax) / s - u0 + 2, nv = int(ymax) / s - v0 + 2;
            constexpr int kMaxNodes = 64;
            const double far_lo = double(far_min) * (1.0 - 1e-6);
            if (nu * nv <= kMaxNodes) {
                thread_local std::vector<std::uint32_t> front, rest;
                front.clear();
                rest.clear();
                // (those reaching a near segment [0, t0] stay per ray: their near terms)
                const double tn_max = any_near ? double(*std::max_element(tn, tn + m)) : 0.0;
                for (std::uint32_t i : gauss) {
                    const bool near = any_near && g_[i].dist < g_[i].radius + tn_max;
                    (!near && g_[i].dist + g_[i].radius <= far_lo ? front : rest).push_back(i);
                }
                if (!front.empty()) {
                    float lx[kMaxNodes], ly[kMaxNodes], lz[kMaxNodes];
                    float cT[kMaxNodes] = {}, cR[kMaxNodes] = {}, cG[kMaxNodes] = {}, cB[kMaxNodes] = {};
                    for (int v = 0; v < nv; ++v)
                        for (int u = 0; u < nu; ++u) {
                            const Vec3 d = glm::normalize(D0_ + double(s * (u0 + u)) * Dx_ + double(s * (v0 + v)) * Dy_);
                            lx[v * nu + u] = float(d.x);
                            ly[v * nu + u] = float(d.y);
                            lz[v * nu + u] = float(d.z);
                        }
                    lattice_batch(front.data(), int(front.size()), nu * nv, lx, ly, lz, cT, cR, cG, cB);
                    const float inv_s = 1.0f / float(s);
                    for (int k = 0; k < m; ++k) {
                        const float fx = fpx[k] * inv_s - float(u0), fy = fpy[k] * inv_s - float(v0);
                        const int u = std::min(nu - 2, int(fx)), v = std::min(nv - 2, int(fy));
                        const float wx = fx - float(u), wy = fy - float(v);
                        const int a = v * nu + u, b = a + 1, c = a + nu, d = c + 1;
                        const float w00 = (1.0f - wx) * (1.0f - wy), w10 = wx * (1.0f - wy), w01 = (1.0f - wx) * wy,
                                    w11 = wx * wy;
                        Tf[k] += w00 * cT[a] + w10 * cT[b] + w01 * cT[c] + w11 * cT[d];
                        Rf[k] += w00 * cR[a] + w10 * cR[b] + w01 * cR[c] + w11 * cR[d];
                        Gf[k] += w00 * cG[a] + w10 * cG[b] + w01 * cG[c] + w11 * cG[d];
                        Bf[k] += w00 * cB[a] + w10 * cB[b] + w01 * cB[c] + w11 * cB[d];
                    }
                    gauss.swap(rest);
                }
            }
        }
        for (std::uint32_t i : gauss) {
            splat_gaussian(i, m, dx, dy, dz, far, Tf, Rf, Gf, Bf);
            // The near segment [0, t0] only meets Gaussians near the eye (as in bin()).
            if (any_near && glm::length(medium_.centre(i) - eye_) < g_[i].radius + double(*std::max_element(tn, tn + m)))
                splat_gaussian(i, m, dx, dy, dz, tn, Tn, Rn, Gn, Bn);
        }
        float L0[kChunk][3] = {};
        if (beta0 > 0.0) {
            double cos_gamma[kChunk];
            float value[kChunk];
            for (std::size_t l = 0; l < L; ++l) {
                const double D = Dsv_[l];
                const Vec3 sv = D > 0.0 ? (lights_[l] - eye_) / D : Vec3(0.0);
                for (int k = 0; k < m; ++k)
                    cos_gamma[k] =
                        D > 0.0 ? std::clamp(ddx[k] * sv.x + ddy[k] * sv.y + ddz[k] * sv.z, -1.0, 1.0) : 1.0;
                if (!extra_.custom_background.empty() && extra_.custom_background[l]) continue;
                homogeneous(cos_gamma, l, far, any_near ? tn : nullptr, m, value);
                const RGB w = weight0_[l] * Csv_[l];
                for (int k = 0; k < m; ++k)
                    for (int c = 0; c < 3; ++c) L0[k][c] += float(w[c]) * value[k];
            }
            background_extra(ddx, ddy, ddz, far, any_near ? tn : nullptr, m, L0);
        }
        for (int k = 0; k < m; ++k) {
            const double seg = double(far[k]) - double(tn[k]);
            Tr[k0 + k] = std::exp(-(background_depth(beta0, seg) + std::max(0.0, double(Tf[k]) - double(Tn[k]))));
            const double scale_g = tn[k] > 0.0f ? std::exp(double(Tn[k])) : 1.0;
            const double scale = tn[k] > 0.0f ? scale_g * std::exp(beta0 * double(tn[k])) : 1.0;
            const RGB g(double(Rf[k]) - Rn[k], double(Gf[k]) - Gn[k], double(Bf[k]) - Bn[k]);
            La[k0 + k] = seg > 0.0 ? scale * glm::max(g, RGB(0.0)) +
                                         scale_g * RGB(double(L0[k][0]), double(L0[k][1]), double(L0[k][2]))
                                   : RGB(0.0);
        }
    }
}

RGB GaussianSplat::eval_exact(const Vec3& dir, double Dvp) const {
    if (!exact_) exact_ = std::make_unique<FogshopAirlight>(medium_, eye_, lights_, table_, threads_);
    return exact_->eval_rgb(dir, Dvp, albedo_.data(), I0_.data(), medium_albedo_);
}

}  // namespace airlight
