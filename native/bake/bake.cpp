// bake.cpp: per-pixel airlight and transmittance for one camera view.
//
// Pass 1 casts one ray through every pixel centre (depth). Pass 2 evaluates the fog
// model per pixel; pixels at depth discontinuities (silhouettes, creases) are supersampled
// through Cycles' Blackman-Harris film filter so fog edges match the render's
// antialiased edges. Both passes run over row bands on worker threads; the calling
// thread only waits and reports progress.
#include "bake/bake.h"
#include "core/constants.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <exception>
#include <limits>
#include <map>
#include <numeric>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <string>
#include <thread>
#include <tuple>

#ifdef __linux__
#include <sys/mman.h>
#endif

#include "bake/surface_pass.h"
#include "homogeneous/biri06.h"
#include "image/camera.h"
#include "core/quadrature.h"
#include "image/raycast.h"
#include "gaussian/airlight.h"
#include "gaussian/medium.h"
#include "gaussian/splat.h"
#include "homogeneous/sun05.h"
#include "homogeneous/sun05_batch.h"
#include "homogeneous/spot_light.h"
#include "homogeneous/sunlight_layer.h"
#include "bake/hoffman02_bake.h"
#include "homogeneous/pegoraro10.h"
#include "homogeneous/sun05_inline.h"

namespace airlight {

namespace {

constexpr int kBandRows = 16;
constexpr int kMaxResolution = 32768;
// A fog-object Gaussian's largest optical depth through its centre for the Fogshop models'
// float kernels (FogModel).
constexpr double kMaxCentreDepth = 1e4;
// Relative tolerance of the quadrature model inside a bake (reference, not speed).
constexpr double kQuadratureRelTol = 1e-8;
// Relative tolerance of the spot-light quadrature (every model: spots have no closed form);
// far below the float passes' and Cycles' noise, and ~3x cheaper than 1e-8.
constexpr double kSpotRelTol = 1e-5;
// Pegoraro 2010 (point lights for 'pegoraro10'; spots see FogModel): Henyey-Greenstein is
// truncated where its Legendre tail is below kPegoraroPhaseTol of the lobe everywhere
// (airlight error ~1e-7, bench_pegoraro.py), at most kPegoraroMaxOrder (|g| <= ~0.78; model
// pegoraro10 refuses wider lobes). Spots of other models use it up to kPegoraroSpotMaxOrder.
constexpr double kPegoraroPhaseTol = 1e-6;
constexpr int kPegoraroMaxOrder = 96;
constexpr int kPegoraroSpotMaxOrder = 8;
// Share of the progress bar given to pass 1 (ray casting).
constexpr double kRaycastProgressShare = 0.3;

// Throw std::invalid_argument with _msg_ unless _ok_.
void require(bool ok, const std::string& msg) {
    if (!ok) throw std::invalid_argument(msg);
}

bool finite3(const glm::dvec3& v) {
    return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}

// Sun lamps and the fog top (sunlight_layer.h).
void validate_suns(const SceneDescription& scene) {
    for (size_t i = 0; i < scene.sun_lights.size(); ++i) {
        const SunLight& sun = scene.sun_lights[i];
        const std::string name = "sun light " + std::to_string(i);
        require(finite3(sun.direction) && glm::length(sun.direction) > 0.0,
                name + ": direction must be finite and nonzero");
        require(finite3(sun.E) && sun.E.x >= 0.0 && sun.E.y >= 0.0 && sun.E.z >= 0.0,
                name + ": irradiance must be finite and >= 0");
    }
    require(!std::isnan(scene.fog_top) && scene.fog_top != -std::numeric_limits<double>::infinity(),
            "fog_top must be a finite height or +inf (no top), got " + std::to_string(scene.fog_top));
}

// Validate the scene and settings once, before any work starts.
void validate(const SceneDescription& scene, const BakeSettings& settings) {
    const Camera& cam = scene.camera;
    require(cam.width > 0 && cam.height > 0,
            "resolution must be positive, got " + std::to_string(cam.width) + " x " +
                std::to_string(cam.height));
    require(cam.width <= kMaxResolution && cam.height <= kMaxResolution,
            "resolution must be at most " + std::to_string(kMaxResolution) + " per axis, got " +
                std::to_string(cam.width) + " x " + std::to_string(cam.height));
    const HomogeneousMedium& medium = scene.medium;
    require(std::isfinite(medium.sigma_t) && medium.sigma_t >= 0.0,
            "sigma_t (density) must be finite and >= 0, got " + std::to_string(medium.sigma_t));
    require(finite3(medium.albedo) && medium.albedo.x >= 0.0 && medium.albedo.y >= 0.0 &&
                medium.albedo.z >= 0.0,
            "albedo must be finite and >= 0");
    require(std::abs(medium.phase.g) < 1.0,
            "phase: g (anisotropy) must be finite with |g| < 1, got " + std::to_string(medium.phase.g));
    // The Sun 2005 models integrate the isotropic phase only: refuse rather than bake wrong fog.
    require(phase_is_isotropic(medium.phase) ||
                (settings.model != ModelId::Sun05Table && settings.model != ModelId::Sun05Exact),
            std::string("model '") + (settings.model == ModelId::Sun05Table ? "sun05" : "sun05_exact") +
                "' supports only the isotropic phase, got '" + phase_name(medium.phase.kind) +
                "' (g = " + std::to_string(medium.phase.g) + "); use 'biri06' or 'quadrature'");
    require(settings.model == ModelId::Sun05Table || settings.model == ModelId::Sun05Exact ||
                settings.model == ModelId::Quadrature || settings.model == ModelId::Biri06 ||
                settings.model == ModelId::Baseline || settings.model == ModelId::Pegoraro10 ||
                settings.model == ModelId::Hoffman02,
            "the bake does not dispatch this model (see models())");
    validate_suns(scene);
    require(std::isfinite(medium.rayleigh_550) && medium.rayleigh_550 >= 0.0,
            "rayleigh_density must be finite and >= 0, got " + std::to_string(medium.rayleigh_550));
    if (settings.model == ModelId::Hoffman02) {
        // Hoffman & Preetham model daylight: sun lamps in a Rayleigh + Mie (HG) medium.
        require(scene.point_lights.empty() && scene.spot_lights.empty(),
                "model 'hoffman02' (Hoffman & Preetham 2002) scatters sun lamps only: exclude the point "
                "and spot lights from the fog or use another model");
        require(scene.gaussians.empty(), "model 'hoffman02' does not take fog objects (Gaussians)");
        require(!settings.surface, "model 'hoffman02' has no surface-shading pass (per-channel extinction): "
                                   "bake it with surface=False");
        require(medium.phase.kind == PhaseKind::Isotropic || medium.phase.kind == PhaseKind::HenyeyGreenstein,
                "model 'hoffman02': the Mie part is Henyey-Greenstein (the Rayleigh part is built in); got phase '" +
                    std::string(phase_name(medium.phase.kind)) + "'");
    }
    // Pegoraro 2010 truncates Henyey-Greenstein; lobes that order kPegoraroMaxOrder cannot
    // represent (|g| >~ 0.79) would bake wrong (even negative) fog: refuse them.
    require(settings.model != ModelId::Pegoraro10 || medium.phase.kind != PhaseKind::HenyeyGreenstein ||
                pegoraro_hg_order(medium.phase.g, kPegoraroPhaseTol, kPegoraroMaxOrder) >= 0,
            "model 'pegoraro10': Henyey-Greenstein g = " + std::to_string(medium.phase.g) +
                " needs a Legendre order above " + std::to_string(kPegoraroMaxOrder) +
                " (|g| <= 0.78 works); use 'biri06' or 'quadrature'");
    // Gaussian fog (Fogshop): the Fogshop approximation (sun05, sun05_exact: F table or exact
    // F for the background term; biri06, pegoraro10: their model for it, any phase) or its
    // quadrature reference; point, spot and sun lamps (gaussian_splat.h GaussianSplatLights).
    const Gaussians& gauss = scene.gaussians;
    if (!gauss.empty()) {
        const size_t n = gauss.scales.size();
        require(gauss.amplitudes.size() == n && gauss.centres.size() == 3 * n,
                "gaussians: centres (" + std::to_string(gauss.centres.size()) + " values), scales (" +
                    std::to_string(n) + ") and amplitudes (" + std::to_string(gauss.amplitudes.size()) +
                    ") must describe the same number of Gaussians (3 centre values each)");
        for (double x : gauss.centres) require(std::isfinite(x), "gaussians: centres must be finite");
        for (size_t i = 0; i < n; ++i) {
            require(std::isfinite(gauss.scales[i]) && gauss.scales[i] > 0.0,
                    "gaussians: scale " + std::to_string(i) + " must be finite and > 0, got " +
                        std::to_string(gauss.scales[i]));
            require(std::isfinite(gauss.amplitudes[i]) && gauss.amplitudes[i] >= 0.0,
                    "gaussians: amplitude " + std::to_string(i) + " must be finite and >= 0, got " +
                        std::to_string(gauss.amplitudes[i]));
        }
        require(gauss.albedo.empty() || gauss.albedo.size() == 3 * n,
                "gaussians: albedo must hold 3 values per Gaussian (" + std::to_string(3 * n) + "), got " +
                    std::to_string(gauss.albedo.size()));
        for (double x : gauss.albedo)
            require(std::isfinite(x) && x >= 0.0, "gaussians: albedo must be finite and >= 0");
        validate_noise({gauss.noise_amplitude, gauss.noise_scale, gauss.noise_offset});
        require(gauss.albedo.empty() || settings.model != ModelId::Quadrature,
                "per-Gaussian colours are not supported by the 'quadrature' reference model; use 'sun05' or "
                "'sun05_exact'");
        require(gauss.noise_amplitude == 0.0 || settings.model != ModelId::Quadrature,
                "fog noise is not supported by the 'quadrature' reference model; set the noise amplitude to 0 or "
                "use 'sun05'");
        require(settings.model == ModelId::Sun05Table || settings.model == ModelId::Sun05Exact ||
                    settings.model == ModelId::Biri06 || settings.model == ModelId::Pegoraro10 ||
                    settings.model == ModelId::Quadrature || settings.model == ModelId::Baseline,
                "Gaussian fog supports the models 'sun05', 'sun05_exact', 'biri06', 'pegoraro10' (Fogshop "
                "approximation), 'quadrature' (reference) and 'baseline'");
    }
    for (size_t i = 0; i < scene.point_lights.size(); ++i) {
        const PointLight& light = scene.point_lights[i];
        require(finite3(light.position), "light " + std::to_string(i) + ": position must be finite");
        require(finite3(light.I0) && light.I0.x >= 0.0 && light.I0.y >= 0.0 && light.I0.z >= 0.0,
                "light " + std::to_string(i) + ": intensity must be finite and >= 0");
    }
    for (size_t i = 0; i < scene.spot_lights.size(); ++i) {
        const SpotLight& spot = scene.spot_lights[i];
        const std::string name = "spot light " + std::to_string(i);
        require(finite3(spot.position), name + ": position must be finite");
        require(finite3(spot.axis) && glm::length(spot.axis) > 0.0, name + ": axis must be finite and nonzero");
        require(finite3(spot.I0) && spot.I0.x >= 0.0 && spot.I0.y >= 0.0 && spot.I0.z >= 0.0,
                name + ": intensity must be finite and >= 0");
        require(std::isfinite(spot.spot_size) && spot.spot_size > 0.0 && spot.spot_size <= kPi + 1e-9,
                name + ": spot_size must be in (0, pi] rad, got " + std::to_string(spot.spot_size));
        require(std::isfinite(spot.spot_blend) && spot.spot_blend >= 0.0 && spot.spot_blend <= 1.0,
                name + ": spot_blend must be in [0, 1], got " + std::to_string(spot.spot_blend));
    }
    const TriangleMesh& mesh = scene.geometry;
    require(mesh.vertices.size() % 3 == 0, "vertices must hold 3 floats per vertex");
    require(mesh.triangles.size() % 3 == 0, "triangles must hold 3 indices per triangle");
    for (float x : mesh.vertices) require(std::isfinite(x), "vertices must be finite (found NaN or inf)");
    const size_t n_vertices = mesh.vertices.size() / 3;
    for (uint32_t index : mesh.triangles)
        require(index < n_vertices, "triangle index " + std::to_string(index) +
                                        " out of range (vertex count " + std::to_string(n_vertices) + ")");
    require(settings.threads >= 0, "threads must be >= 0 (0: all hardware threads)");
    require(settings.aa_samples >= 1 && settings.aa_samples <= 64, "aa_samples must be in [1, 64]");
    require(std::isfinite(settings.filter_width) && settings.filter_width >= 0.0,
            "filter_width must be finite and >= 0");
    require(settings.edge_cluster_tol >= 0.0 && !std::isnan(settings.edge_cluster_tol),
            "edge_cluster_tol must be >= 0 (0: every sub-sample evaluated), got " +
                std::to_string(settings.edge_cluster_tol));
    require(settings.table_nu >= 2 && settings.table_nT >= 2 && settings.table_nu <= 16384 &&
                settings.table_nT <= 16384,
            "table size must be in [2, 16384] per axis");
    // The camera matrices are checked by CameraRays (finite, invertible).
}

// Blackman-Harris window as Cycles' film uses it: support [-w, w] for filter width _w_
// (Cycles doubles the user width for this filter before tabulating it).
double blackman_harris(double x, double w) {
    double a = 2.0 * kPi * (x / (2.0 * w) + 0.5);
    return 0.35875 - 0.48829 * std::cos(a) + 0.14128 * std::cos(2.0 * a) - 0.01168 * std::cos(3.0 * a);
}

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

// Error estimate for a cluster of edge sub-samples (edge_sample_clusters) evaluated at one
// representative ray (mean origin and direction, mean depth D, mean near distance t0),
// relative to the representative's airlight La (per channel), in O(samples + lights):
//  - Each point light l: unattenuated, its in-scattering along [t0, D] is W_l g with
//    g = int_t0^D dt / d(t)^2 = (atan((D - t*) / h) - atan((t0 - t*) / h)) / h (h the
//    ray's closest approach, t* its abscissa). The samples' mean g differs from the
//    representative's by second order: ~g E|delta|^2 / (h - L)^2 in the direction (g ~ 1/h;
//    delta the samples' lateral offsets from the representative at t*, L the largest: the
//    light's image within ~L / h of the pixel) plus Var(D_k) / d_end^3 in the depth (a
//    surface next to the light). Times 2 (a weight non-uniform along the ray, ~1/d^2 against g ~ 1/h)
//    and the light's share of La: at most 1, and at most W_l g / La with W_l <= sigma_s
//    I_l P exp(-sigma_bg (|s - o| - t0)) / (4 pi) (homogeneous fog).
//  - Hits: the attenuation's and the density's share of the integrand's variation over
//    the depths, mean_k int_D^D_k (f(t) - f(D)) dt ~ 1/2 Var(D_k) f'(D), |f_l'| <= f_l
//    (sigma (2 sigma + G / d) + rho') (the phase's slope G, the Gaussians' density rho and
//    its slope near the surface points); suns under a fog top (f drops to 0 there) take
//    the first-order bound mean |D_k - D| f. (Spot lights: no clusters, see bake().)
// The transmittance is rescaled per sample by the background (exact), leaving the
// Gaussians' part: ~Var (rho' / 2 + rho^2 / 2 + rho sigma_bg).
class EdgeClusterBounds {
  public:
    EdgeClusterBounds(const SceneDescription& scene, const GaussianMedium* gaussians)
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

    // Relative error estimates (airlight: the largest over the channels of _La_, the
    // representative's; transmittance) of the cluster of the _n_ samples rays[idx[q]],
    // depth[idx[q]] (all hits or all misses) represented by the ray _rep_ with near distance
    // _t0_ (0 without a near clip) and depth _D_.
    void errors(const Ray* rays, const float* depth, const int* idx, int n, const Ray& rep, double t0, double D,
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

  private:
    struct Light {
        Vec3 s;
        RGB w;  // largest albedo x I0
    };
    struct Sun {
        Vec3 w;
        RGB w_E;  // largest albedo x E
    };

    // 4 pi p over the scattering angles along [t0, D] towards _s_: 1 (isotropic) or the
    // largest of p at the closest approach and the ends.
    double phase_bound(const Ray& r, double t0, double D, const Vec3& s) const {
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

    double sigma_bg_;
    PhaseFunction phase_;
    const GaussianMedium* gaussian_;
    bool isotropic_ = true, sunlight_layer_ = false;
    double phase_grad_ = 0.0;
    std::vector<Light> lights_;
    std::vector<Sun> suns_;
};

#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
// AVX-512 / AVX2 / baseline versions of the per-row loops, picked at load time.
#define AIRLIGHT_ROW_CLONES __attribute__((target_clones("arch=x86-64-v4", "arch=x86-64-v3", "default")))
#else
#define AIRLIGHT_ROW_CLONES
#endif

// Directions of the _n_ rays D = Dj + (i + 0.5) Dx for Embree, scaled to unit length
// along the view axis _forward_ (D / (D . forward)): the ray parameter t is then the
// view-axis depth, so the clip range is [clip_start, clip_end] for every ray and the
// edge key 1 / depth is 1 / t; _len_ = |D / (D . forward)| = 1 / cos_view converts t
// to distance. Float, no square root in double, one division.
AIRLIGHT_ROW_CLONES
void row_directions_cast(const Vec3& Dj, const Vec3& Dx, const Vec3& forward, int n, float* __restrict fx,
                         float* __restrict fy, float* __restrict fz, float* __restrict len) {
    // All float (Embree's precision; GCC vectorises loops of one element width best).
    const float jx = float(Dj.x), jy = float(Dj.y), jz = float(Dj.z);
    const float ix = float(Dx.x), iy = float(Dx.y), iz = float(Dx.z);
    const float vx = float(forward.x), vy = float(forward.y), vz = float(forward.z);
    for (int i = 0; i < n; ++i) {
        const float px = float(i) + 0.5f;
        const float X = jx + px * ix, Y = jy + px * iy, Z = jz + px * iz;
        const float rc = 1.0f / (X * vx + Y * vy + Z * vz);
        const float x = X * rc, y = Y * rc, z = Z * rc;
        fx[i] = x;
        fy[i] = y;
        fz[i] = z;
        len[i] = std::sqrt(x * x + y * y + z * z);
    }
}

// The same rays' unit directions in double (the fog's cos(gamma) near a light needs it)
// and, in float, the near-plane distance t_near = near |D| / (D . forward).
AIRLIGHT_ROW_CLONES
void row_directions_fog(const Vec3& Dj, const Vec3& Dx, const Vec3& forward, float near, int n,
                        double* __restrict dx, double* __restrict dy, double* __restrict dz,
                        float* __restrict t_near) {
    for (int i = 0; i < n; ++i) {
        const double px = i + 0.5;
        const double X = Dj.x + px * Dx.x, Y = Dj.y + px * Dx.y, Z = Dj.z + px * Dx.z;
        const double inv = 1.0 / std::sqrt(X * X + Y * Y + Z * Z);
        dx[i] = X * inv;
        dy[i] = Y * inv;
        dz[i] = Z * inv;
    }
    if (near == 0.0f) {
        for (int i = 0; i < n; ++i) t_near[i] = 0.0f;
        return;
    }
    const float jx = float(Dj.x), jy = float(Dj.y), jz = float(Dj.z);
    const float ix = float(Dx.x), iy = float(Dx.y), iz = float(Dx.z);
    const float vx = float(forward.x), vy = float(forward.y), vz = float(forward.z);
    for (int i = 0; i < n; ++i) {
        const float px = float(i) + 0.5f;
        const float X = jx + px * ix, Y = jy + px * iy, Z = jz + px * iz;
        t_near[i] = near * (std::sqrt(X * X + Y * Y + Z * Z) / (X * vx + Y * vy + Z * vz));
    }
}

// Kink bits (see bake(): bit l set if the key's second difference along line l exceeds
// 1 % or the line mixes hits and misses) of pixels 1 .. n - 2 of the row _mid_ between
// rows _up_ and _down_. Keys are >= 0, 0 where the ray missed: with mn, mx the least and
// greatest key on a line, "mixes" is mn = 0 < mx, and all-miss lines (mx = 0) pass the
// 1 % test exactly. NaN counts as a kink.
AIRLIGHT_ROW_CLONES
void kink_interior(const float* __restrict up, const float* __restrict mid, const float* __restrict down, int n,
                   unsigned char* __restrict out) {
    auto kink = [](float kp, float ka, float kb) -> int {
        const float mn = std::min(kp, std::min(ka, kb)), mx = std::max(kp, std::max(ka, kb));
        const float d = std::abs(ka + kb - 2.0f * kp);
        return int(!(d <= 0.01f * mn)) | (int(mn == 0.0f) & int(mx > 0.0f));
    };
    for (int i = 1; i < n - 1; ++i) {
        const float kp = mid[i];
        out[i] = (unsigned char)(kink(kp, mid[i - 1], mid[i + 1]) | kink(kp, up[i], down[i]) << 1 |
                                 kink(kp, up[i - 1], down[i + 1]) << 2 | kink(kp, down[i - 1], up[i + 1]) << 3);
    }
}

// cos(gamma) of unit directions (dx, dy, dz)[k] with the unit vector _sv_ to a light.
AIRLIGHT_ROW_CLONES
void cos_to_light(const double* __restrict dx, const double* __restrict dy, const double* __restrict dz,
                  const Vec3& sv, int n, double* __restrict cos_gamma) {
    for (int k = 0; k < n; ++k) cos_gamma[k] = dx[k] * sv.x + dy[k] * sv.y + dz[k] * sv.z;
}

// sum_c[k] += w_c value[k] for the three colour channels.
AIRLIGHT_ROW_CLONES
void accumulate_rgb(const float* __restrict value, float wr, float wg, float wb, int n, float* __restrict r,
                    float* __restrict g, float* __restrict b) {
    for (int k = 0; k < n; ++k) {
        r[k] += wr * value[k];
        g[k] += wg * value[k];
        b[k] += wb * value[k];
    }
}

// Per-light data, precomputed once per bake.
struct LightData {
    Vec3 s;          // position
    RGB weight;      // albedo * I0
    double Dsv = 0;  // distance to the camera position (perspective rays share the origin)
};

// Evaluates transmittance and airlight of one view ray for the chosen model.
class FogModel {
  public:
    FogModel(const SceneDescription& scene, const BakeSettings& settings, bool shared_origin,
             const Vec3& origin)
        : model_(settings.model),
          sigma_t_(scene.medium.sigma_t),
          phase_(scene.medium.phase),
          isotropic_(phase_is_isotropic(scene.medium.phase)),
          shared_origin_(shared_origin),
          origin_(origin) {
        if (model_ == ModelId::Sun05Table)
            table_ = shared_special_F_table(settings.table_nu, settings.table_nT, settings.table_interp);
        if (model_ == ModelId::Biri06) biri_table_ = shared_biri06_table(phase_, settings.table_nu, settings.table_nT);
        if (model_ == ModelId::Pegoraro10 || (model_ != ModelId::Quadrature && !scene.spot_lights.empty())) {
            pegoraro_phase_ = pegoraro_phase_auto(phase_, kPegoraroPhaseTol, kPegoraroMaxOrder);
            // Spots: the closed form for model pegoraro10, and for the other non-quadrature models
            // while the phase polynomial is of order <= kPegoraroSpotMaxOrder: there it costs about
            // what the 1e-5 quadrature does (bench_pegoraro.py, isotropic); at HG order 30 it was
            // ~5x slower, so those spots keep the quadrature.
            spot_closed_form_ = model_ == ModelId::Pegoraro10 ||
                                (model_ != ModelId::Quadrature && pegoraro_phase_.order() <= kPegoraroSpotMaxOrder);
        }
        for (const PointLight& light : scene.point_lights) {
            if (!keeps_light(scene, light)) continue;
            RGB weight = scene.medium.albedo * light.I0;
            lights_.push_back({light.position, weight, glm::length(light.position - origin)});
        }
        for (const SpotLight& spot : scene.spot_lights) {
            RGB weight = scene.medium.albedo * spot.I0;
            if (weight.x == 0.0 && weight.y == 0.0 && weight.z == 0.0) continue;
            spots_.push_back({make_spot_cone(spot.axis, spot.spot_size, spot.spot_blend), spot.position, weight});
        }
        for (const SunLight& sun : scene.sun_lights) {
            const RGB weight = scene.medium.albedo * sun.E * sigma_t_;  // sigma_s E
            if (weight.x == 0.0 && weight.y == 0.0 && weight.z == 0.0) continue;
            const Vec3 w = glm::normalize(sun.direction);
            suns_.push_back({w, -w.z, weight});
        }
        fog_top_ = scene.fog_top;
        if (!scene.gaussians.empty()) {
            const Gaussians& g = scene.gaussians;
            gaussian_ = std::make_unique<GaussianMedium>(g.centres, g.scales, g.amplitudes, sigma_t_);
            for (const LightData& light : lights_) gaussian_lights_.push_back(light.s);
            // Per-light I0 (the Gaussians' weights carry their own albedo), per-Gaussian albedo.
            medium_albedo_ = scene.medium.albedo;
            for (const PointLight& light : scene.point_lights)
                if (keeps_light(scene, light)) gaussian_I0_.push_back(light.I0);
            gaussian_albedo_ = g.albedo;
            if (gaussian_albedo_.empty())
                for (size_t i = 0; i < g.scales.size(); ++i)
                    for (int c = 0; c < 3; ++c) gaussian_albedo_.push_back(scene.medium.albedo[c]);
            const GaussianNoise noise{g.noise_amplitude, g.noise_scale, g.noise_offset};
            if (noise.on() && !shared_origin_)
                throw std::invalid_argument("fog noise needs a perspective camera (orthographic cameras bake "
                                            "Gaussian fog without noise only)");
            // Spots and suns with Gaussians (after the point lights in gaussian_lights_ / gaussian_I0_).
            n_gaussian_points_ = gaussian_lights_.size();
            for (const SpotLight& spot : scene.spot_lights) {
                if (spot.I0.x == 0.0 && spot.I0.y == 0.0 && spot.I0.z == 0.0) continue;
                gaussian_lights_.push_back(spot.position);
                gaussian_I0_.push_back(spot.I0);
                gaussian_spots_.push_back({make_spot_cone(spot.axis, spot.spot_size, spot.spot_blend), spot.position,
                                      spot.I0});
            }
            for (const SunLight& sun : scene.sun_lights) {
                if (sun.E.x == 0.0 && sun.E.y == 0.0 && sun.E.z == 0.0) continue;
                const Vec3 w = glm::normalize(sun.direction);
                gaussian_suns_.push_back({w, -w.z, sun.E});
            }
            const bool fogshop = model_ == ModelId::Sun05Table || model_ == ModelId::Sun05Exact ||
                                 model_ == ModelId::Biri06 || model_ == ModelId::Pegoraro10;
            const bool extended = !gaussian_spots_.empty() || !gaussian_suns_.empty() || !isotropic_ ||
                                  model_ == ModelId::Biri06 || model_ == ModelId::Pegoraro10;
            if (fogshop && extended && !shared_origin_)
                throw std::invalid_argument("fog objects with spot or sun lamps, an anisotropic phase or model "
                                            "'biri06' / 'pegoraro10' need a perspective camera (or model "
                                            "'quadrature')");
            // Fogshop's per-(light, Gaussian) precomputation, once for the shared viewpoint,
            // and the tiled splatting (gaussian_splat.h) that evaluates it.
            if (fogshop && shared_origin_) {
                // The splat's float kernels take a Gaussian's optical depth on a segment as
                // (c sqrt(pi) / 2a) times a difference of erfc values, which cancels (both near
                // 1) on a segment that starts inside the Gaussian's core (the eye or a light
                // within ~1 / a of its centre) and is short against 1 / a: that loses c
                // sqrt(pi) / 2a times float's 1.2e-7. Such a Gaussian whose optical depth
                // through its centre, c sqrt(pi) / a, exceeds kMaxCentreDepth (1e4: <= ~1e-3
                // of transmittance; measured 2.9e-3 at 1.8e4, garbage and an infinite airlight
                // at 1.8e8) is refused with what to do. Elsewhere its segments' erfc values are
                // not both near 1 (a dense blob seen from outside: no loss).
                for (size_t i = 0; i < g.scales.size(); ++i) {
                    const double a = g.scales[i];
                    const double depth = g.amplitudes[i] * std::sqrt(kPi) / a;
                    if (!(depth > kMaxCentreDepth)) continue;
                    const Vec3 b(g.centres[3 * i], g.centres[3 * i + 1], g.centres[3 * i + 2]);
                    bool inside = a * glm::length(b - origin_) < 2.0;
                    for (const Vec3& s : gaussian_lights_) inside = inside || a * glm::length(b - s) < 2.0;
                    if (inside) {
                        std::ostringstream os;
                        os << "fog objects: Gaussian " << i << " (amplitude " << g.amplitudes[i] << " /m, scale " << a
                           << " /m) holds the camera or a light in its core and has an optical depth of " << depth
                           << " through its centre, beyond the " << kMaxCentreDepth
                           << " the Fogshop models compute accurately there: give fog this wide and dense to "
                              "the scene's uniform Density, or use model 'quadrature'";
                        throw std::invalid_argument(os.str());
                    }
                }
                GaussianSplatLights extra;
                if (extended) {
                    extra.phase = phase_;
                    const size_t L = gaussian_lights_.size();
                    extra.spot.assign(L, 0);
                    extra.cone.assign(L, SpotCone{});
                    extra.custom_background.assign(L, 0);
                    for (size_t l = 0; l < L; ++l) {
                        const bool is_spot = l >= n_gaussian_points_;
                        extra.spot[l] = is_spot;
                        if (is_spot) extra.cone[l] = gaussian_spots_[l - n_gaussian_points_].cone;
                        // The sun05 term of the splat is isotropic: other models and phases
                        // (and spots) use the bake's own model for the background.
                        extra.custom_background[l] = is_spot || !isotropic_ || model_ == ModelId::Biri06 ||
                                                     model_ == ModelId::Pegoraro10;
                    }
                    for (const GaussianSunData& sun : gaussian_suns_) {
                        extra.sun_w.push_back(sun.w);
                        extra.sun_E.push_back(sun.E);
                    }
                    extra.fog_top = fog_top_;
                    extra.background = [this](size_t l, const Vec3& d, double t0, double Dvp) {
                        return gaussian_background(l, d, t0, Dvp);
                    };
                }
                splat_ = std::make_unique<GaussianSplat>(*gaussian_, origin_, gaussian_lights_, gaussian_I0_, scene.medium.albedo,
                                                    g.albedo, table_.get(), noise, std::max(0, settings.threads),
                                                    extended ? &extra : nullptr);
            }
        }
    }

    // Background (beta0) term of the splat's light l (GaussianSplatLights::background): point
    // lights n_gaussian_points_ first, then spots, then suns; per unit albedo I0 (suns: albedo E)
    // along origin_ + t d over [t0, Dvp], attenuated from t0, with the bake's model.
    double gaussian_background(size_t l, const Vec3& d, double t0, double Dvp) const {
        if (sigma_t_ == 0.0 || !(Dvp > t0)) return 0.0;
        const size_t L = gaussian_lights_.size();
        const Vec3 start = t0 > 0.0 ? origin_ + t0 * d : origin_;
        const double seg = Dvp - t0;  // inf stays inf
        if (l < n_gaussian_points_) {
            const Vec3 sv = gaussian_lights_[l] - start;
            const double Dsv = glm::length(sv);
            const double cos_gamma = Dsv > 0.0 ? std::clamp(glm::dot(d, sv) / Dsv, -1.0, 1.0) : 1.0;
            return airlight(Dsv, cos_gamma, seg);
        }
        if (l < L) {
            const GaussianSpotData& spot = gaussian_spots_[l - n_gaussian_points_];
            return spot_closed_form_
                       ? pegoraro10_spot_airlight(pegoraro_phase_, spot.cone, spot.s, sigma_t_, start, d, seg)
                       : spot_airlight_quadrature(spot.cone, spot.s, phase_, sigma_t_, start, d, seg, kSpotRelTol);
        }
        const GaussianSunData& sun = gaussian_suns_[l - L];
        return sigma_t_ * phase_.eval(-glm::dot(sun.w, d)) *
               sunlight_layer_factor(sigma_t_, fog_top_, sun.mu_s, origin_.z, d.z, t0, Dvp);
    }

    // Transmittance of the ray _r_ from t0 to _depth_ (inf: none), as eval_many computes it.
    double transmittance(const Ray& r, double t0, double depth) const {
        if (!gaussian_) return std::exp(-sigma_t_ * (depth - t0));
        const double seg = std::max(0.0, depth - t0);
        return std::exp(-gaussian_->optical_depth_ray(t0 > 0.0 ? r.o + t0 * r.d : r.o, r.d, seg));
    }

    // Gaussian fog through the tiled splat (perspective, Fogshop models): null otherwise.
    GaussianSplat* splat() const { return splat_.get(); }
    // The Gaussian medium (null for homogeneous fog).
    const GaussianMedium* gaussian_medium() const { return gaussian_.get(); }

    // True if _eval_soa_ applies (perspective camera, table model, fog): then a near
    // distance t0 costs nothing extra (one evaluation of the segment, sun05_batch.h).
    bool soa() const { return shared_origin_ && model_ == ModelId::Sun05Table && sigma_t_ > 0.0 && !gaussian_; }

    // The transmittance part of _eval_soa_ alone (soa() only), the same values.
    void transmittance_soa(const float* Dvp, const float* t0, int n, float* Tr) const {
        constexpr int kChunk = 256;
        float seg[kChunk];
        for (int k0 = 0; k0 < n; k0 += kChunk) {
            const int m = std::min(kChunk, n - k0);
            if (t0) {
                for (int k = 0; k < m; ++k) seg[k] = Dvp[k0 + k] - t0[k0 + k];
                transmittance_batch(float(sigma_t_), seg, m, Tr + k0);
            } else {
                transmittance_batch(float(sigma_t_), Dvp + k0, m, Tr + k0);
            }
        }
    }
    bool has_spots() const { return !spots_.empty(); }

    // Hot path (soa() only): _n_ rays from the shared origin with unit directions (dx,
    // dy, dz)[k] (structure of arrays, so the per-light dot products and accumulations
    // vectorise), segment [t0[k], Dvp[k]] (t0 null: 0). Writes Tr[k] = exp(-sigma_t (Dvp -
    // t0)) and the airlight summed over the lights to rgb[3 k .. 3 k + 2].
    void eval_soa(const double* dx, const double* dy, const double* dz, const float* Dvp, const float* t0, int n,
                  float* Tr, float* rgb) const {
        constexpr int kChunk = 256;
        double cos_gamma[kChunk];
        float sum_r[kChunk], sum_g[kChunk], sum_b[kChunk], value[kChunk], seg[kChunk];
        const float* data = table_->data().data();
        const int nu = table_->nu(), nT = table_->nT();
        for (int k0 = 0; k0 < n; k0 += kChunk) {
            const int m = std::min(kChunk, n - k0);
            const float* near = t0 ? t0 + k0 : nullptr;
            if (near) {
                for (int k = 0; k < m; ++k) seg[k] = Dvp[k0 + k] - near[k];
                transmittance_batch(float(sigma_t_), seg, m, Tr + k0);
            } else {
                transmittance_batch(float(sigma_t_), Dvp + k0, m, Tr + k0);
            }
            for (int k = 0; k < m; ++k) sum_r[k] = sum_g[k] = sum_b[k] = 0.0f;
            for (const LightData& light : lights_) {
                const Vec3 sv = (light.s - origin_) * (light.Dsv > 0.0 ? 1.0 / light.Dsv : 0.0);
                const bool at_light = !(light.Dsv > 0.0);
                if (at_light) std::fill(cos_gamma, cos_gamma + m, 1.0);
                else cos_to_light(dx + k0, dy + k0, dz + k0, sv, m, cos_gamma);
                sun05_airlight_table_batch(data, nu, nT, sigma_t_, light.Dsv, cos_gamma, Dvp + k0, m, value, near,
                                           table_->interp());
                accumulate_rgb(value, float(light.weight.x), float(light.weight.y), float(light.weight.z), m, sum_r,
                               sum_g, sum_b);
            }
            float* out = rgb + 3 * size_t(k0);
            for (int k = 0; k < m; ++k) {
                out[3 * k] = sum_r[k];
                out[3 * k + 1] = sum_g[k];
                out[3 * k + 2] = sum_b[k];
            }
            if (!spots_.empty()) {
                for (int k = 0; k < m; ++k) {
                    const Vec3 d(dx[k0 + k], dy[k0 + k], dz[k0 + k]);
                    const double t_near = near ? double(near[k]) : 0.0;
                    const RGB La = spot_airlight(origin_, d, t_near, double(Dvp[k0 + k]));
                    for (int c = 0; c < 3; ++c) out[3 * k + c] = float(double(out[3 * k + c]) + La[c]);
                }
            }
            if (!suns_.empty()) {
                for (int k = 0; k < m; ++k) {
                    const Vec3 d(dx[k0 + k], dy[k0 + k], dz[k0 + k]);
                    const RGB La = sun_airlight(origin_, d, near ? double(near[k]) : 0.0, double(Dvp[k0 + k]));
                    for (int c = 0; c < 3; ++c) out[3 * k + c] = float(double(out[3 * k + c]) + La[c]);
                }
            }
        }
    }

    // The same for _n_ rays at once, light by light: the iterations of the inner loop
    // are independent, so the CPU overlaps the long dependency chains of the model.
    // _t0_ (near distances, may be null): the fog of the segment [t0, Dvp] with
    // attenuation from the near point, as Cycles integrates it. soa() folds t0 into the
    // table evaluation; the other models move the viewer to the near point o + t0 d (same
    // direction, so the same phase angles along the ray; Dsv and gamma from there), one
    // evaluation per ray and light with no difference to cancel.
    void eval_many(const Ray* rays, const float* Dvp, const float* t0, int n, double* Tr, RGB* La) const {
        if (soa()) {
            constexpr int kChunk = 256;
            double dx[kChunk], dy[kChunk], dz[kChunk];
            float Tr_f[kChunk], rgb[3 * kChunk];
            for (int k0 = 0; k0 < n; k0 += kChunk) {
                const int m = std::min(kChunk, n - k0);
                for (int k = 0; k < m; ++k) {
                    dx[k] = rays[k0 + k].d.x;
                    dy[k] = rays[k0 + k].d.y;
                    dz[k] = rays[k0 + k].d.z;
                }
                eval_soa(dx, dy, dz, Dvp + k0, t0 ? t0 + k0 : nullptr, m, Tr_f, rgb);
                for (int k = 0; k < m; ++k) {
                    Tr[k0 + k] = Tr_f[k];
                    La[k0 + k] = RGB(rgb[3 * k], rgb[3 * k + 1], rgb[3 * k + 2]);
                }
            }
            return;
        }
        if (gaussian_) {
            eval_gaussians(rays, Dvp, t0, n, Tr, La);
            return;
        }
        for (int k = 0; k < n; ++k) {
            const double near = t0 ? double(t0[k]) : 0.0;
            const double seg = std::max(0.0, double(Dvp[k]) - near);  // inf stays inf
            La[k] = RGB(0.0);
            Tr[k] = sigma_t_ == 0.0 ? 1.0 : std::isinf(seg) ? 0.0 : std::exp(-sigma_t_ * seg);
        }
        if (sigma_t_ == 0.0) return;
        for (const LightData& light : lights_) {
            for (int k = 0; k < n; ++k) {
                const double near = t0 ? double(t0[k]) : 0.0;
                const Vec3 o = near > 0.0 ? rays[k].o + near * rays[k].d : rays[k].o;
                const Vec3 sv = light.s - o;
                const double Dsv = shared_origin_ && !(near > 0.0) ? light.Dsv : glm::length(sv);
                const double cos_gamma = Dsv > 0.0 ? std::clamp(glm::dot(rays[k].d, sv) / Dsv, -1.0, 1.0) : 1.0;
                const double seg = std::max(0.0, double(Dvp[k]) - near);
                La[k] += light.weight * airlight(Dsv, cos_gamma, seg);
            }
        }
        if (!spots_.empty())
            for (int k = 0; k < n; ++k) La[k] += spot_airlight(rays[k].o, rays[k].d, t0 ? double(t0[k]) : 0.0, double(Dvp[k]));
        if (!suns_.empty())
            for (int k = 0; k < n; ++k) La[k] += sun_airlight(rays[k].o, rays[k].d, t0 ? double(t0[k]) : 0.0, double(Dvp[k]));
    }

    // Airlight of all sun lamps along o + t d over [t_near, Dvp] (inf: none): sigma_s p E G
    // with the closed form G of sunlight_layer.h (its quadrature for the quadrature model). The
    // phase angle is the same all along the ray.
    RGB sun_airlight(const Vec3& o, const Vec3& d, double t_near, double Dvp) const {
        RGB La(0.0);
        if (sigma_t_ == 0.0 || !(Dvp > t_near)) return La;
        for (const SunData& sun : suns_) {
            const double p = phase_.eval(-glm::dot(sun.w, d));
            const double G = model_ == ModelId::Quadrature
                                 ? sunlight_layer_factor_quadrature(sigma_t_, fog_top_, sun.mu_s, o.z, d.z, t_near, Dvp,
                                                               kQuadratureRelTol)
                                 : sunlight_layer_factor(sigma_t_, fog_top_, sun.mu_s, o.z, d.z, t_near, Dvp);
            La += sun.weight * (p * G);
        }
        return La;
    }

    // Airlight of all spot lights along the ray o + t d over [t_near, Dvp] (Dvp from o; inf:
    // none), attenuated from the near point (the viewer moved there, as eval_many does for
    // the other models). Pegoraro 2010 closed form with the medium's phase (pegoraro10.h), or
    // quadrature (spot_light.h): model 'quadrature', and phases above order 8 unless 'pegoraro10'.
    RGB spot_airlight(const Vec3& o, const Vec3& d, double t_near, double Dvp) const {
        RGB La(0.0);
        if (sigma_t_ == 0.0) return La;
        const double seg = std::max(0.0, Dvp - t_near);  // inf stays inf
        if (!(seg > 0.0)) return La;
        const Vec3 start = t_near > 0.0 ? o + t_near * d : o;
        for (const SpotData& spot : spots_)
            La += spot.weight *
                  (!spot_closed_form_
                       ? spot_airlight_quadrature(spot.cone, spot.s, phase_, sigma_t_, start, d, seg, kSpotRelTol)
                       : pegoraro10_spot_airlight(pegoraro_phase_, spot.cone, spot.s, sigma_t_, start, d, seg));
        return La;
    }

  private:
    // A light scatters if albedo * I0 is nonzero, or (Gaussian fog with its own colours) if
    // I0 is: a black background medium can carry coloured fog objects.
    static bool keeps_light(const SceneDescription& scene, const PointLight& light) {
        const RGB weight = scene.medium.albedo * light.I0;
        if (weight.x != 0.0 || weight.y != 0.0 || weight.z != 0.0) return true;
        return !scene.gaussians.albedo.empty() && (light.I0.x != 0.0 || light.I0.y != 0.0 || light.I0.z != 0.0);
    }

    // Gaussian fog: Tr = exp(-(sigma_t (t1 - t0) + sum_i T_i)) with the culled optical depth,
    // La = sum_l I0_l [albedo L_0,l + sum_i albedo_i L_i,l] (Fogshop) over the same segment
    // [t0, t1], attenuated from the near point o + t0 d: exp(T(eye, near point)) (La_eye(t1) -
    // La_eye(t0)), exact for the integral (the eye-side attenuation of every point beyond t0
    // carries the factor exp(-T(eye, near point))). Perspective cameras: the centre samples
    // come from the tiled splat and the rays here (edge samples) from its per-ray twin, both
    // float (gaussian_splat.h). Orthographic rays (own origins) set the exact double Fogshop up per
    // ray; the quadrature model integrates from the near point directly.
    void eval_gaussians(const Ray* rays, const float* Dvp, const float* t0, int n, double* Tr, RGB* La) const {
        if (splat_) {  // perspective: rays from the shared eye (gaussian_splat.h)
            thread_local std::vector<Vec3> dirs;
            dirs.resize(size_t(n));
            for (int k = 0; k < n; ++k) dirs[k] = rays[k].d;
            splat_->eval_rays(dirs.data(), Dvp, t0, n, Tr, La);
            return;
        }
        const size_t L = lights_.size();
        for (int k = 0; k < n; ++k) {
            const Ray& ray = rays[k];
            const double near = t0 ? double(t0[k]) : 0.0;
            const double seg = std::max(0.0, double(Dvp[k]) - near);  // inf stays inf
            const Vec3 o = near > 0.0 ? ray.o + near * ray.d : ray.o;
            Tr[k] = std::exp(-gaussian_->optical_depth_ray(o, ray.d, seg));
            La[k] = RGB(0.0);
            if (!(seg > 0.0) || (L == 0 && gaussian_spots_.empty() && gaussian_suns_.empty())) continue;
            if (model_ == ModelId::Quadrature) {
                for (size_t l = 0; l < L; ++l) {
                    GaussianRefLight ref;  // a point light
                    ref.s = lights_[l].s;
                    La[k] += lights_[l].weight *
                             (isotropic_ ? gaussian_airlight_quadrature(*gaussian_, lights_[l].s, o, ray.d, seg, kQuadratureRelTol)
                                         : gaussian_airlight_quadrature(*gaussian_, ref, phase_, o, ray.d, seg, kQuadratureRelTol));
                }
                for (const GaussianSpotData& spot : gaussian_spots_) {
                    GaussianRefLight ref;
                    ref.kind = GaussianRefLight::Kind::Spot;
                    ref.s = spot.s;
                    ref.cone = spot.cone;
                    La[k] += medium_albedo_ * spot.I0 *
                             gaussian_airlight_quadrature(*gaussian_, ref, phase_, o, ray.d, seg, kQuadratureRelTol);
                }
                for (const GaussianSunData& sun : gaussian_suns_) {
                    GaussianRefLight ref;
                    ref.kind = GaussianRefLight::Kind::Sun;
                    ref.w = sun.w;
                    ref.fog_top = fog_top_;
                    La[k] += medium_albedo_ * sun.E *
                             gaussian_airlight_quadrature(*gaussian_, ref, phase_, o, ray.d, seg, kQuadratureRelTol);
                }
                continue;
            }
            const FogshopAirlight local(*gaussian_, o, gaussian_lights_, table_.get(), 1);
            La[k] = local.eval_rgb(ray.d, seg, gaussian_albedo_.data(), gaussian_I0_.data(), medium_albedo_);
        }
    }

    double airlight(double Dsv, double cos_gamma, double Dvp) const {
        switch (model_) {
            case ModelId::Sun05Table:  // inlined fast path, same as sun05_airlight(..., Table)
                return sun05_airlight_table(table_->data().data(), table_->nu(), table_->nT(), sigma_t_,
                                            Dsv, cos_gamma, Dvp, 0.0, table_->interp());
            case ModelId::Sun05Exact:
                return sun05_airlight(sigma_t_, Dsv, cos_gamma, Dvp, nullptr, FEval::Exact);
            case ModelId::Quadrature:  // the phase-aware reference unless isotropic
                return isotropic_ ? sun05_airlight_quadrature(sigma_t_, Dsv, cos_gamma, Dvp, kQuadratureRelTol)
                                  : phase_airlight_quadrature(phase_, sigma_t_, Dsv, cos_gamma, Dvp,
                                                              kQuadratureRelTol);
            case ModelId::Biri06:  // Gamma table of the medium's phase (exact where it would cancel)
                return biri06_airlight(phase_, sigma_t_, Dsv, cos_gamma, Dvp, biri_table_.get(), GammaEval::Table);
            case ModelId::Pegoraro10:  // closed form with the phase as a Legendre polynomial
                return pegoraro10_airlight(pegoraro_phase_, sigma_t_, Dsv, cos_gamma, Dvp);
            default:  // rejected by validate()
                break;
        }
        return 0.0;
    }

    ModelId model_;
    double sigma_t_;
    PhaseFunction phase_;
    bool isotropic_;
    bool shared_origin_;
    Vec3 origin_;
    std::shared_ptr<const SpecialFTable> table_;
    std::shared_ptr<const Biri06Table> biri_table_;
    PegoraroPhase pegoraro_phase_;  // spots (all models but quadrature) and model pegoraro10
    bool spot_closed_form_ = false;  // spots by pegoraro10_spot_airlight (else quadrature)
    std::vector<LightData> lights_;
    struct SpotData {
        SpotCone cone;
        Vec3 s;
        RGB weight;  // albedo * I0
    };
    std::vector<SpotData> spots_;
    struct SunData {
        Vec3 w;       // unit propagation direction
        double mu_s;  // -w.z: the cosine of the sun's path through the layer to the vertical
        RGB weight;   // albedo * sigma_t * E
    };
    std::vector<SunData> suns_;
    double fog_top_ = std::numeric_limits<double>::infinity();
    // Gaussian fog (null without): the medium (beta0 = sigma_t), the lights' positions in
    // lights_' order, and Fogshop set up at the shared viewpoint.
    std::unique_ptr<GaussianMedium> gaussian_;
    std::vector<Vec3> gaussian_lights_;
    std::vector<RGB> gaussian_I0_;         // I0 of the lights in lights_' order
    std::vector<double> gaussian_albedo_;  // 3 per Gaussian (the medium's if none given)
    RGB medium_albedo_{1.0};
    size_t n_gaussian_points_ = 0;  // point lights at the front of gaussian_lights_ (spots follow)
    struct GaussianSpotData {
        SpotCone cone;
        Vec3 s;
        RGB I0;
    };
    struct GaussianSunData {
        Vec3 w;       // unit propagation direction
        double mu_s;  // -w.z
        RGB E;
    };
    std::vector<GaussianSpotData> gaussian_spots_;
    std::vector<GaussianSunData> gaussian_suns_;
    std::unique_ptr<GaussianSplat> splat_;
};

// Scratch objects kept between bands and between bakes, one per concurrent user: fresh
// pages cost ~10-20 us per 4 KiB fault here (acquire_image_buffer), more than a band's work
// when its scratch runs to megabytes. A Lease takes one (or a new one) and gives it back.
template <typename T>
class ScratchPool {
  public:
    class Lease {
      public:
        explicit Lease(ScratchPool& pool) : pool_(pool) {
            {
                std::lock_guard<std::mutex> lock(pool_.mutex_);
                if (!pool_.free_.empty()) item_ = std::move(pool_.free_.back()), pool_.free_.pop_back();
            }
            if (!item_) item_ = std::make_unique<T>();
        }
        ~Lease() {
            std::lock_guard<std::mutex> lock(pool_.mutex_);
            pool_.free_.push_back(std::move(item_));
        }
        Lease(const Lease&) = delete;
        Lease& operator=(const Lease&) = delete;
        T& operator*() { return *item_; }

      private:
        ScratchPool& pool_;
        std::unique_ptr<T> item_;
    };

  private:
    std::mutex mutex_;
    std::vector<std::unique_ptr<T>> free_;
};

// Runs _work(i)_ for i in [0, n) on _n_threads_ threads that take items from an atomic
// counter: the calling thread is one of them (n_threads - 1 are started). Between its own
// items the calling thread calls _on_progress(done)_ once every n / 128 completions and at
// the end; if that throws (cancel) or any item throws, the others stop taking items and
// the exception propagates once they have finished.
// (The calling thread used to only wait on a condition variable, woken every n / 128
// items: on 2 cores that third thread preempted a worker at each wake-up, ~3 % of a
// Gaussian bake's samples in reschedule IPIs and futex calls.)
void run_parallel(int n, int n_threads, const std::function<void(int)>& work,
                  const std::function<void(int)>& on_progress) {
    if (n <= 0) return;
    std::atomic<int> next{0};
    std::atomic<bool> stop{false};
    std::atomic<int> done{0};
    std::mutex mutex;
    std::exception_ptr error;
    auto fail = [&](std::exception_ptr e) {
        std::lock_guard<std::mutex> lock(mutex);
        if (!error) error = e;
        stop = true;
    };
    // Takes items until none is left or stop; _after_ runs after each completed item.
    auto take = [&](auto&& after) {
        while (!stop.load(std::memory_order_relaxed)) {
            const int i = next.fetch_add(1);
            if (i >= n) return;
            work(i);
            done.fetch_add(1);
            after();
        }
    };
    auto worker = [&]() {
        try {
            take([] {});
        } catch (...) {
            fail(std::current_exception());
        }
    };
    std::vector<std::thread> threads;
    n_threads = std::max(1, std::min(n_threads, n));
    threads.reserve(size_t(n_threads - 1));
    auto join_all = [&]() {
        for (std::thread& t : threads)
            if (t.joinable()) t.join();
    };
    const int report_every = std::max(1, n / 128);
    int reported = 0;
    try {
        for (int t = 1; t < n_threads; ++t) threads.emplace_back(worker);
        try {
            take([&] {
                const int d = done.load(std::memory_order_relaxed);
                if (d - reported >= report_every) on_progress(reported = d);
            });
        } catch (...) {
            fail(std::current_exception());
        }
    } catch (...) {  // a thread could not be started
        stop = true;
        join_all();
        throw;
    }
    join_all();
    if (error) std::rethrow_exception(error);
    on_progress(n);
}

// Refuses the bake if _caster_ was handed rays Embree cannot take (CameraRays checks the
// camera's; this catches any other pass's): they were not traced, so the passes are wrong.
void check_traced(const RayCaster& caster) {
    if (const long n = caster.invalid_rays())
        throw std::invalid_argument("the camera cannot be baked: " + std::to_string(n) +
                                    " of its rays are not finite (check the camera's lens, sensor, shift and "
                                    "clip range, and the scene's scale)");
}

// Sizes _v_ to _n_ zeros (acquire_image_buffer).
void allocate_image(std::vector<float>& v, size_t n) { acquire_image_buffer(v, n, 0.0f); }

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point start) {
    return std::chrono::duration<double>(Clock::now() - start).count();
}

}  // namespace

// ModelId::Baseline: what Blender's Mist pass does, L = C_fog (1 - Tr), one fog colour for
// the whole image (baseline_fog.h). C_fog is the least-squares fit per channel to the
// physically based airlight of the same view (sun05's table model for isotropic fog,
// biri06 for any other phase; every light type included): the best a constant fog colour
// can do, so the baseline's reported error is a lower bound of any hand-picked colour's.
// 1 - Tr is 1 - e^{-sigma_t D} with D from the near plane to the first hit (1 for misses).
static BakeResult bake_baseline(const SceneDescription& scene, const BakeSettings& settings,
                                const ProgressFn& progress) {
    BakeSettings reference = settings;
    reference.model = phase_is_isotropic(scene.medium.phase) ? ModelId::Sun05Table : ModelId::Biri06;
    BakeResult result = bake(scene, reference, progress);
    const size_t n = size_t(result.width) * size_t(result.height);
    for (int c = 0; c < 3; ++c) {
        double num = 0.0, den = 0.0;
        for (size_t i = 0; i < n; ++i) {
            const double f = 1.0 - double(result.transmittance[3 * i + c]);
            num += double(result.airlight[3 * i + c]) * f;
            den += f * f;
        }
        const double C_fog = den > 0.0 ? num / den : 0.0;
        for (size_t i = 0; i < n; ++i)
            result.airlight[3 * i + c] = float(C_fog * (1.0 - double(result.transmittance[3 * i + c])));
    }
    return result;
}

// F tables are deterministic and costly to build: keep one per (nu, nT, interp) for the process.
std::shared_ptr<const SpecialFTable> shared_special_F_table(int nu, int nT, Interp interp) {
    static std::mutex mutex;
    static std::map<std::tuple<int, int, Interp>, std::shared_ptr<const SpecialFTable>> cache;
    std::lock_guard<std::mutex> lock(mutex);
    auto& slot = cache[{nu, nT, interp}];
    if (!slot) slot = std::make_shared<const SpecialFTable>(nu, nT, interp);
    return slot;
}

// The pool of recycled image buffers (acquire_image_buffer / recycle_image_buffer).
namespace {
constexpr size_t kImagePoolBytes = size_t(256) << 20;  // at most this much kept idle
constexpr size_t kImagePoolMinBytes = size_t(1) << 20;  // smaller buffers are not worth keeping
struct ImagePool {
    std::mutex mutex;
    std::vector<std::vector<float>> buffers;  // oldest first
    size_t bytes = 0;
};
ImagePool& image_pool() {
    static ImagePool* pool = new ImagePool;  // never destroyed: numpy may free arrays at exit
    return *pool;
}
}  // namespace

void acquire_image_buffer(std::vector<float>& v, size_t n, float value) {
    std::vector<float> taken;
    {
        ImagePool& pool = image_pool();
        std::lock_guard<std::mutex> lock(pool.mutex);
        // The smallest buffer that holds n floats, if it is not more than twice that.
        size_t best = pool.buffers.size();
        for (size_t i = 0; i < pool.buffers.size(); ++i) {
            const size_t c = pool.buffers[i].capacity();
            if (c >= n && c / 2 <= n && (best == pool.buffers.size() || c < pool.buffers[best].capacity())) best = i;
        }
        if (best < pool.buffers.size()) {
            taken = std::move(pool.buffers[best]);
            pool.buffers.erase(pool.buffers.begin() + std::ptrdiff_t(best));
            pool.bytes -= taken.capacity() * sizeof(float);
        }
    }
    if (taken.capacity() >= n) {
        v = std::move(taken);
        v.assign(n, value);  // within capacity: no reallocation, the pages are warm
        return;
    }
    v.clear();
    v.shrink_to_fit();
    v.reserve(n);  // allocates without touching the pages
#ifdef __linux__
    const uintptr_t huge = uintptr_t(2) << 20;
    const uintptr_t begin = (reinterpret_cast<uintptr_t>(v.data()) + huge - 1) & ~(huge - 1);
    const uintptr_t end = (reinterpret_cast<uintptr_t>(v.data() + n)) & ~(huge - 1);
    if (end > begin) madvise(reinterpret_cast<void*>(begin), end - begin, MADV_HUGEPAGE);
#endif
    v.resize(n, value);
}

void recycle_image_buffer(std::vector<float>&& buffer) {
    const size_t bytes = buffer.capacity() * sizeof(float);
    if (bytes < kImagePoolMinBytes || bytes > kImagePoolBytes) return;  // freed by the caller's vector
    std::vector<std::vector<float>> evicted;  // freed outside the lock
    ImagePool& pool = image_pool();
    std::lock_guard<std::mutex> lock(pool.mutex);
    while (!pool.buffers.empty() && pool.bytes + bytes > kImagePoolBytes) {
        pool.bytes -= pool.buffers.front().capacity() * sizeof(float);
        evicted.push_back(std::move(pool.buffers.front()));
        pool.buffers.erase(pool.buffers.begin());
    }
    pool.bytes += bytes;
    pool.buffers.push_back(std::move(buffer));
}

BakeResult bake(const SceneDescription& scene, const BakeSettings& settings, const ProgressFn& progress) {
    validate(scene, settings);
    if (settings.model == ModelId::Baseline) return bake_baseline(scene, settings, progress);
    if (settings.model == ModelId::Hoffman02) return bake_hoffman02(scene, settings, progress);
    const CameraRays rays(scene.camera);
    const int W = scene.camera.width, H = scene.camera.height;
    const size_t n_pixels = size_t(W) * size_t(H);
    int n_threads = settings.threads > 0 ? settings.threads : int(std::thread::hardware_concurrency());
    n_threads = std::max(1, n_threads);
    const int n_bands = (H + kBandRows - 1) / kBandRows;

    BakeResult result;
    result.width = W;
    result.height = H;
    allocate_image(result.depth, n_pixels);
    allocate_image(result.airlight, 3 * n_pixels);
    allocate_image(result.transmittance, 3 * n_pixels);

    // Report the progress of one pass, mapped to [begin, end] of the whole bake.
    auto reporter = [&](double begin, double end) {
        return [&progress, begin, end, n_bands](int done) {
            if (!progress) return;
            double fraction = done == n_bands ? end : begin + (end - begin) * done / n_bands;
            if (!progress(fraction)) throw Cancelled();
        };
    };
    if (progress && !progress(0.0)) throw Cancelled();

    // Pass 1: first-hit distance through every pixel centre, a row at a time. Also keep
    // a per-pixel key that is affine in pixel coordinates on any plane (1 / view-axis
    // depth for perspective, the distance itself for orthographic rays; 0 where the ray
    // misses), so the edge test below sees silhouettes and creases but not the slope of
    // an oblique plane.
    const RayCaster caster(scene.geometry);
    const Vec3 forward = rays.forward();
    const bool ortho = rays.orthographic();
    const bool clipped = rays.clipped();
    const Vec3 eye = rays.position();
    // Perspective cameras with Blender's matrices (affine rays) generate each row's
    // directions incrementally, D0 + px Dx + py Dy, normalised once, as arrays.
    const bool affine = rays.affine_perspective();
    Vec3 D0(0.0), Dx(0.0), Dy(0.0);
    if (affine) rays.affine_direction(D0, Dx, Dy);
    // Scratch image, kept per calling thread between bakes (fresh pages cost ~10 us per
    // 4 KiB page fault here); every pixel is written by pass 1 before it is read.
    // (The lambdas below run on worker threads: they use this reference, not the name of
    // the thread_local, which would be their own thread's copy.)
    thread_local std::vector<float> key_cache;
    if (key_cache.size() != n_pixels) allocate_image(key_cache, n_pixels);
    std::vector<float>& key = key_cache;

    // Unit directions of a row's centre rays (double for the fog's cos(gamma), float for
    // Embree), cos of the angle to the view axis and the clip range along each ray.
    struct RowRays {
        std::vector<double> dx, dy, dz;
        std::vector<float> fx, fy, fz, t_near, t_far;
        std::vector<float> len;  // pass 1: |D| over its view-axis component
        void resize(size_t n) {
            for (auto* v : {&dx, &dy, &dz}) v->resize(n);
            for (auto* v : {&fx, &fy, &fz, &len, &t_near, &t_far}) v->resize(n);
        }
    };
    const double clip_start = rays.clip_start(), clip_end = rays.clip_end();
    // Pass 1 wants float directions scaled to unit view-axis depth (row_directions_cast),
    // pass 2 unit directions in double and t_near (row_directions_fog): _cast_ selects.
    auto row_rays = [&](int j, RowRays& r, bool for_cast) {
        const Vec3 Dj = D0 + (j + 0.5) * Dy;
        if (for_cast)
            row_directions_cast(Dj, Dx, forward, W, r.fx.data(), r.fy.data(), r.fz.data(), r.len.data());
        else
            row_directions_fog(Dj, Dx, forward, float(clip_start), W, r.dx.data(), r.dy.data(), r.dz.data(),
                               r.t_near.data());
    };
    // First hits of _n_ camera rays inside the clip range, as Cycles sees them: nearer
    // surfaces clipped away, surfaces beyond t_far hidden (inf). _depth_ is measured from
    // the ray origin (the eye for perspective rays). Perspective rays share the origin and
    // go to Embree with [t_near, t_far]; orthographic ones are cast from the near plane.
    // _t0_ (size n) receives t_near. _scratch_ is reused between calls.
    struct CastScratch {
        RowRays soa;
        std::vector<Ray> moved;
    };
    auto cast = [&](const Ray* r, int n, float* depth, float* t0, CastScratch& scratch) {
        if (!ortho) {
            RowRays& s = scratch.soa;
            if (s.fx.size() < size_t(n)) s.resize(size_t(n));
            for (int k = 0; k < n; ++k) {
                double t_near = 0.0, t_far = std::numeric_limits<double>::infinity();
                if (clipped) rays.clip_range(r[k], t_near, t_far);
                s.fx[k] = float(r[k].d.x);
                s.fy[k] = float(r[k].d.y);
                s.fz[k] = float(r[k].d.z);
                s.t_near[k] = t0[k] = float(t_near);
                s.t_far[k] = float(t_far);
            }
            caster.first_hits(eye, s.fx.data(), s.fy.data(), s.fz.data(), s.t_near.data(), s.t_far.data(), n, depth);
            return;
        }
        if (!clipped) {
            for (int k = 0; k < n; ++k) t0[k] = 0.0f;
            caster.first_hits(r, n, depth);
            return;
        }
        std::vector<Ray>& moved = scratch.moved;
        moved.resize(size_t(n));
        std::vector<double> t_near(static_cast<size_t>(n)), t_far(static_cast<size_t>(n));
        for (int k = 0; k < n; ++k) {
            rays.clip_range(r[k], t_near[k], t_far[k]);
            moved[k] = {r[k].o + t_near[k] * r[k].d, r[k].d};
            t0[k] = float(t_near[k]);
        }
        caster.first_hits(moved.data(), n, depth);
        for (int k = 0; k < n; ++k)
            depth[k] = double(depth[k]) <= t_far[k] - t_near[k]
                           ? float(t_near[k] + double(depth[k]))
                           : std::numeric_limits<float>::infinity();
    };
    auto start = Clock::now();
    run_parallel(
        n_bands, n_threads,
        [&](int band) {
            RowRays r;
            CastScratch scratch;
            std::vector<Ray> row;
            std::vector<float> t0(W);
            std::vector<float> near_depth, far_depth;
            if (affine) {
                r.resize(W);
                near_depth.assign(W, float(clip_start));
                far_depth.assign(W, float(clip_end));
            } else {
                row.resize(W);
            }
            for (int j = band * kBandRows; j < std::min(H, (band + 1) * kBandRows); ++j) {
                float* depth = &result.depth[size_t(j) * W];
                float* k = &key[size_t(j) * W];
                if (affine) {
                    // t: view-axis depth (row_directions_cast), len: distance per unit t.
                    row_rays(j, r, true);
                    caster.first_hits(eye, r.fx.data(), r.fy.data(), r.fz.data(), near_depth.data(), far_depth.data(),
                                      W, depth);
                    for (int i = 0; i < W; ++i) {
                        k[i] = 1.0f / depth[i];  // inf -> 0
                        depth[i] *= r.len[i];
                    }
                    continue;
                }
                for (int i = 0; i < W; ++i) row[i] = rays(i + 0.5, j + 0.5);
                cast(row.data(), W, depth, t0.data(), scratch);
                for (int i = 0; i < W; ++i)
                    k[i] = std::isinf(depth[i]) ? 0.0f
                           : ortho          ? depth[i]
                                            : float(1.0 / (double(depth[i]) * glm::dot(row[i].d, forward)));
            }
        },
        reporter(0.0, kRaycastProgressShare));
    result.stats.seconds_raycast = seconds_since(start);
    check_traced(caster);

    // Edge test, in two steps. A pixel has a "kink" along one of the 4 lines through it
    // (horizontal, vertical, 2 diagonals) if the key's second difference along that line
    // exceeds 1 %, if the line mixes hits and misses, or if it leaves the image. Pixel p
    // and its neighbour r on a line are discontinuous when both kink along it: then
    // neither side's linear extrapolation predicts the other. p is an edge pixel if it
    // is discontinuous with any of its 8 neighbours.
    static constexpr int kLine[4][2] = {{1, 0}, {0, 1}, {1, 1}, {1, -1}};
    // Kinks of pixel (i, j), any position (the image border included).
    auto kinks = [&](int i, int j) {
        const size_t p = size_t(j) * W + i;
        const bool p_miss = std::isinf(result.depth[p]);
        const float kp = key[p];
        unsigned bits = 0;
        for (int l = 0; l < 4; ++l) {
            const int ai = i - kLine[l][0], aj = j - kLine[l][1], bi = i + kLine[l][0], bj = j + kLine[l][1];
            if (ai < 0 || ai >= W || aj < 0 || aj >= H || bi < 0 || bi >= W || bj < 0 || bj >= H) {
                bits |= 1u << l;
                continue;
            }
            const size_t a = size_t(aj) * W + ai, b = size_t(bj) * W + bi;
            const bool a_miss = std::isinf(result.depth[a]), b_miss = std::isinf(result.depth[b]);
            if (p_miss || a_miss || b_miss) {
                if (!(p_miss && a_miss && b_miss)) bits |= 1u << l;
                continue;
            }
            const float ka = key[a], kb = key[b];
            const float tol = 0.01f * std::min(std::abs(kp), std::min(std::abs(ka), std::abs(kb)));
            if (!(std::abs(ka + kb - 2.0f * kp) <= tol)) bits |= 1u << l;  // NaN counts as a kink
        }
        return bits;
    };
    // The same for a whole row _j_ into _out_[0, W): branch-free on the interior (misses
    // are key 0 there), the border pixels by _kinks_.
    auto kink_row = [&](int j, unsigned char* out) {
        if (j == 0 || j == H - 1 || W < 3) {
            for (int i = 0; i < W; ++i) out[i] = (unsigned char)kinks(i, j);
            return;
        }
        out[0] = (unsigned char)kinks(0, j);
        out[W - 1] = (unsigned char)kinks(W - 1, j);
        kink_interior(&key[size_t(j - 1) * W], &key[size_t(j) * W], &key[size_t(j + 1) * W], W, out);
    };
    // Edge flags of rows [j0, j1) from the kinks of rows [j0 - 1, j1 + 1), kept in a
    // buffer with a zero border (one row above and below, one column each side).
    auto edge_rows = [&](int j0, int j1, std::vector<unsigned char>& kink, std::vector<unsigned char>& edge) {
        const int k0 = std::max(0, j0 - 1), k1 = std::min(H, j1 + 1);
        const size_t stride = size_t(W) + 2;
        kink.assign(size_t(k1 - k0 + 2) * stride, 0);
        for (int j = k0; j < k1; ++j) kink_row(j, &kink[size_t(j - k0 + 1) * stride + 1]);
        edge.assign(size_t(j1 - j0) * W, 0);
        for (int j = j0; j < j1; ++j) {
            const unsigned char* c = &kink[size_t(j - k0 + 1) * stride + 1];
            const unsigned char* u = c - stride;
            const unsigned char* d = c + stride;
            unsigned char* e = &edge[size_t(j - j0) * W];
            for (int i = 0; i < W; ++i) {
                const unsigned n = ((c[i - 1] | c[i + 1]) & 1u) | ((u[i] | d[i]) & 2u) | ((u[i - 1] | d[i + 1]) & 4u) |
                                   ((d[i - 1] | u[i + 1]) & 8u);
                e[i] = (unsigned char)((c[i] & n) != 0);
            }
        }
    };

    // Pass 2: fog per pixel; edge pixels averaged over the filter-importance-sampled set.
    const bool supersample = settings.aa_samples > 1 && settings.filter_width > 0.0;
    const int n_aa = supersample ? settings.aa_samples : 1;
    const std::vector<glm::dvec2> pattern = filter_pattern(n_aa, settings.filter_width);
    const auto fog_setup_start = Clock::now();
    const FogModel fog(scene, settings, !rays.orthographic(), rays.position());
    result.stats.seconds_fog_setup = seconds_since(fog_setup_start);
    // Fog of _n_ rays from the near plane (t0, from _cast_) to _depth_ (from the origin,
    // inf: none), as Cycles integrates it: La over [t0, depth] with attenuation measured
    // from the near plane, Tr = exp(-sigma_t (depth - t0)) (FogModel::eval_many).
    const bool near_clip = clipped && clip_start > 0.0;
    struct FogScratch {};
    auto fog_eval = [&](const Ray* r, const float* depth, const float* t0, int n, double* Tr, RGB* La,
                        FogScratch&) { fog.eval_many(r, depth, near_clip ? t0 : nullptr, n, Tr, La); };
    // Homogeneous airlight on a lattice (settings.homogeneous_resolution = s > 1, the SIMD
    // table path only: perspective camera, model sun05, point and sun lights, no spots, no
    // Gaussians). Cells of s x s pixels whose corner pixels (lattice nodes) are evaluated
    // exactly; a cell's airlight is interpolated bilinearly from its corners when (1) no
    // pixel of the closed cell has a depth kink (the edge test above: no silhouette, crease
    // or hit/miss boundary), (2) its centre is not within gamma_ex of a point light's
    // direction and (3) the exact value at its centre pixel agrees with the interpolation to
    // kLatticeTol of the largest channel. Otherwise, and for the partial cells at the right
    // and bottom borders, every pixel is exact. The transmittance is always exact.
    // (2): near a light's image the airlight grows as 1 / gamma (the ray's closest approach
    // h = Dsv sin gamma; the in-scattering integral is ~pi / h), whose bilinear interpolation
    // over a cell of angular size Delta errs by ~Delta^2 / (4 gamma^2) relative: below
    // kLatticeTol for gamma >= Delta / (2 sqrt(kLatticeTol)) (+ one cell).
    const int lattice = settings.homogeneous_resolution;
    const bool use_lattice = lattice > 1 && affine && fog.soa() && !fog.has_spots();
    constexpr double kLatticeTol = 5e-4;
    std::vector<Vec3> light_dirs;
    double cos_ex = 1.0;
    if (use_lattice) {
        for (const PointLight& light : scene.point_lights) {
            const Vec3 v = light.position - eye;
            const double len = glm::length(v);
            if (len > 0.0) light_dirs.push_back(v / len);  // a light at the eye has no image
        }
        // Angle of one pixel step: |Dx| / |D| <= |Dx| / (D . forward), the view-axis
        // component being the least |D| can be (the same for every pixel of Blender's cameras;
        // the least over the corners otherwise).
        double fwd = std::numeric_limits<double>::infinity();
        for (double px : {0.0, double(W)})
            for (double py : {0.0, double(H)}) fwd = std::min(fwd, glm::dot(D0 + px * Dx + py * Dy, forward));
        const double pixel_angle = fwd > 0.0 ? std::max(glm::length(Dx), glm::length(Dy)) / fwd : kPi;
        const double gamma_ex = lattice * pixel_angle * (0.5 / std::sqrt(kLatticeTol) + 1.5);
        cos_ex = gamma_ex >= kPi ? -2.0 : std::cos(gamma_ex);
    }
    struct LatticeScratch {
        std::vector<RowRays> rows;  // rays of rows j0 .. min(j1, H - 1)
        std::vector<double> dx, dy, dz;
        std::vector<float> Dvp, t0, Tr, rgb, nodes, centres;
        std::vector<int> pi, pj;
        std::vector<unsigned char> exact;
    };
    // Airlight and transmittance of rows [j0, j1) of a band; _kink_ as edge_rows left it.
    auto lattice_band = [&](int j0, int j1, const std::vector<unsigned char>& kink, LatticeScratch& ls) {
        const int s = lattice;
        const int j_last = std::min(H - 1, j1);  // the node row below the band is needed too
        const int n_rows = j_last - j0 + 1;
        if (int(ls.rows.size()) < n_rows) ls.rows.resize(size_t(n_rows));
        for (int r = 0; r < n_rows; ++r) {
            if (ls.rows[r].dx.size() != size_t(W)) ls.rows[r].resize(size_t(W));
            row_rays(j0 + r, ls.rows[r], false);
        }
        ls.Tr.resize(size_t(W));
        for (int j = j0; j < j1; ++j) {  // the transmittance: exact everywhere
            fog.transmittance_soa(&result.depth[size_t(j) * W], near_clip ? ls.rows[j - j0].t_near.data() : nullptr,
                                  W, ls.Tr.data());
            float* T = &result.transmittance[3 * size_t(j) * W];
            for (int i = 0; i < W; ++i) T[3 * i] = T[3 * i + 1] = T[3 * i + 2] = ls.Tr[i];
        }
        // Evaluates the listed pixels (pi, pj) exactly into ls.rgb (3 per pixel).
        auto eval_listed = [&]() {
            const size_t m = ls.pi.size();
            ls.dx.resize(m), ls.dy.resize(m), ls.dz.resize(m), ls.Dvp.resize(m), ls.t0.resize(m);
            for (size_t k = 0; k < m; ++k) {
                const RowRays& rr = ls.rows[ls.pj[k] - j0];
                const int i = ls.pi[k];
                ls.dx[k] = rr.dx[i], ls.dy[k] = rr.dy[i], ls.dz[k] = rr.dz[i];
                ls.t0[k] = rr.t_near[i];
                ls.Dvp[k] = result.depth[size_t(ls.pj[k]) * W + i];
            }
            ls.rgb.resize(3 * m);
            if (ls.Tr.size() < m) ls.Tr.resize(m);
            fog.eval_soa(ls.dx.data(), ls.dy.data(), ls.dz.data(), ls.Dvp.data(), near_clip ? ls.t0.data() : nullptr,
                         int(m), ls.Tr.data(), ls.rgb.data());
        };
        auto put = [&](int i, int j, const float* v) {
            float* A = &result.airlight[3 * (size_t(j) * W + i)];
            A[0] = v[0], A[1] = v[1], A[2] = v[2];
        };
        // Full cells: corners (a s, j0 + b s), a < nx, b < ny, inside the image.
        const int nx = (W - 1) / s;
        int ny = 0;
        while (j0 + ny * s < j1 && j0 + (ny + 1) * s <= H - 1) ++ny;
        const int half = s / 2;
        ls.pi.clear(), ls.pj.clear();
        if (nx > 0 && ny > 0) {
            for (int b = 0; b <= ny; ++b)
                for (int a = 0; a <= nx; ++a) ls.pi.push_back(a * s), ls.pj.push_back(j0 + b * s);
            for (int b = 0; b < ny; ++b)
                for (int a = 0; a < nx; ++a) ls.pi.push_back(a * s + half), ls.pj.push_back(j0 + b * s + half);
        }
        eval_listed();
        const size_t n_nodes = size_t(nx + 1) * size_t(ny + 1);
        ls.nodes.assign(ls.rgb.begin(), ls.rgb.begin() + 3 * std::ptrdiff_t(nx > 0 && ny > 0 ? n_nodes : 0));
        ls.centres.assign(ls.rgb.begin() + std::ptrdiff_t(ls.nodes.size()), ls.rgb.end());
        auto node = [&](int a, int b) { return &ls.nodes[3 * (size_t(b) * (nx + 1) + a)]; };
        // Classify the cells.
        const int k0 = std::max(0, j0 - 1);
        const size_t stride = size_t(W) + 2;
        ls.exact.assign(size_t(nx) * ny, 0);
        for (int b = 0; b < ny; ++b)
            for (int a = 0; a < nx; ++a) {
                const int i0 = a * s, c0 = j0 + b * s;
                bool exact = false;
                for (int j = c0; j <= c0 + s && !exact; ++j) {
                    const unsigned char* kr = &kink[size_t(j - k0 + 1) * stride + 1];
                    for (int i = i0; i <= i0 + s; ++i) exact |= kr[i] != 0;
                }
                const RowRays& rc = ls.rows[c0 + half - j0];
                const Vec3 dc(rc.dx[i0 + half], rc.dy[i0 + half], rc.dz[i0 + half]);
                for (const Vec3& l : light_dirs) exact |= glm::dot(dc, l) > cos_ex;
                if (!exact) {
                    const float* e = &ls.centres[3 * (size_t(b) * nx + a)];
                    const float* n00 = node(a, b), *n10 = node(a + 1, b), *n01 = node(a, b + 1), *n11 = node(a + 1, b + 1);
                    const float peak = std::max(e[0], std::max(e[1], e[2]));
                    for (int c = 0; c < 3; ++c) {
                        const float interp = 0.25f * ((n00[c] + n10[c]) + (n01[c] + n11[c]));
                        exact |= !(std::abs(interp - e[c]) <= float(kLatticeTol) * peak);
                    }
                }
                ls.exact[size_t(b) * nx + a] = exact;
            }
        // The pixels still to evaluate: exact cells (but their corner and centre) and the
        // partial cells at the right and bottom borders.
        ls.pi.clear(), ls.pj.clear();
        for (int b = 0; b < ny; ++b)
            for (int a = 0; a < nx; ++a) {
                if (!ls.exact[size_t(b) * nx + a]) continue;
                const int i0 = a * s, c0 = j0 + b * s;
                for (int j = c0; j < c0 + s; ++j)
                    for (int i = i0; i < i0 + s; ++i)
                        if (!((i == i0 && j == c0) || (i == i0 + half && j == c0 + half))) ls.pi.push_back(i), ls.pj.push_back(j);
            }
        for (int j = j0; j < j1; ++j)
            for (int i = (j < j0 + ny * s ? nx * s : 0); i < W; ++i) ls.pi.push_back(i), ls.pj.push_back(j);
        eval_listed();
        for (size_t k = 0; k < ls.pi.size(); ++k) put(ls.pi[k], ls.pj[k], &ls.rgb[3 * k]);
        // The interpolated cells, a row at a time (the row's values on the cell's left and
        // right edges, then along the row), then every cell's corner and centre.
        const float inv_s = 1.0f / float(s);
        for (int b = 0; b < ny; ++b)
            for (int y = 0; y < s; ++y) {
                const int j = j0 + b * s + y;
                const float fy = float(y) * inv_s;
                float* A = &result.airlight[3 * size_t(j) * W];
                for (int a = 0; a < nx; ++a) {
                    if (ls.exact[size_t(b) * nx + a]) continue;
                    const float *n00 = node(a, b), *n10 = node(a + 1, b), *n01 = node(a, b + 1), *n11 = node(a + 1, b + 1);
                    float left[3], step[3];
                    for (int c = 0; c < 3; ++c) {
                        left[c] = (1.0f - fy) * n00[c] + fy * n01[c];
                        step[c] = ((1.0f - fy) * n10[c] + fy * n11[c] - left[c]) * inv_s;
                    }
                    float* out = A + 3 * size_t(a * s);
                    for (int x = 0; x < s; ++x)
                        for (int c = 0; c < 3; ++c) out[3 * x + c] = left[c] + float(x) * step[c];
                }
            }
        for (int b = 0; b < ny; ++b)
            for (int a = 0; a < nx; ++a) {
                const int i0 = a * s, c0 = j0 + b * s;
                put(i0, c0, node(a, b));
                put(i0 + half, c0 + half, &ls.centres[3 * (size_t(b) * nx + a)]);
            }
    };
    std::atomic<long long> supersampled{0}, samples{0}, edge_ns{0};
    start = Clock::now();
    // Gaussian fog with a perspective camera: the centre samples of every pixel come from
    // the tiled splat (gaussian_splat.h) in one pass over tiles; the band loop below then only
    // supersamples edge pixels (through eval_gaussians, the same kernels per ray).
    const bool splatted = affine && fog.splat() != nullptr;
    double band_progress_begin = kRaycastProgressShare;
    if (splatted) {
        GaussianSplat& splat = *fog.splat();
        const auto bin_start = Clock::now();
        splat.bin(D0, Dx, Dy, forward, W, H, near_clip ? clip_start : 0.0, settings.gaussian_resolution,
                  result.depth.data());
        result.stats.seconds_bin = seconds_since(bin_start);
        const int n_tiles = splat.num_tiles();
        // Costliest tiles first (GaussianSplat::tile_cost: binned pairs), so that the last tiles taken are cheap and
        // the threads finish together (in order, the tiles next to a light's image or the
        // cloud's core could leave one thread working alone at the end).
        std::vector<int> order(static_cast<size_t>(n_tiles));
        std::iota(order.begin(), order.end(), 0);
        std::stable_sort(order.begin(), order.end(),
                         [&](int a, int b) { return splat.tile_cost(a) > splat.tile_cost(b); });
        constexpr double kSplatShare = 0.6;  // of the progress bar, after pass 1
        const double end = kRaycastProgressShare + kSplatShare;
        run_parallel(
            n_tiles, n_threads,
            [&](int k) {
                splat.splat_tile(order[k], result.depth.data(), result.transmittance.data(), result.airlight.data());
            },
            [&, last = -1](int done) mutable {
                // Thousands of tiles: report (and check for cancel) once per percent.
                const int percent = int(100LL * done / n_tiles);
                if (!progress || percent == last) return;
                last = percent;
                const double f = kRaycastProgressShare + (end - kRaycastProgressShare) * done / n_tiles;
                if (!progress(f)) throw Cancelled();
            });
        band_progress_begin = end;
    }
    // Edge pixels: one fog evaluation per cluster of sub-samples (edge_sample_clusters), or
    // per sub-sample (edge_cluster_tol = 0: the reference; and with spot lights, whose cone
    // edge makes the fog a kinked function of the ray: the mean ray erred by up to 40 % of
    // the spot's airlight on such pixels).
    const bool clustered = supersample && settings.edge_cluster_tol > 0.0 && scene.spot_lights.empty();
    const double cluster_tol = settings.edge_cluster_tol;
    const double sigma_bg = scene.medium.sigma_t;  // the background extinction (Gaussians' too)
    // Airlight and transmittance error estimates above which a cluster's samples are
    // evaluated one by one (EdgeClusterBounds).
    constexpr double kEdgeAirlightTol = 5e-4, kEdgeTransmittanceTol = 5e-4;
    const EdgeClusterBounds bounds(scene, clustered ? fog.gaussian_medium() : nullptr);
    // Rays to evaluate (segments [t0, t]) and their fog.
    struct RayBatch {
        std::vector<Ray> ray;
        std::vector<float> t, t0;
        std::vector<double> Tr;
        std::vector<RGB> La;
        void resize(size_t n) {
            ray.resize(n), t.resize(n), t0.resize(n), Tr.resize(n), La.resize(n);
        }
    };
    // Scratch from a pool (ScratchPool): a band's rows, and the sub-pixel rays and results
    // of a run of edge pixels (~3 MB for two rows of them).
    struct BandScratch {
        std::vector<Ray> sub, row;
        std::vector<float> sub_t, sub_t0, t0, row_Tr;
        std::vector<double> sub_Tr, row_Tr_d;
        std::vector<RGB> sub_La, row_La;
        std::vector<int> edge_px;
        // Edge clusters (edge_sample_clusters): per row, sample order and cluster ends
        // per pixel, and one representative ray per cluster.
        std::vector<int> cl_order, cl_ends, cl_first;
        RayBatch cl;
        std::vector<unsigned char> cl_refined;
        std::vector<int> ref_k;  // samples of refined clusters (into sub)
        RayBatch ref;
        CastScratch cast_scratch;
        std::vector<unsigned char> kink, edge;
        RowRays r;
    };
    // Per band, its edge pixels (row, column) for the edge pass.
    std::vector<std::vector<std::pair<int, int>>> band_edges(static_cast<size_t>(n_bands));
    const double edges_begin = band_progress_begin + 0.5 * (1.0 - band_progress_begin);
    run_parallel(
        n_bands, n_threads,
        [&](int band) {
            static ScratchPool<BandScratch> band_pool;
            ScratchPool<BandScratch>::Lease lease(band_pool);
            BandScratch& bs = *lease;
            std::vector<float>& t0 = bs.t0;
            t0.resize(W);
            FogScratch fog_scratch;
            std::vector<unsigned char>&kink = bs.kink, &edge = bs.edge;
            const int j0 = band * kBandRows, j1 = std::min(H, (band + 1) * kBandRows);
            if (supersample || use_lattice) edge_rows(j0, j1, kink, edge);
            if (use_lattice) {  // ~1.5 MB of scratch per band
                static ScratchPool<LatticeScratch> lattice_pool;
                ScratchPool<LatticeScratch>::Lease lease(lattice_pool);
                lattice_band(j0, j1, kink, *lease);
            }
            long long band_samples = 0;
            const bool fast = affine && fog.soa();
            RowRays& r = bs.r;
            std::vector<Ray>& row = bs.row;
            std::vector<double>& row_Tr_d = bs.row_Tr_d;
            std::vector<RGB>& row_La = bs.row_La;
            std::vector<float>& row_Tr = bs.row_Tr;
            row_Tr.resize(W);
            if (fast) {
                r.resize(W);
            } else {
                row.resize(W);
                row_Tr_d.resize(W);
                row_La.resize(W);
            }
            for (int j = j0; j < j1; ++j) {
                // Centre samples of the whole row (edge pixels are overwritten below).
                const size_t p0 = size_t(j) * W;
                const float* depth = &result.depth[p0];
                float* A = &result.airlight[3 * p0];
                float* T = &result.transmittance[3 * p0];
                if (splatted || use_lattice) {
                    // Already written by the splat or the lattice.
                } else if (fast) {
                    row_rays(j, r, false);
                    fog.eval_soa(r.dx.data(), r.dy.data(), r.dz.data(), depth, near_clip ? r.t_near.data() : nullptr,
                                 W, row_Tr.data(), A);
                } else {
                    for (int i = 0; i < W; ++i) {
                        row[i] = rays(i + 0.5, j + 0.5);
                        double t_near = 0.0, t_far;
                        if (near_clip) rays.clip_range(row[i], t_near, t_far);
                        t0[i] = float(t_near);
                    }
                    fog_eval(row.data(), depth, t0.data(), W, row_Tr_d.data(), row_La.data(), fog_scratch);
                    for (int i = 0; i < W; ++i) {
                        row_Tr[i] = float(row_Tr_d[i]);
                        for (int c = 0; c < 3; ++c) A[3 * i + c] = float(row_La[i][c]);
                    }
                }
                if (!splatted && !use_lattice)
                    for (int i = 0; i < W; ++i) T[3 * i] = T[3 * i + 1] = T[3 * i + 2] = row_Tr[i];
                band_samples += W;
                if (!supersample) continue;
                // The row's edge pixels, supersampled in the next pass (in runs spread over
                // the threads: a horizon puts them all in one or two bands).
                const unsigned char* edge_row = &edge[size_t(j - j0) * W];
                for (int i = 0; i < W; ++i)
                    if (edge_row[i]) band_edges[size_t(band)].push_back({j, i});
            }
            samples += band_samples;
        },
        reporter(band_progress_begin, edges_begin));
    // The edge pixels in runs of at most kEdgeRun of one row, spread over the threads.
    struct EdgeRun {
        int j, first, count;  // row, into edge_i
    };
    std::vector<int> edge_i;
    std::vector<EdgeRun> edge_runs;
    for (const auto& list : band_edges)
        for (size_t k = 0; k < list.size(); ++k) {
            constexpr int kEdgeRun = 64;
            const int j = list[k].first;
            if (edge_runs.empty() || edge_runs.back().j != j || edge_runs.back().count == kEdgeRun)
                edge_runs.push_back({j, int(edge_i.size()), 0});
            edge_i.push_back(list[k].second);
            ++edge_runs.back().count;
        }
    std::vector<float> edge_out(4 * edge_i.size());
    run_parallel(
        int(edge_runs.size()), n_threads,
        [&](int run) {
            static ScratchPool<BandScratch> edge_pool;
            ScratchPool<BandScratch>::Lease lease(edge_pool);
            BandScratch& bs = *lease;
            const EdgeRun& er = edge_runs[size_t(run)];
            const int j = er.j;
            const size_t n_sub = pattern.size();
            std::vector<Ray>& sub = bs.sub;
            std::vector<float>&sub_t = bs.sub_t, &sub_t0 = bs.sub_t0;
            std::vector<double>& sub_Tr = bs.sub_Tr;
            std::vector<RGB>& sub_La = bs.sub_La;
            std::vector<int>& edge_px = bs.edge_px;
            edge_px.assign(edge_i.begin() + er.first, edge_i.begin() + er.first + er.count);
            CastScratch& cast_scratch = bs.cast_scratch;
            FogScratch fog_scratch;
            long long band_supersampled = 0, band_samples = 0;
            // Results go to edge_out (4 floats per edge pixel: airlight, transmittance) and
            // into the images after the pass: the images keep the centre samples meanwhile,
            // which the hits == 0 fallback below reads.
            float* out = &edge_out[4 * size_t(er.first)];
            // The sub-pixel rays of all the run's pixels at once: cast as packets and
            // evaluated in full SIMD chunks, then averaged per pixel.
            const auto edge_start = Clock::now();
            const size_t m = edge_px.size() * n_sub;
            sub.resize(m);
            sub_t.resize(m);
            sub_t0.resize(m);
            sub_Tr.resize(m);
            sub_La.resize(m);
            for (size_t e = 0; e < edge_px.size(); ++e)
                for (size_t k = 0; k < n_sub; ++k)
                    sub[e * n_sub + k] = rays(edge_px[e] + 0.5 + pattern[k].x, j + 0.5 + pattern[k].y);
            cast(sub.data(), int(m), sub_t.data(), sub_t0.data(), cast_scratch);
            if (clustered) {
                // One fog evaluation per cluster of sub-samples (edge_sample_clusters): the
                // normalised mean direction (and mean origin), mean depth and mean t0 of its
                // samples, exact up to second order in their spread; a cluster of one is
                // its sample.
                bs.cl_order.resize(m);
                bs.cl_ends.clear();
                bs.cl_first.resize(edge_px.size() + 1);
                for (size_t e = 0; e < edge_px.size(); ++e) {
                    bs.cl_first[e] = int(bs.cl_ends.size());
                    edge_sample_clusters(&sub_t[e * n_sub], int(n_sub), cluster_tol, &bs.cl_order[e * n_sub],
                                         bs.cl_ends);
                }
                bs.cl_first[edge_px.size()] = int(bs.cl_ends.size());
                const size_t n_cl = bs.cl_ends.size();
                bs.cl.resize(n_cl);
                bs.cl_refined.assign(n_cl, 0);
                for (size_t e = 0; e < edge_px.size(); ++e) {
                    const int* order = &bs.cl_order[e * n_sub];
                    for (int c = bs.cl_first[e], b = 0; c < bs.cl_first[e + 1]; b = bs.cl_ends[c++]) {
                        const int end = bs.cl_ends[c];
                        const size_t k0 = e * n_sub + size_t(order[b]);
                        if (end - b == 1) {
                            bs.cl.ray[c] = sub[k0];
                            bs.cl.t[c] = sub_t[k0];
                            bs.cl.t0[c] = sub_t0[k0];
                            continue;
                        }
                        Vec3 o(0.0), d(0.0);
                        double t = 0.0, t_near = 0.0;
                        for (int q = b; q < end; ++q) {
                            const size_t k = e * n_sub + size_t(order[q]);
                            o += sub[k].o;
                            d += sub[k].d;
                            t += double(sub_t[k]);
                            t_near += double(sub_t0[k]);
                        }
                        const double inv = 1.0 / double(end - b);
                        bs.cl.ray[c] = {o * inv, glm::normalize(d)};
                        bs.cl.t[c] = std::isinf(sub_t[k0]) ? sub_t[k0] : float(t * inv);
                        bs.cl.t0[c] = float(t_near * inv);
                    }
                }
                fog_eval(bs.cl.ray.data(), bs.cl.t.data(), bs.cl.t0.data(), int(n_cl), bs.cl.Tr.data(),
                         bs.cl.La.data(), fog_scratch);
                // Clusters whose error estimate (EdgeClusterBounds) exceeds the tolerance:
                // every sample evaluated instead, into sub_Tr, sub_La.
                bs.ref_k.clear();
                for (size_t e = 0; e < edge_px.size(); ++e) {
                    const int* order = &bs.cl_order[e * n_sub];
                    for (int c = bs.cl_first[e], b = 0; c < bs.cl_first[e + 1]; b = bs.cl_ends[c++]) {
                        const int end = bs.cl_ends[c];
                        if (end - b == 1) continue;
                        double err_La, err_Tr;
                        bounds.errors(&sub[e * n_sub], &sub_t[e * n_sub], order + b, end - b, bs.cl.ray[c],
                                      near_clip ? double(bs.cl.t0[c]) : 0.0, double(bs.cl.t[c]), bs.cl.La[c],
                                      err_La, err_Tr);
                        if (err_La <= kEdgeAirlightTol && err_Tr <= kEdgeTransmittanceTol) continue;
                        bs.cl_refined[c] = 1;
                        for (int q = b; q < end; ++q) bs.ref_k.push_back(int(e * n_sub + size_t(order[q])));
                    }
                }
                if (!bs.ref_k.empty()) {
                    const size_t n_ref = bs.ref_k.size();
                    bs.ref.resize(n_ref);
                    for (size_t q = 0; q < n_ref; ++q) {
                        bs.ref.ray[q] = sub[bs.ref_k[q]];
                        bs.ref.t[q] = sub_t[bs.ref_k[q]];
                        bs.ref.t0[q] = sub_t0[bs.ref_k[q]];
                    }
                    fog_eval(bs.ref.ray.data(), bs.ref.t.data(), bs.ref.t0.data(), int(n_ref), bs.ref.Tr.data(),
                             bs.ref.La.data(), fog_scratch);
                    for (size_t q = 0; q < n_ref; ++q) {
                        sub_Tr[bs.ref_k[q]] = bs.ref.Tr[q];
                        sub_La[bs.ref_k[q]] = bs.ref.La[q];
                    }
                }
                band_samples += (long long)(n_cl + bs.ref_k.size()) - (long long)edge_px.size();
            } else {
                fog_eval(sub.data(), sub_t.data(), sub_t0.data(), int(m), sub_Tr.data(), sub_La.data(),
                         fog_scratch);
            }
            for (size_t e = 0; e < edge_px.size(); ++e) {
                const int i = edge_px[e];
                const size_t s0 = e * n_sub;
                // Airlight: the filtered mean over all samples. Transmittance: the
                // mean over the samples that hit a surface. The composite is
                // render * T + A, and at a silhouette the render mixes surface
                // (coverage alpha) and background: R = alpha R_s + (1 - alpha) R_b.
                // The fogged truth is alpha R_s T_s + (1 - alpha) R_b T_b + A, with
                // T_b = 0 behind a miss (fog out to infinity). T = mean of all
                // samples = alpha T_s errs by -alpha (1 - alpha) (R_s - R_b) T_s: a
                // dark outline up to (1 - alpha) of the surface's own fogged radiance
                // where a lit object meets a dark sky. T = T_s errs by
                // (1 - alpha) R_b T_s: exact for a black world or a transparent film
                // (the renders in which infinite fog is consistent: whatever the
                // world shows is hidden by it), and never darker than the truth.
                // Behind a bright world it leaves a fringe of the world's colour,
                // 1 / alpha times the all-sample mean's error. Between two surfaces
                // (all samples hit) both are the same coverage-weighted mean.
                double Tr_hits = 0.0, Tr_all = 0.0;
                int hits = 0;
                RGB La(0.0);
                if (!clustered) {
                    for (size_t k = s0; k < s0 + n_sub; ++k) {
                        Tr_all += sub_Tr[k];
                        La += sub_La[k];
                        if (!std::isinf(sub_t[k])) Tr_hits += sub_Tr[k], ++hits;
                    }
                } else {
                    // Each sample takes its cluster's fog, the transmittance scaled by the
                    // background extinction over its own segment: exact for the homogeneous
                    // medium's part (on a grazing surface the depth spread is wide).
                    const int* order = &bs.cl_order[s0];
                    for (int c = bs.cl_first[e], b = 0; c < bs.cl_first[e + 1]; b = bs.cl_ends[c++]) {
                        const int end = bs.cl_ends[c];
                        if (bs.cl_refined[c]) {
                            for (int q = b; q < end; ++q) {
                                const size_t k = s0 + size_t(order[q]);
                                Tr_all += sub_Tr[k];
                                La += sub_La[k];
                                if (!std::isinf(sub_t[k])) Tr_hits += sub_Tr[k], ++hits;
                            }
                            continue;
                        }
                        La += double(end - b) * bs.cl.La[c];
                        if (std::isinf(bs.cl.t[c])) {
                            Tr_all += double(end - b) * bs.cl.Tr[c];
                            continue;
                        }
                        const double seg_c = double(bs.cl.t[c]) - (near_clip ? double(bs.cl.t0[c]) : 0.0);
                        // (in optical depth: in dense fog the factor alone overflows where the
                        // cluster's transmittance has underflowed to 0, and their product was NaN;
                        // the sample's own optical depth is >= 0, its transmittance <= 1)
                        const double log_Tr_c = bs.cl.Tr[c] > 0.0 ? std::log(double(bs.cl.Tr[c]))
                                                                  : -std::numeric_limits<double>::infinity();
                        for (int q = b; q < end; ++q) {
                            const size_t k = s0 + size_t(order[q]);
                            const double seg = double(sub_t[k]) - (near_clip ? double(sub_t0[k]) : 0.0);
                            const double Tr_k = end - b == 1 ? bs.cl.Tr[c]
                                                             : std::exp(std::min(0.0, log_Tr_c - sigma_bg * (seg - seg_c)));
                            Tr_all += Tr_k;
                            if (!std::isinf(sub_t[k])) Tr_hits += Tr_k, ++hits;
                        }
                    }
                }
                // No sample hit, yet the pixel was flagged: a surface lies in the
                // filter's tail (coverage < 1/(2N), e.g. 2 % of an emitter showing
                // in the render). The render there is that surface's light, so use
                // the transmittance of the neighbouring hits' centre samples (with
                // the all-sample mean, 0, that light would vanish: measured -20 %
                // on such pixels of the halo scene).
                if (hits == 0) {
                    for (int dj = -1; dj <= 1; ++dj)
                        for (int di = -1; di <= 1; ++di) {
                            const int ni = i + di, nj = j + dj;
                            if (ni < 0 || ni >= W || nj < 0 || nj >= H) continue;
                            const size_t q = size_t(nj) * W + size_t(ni);
                            if (std::isinf(result.depth[q])) continue;
                            Tr_hits += double(result.transmittance[3 * q]);  // its centre sample
                            ++hits;
                        }
                }
                const double Tr = hits > 0 ? Tr_hits / hits : Tr_all / double(n_sub);
                La /= double(n_sub);
                for (int c = 0; c < 3; ++c) out[4 * e + c] = float(La[c]);
                out[4 * e + 3] = float(Tr);
                ++band_supersampled;
                if (!clustered) band_samples += (long long)n_sub - 1;
            }
            edge_ns += std::chrono::duration_cast<std::chrono::nanoseconds>(Clock::now() - edge_start).count();
            supersampled += band_supersampled;
            samples += band_samples;
        },
        [&, n_runs = int(edge_runs.size())](int done) {
            if (!progress) return;
            if (!progress(done == n_runs ? 1.0 : edges_begin + (1.0 - edges_begin) * done / n_runs)) throw Cancelled();
        });
    if (progress && edge_runs.empty() && !progress(1.0)) throw Cancelled();
    for (const EdgeRun& er : edge_runs)
        for (int e = 0; e < er.count; ++e) {
            const size_t p = size_t(er.j) * W + size_t(edge_i[size_t(er.first + e)]);
            const float* v = &edge_out[4 * size_t(er.first + e)];
            for (int c = 0; c < 3; ++c) {
                result.airlight[3 * p + c] = v[c];
                result.transmittance[3 * p + c] = v[3];
            }
        }
    result.stats.seconds_airlight = seconds_since(start);
    result.stats.supersampled_pixels = supersampled;
    result.stats.seconds_edges = 1e-9 * double(edge_ns);
    result.stats.samples = samples;
    // Surface shading pass (bake_surface.cpp), only when asked for.
    if (settings.surface) {
        start = Clock::now();
        bake_surface_pass(scene, settings, rays, caster, n_threads, result);
        result.stats.seconds_surface = seconds_since(start);
    }
    check_traced(caster);
    return result;
}

}  // namespace airlight
