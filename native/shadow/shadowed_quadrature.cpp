// shadowed_quadrature.cpp: see shadowed_quadrature.h.
#include "shadow/shadowed_quadrature.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "core/quadrature.h"

namespace airlight {

namespace {

// Breakpoints along the ray: geometric ladders about the closest approach a (scale h), where
// the point integrand peaks (as phase_airlight_quadrature).
std::vector<double> approach_cuts(double a, double h, double scale, double end, double lobe) {
    std::vector<double> cuts{0.0};
    if (a > 0.0 && a < end) cuts.push_back(a);
    for (double w = std::max(h, 1e-12 * scale); w < 4.0 * scale / lobe; w *= 4.0) {
        if (a - w > 0.0 && a - w < end) cuts.push_back(a - w);
        if (a + w > 0.0 && a + w < end) cuts.push_back(a + w);
    }
    std::sort(cuts.begin(), cuts.end());
    return cuts;
}

// Where the visibility changes along start + x d, x in [0, end]: sampled at kScan points
// (uniform in x / (x + scale) for an unbounded segment) and each change bisected to 1e-12 of
// its position. An adaptive rule alone can step over a jump (measured: 2e-3 off on a shaft's
// edge at 1e-12 tolerance), so the jumps are its breakpoints. Occluders thinner than the scan's
// spacing can be missed: a reference for scenes whose shadows are wider than end / kScan.
constexpr int kScan = 512;
std::vector<double> visibility_jumps(const Visibility& visible, const Vec3& start, const Vec3& d, double end,
                                     double scale) {
    const bool unbounded = std::isinf(end);
    auto at = [&](double u) { return unbounded ? scale * u / (1.0 - u) : end * u; };
    std::vector<double> jumps;
    double u_prev = 0.0;
    bool prev = visible(start);
    for (int k = 1; k <= kScan; ++k) {
        const double u = unbounded ? double(k) / (kScan + 1) : double(k) / kScan;
        const bool cur = visible(start + at(u) * d);
        if (cur != prev) {
            double lo = u_prev, hi = u;
            for (int it = 0; it < 60 && hi - lo > 1e-12 * std::max(hi, 1e-300); ++it) {
                const double mid = 0.5 * (lo + hi);
                (visible(start + at(mid) * d) == prev ? lo : hi) = mid;
            }
            jumps.push_back(at(0.5 * (lo + hi)));
        }
        prev = cur;
        u_prev = u;
    }
    return jumps;
}

// The unshadowed integral to 1e-3, the scale of the shadowed one's absolute tolerance: a piece
// in shadow (its integral ~0) or one whose visibility flickers is refined until its error is
// rel_tol of the whole ray's light, not of its own.
// Panels per piece between breakpoints (15 shadow rays each). A piece whose visibility
// flickers (a shadow ray grazing casters around the light, in floats) cannot converge; this
// bounds its cost (measured: 600k shadow rays per pixel at 20000 panels, a 96 x 4 bake 31 s)
// and leaves its error at the flicker's share of the light.
constexpr int kShadowMaxPanels = 1000;

template <typename F>
double unshadowed_scale(const F& f, const std::vector<double>& cuts, double end, double tail_scale) {
    return std::abs(integrate_piecewise(f, cuts, end, tail_scale, 1e-3));
}

template <typename Profile>
double positional_visible(const PhaseFunction& phase, double sigma_t, const Vec3& s, const Vec3& start, const Vec3& d,
                          double seg, const Visibility& visible, double rel_tol, const std::vector<double>* jumps,
                          const Profile& profile) {
    if (sigma_t == 0.0 || !(seg > 0.0)) return 0.0;
    const Vec3 w = start - s;
    const double Dsv = glm::length(w), a = -glm::dot(w, d);
    const double h = std::sqrt(std::max(0.0, Dsv * Dsv - a * a));
    auto unshadowed = [&](double x) {
        const Vec3 p = start + x * d;
        const Vec3 v = p - s;
        const double r2 = glm::dot(v, v), r = std::sqrt(r2);
        if (!(r > 0.0)) return 0.0;
        const double prof = profile(v / r);
        if (prof == 0.0) return 0.0;
        return prof * phase.eval(-glm::dot(v / r, d)) * std::exp(-sigma_t * (x + r)) / r2;
    };
    auto integrand = [&](double x) { return visible(start + x * d) ? unshadowed(x) : 0.0; };
    const double end = std::isinf(seg) ? std::numeric_limits<double>::infinity() : seg;
    std::vector<double> cuts = approach_cuts(a, h, Dsv, end, phase.lobe_width());
    const double whole = unshadowed_scale(unshadowed, cuts, end, Dsv);
    for (double x : jumps ? *jumps : visibility_jumps(visible, start, d, end, std::max(Dsv, 1e-6)))
        if (x > 0.0 && x < end) cuts.push_back(x);
    std::sort(cuts.begin(), cuts.end());
    return sigma_t * integrate_piecewise(integrand, cuts, end, Dsv, rel_tol, rel_tol * whole, kShadowMaxPanels);
}

}  // namespace

double point_airlight_visible(const PhaseFunction& phase, double sigma_t, const Vec3& s, const Vec3& start,
                              const Vec3& d, double seg, const Visibility& visible, double rel_tol,
                              const std::vector<double>* jumps) {
    return positional_visible(phase, sigma_t, s, start, d, seg, visible, rel_tol, jumps,
                              [](const Vec3&) { return 1.0; });
}

double spot_airlight_visible(const SpotCone& cone, const PhaseFunction& phase, double sigma_t, const Vec3& s,
                             const Vec3& start, const Vec3& d, double seg, const Visibility& visible, double rel_tol,
                             const std::vector<double>* jumps) {
    return positional_visible(phase, sigma_t, s, start, d, seg, visible, rel_tol, jumps,
                              [&](const Vec3& u) { return spot_profile(cone, glm::dot(u, cone.axis)); });
}

double sunlight_factor_visible(double sigma_t, double h_top, double mu_s, const Vec3& start, const Vec3& d,
                               double seg, const Visibility& visible, double rel_tol,
                               const std::vector<double>* jumps) {
    if (!(seg > 0.0)) return 0.0;
    const bool layer = std::isfinite(h_top);
    if (layer && !(mu_s > 0.0)) return 0.0;
    // Where the ray is inside the layer z <= h_top: [x_in, x_out].
    double x_in = 0.0, x_out = seg;
    if (layer) {
        if (d.z > 0.0) x_out = std::min(x_out, (h_top - start.z) / d.z);
        else if (d.z < 0.0) x_in = std::max(x_in, (h_top - start.z) / d.z);
        else if (start.z > h_top) return 0.0;
        if (!(x_out > x_in)) return 0.0;
    }
    auto unshadowed = [&](double x) {
        const Vec3 p = start + x * d;
        const double view = sigma_t * (x - x_in);
        const double sun = layer ? sigma_t * std::max(0.0, h_top - p.z) / mu_s : 0.0;
        return std::exp(-view - sun);
    };
    auto integrand = [&](double x) { return visible(start + x * d) ? unshadowed(x) : 0.0; };
    const double scale = sigma_t > 0.0 ? 1.0 / sigma_t : 1.0;
    std::vector<double> cuts{x_in};
    const double whole = unshadowed_scale(unshadowed, cuts, x_out, scale);
    if (jumps) {
        for (double x : *jumps)
            if (x > x_in && x < x_out) cuts.push_back(x);
    } else {
        for (double x : visibility_jumps(visible, start + x_in * d, d, x_out - x_in, scale)) cuts.push_back(x_in + x);
    }
    std::sort(cuts.begin(), cuts.end());
    return integrate_piecewise(integrand, cuts, x_out, scale, rel_tol, rel_tol * whole, kShadowMaxPanels);
}

}  // namespace airlight
