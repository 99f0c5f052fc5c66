// splat_bin.cpp: GaussianSplat::bin, the Gaussians binned into 16x16 pixel tiles. It
// computes each Gaussian's cull-sphere bounds in film coordinates (the sphere's tangent
// planes through the eye, exact for the projective map D0 + px Dx + py Dy, shift and sensor
// fit included) and lists it in every tile of those bounds whose cone of rays meets the
// sphere; spheres that reach the plane through the eye parallel to the film go to every
// tile. At reduced resolution it also sets up what splat_reduced.cpp reads: the light
// bounds per tile, the lattice classes per Gaussian and the far-field grids
// (splat_far_field.cpp).
#include "gaussian/splat.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <mutex>
#include <sstream>
#include <stdexcept>
#include <vector>

#include "core/constants.h"
#include "core/target_clones.h"

namespace airlight {

namespace {

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

// bin()'s steps and their shared state.
struct GaussianSplat::Binning {
    GaussianSplat& gs;
    const std::size_t n;
    const int n_tiles;
    // Each tile's cone of rays: unit axis through its centre, cos and sin of the largest
    // angle to its corner rays. A ball of angular radius rho around direction u can meet
    // the tile's rays only if angle(axis, u) <= theta + rho: cuts the bounding boxes'
    // corners and the tile rounding.
    struct Cone {
        Vec3 axis;
        double cos_t, sin_t;
    };
    std::vector<Cone> cones;
    // The tiles' cones in structure-of-arrays form for cone_hits (ball i against tile t).
    std::vector<double> cone_x, cone_y, cone_z, cone_c, cone_s;
    // Per Gaussian: its tile rectangle x0, x1, y0, y1 (x1 < x0: none) and cone-test ball
    // (direction u, sin and cos of its angular radius; inside: the eye is in the ball, every
    // tile of the rectangle).
    std::vector<int> rect;
    struct Ball {
        Vec3 u{0.0};
        double sin_r = 1.0, cos_r = 0.0;
        bool inside = true;
    };
    std::vector<Ball> balls;
    std::vector<std::uint32_t> count;  // pairs per tile (shifted by one), then their prefix sums
    FarScratch far;                    // far.counts allocated: there are far-field candidates

    explicit Binning(GaussianSplat& splat)
        : gs(splat),
          n(splat.medium_.size()),
          n_tiles(splat.num_tiles()),
          rect(4 * n),
          balls(n),
          count(n_tiles + 1, 0) {}
    void cull_spheres();
    void tile_cones();
    void bound_tile_lights();
    void footprints(double t0_max);
    void scan_rows(bool fill_lists, std::uint32_t* fill);
    void lattice_classes();
};

// Cull spheres (gaussian/medium.h: outside R_i a ray's T_i < eps): the medium's cull_eps at
// full resolution (the reference path); at reduced resolution eps = kReducedCullEps (at
// least the medium's), tied to the lattice's own error: with the default 1e-7, a quarter of
// the tile-Gaussian pairs held terms below 1e-5 (see gaussian/splat.h). And far_eye,
// far_lights (GaussF): a sqrt(D^2 - R^2) >= kFarStart for the eye and every point light
// (plain path only: the extended light kernels keep both erfc terms).
void GaussianSplat::Binning::cull_spheres() {
    const GaussianMedium& medium = gs.medium_;
    const int step = gs.step_;
    const double eps_cull =
        step == 1 ? medium.cull_eps() : std::max(medium.cull_eps(), kReducedCullEps[step / 2 - 1]);
    for (std::size_t i = 0; i < gs.g_.size(); ++i) {
        const double R = step == 1 ? medium.cull_radius(i)
                                   : GaussianMedium::cull_radius_for(medium.amplitude(i), medium.scale(i), eps_cull);
        gs.g_[i].radius = R;
        const double a = medium.scale(i);
        auto far_from = [&](const Vec3& p) {
            const double D = glm::length(medium.centre(i) - p);
            return D > R && a * std::sqrt(D * D - R * R) >= kFarStart;
        };
        gs.g_[i].far_eye = far_from(gs.eye_);
        bool lights_far = gs.plain_;
        for (const Vec3& s : gs.lights_) lights_far = lights_far && far_from(s);
        gs.g_[i].far_lights = lights_far;
    }
}

void GaussianSplat::Binning::tile_cones() {
    const Vec3 &D0 = gs.D0_, &Dx = gs.Dx_, &Dy = gs.Dy_;
    const int W = gs.W_, H = gs.H_, tiles_x = gs.tiles_x_;
    cones.resize(n_tiles);
    parallel_chunks(std::size_t(n_tiles), gs.threads_, 256, [&](std::size_t tb, std::size_t te) {
        for (std::size_t tt = tb; tt < te; ++tt) {
            const int tx = int(tt) % tiles_x, ty = int(tt) / tiles_x;
            const double x0 = tx * kTile, x1 = std::min(W, (tx + 1) * kTile);
            const double y0 = ty * kTile, y1 = std::min(H, (ty + 1) * kTile);
            Cone& c = cones[ty * tiles_x + tx];
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
    for (auto* v : {&cone_x, &cone_y, &cone_z, &cone_c, &cone_s}) v->resize(n_tiles);
    for (int t = 0; t < n_tiles; ++t) {
        cone_x[t] = cones[t].axis.x;
        cone_y[t] = cones[t].axis.y;
        cone_z[t] = cones[t].axis.z;
        cone_c[t] = cones[t].cos_t;
        cone_s[t] = cones[t].sin_t;
    }
}

// Reduced resolution: per (tile, light), bounds on the light factor's distance |b^r - s|
// over the tile's rays (light_clear); tiles where some Gaussian could come closer to a
// light than the lattice allows are flagged (exact_tile_: their Gaussians are checked
// one by one in splat_tile_reduced, and their edge samples skip the lattice).
void GaussianSplat::Binning::bound_tile_lights() {
    const int step = gs.step_;
    gs.exact_tile_.assign(step > 1 ? n_tiles : 0, 0);
    const std::size_t L = gs.lights_.size();
    gs.tile_light_.assign(step > 1 ? std::size_t(n_tiles) * L : 0, TileLight{});
    gs.light_min_ = 0.0;
    if (step == 1) return;
    // The lattice's light-factor criterion at spacing s (see lattice_classes' smooth_):
    // |b^r - s| >= light_min_ d_i, d_i the Gaussian's distance from the eye.
    const double f = glm::dot(gs.D0_, gs.forward_);
    const double pix = f > 0.0 ? std::max(glm::length(gs.Dx_), glm::length(gs.Dy_)) / f : 0.0;
    const double tau = 1e-3 * (step / 4.0) * (step / 4.0);
    gs.light_min_ = step * std::sqrt(6.0 / (8.0 * tau)) * pix;
    double dist_max = 0.0;
    for (const GaussF& g : gs.g_) dist_max = std::max(dist_max, g.dist);
    for (int t = 0; t < n_tiles; ++t) {
        const double half = std::acos(std::clamp(cones[t].cos_t, -1.0, 1.0));
        for (std::size_t l = 0; l < L; ++l) {
            TileLight& tl = gs.tile_light_[std::size_t(t) * L + l];
            const Vec3 u = gs.lights_[l] - gs.eye_;
            const double D = glm::length(u);
            if (!(D > 0.0)) {  // a light at the eye: no bound
                tl = TileLight{0.0f, 0.0f, 1.0f};
                gs.exact_tile_[t] = 1;
                continue;
            }
            const double c = std::acos(std::clamp(glm::dot(cones[t].axis, u / D), -1.0, 1.0));
            const double a_min = std::max(0.0, c - half - 1e-9), a_max = c + half + 1e-9;
            // The ray's closest approach to s: D sin(angle), or D (the eye) past 90 degrees.
            tl.h_min = float((a_min >= 0.5 * kPi ? D : D * std::sin(a_min)) * (1.0 - 1e-6));
            if (a_max < 0.5 * kPi) tl.cos_max = float(std::cos(a_max)), tl.sin_max = float(std::sin(a_max));
            else tl.cos_max = 0.0f, tl.sin_max = 1.0f;
            if (double(tl.h_min) < gs.light_min_ * dist_max) gs.exact_tile_[t] = 1;
        }
    }
}

// Per Gaussian its tile rectangle (the film-coordinate bounds of its cull sphere, exact for
// the projective map D0 + px Dx + py Dy) and cone-test ball; GaussF::near (the sphere
// reaches the near clip ball of radius t0_max, the farthest near point).
void GaussianSplat::Binning::footprints(double t0_max) {
    const Vec3 &q0 = gs.q0_, &q1 = gs.q1_, &q2 = gs.q2_;
    const int W = gs.W_, H = gs.H_;
    const double clip_start = gs.clip_start_;
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
    parallel_chunks(n, gs.threads_, 256, [&](std::size_t ib, std::size_t ie) {
        for (std::size_t i = ib; i < ie; ++i) {
            int* r = &rect[4 * i];
            r[0] = 0;
            r[1] = -1;
            r[2] = 0;
            r[3] = -1;
            const double R = gs.g_[i].radius;
            if (!(R > 0.0) || gs.medium_.amplitude(i) == 0.0) continue;
            const Vec3 c = gs.medium_.centre(i) - gs.eye_;
            const double dist = glm::length(c);
            gs.g_[i].near = clip_start > 0.0 && dist < R + t0_max;
            // Entirely behind the eye: no ray from the eye meets it.
            if (glm::dot(q0, c) + R * glm::length(q0) < 0.0) continue;
            double x_lo, x_hi, y_lo, y_hi;
            int tx0 = 0, tx1 = gs.tiles_x_ - 1, ty0 = 0, ty1 = gs.tiles_y_ - 1;
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
}

// Counts per tile (fill_lists false: into count[t + 1]), then the lists (at fill[t]), by
// tile rows in parallel (each row's tiles list their Gaussians in index order, as a serial
// pass over the Gaussians would). The fill also counts each far-field candidate's tiles in
// front / behind / cut (far_candidates).
void GaussianSplat::Binning::scan_rows(bool fill_lists, std::uint32_t* fill) {
    const int tiles_x = gs.tiles_x_;
    parallel_chunks(std::size_t(gs.tiles_y_), gs.threads_, 1, [&](std::size_t yb, std::size_t ye) {
        std::vector<unsigned char> hit(std::size_t(tiles_x), 1);
        for (int ty = int(yb); ty < int(ye); ++ty)
            for (std::size_t i = 0; i < n; ++i) {
                const int* r = &rect[4 * i];
                if (r[1] < r[0] || ty < r[2] || ty > r[3]) continue;
                const Ball& ball = balls[i];
                const int t0 = ty * tiles_x + r[0], m = r[1] - r[0] + 1;
                if (ball.inside) std::fill(hit.begin(), hit.begin() + m, 1);
                else
                    cone_hits(m, &cone_x[t0], &cone_y[t0], &cone_z[t0], &cone_c[t0], &cone_s[t0], ball.u.x, ball.u.y,
                              ball.u.z, ball.sin_r, ball.cos_r, hit.data());
                if (fill_lists) {
                    for (int k = 0; k < m; ++k)
                        if (hit[k]) gs.bin_index_[fill[t0 + k]++] = std::uint32_t(i);
                    if (far.counts && far.cand[i]) {
                        const float lo = far.span[2 * i], hi = far.span[2 * i + 1];
                        std::uint32_t c[3] = {0, 0, 0};
                        for (int k = 0; k < m; ++k)
                            if (hit[k]) ++c[hi <= far.tmin[t0 + k] ? 0 : (lo >= far.tmax[t0 + k] ? 1 : 2)];
                        for (int q = 0; q < 3; ++q)
                            if (c[q]) far.counts[3 * i + q].fetch_add(c[q], std::memory_order_relaxed);
                    }
                } else {
                    for (int k = 0; k < m; ++k) count[t0 + k + 1] += hit[k];
                }
            }
    });
}

// Coarse-lattice Gaussians (smooth_, see splat_reduced.cpp): H = 2 step pixels, tau = 1e-3
// at quarter resolution and 1e-3 / 4 at half (which errs ~4x less than quarter: keeps that);
// pix = the largest angle of a pixel (at the film point nearest the eye: |Dx| / (D0 .
// forward)). And light_far_: the same light criterion on the lattice itself.
void GaussianSplat::Binning::lattice_classes() {
    const int step = gs.step_;
    gs.smooth_.assign(step > 1 ? n : 0, 0);
    gs.light_far_.assign(step > 1 ? n : 0, 0);
    if (step == 1) return;
    const double f = glm::dot(gs.D0_, gs.forward_);
    const double pix = f > 0.0 ? std::max(glm::length(gs.Dx_), glm::length(gs.Dy_)) / f : 0.0;
    const double H = 2.0 * step, tau = 1e-3 * (step / 4.0) * (step / 4.0);
    const double sigma_min = H / (2.0 * std::sqrt(tau)) * pix;      // angle
    const double light_min = H * std::sqrt(6.0 / (8.0 * tau)) * pix;  // |b - s| - R per unit d
    for (std::size_t i = 0; i < n && pix > 0.0; ++i) {
        const double dist = std::max(gs.g_[i].dist, 1e-12), a = gs.medium_.scale(i);
        double clearance = std::numeric_limits<double>::infinity();  // least |b - s| - R over the lights
        for (const Vec3& s : gs.lights_)
            clearance = std::min(clearance, glm::length(gs.medium_.centre(i) - s) - gs.g_[i].radius);
        // 2: everywhere; 1: where the tile's rays keep b^r far enough from the lights
        // (light_clear with factor H / s = 2: a light's image far from the tile).
        const bool wide = 1.0 / (std::sqrt(2.0) * a * dist) >= sigma_min;
        gs.smooth_[i] = !wide ? 0 : (clearance >= light_min * dist ? 2 : 1);
        // The same light criterion on the lattice itself (step s, half of H: light_min_):
        // every b^r of the Gaussian's rays stays that far from every light, so its light
        // factor 1 / |b^r - s|^2 interpolates to tau over a lattice cell.
        gs.light_far_[i] = clearance >= gs.light_min_ * dist;
    }
}

void GaussianSplat::bin(const Vec3& D0, const Vec3& Dx, const Vec3& Dy, const Vec3& forward, int W, int H,
                        double clip_start, int step, const float* depth) {
    if (step != 1 && step != 2 && step != 4) {
        std::ostringstream os;
        os << "Gaussian resolution step must be 1 (full), 2 (half) or 4 (quarter), got " << step;
        throw std::invalid_argument(os.str());
    }
    step_ = step;
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
    q0_ = Qt[0];
    q1_ = Qt[1];
    q2_ = Qt[2];
    // (the per-tile and per-Gaussian work below runs on threads_ threads: parallel_chunks)
    Binning b(*this);
    b.cull_spheres();
    b.tile_cones();
    b.bound_tile_lights();
    b.footprints(t0_max);
    b.scan_rows(false, nullptr);
    b.lattice_classes();
    std::vector<std::uint32_t>& count = b.count;
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
    const bool far_field = far_candidates(depth, b.rect, b.far);
    b.scan_rows(true, fill.data());
    if (far_field) build_far_field(b.rect, b.far);
}

}  // namespace airlight
