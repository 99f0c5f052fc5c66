// splat.h: the bake's fast path for Gaussian fog (Fogshop, Zhou et al. 2007, §5.2-5.3 and the
// noise of §5.5): screen-space splatting of the Gaussians' cull spheres into 16x16 pixel
// tiles, float SIMD evaluation of the paper's per-(pixel, Gaussian) terms.
//
// Per pixel (perspective camera at the eye v, unit direction r, near distance t0 along
// the ray, first hit Dvp) it computes the same quantities as the exact double path
// (FogshopAirlight::eval, used by FogModel::eval_gaussians before; still the reference):
//   T  = beta0 (Dvp - t0) + sum_i [T_i(v, Dvp) - T_i(v, t0)]
//   La = exp(T(v, t0)) sum_l [ Lg_l(Dvp) - Lg_l(t0) ] + sum_l w_l C_sv,l exp(Tg(v, t0)) L0seg_l
//   Lg_l(t) = sum_i w_{l,i} f1'_{l,i} exp(-T_i(s_l, b_i^r) - T_i(v, b_i^r)) T_i(v, t) / |b_i^r - s_l|^2
// with b_i^r the projection of b_i on the ray clamped to [0, t], f1' = f1 exp(T_i(s, b_i) +
// T_i(v, b_i)) (the other Gaussians and beta0 on s -> b_i -> v), w_{l,i} = albedo_i I0_l /
// (4 pi) (albedo_i: the Gaussian's own colour if Gaussians::albedo is given, else the
// medium's), w_l = medium albedo I0_l, and L0seg the homogeneous Sun 2005 term of the
// segment [t0, Dvp] attenuated from the near point (sun05_batch.h; F table or exact F).
// Differences to the exact path: float arithmetic with fast_erf.h (error bound there;
// splat_test.cpp measures the whole image against the exact path), and every Gaussian
// whose cull sphere's screen bounds cover a pixel is evaluated there (a superset of the
// per-ray cull, whose skipped terms are < cull_eps each; at half and quarter resolution the
// spheres are sized for kReducedCullEps instead).
//
// Noise (§5.5; off when amplitude = 0, then the code path is the one without noise): per
// (pixel, Gaussian) the view direction used for T_i(v, Dvp) and T_i(v, t0) is perturbed,
//   r' = normalize(r + amplitude (R_i / |b_i - v|) N(b_i^r / scale + offset)),
// N the vector gradient noise of noise.h (world space, so it sticks to the scene when the
// camera moves; _offset_ animates it), R_i the Gaussian's cull radius; the integration
// distance is unchanged, and the light-side terms (f0, b_i^r) use the unperturbed ray,
// as in the paper. It perturbs both the screen optical depth and the airlight.
//
// GaussianSplat's parts, one file each: splat.cpp (set-up; one Gaussian's terms on many
// rays), splat_bin.cpp (bin: the tiles' lists), splat_tile.cpp (a tile's pixels; edge rays),
// splat_reduced.cpp (half and quarter resolution: the lattice), splat_far_field.cpp (the
// far-field grids); their float kernels in splat_kernels.h and splat_interp.h. The light
// side's set-up takes its optical depths from centre_depths.h.
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <limits>
#include <memory>
#include <vector>

#include "core/phase.h"
#include "gaussian/airlight.h"
#include "gaussian/medium.h"
#include "core/scene.h"
#include "core/special_f.h"
#include "homogeneous/spot_light.h"
// (bindings/bind_rbf.cpp reaches rbf_preview_factors through this header; drop this include
// once it includes gaussian/preview_factors.h itself)
#include "gaussian/preview_factors.h"

namespace airlight {

struct GaussianNoise {
    double amplitude = 0.0;  // 0: off (bit-identical to no noise)
    double scale = 1.0;      // world-space size of the noise cells in m (> 0)
    Vec3 offset{0.0};        // added to the noise lookup point (in cells): animate it
    bool on() const { return amplitude > 0.0; }
};

// Throws std::invalid_argument unless amplitude >= 0, scale > 0 and all are finite.
void validate_noise(const GaussianNoise& noise);

// Lights and phases beyond isotropic point lights (the Fogshop terms generalised; all
// optional, the defaults keep the plain path bit-identical). Per (pixel, Gaussian i, light):
//  - phase: the term is multiplied by 4 pi p(cos theta) at b_i^r, theta between the light's
//    propagation direction there and the direction towards the eye (phase.h convention);
//  - spot (spot[l] set): times the Cycles profile spot_profile(cone[l], .) of the direction
//    light -> b_i^r (spot_light.h), I0 being the spot's on-axis intensity;
//  - sun j (propagation direction sun_w[j], irradiance sun_E[j]): f0 = E p(cos theta) (no
//    1/d^2, theta fixed along the ray), Gaussian i's own light-side depth the exact half-line
//    integral from b_i^r towards the sun (erfc form, to infinity), f1 = exp(-T_sun(b_i) -
//    T(v, b_i)) with T_sun(b_i) the other Gaussians' half-line depths from b_i plus the
//    homogeneous part of sunlight_layer.h: beta0 (fog_top - z)/mu_s below a finite top (0 above
//    it; no sunlight for mu_s <= 0), nothing without a top (Hoffman-Preetham's unattenuated
//    sun). The Gaussians are not cut at the top (the view side does not see the top either).
//  - background (beta0) term of light l (l < L: point / spot, l = L + j: sun j), per unit
//    weight (albedo I0, or albedo E for suns) along the unit direction d from the eye over
//    [t0, Dvp], attenuated from t0: _background_ (the bake's homogeneous model for that light
//    and phase). It is scaled like Fogshop's C_sv: by the Gaussians' transmittance from the
//    light to the eye (suns: along the half-line from the eye towards the sun). Used for the
//    lights with custom_background[l] set (and every sun); the others keep the sun05 term.
struct GaussianSplatLights {
    PhaseFunction phase;
    std::vector<char> spot;          // per point light (size L or empty: none is a spot)
    std::vector<SpotCone> cone;      // per point light (read where spot[l])
    std::vector<Vec3> sun_w;         // unit propagation directions of the sun lamps
    std::vector<RGB> sun_E;          // their irradiance (W/m^2 per channel)
    double fog_top = std::numeric_limits<double>::infinity();
    std::vector<char> custom_background;  // per point light (size L or empty: none)
    std::function<double(std::size_t l, const Vec3& d, double t0, double Dvp)> background;
};

class GaussianSplat {
  public:
    static constexpr int kTile = 16;
    static constexpr int kTilePixels = kTile * kTile;
    // Per-Gaussian optical depth below which a ray skips a Gaussian at half and quarter
    // resolution (the cull spheres of bin(); full resolution keeps the medium's cull_eps,
    // 1e-7 by default). Tied to the lattice's own error: at 1e-7 a quarter of the
    // (tile, Gaussian) pairs of bench_rbf.py's 3000 Gaussians held only terms below 1e-5;
    // quarter at 1e-5 costs 30 % less CPU there, its airlight error against full rising from
    // 0.03 % to 0.14 % at most (transmittance 0.49 -> 0.50 %), half at 1e-6 14 % less for
    // no measurable change (benchmarks/bench_rbf.py).
    static constexpr double kReducedCullEps[2] = {1e-6, 1e-5};  // half, quarter
    // a sqrt(D^2 - R^2) >= kFarStart (D the distance of the eye or a light from a Gaussian's
    // centre, R its cull radius): every point of the cull sphere lies at least that far (in
    // units of 1 / a) along the path from there, so erfc(a t) <= erfc(4.5) = 2e-10 there.
    static constexpr double kFarStart = 4.5;

    // _lights_ and _I0_ (W/sr per channel) of the point lights; _medium_albedo_ the
    // homogeneous medium's albedo; _albedo_ 3 per Gaussian or empty (use medium_albedo);
    // _table_ F table for the homogeneous term (nullptr = exact F). The medium and table
    // must outlive this object. Does Fogshop's per-(light, Gaussian) precomputation.
    GaussianSplat(const GaussianMedium& medium, const Vec3& eye, const std::vector<Vec3>& lights,
                  const std::vector<RGB>& I0, const RGB& medium_albedo, const std::vector<double>& albedo,
                  const SpecialFTable* table, const GaussianNoise& noise, int threads = 0,
                  const GaussianSplatLights* extra = nullptr);
    // Hands the pair list's memory to the next GaussianSplat's bin() (splat_bin.cpp, pair_pool).
    ~GaussianSplat();

    // Bins the Gaussians into tiles for the image W x H whose pixel (px, py) (film
    // position, pixel centres at +0.5) looks along D0 + px Dx + py Dy from the eye;
    // _forward_ the unit view axis, _clip_start_ the near clip depth along it (0: none).
    // _step_ (1, 2 or 4) is the resolution of the Gaussian terms' evaluation, see
    // splat_tile; 1 (full) is the plain splat. Throws std::invalid_argument otherwise.
    // _depth_ (optional; W x H, as splat_tile will read it): at step > 1 on the plain path
    // without noise it lets bin() put broad Gaussians on the far-field grids (splat_far_field.cpp).
    void bin(const Vec3& D0, const Vec3& Dx, const Vec3& Dy, const Vec3& forward, int W, int H, double clip_start,
             int step = 1, const float* depth = nullptr);
    int step() const { return step_; }
    int num_tiles() const { return tiles_x_ * tiles_y_; }
    // Pairs (tile, Gaussian) binned: the work of the splat.
    std::size_t num_pairs() const { return bin_index_.size(); }
    // Pairs binned to tile t (after bin()).
    std::size_t tile_pairs(int t) const { return bin_start_[std::size_t(t) + 1] - bin_start_[std::size_t(t)]; }
    // A cost estimate of tile t for scheduling: its pairs, those on far-field grids (a
    // grid share read, or cancelled) counted a quarter.
    std::size_t tile_cost(int t) const {
        return tile_far_pairs_.empty() ? 4 * tile_pairs(t) : 4 * tile_pairs(t) - 3 * tile_far_pairs_[std::size_t(t)];
    }

    // Evaluates tile _t_ (after bin()): reads depth[W H] (distance from the eye, inf: no
    // hit), writes transmittance (3 equal floats per pixel) and airlight (RGB) of the
    // tile's pixels into the W x H images. Thread safe for distinct tiles.
    //
    // At reduced resolution (step s = 2 or 4) the Gaussian terms are evaluated exactly only
    // where the tile's surface cuts a Gaussian; the others come from a lattice of rays every s
    // pixels, interpolated bilinearly, or from the far-field grids (splat_reduced.cpp and
    // splat_far_field.cpp give an overview; docs/architecture.md the criteria and bounds).
    void splat_tile(int t, const float* depth, float* transmittance, float* airlight) const;
    // Pair counts of the last splat at step > 1 (all tiles; reset by bin()): lattice
    // (interpolated), exact per pixel, skipped behind the surface; coarse: of the lattice
    // pairs, those on the coarse lattice (every other node, see splat_reduced.cpp).
    // far: of the lattice pairs, those served by the far-field grids; far_cancelled: of the
    // pairs behind, those whose grid share was cancelled; far_gaussians and far_nodes: the
    // Gaussians on the grids and their (grid node, Gaussian) evaluations. fine: of the lattice
    // pairs, those on the fine lattice of a tile next to a light's image (splat_reduced.cpp).
    struct ReducedCounts {
        std::size_t lattice = 0, exact = 0, behind = 0, coarse = 0, far = 0, far_cancelled = 0, far_gaussians = 0,
                    far_nodes = 0, fine = 0;
    };
    ReducedCounts reduced_counts() const;

    // Rays from the eye with unit directions dirs[k], segment [t0[k], Dvp[k]] (t0 null: 0):
    // the same quantities as splat_tile (Tr, RGB airlight), for edge supersampling. Rays go
    // in chunks of 16, 64 at step > 1 (pass neighbouring rays together, e.g. one pixel's
    // sub-samples); each chunk evaluates the union of the Gaussians whose cull spheres its
    // segments reach (from the medium's hierarchy) with the splat's kernels. At step > 1
    // (after bin()) the union comes from the tile bins, and on the plain path without noise
    // the Gaussians in front of every segment of a chunk come from the lattice (nodes around
    // the chunk's film positions, interpolated at each ray), as for the centre samples.
    // Thread safe.
    void eval_rays(const Vec3* dirs, const float* Dvp, const float* t0, int n, double* Tr, RGB* La) const;

    // Exact double reference for one ray (no noise support; FogshopAirlight::eval with
    // per-Gaussian albedo, its f1 in double): RGB airlight of the segment [0, Dvp] from
    // the eye. Sets up the reference on first use: not thread safe (tests).
    RGB eval_exact(const Vec3& dir, double Dvp) const;


    // Float per-Gaussian data (relative to the eye).
    struct GaussF {
        float rx, ry, rz;      // b - eye
        float a, a2, k0;       // scale, a^2, c sqrt(pi) / (2 a)
        // k0 exp(-a^2 |b - eye|^2): the eye-side term k0 e^{-a^2 h^2} erfc(a |ts|) of a ray
        // from the eye equals ke erfcx(a |ts|) (h^2 + ts^2 = |b - eye|^2; fast_erf.h)
        float ke;
        float nscale;          // noise: amplitude R / |b - eye|
        bool near;             // the cull sphere reaches the near clip ball
        // (bin()) the eye, and every point light, lies >= kFarStart / a before the cull
        // sphere along any path to a point in it: the erfc at that end is < 2e-10 and left
        // out of the view (far_eye) and light-side (far_lights) optical depths
        bool far_eye = false, far_lights = false;
        double dist, radius;   // |b - eye| and the cull radius R
    };
    // Per (Gaussian, light): b - s, the RGB weight albedo I0 f1' / (4 pi) and k0 exp(-a^2
    // |b - s|^2) (the light-side ke, as GaussF's).
    struct GaussLightF {
        float sx, sy, sz;
        float wr, wg, wb;
        float ke;
    };
    struct LightF {
        float vx, vy, vz;  // eye - s
        // Spots (GaussianSplatLights): unit axis, cos(size / 2) and the smoothstep width;
        // an area light's Spread (SpotCone): the profile spread_a c - spread_b sqrt(1 - c^2).
        float ax = 0.0f, ay = 0.0f, az = 0.0f, cos_half = 0.0f, smooth = 0.0f;
        float spread_a = 1.0f, spread_b = 0.0f;
    };

  private:
    // The steps of bin(), of splat_tile_reduced (one tile), of build_far_field and of
    // eval_rays (one chunk of rays), with their state: splat_bin.cpp, splat_reduced.cpp,
    // splat_far_field.cpp, splat_tile.cpp.
    struct Binning;
    struct ReducedTile;
    struct FarBuild;
    struct RayChunk;
    // The suns' f1 weights and C factors (gs_, Csun_) from the eye row of _depth_ (constructor).
    void sun_weights(const std::vector<double>& depth);
    // Accumulates Gaussian g's optical depth over [0, tend[k]] into accT and its airlight
    // (all lights) into accR/G/B for the n rays (dx, dy, dz). At step_ > 1, tend =
    // nullptr means +inf for every ray (the lattice).
    void splat_gaussian(std::size_t g, int n, const float* dx, const float* dy, const float* dz, const float* tend,
                        float* accT, float* accR, float* accG, float* accB) const;
    // The Gaussian terms of tile (x0, y0, w x h, n pixels) at step_ > 1 (splat_reduced.cpp)
    // into the accumulators: far segment (tend = far) and near segment (t0).
    void splat_tile_reduced(int t, int x0, int y0, int w, int h, const float* dx, const float* dy, const float* dz,
                            const float* far, const float* t0, float* Tf, float* Rf, float* Gf, float* Bf, float* Tn,
                            float* Rn, float* Gn, float* Bn) const;
    // The Dvp = inf terms of Gaussians idx[0..n) (wholly in front; plain path, no noise) on
    // the m lattice rays (lx, ly, lz), added to T, R, G, B (lattice_gaussian_major).
    void lattice_batch(const std::uint32_t* idx, int n, int m, const float* lx, const float* ly, const float* lz,
                       float* T, float* R, float* G, float* B) const;
    // Homogeneous term of light l for n rays: segment [t0, Dvp] attenuated from t0.
    void homogeneous(const double* cos_gamma, std::size_t l, const float* Dvp, const float* t0, int n,
                     float* out) const;
    // The light terms of Gaussian i (all lights, suns included) from its view terms, when
    // !plain_ (the plain path calls light_terms directly).
    void light_loop(std::size_t i, int n, const float* dx, const float* dy, const float* dz, const float* Tvp,
                    const float* Tvr, const float* tr, float* accR, float* accG, float* accB) const;
    // Adds the background terms of the lights with a custom background (GaussianSplatLights) and
    // of the suns, scaled by their C factors, to L0 for n rays.
    void background_extra(const double* ddx, const double* ddy, const double* ddz, const float* far,
                          const float* t0, int n, float (*L0)[3]) const;

    const GaussianMedium& medium_;
    const SpecialFTable* table_;
    Vec3 eye_;
    std::vector<Vec3> lights_;
    std::vector<RGB> I0_;
    RGB medium_albedo_;
    std::vector<RGB> weight0_;  // medium albedo * I0 per light (homogeneous term)
    GaussianNoise noise_;
    int threads_ = 0;
    std::vector<double> Dsv_, Csv_;
    mutable std::unique_ptr<FogshopAirlight> exact_;
    std::vector<double> albedo_;  // 3 per Gaussian (resolved: medium albedo if none given)
    std::vector<GaussF> g_;
    std::vector<GaussLightF> gl_;  // [i * L + l]
    std::vector<LightF> lf_;
    float eye_f_[3];
    // Extensions (GaussianSplatLights): plain_ = isotropic point lights only (the original kernels).
    bool plain_ = true;
    GaussianSplatLights extra_;
    std::vector<GaussLightF> gs_;  // [i * S + j] per sun: sx, sy, sz unused
    std::vector<double> Csun_;     // per sun: Gaussians' transmittance from the eye towards it
    // Binning.
    int W_ = 0, H_ = 0, tiles_x_ = 0, tiles_y_ = 0;
    Vec3 D0_{0.0}, Dx_{0.0}, Dy_{0.0}, forward_{0.0, 0.0, -1.0};
    double clip_start_ = 0.0;
    int step_ = 1;
    Vec3 q0_{0.0}, q1_{0.0}, q2_{0.0};  // film coordinates of a direction d: (q1.d, q2.d) / q0.d
    // step_ > 1: tiles where a Gaussian's b^r may come closer to a light than the lattice
    // allows: their Gaussians are checked one by one (light_far_, light_clear), their edge
    // samples skip the lattice
    std::vector<unsigned char> exact_tile_;
    mutable std::atomic<std::size_t> n_lattice_{0}, n_exact_{0}, n_behind_{0}, n_coarse_{0}, n_fine_{0};
    // step_ > 1: per Gaussian, coarse lattice allowed: 2 everywhere, 1 in tiles whose rays keep
    // its b^r far enough from the lights (light_clear), 0 nowhere (too narrow)
    std::vector<unsigned char> smooth_;
    // step_ > 1: per Gaussian, far enough from every light for the lattice even in tiles
    // next to a light's image (exact_tile_)
    std::vector<unsigned char> light_far_;
    // step_ > 1: per (tile, light): the least closest approach of the tile's rays to the
    // light (h_min), cos and sin of their largest angle to its direction (0 and 1 past 90
    // degrees); light_min_: the lattice's light-factor distance per unit distance from the eye.
    struct TileLight {
        float h_min = 0.0f, cos_max = 0.0f, sin_max = 1.0f;
    };
    std::vector<TileLight> tile_light_;
    double light_min_ = 0.0;
    // Whether Gaussian i's b^r stays factor light_min_ d_i away from every light whose image is
    // next to tile t, for all of the tile's rays (splat_reduced.cpp): factor 1 is the lattice's
    // criterion at spacing s, 2 the coarse lattice's (2 s), 1/2 a lattice at spacing s / 2.
    bool light_clear(std::size_t i, int t, double factor = 1.0) const;
    // Far-field grids (splat_far_field.cpp), built by bin() from the depth: level k (1..) has
    // spacing h = step_ kFarSpacing[k - 1] pixels, node (P, Q) at film (h (P - 1), h (Q - 1)),
    // sums of the Dvp = inf terms of the Gaussians with level_[i] = k (0: on the tile lattices).
    struct FarGrid {
        int h = 0, nx = 0, ny = 0;
        std::vector<float> T, R, G, B;  // [Q nx + P]
        std::vector<float> dx, dy, dz;  // the nodes' unit ray directions
    };
    std::vector<FarGrid> far_grids_;       // [k - 1]; empty: no far field
    std::vector<unsigned char> level_;     // per Gaussian
    std::vector<std::uint16_t> tile_far_;  // per tile: bit k - 1 set when it reads the level-k grid
    std::vector<std::uint32_t> tile_far_pairs_;  // per tile: its pairs with a far-field Gaussian
    // Per tile (empty: no grids): the end of the pairs splat_tile_reduced walks; those after
    // it, up to the list's end, lie wholly in front on a grid the tile reads.
    std::vector<std::uint32_t> splat_end_;
    mutable std::atomic<std::size_t> n_far_{0}, n_cancelled_{0};
    std::size_t far_gaussians_ = 0, far_nodes_ = 0;
    // Levels 1..9: spacings step_ times 2, 3, 4, 6, 8, 12, 16, 24, 32 pixels (a ratio of ~1.41
    // between levels: with powers of 2 a Gaussian's grid had ~1.4x the nodes on average).
    static constexpr int kMaxFarLevel = 9;
    static constexpr int kFarSpacing[kMaxFarLevel] = {2, 3, 4, 6, 8, 12, 16, 24, 32};
    // bin()'s far-field pass in two halves around its list fill: far_candidates picks each
    // Gaussian's candidate level and the tiles' depth ranges (false: none, no grids); the
    // fill then counts per candidate the tiles it lies wholly in front of / behind / cuts
    // (by depth range; counts[3 i + 0, 1, 2]), and build_far_field chooses the Gaussians
    // that go on grids and builds those.
    struct FarScratch {
        std::vector<unsigned char> cand;  // per Gaussian: candidate level (0: none)
        std::vector<float> span;          // per candidate: dist -/+ radius
        std::vector<float> tmin, tmax;    // per tile: depth range
        std::unique_ptr<std::atomic<std::uint32_t>[]> counts;
    };
    bool far_candidates(const float* depth, const std::vector<int>& rect, FarScratch& far);
    void build_far_field(const std::vector<int>& rect, FarScratch& far);
    // Evaluations Gaussian i costs on a quarter tile's lattice when in front (the far-field
    // cost models): 25 nodes, 9 on the coarse lattice, ~17 where that depends on the tile.
    float lattice_evals(std::size_t i) const { return smooth_[i] == 2 ? 9.0f : (smooth_[i] == 1 ? 17.0f : 25.0f); }
    // Gaussian i's share of its far-field grid at tile lattice nodes (film x0 + s u, y0 + s v,
    // nu x nv): its terms on the grid nodes the tile's stencils reach, then interpolated as
    // the grid is; into out[4] (zeroed first).
    void far_share(std::size_t i, int x0, int y0, int s, int nu, int nv, float* const* out) const;
    std::vector<std::uint32_t> bin_start_;  // per tile, into bin_index_ (size tiles + 1)
    std::vector<std::uint32_t> bin_index_;
};

}  // namespace airlight
