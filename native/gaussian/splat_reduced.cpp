// splat_reduced.cpp: a tile's Gaussian terms at half and quarter resolution (step s = 2 or 4,
// GaussianSplat::bin; Fogshop also evaluated its airlight at reduced resolution), in a
// depth-independent form. With the tile's pixel depths in [Dmin, Dmax] and Gaussian i at
// distance d_i from the eye with cull radius R_i:
//  - behind (d_i - R_i >= Dmax): every segment [0, Dvp] misses the cull sphere: skipped;
//  - in front (d_i + R_i <= Dmin): the term equals the one with Dvp = inf to < cull_eps, a
//    smooth function of the direction: evaluated on a lattice of rays every s pixels (film
//    x0 + s u, y0 + s v; (16/s + 1)^2 rays) and interpolated bilinearly (splat_interp.h);
//    broad ones on every other node (the coarse lattice) or on the image-wide far-field
//    grids (splat_far_field.cpp);
//  - cut (the surface crosses the sphere in the tile): exact on the 4x4 pixel blocks it
//    reaches, or on the lattice with the exact value replacing the interpolated one on the
//    cut blocks when cheaper. On the plain path without noise only the view terms (Tvp, Tvr)
//    are exact there: the light side depends on Dvp only through b^r, so it is the
//    lattice's where b^r lies before the surface, and exp(-Tvp) G(p), G(p) = sum_l w_l
//    exp(-T_i(s_l, p)) / |p - s_l|^2 at the surface point p where the surface lies before
//    b^r, interpolated from a block's corner pixels on a smooth patch (cut_light_factor).
// A Gaussian reaching the near clip plane has its near segment [0, t0] on the lattice too.
// Next to a light's image (exact_tile_) the light factor 1 / |b^r - s|^2 peaks: a Gaussian
// whose b^r may come closer to a light than 27 s pixels' angle times d_i (light_clear) is
// skipped behind, goes on a fine lattice of spacing s / 2 when in front and clear at that
// spacing (quarter only), else is exact per pixel.
// Depth edges cost no accuracy (a pixel's depth only selects which Gaussians are exact);
// the error is the bilinear interpolation of smooth terms (splat_test.cpp, bench_rbf.py).
// The criteria and their error bounds: docs/architecture.md, "The Gaussian splat".
#include "gaussian/splat.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <vector>

#include "core/fast_erf.h"
#include "core/target_clones.h"
#include "gaussian/splat_interp.h"
#include "gaussian/splat_kernels.h"

namespace airlight {

using namespace splat;

namespace {

constexpr int kTilePixels = GaussianSplat::kTilePixels;

// Reduced resolution (splat_tile_reduced): which of the n rays (segments [0, far[k]])
// Gaussian g's cull sphere (radius^2 R2) against the rays of a tile's pixels (dx, dy, dz,
// n of them, ending at far). A ray that misses the sphere is neither; one that crosses it
// is "not in front" unless the sphere's exit lies before far[k], and "not behind" unless
// its entry lies beyond far[k]. Per pixel into nf, nb (1: not in front, not behind); one
// loop over the tile (a call per 4x4 block spent ~40 % in its set-up), and without the
// square root: te >= ts + half as te - ts >= 0 and (te - ts)^2 >= R2 - h2.
AIRLIGHT_SIMD_CLONES void depth_classes(const GaussF g, float R2, int n, const float* __restrict dx,
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

}  // namespace

// One tile's work at step_ > 1 (splat_tile_reduced): its lattice and the sums on it, its
// pixels regrouped into 4x4 blocks (one SIMD vector each) so that a Gaussian the surface
// cuts is evaluated exactly only on the blocks it reaches, and the Gaussians sorted into
// the lattice's lists; the tile's accumulators (Tf, Rf, Gf, Bf over [0, far], Tn, ... over
// [0, t0]) receive the exact terms as they come and the interpolated ones at the end.
struct GaussianSplat::ReducedTile {
    static constexpr int kMaxLattice = 96;  // (16 / 2 + 1)^2 = 81 at step 2, rounded up to 16
    static constexpr int kBlock = 4, kMaxBlocks = (kTile / kBlock) * (kTile / kBlock);
    // The lattice's lists of Gaussians (thread_local: their memory is kept from tile to tile).
    struct Lists {
        std::vector<std::uint32_t> batch, coarse, cancel, fine;
    };
    static Lists& thread_lists() {
        thread_local Lists lists;
        return lists;
    }

    const GaussianSplat& gs;
    const int t, x0, y0, w, h, n, s;
    const float *dx, *dy, *dz, *far, *t0;
    float *Tf, *Rf, *Gf, *Bf, *Tn, *Rn, *Gn, *Bn;
    const bool near_clip;
    // The tile's depth range (far = max(Dvp, t0); inf where no hit), and conservative
    // margins for the float depths (relative 1e-6).
    float dmin = std::numeric_limits<float>::infinity(), dmax = 0.0f;
    double far_lo = 0.0, far_hi = 0.0;
    // Lattice of rays at the film corners x0 + s u, y0 + s v covering the pixel centres,
    // padded to whole SIMD vectors with copies of the last ray; the sums on it.
    int nu = 0, nv = 0, m = 0, m_pad = 0;
    float lx[kMaxLattice], ly[kMaxLattice], lz[kMaxLattice];
    float cT[kMaxLattice] = {}, cR[kMaxLattice] = {}, cG[kMaxLattice] = {}, cB[kMaxLattice] = {};
    // Near segments on the lattice (near clip only): lattice t0 and sums.
    float lt0[kMaxLattice], nT[kMaxLattice] = {}, nR[kMaxLattice] = {}, nG[kMaxLattice] = {}, nB[kMaxLattice] = {};
    bool near_lattice = false;
    std::size_t lattice = 0, exact = 0, behind = 0, far_front = 0;
    // The 4x4 blocks, set up on the first Gaussian that needs them (prepare_blocks): a tile
    // whose Gaussians all lie wholly in front of or behind its surface never does.
    int perm[kTilePixels], block_start[kMaxBlocks + 1];
    float bx[kTilePixels], by[kTilePixels], bz[kTilePixels], bfar[kTilePixels];
    int n_blocks = 0;
    // Per regrouped pixel: its lattice cell (top-left lattice index) and bilinear weights,
    // and the exact terms (added to the accumulators in pixel order by finish).
    int lat[kTilePixels];
    float wgt[4 * kTilePixels];
    float eT[kTilePixels], eR[kTilePixels], eG[kTilePixels], eB[kTilePixels];
    // Per 4x4 block (cut_light_factor): the size blk_h of its surface patch (corner pixels'
    // surface points, the larger diagonal) and the largest deviation blk_err of a pixel's
    // surface point from the bilinear patch of the corners'; inf where the block is not
    // 4x4, has no hit at a corner, or lies near a light (h > 0.05 |p - s|, err > 0.01 |p - s|).
    float blk_h[kMaxBlocks], blk_err[kMaxBlocks];
    bool blocks_ready = false;
    // Next to a light's image the light terms peak (1 / |b^r - s|^2 along rays passing
    // close to the light): no interpolation there.
    bool exact_tile = false;
    // The Gaussians wholly in front go to the lattice in one Gaussian-major pass
    // (lattice_batch) on the plain path without noise (batch); the coarse lattice takes every
    // other node (needs an odd number of nodes per row and column).
    bool batch = false, fine_ok = false, coarse_ok = false;
    Lists& lists;
    // Far-field grids (build_far_field): the levels whose grids the tile reads; its pairs
    // wholly in front on those lie past splat_end_ (they only count here).
    unsigned use_far = 0;
    std::uint32_t walk_end = 0;
    bool far_field = false;

    ReducedTile(const GaussianSplat& splat, int tile, int x0_, int y0_, int w_, int h_, const float* dx_,
                const float* dy_, const float* dz_, const float* far_, const float* t0_, float* const acc[8]);
    // The rays of a lattice of spacing sp with nu_ x nv_ nodes: returns their count padded.
    int lattice_rays(int sp, int nu_, int nv_, float* x, float* y, float* z) const;
    void prepare_blocks();
    void surface_patches();
    // Sorts Gaussian i (of the tile's list) by its place against the tile's surface, and
    // evaluates or lists it.
    void add_gaussian(std::size_t i);
    void next_to_light(std::size_t i);
    void to_lattice(std::size_t i);
    void cut_by_surface(std::size_t i, bool on_grid);
    void replace_on_blocks(std::size_t i, bool on_grid, unsigned cut, unsigned front_blocks);
    void exact_blocks(std::size_t i, unsigned live);
    void cut_light_factor(std::size_t i, unsigned live);
    void surface_blocks(std::size_t i, const int* mode, const float* Tvp, const float* Tvr, const float* tr);
    // After the last Gaussian: the counts, the exact terms and the lattice lists' terms
    // (interpolated) into the accumulators.
    void finish();
    void lattice_sum(const std::vector<std::uint32_t>& list, int mm, const float* x, const float* y, const float* z,
                     float* T, float* R, float* G, float* B) const;
    void add_coarse_lattice();
    void add_far_field();
    void add_fine_lattice();
};

GaussianSplat::ReducedTile::ReducedTile(const GaussianSplat& splat, int tile, int x0_, int y0_, int w_, int h_,
                                        const float* dx_, const float* dy_, const float* dz_, const float* far_,
                                        const float* t0_, float* const acc[8])
    : gs(splat),
      t(tile),
      x0(x0_),
      y0(y0_),
      w(w_),
      h(h_),
      n(w_ * h_),
      s(splat.step_),
      dx(dx_),
      dy(dy_),
      dz(dz_),
      far(far_),
      t0(t0_),
      Tf(acc[0]),
      Rf(acc[1]),
      Gf(acc[2]),
      Bf(acc[3]),
      Tn(acc[4]),
      Rn(acc[5]),
      Gn(acc[6]),
      Bn(acc[7]),
      near_clip(splat.clip_start_ > 0.0),
      lists(thread_lists()) {
    for (int k = 0; k < n; ++k) {
        dmin = std::min(dmin, far[k]);
        dmax = std::max(dmax, far[k]);
    }
    nu = int((w - 0.5) / s) + 2;
    nv = int((h - 0.5) / s) + 2;
    m = nu * nv;
    m_pad = lattice_rays(s, nu, nv, lx, ly, lz);
    if (near_clip)
        for (int k = 0; k < m_pad; ++k)
            lt0[k] = float(gs.clip_start_ / (double(lx[k]) * gs.forward_.x + double(ly[k]) * gs.forward_.y +
                                             double(lz[k]) * gs.forward_.z));
    far_lo = double(dmin) * (1.0 - 1e-6);
    far_hi = double(dmax) * (1.0 + 1e-6);
    exact_tile = gs.exact_tile_[t] != 0;
    batch = gs.plain_ && !gs.noise_.on();
    fine_ok = batch && exact_tile && s == 4;
    coarse_ok = batch && (nu - 1) % 2 == 0 && (nv - 1) % 2 == 0;
    lists.batch.clear();
    lists.coarse.clear();
    lists.cancel.clear();
    lists.fine.clear();
    use_far = gs.far_grids_.empty() ? 0u : gs.tile_far_[t];
    walk_end = gs.splat_end_.empty() ? gs.bin_start_[t + 1] : gs.splat_end_[t];
    far_front = gs.bin_start_[t + 1] - walk_end;
    far_field = use_far != 0;
}

int GaussianSplat::ReducedTile::lattice_rays(int sp, int nu_, int nv_, float* x, float* y, float* z) const {
    const int mm = nu_ * nv_, mm_pad = (mm + 15) / 16 * 16;
    for (int v = 0; v < nv_; ++v)
        for (int u = 0; u < nu_; ++u) {
            const Vec3 d = glm::normalize(gs.D0_ + double(x0 + sp * u) * gs.Dx_ + double(y0 + sp * v) * gs.Dy_);
            const int k = v * nu_ + u;
            x[k] = float(d.x);
            y[k] = float(d.y);
            z[k] = float(d.z);
        }
    for (int k = mm; k < mm_pad; ++k) {
        x[k] = x[mm - 1];
        y[k] = y[mm - 1];
        z[k] = z[mm - 1];
    }
    return mm_pad;
}

// The pixels regrouped into blocks (perm: block order -> pixel), their lattice cells and
// weights, the exact terms zeroed, and the blocks' surface patches.
void GaussianSplat::ReducedTile::prepare_blocks() {
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
    surface_patches();
}

// blk_h and blk_err per block.
void GaussianSplat::ReducedTile::surface_patches() {
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
        for (const LightF& lf : gs.lf_) dl = std::min(dl, dist(px[0] + lf.vx, py[0] + lf.vy, pz[0] + lf.vz));
        if (hb <= 0.05f * dl && err <= 0.01f * dl) {
            blk_h[b] = hb;
            blk_err[b] = err;
        }
    }
}

void GaussianSplat::ReducedTile::add_gaussian(std::size_t i) {
    const GaussF& g = gs.g_[i];
    // A Gaussian far from every light (light_far_: the lattice's light-factor criterion)
    // or far from the lights whose image is next to the tile along their line of sight
    // (light_clear_) has no peak in its light terms here: classified as anywhere.
    const bool exact_here = exact_tile && !gs.light_far_[i] && !gs.light_clear(i, t);
    if (near_clip && g.near) {
        if (exact_here) {
            gs.splat_gaussian(i, n, dx, dy, dz, far, Tf, Rf, Gf, Bf);
            gs.splat_gaussian(i, n, dx, dy, dz, t0, Tn, Rn, Gn, Bn);
            ++exact;
            return;
        }
        // The near segment [0, t0] (t0 = clip_start / cos, smooth in the direction) on
        // the lattice; the far segment is classified below like any other.
        gs.splat_gaussian(i, m_pad, lx, ly, lz, lt0, nT, nR, nG, nB);
        near_lattice = true;
    }
    if (exact_here) {
        next_to_light(i);
        return;
    }
    // By the tile's depth range, else ray by ray (the sphere inflated by 1e-4 for
    // the float rounding of ts and h).
    const bool front = g.dist + g.radius <= far_lo, back = g.dist - g.radius >= far_hi;
    const bool on_grid = far_field && gs.level_[i] != 0 && (use_far >> (gs.level_[i] - 1) & 1u);
    if (back) {
        ++behind;
        if (on_grid) lists.cancel.push_back(std::uint32_t(i));
        return;
    }
    if (on_grid && front) {
        ++far_front;
        return;
    }
    if (front) {
        to_lattice(i);
        return;
    }
    cut_by_surface(i, on_grid);
}

// A Gaussian whose light terms may peak in this tile (add_gaussian's exact_here).
void GaussianSplat::ReducedTile::next_to_light(std::size_t i) {
    const GaussF& g = gs.g_[i];
    // Wholly behind the tile's surface: below the cull bound, as anywhere else.
    if (g.dist - g.radius >= far_hi) {
        ++behind;
        return;
    }
    // Wholly in front and clear of the lights at half the lattice's spacing: on the
    // fine lattice (spacing s / 2, the same light-factor bound tau; quarter only).
    if (fine_ok && g.dist + g.radius <= far_lo && gs.light_clear(i, t, 0.5)) {
        lists.fine.push_back(std::uint32_t(i));
        return;
    }
    gs.splat_gaussian(i, n, dx, dy, dz, far, Tf, Rf, Gf, Bf);
    ++exact;
}

// A Gaussian wholly in front of the tile's surface: on the lattice (listed for the coarse
// lattice or the Gaussian-major batch on the plain path without noise).
void GaussianSplat::ReducedTile::to_lattice(std::size_t i) {
    if (batch) {
        const bool coarse =
            coarse_ok && (gs.smooth_[i] == 2 || (gs.smooth_[i] == 1 && gs.light_clear(i, t, 2.0)));
        (coarse ? lists.coarse : lists.batch).push_back(std::uint32_t(i));
    } else {
        gs.splat_gaussian(i, m_pad, lx, ly, lz, nullptr, cT, cR, cG, cB);
    }
    ++lattice;
}

// A Gaussian whose cull sphere the tile's depth range does not place, block by block:
// blocks wholly behind are skipped; if every block is in front the Gaussian goes to the
// lattice, else the blocks not behind are evaluated exactly (or the lattice value replaced
// on them, when cheaper).
void GaussianSplat::ReducedTile::cut_by_surface(std::size_t i, bool on_grid) {
    const GaussF& g = gs.g_[i];
    prepare_blocks();
    const float R = float(g.radius * (1.0 + 1e-4));
    bool all_front = true;
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
        return;
    }
    if (all_front) {
        to_lattice(i);
        return;
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
        replace_on_blocks(i, on_grid, cut, front_blocks);
        ++lattice;
        return;
    }
    if (batch && live_px > 0) {
        cut_light_factor(i, live);
        ++exact;
        return;
    }
    exact_blocks(i, live);
}

// cut_by_surface's cheaper form: the Gaussian's lattice terms (or its far-field grid share)
// added to the lattice and subtracted, interpolated, on the blocks not wholly in front; its
// exact terms added on the blocks it cuts.
void GaussianSplat::ReducedTile::replace_on_blocks(std::size_t i, bool on_grid, unsigned cut, unsigned front_blocks) {
    float gT[kMaxLattice], gR[kMaxLattice], gG[kMaxLattice], gB[kMaxLattice];
    for (float* v : {gT, gR, gG, gB}) std::fill(v, v + m_pad, 0.0f);  // (a call per pair)
    if (on_grid) {  // its grid share (cancels it exactly where subtracted)
        float* share[4] = {gT, gR, gG, gB};
        gs.far_share(i, x0, y0, s, nu, nv, share);
    } else {
        gs.splat_gaussian(i, m_pad, lx, ly, lz, nullptr, gT, gR, gG, gB);
        add_to(gT, m_pad, cT);
        add_to(gR, m_pad, cR);
        add_to(gG, m_pad, cG);
        add_to(gB, m_pad, cB);
    }
    if (batch && cut != 0) cut_light_factor(i, cut);
    for (int b = 0; b < n_blocks; ++b) {
        if (front_blocks >> b & 1u) continue;
        const int k0 = block_start[b], nb = block_start[b + 1] - k0;
        if (!batch && (cut >> b & 1u)) {
            gs.splat_gaussian(i, nb, bx + k0, by + k0, bz + k0, bfar + k0, eT + k0, eR + k0, eG + k0, eB + k0);
        }
        if (lat[k0] == lat[k0 + nb - 1])  // the block inside one cell (quarter resolution)
            sub_interp_cell(nb, lat[k0], wgt + k0, nu, gT, gR, gG, gB, eT + k0, eR + k0, eG + k0, eB + k0);
        else
            sub_interp(nb, lat + k0, wgt + k0, nu, gT, gR, gG, gB, eT + k0, eR + k0, eG + k0, eB + k0);
    }
}

// Exact terms on the live blocks (runs of consecutive ones in one call).
void GaussianSplat::ReducedTile::exact_blocks(std::size_t i, unsigned live) {
    bool any_exact = false;
    for (int b = 0; b < n_blocks; ++b) {
        if (!(live >> b & 1u)) continue;
        int e = b;
        while (e + 1 < n_blocks && (live >> (e + 1) & 1u)) ++e;
        const int k0 = block_start[b], k1 = block_start[e + 1];
        gs.splat_gaussian(i, k1 - k0, bx + k0, by + k0, bz + k0, bfar + k0, eT + k0, eR + k0, eG + k0, eB + k0);
        any_exact = true;
        b = e;
    }
    if (any_exact) ++exact;
    else ++behind;
}

// A Gaussian the surface cuts in the tile (plain path, no noise): exact view terms on the
// live blocks (bit mask _live_ over the regrouped pixels), and the light side per block:
//  1: b^r = eye + max(ts, 0) d lies before the surface (ts < Dvp) at every pixel: the
//     light side exp(-T_i(s, b^r) - T_i(v, b^r)) / |b^r - s|^2 does not depend on the
//     depth; it is the lattice's (Dvp = inf), interpolated like it, times Tvp(Dvp);
//  2: a 4x4 block whose surface points deviate little from the bilinear patch of its
//     corner pixels' (blk_h, blk_err): where the surface lies before b^r (b^r = the surface
//     point p) the light side is exp(-Tvp) G(p), G(p) = sum_l w exp(-T_i(s_l, p)) /
//     |p - s_l|^2 smooth in p (scale 1/a, and |p - s_l|), evaluated at the 4 corner pixels
//     and interpolated (surface_blocks); the other pixels as in 1;
//  0: exact.
// The lattice (m_pad rays, view and light terms) only where it saves more light terms.
// Into eT, eR, eG, eB.
void GaussianSplat::ReducedTile::cut_light_factor(std::size_t i, unsigned live) {
    const GaussF& g = gs.g_[i];
    const std::size_t L = gs.lights_.size();
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
    // The light terms block by block (no per-pixel gathering), each block by its mode.
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
            (g.far_lights ? light_terms<true> : light_terms<false>)(g, gs.gl_[i * L + l], gs.lf_[l], nr, bx + k0,
                                                                   by + k0, bz + k0, Tvp + k0, Tvr + k0, tr + k0,
                                                                   eR + k0, eG + k0, eB + k0);
        b = e;
    }
    if (use_lattice) {
        float lTvp[kMaxLattice], lTvr[kMaxLattice], ltr[kMaxLattice], ones[kMaxLattice];
        float FR[kMaxLattice], FG[kMaxLattice], FB[kMaxLattice];  // (zeroed to m_pad: a call per pair)
        for (float* v : {FR, FG, FB}) std::fill(v, v + m_pad, 0.0f);
        (g.far_eye ? view_terms<true, true> : view_terms<true, false>)(g, m_pad, lx, ly, lz, nullptr, lTvp, lTvr,
                                                                        ltr);
        std::fill(ones, ones + m_pad, 1.0f);
        for (std::size_t l = 0; l < L; ++l)
            (g.far_lights ? light_terms<true> : light_terms<false>)(g, gs.gl_[i * L + l], gs.lf_[l], m_pad, lx, ly, lz,
                                                                   ones, lTvr, ltr, FR, FG, FB);
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
    surface_blocks(i, mode, Tvp, Tvr, tr);
}

// cut_light_factor's mode-2 blocks: G at the corner pixels (0,0), (3,0), (0,3), (3,3), in one
// batch, interpolated where the surface lies before b^r.
void GaussianSplat::ReducedTile::surface_blocks(std::size_t i, const int* mode, const float* Tvp, const float* Tvr,
                                                const float* tr) {
    const GaussF& g = gs.g_[i];
    const std::size_t L = gs.lights_.size();
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
        light_terms(g, gs.gl_[i * L + l], gs.lf_[l], nc, gx, gy, gz, gone, gzero, gtr, GR, GG, GB);
    for (int sb = 0; sb < n_sblk; ++sb) {
        const int k0 = block_start[sblk[sb]];
        float wt[16];
        surface_weight(16, Tvp + k0, Tvr + k0, tr + k0, bfar + k0, wt);
        add_surface_factor16(wt, GR + 4 * sb, GG + 4 * sb, GB + 4 * sb, eR + k0, eG + k0, eB + k0);
    }
}

// Gaussian-major (lattice_batch: lanes over the Gaussians, padded to 16, plus a call per
// node) or ray-major (splat_gaussian per Gaussian on the nodes padded to 16), whichever
// evaluates fewer terms: few Gaussians in a tile (e.g. 34 broad ones) go ray-major.
void GaussianSplat::ReducedTile::lattice_sum(const std::vector<std::uint32_t>& list, int mm, const float* x,
                                             const float* y, const float* z, float* T, float* R, float* G,
                                             float* B) const {
    const int nl = int(list.size()), nl_pad = (nl + 15) / 16 * 16, mm_pad = (mm + 15) / 16 * 16;
    if (mm * (nl_pad + 8) < nl * mm_pad) gs.lattice_batch(list.data(), nl, mm, x, y, z, T, R, G, B);
    else
        for (std::uint32_t i : list) gs.splat_gaussian(i, mm_pad, x, y, z, nullptr, T, R, G, B);
}

// The coarse lattice: every other node, then its bilinear interpolant spread onto the
// lattice (the same function as interpolating the coarse nodes at the pixels).
void GaussianSplat::ReducedTile::add_coarse_lattice() {
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
    lattice_sum(lists.coarse, mc, qx, qy, qz, qT, qR, qG, qB);
    for (int v = 0; v < nv; ++v)
        for (int u = 0; u < nu; ++u) {
            const int uc = u / 2, vc = v / 2;
            const float fu = (u & 1) ? 0.5f : 0.0f, fv = (v & 1) ? 0.5f : 0.0f;
            const int a = vc * nuc + uc, b = (u & 1) ? a + 1 : a, c = (v & 1) ? a + nuc : a, d = (v & 1) ? b + nuc : b;
            const float w00 = (1.0f - fu) * (1.0f - fv), w10 = fu * (1.0f - fv), w01 = (1.0f - fu) * fv,
                        w11 = fu * fv;
            const int k = v * nu + u;
            cT[k] += w00 * qT[a] + w10 * qT[b] + w01 * qT[c] + w11 * qT[d];
            cR[k] += w00 * qR[a] + w10 * qR[b] + w01 * qR[c] + w11 * qR[d];
            cG[k] += w00 * qG[a] + w10 * qG[b] + w01 * qG[c] + w11 * qG[d];
            cB[k] += w00 * qB[a] + w10 * qB[b] + w01 * qB[c] + w11 * qB[d];
        }
    gs.n_coarse_.fetch_add(lists.coarse.size(), std::memory_order_relaxed);
}

// The far-field grids at the lattice nodes, less the share of the Gaussians wholly behind
// the surface here (far_share: the same interpolation of their own terms, so it cancels to
// float rounding).
void GaussianSplat::ReducedTile::add_far_field() {
    float* c[4] = {cT, cR, cG, cB};
    for (int k = 0; k < kMaxFarLevel; ++k) {
        if (!(use_far >> k & 1u)) continue;
        const FarGrid& grid = gs.far_grids_[k];
        const float* g[4] = {grid.T.data(), grid.R.data(), grid.G.data(), grid.B.data()};
        add_far_grid(g, grid.h, grid.nx, 0, 0, x0, y0, s, nu, nv, c);
    }
    for (std::uint32_t i : lists.cancel) {
        float mT[kMaxLattice], mR[kMaxLattice], mG[kMaxLattice], mB[kMaxLattice];
        float* share[4] = {mT, mR, mG, mB};
        gs.far_share(i, x0, y0, s, nu, nv, share);
        for (int k = 0; k < m; ++k) {
            cT[k] -= mT[k];
            cR[k] -= mR[k];
            cG[k] -= mG[k];
            cB[k] -= mB[k];
        }
    }
}

// The fine lattice of an exact tile (spacing s / 2), interpolated to the pixels.
void GaussianSplat::ReducedTile::add_fine_lattice() {
    const int sf = s / 2, nuf = int((w - 0.5) / sf) + 2, nvf = int((h - 0.5) / sf) + 2, mf = nuf * nvf;
    float qx[kMaxLattice], qy[kMaxLattice], qz[kMaxLattice];
    float qT[kMaxLattice] = {}, qR[kMaxLattice] = {}, qG[kMaxLattice] = {}, qB[kMaxLattice] = {};
    lattice_rays(sf, nuf, nvf, qx, qy, qz);
    lattice_sum(lists.fine, mf, qx, qy, qz, qT, qR, qG, qB);
    interp_lattice(w, h, sf, nuf, qT, qR, qG, qB, Tf, Rf, Gf, Bf);
}

void GaussianSplat::ReducedTile::finish() {
    gs.n_lattice_.fetch_add(lattice + far_front + lists.fine.size(), std::memory_order_relaxed);
    gs.n_fine_.fetch_add(lists.fine.size(), std::memory_order_relaxed);
    gs.n_far_.fetch_add(far_front, std::memory_order_relaxed);
    gs.n_cancelled_.fetch_add(lists.cancel.size(), std::memory_order_relaxed);
    gs.n_exact_.fetch_add(exact, std::memory_order_relaxed);
    gs.n_behind_.fetch_add(behind, std::memory_order_relaxed);
    for (int k = 0; blocks_ready && k < n; ++k) {
        const int q = perm[k];
        Tf[q] += eT[k];
        Rf[q] += eR[k];
        Gf[q] += eG[k];
        Bf[q] += eB[k];
    }
    if (!lists.batch.empty()) lattice_sum(lists.batch, m, lx, ly, lz, cT, cR, cG, cB);
    if (!lists.coarse.empty()) add_coarse_lattice();
    if (far_field) add_far_field();
    if (!lists.fine.empty()) add_fine_lattice();
    if (lattice == 0 && !near_lattice && !far_field) return;
    // Bilinear interpolation of the lattice sums to the pixel centres.
    if (lattice > 0 || far_field) interp_lattice(w, h, s, nu, cT, cR, cG, cB, Tf, Rf, Gf, Bf);
    if (near_lattice) interp_lattice(w, h, s, nu, nT, nR, nG, nB, Tn, Rn, Gn, Bn);
}

void GaussianSplat::splat_tile_reduced(int t, int x0, int y0, int w, int h, const float* dx, const float* dy,
                                       const float* dz, const float* far, const float* t0, float* Tf, float* Rf,
                                       float* Gf, float* Bf, float* Tn, float* Rn, float* Gn, float* Bn) const {
    float* const acc[8] = {Tf, Rf, Gf, Bf, Tn, Rn, Gn, Bn};
    ReducedTile tile(*this, t, x0, y0, w, h, dx, dy, dz, far, t0, acc);
    for (std::uint32_t e = bin_start_[t]; e < tile.walk_end; ++e) tile.add_gaussian(bin_index_[e]);
    tile.finish();
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

}  // namespace airlight
