// spot_light.cpp: Cycles spot profile and its single-scattering airlight by quadrature.
#include "homogeneous/spot_light.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "core/quadrature.h"

namespace airlight {

SpotCone make_spot_cone(const glm::dvec3& axis, double spot_size, double spot_blend, double spread) {
    SpotCone cone;
    const double len = glm::length(axis);
    cone.axis = len > 0.0 ? axis / len : glm::dvec3(0.0, 0.0, -1.0);
    if (spread < kPi - 1e-9) {
        if (!(spread >= kMinSpread) || spot_size < kPi - 1e-9 || spot_blend != 0.0)
            throw std::invalid_argument("make_spot_cone: a Spread in [1 deg, 180 deg) needs a 180 deg cone without blend");
        const double h = 0.5 * spread, ch = std::cos(h), sh = std::sin(h);
        // sin h - h cos h = h^3/3 - h^5/30 + ...: the series below 0.05 (no cancellation).
        const double norm = h > 0.05 ? sh - h * ch : h * h * h * (1.0 / 3.0 - h * h / 30.0 + h * h * h * h / 840.0);
        cone.cos_half_angle = ch;
        cone.spread_a = sh / norm;
        cone.spread_b = ch / norm;
        return cone;
    }
    cone.cos_half_angle = std::cos(0.5 * spot_size);
    cone.smooth = (1.0 - cone.cos_half_angle) * spot_blend;
    return cone;
}

SpotCone make_profile_cone(const glm::dvec3& axis, const std::vector<double>& profile, double extent) {
    SpotCone cone;
    const double len = glm::length(axis);
    cone.axis = len > 0.0 ? axis / len : glm::dvec3(0.0, 0.0, -1.0);
    cone.cos_half_angle = extent >= kPi ? -1.0 : std::cos(extent);
    cone.profile = profile;
    cone.profile_alone = true;
    return cone;
}

SpotCone make_light_cone(const SpotLight& spot) {
    if (!spot.profile.empty() && !spot.profile_in_cone)
        return make_profile_cone(spot.axis, spot.profile, spot.profile_extent);
    SpotCone cone = make_spot_cone(spot.axis, spot.spot_size, spot.spot_blend, spot.spread);
    cone.profile = spot.profile;
    return cone;
}

double profile_polynomial(const std::vector<double>& profile, double c) {
    double v = 0.0;
    for (size_t k = profile.size(); k-- > 0;) v = v * c + profile[k];
    return v;
}

namespace {
double cone_factor(const SpotCone& cone, double cos_theta) {
    if (!(cos_theta > cone.cos_half_angle)) return 0.0;
    if (cone.spread_b > 0.0)
        return std::max(0.0, cone.spread_a * cos_theta -
                                 cone.spread_b * std::sqrt(std::max(0.0, (1.0 - cos_theta) * (1.0 + cos_theta))));
    const double t = cos_theta - cone.cos_half_angle;
    if (cone.smooth > 0.0 && t < cone.smooth) {
        const double u = t / cone.smooth;
        return cos_theta * u * u * (3.0 - 2.0 * u);
    }
    return cos_theta;
}
}  // namespace

double spot_profile(const SpotCone& cone, double cos_theta) {
    if (!cone.has_profile()) return cone_factor(cone, cos_theta);
    if (cone.profile_alone)
        return cos_theta > cone.cos_half_angle || cone.cos_half_angle <= -1.0
                   ? std::max(0.0, profile_polynomial(cone.profile, cos_theta))
                   : 0.0;
    const double f = cone_factor(cone, cos_theta);
    return f == 0.0 ? 0.0 : f * std::max(0.0, profile_polynomial(cone.profile, cos_theta));
}

double ray_axis_approach(const glm::dvec3& o, const glm::dvec3& d, const glm::dvec3& s, const glm::dvec3& axis,
                         double lo, double hi) {
    // Around the closest approach to s (abscissa a, distance h, unit normal n), with
    // u = (x - a) / h: cos(theta) = (n.axis + u d.axis) / sqrt(1 + u^2), largest at
    // u = d.axis / n.axis where n.axis > 0 (else it only tends to its bound at infinity).
    const glm::dvec3 w = o - s;
    const double a = -glm::dot(w, d);
    const glm::dvec3 q = w + a * d;
    const double h = glm::length(q);
    if (!(h > 0.0)) return -1.0;
    const double dc = glm::dot(q, axis) / h;
    if (!(dc > 0.0)) return -1.0;
    const double x = a + h * glm::dot(d, axis) / dc;
    return std::isfinite(x) && x > lo && x < hi ? x : -1.0;
}

std::vector<double> ray_cone_crossings(const glm::dvec3& o, const glm::dvec3& d, const glm::dvec3& s,
                                       const glm::dvec3& axis, double cos_half, double lo, double hi) {
    // |dot(w + x d, axis)|^2 = cos_half^2 |w + x d|^2 with w = o - s: A x^2 + B x + C = 0.
    const glm::dvec3 w = o - s;
    const double k = glm::dot(d, axis), m = glm::dot(w, axis), c2 = cos_half * cos_half;
    const double A = k * k - c2 * glm::dot(d, d);
    const double B = 2.0 * (m * k - c2 * glm::dot(w, d));
    const double C = m * m - c2 * glm::dot(w, w);
    std::vector<double> roots;
    if (A == 0.0) {  // ray parallel to a generator: one crossing (the stable pair covers A ~ 0)
        if (B != 0.0) roots.push_back(-C / B);
    } else {
        const double disc = B * B - 4.0 * A * C;
        if (disc >= 0.0) {
            // Numerically stable pair (no cancellation between -B and sqrt(disc)).
            const double q = -0.5 * (B + std::copysign(std::sqrt(disc), B));
            if (q != 0.0) {
                roots.push_back(q / A);
                roots.push_back(C / q);
            } else {
                roots.push_back(0.0);
            }
        }
    }
    std::vector<double> out;
    for (double x : roots)
        if (std::isfinite(x) && x > lo && x < hi) out.push_back(x);
    std::sort(out.begin(), out.end());
    return out;
}

double spot_airlight_quadrature(const SpotCone& cone, const glm::dvec3& s, const PhaseFunction& phase,
                                double sigma_t, const glm::dvec3& o, const glm::dvec3& d, double Dvp,
                                double rel_tol) {
    if (sigma_t == 0.0 || !(Dvp > 0.0)) return 0.0;
    const glm::dvec3 w = o - s;
    const double Dsv = glm::length(w);
    const double a = -glm::dot(w, d);  // abscissa of the closest approach
    const double h = std::sqrt(std::max(0.0, Dsv * Dsv - a * a));
    const bool isotropic = phase.kind == PhaseKind::Isotropic ||
                           (phase.kind == PhaseKind::HenyeyGreenstein && phase.g == 0.0);
    // Point-light integrand times the spot profile; d^2 written around the closest approach.
    auto integrand = [&](double x) {
        const double dx = x - a;
        const double d2 = dx * dx + h * h;
        const double dist = std::sqrt(d2);
        if (!(dist > 0.0)) return 0.0;
        const glm::dvec3 u = (w + x * d) / dist;  // light -> point
        const double prof = spot_profile(cone, glm::dot(u, cone.axis));
        if (prof == 0.0) return 0.0;
        const double p = isotropic ? kInv4Pi : phase.eval(-dx / dist);
        return prof * p * std::exp(-sigma_t * (dist + x)) / d2;
    };
    const double end = Dvp;  // may be inf
    // Breakpoints: cone and blend-cone crossings (profile kinks / steps), a Spread's axis, and the peak at
    // the closest approach with a geometric ladder resolving its width h, as sun05.
    std::vector<double> cuts{0.0};
    auto add = [&](const std::vector<double>& xs) { cuts.insert(cuts.end(), xs.begin(), xs.end()); };
    add(ray_cone_crossings(o, d, s, cone.axis, cone.cos_half_angle, 0.0, end));
    const double cos_blend = cone.cos_half_angle + cone.smooth;
    if (cone.smooth > 0.0 && cos_blend < 1.0) add(ray_cone_crossings(o, d, s, cone.axis, cos_blend, 0.0, end));
    // The plane through the light normal to the axis: it separates the cone from its back
    // nappe, and for a 180 deg spot it is the cone (whose quadratic has a lost double root).
    const double k_axis = glm::dot(d, cone.axis);
    if (k_axis != 0.0) {
        const double xp = -glm::dot(w, cone.axis) / k_axis;
        if (xp > 0.0 && xp < end) cuts.push_back(xp);
    }
    if (cone.has_spread()) {  // the Spread profile's kink on the axis
        const double xa = ray_axis_approach(o, d, s, cone.axis, 0.0, end);
        if (xa > 0.0) cuts.push_back(xa);
    }
    if (a > 0.0 && a < end) {
        cuts.push_back(a);
        for (double wd = std::max(h, 1e-12 * Dsv); wd < 4.0 * Dsv; wd *= 8.0) {
            if (a - wd > 0.0) cuts.push_back(a - wd);
            if (a + wd < end) cuts.push_back(a + wd);
        }
    }
    std::sort(cuts.begin(), cuts.end());
    cuts.erase(std::unique(cuts.begin(), cuts.end()), cuts.end());
    // Between consecutive crossings the ray is wholly inside or outside the cone: test
    // each piece's midpoint and skip the dark ones (most of a narrow spot's rays).
    auto lit = [&](double x) {
        const glm::dvec3 p = w + x * d;
        const double len = glm::length(p);
        return len > 0.0 && glm::dot(p, cone.axis) > cone.cos_half_angle * len;
    };
    double sum = 0.0;
    const double piece_tol = rel_tol * 0.1;
    for (size_t i = 0; i + 1 < cuts.size(); ++i) {
        if (!lit(0.5 * (cuts[i] + cuts[i + 1]))) continue;
        sum += integrate_adaptive(integrand, cuts[i], cuts[i + 1], piece_tol);
    }
    const double last = cuts.back();
    if (std::isinf(end)) {
        // Tail [last, inf): x = last + L t / (1 - t), L the natural length scale.
        const double L = std::max({last, Dsv, 1e-300});
        if (lit(last + L)) {
            auto g = [&](double t) {
                const double om = 1.0 - t;
                const double v = integrand(last + L * t / om);
                return v == 0.0 ? 0.0 : v * L / (om * om);
            };
            sum += integrate_adaptive(g, 0.0, 1.0, piece_tol);
        }
    } else if (end > last && lit(0.5 * (last + end))) {
        sum += integrate_adaptive(integrand, last, end, piece_tol);
    }
    return sigma_t * sum;
}

}  // namespace airlight
