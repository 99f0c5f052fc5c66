// centre_depths.cpp: optical depths from a point to every Gaussian centre (centre_depths.h).
//
// The segments from a source s (the eye or a light) to the centres b_i form a star, so
// instead of walking the medium's hierarchy once per segment the Gaussians are binned once
// per source by direction, like the screen splat bins them into tiles: a cube map around s
// (6 faces of K x K cells, gnomonic: a direction u on face (axis m, sign) has face
// coordinates u_p / |u_m|, u_q / |u_m| in [-1, 1]) lists in each cell every Gaussian whose
// cull sphere's cone of directions from s touches it (exact bounds of the cone's projections
// on the planes (m, p) and (m, q), padded). A segment s -> b_i that reaches the sphere of
// Gaussian j has its direction inside that cone, so the cell of b_i's direction lists j: the
// candidates are a superset of the culled set. Each cell's list is in ascending key_j =
// |b_j - s| - R_j (the distance from s to the sphere), so a segment of length D only looks
// at the prefix key_j < D. Per target the float kernels then run the cull test of
// for_each_near (segment_reaches) and the line integrals (segment_integrals, eq. 31) on the
// candidates, vectorised. Spheres holding s (or covering more than a face's worth of cells)
// are in a list every target looks at.
// Three ways to the same sums, by the cost of the work (star_depths picks one):
//  - per target (few targets, a brush stroke's new Gaussians): one list of all candidates
//    in the medium's leaf order, no binning, with a cull test per block of 16 first; each
//    target's cull test runs over every candidate, vectorised, then the integrals of those
//    that reach;
//  - per candidate (few candidates, the old Gaussians' update by a stroke's new ones): each
//    candidate's cull test runs over every target, vectorised (no binning, no per-target
//    overhead; depths_per_candidate);
//  - binned (many of both): the cube map of build_star, per target only its cell's list.
// Sun lamps (sun_depths): parallel half-lines instead of a star, binned on a grid over the
// plane normal to the sun's direction.
#include "gaussian/centre_depths.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <stdexcept>
#include <utility>

#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
#include <immintrin.h>
#endif

#include "core/constants.h"
#include "core/cube_map.h"
#include "core/fast_erf.h"
#include "core/target_clones.h"

namespace airlight {

namespace {

// Line integrals of the gathered Gaussians (rel = b - from) on from + t d, t in [0, D].
AIRLIGHT_SIMD_CLONES void segment_integrals(int n, const float* __restrict rx, const float* __restrict ry,
                                            const float* __restrict rz, const float* __restrict a,
                                            const float* __restrict k0, float dx, float dy, float dz, float D,
                                            float* __restrict out) {
    for (int k = 0; k < n; ++k) {
        const float ts = rx[k] * dx + ry[k] * dy + rz[k] * dz;
        const float cx = ry[k] * dz - rz[k] * dy, cy = rz[k] * dx - rx[k] * dz, cz = rx[k] * dy - ry[k] * dx;
        const float e = k0[k] * fast_expf_le88(-a[k] * a[k] * (cx * cx + cy * cy + cz * cz));
        const float x1 = -a[k] * ts, x2 = a[k] * (D - ts);
        const float E1 = fast_erfc_pos(x1 < 0.0f ? -x1 : x1);
        const float E2 = fast_erfc_pos(x2 < 0.0f ? -x2 : x2);
        out[k] = e * (x1 >= 0.0f ? E1 - E2 : (x2 <= 0.0f ? E2 - E1 : 2.0f - E1 - E2));
    }
}

// keep[k] = 1 if the segment from + t d, t in [0, D], passes within sqrt(R2[k]) of the
// Gaussian at rel[k] (relative to from; the test of GaussianMedium::for_each_near, R2 inflated
// by the caller for float rounding) and id[k] != skip, else 0.
AIRLIGHT_SIMD_CLONES void segment_reaches(int n, const float* __restrict rx, const float* __restrict ry,
                                          const float* __restrict rz, const float* __restrict R2,
                                          const std::uint32_t* __restrict id, std::uint32_t skip, float dx,
                                          float dy, float dz, float D, float* __restrict keep) {
    for (int k = 0; k < n; ++k) {
        const float ts = rx[k] * dx + ry[k] * dy + rz[k] * dz;
        const float tc = ts < 0.0f ? 0.0f : (ts > D ? D : ts);
        const float qx = rx[k] - tc * dx, qy = ry[k] - tc * dy, qz = rz[k] - tc * dz;
        keep[k] = (qx * qx + qy * qy + qz * qz < R2[k]) & (id[k] != skip) ? 1.0f : 0.0f;
    }
}

// segment_reaches that also sorts the reaching Gaussians: keep[k] = 2 where the segment
// covers the Gaussian with 4.5 / a to spare at both ends (a ts >= 4.5 and a (D - ts) >=
// 4.5: both erfc terms of eq. 31 are below 2e-10, so T = 2 e to float precision, one exp
// instead of three), 1 for the other reaching ones, 0 for the rest.
constexpr float kInteriorX = 4.5f;
AIRLIGHT_SIMD_CLONES void segment_reaches_split(int n, const float* __restrict rx, const float* __restrict ry,
                                                const float* __restrict rz, const float* __restrict R2,
                                                const float* __restrict a, const std::uint32_t* __restrict id,
                                                std::uint32_t skip, float dx, float dy, float dz, float D,
                                                float* __restrict keep) {
    for (int k = 0; k < n; ++k) {
        const float ts = rx[k] * dx + ry[k] * dy + rz[k] * dz;
        const float tc = ts < 0.0f ? 0.0f : (ts > D ? D : ts);
        const float qx = rx[k] - tc * dx, qy = ry[k] - tc * dy, qz = rz[k] - tc * dz;
        const bool reach = (qx * qx + qy * qy + qz * qz < R2[k]) & (id[k] != skip);
        const bool inside = (a[k] * ts >= kInteriorX) & (a[k] * (D - ts) >= kInteriorX);
        keep[k] = reach ? (inside ? 2.0f : 1.0f) : 0.0f;
    }
}

// The whole-line integral 2 e = c sqrt(pi) / a exp(-a^2 h^2) of the gathered Gaussians
// (those segment_reaches_split marks 2).
AIRLIGHT_SIMD_CLONES void line_integrals_whole(int n, const float* __restrict rx, const float* __restrict ry,
                                               const float* __restrict rz, const float* __restrict a,
                                               const float* __restrict k0, float dx, float dy, float dz,
                                               float* __restrict out) {
    for (int k = 0; k < n; ++k) {
        const float cx = ry[k] * dz - rz[k] * dy, cy = rz[k] * dx - rx[k] * dz, cz = rx[k] * dy - ry[k] * dx;
        out[k] = 2.0f * k0[k] * fast_expf_le88(-a[k] * a[k] * (cx * cx + cy * cy + cz * cz));
    }
}

// Per candidate Gaussian (rel = b - s, R2, a, k0; index _skip_) over n targets' segments
// s + t d_k, t in [0, D_k]: keep[k] = the cull test of segment_reaches (and tid[k] !=
// skip); out[k] = the line integral (segment_integrals with the roles swapped).
AIRLIGHT_SIMD_CLONES void targets_reached(int n, const float* __restrict dx, const float* __restrict dy,
                                          const float* __restrict dz, const float* __restrict D,
                                          const std::uint32_t* __restrict tid, std::uint32_t skip, float rx,
                                          float ry, float rz, float R2, float* __restrict keep) {
    for (int k = 0; k < n; ++k) {
        const float ts = rx * dx[k] + ry * dy[k] + rz * dz[k];
        const float tc = ts < 0.0f ? 0.0f : (ts > D[k] ? D[k] : ts);
        const float qx = rx - tc * dx[k], qy = ry - tc * dy[k], qz = rz - tc * dz[k];
        keep[k] = (qx * qx + qy * qy + qz * qz < R2) & (tid[k] != skip) ? 1.0f : 0.0f;
    }
}
AIRLIGHT_SIMD_CLONES void target_integrals(int n, const float* __restrict dx, const float* __restrict dy,
                                           const float* __restrict dz, const float* __restrict D, float rx, float ry,
                                           float rz, float a, float k0, float* __restrict out) {
    for (int k = 0; k < n; ++k) {
        const float ts = rx * dx[k] + ry * dy[k] + rz * dz[k];
        const float cx = ry * dz[k] - rz * dy[k], cy = rz * dx[k] - rx * dz[k], cz = rx * dy[k] - ry * dx[k];
        const float e = k0 * fast_expf_le88(-a * a * (cx * cx + cy * cy + cz * cz));
        const float x1 = -a * ts, x2 = a * (D[k] - ts);
        const float E1 = fast_erfc_pos(x1 < 0.0f ? -x1 : x1);
        const float E2 = fast_erfc_pos(x2 < 0.0f ? -x2 : x2);
        out[k] = e * (x1 >= 0.0f ? E1 - E2 : (x2 <= 0.0f ? E2 - E1 : 2.0f - E1 - E2));
    }
}

constexpr std::size_t kStarLanes = 16;  // lists are padded to whole AVX-512 vectors
inline std::size_t lanes_up(std::size_t n) { return (n + kStarLanes - 1) / kStarLanes * kStarLanes; }

// Candidates in float structure-of-arrays form, storage padded to a multiple of
// kStarLanes with entries that never reach (R2 < 0) and integrate to 0 (k0 = 0), so the
// kernels run whole vectors (their scalar remainder loops cost more than the vectors on
// the short lists here).
struct StarCands {
    std::vector<float> rx, ry, rz, a, k0, R2, key;  // b_j - s, a_j, c_j sqrt(pi) / (2 a_j), R_j^2, key_j
    std::vector<std::uint32_t> id;                  // Gaussian index j
    std::size_t n = 0;
    // Optional (block_test): per run of kStarLanes entries a sphere holding all of their
    // cull spheres (centre relative to s, radius^2), for lists in a spatially coherent order.
    std::vector<float> bx, by, bz, bR2;
    std::vector<std::uint32_t> bid;  // all "none" (segment_reaches' skip never matches)
    bool block_test = false;
    void resize(std::size_t m) {
        block_test = false;
        const std::size_t size = lanes_up(m);
        for (auto* v : {&rx, &ry, &rz, &a, &k0, &R2, &key}) v->resize(size);
        id.resize(size);
        n = m;
        for (std::size_t k = m; k < size; ++k) {
            rx[k] = ry[k] = rz[k] = k0[k] = 0.0f;
            a[k] = 1.0f;
            R2[k] = -1.0f;
            key[k] = std::numeric_limits<float>::infinity();
            id[k] = std::numeric_limits<std::uint32_t>::max();
        }
    }
    void set(std::size_t k, const StarCands& from, std::size_t j) {
        rx[k] = from.rx[j];
        ry[k] = from.ry[j];
        rz[k] = from.rz[j];
        a[k] = from.a[j];
        k0[k] = from.k0[j];
        R2[k] = from.R2[j];
        key[k] = from.key[j];
        id[k] = from.id[j];
    }
};

struct StarScratch {
    std::vector<float> keep, rx, ry, rz, a, k0, wx, wy, wz, wa, wk0, out, bkeep;
    std::vector<std::uint32_t> idx;
    void reserve(std::size_t m) {
        m += kStarLanes;  // compact() stores whole vectors past the last hit
        if (keep.size() >= m) return;
        for (auto* v : {&keep, &rx, &ry, &rz, &a, &k0, &wx, &wy, &wz, &wa, &wk0, &out}) v->resize(m);
        idx.resize(m);
    }
};

// sum_k x[k] in double over n (a multiple of 8): eight accumulators, so GCC vectorises it
// without reassociating (the same order in every clone).
AIRLIGHT_SIMD_CLONES double sum_double(const float* __restrict x, std::size_t n) {
    double acc[8] = {0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0};
    for (std::size_t k = 0; k < n; k += 8)
        for (int l = 0; l < 8; ++l) acc[l] += double(x[k + l]);
    return ((acc[0] + acc[1]) + (acc[2] + acc[3])) + ((acc[4] + acc[5]) + (acc[6] + acc[7]));
}

// Copies the entries k < n (a multiple of 16) with keep[k] == want of the nv arrays of 32-bit
// words in[] to out[] (each with room for n + 16), in order; returns their number
// (idx: scratch of n). AVX-512: compress in registers and store whole vectors (a
// compressing store to memory is slow on some cores).
std::size_t compact_scalar(const float* keep, float want, std::size_t n, int nv, const void* const* in,
                           void* const* out, std::uint32_t* idx) {
    std::size_t m = 0;
    for (std::size_t k = 0; k < n; ++k) {
        idx[m] = std::uint32_t(k);
        m += keep[k] == want ? 1 : 0;
    }
    for (int v = 0; v < nv; ++v) {
        const unsigned char* src = static_cast<const unsigned char*>(in[v]);
        unsigned char* dst = static_cast<unsigned char*>(out[v]);
        for (std::size_t q = 0; q < m; ++q) std::memcpy(dst + 4 * q, src + 4 * std::size_t(idx[q]), 4);
    }
    return m;
}
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
__attribute__((target("avx512f"))) std::size_t compact_avx512(const float* keep, float want, std::size_t n, int nv,
                                                                const void* const* in, void* const* out) {
    std::size_t m = 0;
    const __m512 w = _mm512_set1_ps(want);
    for (std::size_t k = 0; k < n; k += 16) {
        const __mmask16 mk = _mm512_cmp_ps_mask(_mm512_loadu_ps(keep + k), w, _CMP_EQ_OQ);
        if (mk == 0) continue;
        for (int v = 0; v < nv; ++v) {
            const __m512i x = _mm512_loadu_si512(static_cast<const std::uint32_t*>(in[v]) + k);
            _mm512_storeu_si512(static_cast<std::uint32_t*>(out[v]) + m, _mm512_maskz_compress_epi32(mk, x));
        }
        m += std::size_t(__builtin_popcount(mk));
    }
    return m;
}
#endif
std::size_t compact(const float* keep, float want, std::size_t n, int nv, const void* const* in, void* const* out,
                    std::uint32_t* idx) {
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
    static const bool avx512 = __builtin_cpu_supports("avx512f");
    if (avx512) return compact_avx512(keep, want, n, nv, in, out);
#endif
    return compact_scalar(keep, want, n, nv, in, out, idx);
}

// Sum of the culled line integrals of the candidates c[0 .. n) except Gaussian _skip_ on
// s + t d, t in [0, D] (d unit, relative coordinates from s), in float, summed in double:
// the cull test (on the list's blocks first if it has them), the reaching ones gathered
// in two groups (segment_reaches_split), and each group's integrals.
double star_sum(const StarCands& c, std::size_t n, std::uint32_t skip, float dx, float dy, float dz, float D,
                StarScratch& w) {
    // The prefix that can reach: key < D (keys are rounded down, see build_star), run to a
    // whole number of vectors (the entries past the prefix or the padding do not reach).
    const std::size_t P = std::size_t(std::upper_bound(c.key.begin(), c.key.begin() + n, D) - c.key.begin());
    if (P == 0) return 0.0;
    const std::size_t P16 = lanes_up(P);
    w.reserve(P16);
    std::size_t m1 = 0, m2 = 0;  // edge and whole-line groups
    auto run = [&](std::size_t k0_, std::size_t k1_) {
        const std::size_t len = k1_ - k0_;
        segment_reaches_split(int(len), c.rx.data() + k0_, c.ry.data() + k0_, c.rz.data() + k0_, c.R2.data() + k0_,
                              c.a.data() + k0_, c.id.data() + k0_, skip, dx, dy, dz, D, w.keep.data());
        const void* in[5] = {c.rx.data() + k0_, c.ry.data() + k0_, c.rz.data() + k0_, c.a.data() + k0_,
                             c.k0.data() + k0_};
        void* edge[5] = {w.rx.data() + m1, w.ry.data() + m1, w.rz.data() + m1, w.a.data() + m1, w.k0.data() + m1};
        m1 += compact(w.keep.data(), 1.0f, len, 5, in, edge, w.idx.data());
        void* whole[5] = {w.wx.data() + m2, w.wy.data() + m2, w.wz.data() + m2, w.wa.data() + m2, w.wk0.data() + m2};
        m2 += compact(w.keep.data(), 2.0f, len, 5, in, whole, w.idx.data());
    };
    if (c.block_test) {
        const std::size_t nb = P16 / kStarLanes, nb16 = lanes_up(nb);
        w.bkeep.resize(nb16);
        segment_reaches(int(nb16), c.bx.data(), c.by.data(), c.bz.data(), c.bR2.data(), c.bid.data(), skip, dx, dy,
                        dz, D, w.bkeep.data());
        for (std::size_t b = 0; b < nb;) {
            if (w.bkeep[b] == 0.0f) {
                ++b;
                continue;
            }
            std::size_t e = b + 1;
            while (e < nb && w.bkeep[e] != 0.0f) ++e;
            run(b * kStarLanes, e * kStarLanes);
            b = e;
        }
    } else {
        run(0, P16);
    }
    const std::size_t e16 = lanes_up(m1), w16 = lanes_up(m2);
    for (std::size_t q = m1; q < e16; ++q) {
        w.rx[q] = w.ry[q] = w.rz[q] = w.k0[q] = 0.0f;
        w.a[q] = 1.0f;
    }
    for (std::size_t q = m2; q < w16; ++q) {
        w.wx[q] = w.wy[q] = w.wz[q] = w.wk0[q] = 0.0f;
        w.wa[q] = 1.0f;
    }
    segment_integrals(int(e16), w.rx.data(), w.ry.data(), w.rz.data(), w.a.data(), w.k0.data(), dx, dy, dz, D,
                      w.out.data());
    double T = sum_double(w.out.data(), e16);
    line_integrals_whole(int(w16), w.wx.data(), w.wy.data(), w.wz.data(), w.wa.data(), w.wk0.data(), dx, dy, dz,
                         w.out.data());
    return T + sum_double(w.out.data(), w16);
}

// Face-coordinate range [lo, hi] (clamped to [-1, 1]) of the rays from the origin through
// the sphere of radius R around a centre whose components along the face axis and along
// the face's axis p are (cm, cp): the rays' projections on that plane pass through the
// projected disc, so their angles from the axis lie within asin(R / rho) of the centre's
// (rho = |(cm, cp)|; every angle if the disc holds the origin). False if that range misses
// the face's [-pi/4, pi/4]. Padded by 1e-6 rad against rounding.
bool face_range(double cm, double cp, double R, double& lo, double& hi) {
    const double rho = std::hypot(cm, cp);
    if (!(rho > R)) {
        lo = -1.0;
        hi = 1.0;
        return true;
    }
    const double phi = std::atan2(cp, cm), beta = std::asin(R / rho);
    // |phi| <= pi and beta < pi/2: a range wrapping past +-pi stays below -pi/2 or above
    // pi/2 there, so it cannot reach the face by the wrapped side.
    const double a0 = phi - beta - 1e-6, a1 = phi + beta + 1e-6;
    if (a1 < -kQuarterPi || a0 > kQuarterPi) return false;
    lo = a0 <= -kQuarterPi ? -1.0 : std::max(-1.0, std::tan(a0));
    hi = a1 >= kQuarterPi ? 1.0 : std::min(1.0, std::tan(a1));
    return true;
}

// Cube-map cell of a face coordinate (K cells per side).
inline int face_cell(double t, int K) { return std::min(K - 1, std::max(0, int(std::floor((t + 1.0) * 0.5 * K)))); }

// Cell of the direction u != 0 (finite), on core/cube_map.h's faces.
inline std::size_t cube_cell(const Vec3& u, int K) {
    const CubeFacePoint c = cube_face_point(u);
    return (std::size_t(c.face) * K + face_cell(c.q, K)) * K + face_cell(c.p, K);
}

// Binning of one source's candidates (see the top of the file). K = 0: no cells, every
// candidate is in _everywhere_ (the brute-force form for few targets).
struct StarGrid {
    Vec3 s{0.0};
    StarCands cands;                       // in ascending key
    int K = 0;
    std::vector<std::uint32_t> start;      // per cell (6 K^2 + 1), into entries
    std::vector<std::uint32_t> entries;    // positions in cands, ascending within a cell
    StarCands everywhere;                  // looked at by every target, ascending key
    // build_star's scratch, kept for the next source.
    std::vector<std::uint32_t> js;
    std::vector<double> dist;
    std::vector<std::pair<float, std::uint32_t>> keyed;
};

// The cull radius of the float reach tests, R_j inflated by 2e-4 against float rounding.
inline double inflated_radius(const GaussianMedium& m, std::size_t j) { return m.cull_radius(j) * 1.0002; }

// Per run of kStarLanes candidates of c (an unbinned list in the hierarchy's leaf order): the
// sphere around the box of their cull spheres (StarCands::block_test), radius inflated by
// 1e-3 against float rounding (a segment reaching one of the spheres passes within the
// block's radius of its centre).
void block_spheres(const GaussianMedium& m, const Vec3& s, StarCands& c) {
    const std::size_t nb = c.rx.size() / kStarLanes, nb16 = lanes_up(nb);
    for (auto* v : {&c.bx, &c.by, &c.bz, &c.bR2}) v->assign(nb16, 0.0f);
    c.bid.assign(nb16, std::numeric_limits<std::uint32_t>::max());
    for (std::size_t b = nb; b < nb16; ++b) c.bR2[b] = -1.0f;
    for (std::size_t b = 0; b < nb; ++b) {
        Vec3 lo(std::numeric_limits<double>::infinity()), hi(-std::numeric_limits<double>::infinity());
        const std::size_t k1 = std::min(c.n, (b + 1) * kStarLanes);
        for (std::size_t k = b * kStarLanes; k < k1; ++k) {
            const Vec3 rel = m.centre(c.id[k]) - s;
            const double R = inflated_radius(m, c.id[k]);
            lo = glm::min(lo, rel - Vec3(R));
            hi = glm::max(hi, rel + Vec3(R));
        }
        const Vec3 mid = 0.5 * (lo + hi);
        double rad = 0.0;
        for (std::size_t k = b * kStarLanes; k < k1; ++k)
            rad = std::max(rad, glm::length(m.centre(c.id[k]) - s - mid) + inflated_radius(m, c.id[k]));
        rad *= 1.001;
        c.bx[b] = float(mid.x);
        c.by[b] = float(mid.y);
        c.bz[b] = float(mid.z);
        c.bR2[b] = float(rad * rad);
    }
    c.block_test = true;
}

// The cube map of the binned candidates g.cands around g.s (see the top of the file): the
// cells' lists (g.K, g.start, g.entries) and the candidates every target looks at
// (g.everywhere: spheres holding s, or covering more than a face's worth of cells).
void bin_cones(const GaussianMedium& m, StarGrid& g) {
    const Vec3& s = g.s;
    const StarCands& c = g.cands;
    const std::vector<double>& dist = g.dist;
    // Per candidate: the rectangles (face, p range, q range) its cone covers, in face
    // coordinates; spheres holding s are everywhere.
    struct Rect {
        std::uint32_t k;
        int face;
        double p0, p1, q0, q1;
    };
    std::vector<Rect> rects;
    std::vector<char> all(c.n, 0);
    std::vector<double> rho;
    rects.reserve(c.n * 2);
    rho.reserve(c.n);
    for (std::size_t k = 0; k < c.n; ++k) {
        const std::uint32_t j = c.id[k];
        const Vec3 rel = m.centre(j) - s;
        const double R = inflated_radius(m, j), d = dist[j];
        if (!(d > R)) {
            all[k] = 1;
            continue;
        }
        rho.push_back(R / d);
        for (int face = 0; face < 6; ++face) {
            const int mm = face / 2, p = (mm + 1) % 3, q = (mm + 2) % 3;
            const double cm = (face & 1) ? -rel[mm] : rel[mm];
            // The sphere's bounding box must reach the face's pyramid |x_p|, |x_q| <= x_m.
            if (cm + R <= 0.0 || cm + R < std::max(std::abs(rel[p]), std::abs(rel[q])) - R) continue;
            Rect r{std::uint32_t(k), face, 0, 0, 0, 0};
            if (face_range(cm, rel[p], R, r.p0, r.p1) && face_range(cm, rel[q], R, r.q0, r.q1)) rects.push_back(r);
        }
    }
    // K: cells about half the median cone radius wide (2 / K in face coordinates ~ radians
    // at the face centre), fewer while the lists would exceed ~48 entries per candidate.
    double rho_med = 0.1;
    if (!rho.empty()) {
        std::nth_element(rho.begin(), rho.begin() + rho.size() / 2, rho.end());
        rho_med = rho[rho.size() / 2];
    }
    int K = int(std::clamp(4.0 / rho_med, 1.0, 256.0));
    auto count = [&](int KK, std::vector<char>* flag) {
        std::size_t total = 0;
        for (std::size_t r0 = 0; r0 < rects.size();) {
            std::size_t r1 = r0, cells = 0;
            for (; r1 < rects.size() && rects[r1].k == rects[r0].k; ++r1) {
                const Rect& r = rects[r1];
                cells += std::size_t(face_cell(r.p1, KK) - face_cell(r.p0, KK) + 1) *
                         std::size_t(face_cell(r.q1, KK) - face_cell(r.q0, KK) + 1);
            }
            if (cells > std::size_t(KK) * KK) {
                if (flag) (*flag)[rects[r0].k] = 1;
            } else {
                total += cells;
            }
            r0 = r1;
        }
        return total;
    };
    while (K > 1 && count(K, nullptr) > 48 * c.n + 65536) K = std::max(1, K * 2 / 3);
    count(K, &all);
    g.K = K;
    const std::size_t cells = 6 * std::size_t(K) * K;
    g.start.assign(cells + 1, 0);
    for (int pass = 0; pass < 2; ++pass) {
        for (const Rect& r : rects) {
            if (all[r.k]) continue;
            const int p0 = face_cell(r.p0, K), p1 = face_cell(r.p1, K), q0 = face_cell(r.q0, K), q1 = face_cell(r.q1, K);
            for (int qq = q0; qq <= q1; ++qq)
                for (int pp = p0; pp <= p1; ++pp) {
                    const std::size_t cell = (std::size_t(r.face) * K + qq) * K + pp;
                    if (pass == 0)
                        ++g.start[cell + 1];
                    else
                        g.entries[g.start[cell]++] = r.k;
                }
        }
        if (pass == 0) {
            for (std::size_t q = 0; q < cells; ++q) g.start[q + 1] += g.start[q];
            g.entries.resize(g.start[cells]);
        } else {
            // start[q] now holds the end of cell q: shift back.
            for (std::size_t q = cells; q > 0; --q) g.start[q] = g.start[q - 1];
            g.start[0] = 0;
        }
    }
    std::size_t ne = 0;
    for (std::size_t k = 0; k < c.n; ++k) ne += all[k];
    g.everywhere.resize(ne);
    ne = 0;
    for (std::size_t k = 0; k < c.n; ++k)
        if (all[k]) g.everywhere.set(ne++, c, k);
}

void build_star(const GaussianMedium& m, const float* a, const float* k0, const Vec3& s, std::size_t c0, std::size_t c1,
                bool binned, StarGrid& g) {
    g.s = s;
    // Candidates with a cull sphere (R = 0: never reaches cull_eps, as in for_each_near).
    // Unbinned: in the hierarchy's leaf order, for the block test.
    std::vector<std::uint32_t>& js = g.js;
    std::vector<double>& dist = g.dist;
    js.clear();
    js.reserve(c1 - c0);
    if (binned) {
        for (std::size_t j = c0; j < c1; ++j)
            if (m.cull_radius(j) > 0.0) js.push_back(std::uint32_t(j));
    } else {
        for (std::uint32_t j : m.leaf_order())
            if (j >= c0 && j < c1) js.push_back(j);
    }
    dist.resize(m.size() > 0 ? c1 : 0);
    for (std::uint32_t j : js) dist[j] = glm::length(m.centre(j) - s);
    // key_j = d_j - R_j, with R inflated (inflated_radius) and rounded down to float so that
    // key < D never misses a reaching segment.
    // Unbinned (few targets): no order, every key -inf (the whole list is the prefix).
    std::vector<std::pair<float, std::uint32_t>>& keyed = g.keyed;
    keyed.resize(js.size());
    for (std::size_t k = 0; k < js.size(); ++k)
        keyed[k] = {binned ? std::nextafter(float(dist[js[k]] - inflated_radius(m, js[k])), -INFINITY)
                           : -std::numeric_limits<float>::infinity(),
                    js[k]};
    if (binned) std::sort(keyed.begin(), keyed.end());
    StarCands& c = g.cands;
    c.resize(keyed.size());
    for (std::size_t k = 0; k < keyed.size(); ++k) {
        const std::uint32_t j = keyed[k].second;
        const Vec3 rel = m.centre(j) - s;
        const double R = inflated_radius(m, j);
        c.rx[k] = float(rel.x);
        c.ry[k] = float(rel.y);
        c.rz[k] = float(rel.z);
        c.a[k] = a[j];
        c.k0[k] = k0[j];
        c.R2[k] = float(R * R);
        c.key[k] = keyed[k].first;
        c.id[k] = j;
    }
    g.K = 0;
    g.start.clear();
    g.entries.clear();
    if (!binned) {
        block_spheres(m, s, c);
        std::swap(g.everywhere, c);  // (g.cands keeps the other buffer for the next source)
        return;
    }
    bin_cones(m, g);
}

// Per candidate (method 2): the targets of each source in float SoA, padded to whole
// vectors with D = 0 (integral 0), in blocks of 1024 (the threads' units); per candidate its
// cull test over a block's targets, then the integrals of those it reaches. Into out
// (sources x targets).
void depths_per_candidate(const GaussianMedium& m, const std::vector<Vec3>& src, std::size_t t0, std::size_t t1,
                          std::size_t c0, std::size_t c1, const std::vector<float>& a, const std::vector<float>& k0,
                          int threads, std::vector<double>& out) {
    const std::size_t nt = t1 - t0, rows = src.size();
    const std::size_t nt16 = lanes_up(nt), block = 1024;
    std::vector<float> tdx(nt16), tdy(nt16), tdz(nt16), tD(nt16);
    std::vector<std::uint32_t> tid(nt16), slot(nt16);
    for (std::size_t k = 0; k < nt16; ++k) {
        tid[k] = k < nt ? std::uint32_t(t0 + k) : std::numeric_limits<std::uint32_t>::max();
        slot[k] = std::uint32_t(k);
    }
    struct Cand {
        float rx, ry, rz, R2, a, k0;
        std::uint32_t j;
    };
    std::vector<Cand> cands;
    const std::size_t blocks = (nt16 + block - 1) / block;
    for (std::size_t r = 0; r < rows; ++r) {
        std::fill(tdx.begin(), tdx.end(), 0.0f);
        std::fill(tdy.begin(), tdy.end(), 0.0f);
        std::fill(tdz.begin(), tdz.end(), 0.0f);
        std::fill(tD.begin(), tD.end(), 0.0f);
        for (std::size_t k = 0; k < nt; ++k) {
            const Vec3 d = m.centre(t0 + k) - src[r];
            const double D = glm::length(d);
            if (!(D > 0.0)) continue;
            tdx[k] = float(d.x / D);
            tdy[k] = float(d.y / D);
            tdz[k] = float(d.z / D);
            tD[k] = float(D);
        }
        cands.clear();
        for (std::size_t j = c0; j < c1; ++j) {
            const double R = inflated_radius(m, j);
            if (!(R > 0.0)) continue;
            const Vec3 rel = m.centre(j) - src[r];
            cands.push_back({float(rel.x), float(rel.y), float(rel.z), float(R * R), a[j], k0[j], std::uint32_t(j)});
        }
        parallel_chunks(blocks, threads, 1, [&](std::size_t ub, std::size_t ue) {
            thread_local std::vector<float> keep, hx, hy, hz, hD, val;
            thread_local std::vector<std::uint32_t> hs, idx;
            thread_local std::vector<double> acc;
            for (auto* v : {&keep, &hx, &hy, &hz, &hD, &val}) v->resize(block + kStarLanes);
            hs.resize(block + kStarLanes);
            idx.resize(block);
            acc.resize(block);
            for (std::size_t u = ub; u < ue; ++u) {
                const std::size_t b = u * block, e = std::min(nt16, b + block), n = e - b;
                std::fill(acc.begin(), acc.end(), 0.0);
                const void* in[5] = {tdx.data() + b, tdy.data() + b, tdz.data() + b, tD.data() + b, slot.data() + b};
                void* hit[5] = {hx.data(), hy.data(), hz.data(), hD.data(), hs.data()};
                for (const Cand& c : cands) {
                    targets_reached(int(n), tdx.data() + b, tdy.data() + b, tdz.data() + b, tD.data() + b,
                                    tid.data() + b, c.j, c.rx, c.ry, c.rz, c.R2, keep.data());
                    const std::size_t h = compact(keep.data(), 1.0f, n, 5, in, hit, idx.data());
                    if (h == 0) continue;
                    const std::size_t h16 = lanes_up(h);
                    for (std::size_t q = h; q < h16; ++q) {
                        hx[q] = hy[q] = hz[q] = hD[q] = 0.0f;  // D = 0: integral 0
                        hs[q] = std::uint32_t(b);
                    }
                    target_integrals(int(h16), hx.data(), hy.data(), hz.data(), hD.data(), c.rx, c.ry, c.rz,
                                     c.a, c.k0, val.data());
                    for (std::size_t q = 0; q < h; ++q) acc[hs[q] - b] += double(val[q]);
                }
                for (std::size_t k = b; k < std::min(e, nt); ++k) out[r * nt + k] = acc[k - b];
            }
        });
    }
}

// Per target (method 1) or binned (binned: method 3), one source at a time (see the top of
// the file): into out (sources x targets).
void depths_per_target(const GaussianMedium& m, const std::vector<Vec3>& src, std::size_t t0, std::size_t t1,
                       std::size_t c0, std::size_t c1, const std::vector<float>& a, const std::vector<float>& k0,
                       int threads, bool binned, std::vector<double>& out) {
    const std::size_t nt = t1 - t0, rows = src.size();
    // One source at a time, reusing the per-source structures (a call then allocates about
    // one source's worth: the preview runs this per edit, and fresh memory costs page faults).
    StarGrid g;
    std::vector<std::uint32_t> order(nt), cell_of(nt), tstart, fill;
    // Work units: (cell, a run of <= 32 of the cell's targets).
    struct Unit {
        std::uint32_t cell, b, e;
    };
    std::vector<Unit> units;
    for (std::size_t r = 0; r < rows; ++r) {
        build_star(m, a.data(), k0.data(), src[r], c0, c1, binned, g);
        const std::size_t cells = g.K > 0 ? 6 * std::size_t(g.K) * g.K : 1;
        tstart.assign(cells + 1, 0);
        for (std::size_t k = 0; k < nt; ++k) {
            const Vec3 u = m.centre(t0 + k) - g.s;
            cell_of[k] = g.K > 0 && (u.x != 0.0 || u.y != 0.0 || u.z != 0.0) ? std::uint32_t(cube_cell(u, g.K)) : 0;
            ++tstart[cell_of[k] + 1];
        }
        for (std::size_t q = 0; q < cells; ++q) tstart[q + 1] += tstart[q];
        fill.assign(tstart.begin(), tstart.end() - 1);
        for (std::size_t k = 0; k < nt; ++k) order[fill[cell_of[k]]++] = std::uint32_t(k);
        units.clear();
        for (std::size_t q = 0; q < cells; ++q)
            for (std::uint32_t b = tstart[q]; b < tstart[q + 1]; b += 32)
                units.push_back({std::uint32_t(q), b, std::min<std::uint32_t>(b + 32, tstart[q + 1])});
        parallel_chunks(units.size(), threads, 8, [&](std::size_t ub, std::size_t ue) {
            thread_local StarScratch w;
            thread_local StarCands local;
            for (std::size_t u = ub; u < ue; ++u) {
                const Unit& unit = units[u];
                const StarCands* cell = nullptr;
                if (g.K > 0) {
                    const std::uint32_t e0 = g.start[unit.cell], e1 = g.start[unit.cell + 1];
                    local.resize(e1 - e0);
                    for (std::uint32_t e = e0; e < e1; ++e) local.set(e - e0, g.cands, g.entries[e]);
                    cell = &local;
                }
                for (std::uint32_t x = unit.b; x < unit.e; ++x) {
                    const std::uint32_t k = order[x];
                    const std::size_t i = t0 + k;
                    const Vec3 d = m.centre(i) - g.s;
                    const double D = glm::length(d);
                    if (!(D > 0.0)) continue;
                    const Vec3 dir = d / D;
                    const float dx = float(dir.x), dy = float(dir.y), dz = float(dir.z), Df = float(D);
                    double T = star_sum(g.everywhere, g.everywhere.n, std::uint32_t(i), dx, dy, dz, Df, w);
                    if (cell) T += star_sum(*cell, cell->n, std::uint32_t(i), dx, dy, dz, Df, w);
                    out[r * nt + k] = T;
                }
            }
        });
    }
}

// out[r (t1 - t0) + k] = sum over the Gaussians j in [c0, c1), j != i, of the culled line
// integral T_j(src[r], b_i) (float kernels, each skipped Gaussian < cull_eps as in
// for_each_near) for the targets i = t0 + k in [t0, t1), by _method_ (0: the cheapest by
// the cost model below; gaussian_depths_to_centres). No beta0. Throws
// std::invalid_argument on a non-finite source or ranges outside the medium.
std::vector<double> star_depths(const GaussianMedium& m, const std::vector<Vec3>& src, std::size_t t0, std::size_t t1,
                                std::size_t c0, std::size_t c1, int threads, int method) {
    for (const Vec3& s : src)
        if (!std::isfinite(s.x) || !std::isfinite(s.y) || !std::isfinite(s.z))
            throw std::invalid_argument("Gaussian fog: a light or eye position is not finite");
    if (t0 > t1 || t1 > m.size() || c0 > c1 || c1 > m.size())
        throw std::invalid_argument("Gaussian fog: target or candidate range outside the Gaussians");
    const std::size_t nt = t1 - t0, nc = c1 - c0, rows = src.size();
    std::vector<double> out(rows * nt, 0.0);
    if (nt == 0 || nc == 0 || rows == 0) return out;
    std::vector<float> a(m.size()), k0(m.size());
    for (std::size_t j = c0; j < c1; ++j) {
        a[j] = float(m.scale(j));
        k0[j] = float(m.amplitude(j) * kSqrtPi / (2.0 * m.scale(j)));
    }
    if (method == 0) {
        // Rough costs in ns per source, one thread (measured, Gaussians of 1/a 1..3 m, and
        // 0.3..1 m at 3e4, in a 60 x 8 x 70 m box): per target ~0.55 per (target, candidate)
        // pair and ~180 per target; per candidate ~0.9 per pair and ~100 per candidate;
        // binned ~2100 per candidate and ~450 per target (3x the bare binning: the targets'
        // sums over their cells grow with the density). Per target at 3000 Gaussians took
        // 5.4 ms, per candidate 9.0 and binned 6.5 (the previous model's pick was per
        // candidate); per candidate wins a brush stroke's old targets (3000 x 100 new: 0.25
        // ms against 0.56), binned 3e4 Gaussians (90 ms against 167).
        const double pairs = double(nt) * double(nc);
        const double per_target = 0.55 * pairs + 180.0 * double(nt), per_cand = 0.9 * pairs + 100.0 * double(nc),
                     binned = 2100.0 * double(nc) + 450.0 * double(nt);
        method = nt < 256 ? 1 : (per_cand < std::min(per_target, binned) ? 2 : (per_target <= binned ? 1 : 3));
    }
    // Small work (a brush stroke's update) stays on the calling thread: starting threads
    // costs more than it saves there.
    if (double(nt) * double(nc) * double(rows) < 4e6) threads = 1;
    if (method == 2) depths_per_candidate(m, src, t0, t1, c0, c1, a, k0, threads, out);
    else depths_per_target(m, src, t0, t1, c0, c1, a, k0, threads, method == 3, out);
    return out;
}

// Sun lamps' binning (sun_depths): the Gaussians on a grid over the plane normal to u,
// frame (e1, e2, u) (Gaussian j covers the square of half-side R_j around its projection
// (P_j, Q_j)), each cell's list in descending z_j + R_j (z = b . u: the half-line from b_i
// reaches sphere j only if z_j + R_j > z_i), as the ascending keys of _keyed_.
struct SunGrid {
    std::vector<double> P, Q, R;
    std::vector<std::pair<float, std::uint32_t>> keyed;  // (key, j) in ascending key
    double p0 = 0.0, q0 = 0.0, hp = 1.0, hq = 1.0;
    int KP = 1, KQ = 1;
    std::vector<std::uint32_t> start, entries;  // per cell (KP KQ + 1), into keyed
    int cp(double p) const { return std::min(KP - 1, std::max(0, int(std::floor((p - p0) / hp)))); }
    int cq(double q) const { return std::min(KQ - 1, std::max(0, int(std::floor((q - q0) / hq)))); }
    std::size_t cells() const { return std::size_t(KP) * KQ; }
};

SunGrid bin_half_lines(const GaussianMedium& m, const Vec3& u) {
    const std::size_t n = m.size();
    SunGrid g;
    std::vector<double>&P = g.P, &Q = g.Q, &R = g.R;
    std::vector<std::pair<float, std::uint32_t>>& keyed = g.keyed;
    const Vec3 e1 = glm::normalize(std::abs(u.x) < 0.9 ? glm::cross(u, Vec3(1.0, 0.0, 0.0))
                                                         : glm::cross(u, Vec3(0.0, 1.0, 0.0)));
    const Vec3 e2 = glm::cross(u, e1);
    P.resize(n);
    Q.resize(n);
    R.resize(n);
    double p0 = std::numeric_limits<double>::infinity(), p1 = -p0, q0 = p0, q1 = -p0;
    std::vector<double> radii;
    for (std::size_t j = 0; j < n; ++j) {
        const Vec3 b = m.centre(j);
        P[j] = glm::dot(b, e1);
        Q[j] = glm::dot(b, e2);
        R[j] = inflated_radius(m, j);
        p0 = std::min(p0, P[j]);
        p1 = std::max(p1, P[j]);
        q0 = std::min(q0, Q[j]);
        q1 = std::max(q1, Q[j]);
        if (m.cull_radius(j) > 0.0) {
            // Descending z + R as an ascending key, rounded down: key <= -z_i never misses.
            keyed.push_back({std::nextafter(float(-(glm::dot(b, u) + R[j])), -INFINITY), std::uint32_t(j)});
            radii.push_back(R[j]);
        }
    }
    std::sort(keyed.begin(), keyed.end());
    // Cells about half the median cull radius wide, at most 1024 per side.
    double h = 1.0;
    if (!radii.empty()) {
        std::nth_element(radii.begin(), radii.begin() + radii.size() / 2, radii.end());
        h = std::max(0.5 * radii[radii.size() / 2], 1e-6);
    }
    g.p0 = p0;
    g.q0 = q0;
    g.KP = int(std::clamp(std::ceil((p1 - p0) / h), 1.0, 1024.0));
    g.KQ = int(std::clamp(std::ceil((q1 - q0) / h), 1.0, 1024.0));
    g.hp = std::max((p1 - p0) / g.KP, 1e-300);
    g.hq = std::max((q1 - q0) / g.KQ, 1e-300);
    const std::size_t cells = g.cells();
    std::vector<std::uint32_t>&start = g.start, &entries = g.entries;
    start.assign(cells + 1, 0);
    for (int pass = 0; pass < 2; ++pass) {
        for (std::size_t k = 0; k < keyed.size(); ++k) {
            const std::uint32_t j = keyed[k].second;
            for (int y = g.cq(Q[j] - R[j]); y <= g.cq(Q[j] + R[j]); ++y)
                for (int x = g.cp(P[j] - R[j]); x <= g.cp(P[j] + R[j]); ++x) {
                    const std::size_t cell = std::size_t(y) * g.KP + x;
                    if (pass == 0)
                        ++start[cell + 1];
                    else
                        entries[start[cell]++] = std::uint32_t(k);
                }
        }
        if (pass == 0) {
            for (std::size_t c = 0; c < cells; ++c) start[c + 1] += start[c];
            entries.resize(start[cells]);
        } else {
            for (std::size_t c = cells; c > 0; --c) start[c] = start[c - 1];
            start[0] = 0;
        }
    }
    return g;
}

// Sun lamps: T_sun[i] = sum over j != i of the culled line integral of Gaussian j on the
// half-line b_i + t u, t >= 0 (u towards the sun), in float: per target its cell's prefix
// (bin_half_lines) gathered relative to b_i (double differences, then float) and summed by
// star_sum with D = inf. No beta0.
std::vector<double> sun_depths(const GaussianMedium& m, const Vec3& u, int threads) {
    const std::size_t n = m.size();
    std::vector<double> out(n, 0.0);
    if (n == 0) return out;
    const SunGrid g = bin_half_lines(m, u);
    const std::vector<double>&P = g.P, &Q = g.Q, &R = g.R;
    const std::vector<std::pair<float, std::uint32_t>>& keyed = g.keyed;
    const std::vector<std::uint32_t>&start = g.start, &entries = g.entries;
    const std::size_t cells = g.cells();
    // Targets by cell, in units of <= 32.
    std::vector<std::uint32_t> tcell(n), tstart(cells + 1, 0), order(n);
    for (std::size_t i = 0; i < n; ++i) {
        tcell[i] = std::uint32_t(std::size_t(g.cq(Q[i])) * g.KP + g.cp(P[i]));
        ++tstart[tcell[i] + 1];
    }
    for (std::size_t c = 0; c < cells; ++c) tstart[c + 1] += tstart[c];
    {
        std::vector<std::uint32_t> fill(tstart.begin(), tstart.end() - 1);
        for (std::size_t i = 0; i < n; ++i) order[fill[tcell[i]]++] = std::uint32_t(i);
    }
    struct Unit {
        std::uint32_t cell, b, e;
    };
    std::vector<Unit> units;
    for (std::size_t c = 0; c < cells; ++c)
        for (std::uint32_t b = tstart[c]; b < tstart[c + 1]; b += 32)
            units.push_back({std::uint32_t(c), b, std::min<std::uint32_t>(b + 32, tstart[c + 1])});
    std::vector<float> fa(n), fk0(n), fR2(n);
    for (std::size_t j = 0; j < n; ++j) {
        fa[j] = float(m.scale(j));
        fk0[j] = float(m.amplitude(j) * kSqrtPi / (2.0 * m.scale(j)));
        fR2[j] = float(R[j] * R[j]);
    }
    const float ux = float(u.x), uy = float(u.y), uz = float(u.z), inf = std::numeric_limits<float>::infinity();
    parallel_chunks(units.size(), threads, 8, [&](std::size_t ub, std::size_t ue) {
        thread_local StarScratch w;
        thread_local StarCands local;
        for (std::size_t un = ub; un < ue; ++un) {
            const Unit& unit = units[un];
            const std::uint32_t e0 = start[unit.cell], e1_ = start[unit.cell + 1];
            for (std::uint32_t x = unit.b; x < unit.e; ++x) {
                const std::uint32_t i = order[x];
                const Vec3 bi = m.centre(i);
                // The prefix z_j + R_j > z_i (ascending key = -(z_j + R_j) below -z_i).
                const float zkey = float(-glm::dot(bi, u));
                std::uint32_t e = e0;
                while (e < e1_ && keyed[entries[e]].first <= zkey) ++e;
                local.resize(e - e0);
                for (std::uint32_t q = e0; q < e; ++q) {
                    const std::uint32_t j = keyed[entries[q]].second;
                    const std::size_t k = q - e0;
                    const Vec3 rel = m.centre(j) - bi;
                    local.rx[k] = float(rel.x);
                    local.ry[k] = float(rel.y);
                    local.rz[k] = float(rel.z);
                    local.a[k] = fa[j];
                    local.k0[k] = fk0[j];
                    local.R2[k] = fR2[j];
                    local.key[k] = -inf;
                    local.id[k] = j;
                }
                out[i] = star_sum(local, local.n, i, ux, uy, uz, inf, w);
            }
        }
    });
    return out;
}

}  // namespace

std::vector<double> gaussian_depths_to_centres(const GaussianMedium& medium, const std::vector<Vec3>& sources,
                                               std::size_t first, std::size_t last, std::size_t cand_first,
                                               std::size_t cand_last, int threads, int method) {
    if (method < 0 || method > 3) throw std::invalid_argument("gaussian_depths_to_centres: method must be 0..3");
    return star_depths(medium, sources, first, last, cand_first, cand_last, threads, method);
}

std::vector<double> gaussian_centre_depths(const GaussianMedium& medium, const Vec3& eye, const std::vector<Vec3>& lights,
                                           int threads) {
    const std::size_t n = medium.size();
    std::vector<Vec3> src{eye};
    src.insert(src.end(), lights.begin(), lights.end());
    std::vector<double> out = gaussian_depths_to_centres(medium, src, 0, n, 0, n, threads);
    for (std::size_t row = 0; row < src.size(); ++row)
        for (std::size_t i = 0; i < n; ++i)
            out[row * n + i] += background_depth(medium.beta0(), glm::length(medium.centre(i) - src[row]));
    return out;
}

std::vector<double> gaussian_sun_depths(const GaussianMedium& medium, const Vec3& u, int threads) {
    if (!std::isfinite(u.x) || !std::isfinite(u.y) || !std::isfinite(u.z) || std::abs(glm::length(u) - 1.0) > 1e-6)
        throw std::invalid_argument("rbf_sun_depths: the sun direction must be a finite unit vector");
    return sun_depths(medium, u, threads);
}

}  // namespace airlight
