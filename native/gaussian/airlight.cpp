// airlight.cpp: Fogshop airlight (eq. 8-17) and its quadrature reference.
//
// Per view ray the Gaussians come from the medium's cull hierarchy (those whose line
// integral on the view segment can exceed the medium's cull_eps); a skipped Gaussian
// would add at most cull_eps / (4 pi d^2) f1 to L_i. Per ray and near Gaussian the
// approximation takes three line integrals: T_i(v, p) and T_i(v, b_i^r) on the view line
// (sharing t* and h), and T_i(s, b_i^r) per light. f1 and C_sv are per (light, Gaussian)
// and per light, computed once in the constructor with culled optical depths.
//
// Where the approximation fails (measured in airlight_test.cpp, not hidden):
// - a light close to a Gaussian: 1/d^2 varies fast across the Gaussian, so sampling it at
//   b_i^r alone misses the halo's shape;
// - light shafts through holes: L_0 attenuates the whole ray by the single factor C_sv of
//   the segment s -> v, and Gaussian i by the medium on s -> b_i, so occluders between
//   the light and other parts of the ray cast no shadow (paper, Fig. 7).
// d^2 at b_i^r is kept >= kMinD2 so a light sitting on the ray stays finite.
#include "gaussian/airlight.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>

#include "core/constants.h"
#include "core/fast_erf.h"
#include "core/phase.h"
#include "core/quadrature.h"
#include "gaussian/airlight_batch.h"
#include "gaussian/centre_depths.h"
#include "gaussian/splat.h"
#include "homogeneous/sun05.h"
#include "homogeneous/sunlight_layer.h"

namespace airlight {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kMinD2 = 1e-12;

bool finite3(const Vec3& p) { return std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z); }

// The erf differences and exps of a Gaussian's term: libm in double (Exact), or the splat's
// float kernels (Fast: core/fast_erf.h, ~1e-5 relative, ~5x cheaper; exponents above 80 and
// so beyond float's range go to libm).
struct ExactMath {
    static double erf_diff(double x1, double x2) { return airlight::erf_diff(x1, x2); }
    static double exp(double x) { return std::exp(x); }
};
struct FastMath {
    static double erf_diff(double x1, double x2) {
        return x2 > x1 ? double(fast_erf_diff(float(x1), float(x2))) : 0.0;
    }
    static double exp(double x) { return x > 80.0 ? std::exp(x) : double(fast_expf_le88(float(x))); }
};

// gaussian_line_integral (medium.h) with _M_'s functions.
template <typename M>
double line_integral(double c, double a, const Vec3& b, const Vec3& o, const Vec3& r, double t0, double t1) {
    if (c == 0.0 || !(t1 > t0)) return 0.0;
    const Vec3 rel = b - o;
    const double ts = glm::dot(rel, r);
    const Vec3 cr = glm::cross(rel, r);
    const double x2 = std::isinf(t1) ? kInf : a * (t1 - ts);
    return c * kSqrtPi / (2.0 * a) * M::exp(-a * a * glm::dot(cr, cr)) * M::erf_diff(a * (t0 - ts), x2);
}

// Gaussian i on the view line v + t r: its scale a, amplitude c, the abscissa ts of the
// closest approach to its centre and k = c sqrt(pi) / (2 a) e^{-a^2 h^2} (its line integral is
// k times an erf difference; 0: too far from the line to count).
struct ViewLine {
    double a, c, ts, k;
};

template <typename M = ExactMath>
ViewLine view_line(const GaussianMedium& medium, std::size_t i, const Vec3& v, const Vec3& r) {
    const double a = medium.scale(i), c = medium.amplitude(i);
    const Vec3 rel = medium.centre(i) - v;
    const Vec3 cr = glm::cross(rel, r);
    return {a, c, glm::dot(rel, r), c * kSqrtPi / (2.0 * a) * M::exp(-a * a * glm::dot(cr, cr))};
}

void require_finite(const Vec3& p, const char* what) {
    if (!finite3(p)) {
        std::ostringstream os;
        os << "rbf_airlight: " << what << " (" << p.x << ", " << p.y << ", " << p.z << ") is not finite";
        throw std::invalid_argument(os.str());
    }
}

}  // namespace

FogshopAirlight::FogshopAirlight(const GaussianMedium& medium, const Vec3& origin, const std::vector<Vec3>& lights,
                                       const SpecialFTable* table, int threads, const std::vector<Vec3>& sun_dirs,
                                       double fog_top)
    : medium_(medium), table_(table), v_(origin), lights_(lights) {
    require_finite(origin, "viewpoint");
    for (const Vec3& s : lights_) require_finite(s, "light position");
    const std::size_t n = medium.size(), L = lights_.size();
    // C_sv = exp(-(T(s, v) - beta0 Dsv)): the Gaussians alone on the segment s -> v.
    for (const Vec3& s : lights_) {
        const Vec3 d = v_ - s;
        const double D = glm::length(d);
        Dsv_.push_back(D);
        Csv_.push_back(D > 0.0 ? std::exp(-medium.optical_depth_ray(s, d / D, D, GaussianMedium::npos, false)) : 1.0);
    }
    // f1 with Gaussian i's own terms removed: the medium without i (beta0 included) on
    // s -> b_i and v -> b_i, summed directly so that no T_i cancels against itself (the
    // splat's sums, gaussian_centre_depths, in float: the two Fogshop values agree).
    const std::vector<double> depth = gaussian_centre_depths(medium, v_, lights_, threads);
    const std::vector<double> Tv(depth.begin(), depth.begin() + std::ptrdiff_t(n));
    f1_.resize(L * n);
    for (std::size_t l = 0; l < L; ++l)
        for (std::size_t i = 0; i < n; ++i) f1_[l * n + i] = std::exp(-depth[(l + 1) * n + i] - Tv[i]);
    // Suns: the splat's f1 and C factors (GaussianSplat::sun_weights), in double.
    f1_sun_.resize(sun_dirs.size() * n);
    for (std::size_t j = 0; j < sun_dirs.size(); ++j) {
        require_finite(sun_dirs[j], "sun direction");
        const Vec3 u = -glm::normalize(sun_dirs[j]);
        sun_u_.push_back(u);
        Csun_.push_back(std::exp(-medium.optical_depth_ray(v_, u, kInf, GaussianMedium::npos, false)));
        const std::vector<double> Tg = gaussian_sun_depths(medium, u, threads);
        for (std::size_t i = 0; i < n; ++i) {
            const double Tsun = Tg[i] + sunlight_layer_depth(medium.beta0(), fog_top, u.z, medium.centre(i).z);
            f1_sun_[j * n + i] = std::isinf(Tsun) ? 0.0 : std::exp(-Tv[i] - Tsun);
        }
    }
}

template <typename H, typename G>
void FogshopAirlight::eval_terms(const Vec3& r, double Dvp, H&& homogeneous, G&& gaussian) const {
    const std::size_t L = lights_.size(), n = medium_.size();
    const double beta0 = medium_.beta0();
    // Homogeneous term L_0 (eq. 17).
    for (std::size_t l = 0; l < L; ++l) {
        if (beta0 > 0.0) {
            const double D = Dsv_[l];
            double cos_gamma = D > 0.0 ? glm::dot(r, lights_[l] - v_) / D : 1.0;
            cos_gamma = std::clamp(cos_gamma, -1.0, 1.0);
            homogeneous(l, Csv_[l] * sun05_airlight(beta0, D, cos_gamma, Dvp, table_,
                                                     table_ ? FEval::Table : FEval::Exact));
        } else {
            homogeneous(l, 0.0);
        }
    }
    // Gaussian terms L_i (eq. 11-13).
    medium_.for_each_near(v_, r, Dvp, [&](std::size_t i) {
        const ViewLine g = view_line(medium_, i, v_, r);
        if (g.k == 0.0) return;
        const double a = g.a, c = g.c, ts = g.ts, k = g.k;
        const Vec3 b = medium_.centre(i);
        const double x1 = -a * ts;
        const double Tvp = k * erf_diff(x1, std::isinf(Dvp) ? kInf : a * (Dvp - ts));
        if (Tvp == 0.0) return;
        const double tr = std::clamp(ts, 0.0, Dvp);
        const double Tvr = k * erf_diff(x1, a * (tr - ts));
        const Vec3 xr = v_ + tr * r;
        for (std::size_t l = 0; l < L; ++l) {
            const Vec3 sx = xr - lights_[l];
            const double d2 = glm::dot(sx, sx);
            const double Ds = std::sqrt(d2);
            const double Tsr = Ds > 0.0 ? gaussian_line_integral(c, a, b, lights_[l], sx / Ds, 0.0, Ds) : 0.0;
            gaussian(l, i, kInv4Pi / std::max(d2, kMinD2) * std::exp(-Tsr - Tvr) * f1_[l * n + i] * Tvp);
        }
    });
}

RGB FogshopAirlight::eval_rgb_spans(const Vec3& r, double t_start, const RaySpans* spans, const double* albedo,
                                    const RGB* I0, const RGB& medium_albedo, const PhaseFunction* phase,
                                    const SpanBackground* background, const SpanProfile* profile,
                                    bool fast) const {
    const std::size_t L = lights_.size(), S = sun_u_.size();
    const double beta0 = medium_.beta0();
    double far = 0.0;  // the farthest lit point of any light: the Gaussians near the ray up to it
    for (std::size_t l = 0; l < L + S; ++l)
        for (int k = 0; k < spans[l].count; ++k) far = std::max(far, spans[l].spans[k].second);
    RGB out(0.0);
    if (!(far > 0.0)) return out;
    // The fog starts at t_start: the terms shed what f1 and C_sv count before it (the splat's
    // exp(T(v, t0))).
    const double Tg_near = near_depth(r, t_start), near_gain = std::exp(Tg_near);
    // Homogeneous term: sun05 on each lit span [ta, tb], attenuated by beta0 to ta, times C_sv.
    if (beta0 > 0.0)
        for (std::size_t l = 0; l < L; ++l) {
            double sum = 0.0;
            for (int k = 0; k < spans[l].count; ++k) {
                const double ta = spans[l].spans[k].first, tb = spans[l].spans[k].second;
                if (!(tb > ta)) continue;
                double span;
                if (background) {
                    span = (*background)(l, ta, tb);
                } else {
                    const Vec3 sx = lights_[l] - (v_ + ta * r);
                    const double D = glm::length(sx);
                    const double cos_gamma = D > 0.0 ? std::clamp(glm::dot(r, sx) / D, -1.0, 1.0) : 1.0;
                    span = sun05_airlight(beta0, D, cos_gamma, tb - ta, table_, table_ ? FEval::Table : FEval::Exact);
                }
                sum += std::exp(-beta0 * (ta - t_start)) * span;
            }
            out += medium_albedo * I0[l] * (near_gain * Csv_[l] * sum);
        }
    if (beta0 > 0.0 && background)
        for (std::size_t j = 0; j < S; ++j) {
            double sum = 0.0;
            for (int k = 0; k < spans[L + j].count; ++k) {
                const double ta = spans[L + j].spans[k].first, tb = spans[L + j].spans[k].second;
                if (tb > ta) sum += (*background)(L + j, ta, tb);
            }
            out += medium_albedo * I0[L + j] * (near_gain * Csun_[j] * sum);
        }
    // Gaussian terms: eq. 11 with T_i over the lit spans.
    const double near_depth = t_start > 0.0 ? beta0 * t_start + Tg_near : 0.0;
    if (fast && near_depth <= 80.0) {  // (the batch's float exponents)
        thread_local std::vector<std::size_t> near;
        near.clear();
        medium_.for_each_near(v_, r, far, [&](std::size_t i) { near.push_back(i); });
        for (std::size_t l = 0; l < L + S; ++l) {
            if (spans[l].count == 0) continue;
            out += light_terms(l, r, t_start, spans[l], phase, profile, near, near_depth, albedo) * I0[l];
        }
        return out;
    }
    medium_.for_each_near(v_, r, far, [&](std::size_t i) {
        for (std::size_t l = 0; l < L + S; ++l) {
            const double v = gaussian_term(i, l, r, t_start, spans[l], phase, profile, Tg_near, fast);
            if (v != 0.0) out += RGB(albedo[3 * i], albedo[3 * i + 1], albedo[3 * i + 2]) * I0[l] * v;
        }
    });
    return out;
}

RGB FogshopAirlight::light_terms(std::size_t l, const Vec3& r, double t_start, const RaySpans& lit,
                                 const PhaseFunction* phase, const SpanProfile* profile,
                                 const std::vector<std::size_t>& near, double near_depth, const double* albedo) const {
    // term<FastMath>'s geometry in double, its erf differences and exps in the batch's loops.
    thread_local FogshopTermBatch b;
    thread_local std::vector<double> scale, line_ts;  // a_i and t*_i
    const std::size_t n = near.size(), N = medium_.size();
    b.resize(n), scale.resize(n), line_ts.resize(n);
    double Dvp = 0.0;
    for (int q = 0; q < lit.count; ++q) Dvp = std::max(Dvp, lit.spans[q].second);
    const std::size_t L = lights_.size();
    const bool sun = l >= L;
    const Vec3& s = sun ? v_ : lights_[l];
    // (A sun's phase angle is the same all along the ray.)
    const double p_sun = !sun ? 0.0 : phase ? phase->eval(glm::dot(sun_u_[l - L], r)) : kInv4Pi;
    for (std::size_t j = 0; j < n; ++j) {
        const std::size_t i = near[j];
        const ViewLine g = view_line<FastMath>(medium_, i, v_, r);
        const double a = g.a, ts = g.ts;
        scale[j] = a, line_ts[j] = ts;
        b.k[j] = float(g.k), b.Tlit[j] = 0.0f;
        const double tr = std::clamp(ts, t_start, std::max(t_start, Dvp));
        b.view0[j] = float(a * (t_start - ts)), b.view1[j] = float(a * (tr - ts));
        b.near0[j] = t_start > 0.0 ? float(-a * ts) : 0.0f;
        b.near1[j] = t_start > 0.0 ? float(a * (t_start - ts)) : 0.0f;
        const Vec3 sx = v_ + tr * r - s;
        const double d2 = glm::dot(sx, sx), Ds = std::sqrt(d2);
        b.kl[j] = 0.0f, b.light_h[j] = 0.0f, b.light0[j] = 0.0f, b.light1[j] = 0.0f, b.factor[j] = 0.0f;
        if (g.k == 0.0) continue;
        if (sun) {  // the light path: from the point tr towards the sun, to infinity
            const Vec3& u = sun_u_[l - L];
            const Vec3 rel = medium_.centre(i) - (v_ + tr * r);
            const double tsl = glm::dot(rel, u);
            const Vec3 cr = glm::cross(rel, u);
            b.kl[j] = float(g.c * kSqrtPi / (2.0 * a)), b.light_h[j] = float(-a * a * glm::dot(cr, cr));
            b.light0[j] = float(-a * tsl), b.light1[j] = std::numeric_limits<float>::infinity();
            b.factor[j] = float(p_sun * f1_sun_[(l - L) * N + i]);
            continue;
        }
        double p = kInv4Pi;
        if (Ds > 0.0) {
            const Vec3 u = sx / Ds, rel = medium_.centre(i) - s;
            const double tsl = glm::dot(rel, u);
            const Vec3 cr = glm::cross(rel, u);
            b.kl[j] = float(g.c * kSqrtPi / (2.0 * a)), b.light_h[j] = float(-a * a * glm::dot(cr, cr));
            b.light0[j] = float(-a * tsl), b.light1[j] = float(a * (Ds - tsl));
            if (phase) p = phase->eval(-glm::dot(sx, r) / Ds);
            if (profile) p *= (*profile)(l, u);
        }
        b.factor[j] = float(p / std::max(d2, kMinD2) * f1_[l * N + i]);
    }
    for (int q = 0; q < lit.count; ++q) {
        const double ta = lit.spans[q].first, tb = lit.spans[q].second;
        if (!(tb > ta)) continue;
        for (std::size_t j = 0; j < n; ++j) {
            b.x1[j] = float(scale[j] * (ta - line_ts[j]));
            b.x2[j] = std::isinf(tb) ? std::numeric_limits<float>::infinity() : float(scale[j] * (tb - line_ts[j]));
        }
        add_lit_span(b, n);
    }
    fogshop_point_terms(b, n, float(near_depth));
    RGB out(0.0);
    for (std::size_t j = 0; j < n; ++j)
        if (b.out[j] != 0.0f) {
            const std::size_t i = near[j];
            out += RGB(albedo[3 * i], albedo[3 * i + 1], albedo[3 * i + 2]) * double(b.out[j]);
        }
    return out;
}

double FogshopAirlight::near_depth(const Vec3& r, double t_start) const {
    return t_start > 0.0 ? medium_.optical_depth_ray(v_, r, t_start, GaussianMedium::npos, false) : 0.0;
}

double FogshopAirlight::gaussian_term(std::size_t i, std::size_t l, const Vec3& r, double t_start,
                                      const RaySpans& lit, const PhaseFunction* phase,
                                      const SpanProfile* profile, double Tg_near, bool fast) const {
    return fast ? term<FastMath>(i, l, r, t_start, lit, phase, profile, Tg_near)
                : term<ExactMath>(i, l, r, t_start, lit, phase, profile, Tg_near);
}

template <typename M>
double FogshopAirlight::term(std::size_t i, std::size_t l, const Vec3& r, double t_start, const RaySpans& lit,
                             const PhaseFunction* phase, const SpanProfile* profile, double Tg_near) const {
    const std::size_t L = lights_.size(), n = medium_.size();
    if (lit.count == 0) return 0.0;
    const ViewLine g = view_line<M>(medium_, i, v_, r);
    if (g.k == 0.0) return 0.0;
    const double a = g.a, c = g.c, ts = g.ts, k = g.k;
    const Vec3 b = medium_.centre(i);
    double Tlit = 0.0, Dvp = 0.0;
    for (int q = 0; q < lit.count; ++q) {
        const double ta = lit.spans[q].first, tb = lit.spans[q].second;
        Tlit += k * M::erf_diff(a * (ta - ts), std::isinf(tb) ? kInf : a * (tb - ts));
        Dvp = std::max(Dvp, tb);
    }
    if (!(Tlit > 0.0)) return 0.0;
    const double tr = std::clamp(ts, t_start, std::max(t_start, Dvp));
    const double Tvr = k * M::erf_diff(a * (t_start - ts), a * (tr - ts));
    // f1 counts the medium from the eye: shed its part before t_start (Gaussian i's own is in Tvr).
    const double Tnear = t_start > 0.0 ? medium_.beta0() * t_start + Tg_near - k * M::erf_diff(-a * ts, a * (t_start - ts)) : 0.0;
    if (l < L) {
        const Vec3 sx = v_ + tr * r - lights_[l];
        const double d2 = glm::dot(sx, sx);
        const double Ds = std::sqrt(d2);
        const double Tsr = Ds > 0.0 ? line_integral<M>(c, a, b, lights_[l], sx / Ds, 0.0, Ds) : 0.0;
        double p = phase && Ds > 0.0 ? phase->eval(-glm::dot(sx, r) / Ds) : kInv4Pi;
        if (profile && Ds > 0.0) p *= (*profile)(l, sx / Ds);
        if (p == 0.0) return 0.0;
        return p / std::max(d2, kMinD2) * M::exp(Tnear - Tsr - Tvr) * f1_[l * n + i] * Tlit;
    }
    const std::size_t j = l - L;
    if (f1_sun_[j * n + i] == 0.0) return 0.0;
    const Vec3& u = sun_u_[j];
    const double Tsr = line_integral<M>(c, a, b, v_ + tr * r, u, 0.0, kInf);
    const double p = phase ? phase->eval(glm::dot(u, r)) : kInv4Pi;
    return p * M::exp(Tnear - Tsr - Tvr) * f1_sun_[j * n + i] * Tlit;
}

void FogshopAirlight::eval(const Vec3& r, double Dvp, double* out) const {
    eval_terms(
        r, Dvp, [&](std::size_t l, double v) { out[l] = v; },
        [&](std::size_t l, std::size_t, double v) { out[l] += v; });
}

RGB FogshopAirlight::eval_rgb(const Vec3& r, double Dvp, const double* albedo, const RGB* I0,
                                 const RGB& medium_albedo) const {
    RGB out(0.0);
    eval_terms(
        r, Dvp, [&](std::size_t l, double v) { out += medium_albedo * I0[l] * v; },
        [&](std::size_t l, std::size_t i, double v) {
            out += RGB(albedo[3 * i], albedo[3 * i + 1], albedo[3 * i + 2]) * I0[l] * v;
        });
    return out;
}

double gaussian_airlight_quadrature(const GaussianMedium& medium, const Vec3& s, const Vec3& v, const Vec3& r, double Dvp,
                               double rel_tol, GaussianSums sums) {
    GaussianRefLight light;
    light.s = s;
    return gaussian_airlight_quadrature(medium, light, PhaseFunction{}, v, r, Dvp, rel_tol, sums);
}

double gaussian_airlight_quadrature(const GaussianMedium& medium, const GaussianRefLight& light, const PhaseFunction& phase,
                               const Vec3& v, const Vec3& r, double Dvp, double rel_tol, GaussianSums sums) {
    const bool culled = sums == GaussianSums::Culled;
    const bool sun = light.kind == GaussianRefLight::Kind::Sun, spot = light.kind == GaussianRefLight::Kind::Spot;
    const bool isotropic = phase.kind == PhaseKind::Isotropic;
    const Vec3 s = sun ? v : light.s;  // (suns: only for the breakpoint layout below)
    const Vec3 u_sun = -light.w;        // towards the sun
    const double top = light.fog_top, mu_s = u_sun.z;
    const std::size_t n = medium.size();
    const double beta0 = medium.beta0();
    // Per-Gaussian view-line data: t*, a, c sqrt(pi)/(2a) e^{-a^2 h^2}, c e^{-a^2 h^2}.
    struct Line {
        double ts, a, k, ch;
        bool near;  // within 5 widths of the ray: its peak gets breakpoints
    };
    std::vector<Line> line;
    auto add_line = [&](std::size_t i) {
        const double a = medium.scale(i), c = medium.amplitude(i);
        const Vec3 rel = medium.centre(i) - v;
        const Vec3 cr = glm::cross(rel, r);
        const double ah2 = a * a * glm::dot(cr, cr);
        const double eh = std::exp(-ah2);
        if (c * eh == 0.0) return;
        line.push_back({glm::dot(rel, r), a, c * kSqrtPi / (2.0 * a) * eh, c * eh, ah2 < 25.0});
    };
    if (culled) {
        medium.for_each_near(v, r, std::isinf(Dvp) ? kInf : Dvp, add_line);
    } else {
        line.reserve(n);
        for (std::size_t i = 0; i < n; ++i) add_line(i);
    }
    // Half-line depth of the Gaussians from x towards the sun.
    auto sun_depth = [&](const Vec3& x) {
        if (culled) return medium.optical_depth_ray(x, u_sun, kInf, GaussianMedium::npos, false);
        double Ts = 0.0;
        for (std::size_t i = 0; i < n; ++i) Ts += medium.gaussian_optical_depth(i, x, u_sun, 0.0, kInf);
        return Ts;
    };
    // Eq. 2 integrand with exact optical depths: T(v, x) from the view-line data, T(s, x)
    // over the Gaussians (_sums_).
    auto integrand = [&](double t) {
        const Vec3 x = v + t * r;
        double beta = beta0, Tv = beta0 == 0.0 ? 0.0 : beta0 * t;
        for (const Line& g : line) {
            const double u = g.a * (t - g.ts);
            beta += g.ch * std::exp(-u * u);
            Tv += g.k * erf_diff(-g.a * g.ts, u);
        }
        if (sun) {
            // Scattering: Gaussians, and beta0 inside the layer only.
            const bool in_layer = std::isinf(top) || x.z <= top;
            if (!in_layer) beta -= beta0;
            if (!(beta > 0.0)) return 0.0;
            if (light.visible && !light.visible(x)) return 0.0;
            double Ts = sun_depth(x);
            if (beta0 > 0.0 && !std::isinf(top)) {
                if (mu_s > 0.0) Ts += beta0 * std::max(0.0, top - x.z) / mu_s;
                else if (!(mu_s == 0.0 && x.z > top)) return 0.0;  // no sunlight
            }
            return beta * phase.eval(-glm::dot(light.w, r)) * std::exp(-Ts - Tv);
        }
        if (beta == 0.0) return 0.0;
        const Vec3 sx = x - s;
        const double d2 = glm::dot(sx, sx);
        double f = isotropic ? kInv4Pi : phase.eval(-glm::dot(sx, r) / std::sqrt(d2));
        if (spot) {
            f *= spot_profile(light.cone, glm::dot(light.cone.axis, sx) / std::sqrt(d2));
            if (f == 0.0) return 0.0;
        }
        if (light.visible && !light.visible(x)) return 0.0;
        const double Ts = culled ? medium.optical_depth(s, x) : medium.optical_depth_all(s, x);
        return beta * f / d2 * std::exp(-Ts - Tv);
    };
    // Breakpoints: each Gaussian's projection and +-1, 2, 4 widths, and a geometric
    // ladder around the light's closest approach (width h, the 1/d^2 peak).
    const double end = std::isinf(Dvp) ? kInf : Dvp;
    std::vector<double> cuts{0.0};
    auto add = [&](double t) {
        if (t > 0.0 && t < end) cuts.push_back(t);
    };
    for (const Line& g : line)
        if (g.near)
            for (double k : {-4.0, -2.0, -1.0, 0.0, 1.0, 2.0, 4.0}) add(g.ts + k / g.a);
    const Vec3 rs = s - v;
    const double Dsv = glm::length(rs);
    const double as = glm::dot(rs, r);
    const double hs = glm::length(glm::cross(rs, r));
    if (!sun) {
        add(as);
        for (double w = std::max(hs, 1e-12 * Dsv); w < 4.0 * Dsv; w *= 8.0) {
            add(as - w);
            add(as + w);
        }
    } else if (!std::isinf(top) && r.z != 0.0) {
        add((top - v.z) / r.z);  // the layer's top
    }
    if (spot) {  // the cone and the inner (blend) cone
        for (double c : {light.cone.cos_half_angle, light.cone.cos_half_angle + light.cone.smooth})
            if (c < 1.0)
                for (double t : ray_cone_crossings(v, r, s, light.cone.axis, c, 0.0, end)) add(t);
        if (light.cone.has_spread()) add(ray_axis_approach(v, r, s, light.cone.axis, 0.0, end));  // its kink
    }
    for (double t : light.jumps) add(t);  // where the light's visibility changes
    std::sort(cuts.begin(), cuts.end());
    cuts.erase(std::unique(cuts.begin(), cuts.end()), cuts.end());
    // Tail [last, inf): t = last + S u / (1 - u).
    const double last = cuts.back();
    const double S = std::max({last, Dsv, 1.0});
    auto tail = [&](double u) {
        const double om = 1.0 - u;
        const double f = integrand(last + S * u / om);
        return f == 0.0 ? 0.0 : f * S / (om * om);
    };
    // A rough pass (one Kronrod panel each) sets the absolute tolerance, so panels where
    // the integrand is negligible do not chase a relative tolerance on nothing.
    double rough = 0.0;
    for (std::size_t j = 0; j + 1 < cuts.size(); ++j)
        rough += std::abs(integrate_adaptive(integrand, cuts[j], cuts[j + 1], 1.0, 0.0, 0));
    if (std::isinf(end)) rough += std::abs(integrate_adaptive(tail, 0.0, 1.0, 1.0, 0.0, 0));
    else rough += std::abs(integrate_adaptive(integrand, last, end, 1.0, 0.0, 0));
    const std::size_t panels = cuts.size();
    const double abs_tol = 1e-3 * rel_tol * rough / static_cast<double>(panels);
    double sum = 0.0;
    for (std::size_t j = 0; j + 1 < cuts.size(); ++j)
        sum += integrate_adaptive(integrand, cuts[j], cuts[j + 1], rel_tol * 0.1, abs_tol);
    if (std::isinf(end)) sum += integrate_adaptive(tail, 0.0, 1.0, rel_tol * 0.1, abs_tol);
    else if (end > last) sum += integrate_adaptive(integrand, last, end, rel_tol * 0.1, abs_tol);
    return sum;
}

void gaussian_airlight(const GaussianMedium& medium, const std::vector<Vec3>& lights, const Vec3& origin, const Vec3* dirs,
                  const double* Dvp, std::size_t n, double* out, GaussianAirlightModel model, const SpecialFTable* table,
                  int threads) {
    require_finite(origin, "viewpoint");
    for (const Vec3& s : lights) require_finite(s, "light position");
    for (std::size_t j = 0; j < n; ++j) {
        const double len = glm::length(dirs[j]);
        if (!finite3(dirs[j]) || std::abs(len - 1.0) > 1e-6) {
            std::ostringstream os;
            os << "rbf_airlight: direction " << j << " (" << dirs[j].x << ", " << dirs[j].y << ", " << dirs[j].z
               << ") is not a finite unit vector";
            throw std::invalid_argument(os.str());
        }
        if (std::isnan(Dvp[j]) || !(Dvp[j] > 0.0)) {
            std::ostringstream os;
            os << "rbf_airlight: Dvp[" << j << "] = " << Dvp[j] << " is invalid (need Dvp > 0, may be inf)";
            throw std::invalid_argument(os.str());
        }
    }
    const std::size_t L = lights.size();
    if (L == 0 || n == 0) return;
    if (model == GaussianAirlightModel::Quadrature) {
        parallel_chunks(n, threads, 4, [&](std::size_t b, std::size_t e) {
            for (std::size_t j = b; j < e; ++j)
                for (std::size_t l = 0; l < L; ++l)
                    out[j * L + l] = gaussian_airlight_quadrature(medium, lights[l], origin, dirs[j], Dvp[j]);
        });
        return;
    }
    FogshopAirlight fogshop(medium, origin, lights, table, threads);
    parallel_chunks(n, threads, 512, [&](std::size_t b, std::size_t e) {
        for (std::size_t j = b; j < e; ++j) fogshop.eval(dirs[j], Dvp[j], out + j * L);
    });
}

}  // namespace airlight
