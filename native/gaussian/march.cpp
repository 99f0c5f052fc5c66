// march.cpp: the marched airlight of Gaussian fog (march.h).
#include "gaussian/march.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <optional>
#include <vector>

#include "core/constants.h"
#include "core/fast_erf.h"
#include "core/target_clones.h"
#include "homogeneous/sunlight_layer.h"

namespace airlight {

namespace {

// A Gaussian's density on the ray: c e^{-a^2 h^2} e^{-a^2 (t - ts)^2}, negligible (below e^-20
// of its peak) outside [lo, hi]; its albedo.
struct RayGaussian {
    double ts, a, peak, lo, hi;
    RGB albedo;
};

constexpr double kDepthTol = 1e-3;  // Simpson against trapezoids on a step's view depth (absolute)
constexpr double kMinStep = 1e-9;  // relative to max(1, t): no step is halved below it
constexpr double kOpaque = 700.0;  // the view depth past which nothing is left (e^-700 ~ 1e-304)

struct Density {
    double beta;  // extinction
    RGB sigma_s;  // scattering
};

// A Gaussian's width 1 / (a sqrt 2) (its density's standard deviation).
double width(double a) { return 0.70710678118654752 / a; }

// The Gaussians of the window (those whose support holds the step), as arrays for the kernel.
struct Window {
    std::vector<double> ts, hi;
    std::vector<float> a, peak, r, g, b;
    std::vector<float> e;  // the kernel's densities
    double first_end = std::numeric_limits<double>::infinity();  // the least hi
    double narrowest = std::numeric_limits<double>::infinity();  // the least width 1 / (a sqrt 2)
    void push(const RayGaussian& x) {
        first_end = std::min(first_end, x.hi);
        narrowest = std::min(narrowest, width(x.a));
        ts.push_back(x.ts), hi.push_back(x.hi);
        a.push_back(float(x.a)), peak.push_back(float(x.peak));
        r.push_back(float(x.albedo.x)), g.push_back(float(x.albedo.y)), b.push_back(float(x.albedo.z));
    }
    std::size_t size() const { return ts.size(); }
    bool empty() const { return ts.empty(); }
    // Drops the Gaussians that end before t, every kLazy-th step that has some: the compaction
    // (7 arrays and a branch each step and Gaussian) was a third of the march's own time when
    // it ran every step; a passed Gaussian left in adds its density below e^-20 of its peak.
    static constexpr int kLazy = 8;
    int since = 0;
    void drop(double t) {
        if (!(first_end < t) || ++since < kLazy) return;
        since = 0;
        std::size_t k = 0;
        first_end = narrowest = std::numeric_limits<double>::infinity();
        for (std::size_t j = 0; j < ts.size(); ++j) {
            if (hi[j] < t) continue;
            ts[k] = ts[j], hi[k] = hi[j], a[k] = a[j], peak[k] = peak[j], r[k] = r[j], g[k] = g[j], b[k] = b[j];
            first_end = std::min(first_end, hi[k]);
            narrowest = std::min(narrowest, width(a[k]));
            ++k;
        }
        for (auto* v : {&ts, &hi}) v->resize(k);
        for (auto* v : {&a, &peak, &r, &g, &b}) v->resize(k);
    }
};

// e[j] = peak_j exp(-(a_j (t - ts_j))^2), in float (fast_expf: 3e-7; t - ts in double, so a
// Gaussian's argument keeps float's precision wherever it lies on the ray), and their sum.
AIRLIGHT_SIMD_CLONES double window_densities(const double* ts, const float* a, const float* peak, std::size_t n,
                                             double t, float* e) {
    float sum = 0.0f;
    for (std::size_t j = 0; j < n; ++j) {
        const float u = a[j] * float(t - ts[j]);
        e[j] = peak[j] * fast_expf_le88(-u * u);
        sum += e[j];
    }
    return double(sum);
}

// The albedo-weighted sum of the kernel's densities.
RGB weighted(const Window& w) {
    RGB out(0.0);
    for (std::size_t j = 0; j < w.size(); ++j) out += double(w.e[j]) * RGB(w.r[j], w.g[j], w.b[j]);
    return out;
}

double sum(const RGB& x) { return x.x + x.y + x.z; }

// Sorts _line_ by lo: by float keys packed with the indices (sorting the 64-byte records took a
// fifth of a march through the 3000-Gaussian cloud), then an insertion pass on the exact lo
// (keys that round alike).
void sort_by_start(std::vector<RayGaussian>& line) {
    thread_local std::vector<std::uint64_t> keys;
    thread_local std::vector<RayGaussian> sorted;
    const std::size_t n = line.size();
    if (n < 2) return;
    keys.resize(n);
    for (std::size_t k = 0; k < n; ++k) {
        // (float bits ordered as unsigned integers: negatives' bits flipped, positives' sign set)
        std::uint32_t u;
        const float f = float(line[k].lo);
        std::memcpy(&u, &f, sizeof u);
        u ^= (u >> 31) != 0 ? 0xFFFFFFFFu : 0x80000000u;
        keys[k] = (std::uint64_t(u) << 32) | k;
    }
    // (LSD radix sort on the key's four bytes: std::sort's comparisons of random keys were
    // mispredicted branches, 9 us for 339 Gaussians)
    thread_local std::vector<std::uint64_t> other;
    other.resize(n);
    for (int shift = 32; shift < 64; shift += 8) {
        std::uint32_t count[257] = {};
        for (std::size_t k = 0; k < n; ++k) ++count[((keys[k] >> shift) & 0xFF) + 1];
        if (count[((keys[0] >> shift) & 0xFF) + 1] == n) continue;  // (one digit for all)
        for (int b = 0; b < 256; ++b) count[b + 1] += count[b];
        for (std::size_t k = 0; k < n; ++k) other[count[(keys[k] >> shift) & 0xFF]++] = keys[k];
        keys.swap(other);
    }
    sorted.resize(n);
    for (std::size_t k = 0; k < n; ++k) sorted[k] = line[keys[k] & 0xFFFFFFFFu];
    for (std::size_t k = 1; k < n; ++k)
        for (std::size_t j = k; j > 0 && sorted[j].lo < sorted[j - 1].lo; --j) std::swap(sorted[j], sorted[j - 1]);
    line.swap(sorted);
}

// The light of a march: a point light at s (a spot with GaussianMarch::cone) and its map, or a
// sun lamp (sun non-null: its footprint, towards it along sun->u) with its map and the uniform
// fog's layer top.
struct MarchLight {
    Vec3 s{0.0};
    const LightDepthMap* map = nullptr;
    const SunFootprint* sun = nullptr;
    const SunDepthMap* sun_map = nullptr;
    double fog_top = std::numeric_limits<double>::infinity();
};

RGB march_rgb(const GaussianMedium& medium, const MarchLight& light, const PhaseFunction& phase, const Vec3& v,
              const Vec3& r, double Dvp, GaussianMarch& march) {
    march.steps = 0, march.work = 0, march.stopped = false;
    const bool infinite = std::isinf(Dvp);
    const Vec3& s = light.s;
    const LightDepthMap* map = light.map;
    const SunFootprint* sun = light.sun;
    // A spot's profile edges, a sun's layer top and the ends of the sun's footprint (where the
    // Gaussians above shade the ray): steps end there.
    std::vector<double> cuts;
    std::pair<double, double> shaded(1.0, 0.0);  // the ray within the sun's footprint
    if (sun) {
        if (!std::isinf(light.fog_top) && r.z != 0.0) cuts.push_back((light.fog_top - v.z) / r.z);
        shaded = sun->clip(v, r);
        if (shaded.first <= shaded.second)
            for (double x : {shaded.first, shaded.second})
                if (x > 0.0 && x < Dvp) cuts.push_back(x);
        auto outside = [&](double x) { return !(x > 0.0 && x < Dvp); };
        cuts.erase(std::remove_if(cuts.begin(), cuts.end(), outside), cuts.end());
        std::sort(cuts.begin(), cuts.end());
    }
    // (A sun's steps within its footprint: the shade's scale, the map's cells or the Gaussians' widths.)
    const double shade_step =
        !sun ? 0.0 : light.sun_map ? std::max(light.sun_map->cell_step(r), march.step_widths * sun->narrowest)
                                   : march.step_widths * sun->narrowest;
    if (march.cone) {
        const SpotCone& cone = *march.cone;
        for (double c : {cone.cos_half_angle, cone.cos_half_angle + cone.smooth})
            if (c < 1.0)
                for (double x : ray_cone_crossings(v, r, s, cone.axis, c, 0.0, Dvp)) cuts.push_back(x);
        if (cone.has_spread()) {
            const double x = ray_axis_approach(v, r, s, cone.axis, 0.0, Dvp);
            if (x > 0.0) cuts.push_back(x);
        }
        std::sort(cuts.begin(), cuts.end());
    }
    // A ray that starts outside a spot's cone and never crosses it is dark: no need to gather
    // its Gaussians (most refined rays of a frame miss most spots). (Not with an IES profile,
    // which may be 0 between lit directions away from any cut.)
    // The cosine to a spot's axis just past t (t may be a cut), seen from the light.
    auto cone_cos = [&](double t) {
        const Vec3 sx = v + (t + 1e-7 * std::max(1.0, t)) * r - s;
        const double len = glm::length(sx);
        return len > 0.0 ? glm::dot(march.cone->axis, sx) / len : 1.0;
    };
    const bool cone_bounds_light = march.cone && !march.cone->has_profile();
    if (cone_bounds_light && cuts.empty() && !(spot_profile(*march.cone, cone_cos(0.0)) > 0.0)) return RGB(0.0);
    thread_local std::vector<RayGaussian> line;  // (kept between marches: its growth took ~1 us of each)
    line.clear();
    double last_end = 0.0;
    const GaussianWindow window_of(march.window);
    (march.gather ? *march.gather : medium).for_each_near(v, r, Dvp, [&](std::size_t g) {
        const double a = medium.scale(g), c = medium.amplitude(g);
        const Vec3 rel = medium.centre(g) - v;
        const Vec3 cr = glm::cross(rel, r);
        const double ah2 = a * a * glm::dot(cr, cr);
        const double window = window_of(c * kSqrtPi / a);
        if (ah2 >= window) return;
        const double ts = glm::dot(rel, r), reach = std::sqrt(window - ah2) / a;
        if (ts + reach <= 0.0) return;
        const RGB albedo = march.albedo ? RGB(march.albedo[3 * g], march.albedo[3 * g + 1], march.albedo[3 * g + 2])
                                        : RGB(1.0);
        line.push_back({ts, a, c * std::exp(-ah2), ts - reach, ts + reach, albedo});
        last_end = std::max(last_end, ts + reach);
    });
    sort_by_start(line);
    const double beta0 = medium.beta0();
    const RGB sigma0 = beta0 * march.medium_albedo;
    const bool isotropic = phase.kind == PhaseKind::Isotropic;
    // The angular scale the steps resolve (a tenth of the light's distance times it): the phase
    // lobe's, and inside a spot's blend zone that zone's width (its ends are cuts, below, so a
    // step lies in the zone or out of it; elsewhere the profile varies as cos theta).
    const double lobe = std::min(1.0, phase.lobe_width());
    double blend_lobe = lobe;
    if (march.cone && march.cone->smooth > 0.0) {
        const SpotCone& cone = *march.cone;
        blend_lobe = std::min(lobe, std::acos(cone.cos_half_angle) -
                                        std::acos(std::min(1.0, cone.cos_half_angle + cone.smooth)));
    }
    auto in_blend = [&](double t) {
        if (!(blend_lobe < lobe)) return false;
        const double c = cone_cos(t);
        return c > march.cone->cos_half_angle && c < march.cone->cos_half_angle + march.cone->smooth;
    };
    const Vec3 vs = s - v;
    const double t_s = sun ? 0.0 : glm::dot(vs, r);  // the light's closest approach
    // (A sun's phase angle is the same all along the ray.)
    const double p_sun = sun ? (isotropic ? kInv4Pi : phase.eval(glm::dot(sun->u, r))) : 0.0;
    const double p_max = sun ? p_sun
                             : (isotropic ? kInv4Pi : std::max(phase.eval(1.0), phase.eval(-1.0))) *
                                   (march.cone ? march.emission_max : 1.0);
    std::size_t cut = 0;
    auto next_cut = [&](double t) {
        while (cut < cuts.size() && cuts[cut] <= t) ++cut;
        return cut < cuts.size() ? cuts[cut] : std::numeric_limits<double>::infinity();
    };
    // The lit spans: steps end at their ends, and a step is lit where its midpoint is.
    const RaySpans all{nullptr, 0};
    const RaySpans& lit = march.lit ? *march.lit : all;
    int span = 0;  // the first span that does not end before t
    auto next_end = [&](double t) {
        while (span < lit.count && lit.spans[span].second <= t) ++span;
        if (span == lit.count) return std::numeric_limits<double>::infinity();
        return lit.spans[span].first > t ? lit.spans[span].first : lit.spans[span].second;
    };
    auto is_lit = [&](double t) {
        return !march.lit || (span < lit.count && lit.spans[span].first <= t && t < lit.spans[span].second);
    };

    // One albedo for every Gaussian (or none given): the densities' sum alone.
    bool one_albedo = true;
    for (const RayGaussian& g : line) one_albedo = one_albedo && g.albedo == line.front().albedo;
    const RGB albedo_g = line.empty() ? RGB(1.0) : line.front().albedo;
    RGB albedo_max = march.medium_albedo;
    for (const RayGaussian& g : line) albedo_max = glm::max(albedo_max, g.albedo);
    const double albedo_sum = sum(albedo_max);
    Window active;
    std::size_t next = 0;
    // The step inside the Gaussians: step_widths of the narrowest one the step from t holds (those
    // of the window, and those that start within the step). (The narrowest on the whole ray took
    // 1.11x the steps on the 3000-Gaussian cloud, whose widths vary 3x.)
    auto inside_step = [&](double t) {
        double h = march.step_widths * active.narrowest;
        for (std::size_t k = next; k < line.size() && line[k].lo <= t + h; ++k)
            h = std::min(h, march.step_widths * width(line[k].a));
        return h;
    };
    auto density = [&](double t) {
        march.work += long(active.size());
        active.e.resize(active.size());
        const double beta_g = window_densities(active.ts.data(), active.a.data(), active.peak.data(), active.size(), t,
                                               active.e.data());
        return Density{beta0 + beta_g, sigma0 + (one_albedo ? beta_g * albedo_g : weighted(active))};
    };
    // A sun's: the uniform fog's layer depth and the Gaussians' on the half-line towards it.
    auto sun_depth = [&](const Vec3& x) {
        march.work += GaussianMarch::kPointWork;
        const double layer = sunlight_layer_depth(beta0, light.fog_top, sun->u.z, x.z);
        if (std::isinf(layer)) return layer;
        if (light.sun_map) return layer + (*light.sun_map)(x);
        double T = layer;
        medium.for_each_near(x, sun->u, std::numeric_limits<double>::infinity(), [&](std::size_t g) {
            T += medium.gaussian_optical_depth(g, x, sun->u, 0.0, std::numeric_limits<double>::infinity());
            march.work += GaussianMarch::kTermWork;
        });
        return T;
    };
    auto light_depth = [&](const Vec3& x, double d) {
        march.work += GaussianMarch::kPointWork;
        if (map) return beta0 * d + (*map)(x);
        const Vec3 u = (x - s) / d;
        double T = beta0 * d;
        medium.for_each_near(s, u, d, [&](std::size_t g) {
            T += medium.gaussian_optical_depth(g, s, u, 0.0, d);
            march.work += GaussianMarch::kTermWork;
        });
        return T;
    };
    const bool layer_top = sun && !std::isinf(light.fog_top);
    auto in_scattered = [&](double t, const Density& dens, double Tv) {
        if (dens.beta == 0.0) return RGB(0.0);
        if (sun) {  // (the uniform fog scatters sunlight inside its layer only: sunlight_layer.h)
            const Vec3 x = v + t * r;
            const RGB sigma_s = layer_top && x.z > light.fog_top ? dens.sigma_s - sigma0 : dens.sigma_s;
            if (sigma_s == RGB(0.0) || p_sun == 0.0) return RGB(0.0);
            return sigma_s * (p_sun * std::exp(-sun_depth(x) - Tv));
        }
        const Vec3 sx = v + t * r - s;
        const double d2 = glm::dot(sx, sx);
        if (!(d2 > 0.0)) return RGB(0.0);
        const double d = std::sqrt(d2);
        double p = isotropic ? kInv4Pi : phase.eval(-glm::dot(sx, r) / d);
        if (march.cone) p *= spot_profile(*march.cone, glm::dot(march.cone->axis, sx) / d);
        if (p == 0.0) return RGB(0.0);
        return dens.sigma_s * (p / d2 * std::exp(-light_depth(v + t * r, d) - Tv));
    };

    double t = 0.0, Tv = 0.0;
    RGB total(0.0);
    while (next < line.size() && line[next].lo <= 0.0) active.push(line[next++]);
    Density dens_a = density(0.0);
    RGB f_a = in_scattered(0.0, dens_a, 0.0);
    const double end = infinite ? std::numeric_limits<double>::max() : Dvp;
    while (t < end) {
        const double boundary = next_end(t);
        if (march.lit && std::isinf(boundary)) break;  // (no lit span left)
        const double d = sun ? 0.0 : glm::length(v + t * r - s);
        // (A sun's step outside the Gaussians is free but for the shade of those above.)
        const bool in_fog = !active.empty() || (!sun && next < line.size() && line[next].lo < t + 0.1 * d);
        // In a spot's blend zone the profile falls to 0 as the square of the distance to its
        // outer end, where Simpson and the trapezoids part by half the step whatever its length:
        // the steps there are a twentieth of the zone's angle and take no halving test of the
        // in-scattering (the view depth's still holds).
        const bool blend = in_blend(t);
        double h = sun ? std::numeric_limits<double>::infinity()
                       : 0.1 * std::max(d, 1e-9 * std::max(1.0, glm::length(vs))) * (blend ? 0.5 * blend_lobe : lobe);
        if (sun && t >= shaded.first && t < shaded.second) h = std::min(h, shade_step);
        const double fog_step = in_fog || next < line.size() ? inside_step(t) : 0.0;
        if (in_fog) h = std::min(h, fog_step);
        if (next < line.size() && line[next].lo > t) h = std::min(h, std::max(line[next].lo - t, fog_step));
        // (Thick fog: a step's depth stays below 1/2.)
        h = std::min({h, end - t, 0.5 / dens_a.beta, boundary - t, next_cut(t) - t});
        Density dens_m, dens_b;
        RGB f_m, f_b, step;
        double T_b;
        bool lit_step;
        for (;;) {
            while (next < line.size() && line[next].lo <= t + h) active.push(line[next++]);
            dens_m = density(t + 0.5 * h), dens_b = density(t + h);
            const double T_m = Tv + h / 24.0 * (5.0 * dens_a.beta + 8.0 * dens_m.beta - dens_b.beta);
            T_b = Tv + h / 6.0 * (dens_a.beta + 4.0 * dens_m.beta + dens_b.beta);
            lit_step = is_lit(t + 0.5 * h);
            f_m = in_scattered(t + 0.5 * h, dens_m, T_m), f_b = in_scattered(t + h, dens_b, T_b);
            step = h / 6.0 * (f_a + 4.0 * f_m + f_b);
            // Simpson against the trapezoids of the same points: a step where they part by more
            // than step_tol (a shadow's edge, a thick Gaussian's rim), or whose view depth parts by
            // more than kDepthTol, is halved.
            const RGB trapezoids = h / 4.0 * (f_a + 2.0 * f_m + f_b);
            const double depth_gap = std::abs(T_b - Tv - h / 4.0 * (dens_a.beta + 2.0 * dens_m.beta + dens_b.beta));
            const double gap = lit_step && !blend ? sum(glm::abs(step - trapezoids)) : 0.0;
            if ((gap <= march.step_tol * std::max(sum(step), march.tail_tol * sum(total)) && depth_gap <= kDepthTol) ||
                h <= kMinStep * std::max(1.0, t))
                break;
            h *= 0.5;
        }
        if (lit_step) total += step;
        t += h, Tv = T_b, dens_a = dens_b, f_a = f_b;
        ++march.steps;
        if (march.work > march.work_limit) {
            march.stopped = true;
            break;
        }
        if (Tv > kOpaque) break;
        // Opaque enough: past t, int beta e^{-(T - Tv)} dt <= 1, so the rest is below
        // albedo p_max e^{-Tv} / d_min^2 (d_min: the light's least distance to the rest of the ray).
        const double d_min2 =
            sun ? 1.0 : t >= t_s ? glm::dot(v + t * r - s, v + t * r - s) : glm::dot(vs, vs) - t_s * t_s;
        if (d_min2 > 0.0 && albedo_sum * p_max * std::exp(-Tv) / d_min2 <= march.tail_tol * sum(total)) break;
        // Past a spot's last cone crossing and outside the cone: nothing more is lit.
        if (cone_bounds_light && std::isinf(next_cut(t)) && !(spot_profile(*march.cone, cone_cos(t)) > 0.0)) break;
        active.drop(t);
        if (sun && active.empty() && next == line.size() && t > last_end) {
            // Only the uniform fog is left: nothing above the layer going up; on an infinite ray
            // its rest is below p_sun e^{-Tv} (the integral of beta0 e^{-beta0 t} is 1).
            if (beta0 == 0.0 || (layer_top && r.z >= 0.0 && v.z + t * r.z >= light.fog_top)) break;
            if (infinite && p_max * std::exp(-Tv) <= march.tail_tol * sum(total) / 3.0) break;
        } else if (!sun && infinite && active.empty() && next == line.size() && t > std::max(t_s, last_end)) {
            // Only the uniform fog is left: its rest is below beta0 p_max e^{-Tv} / (t - t_s).
            if (beta0 == 0.0 || beta0 * p_max * std::exp(-Tv) / (t - t_s) <= march.tail_tol * sum(total) / 3.0) break;
        }
    }
    return total;
}

}  // namespace

RGB gaussian_march_airlight_rgb(const GaussianMedium& medium, const Vec3& s, const PhaseFunction& phase,
                                const Vec3& origin, const Vec3& r, double Dvp, const LightDepthMap* map,
                                GaussianMarch& march) {
    MarchLight light;
    light.s = s, light.map = map;
    return march_rgb(medium, light, phase, origin, r, Dvp, march);
}

RGB gaussian_march_sun_rgb(const GaussianMedium& medium, const Vec3& u, double fog_top, const PhaseFunction& phase,
                           const Vec3& origin, const Vec3& r, double Dvp, const SunDepthMap* map,
                           GaussianMarch& march) {
    std::optional<SunFootprint> own;
    if (!map) own.emplace(medium, u);
    MarchLight light;
    light.sun = map ? &map->footprint() : &*own;
    light.sun_map = map, light.fog_top = fog_top;
    march.cone = nullptr;
    return march_rgb(medium, light, phase, origin, r, Dvp, march);
}

void GaussianMarch::set_accuracy(double target) {
    // Measured on the 3000- and 34-Gaussian bench scenes at 1 % (bench_gaussian_accuracy.py):
    // step 1 width, tolerance 1e-2 left the bakes' errors as they were at 0.35 and 1e-3 (the
    // marches are far inside the target; the light-depth maps and the interpolation between
    // refined rays take most of it) at 40-60 % of the march's work. Below 0.5 % the finer
    // steps stay: wider ones there were halved so often that they cost more.
    // The window of e^-10 instead of e^-20 (for Gaussians of optical depth up to 0.22 through
    // the centre; denser ones keep the window that leaves out 1e-5 of it) holds ~half the
    // Gaussians: 3000 x 1 at 1 %, 1080p, 27.5k -> 15.2k densities a march, 84 -> 66 us (the
    // bakes' errors as they were to 1e-5).
    if (target >= 5e-3) step_widths = 1.0, step_tol = 1e-2, window = 10.0;
}

double gaussian_march_airlight(const GaussianMedium& medium, const Vec3& s, const PhaseFunction& phase,
                               const Vec3& origin, const Vec3& r, double Dvp, const LightDepthMap* map,
                               GaussianMarch& march) {
    GaussianMarch unit = march;
    unit.albedo = nullptr, unit.medium_albedo = RGB(1.0);
    const double La = gaussian_march_airlight_rgb(medium, s, phase, origin, r, Dvp, map, unit).x;
    march.steps = unit.steps, march.work = unit.work, march.stopped = unit.stopped;
    return La;
}

double gaussian_march_sun(const GaussianMedium& medium, const Vec3& u, double fog_top, const PhaseFunction& phase,
                          const Vec3& origin, const Vec3& r, double Dvp, const SunDepthMap* map, GaussianMarch& march) {
    GaussianMarch unit = march;
    unit.albedo = nullptr, unit.medium_albedo = RGB(1.0);
    const double La = gaussian_march_sun_rgb(medium, u, fog_top, phase, origin, r, Dvp, map, unit).x;
    march.steps = unit.steps, march.work = unit.work, march.stopped = unit.stopped;
    return La;
}

}  // namespace airlight
