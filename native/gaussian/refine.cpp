// refine.cpp: Fogshop's error bound per (light, Gaussian) pair and the exact uniform-fog
// terms (refine.h).
#include "gaussian/refine.h"

#include <algorithm>
#include <cmath>
#include <mutex>

#include "homogeneous/spot_light.h"

#include "core/constants.h"
#include "core/quadrature.h"
#include "homogeneous/sunlight_layer.h"

namespace airlight {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// The bound's constants (refine.h): the largest error measured against the exact term on
// single pairs over the bound's form, then doubled.
constexpr double kGeo = 3.0;
constexpr double kPhase = 0.25;
constexpr double kThick = 0.15;
constexpr double kShade = 0.5;
// A light closer to the centre than kNear standard deviations has no bound.
constexpr double kNear = 3.0;
// Panels per piece of the exact quadrature (a smooth integrand needs one to four).
constexpr int kMaxPanels = 400;
// A Gaussian whose optical depth along the view ray exceeds this gets breakpoints in the
// uniform fog's correction.
constexpr double kThickOnRay = 0.1;

thread_local std::uint64_t work = 0;
thread_local std::uint64_t work_limit = std::numeric_limits<std::uint64_t>::max();

// Counts one Gaussian term of an integrand; past the thread's limit the refinement stops.
inline void count_work() {
    if (++work > work_limit) throw RefineWorkExceeded{};
}

double sigma_of(double a) { return 1.0 / (a * std::sqrt(2.0)); }

// sum over the Gaussians j != i near o + t u, t in [0, tmax] of c_j sqrt(2 pi) sigma t_j / tmax
// (tmax inf: sum c_j sqrt(2 pi) sigma): how much their optical depth changes across
// Gaussian i (standard deviation sigma) at the end of the path.
double shade(const GaussianMedium& medium, std::size_t i, const Vec3& o, const Vec3& u, double tmax, double sigma) {
    double G = 0.0;
    medium.for_each_near(o, u, tmax, [&](std::size_t j) {
        if (j == i) return;
        const double tj = std::clamp(glm::dot(medium.centre(j) - o, u), 0.0, tmax);
        const double scale = std::isinf(tmax) ? 1.0 : tj / tmax;
        G += medium.amplitude(j) * std::sqrt(2.0 * kPi) * sigma * scale;
    });
    return G;
}

// The bound's light term, of the geometry alone (no walk of the medium): kGeo's, 0 and _dark_
// for a Gaussian out of a spot's cone (the whole bound is 0), inf where there is no bound
// (a light within kNear standard deviations; a cone's edge, blend or Spread across the support).
struct LightTerm {
    double e = 0.0;
    bool dark = false;
};

LightTerm light_term(const GaussianMedium& medium, std::size_t i, const RefineLight& light, double kappa) {
    if (light.kind == GaussianRefLight::Kind::Sun) return {};
    const double sigma = sigma_of(medium.scale(i));
    const Vec3 sb = medium.centre(i) - light.s;
    const double D = glm::length(sb);
    if (!(D > kNear * sigma)) return {kInf, false};
    if (light.kind == GaussianRefLight::Kind::Spot) {
        const Vec3 u = sb / D;
        const double alpha = std::acos(std::clamp(glm::dot(light.cone.axis, u), -1.0, 1.0));
        const double rho = std::asin(std::min(1.0, kNear * sigma / D));
        const double edge = std::acos(std::clamp(light.cone.cos_half_angle, -1.0, 1.0));
        const double inner = std::acos(std::clamp(light.cone.cos_half_angle + light.cone.smooth, -1.0, 1.0));
        if (alpha - rho >= edge) return {0.0, true};      // outside the cone: no light
        if (alpha + rho > inner) return {kInf, false};    // the cone's edge or blend across the support
        if (light.cone.has_spread()) return {kInf, false};  // sin(h - theta) varies all across the cone
    }
    const double g = sigma / (D - 2.0 * sigma);
    return {kGeo * g * g * (1.0 + kPhase * kappa), false};
}

}  // namespace

std::uint64_t& refine_work() { return work; }
std::uint64_t& refine_work_limit() { return work_limit; }

double phase_curvature(const PhaseFunction& phase) {
    if (phase.kind == PhaseKind::Isotropic) return 0.0;
    constexpr int n = 2048;
    const double h = kPi / n;
    double worst = 0.0;
    auto lp = [&](double th) { return std::log(phase.eval(std::cos(th))); };
    for (int k = 1; k < n; ++k) {
        const double th = k * h;
        const double l0 = lp(th - h), l1 = lp(th), l2 = lp(th + h);
        const double d1 = (l2 - l0) / (2.0 * h), d2 = (l2 - 2.0 * l1 + l0) / (h * h);
        worst = std::max(worst, std::abs(d2) + d1 * d1);
    }
    return worst;
}

double fogshop_pair_bound(const GaussianMedium& medium, std::size_t i, const RefineLight& light, const Vec3& eye,
                          double kappa) {
    const LightTerm lt = light_term(medium, i, light, kappa);
    if (lt.dark) return 0.0;
    if (std::isinf(lt.e)) return kInf;
    const double a = medium.scale(i);
    const double sigma = sigma_of(a);
    const Vec3 b = medium.centre(i);
    const double beta = medium.density_near(b);  // (all of them: n^2 over the plan, minutes at 1e5)
    const double e = kThick * (beta / a) * (beta / a) + lt.e;
    double G_light = 0.0;
    if (light.kind == GaussianRefLight::Kind::Sun) {
        G_light = shade(medium, i, b, -glm::normalize(light.w), kInf, sigma);
    } else {
        const Vec3 sb = b - light.s;
        const double D = glm::length(sb);
        G_light = shade(medium, i, light.s, sb / D, D, sigma);
    }
    const Vec3 vb = b - eye;
    const double Dv = glm::length(vb);
    const double G_view = Dv > 0.0 ? shade(medium, i, eye, vb / Dv, Dv, sigma) : 0.0;
    return e + kShade * (G_light * G_light + G_view * G_view);
}

GaussianRefinePlan plan_gaussian_refinement(const GaussianMedium& medium, const Vec3& eye,
                                            const std::vector<RefineLight>& lights, const PhaseFunction& phase,
                                            double target, int threads, const std::vector<char>& whole) {
    const double kappa = phase_curvature(phase);
    const std::size_t n = medium.size(), L = lights.size();
    GaussianRefinePlan plan;
    // A light refined whole needs one pair over the target: the light terms alone find one
    // where the light is near a Gaussian (the bound is at least its light term), and its pairs
    // need no walk of the medium.
    std::vector<char> decided(L, 0);
    for (std::size_t l = 0; l < L; ++l) {
        if (l >= whole.size() || !whole[l]) continue;
        std::vector<double> e(n, -1.0);
        parallel_chunks(n, threads, 1024, [&](std::size_t begin, std::size_t end) {
            for (std::size_t i = begin; i < end; ++i)
                if (medium.cull_radius(i) > 0.0) e[i] = light_term(medium, i, lights[l], kappa).e;
        });
        const std::size_t worst = std::size_t(std::max_element(e.begin(), e.end()) - e.begin());
        if (n == 0 || !(e[worst] > target)) continue;
        decided[l] = 1;
        plan.pairs += std::size_t(std::count_if(e.begin(), e.end(), [](double x) { return x >= 0.0; }));
        plan.refined.push_back({std::uint32_t(l), std::uint32_t(worst), e[worst]});
    }
    std::vector<double> bound(L * n, 0.0);
    parallel_chunks(L * n, threads, 64, [&](std::size_t begin, std::size_t end) {
        for (std::size_t p = begin; p < end; ++p) {
            const std::size_t l = p / n, i = p % n;
            if (decided[l]) continue;
            bound[p] = medium.cull_radius(i) > 0.0 ? fogshop_pair_bound(medium, i, lights[l], eye, kappa) : -1.0;
        }
    });
    for (std::size_t p = 0; p < L * n; ++p) {
        if (decided[p / n] || bound[p] < 0.0) continue;
        ++plan.pairs;
        if (bound[p] > target)
            plan.refined.push_back({std::uint32_t(p / n), std::uint32_t(p % n), bound[p]});
        else
            plan.kept_bound = std::max(plan.kept_bound, bound[p]);
    }
    return plan;
}

GaussianRefiner::GaussianRefiner(const GaussianMedium& medium, const Vec3& eye, std::vector<RefineLight> lights,
                                 const PhaseFunction& phase, double fog_top)
    : medium_(medium), eye_(eye), lights_(std::move(lights)), phase_(phase), fog_top_(fog_top) {
    const std::size_t n = medium_.size();
    for (std::size_t j = 0; j < n; ++j) max_line_depth_ += medium_.amplitude(j) * kSqrtPi / medium_.scale(j);
}

void GaussianRefiner::gather(const Vec3& r, double t_start, double t_end, ViewDepth& view) const {
    view.lines.clear();
    medium_.for_each_near(eye_, r, t_end, [&](std::size_t j) {
        const double a = medium_.scale(j), c = medium_.amplitude(j);
        const Vec3 rel = medium_.centre(j) - eye_;
        const Vec3 cr = glm::cross(rel, r);
        const double k = c * kSqrtPi / (2.0 * a) * std::exp(-a * a * glm::dot(cr, cr));
        if (k > 0.0) view.lines.push_back({glm::dot(rel, r), a, k});
    });
    view.build(t_start);
}

void GaussianRefiner::ViewDepth::build(double start) {
    t_start = start;
    std::sort(lines.begin(), lines.end(), [](const ViewLine& x, const ViewLine& y) { return x.ts < y.ts; });
    const std::size_t n = lines.size();
    ts.resize(n);
    reach = 0.0;
    std::vector<std::pair<double, double>> by_end(n);  // (end, whole depth from t_start)
    for (std::size_t j = 0; j < n; ++j) {
        const ViewLine& g = lines[j];
        ts[j] = g.ts;
        reach = std::max(reach, kReach / g.a);
        by_end[j] = {g.ts + kReach / g.a, g.k * erf_diff(g.a * (t_start - g.ts), kInf)};
    }
    std::sort(by_end.begin(), by_end.end());
    ends.resize(n);
    passed.assign(n + 1, 0.0);
    for (std::size_t j = 0; j < n; ++j) ends[j] = by_end[j].first, passed[j + 1] = passed[j] + by_end[j].second;
}

double GaussianRefiner::ViewDepth::operator()(double t) const {
    if (lines.empty()) return 0.0;
    double T = passed[std::size_t(std::upper_bound(ends.begin(), ends.end(), t) - ends.begin())];
    const std::size_t first = std::size_t(std::lower_bound(ts.begin(), ts.end(), t - reach) - ts.begin());
    for (std::size_t j = first; j < lines.size() && ts[j] <= t + reach; ++j) {
        const ViewLine& g = lines[j];
        const double u = g.a * (t - g.ts);
        if (u > kReach || u < -kReach) continue;  // passed (in the sums) or ahead
        T += g.k * erf_diff(g.a * (t_start - g.ts), u);
        count_work();
    }
    return T;
}

double GaussianRefiner::gaussians_on(const Vec3& o, const Vec3& u, double len) const {
    double T = 0.0;
    medium_.for_each_near(o, u, len, [&](std::size_t j) {
        T += gaussian_line_integral(medium_.amplitude(j), medium_.scale(j), medium_.centre(j), o, u, 0.0, len);
        count_work();
    });
    return T;
}

double GaussianRefiner::integrate_light(const RefineLight& light, const Vec3& r, double lo, double hi,
                                        std::vector<double>& cuts, const std::function<double(double)>& f,
                                        double rel_tol, double abs_tol) const {
    const bool sun = light.kind == GaussianRefLight::Kind::Sun, spot = light.kind == GaussianRefLight::Kind::Spot;
    // Points and spots: t = t_s + h tan(theta) about the light's closest approach takes the
    // 1 / d^2 peak into the variable (dt / d^2 = dtheta / h).
    const Vec3 es = light.s - eye_;
    const double t_s = glm::dot(es, r);
    const double h = glm::length(glm::cross(es, r));
    const bool angular = !sun && h > 1e-9 * std::max(1.0, std::abs(t_s));
    auto g = [&](double theta) { return f(t_s + h * std::tan(theta)) / h; };
    auto plain = [&](double t) {
        if (sun) return f(t);
        const Vec3 sx = eye_ + t * r - light.s;
        return f(t) / std::max(glm::dot(sx, sx), 1e-12);
    };
    if (spot)
        for (double cos_cut : {light.cone.cos_half_angle, light.cone.cos_half_angle + light.cone.smooth})
            if (cos_cut < 1.0)
                for (double t : ray_cone_crossings(eye_, r, light.s, light.cone.axis, cos_cut, lo, std::min(hi, 1e300)))
                    cuts.push_back(t);
    if (spot && light.cone.has_spread())  // a Spread's kink on the axis
        cuts.push_back(ray_axis_approach(eye_, r, light.s, light.cone.axis, lo, std::min(hi, 1e300)));
    if (!sun) cuts.push_back(t_s);
    cuts.erase(std::remove_if(cuts.begin(), cuts.end(), [&](double t) { return !(t > lo && t < hi); }), cuts.end());
    cuts.push_back(lo), cuts.push_back(hi);
    std::sort(cuts.begin(), cuts.end());
    double sum = 0.0;
    for (std::size_t j = 0; j + 1 < cuts.size(); ++j) {
        const double ta = cuts[j], tb = cuts[j + 1];
        if (!(tb > ta)) continue;
        if (angular)
            sum += integrate_adaptive(g, std::atan((ta - t_s) / h), std::isinf(tb) ? 0.5 * kPi : std::atan((tb - t_s) / h),
                                      rel_tol, abs_tol, 60, kMaxPanels);
        else
            sum += integrate_adaptive(plain, ta, tb, rel_tol, abs_tol, 60, kMaxPanels);
    }
    return sum;
}

double GaussianRefiner::background_integrand(std::size_t l, const Vec3& r, double t_start, double t, Vec3& u,
                                             double& D) const {
    const RefineLight& light = lights_[l];
    const double beta0 = medium_.beta0();
    const Vec3 x = eye_ + t * r;
    if (light.kind == GaussianRefLight::Kind::Sun) {
        u = -glm::normalize(light.w);
        D = kInf;
        if (!std::isinf(fog_top_) && x.z > fog_top_) return 0.0;  // scattering inside the layer only
        const double T = sunlight_layer_depth(beta0, fog_top_, u.z, x.z);
        if (std::isinf(T)) return 0.0;
        return beta0 * phase_.eval(glm::dot(u, r)) * std::exp(-beta0 * (t - t_start) - T);
    }
    const Vec3 sx = x - light.s;
    D = glm::length(sx);
    if (!(D > 0.0)) return 0.0;
    u = sx / D;
    double weight = phase_.eval(-glm::dot(u, r));
    if (light.kind == GaussianRefLight::Kind::Spot) weight *= spot_profile(light.cone, glm::dot(light.cone.axis, u));
    if (weight == 0.0) return 0.0;
    return beta0 * weight * std::exp(-beta0 * (t - t_start + D));
}

double GaussianRefiner::integrate_background(std::size_t l, const Vec3& r, double t_start, const RaySpans& spans,
                                              const ViewDepth* view, const std::function<double(double)>& f,
                                              double rel_tol, double abs_tol) const {
    double sum = 0.0;
    std::vector<double> cuts;
    for (int q = 0; q < spans.count; ++q) {
        const double lo = std::max(spans.spans[q].first, t_start), hi = spans.spans[q].second;
        if (!(hi > lo)) continue;
        cuts.clear();
        // Where the eye-side depth changes steeply: the supports of the near Gaussians that are
        // thick on the ray (the quadrature adapts to the others); and a sun's layer top.
        if (view)
            for (const ViewLine& g : view->lines)
                if (2.0 * g.k > kThickOnRay)
                    for (double w : {-2.0, 0.0, 2.0}) cuts.push_back(g.ts + w / g.a);
        if (lights_[l].kind == GaussianRefLight::Kind::Sun && !std::isinf(fog_top_) && r.z != 0.0)
            cuts.push_back((fog_top_ - eye_.z) / r.z);
        sum += integrate_light(lights_[l], r, lo, hi, cuts, f, rel_tol, abs_tol);
    }
    return sum;
}

double GaussianRefiner::plain_background(std::size_t l, const Vec3& r, double t_start, const RaySpans& spans,
                                         double rel_tol) const {
    if (!(medium_.beta0() > 0.0)) return 0.0;
    auto f = [&](double t) {
        Vec3 u;
        double D;
        return background_integrand(l, r, t_start, t, u, D);
    };
    return integrate_background(l, r, t_start, spans, nullptr, f, rel_tol, 0.0);
}

double GaussianRefiner::background_correction(std::size_t l, const Vec3& r, double t_start, const RaySpans& spans,
                                              const ViewDepth& view, double C, double abs_tol) const {
    if (!(medium_.beta0() > 0.0)) return 0.0;
    const bool sun = lights_[l].kind == GaussianRefLight::Kind::Sun;
    const Vec3 s = lights_[l].s;
    auto f = [&](double t) {
        Vec3 u;
        double D;
        const double hom = background_integrand(l, r, t_start, t, u, D);
        if (hom == 0.0) return 0.0;
        const double T = (sun ? gaussians_on(eye_ + t * r, u, kInf) : gaussians_on(s, u, D)) + view(t);
        return hom * (std::exp(-T) - C);
    };
    return integrate_background(l, r, t_start, spans, &view, f, 1e-3, abs_tol);
}

double GaussianRefiner::background_bound(double T_view, double C) const {
    const double T = std::isinf(T_view) ? 2.0 * max_line_depth_ : T_view + max_line_depth_;
    return std::max(-std::expm1(-T), 1.0 - C);
}

}  // namespace airlight
