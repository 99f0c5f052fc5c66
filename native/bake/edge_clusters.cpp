// edge_clusters.cpp: see edge_clusters.h.
#include "bake/edge_clusters.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>

#include "core/constants.h"

namespace airlight {

namespace {

// Blackman-Harris window as Cycles' film uses it: support [-w, w] for filter width _w_
// (Cycles doubles the user width for this filter before tabulating it).
double blackman_harris(double x, double w) {
    double a = 2.0 * kPi * (x / (2.0 * w) + 0.5);
    return 0.35875 - 0.48829 * std::cos(a) + 0.14128 * std::cos(2.0 * a) - 0.01168 * std::cos(3.0 * a);
}

}  // namespace

// Sub-pixel offsets for edge pixels: _n_ x _n_ = N points with N distinct offsets on
// each axis, so a horizontal or vertical edge's coverage is resolved to 1/N (a regular
// n x n grid has only n distinct rows: measured on Cycles' floor-edge scene, its edge rows
// came out ~12 % dark). The points are a rank-1 lattice {((k + 1/2) / N, (a k mod N + 1/2)
// / N)} with the generator _a_ that maximises the shortest lattice vector on the torus
// (Korobov's choice: well spread in 2D, one point per row and per column), mapped per
// axis through the inverse CDF of Cycles' Blackman-Harris filter of support [-w, w]
// (separable filter, so that is importance sampling with equal weights, as Cycles does).
std::vector<glm::dvec2> filter_pattern(int n, double w) {
    const int N = n * n;
    std::vector<glm::dvec2> points(N, glm::dvec2(0.0));
    if (N <= 1 || w <= 0.0) return points;
    // Generator: the shortest nonzero lattice vector is the minimum distance between points.
    int best_a = 1;
    long long best_d2 = -1;
    for (int a = 1; a < N; ++a) {
        if (std::gcd(a, N) != 1) continue;
        long long d2_min = std::numeric_limits<long long>::max();
        for (int k = 1; k < N && d2_min > best_d2; ++k) {
            long long x = k, y = (long long)a * k % N;
            x = std::min(x, N - x);
            y = std::min(y, N - y);
            d2_min = std::min(d2_min, x * x + y * y);
        }
        if (d2_min > best_d2) best_d2 = d2_min, best_a = a;
    }
    // Tabulate the filter's CDF with the trapezoid rule; invert it by linear interpolation.
    const int m = 4096;
    std::vector<double> cdf(m + 1, 0.0);
    for (int i = 1; i <= m; ++i) {
        double x0 = -w + 2.0 * w * (i - 1) / m, x1 = -w + 2.0 * w * i / m;
        cdf[i] = cdf[i - 1] + 0.5 * (blackman_harris(x0, w) + blackman_harris(x1, w)) * (x1 - x0);
    }
    auto inverse_cdf = [&](double u) {
        double target = cdf[m] * u;
        int i = int(std::lower_bound(cdf.begin(), cdf.end(), target) - cdf.begin());
        i = std::clamp(i, 1, m);
        double f = (target - cdf[i - 1]) / std::max(cdf[i] - cdf[i - 1], 1e-300);
        return -w + 2.0 * w * (i - 1 + f) / m;
    };
    for (int k = 0; k < N; ++k)
        points[k] = {inverse_cdf((k + 0.5) / N), inverse_cdf((double((long long)best_a * k % N) + 0.5) / N)};
    return points;
}

// Clusters of one edge pixel's _n_ sub-samples for the supersampling in bake() (pass 2):
// the fog of a sub-sample is a smooth function of its ray and its segment [t0, depth], and
// within one pixel's filter footprint the rays differ by ~1 pixel, so what sets samples apart
// is the surface they hit (or that they hit none). Writes the sample indices 0 .. n-1 sorted
// by _depth_ (misses, inf, last) to _order_ and appends to _ends_ the end (index into
// _order_) of each cluster: all misses in one; the hits split greedily, nearest first, into
// runs whose farthest depth is at most (1 + _tol_) times their nearest. A NaN depth (never
// cast) is a cluster of its own.
void edge_sample_clusters(const float* depth, int n, double tol, int* order, std::vector<int>& ends) {
    // Insertion sort (n is small: aa_samples^2) on depth, NaN after inf.
    auto before = [&](int a, int b) {
        const float ka = depth[a], kb = depth[b];
        return std::isnan(kb) ? !std::isnan(ka) : ka < kb;
    };
    for (int k = 0; k < n; ++k) {
        int q = k;
        for (; q > 0 && before(k, order[q - 1]); --q) order[q] = order[q - 1];
        order[q] = k;
    }
    for (int b = 0; b < n;) {
        const float first = depth[order[b]];
        int e = b + 1;
        if (std::isinf(first)) {
            while (e < n && std::isinf(depth[order[e]])) ++e;
        } else if (!std::isnan(first)) {
            const double limit = double(first) * (1.0 + tol);
            while (e < n && std::isfinite(depth[order[e]]) && double(depth[order[e]]) <= limit) ++e;
        }
        ends.push_back(e);
        b = e;
    }
}

EdgeClusterBounds::EdgeClusterBounds(const SceneDescription& scene, const GaussianMedium* gaussians)
    : sigma_bg_(scene.medium.sigma_t), phase_(scene.medium.phase), gaussian_(gaussians) {
    RGB albedo = scene.medium.albedo;
    for (size_t i = 0; i + 2 < scene.gaussians.albedo.size(); i += 3)
        for (int c = 0; c < 3; ++c) albedo[c] = std::max(albedo[c], scene.gaussians.albedo[i + c]);
    isotropic_ = phase_is_isotropic(phase_);
    // G = max |d ln p / d theta| (the phase's share of f'/f is G |d theta / dt| <= G / d).
    if (!isotropic_) {
        constexpr int n = 2048;
        double prev = std::log(phase_.eval(1.0));
        for (int k = 1; k <= n; ++k) {
            const double theta = kPi * k / n, cur = std::log(phase_.eval(std::cos(theta)));
            phase_grad_ = std::max(phase_grad_, std::abs(cur - prev) / (kPi / n));
            prev = cur;
        }
    }
    for (const PointLight& l : scene.point_lights) lights_.push_back({l.position, albedo * l.I0});
    for (const SunLight& l : scene.sun_lights) suns_.push_back({glm::normalize(l.direction), albedo * l.E});
    sunlight_layer_ = std::isfinite(scene.fog_top);
}

void EdgeClusterBounds::errors(const Ray* rays, const float* depth, const int* idx, int n, const Ray& rep, double t0, double D,
            const RGB& La, double& err_La, double& err_Tr) const {
    const bool hit = std::isfinite(D);
    double var = 0.0, mad = 0.0, lateral = 0.0, lo = D, hi = D, o_spread = 0.0, d_spread = 0.0;
    double o_var = 0.0, d_var = 0.0;  // mean squared offsets of the samples' origins, directions
    for (int q = 0; q < n; ++q) {
        const Ray& r = rays[idx[q]];
        const double o2 = glm::dot(r.o - rep.o, r.o - rep.o), d2 = glm::dot(r.d - rep.d, r.d - rep.d);
        o_var += o2;
        d_var += d2;
        o_spread = std::max(o_spread, o2);  // (squared until after the loop)
        d_spread = std::max(d_spread, d2);
        if (!hit) continue;
        const double Dk = depth[idx[q]], dk = Dk - D;
        var += dk * dk;
        mad += std::abs(dk);
        lo = std::min(lo, Dk);
        hi = std::max(hi, Dk);
    }
    o_var /= n;
    d_var /= n;
    o_spread = std::sqrt(o_spread);
    d_spread = std::sqrt(d_spread);
    if (hit) {
        var /= n;
        mad /= n;
        lateral = o_spread + hi * d_spread;  // of the surface points from the representative ray
    }
    // The Gaussians' extinction (rho) and its slope along the ray near the hits' segment.
    double rho = 0.0, rho_slope = 0.0;
    if (gaussian_ && hit) {
        const Vec3 p = rep.o + lo * rep.d;
        gaussian_->for_each_near(p, rep.d, hi - lo, [&](std::size_t i) {
            const Vec3 b = gaussian_->centre(i);
            const double t = std::clamp(glm::dot(b - p, rep.d), 0.0, hi - lo);
            const double r = std::max(0.0, glm::length(p + t * rep.d - b) - lateral);
            const double a = gaussian_->scale(i), c = gaussian_->amplitude(i);
            rho += c * std::exp(-a * a * r * r);
            rho_slope += c * a * 0.8578;  // max of |d/dt c exp(-a^2 r^2)| = sqrt(2 / e) a c
        });
    }
    const double sigma = sigma_bg_ + rho;
    constexpr double kInf = std::numeric_limits<double>::infinity();
    RGB first(0.0), second(0.0), profile(0.0);
    for (const Light& l : lights_) {
        const Vec3 v = l.s - rep.o;
        const double ts = glm::dot(v, rep.d);
        const double h = glm::length(v - ts * rep.d);
        const double L = o_spread + std::abs(ts) * d_spread;
        if (!(h > 2.0 * L)) {  // the light's image among the samples
            err_La = err_Tr = kInf;
            return;
        }
        // (g: needed for the depth term and the homogeneous share only)
        const double g = !hit && gaussian_ ? 0.0
                                      : (hit ? std::atan((D - ts) / h) : 0.5 * kPi) - std::atan((t0 - ts) / h);
        // (E 1/|h - delta| <= (1 + E |delta|^2 / h^2) / h for the lateral offsets delta)
        const double lat_var = o_var + 2.0 * std::abs(ts) * std::sqrt(o_var * d_var) + ts * ts * d_var;
        double rel = lat_var / ((h - L) * (h - L));
        double de = kInf;  // the surface points' least distance to the light
        if (hit) {
            const double te = std::clamp(ts, lo, hi);
            de = glm::length(l.s - (rep.o + te * rep.d)) - lateral;
            if (!(de > 0.0)) {  // the light next to a surface point
                err_La = err_Tr = kInf;
                return;
            }
            rel += g > 0.0 ? var * h / (de * de * de * g) : kInf;
        }
        const double P = phase_bound(rep, t0, D, l.s);
        const double share = gaussian_ ? kInf  // (the Gaussians' density along the ray: unbounded here)
                                  : sigma_bg_ * P * std::exp(-sigma_bg_ * std::max(0.0, glm::length(v) - t0)) /
                                        (4.0 * kPi) * g / h;
        for (int c = 0; c < 3; ++c) profile[c] += std::min(La[c], l.w[c] * share) * 2.0 * rel;
        if (!hit) continue;
        const double att_end = std::exp(-sigma_bg_ * std::max(0.0, lo - t0 + de));
        second += l.w * (P * att_end / (4.0 * kPi * de * de) * (sigma * (2.0 * sigma + phase_grad_ / de) + rho_slope));
    }
    if (hit)
        for (const Sun& s : suns_) {
            const double p = phase_.eval(-glm::dot(s.w, rep.d));
            const RGB f = s.w_E * (p * std::exp(-sigma_bg_ * std::max(0.0, lo - t0)));
            if (sunlight_layer_) first += f * sigma;
            else second += f * (sigma * 2.0 * sigma + rho_slope);
        }
    err_La = 0.0;
    for (int c = 0; c < 3; ++c) {
        const double e = profile[c] + mad * first[c] + 0.5 * var * second[c];
        if (e > 0.0) err_La = std::max(err_La, La[c] > 0.0 ? e / La[c] : kInf);
    }
    err_Tr = var * (0.5 * rho_slope + 0.5 * rho * rho + rho * sigma_bg_);
}

double EdgeClusterBounds::phase_bound(const Ray& r, double t0, double D, const Vec3& s) const {
    if (isotropic_) return 1.0;
    double P = 0.0;
    const double ts = glm::dot(s - r.o, r.d);
    for (double t : {t0, std::clamp(ts, t0, std::isinf(D) ? std::max(ts, t0) : D), std::isinf(D) ? 1e30 : D}) {
        const Vec3 v = r.o + t * r.d - s;
        const double len = glm::length(v);
        const double mu = len > 0.0 ? glm::dot(v / len, r.d) : 1.0;
        P = std::max(P, 4.0 * kPi * std::max(phase_.eval(mu), phase_.eval(-mu)));
    }
    return P;
}

}  // namespace airlight
