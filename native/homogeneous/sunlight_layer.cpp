// sunlight_layer.cpp: sun lamps in (layered) homogeneous fog, see sunlight_layer.h.
#include "homogeneous/sunlight_layer.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "core/quadrature.h"

namespace airlight {

namespace {

// (1 - e^{-k L}) / k for k >= 0, L >= 0 (L may be inf): L at k = 0, 1 / k for L = inf.
double one_minus_exp_over(double k, double L) {
    if (k == 0.0) return L;
    if (std::isinf(L)) return 1.0 / k;
    return -std::expm1(-k * L) / k;
}

}  // namespace

double sunlight_layer_factor(double sigma_t, double h_top, double mu_s, double o_z, double d_z, double t0, double t1) {
    if (!(t1 > t0)) return 0.0;
    if (std::isinf(h_top)) return one_minus_exp_over(sigma_t, t1 - t0);  // Hoffman-Preetham
    if (!(mu_s > 0.0)) return 0.0;  // the sunlight crossed infinitely much fog
    // [ta, tb]: the part of [t0, t1] below the top.
    double ta = t0, tb = t1;
    const double rise = h_top - o_z;  // the top's height above the ray origin
    if (d_z > 0.0) {
        tb = std::min(tb, rise / d_z);
    } else if (d_z < 0.0) {
        ta = std::max(ta, rise / d_z);
    } else if (rise < 0.0) {
        return 0.0;
    }
    if (!(tb > ta)) return 0.0;
    const double L = tb - ta;
    const double k = sigma_t * (1.0 - d_z / mu_s);
    if (k >= 0.0) {
        const double tau_a = sigma_t * std::max(0.0, rise - ta * d_z) / mu_s;
        return std::exp(-tau_a) * one_minus_exp_over(k, L);
    }
    // k < 0 only if d_z > mu_s > 0: tb is finite.
    const double tau_b = sigma_t * std::max(0.0, rise - tb * d_z) / mu_s;
    return std::exp(-sigma_t * L - tau_b) * one_minus_exp_over(-k, L);
}

double sunlight_layer_factor_quadrature(double sigma_t, double h_top, double mu_s, double o_z, double d_z, double t0,
                                   double t1, double rel_tol) {
    if (!(t1 > t0)) return 0.0;
    const bool layered = !std::isinf(h_top);
    auto inside = [&](double t) { return !layered || o_z + t * d_z <= h_top; };
    // Where the ray crosses the top (a breakpoint of the integrand), if it does.
    std::vector<double> cuts{t0};
    if (layered && d_z != 0.0) {
        const double t_top = (h_top - o_z) / d_z;
        if (t_top > t0 && t_top < t1) cuts.push_back(t_top);
    }
    // Optical depth of the view path from t0 to t: sigma times its length inside the fog,
    // found by clipping [t0, t] against the layer.
    auto view_depth = [&](double t) {
        if (!layered || d_z == 0.0) return sigma_t * (t - t0);
        const double t_top = (h_top - o_z) / d_z;
        const double lo = d_z > 0.0 ? t0 : std::max(t0, t_top);
        const double hi = d_z > 0.0 ? std::min(t, t_top) : t;
        return sigma_t * std::max(0.0, hi - lo);
    };
    // Optical depth of the sunlight reaching x(t): the sun ray back from x towards the
    // sun, x - s w, leaves the layer at s = (h_top - z) / mu_s.
    auto sun_depth = [&](double t) {
        if (!layered) return 0.0;
        if (!(mu_s > 0.0)) return std::numeric_limits<double>::infinity();
        return sigma_t * (h_top - (o_z + t * d_z)) / mu_s;
    };
    auto f = [&](double t) {
        if (!inside(t)) return 0.0;
        return std::exp(-view_depth(t) - sun_depth(t));
    };
    // The integrand is an exponential in t of rate |k| (sunlight_layer.h) peaking at the entry
    // into the fog or at the exit through the top: cut geometrically around both ends so
    // that narrow peaks (grazing sun: width mu_s / sigma) are resolved.
    const double k = std::abs(sigma_t * (1.0 - (layered && mu_s > 0.0 ? d_z / mu_s : 0.0)));
    if (k > 0.0 && std::isfinite(k)) {
        const double lo = cuts.size() > 1 && d_z < 0.0 ? cuts[1] : t0;  // entry
        const double hi = cuts.size() > 1 && d_z > 0.0 ? cuts[1] : t1;  // exit
        for (double j : {1.0, 4.0, 16.0, 64.0}) {
            if (lo + j / k < hi) cuts.push_back(lo + j / k);
            if (std::isfinite(hi) && hi - j / k > lo) cuts.push_back(hi - j / k);
        }
        std::sort(cuts.begin(), cuts.end());
    }
    if (std::isinf(t1)) return integrate_piecewise(f, cuts, t1, k > 0.0 ? 1.0 / k : 1.0, rel_tol);
    cuts.push_back(t1);
    double sum = 0.0;
    for (size_t i = 0; i + 1 < cuts.size(); ++i) sum += integrate_adaptive(f, cuts[i], cuts[i + 1], rel_tol);
    return sum;
}

double sunlight_span(double sigma_t, double h_top, double mu_s, double o_z, double d_z, double t_start, double a,
                     double b) {
    const double G = sunlight_layer_factor(sigma_t, h_top, mu_s, o_z, d_z, a, b);
    if (G == 0.0) return 0.0;
    // Where the ray enters the layer z <= h_top (-inf: it starts inside or never leaves).
    double enter = -std::numeric_limits<double>::infinity();
    if (std::isfinite(h_top) && d_z < 0.0 && o_z > h_top) enter = (h_top - o_z) / d_z;
    return G * std::exp(-sigma_t * (std::max(a, enter) - std::max(t_start, enter)));
}

double sunlight_layer_depth(double beta0, double h_top, double mu_s, double z) {
    if (!(beta0 > 0.0) || std::isinf(h_top)) return 0.0;
    if (mu_s > 0.0) return beta0 * std::max(0.0, h_top - z) / mu_s;
    if (mu_s == 0.0 && z > h_top) return 0.0;  // horizontal above the layer
    return std::numeric_limits<double>::infinity();
}

}  // namespace airlight
