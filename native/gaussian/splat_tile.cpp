// splat_tile.cpp: GaussianSplat::splat_tile, one 16x16 tile's pixels into the passes: the
// tile's rays in structure-of-arrays form, the Gaussian terms (one branch-free loop over the
// pixels per (Gaussian, light) at full resolution, splat_reduced.cpp at half and quarter),
// the homogeneous term per light, and the transmittance and airlight. And eval_rays, the
// same quantities for single rays (edge supersamples), in chunks.
#include "gaussian/splat.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include "core/fast_erf.h"
#include "core/target_clones.h"
#include "gaussian/centre_depths.h"

namespace airlight {

namespace {

constexpr int kTilePixels = GaussianSplat::kTilePixels;

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

}  // namespace

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

// One chunk of eval_rays' rays (at most kChunk), and the Gaussians it evaluates.
struct GaussianSplat::RayChunk {
    static constexpr int kChunk = 64;
    const GaussianSplat& gs;
    const int m;
    std::vector<std::uint32_t>& gauss;  // the union of the Gaussians the segments reach
    float dx[kChunk], dy[kChunk], dz[kChunk], far[kChunk], tn[kChunk];
    double ddx[kChunk], ddy[kChunk], ddz[kChunk];
    bool any_near = false;
    // Reduced resolution: the rays' film positions, and whether the Gaussians in front of
    // every segment may come from the lattice.
    float fpx[kChunk], fpy[kChunk];
    float far_min = std::numeric_limits<float>::infinity();
    bool lattice_ok = false;
    float Tf[kChunk] = {}, Rf[kChunk] = {}, Gf[kChunk] = {}, Bf[kChunk] = {};
    float Tn[kChunk] = {}, Rn[kChunk] = {}, Gn[kChunk] = {}, Bn[kChunk] = {};
    float L0[kChunk][3] = {};

    RayChunk(const GaussianSplat& splat, int m_, std::vector<std::uint32_t>& gauss_)
        : gs(splat), m(m_), gauss(gauss_) {}
    void gather(const Vec3* dirs, const float* Dvp, const float* t0, std::vector<std::uint32_t>& stamp,
                std::uint32_t generation);
    void front_from_lattice();
    void add_gaussians();
    void add_homogeneous();
    void write(double* Tr, RGB* La) const;
};

// The chunk's rays (dirs, Dvp, t0: its first), and the Gaussians whose cull spheres their
// segments reach, each once (stamp[i] == generation: listed).
void GaussianSplat::RayChunk::gather(const Vec3* dirs, const float* Dvp, const float* t0,
                                     std::vector<std::uint32_t>& stamp, std::uint32_t generation) {
    gauss.clear();
    // Reduced resolution: the Gaussians binned to the tiles the rays fall in (a
    // superset of each ray's cull; those wholly behind every segment left out) instead
    // of one hierarchy traversal per ray. Full resolution keeps the per-ray traversal.
    const bool from_bins = gs.step_ > 1 && !gs.bin_start_.empty();
    float far_max = 0.0f;
    for (int k = 0; k < m; ++k) {
        tn[k] = t0 ? t0[k] : 0.0f;
        far[k] = std::max(Dvp[k], tn[k]);
        far_max = std::max(far_max, far[k]);
    }
    const double far_hi = double(far_max) * (1.0 + 1e-6);
    // Reduced resolution, plain path: the Gaussians wholly in front of every segment of
    // the chunk come from the lattice as in splat_tile (interpolated at the rays' film
    // positions), unless a ray lies outside the image or in a tile kept exact.
    lattice_ok = from_bins && gs.plain_ && !gs.noise_.on();
    for (int k = 0; k < m; ++k) far_min = std::min(far_min, far[k]);
    int last_tile = -1;
    for (int k = 0; k < m; ++k) {
        const Vec3& d = dirs[k];
        ddx[k] = d.x;
        ddy[k] = d.y;
        ddz[k] = d.z;
        dx[k] = float(d.x);
        dy[k] = float(d.y);
        dz[k] = float(d.z);
        any_near = any_near || tn[k] > 0.0f;
        if (from_bins) {
            const double lam = glm::dot(gs.q0_, d);
            const double px = lam > 0.0 ? glm::dot(gs.q1_, d) / lam : -1.0,
                         py = lam > 0.0 ? glm::dot(gs.q2_, d) / lam : -1.0;
            if (px >= 0.0 && py >= 0.0 && px <= double(gs.W_) && py <= double(gs.H_)) {
                const int tx = std::min(gs.tiles_x_ - 1, int(px) / kTile),
                          ty = std::min(gs.tiles_y_ - 1, int(py) / kTile);
                const int t = ty * gs.tiles_x_ + tx;
                fpx[k] = float(px);
                fpy[k] = float(py);
                if (gs.exact_tile_[t]) lattice_ok = false;
                // (the chunk's rays mostly share a tile: its list is gathered once)
                if (t == last_tile) continue;
                last_tile = t;
                for (std::uint32_t e = gs.bin_start_[t]; e < gs.bin_start_[t + 1]; ++e) {
                    const std::uint32_t i = gs.bin_index_[e];
                    if (stamp[i] == generation) continue;
                    stamp[i] = generation;
                    // (a Gaussian reaching a near segment [0, t0] is not behind either)
                    if (gs.g_[i].dist - gs.g_[i].radius < far_hi) gauss.push_back(i);
                }
                continue;
            }
        }
        lattice_ok = false;
        gs.medium_.for_each_near(gs.eye_, d, double(far[k]), [&](std::size_t i) {
            if (stamp[i] != generation) {
                stamp[i] = generation;
                gauss.push_back(std::uint32_t(i));
            }
        });
    }
}

// Where lattice_ok: the Gaussians wholly in front of every segment (and not reaching a near
// segment) on the lattice nodes (film s u, s v, as splat_tile_reduced's) around the rays,
// interpolated at each ray, and taken off the list.
void GaussianSplat::RayChunk::front_from_lattice() {
    const int s = gs.step_;
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
    if (nu * nv > kMaxNodes) return;
    thread_local std::vector<std::uint32_t> front, rest;
    front.clear();
    rest.clear();
    // (those reaching a near segment [0, t0] stay per ray: their near terms)
    const double tn_max = any_near ? double(*std::max_element(tn, tn + m)) : 0.0;
    for (std::uint32_t i : gauss) {
        const bool near = any_near && gs.g_[i].dist < gs.g_[i].radius + tn_max;
        (!near && gs.g_[i].dist + gs.g_[i].radius <= far_lo ? front : rest).push_back(i);
    }
    if (front.empty()) return;
    float lx[kMaxNodes], ly[kMaxNodes], lz[kMaxNodes];
    float cT[kMaxNodes] = {}, cR[kMaxNodes] = {}, cG[kMaxNodes] = {}, cB[kMaxNodes] = {};
    for (int v = 0; v < nv; ++v)
        for (int u = 0; u < nu; ++u) {
            const Vec3 d = glm::normalize(gs.D0_ + double(s * (u0 + u)) * gs.Dx_ + double(s * (v0 + v)) * gs.Dy_);
            lx[v * nu + u] = float(d.x);
            ly[v * nu + u] = float(d.y);
            lz[v * nu + u] = float(d.z);
        }
    gs.lattice_batch(front.data(), int(front.size()), nu * nv, lx, ly, lz, cT, cR, cG, cB);
    const float inv_s = 1.0f / float(s);
    for (int k = 0; k < m; ++k) {
        const float fx = fpx[k] * inv_s - float(u0), fy = fpy[k] * inv_s - float(v0);
        const int u = std::min(nu - 2, int(fx)), v = std::min(nv - 2, int(fy));
        const float wx = fx - float(u), wy = fy - float(v);
        const int a = v * nu + u, b = a + 1, c = a + nu, d = c + 1;
        const float w00 = (1.0f - wx) * (1.0f - wy), w10 = wx * (1.0f - wy), w01 = (1.0f - wx) * wy, w11 = wx * wy;
        Tf[k] += w00 * cT[a] + w10 * cT[b] + w01 * cT[c] + w11 * cT[d];
        Rf[k] += w00 * cR[a] + w10 * cR[b] + w01 * cR[c] + w11 * cR[d];
        Gf[k] += w00 * cG[a] + w10 * cG[b] + w01 * cG[c] + w11 * cG[d];
        Bf[k] += w00 * cB[a] + w10 * cB[b] + w01 * cB[c] + w11 * cB[d];
    }
    gauss.swap(rest);
}

// The listed Gaussians on every ray of the chunk, with the splat's kernels.
void GaussianSplat::RayChunk::add_gaussians() {
    for (std::uint32_t i : gauss) {
        gs.splat_gaussian(i, m, dx, dy, dz, far, Tf, Rf, Gf, Bf);
        // The near segment [0, t0] only meets Gaussians near the eye (as in bin()).
        if (any_near &&
            glm::length(gs.medium_.centre(i) - gs.eye_) < gs.g_[i].radius + double(*std::max_element(tn, tn + m)))
            gs.splat_gaussian(i, m, dx, dy, dz, tn, Tn, Rn, Gn, Bn);
    }
}

// The homogeneous terms per light (as splat_tile's) into L0.
void GaussianSplat::RayChunk::add_homogeneous() {
    if (!(gs.medium_.beta0() > 0.0)) return;
    const std::size_t L = gs.lights_.size();
    double cos_gamma[kChunk];
    float value[kChunk];
    for (std::size_t l = 0; l < L; ++l) {
        const double D = gs.Dsv_[l];
        const Vec3 sv = D > 0.0 ? (gs.lights_[l] - gs.eye_) / D : Vec3(0.0);
        for (int k = 0; k < m; ++k)
            cos_gamma[k] = D > 0.0 ? std::clamp(ddx[k] * sv.x + ddy[k] * sv.y + ddz[k] * sv.z, -1.0, 1.0) : 1.0;
        if (!gs.extra_.custom_background.empty() && gs.extra_.custom_background[l]) continue;
        gs.homogeneous(cos_gamma, l, far, any_near ? tn : nullptr, m, value);
        const RGB w = gs.weight0_[l] * gs.Csv_[l];
        for (int k = 0; k < m; ++k)
            for (int c = 0; c < 3; ++c) L0[k][c] += float(w[c]) * value[k];
    }
    gs.background_extra(ddx, ddy, ddz, far, any_near ? tn : nullptr, m, L0);
}

// Transmittance and airlight of the chunk's rays (Tr, La: its first), as splat_tile's.
void GaussianSplat::RayChunk::write(double* Tr, RGB* La) const {
    const double beta0 = gs.medium_.beta0();
    for (int k = 0; k < m; ++k) {
        const double seg = double(far[k]) - double(tn[k]);
        Tr[k] = std::exp(-(background_depth(beta0, seg) + std::max(0.0, double(Tf[k]) - double(Tn[k]))));
        const double scale_g = tn[k] > 0.0f ? std::exp(double(Tn[k])) : 1.0;
        const double scale = tn[k] > 0.0f ? scale_g * std::exp(beta0 * double(tn[k])) : 1.0;
        const RGB g(double(Rf[k]) - Rn[k], double(Gf[k]) - Gn[k], double(Bf[k]) - Bn[k]);
        La[k] = seg > 0.0 ? scale * glm::max(g, RGB(0.0)) +
                                scale_g * RGB(double(L0[k][0]), double(L0[k][1]), double(L0[k][2]))
                          : RGB(0.0);
    }
}

void GaussianSplat::eval_rays(const Vec3* dirs, const float* Dvp, const float* t0, int n, double* Tr, RGB* La) const {
    // Chunks of up to kChunk rays (the bake passes each edge pixel's sub-samples together,
    // so a chunk's rays are close): the union of the Gaussians whose cull spheres the
    // chunk's segments reach, each evaluated over the whole chunk with the splat's kernels.
    // Reduced resolution gathers from the tile bins: 4 pixels' sub-samples per chunk
    // amortise the per-Gaussian call overhead (neighbouring edge pixels share tiles).
    const int chunk = step_ > 1 && !bin_start_.empty() ? RayChunk::kChunk : 16;
    thread_local std::vector<std::uint32_t> stamp;
    thread_local std::uint32_t generation = 0;
    if (stamp.size() != medium_.size()) {
        stamp.assign(medium_.size(), 0);
        generation = 0;
    }
    std::vector<std::uint32_t> gauss;
    for (int k0 = 0; k0 < n; k0 += chunk) {
        RayChunk c(*this, std::min(chunk, n - k0), gauss);
        if (++generation == 0) {  // wrapped: reset the stamps
            std::fill(stamp.begin(), stamp.end(), 0);
            generation = 1;
        }
        c.gather(dirs + k0, Dvp + k0, t0 ? t0 + k0 : nullptr, stamp, generation);
        if (c.lattice_ok) c.front_from_lattice();
        c.add_gaussians();
        c.add_homogeneous();
        c.write(Tr + k0, La + k0);
    }
}

}  // namespace airlight
