// sphere_light.cpp: a light's radius in uniform fog (sphere_light.h).
#include "homogeneous/sphere_light.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include "core/complex_e1.h"
#include "core/constants.h"
#include "core/quadrature.h"

namespace airlight {

double sphere_light_falloff(double sigma_t, double d, double r) {
    if (!(r > 0.0)) return std::exp(-sigma_t * d) / (d * d);
    if (!(d > 0.0)) return 2.0 / (r * r);  // the disk's centre: sigma d E1(sigma d) -> 0
    const double D = std::sqrt(d * d + r * r), L = r * r / (D + d);  // L = D - d
    if (L < 0.1 * d && sigma_t * L < 2.0) {
        // Far from the disk the closed form's terms cancel (each ~ r^2 / d^2): F_r = (2 d / r^2)
        // int_d^D e^{-sigma rho} / rho^2 d rho (rho^2 = d^2 + s^2 over the disk's radius s) by
        // 8-point Gauss-Legendre on [d, D], analytic there (the pole at -d lies 10 L away).
        static const std::vector<double>* rule = [] {
            auto* xw = new std::vector<double>[2];
            gauss_legendre(8, xw[0], xw[1]);
            return xw;
        }();
        double sum = 0.0;
        for (int k = 0; k < 8; ++k) {
            const double u = 0.5 * L * (1.0 + rule[0][k]), rho = d + u;
            sum += rule[1][k] * std::exp(-sigma_t * u) / (rho * rho);
        }
        return 2.0 * d / (r * r) * std::exp(-sigma_t * d) * 0.5 * L * sum;
    }
    // 1 - (d / D) e^{-sigma (D - d)} = -expm1(-x), x = log(D / d) + sigma (D - d).
    const double x = 0.5 * std::log1p((r / d) * (r / d)) + sigma_t * L;
    double bracket = -std::expm1(-x);
    if (sigma_t > 0.0) {
        // sigma d e^{sigma d} (E1(sigma d) - E1(sigma D)), the difference without cancellation.
        const double S = complex_e1_difference_scaled(cplx(sigma_t * d, 0.0), cplx(sigma_t * D, 0.0)).real();
        bracket -= sigma_t * d * S;
    }
    return 2.0 / (r * r) * std::exp(-sigma_t * d) * std::max(0.0, bracket);
}

SphereFalloff::SphereFalloff(double sigma_t, double r) : sigma_t_(sigma_t), r_(r) {
    constexpr int kN = 2048;
    u_max_ = std::sqrt(sphere_light_reach(sigma_t, r) / r + 1.0);
    inv_du_ = (kN - 1) / u_max_;
    q_.resize(kN);
    for (int i = 0; i < kN; ++i) {
        const double u = i / inv_du_, rho = u * u * r;
        q_[size_t(i)] = sphere_light_falloff(sigma_t, rho, r) * std::exp(sigma_t * rho) * (0.5 * r * r);
    }
}

double SphereFalloff::operator()(double rho) const {
    const double x = std::sqrt(rho / r_) * inv_du_;
    if (!(x < double(q_.size() - 1))) return sphere_light_falloff(sigma_t_, rho, r_);
    const size_t i = size_t(x);
    const double f = x - double(i);
    return (q_[i] + f * (q_[i + 1] - q_[i])) * std::exp(-sigma_t_ * rho) * (2.0 / (r_ * r_));
}

double sphere_light_reach(double sigma_t, double r, double tol) {
    if (!(r > 0.0)) return 0.0;
    // (r^2 / 4)(3 y^2 + sigma y) = tol for y = 1 / rho: the expansion's relative difference.
    const double a = 0.75 * r * r, b = 0.25 * sigma_t * r * r;
    const double y = (-b + std::sqrt(b * b + 4.0 * a * tol)) / (2.0 * a);
    const double reach = 1.0 / y;
    // Beyond 10 optical depths of the light (and at least the clear fog's reach) the in-scattering
    // is e^{-10} of what it is near the light; where sigma r is large it is cut there.
    return sigma_t > 0.0 ? std::min(reach, std::max(std::sqrt(0.75 / tol) * r, 10.0 / sigma_t)) : reach;
}

bool sphere_light_window(double sigma_t, const Vec3& s, double r, const Vec3& o, const Vec3& d, double lo, double hi,
                         double& a, double& b, double tol) {
    if (!(r > 0.0) || !(hi > lo)) return false;
    const double reach = sphere_light_reach(sigma_t, r, tol);
    const Vec3 so = s - o;
    const double tc = glm::dot(so, d);
    const double h2 = std::max(0.0, glm::dot(so, so) - tc * tc);
    if (h2 >= reach * reach) return false;
    const double half = std::sqrt(reach * reach - h2);
    a = std::max(lo, tc - half);
    b = std::min(hi, tc + half);
    return b > a;
}

namespace {

// How wide (in phi) a panel of the rule may be for the phase's lobe.
double panel_width(const PhaseFunction& phase) {
    double lobe = 1.0;
    if (phase.kind == PhaseKind::HenyeyGreenstein) lobe = std::max(0.05, 1.0 - std::abs(phase.g));
    if (phase.kind == PhaseKind::HazyMie || phase.kind == PhaseKind::MurkyMie) lobe = 0.1;
    return 0.25 * kPi * lobe;
}

constexpr int kNodes = 16;

struct Rule {
    std::vector<double> x, w;
    explicit Rule(int n = kNodes) { gauss_legendre(n, x, w); }
};

// The series' integrand is ~cos^2 phi times the attenuation and the phase: 8 nodes on panels
// four times as wide (one for the isotropic phase's whole ray) (with the remainder, within 2e-4 of the point's airlight: sphere_light_test.cpp).
constexpr int kSeriesNodes = 8;

// Gauss-Legendre (_rule_) of f(phi) over [phi_a, phi_b] in equal panels at most _width_ wide.
template <class F>
double integrate_phi(const Rule& rule, double phi_a, double phi_b, double width, F f) {
    const int panels = std::max(1, int(std::ceil((phi_b - phi_a) / width)));
    const double step = (phi_b - phi_a) / panels, half = 0.5 * step;
    double sum = 0.0;
    for (int p = 0; p < panels; ++p) {
        const double mid = phi_a + (p + 0.5) * step;
        for (size_t k = 0; k < rule.x.size(); ++k) sum += half * rule.w[k] * f(mid + half * rule.x[k]);
    }
    return sum;
}

// One piece [a, b] of sphere_light_airlight (no breakpoint inside).
double airlight_piece(const PhaseFunction& phase, double sigma_t, const Vec3& s, double r, const Vec3& o,
                      const Vec3& d, double a, double b, double t_start,
                      const std::function<double(const Vec3&)>& profile, const SphereFalloff* falloff) {
    static const Rule rule;
    const Vec3 so = s - o;
    const double tc = glm::dot(so, d);
    const double h2 = std::max(0.0, glm::dot(so, so) - tc * tc);
    const double w = std::sqrt(h2 + 0.5 * r * r);
    const double phi_a = std::atan((a - tc) / w), phi_b = std::atan((b - tc) / w);
    const double sum = integrate_phi(rule, phi_a, phi_b, panel_width(phase), [&](double phi) {
        const double tn = std::tan(phi), t = tc + w * tn;
        const Vec3 x = o + t * d, sx = s - x;
        const double rho = glm::length(sx);
        const double cos_theta = rho > 0.0 ? std::clamp(glm::dot(sx, d) / rho, -1.0, 1.0) : 1.0;
        const double F = falloff ? (*falloff)(rho) : sphere_light_falloff(sigma_t, rho, r);
        double f = phase.eval(cos_theta) * std::exp(-sigma_t * (t - t_start)) * F;
        if (profile) f *= profile(x);
        return f * w * (1.0 + tn * tn);
    });
    return sigma_t * sum;
}

}  // namespace

double sphere_light_airlight(const PhaseFunction& phase, double sigma_t, const Vec3& s, double r, const Vec3& o,
                             const Vec3& d, double a, double b, double t_start,
                             const std::function<double(const Vec3&)>& profile, std::vector<double> cuts,
                             const SphereFalloff* falloff) {
    if (!(b > a) || sigma_t == 0.0) return 0.0;
    {
        // F_r(rho) has a cusp at rho = 0 (slope -2 / r^3), which the ray sees smoothed over
        // ~h about its closest approach t_c, and the phase angle turns there by up to pi: a
        // graded set of breakpoints t_c +- h 4^k out to w, so that each piece sees it smooth.
        const Vec3 so = s - o;
        const double tc = glm::dot(so, d);
        const double h = std::sqrt(std::max(0.0, glm::dot(so, so) - tc * tc));
        const double w = std::sqrt(h * h + 0.5 * r * r);
        cuts.push_back(tc);
        for (double step = h; step > 0.0 && step < w; step *= 4.0) cuts.push_back(tc - step), cuts.push_back(tc + step);
    }
    // Dense fog: pieces of at most 2 optical depths (24 at most), where tan's stretch of the
    // far parts of the window would make the attenuation steep in phi.
    for (int k = 1; k <= 24 && a + 2.0 * k / sigma_t < b; ++k) cuts.push_back(a + 2.0 * k / sigma_t);
    std::sort(cuts.begin(), cuts.end());
    double sum = 0.0, lo = a;
    for (double c : cuts) {
        if (!(c > lo) || !(c < b)) continue;
        sum += airlight_piece(phase, sigma_t, s, r, o, d, lo, c, t_start, profile, falloff);
        lo = c;
    }
    return sum + airlight_piece(phase, sigma_t, s, r, o, d, lo, b, t_start, profile, falloff);
}

bool sphere_light_series_applies(double sigma_t, double r, double h) {
    return h >= kSphereSeriesRadii * r && sigma_t * r * r <= 0.25 * h;
}

bool sphere_light_matters(double sigma_t, double r, double h, double tol) {
    if (!(r > 0.0)) return false;
    if (!(h > 0.0)) return true;
    return 0.25 * r * r * (3.0 + sigma_t * h) / (h * h) > tol;
}

double sphere_light_excess_series(const PhaseFunction& phase, double sigma_t, const Vec3& s, double r, const Vec3& o,
                                  const Vec3& d, double a, double b, double t_start,
                                  const std::function<double(const Vec3&)>& profile, std::vector<double> cuts) {
    if (!(b > a) || sigma_t == 0.0) return 0.0;
    static const Rule rule(kSeriesNodes);
    const Vec3 so = s - o;
    const double tc = glm::dot(so, d);
    const double h = std::sqrt(std::max(0.0, glm::dot(so, so) - tc * tc));
    const double r2 = r * r;
    const bool isotropic = phase_is_isotropic(phase);
    if (!isotropic) cuts.push_back(tc);
    for (int k = 1; k <= 24 && a + 2.0 * k / sigma_t < b; ++k) cuts.push_back(a + 2.0 * k / sigma_t);
    if (cuts.size() > 1) std::sort(cuts.begin(), cuts.end());
    double sum = 0.0, lo = a;
    auto piece = [&](double p0, double p1) {
        const double phi_a = std::atan((p0 - tc) / h), phi_b = std::atan((p1 - tc) / h);
        return integrate_phi(rule, phi_a, phi_b, 4.0 * panel_width(phase), [&](double phi) {
            const double tn = std::tan(phi), t = tc + h * tn;
            const Vec3 x = o + t * d, sx = s - x;
            const double rho2 = h * h * (1.0 + tn * tn), rho = std::sqrt(rho2);
            const double cos_theta = std::clamp(glm::dot(sx, d) / rho, -1.0, 1.0);
            const double eps = r2 / rho2, sr = sigma_t * rho;
            const double series = -0.25 * eps * (3.0 + sr) + eps * eps * (15.0 + 7.0 * sr + sr * sr) / 24.0;
            // e^{-sigma rho} / rho^2 dt = e^{-sigma rho} dphi / h.
            double f = (isotropic ? kInv4Pi : phase.eval(cos_theta)) * std::exp(-sigma_t * (t - t_start + rho)) *
                       series / h;
            if (profile) f *= profile(x);
            return f;
        });
    };
    for (double c : cuts) {
        if (!(c > lo) || !(c < b)) continue;
        sum += piece(lo, c);
        lo = c;
    }
    return sigma_t * (sum + piece(lo, b));
}

double sphere_light_airlight_quadrature(const PhaseFunction& phase, double sigma_t, const Vec3& s, double r,
                                        const Vec3& o, const Vec3& d, double a, double b, double t_start,
                                        double rel_tol, const std::function<double(const Vec3&)>& profile,
                                        std::vector<double> cuts) {
    if (!(b > a) || sigma_t == 0.0) return 0.0;
    const double tc = glm::dot(s - o, d);
    for (double c : {tc - r, tc, tc + r}) cuts.push_back(c);
    auto f = [&](double t) {
        const Vec3 x = o + t * d, sx = s - x;
        const double rho = glm::length(sx);
        const double cos_theta = rho > 0.0 ? std::clamp(glm::dot(sx, d) / rho, -1.0, 1.0) : 1.0;
        double v = phase.eval(cos_theta) * std::exp(-sigma_t * (t - t_start)) * sphere_light_falloff(sigma_t, rho, r);
        if (profile) v *= profile(x);
        return v;
    };
    return sigma_t * integrate_cut(f, a, b, cuts, rel_tol);
}

std::vector<Vec3> sphere_light_shadow_samples(int n) {
    if (n <= 1) return {Vec3(0.0)};
    // m points and their mirror images (so that the samples' mean is the centre: no shifted
    // light), and the centre for odd n.
    const int m = n / 2;
    const double golden = 0.5 * (std::sqrt(5.0) - 1.0), shuffle = std::sqrt(2.0) - 1.0;
    // The radii's order: k ranked by frac(k (sqrt 2 - 1)), unrelated to the directions' z (linear
    // in k) and azimuth (frac(k golden)).
    std::vector<int> order(static_cast<size_t>(m)), rank(static_cast<size_t>(m));
    for (int k = 0; k < m; ++k) order[size_t(k)] = k;
    std::sort(order.begin(), order.end(),
              [&](int a, int b) { return std::fmod(a * shuffle, 1.0) < std::fmod(b * shuffle, 1.0); });
    for (int q = 0; q < m; ++q) rank[size_t(order[size_t(q)])] = q;
    std::vector<Vec3> out;
    for (int k = 0; k < m; ++k) {
        // Radius: F^{-1}((rank + 0.5) / m) by bisection over theta = asin rho.
        const double u = (rank[size_t(k)] + 0.5) / m;
        double lo = 0.0, hi = 0.5 * kPi;
        for (int it = 0; it < 60; ++it) {
            const double mid = 0.5 * (lo + hi);
            ((2.0 * mid - std::sin(2.0 * mid)) / kPi < u ? lo : hi) = mid;
        }
        const double rho = std::sin(0.5 * (lo + hi));
        // Direction: the Fibonacci sphere's k-th point (of m).
        const double z = 1.0 - (2.0 * k + 1.0) / m, ring = std::sqrt(std::max(0.0, 1.0 - z * z));
        const double phi = 2.0 * kPi * std::fmod(k * golden, 1.0);
        out.push_back(rho * Vec3(ring * std::cos(phi), ring * std::sin(phi), z));
    }
    for (int k = 0; k < m; ++k) out.push_back(-out[size_t(k)]);
    if (n % 2) out.push_back(Vec3(0.0));
    // The one nearest the centre first (the surfaces' glow takes its shadow from it).
    std::iter_swap(out.begin(), std::min_element(out.begin(), out.end(), [](const Vec3& a, const Vec3& b) {
                       return glm::dot(a, a) < glm::dot(b, b);
                   }));
    return out;
}

std::vector<Vec3> sun_shadow_directions(const Vec3& w, double angle, int n) {
    if (n <= 1 || !(angle > 0.0)) return {w};
    const Vec3 a = glm::normalize(glm::cross(w, std::abs(w.z) < 0.9 ? Vec3(0.0, 0.0, 1.0) : Vec3(1.0, 0.0, 0.0)));
    const Vec3 b = glm::cross(w, a);
    // (Blender's largest Angle, 180 deg, is the half-space: tan(90 deg) held finite, as Cycles'
    // float tan is.)
    const double radius = std::tan(0.5 * std::min(angle, kPi - 1e-6)), golden = 0.5 * (std::sqrt(5.0) - 1.0);
    std::vector<Vec3> out;
    for (int k = 0; k < n; ++k) {
        const double rho = std::sqrt((k + 0.5) / n), phi = 2.0 * kPi * std::fmod(k * golden, 1.0);
        out.push_back(glm::normalize(w + radius * rho * (std::cos(phi) * a + std::sin(phi) * b)));
    }
    return out;
}

}  // namespace airlight
