// quadrature.cpp: adaptive Gauss-Kronrod (7-15) references.
//
// Global adaptive scheme in the style of QUADPACK QAG: keep the subintervals in a
// max-heap by error estimate and bisect the worst one until the summed error is below
// max(abs_tol, rel_tol |I|). The error estimate of one panel is QUADPACK's qk15 rule
// (|K15 - G7| scaled by the panel's "resasc"), which is realistic for smooth panels.
#include "core/quadrature.h"
#include "core/constants.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <queue>
#include <vector>

namespace airlight {

namespace {


// Kronrod nodes (positive half, last is 0) and weights; Gauss weights for the
// 7-point rule living on the odd Kronrod nodes.
constexpr double kXgk[8] = {0.991455371120812639206854697526329, 0.949107912342758524526189684047851,
                            0.864864423359769072789712788640926, 0.741531185599394439863864773280788,
                            0.586087235467691130294144845693013, 0.405845151377397166906606412076961,
                            0.207784955007898467600689403773245, 0.0};
constexpr double kWgk[8] = {0.022935322010529224963732008058970, 0.063092092629978553290700663189204,
                            0.104790010322250183839876322541518, 0.140653259715525918745189590510238,
                            0.169004726639267902826583426598550, 0.190350578064785409913256402421014,
                            0.204432940075298892414161999234649, 0.209482141084727828012999174891714};
constexpr double kWg[4] = {0.129484966168869693270611432679082, 0.279705391489276667901467771423780,
                           0.381830050505118944950369775488975, 0.417959183673469387755102040816327};

struct Panel {
    double a, b, integral, error;
    int depth;
    bool operator<(const Panel& o) const { return error < o.error; }
};

// One 15-point Kronrod panel with QUADPACK's error estimate.
Panel gk15(const std::function<double(double)>& f, double a, double b, int depth) {
    const double c = 0.5 * (a + b), hw = 0.5 * (b - a);
    const double fc = f(c);
    double resk = fc * kWgk[7], resg = fc * kWg[3], resabs = std::abs(resk);
    double fv1[7], fv2[7];
    for (int j = 0; j < 7; ++j) {
        const double dx = hw * kXgk[j];
        fv1[j] = f(c - dx);
        fv2[j] = f(c + dx);
        resk += kWgk[j] * (fv1[j] + fv2[j]);
        resabs += kWgk[j] * (std::abs(fv1[j]) + std::abs(fv2[j]));
        if (j % 2 == 1) resg += kWg[j / 2] * (fv1[j] + fv2[j]);
    }
    const double reskh = 0.5 * resk;
    double resasc = kWgk[7] * std::abs(fc - reskh);
    for (int j = 0; j < 7; ++j) resasc += kWgk[j] * (std::abs(fv1[j] - reskh) + std::abs(fv2[j] - reskh));
    resasc *= std::abs(hw);
    double err = std::abs((resk - resg) * hw);
    if (resasc != 0.0 && err != 0.0) err = resasc * std::min(1.0, std::pow(200.0 * err / resasc, 1.5));
    const double eps = std::numeric_limits<double>::epsilon();
    if (resabs * std::abs(hw) > std::numeric_limits<double>::min() / (50.0 * eps))
        err = std::max(50.0 * eps * resabs * std::abs(hw), err);
    return {a, b, resk * hw, err, depth};
}

}  // namespace

double integrate_adaptive(const std::function<double(double)>& f, double a, double b, double rel_tol,
                          double abs_tol, int max_depth, int max_panels) {
    if (a == b) return 0.0;
    if (a > b) return -integrate_adaptive(f, b, a, rel_tol, abs_tol, max_depth, max_panels);
    // Infinite upper limit: x = a + t / (1 - t), dx = dt / (1 - t)^2, t in [0, 1).
    if (std::isinf(b)) {
        auto g = [&f, a](double t) {
            const double om = 1.0 - t;
            const double v = f(a + t / om);
            return v == 0.0 ? 0.0 : v / (om * om);
        };
        return integrate_adaptive(g, 0.0, 1.0, rel_tol, abs_tol, max_depth, max_panels);
    }
    std::priority_queue<Panel> heap;
    Panel p0 = gk15(f, a, b, 0);
    double total = p0.integral, total_err = p0.error;
    heap.push(p0);
    // _done_ holds panels that cannot be split further (depth or resolution limit).
    double done_integral = 0.0, done_error = 0.0;
    int panels = 1;
    while (!heap.empty() && total_err > std::max(abs_tol, rel_tol * std::abs(total)) && panels < max_panels) {
        Panel p = heap.top();
        heap.pop();
        const double m = 0.5 * (p.a + p.b);
        if (p.depth >= max_depth || m <= p.a || m >= p.b) {
            done_integral += p.integral;
            done_error += p.error;
            total_err -= p.error;  // accepted as is; keep it out of the loop criterion
            continue;
        }
        Panel l = gk15(f, p.a, m, p.depth + 1), r = gk15(f, m, p.b, p.depth + 1);
        total += l.integral + r.integral - p.integral;
        total_err += l.error + r.error - p.error;
        heap.push(l);
        heap.push(r);
        ++panels;
    }
    // Re-sum for accuracy (the running total accumulates rounding).
    double sum = done_integral;
    while (!heap.empty()) {
        sum += heap.top().integral;
        heap.pop();
    }
    return sum;
}

double integrate_cut(const std::function<double(double)>& f, double lo, double hi, std::vector<double> cuts,
                     double rel_tol) {
    cuts.push_back(lo);
    cuts.push_back(hi);
    std::sort(cuts.begin(), cuts.end());
    double sum = 0.0;
    for (size_t k = 0; k + 1 < cuts.size(); ++k) {
        const double a = std::max(lo, cuts[k]), b = std::min(hi, cuts[k + 1]);
        if (b > a) sum += integrate_adaptive(f, a, b, rel_tol, 0.0, 60);
    }
    return sum;
}

double integrate_piecewise(const std::function<double(double)>& f, const std::vector<double>& cuts,
                           double end, double tail_scale, double rel_tol, double abs_tol, int max_panels) {
    const double piece_abs = abs_tol / double(cuts.size());
    double sum = 0.0;
    for (size_t i = 0; i + 1 < cuts.size(); ++i)
        sum += integrate_adaptive(f, cuts[i], cuts[i + 1], rel_tol * 0.1, piece_abs, 60, max_panels);
    const double last = cuts.back();
    if (std::isinf(end)) {
        // Tail [last, inf): x = last + L t / (1 - t) with L the natural length scale.
        const double L = std::max({last, tail_scale, 1e-300});
        auto g = [&](double t) {
            const double om = 1.0 - t;
            const double v = f(last + L * t / om);
            return v == 0.0 ? 0.0 : v * L / (om * om);
        };
        sum += integrate_adaptive(g, 0.0, 1.0, rel_tol * 0.1, piece_abs, 60, max_panels);
    } else if (end > last) {
        sum += integrate_adaptive(f, last, end, rel_tol * 0.1, piece_abs, 60, max_panels);
    }
    return sum;
}

double sun05_airlight_quadrature(double sigma_t, double Dsv, double cos_gamma, double Dvp, double rel_tol) {
    if (sigma_t == 0.0 || Dvp == 0.0) return 0.0;
    const double c = std::clamp(cos_gamma, -1.0, 1.0);
    const double a = Dsv * c;                                // abscissa of the closest approach
    // Closest distance to the light, regularised as sun05 does (sin gamma >= 1e-8): a ray
    // through the light diverges and gave inf (stability suite).
    const double h = Dsv * std::max(std::sqrt((1.0 - c) * (1.0 + c)), 1e-8);
    // Eq. 5 integrand; d^2 written around the closest approach to avoid cancellation.
    auto integrand = [=](double x) {
        const double dx = x - a;
        const double d2 = dx * dx + h * h;
        const double d = std::sqrt(d2);
        return std::exp(-sigma_t * (d + x)) / d2;
    };
    // Breakpoints: the peak at _a_ and a geometric ladder around it resolving its width _h_.
    std::vector<double> cuts{0.0};
    const double end = std::isinf(Dvp) ? std::numeric_limits<double>::infinity() : Dvp;
    if (a > 0.0 && a < end) {
        for (double w = std::max(h, 1e-12 * Dsv); w < 4.0 * Dsv; w *= 8.0) {
            if (a - w > 0.0) cuts.push_back(a - w);
        }
        std::reverse(cuts.begin() + 1, cuts.end());
        cuts.push_back(a);
        for (double w = std::max(h, 1e-12 * Dsv); w < 4.0 * Dsv; w *= 8.0) {
            if (a + w < end) cuts.push_back(a + w);
        }
    }
    std::sort(cuts.begin(), cuts.end());
    const double sum = integrate_piecewise(integrand, cuts, end, Dsv, rel_tol);
    return sigma_t / (4.0 * kPi) * sum;
}

void gauss_legendre(int n, std::vector<double>& x, std::vector<double>& w) {
    x.assign(size_t(n), 0.0);
    w.assign(size_t(n), 0.0);
    for (int i = 0; i < n; ++i) {
        double z = std::cos(kPi * (i + 0.75) / (n + 0.5)), dp = 1.0;
        for (int it = 0; it < 100; ++it) {
            double p0 = 1.0, p1 = z;
            for (int k = 2; k <= n; ++k) {
                const double p2 = ((2.0 * k - 1.0) * z * p1 - (k - 1.0) * p0) / k;
                p0 = p1;
                p1 = p2;
            }
            dp = n * (z * p1 - p0) / (z * z - 1.0);
            const double dz = p1 / dp;
            z -= dz;
            if (std::abs(dz) < 1e-16) break;
        }
        x[size_t(i)] = z;
        w[size_t(i)] = 2.0 / ((1.0 - z * z) * dp * dp);
    }
}

void gauss_laguerre(int n, std::vector<double>& x, std::vector<double>& w) {
    // Newton on the Laguerre recurrence from the usual asymptotic guesses (Numerical
    // Recipes' gaulag with alpha = 0); w_i = x_i / ((n + 1) L_{n+1}(x_i))^2.
    x.assign(size_t(n), 0.0);
    w.assign(size_t(n), 0.0);
    double z = 0.0;
    for (int i = 0; i < n; ++i) {
        if (i == 0) z = 3.0 / (1.0 + 2.4 * n);
        else if (i == 1) z += 15.0 / (1.0 + 2.5 * n);
        else z += (1.0 + 2.55 * (i - 1)) / (1.9 * (i - 1)) * (z - x[size_t(i - 2)]);
        double dp = 1.0, p1 = 1.0, p2 = 0.0;
        for (int it = 0; it < 100; ++it) {
            p1 = 1.0;
            p2 = 0.0;
            for (int k = 1; k <= n; ++k) {
                const double p3 = p2;
                p2 = p1;
                p1 = ((2.0 * k - 1.0 - z) * p2 - (k - 1.0) * p3) / k;
            }
            dp = n * (p1 - p2) / z;
            const double dz = p1 / dp;
            z -= dz;
            if (std::abs(dz) <= 1e-15 * std::max(1.0, z)) break;
        }
        x[size_t(i)] = z;
        w[size_t(i)] = -1.0 / (dp * n * p2);
    }
}

}  // namespace airlight
