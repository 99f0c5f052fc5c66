// medium.h: inhomogeneous medium as a sum of Gaussians (Fogshop, Zhou et al. 2007):
//   beta(x) = beta0 + sum_i c_i exp(-a_i^2 |x - b_i|^2)          (eq. 6, 7)
// with centre _b_ (m), scale _a_ (1/m), amplitude _c_ (1/m) and a constant background
// _beta0_ (1/m). Stored as a struct of arrays (up to ~1e5 Gaussians) with a bounding
// volume hierarchy over per-Gaussian cull spheres, so that a segment's optical depth
// costs O(log n + Gaussians near the segment), not O(n).
//
// Optical depth of a segment (eq. 31, done in medium.cpp without cancellation):
//   T_i(p, q) = c_i sqrt(pi) / (2 a_i) exp(-a_i^2 h^2) [erf(a_i (L - t*)) - erf(-a_i t*)],
//   t* = (b_i - p) . r,  h = |(b_i - p) x r|,  L = |q - p|,  r = (q - p) / L,
//   T(p, q) = beta0 L + sum_i T_i(p, q).
//
// Culling (the line-integral form of eq. 30). On a line at distance h from b_i,
//   T_i <= c_i sqrt(pi) / a_i exp(-a_i^2 h^2),
// so Gaussian i is skipped when the segment stays outside the sphere of radius
//   R_i = sqrt(ln(c_i sqrt(pi) / (a_i eps))) / a_i       (R_i = 0 if the log is <= 0)
// around b_i. Then every skipped T_i is below _eps_ (a segment whose line passes inside
// the sphere but whose ends stay outside it integrates at most eps / 2), so the culled
// optical depth differs from the full sum by at most eps times the number of Gaussians
// skipped (tested in medium_test.cpp). The paper's eq. 30 bounds the density at the
// closest point instead (c_i e^{-a_i^2 h^2} <= e^-9); that bounds no line integral, since a
// broad faint Gaussian can still integrate to a lot.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <atomic>
#include <functional>
#include <limits>
#include <thread>
#include <utility>
#include <vector>

#include "core/scene.h"

namespace airlight {

// erf(x2) - erf(x1) for x1 <= x2 (x2 may be +inf, x1 may be -inf), without the
// cancellation of the plain difference: erfc differences when both arguments have one
// sign, Gauss-Legendre on exp(-t^2) when the interval is so short that even those cancel.
// Relative error ~1e-14 wherever the result is a normal double.
double erf_diff(double x1, double x2);

// Line integral of one Gaussian (c, a, b) along o + t r, t in [t0, t1] (t1 may be +inf),
// r a unit vector: eq. 31 with erf_diff.
double gaussian_line_integral(double c, double a, const Vec3& b, const Vec3& o, const Vec3& r, double t0,
                              double t1);

// Runs fn(begin, end) over [0, n) in chunks of _chunk_ on _threads_ std::threads
// (0 = hardware concurrency; the calling thread is one of them). Exceptions from fn are
// rethrown in the caller (the first one wins).
void parallel_chunks(std::size_t n, int threads, std::size_t chunk,
                     const std::function<void(std::size_t, std::size_t)>& fn);

// A march's window for each Gaussian (gaussian/march.h, GaussianMarch::window): a Gaussian's
// density is left out of a line where a^2 h^2 >= GaussianWindow(window)(c sqrt(pi) / a) at the
// line's closest approach h to its centre. _window_ for the Gaussians of optical depth below
// kWindowDepth e^window through the centre (at most centre_depth e^-window of each is left
// out); a denser one keeps the window that leaves out kWindowDepth of it, up to kMaxWindow.
// The light-depth maps leave out what a march would.
struct GaussianWindow {
    static constexpr double kWindowDepth = 1e-5, kMaxWindow = 20.0;
    static constexpr double kNone = std::numeric_limits<double>::infinity();  // (leaves out nothing)
    explicit GaussianWindow(double window) : window(window), dense(kWindowDepth * std::exp(window)) {}
    double operator()(double centre_depth) const {
        return centre_depth <= dense ? window : std::min(kMaxWindow, std::log(centre_depth / kWindowDepth));
    }
    double window, dense;
};

class GaussianMedium {
  public:
    // Per-Gaussian culling tolerance on the optical depth (see the header comment).
    static constexpr double kDefaultCullEps = 1e-7;

    GaussianMedium() = default;
    // _centres_ holds 3 n doubles (x, y, z per Gaussian). Throws std::invalid_argument on
    // non-finite centres, a <= 0 or non-finite, c < 0 or non-finite, beta0 < 0 or
    // non-finite, eps <= 0, or arrays of different lengths. Builds the hierarchy.
    GaussianMedium(std::vector<double> centres, std::vector<double> scales, std::vector<double> amplitudes,
              double beta0, double cull_eps = kDefaultCullEps);

    std::size_t size() const { return a_.size(); }
    double beta0() const { return beta0_; }
    double cull_eps() const { return eps_; }
    // A 64-bit hash (FNV-1a) of the Gaussians and the cull tolerance: media that agree on it
    // have the same Gaussians and hierarchy (a table built from one serves the other).
    std::uint64_t fingerprint() const;
    Vec3 centre(std::size_t i) const { return {bx_[i], by_[i], bz_[i]}; }
    double scale(std::size_t i) const { return a_[i]; }
    double amplitude(std::size_t i) const { return c_[i]; }
    // Radius of Gaussian i's cull sphere (R_i above).
    double cull_radius(std::size_t i) const { return radius_[i]; }
    // R for amplitude c, scale a and tolerance eps (the formula above; 0 where c sqrt(pi) /
    // a <= eps): the medium's own spheres use eps = cull_eps(), splat_bin.cpp larger ones.
    static double cull_radius_for(double c, double a, double eps);
    // The Gaussians with a cull sphere (R_i > 0) in the hierarchy's leaf order: runs of it
    // are spatially compact (gaussian/splat_bin.cpp blocks them for its cull tests).
    const std::vector<std::uint32_t>& leaf_order() const { return order_; }

    // The same Gaussians with each cull sphere cut to the window a march with _window_ keeps of
    // them (GaussianWindow: the radius sqrt(W) / a, where it is the smaller), and its hierarchy:
    // for_each_near over it reaches only the Gaussians such a march (or a depth map with that
    // window) keeps, ~0.7 of the cull spheres' at window 10. Its own optical depths leave out
    // what the window does; the exact references take the medium itself.
    GaussianMedium windowed(double window) const;

    // Density beta(x) (no culling).
    double density(const Vec3& x) const;
    // The same from the Gaussians whose cull sphere holds x (the hierarchy: O(log n) with
    // small Gaussians); each one left out adds below eps a / sqrt(pi) there.
    double density_near(const Vec3& x) const;

    // Optical depth of the segment p -> q with culling (<= eps per skipped Gaussian).
    double optical_depth(const Vec3& p, const Vec3& q) const;
    // Same along o + t r for t in [0, tmax], r unit, tmax may be +inf (T = inf if beta0 > 0).
    double optical_depth_ray(const Vec3& o, const Vec3& r, double tmax) const;
    // Same, leaving out Gaussian _skip_ (and beta0 if !with_beta0); skip = npos for none.
    double optical_depth_ray(const Vec3& o, const Vec3& r, double tmax, std::size_t skip, bool with_beta0) const;
    // Brute force over all Gaussians, no culling (the reference).
    double optical_depth_all(const Vec3& p, const Vec3& q) const;
    double optical_depth_all_ray(const Vec3& o, const Vec3& r, double tmax) const;
    // Line integral of Gaussian i alone along o + t r, t in [t0, t1].
    double gaussian_optical_depth(std::size_t i, const Vec3& o, const Vec3& r, double t0, double t1) const;

    // Batched segments p[j] -> q[j] (culled or brute force), multithreaded.
    void optical_depth_batch(const Vec3* p, const Vec3* q, std::size_t n, double* out, bool culled = true,
                             int threads = 0) const;
    // Batched rays o[j] + t r[j], t in [0, tmax[j]] (r unit, tmax may be inf).
    void optical_depth_ray_batch(const Vec3* o, const Vec3* r, const double* tmax, std::size_t n, double* out,
                                 bool culled = true, int threads = 0) const;

    // Calls fn(i) for every Gaussian whose cull sphere the segment o + t r, t in [0, tmax]
    // (r unit, tmax may be inf) reaches; every other Gaussian integrates to < eps on it.
    template <typename Fn>
    void for_each_near(const Vec3& o, const Vec3& r, double tmax, Fn&& fn) const;

    // Calls fn(i) for every Gaussian whose cull sphere meets the cone from _o_ around unit _axis_
    // of half-angle acos(cos_half) (cos_half >= 0), and some more (a node's box is taken by its
    // bounding sphere): a bundle of rays from _o_ within the cone gathers its Gaussians here once
    // and each ray keeps those segment_reaches (for_each_near's set, one walk for the bundle).
    template <typename Fn>
    void for_each_in_cone(const Vec3& o, const Vec3& axis, double cos_half, Fn&& fn) const;
    // for_each_near's test of Gaussian i: the segment o + t r, t in [0, tmax], reaches its sphere
    // (the distance from b_i to the segment below R_i).
    bool segment_reaches(std::size_t i, const Vec3& o, const Vec3& r, double tmax) const {
        const double px = bx_[i] - o.x, py = by_[i] - o.y, pz = bz_[i] - o.z;
        const double ts = px * r.x + py * r.y + pz * r.z;
        const double tc = ts < 0.0 ? 0.0 : (ts > tmax ? tmax : ts);
        const double qx = px - tc * r.x, qy = py - tc * r.y, qz = pz - tc * r.z;
        return qx * qx + qy * qy + qz * qz < radius_[i] * radius_[i];
    }

    static constexpr std::size_t npos = static_cast<std::size_t>(-1);

  private:
    struct Node {
        double lo[3], hi[3];
        // Leaf: first primitive in _order_ and count > 0; inner: right child, count = 0
        // (the left child is the next node).
        std::uint32_t first_or_right, count;
    };
    void build();
    void build_hierarchy();  // over the Gaussians with radius_ > 0
    // Depth-first over the hierarchy: the nodes node_hit(node) takes, leaf(i) for their Gaussians.
    template <typename NodeHit, typename Leaf>
    void walk(NodeHit&& node_hit, Leaf&& leaf) const;
    std::uint32_t build_node(std::uint32_t begin, std::uint32_t end, int depth);

    std::vector<double> bx_, by_, bz_, a_, c_;
    std::vector<double> radius_;  // R_i
    double beta0_ = 0.0, eps_ = kDefaultCullEps;
    double window_ = GaussianWindow::kNone;  // (windowed's)
    std::vector<Node> nodes_;
    std::vector<std::uint32_t> order_;  // leaf order -> Gaussian index
};

template <typename NodeHit, typename Leaf>
void GaussianMedium::walk(NodeHit&& node_hit, Leaf&& leaf) const {
    if (nodes_.empty()) return;
    std::uint32_t stack[64];
    int sp = 0;
    std::uint32_t ni = 0;
    for (;;) {
        const Node& n = nodes_[ni];
        if (node_hit(n)) {
            if (n.count > 0) {
                for (std::uint32_t k = 0; k < n.count; ++k) leaf(order_[n.first_or_right + k]);
            } else {
                stack[sp++] = n.first_or_right;
                ni = ni + 1;
                continue;
            }
        }
        if (sp == 0) break;
        ni = stack[--sp];
    }
}

template <typename Fn>
void GaussianMedium::for_each_near(const Vec3& o, const Vec3& r, double tmax, Fn&& fn) const {
    const double inv[3] = {1.0 / r.x, 1.0 / r.y, 1.0 / r.z};
    const double org[3] = {o.x, o.y, o.z};
    // Slab test of a node's box against t in [0, tmax]. 0 * inf = NaN fails the comparisons,
    // which is the right outcome only when the origin is outside the slab; handle r_k = 0
    // explicitly.
    auto hits = [&](const Node& n) {
        double t_near = 0.0, t_far = tmax;
        for (int k = 0; k < 3; ++k) {
            if (std::isinf(inv[k])) {
                if (!(org[k] >= n.lo[k] && org[k] <= n.hi[k])) return false;
                continue;
            }
            double ta = (n.lo[k] - org[k]) * inv[k], tb = (n.hi[k] - org[k]) * inv[k];
            if (ta > tb) std::swap(ta, tb);
            t_near = ta > t_near ? ta : t_near;
            t_far = tb < t_far ? tb : t_far;
            if (!(t_near <= t_far)) return false;
        }
        return true;
    };
    walk(hits, [&](std::uint32_t i) {
        if (segment_reaches(i, o, r, tmax)) fn(static_cast<std::size_t>(i));
    });
}

template <typename Fn>
void GaussianMedium::for_each_in_cone(const Vec3& o, const Vec3& axis, double cos_half, Fn&& fn) const {
    const double sin_half = std::sqrt(std::max(0.0, 1.0 - cos_half * cos_half));
    // The sphere (c, rho) meets the cone where the angle from the axis to c - o is at most the
    // half-angle plus asin(rho / |c - o|) (both at most pi / 2: cos falls monotonically).
    auto meets = [&](double cx, double cy, double cz, double rho) {
        const double dx = cx - o.x, dy = cy - o.y, dz = cz - o.z;
        const double L2 = dx * dx + dy * dy + dz * dz;
        if (L2 <= rho * rho) return true;
        const double L = std::sqrt(L2), sa = rho / L, ca = std::sqrt(1.0 - sa * sa);
        return dx * axis.x + dy * axis.y + dz * axis.z >= L * (cos_half * ca - sin_half * sa);
    };
    auto hits = [&](const Node& n) {  // (its box's bounding sphere)
        const double hx = 0.5 * (n.hi[0] - n.lo[0]), hy = 0.5 * (n.hi[1] - n.lo[1]), hz = 0.5 * (n.hi[2] - n.lo[2]);
        return meets(n.lo[0] + hx, n.lo[1] + hy, n.lo[2] + hz, std::sqrt(hx * hx + hy * hy + hz * hz));
    };
    walk(hits, [&](std::uint32_t i) {
        if (meets(bx_[i], by_[i], bz_[i], radius_[i])) fn(static_cast<std::size_t>(i));
    });
}

}  // namespace airlight
