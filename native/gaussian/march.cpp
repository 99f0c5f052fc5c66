// march.cpp: the marched airlight of Gaussian fog (march.h).
#include "gaussian/march.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "core/constants.h"

namespace airlight {

namespace {

// A Gaussian's density on the ray: c e^{-a^2 h^2} e^{-a^2 (t - ts)^2}, negligible (below e^-20
// of its peak) outside [lo, hi].
struct RayGaussian {
    double ts, a, peak, lo, hi;
};

constexpr double kWindow = 20.0;  // a^2 (h^2 + (t - ts)^2) beyond which a density is left out
constexpr double kStepTol = 1e-3;  // Simpson against trapezoids within a step (relative; depth: absolute)
constexpr double kMinStep = 1e-9;  // relative to max(1, t): no step is halved below it
constexpr double kOpaque = 700.0;  // the view depth past which nothing is left (e^-700 ~ 1e-304)

}  // namespace

double gaussian_march_airlight(const GaussianMedium& medium, const Vec3& s, const PhaseFunction& phase,
                               const Vec3& v, const Vec3& r, double Dvp, const LightDepthMap* map,
                               GaussianMarch& march) {
    march.steps = 0;
    const bool infinite = std::isinf(Dvp);
    std::vector<RayGaussian> line;
    double narrowest = std::numeric_limits<double>::infinity(), last_end = 0.0;
    medium.for_each_near(v, r, Dvp, [&](std::size_t g) {
        const double a = medium.scale(g), c = medium.amplitude(g);
        const Vec3 rel = medium.centre(g) - v;
        const Vec3 cr = glm::cross(rel, r);
        const double ah2 = a * a * glm::dot(cr, cr);
        if (ah2 >= kWindow) return;
        const double ts = glm::dot(rel, r), reach = std::sqrt(kWindow - ah2) / a;
        if (ts + reach <= 0.0) return;
        line.push_back({ts, a, c * std::exp(-ah2), ts - reach, ts + reach});
        narrowest = std::min(narrowest, 1.0 / (a * std::sqrt(2.0)));
        last_end = std::max(last_end, ts + reach);
    });
    std::sort(line.begin(), line.end(), [](const RayGaussian& x, const RayGaussian& y) { return x.lo < y.lo; });
    const double beta0 = medium.beta0();
    const bool isotropic = phase.kind == PhaseKind::Isotropic;
    const double lobe = std::min(1.0, phase.lobe_width());
    const double inside_step = march.step_widths * narrowest;
    const Vec3 vs = s - v;
    const double t_s = glm::dot(vs, r);  // the light's closest approach
    const double p_max = isotropic ? kInv4Pi : std::max(phase.eval(1.0), phase.eval(-1.0));

    std::vector<const RayGaussian*> active;
    std::size_t next = 0;
    auto density = [&](double t) {
        double beta = beta0;
        for (const RayGaussian* g : active) {
            const double u = g->a * (t - g->ts);
            beta += g->peak * std::exp(-u * u);
        }
        return beta;
    };
    auto light_depth = [&](const Vec3& x, double d) {
        return map ? beta0 * d + (*map)(x) : medium.optical_depth(s, x);
    };
    auto in_scattered = [&](double t, double beta, double Tv) {
        if (beta == 0.0) return 0.0;
        const Vec3 sx = v + t * r - s;
        const double d2 = glm::dot(sx, sx);
        if (!(d2 > 0.0)) return 0.0;
        const double d = std::sqrt(d2);
        const double p = isotropic ? kInv4Pi : phase.eval(-glm::dot(sx, r) / d);
        return beta * p / d2 * std::exp(-light_depth(v + t * r, d) - Tv);
    };

    double t = 0.0, Tv = 0.0, sum = 0.0;
    while (next < line.size() && line[next].lo <= 0.0) active.push_back(&line[next++]);
    double beta_a = density(0.0), f_a = in_scattered(0.0, beta_a, 0.0);
    const double end = infinite ? std::numeric_limits<double>::max() : Dvp;
    while (t < end) {
        const double d = glm::length(v + t * r - s);
        const bool in_fog = !active.empty() || (next < line.size() && line[next].lo < t + 0.1 * d);
        double h = 0.1 * std::max(d, 1e-9 * std::max(1.0, glm::length(vs))) * lobe;
        if (in_fog) h = std::min(h, inside_step);
        if (next < line.size() && line[next].lo > t) h = std::min(h, std::max(line[next].lo - t, inside_step));
        h = std::min({h, end - t, 0.5 / beta_a});  // (thick fog: a step's depth stays below 1/2)
        double beta_m, beta_b, T_b, f_m, f_b, step;
        for (;;) {
            while (next < line.size() && line[next].lo <= t + h) active.push_back(&line[next++]);
            beta_m = density(t + 0.5 * h), beta_b = density(t + h);
            const double T_m = Tv + h / 24.0 * (5.0 * beta_a + 8.0 * beta_m - beta_b);
            T_b = Tv + h / 6.0 * (beta_a + 4.0 * beta_m + beta_b);
            f_m = in_scattered(t + 0.5 * h, beta_m, T_m), f_b = in_scattered(t + h, beta_b, T_b);
            step = h / 6.0 * (f_a + 4.0 * f_m + f_b);
            // Simpson against the trapezoids of the same points: a step where they part by more
            // than kStepTol (a shadow's edge, a thick Gaussian's rim) is halved.
            const double trapezoids = h / 4.0 * (f_a + 2.0 * f_m + f_b);
            const double depth_gap = std::abs(T_b - Tv - h / 4.0 * (beta_a + 2.0 * beta_m + beta_b));
            if ((std::abs(step - trapezoids) <= kStepTol * std::max(step, march.tail_tol * sum) && depth_gap <= kStepTol) ||
                h <= kMinStep * std::max(1.0, t))
                break;
            h *= 0.5;
        }
        sum += step;
        t += h, Tv = T_b, beta_a = beta_b, f_a = f_b;
        ++march.steps;
        if (Tv > kOpaque) break;
        active.erase(std::remove_if(active.begin(), active.end(), [&](const RayGaussian* g) { return g->hi < t; }),
                     active.end());
        if (infinite && active.empty() && next == line.size() && t > std::max(t_s, last_end)) {
            // Only the uniform fog is left: its rest is below beta0 p_max e^{-Tv} / (t - t_s).
            if (beta0 == 0.0 || beta0 * p_max * std::exp(-Tv) / (t - t_s) <= march.tail_tol * sum) break;
        }
    }
    return sum;
}

}  // namespace airlight
