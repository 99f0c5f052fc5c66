// bake.cpp: per-pixel airlight and transmittance for one camera view.
//
// Pass 1 casts one ray through every pixel centre (depth). Pass 2 evaluates the fog
// model per pixel; pixels at depth discontinuities (silhouettes, creases) are supersampled
// through Cycles' Blackman-Harris film filter so fog edges match the render's
// antialiased edges. Both passes run over row bands on worker threads; the calling
// thread only waits and reports progress.
#include "bake.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <exception>
#include <limits>
#include <map>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <string>
#include <thread>

#include "camera.h"
#include "quadrature.h"
#include "raycast.h"
#include "sun05.h"
#include "sun05_inline.h"

namespace airlight {

namespace {

constexpr int kBandRows = 16;
constexpr int kMaxResolution = 32768;
constexpr double kPi = 3.14159265358979323846;
// Relative tolerance of the quadrature model inside a bake (reference, not speed).
constexpr double kQuadratureRelTol = 1e-8;
// Share of the progress bar given to pass 1 (ray casting).
constexpr double kRaycastProgressShare = 0.3;

// Throw std::invalid_argument with _msg_ unless _ok_.
void require(bool ok, const std::string& msg) {
    if (!ok) throw std::invalid_argument(msg);
}

bool finite3(const glm::dvec3& v) {
    return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
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
    for (size_t i = 0; i < scene.point_lights.size(); ++i) {
        const PointLight& light = scene.point_lights[i];
        require(finite3(light.position), "light " + std::to_string(i) + ": position must be finite");
        require(finite3(light.I0) && light.I0.x >= 0.0 && light.I0.y >= 0.0 && light.I0.z >= 0.0,
                "light " + std::to_string(i) + ": intensity must be finite and >= 0");
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
    require(settings.table_nu >= 2 && settings.table_nT >= 2, "table size must be at least 2 x 2");
    // The camera matrices are checked by CameraRays (finite, invertible).
}

// Blackman-Harris window as Cycles' film uses it: support [-w, w] for filter width _w_
// (Cycles doubles the user width for this filter before tabulating it).
double blackman_harris(double x, double w) {
    double a = 2.0 * kPi * (x / (2.0 * w) + 0.5);
    return 0.35875 - 0.48829 * std::cos(a) + 0.14128 * std::cos(2.0 * a) - 0.01168 * std::cos(3.0 * a);
}

// Stratified 1D sub-pixel offsets for the separable filter: the filter's inverse CDF at
// the centres of _n_ equal-mass strata, so all samples carry equal weight (importance
// sampling, as Cycles does). The filtered pixel is the mean over the n x n grid.
std::vector<double> filter_offsets(int n, double w) {
    std::vector<double> offsets(n, 0.0);
    if (n <= 1 || w <= 0.0) return offsets;
    // Tabulate the CDF with the trapezoid rule, then invert it by linear interpolation.
    const int m = 4096;
    std::vector<double> cdf(m + 1, 0.0);
    for (int i = 1; i <= m; ++i) {
        double x0 = -w + 2.0 * w * (i - 1) / m, x1 = -w + 2.0 * w * i / m;
        cdf[i] = cdf[i - 1] + 0.5 * (blackman_harris(x0, w) + blackman_harris(x1, w)) * (x1 - x0);
    }
    for (int k = 0; k < n; ++k) {
        double target = cdf[m] * (k + 0.5) / n;
        int i = int(std::lower_bound(cdf.begin(), cdf.end(), target) - cdf.begin());
        i = std::clamp(i, 1, m);
        double f = (target - cdf[i - 1]) / std::max(cdf[i] - cdf[i - 1], 1e-300);
        offsets[k] = -w + 2.0 * w * (i - 1 + f) / m;
    }
    return offsets;
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
        : model_(settings.model), sigma_t_(scene.medium.sigma_t), shared_origin_(shared_origin) {
        if (model_ == ModelId::Sun05Table) table_ = shared_special_F_table(settings.table_nu, settings.table_nT);
        for (const PointLight& light : scene.point_lights) {
            RGB weight = scene.medium.albedo * light.I0;
            if (weight.x == 0.0 && weight.y == 0.0 && weight.z == 0.0) continue;
            lights_.push_back({light.position, weight, glm::length(light.position - origin)});
        }
    }

    // Transmittance exp(-sigma_t Dvp) (0 at Dvp = inf unless sigma_t = 0) and airlight
    // summed over the lights, for the ray (_o_, unit _d_) ending at _Dvp_.
    void eval(const Ray& ray, double Dvp, double& Tr, RGB& La) const {
        La = RGB(0.0);
        if (sigma_t_ == 0.0) {
            Tr = 1.0;
            return;
        }
        Tr = std::isinf(Dvp) ? 0.0 : std::exp(-sigma_t_ * Dvp);
        for (const LightData& light : lights_) {
            Vec3 sv = light.s - ray.o;
            double Dsv = shared_origin_ ? light.Dsv : glm::length(sv);
            double cos_gamma = Dsv > 0.0 ? std::clamp(glm::dot(ray.d, sv) / Dsv, -1.0, 1.0) : 1.0;
            La += light.weight * airlight(Dsv, cos_gamma, Dvp);
        }
    }

  private:
    double airlight(double Dsv, double cos_gamma, double Dvp) const {
        switch (model_) {
            case ModelId::Sun05Table:  // inlined fast path, same as sun05_airlight(..., Table)
                return sun05_airlight_table(table_->data().data(), table_->nu(), table_->nT(), sigma_t_,
                                            Dsv, cos_gamma, Dvp);
            case ModelId::Sun05Exact:
                return sun05_airlight(sigma_t_, Dsv, cos_gamma, Dvp, nullptr, FEval::Exact);
            case ModelId::Quadrature:
                return sun05_airlight_quadrature(sigma_t_, Dsv, cos_gamma, Dvp, kQuadratureRelTol);
        }
        return 0.0;
    }

    ModelId model_;
    double sigma_t_;
    bool shared_origin_;
    std::shared_ptr<const SpecialFTable> table_;
    std::vector<LightData> lights_;
};

// Runs _work(i)_ for i in [0, n) on _n_threads_ workers that take items from an atomic
// counter. The calling thread waits and calls _on_progress(done)_ after completions; if
// that throws (cancel) or a worker throws, the workers stop and the exception propagates.
void run_parallel(int n, int n_threads, const std::function<void(int)>& work,
                  const std::function<void(int)>& on_progress) {
    if (n <= 0) return;
    std::atomic<int> next{0};
    std::atomic<bool> stop{false};
    std::mutex mutex;
    std::condition_variable cv;
    int done = 0;
    std::exception_ptr error;

    auto worker = [&]() {
        while (!stop.load(std::memory_order_relaxed)) {
            int i = next.fetch_add(1);
            if (i >= n) break;
            try {
                work(i);
            } catch (...) {
                std::lock_guard<std::mutex> lock(mutex);
                if (!error) error = std::current_exception();
                stop = true;
                cv.notify_all();
                return;
            }
            std::lock_guard<std::mutex> lock(mutex);
            ++done;
            cv.notify_all();
        }
    };
    std::vector<std::thread> threads;
    n_threads = std::max(1, std::min(n_threads, n));
    threads.reserve(n_threads);
    auto join_all = [&]() {
        for (std::thread& t : threads)
            if (t.joinable()) t.join();
    };
    try {
        for (int t = 0; t < n_threads; ++t) threads.emplace_back(worker);
        // Report completions from this (the calling) thread only.
        int reported = 0;
        std::unique_lock<std::mutex> lock(mutex);
        while (reported < n) {
            cv.wait(lock, [&] { return done != reported || error; });
            if (error) break;
            reported = done;
            lock.unlock();
            on_progress(reported);
            lock.lock();
        }
    } catch (...) {
        stop = true;
        join_all();
        throw;
    }
    join_all();
    if (error) std::rethrow_exception(error);
}

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point start) {
    return std::chrono::duration<double>(Clock::now() - start).count();
}

}  // namespace

// F tables are deterministic and costly to build: keep one per (nu, nT) for the process.
std::shared_ptr<const SpecialFTable> shared_special_F_table(int nu, int nT) {
    static std::mutex mutex;
    static std::map<std::pair<int, int>, std::shared_ptr<const SpecialFTable>> cache;
    std::lock_guard<std::mutex> lock(mutex);
    auto& slot = cache[{nu, nT}];
    if (!slot) slot = std::make_shared<const SpecialFTable>(nu, nT);
    return slot;
}

BakeResult bake(const SceneDescription& scene, const BakeSettings& settings, const ProgressFn& progress) {
    validate(scene, settings);
    const CameraRays rays(scene.camera);
    const int W = scene.camera.width, H = scene.camera.height;
    const size_t n_pixels = size_t(W) * size_t(H);
    int n_threads = settings.threads > 0 ? settings.threads : int(std::thread::hardware_concurrency());
    n_threads = std::max(1, n_threads);
    const int n_bands = (H + kBandRows - 1) / kBandRows;

    BakeResult result;
    result.width = W;
    result.height = H;
    result.depth.assign(n_pixels, 0.0f);
    result.airlight.assign(3 * n_pixels, 0.0f);
    result.transmittance.assign(3 * n_pixels, 0.0f);

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
    // depth for perspective, the distance itself for orthographic rays), so the edge
    // test below sees silhouettes and creases but not the slope of an oblique plane.
    const RayCaster caster(scene.geometry);
    const Vec3 forward = -glm::normalize(Vec3(scene.camera.cam_to_world[2]));
    const bool ortho = rays.orthographic();
    std::vector<float> key(n_pixels);
    auto start = Clock::now();
    run_parallel(
        n_bands, n_threads,
        [&](int band) {
            std::vector<Ray> row(W);
            for (int j = band * kBandRows; j < std::min(H, (band + 1) * kBandRows); ++j) {
                for (int i = 0; i < W; ++i) row[i] = rays(i + 0.5, j + 0.5);
                float* depth = &result.depth[size_t(j) * W];
                caster.first_hits(row.data(), W, depth);
                for (int i = 0; i < W; ++i)
                    key[size_t(j) * W + i] =
                        ortho ? depth[i] : float(1.0 / (double(depth[i]) * glm::dot(row[i].d, forward)));
            }
        },
        reporter(0.0, kRaycastProgressShare));
    result.stats.seconds_raycast = seconds_since(start);

    // Edge test: pixel p and neighbour r = p + delta are discontinuous if one ray misses
    // and the other hits, or if neither side's linear extrapolation (from p - delta
    // through p, from r + delta through r) predicts the other within 1 %.
    auto is_edge = [&](int i, int j) {
        const size_t p = size_t(j) * W + i;
        const bool p_miss = std::isinf(result.depth[p]);
        const float kp = key[p];
        for (int dj = -1; dj <= 1; ++dj)
            for (int di = -1; di <= 1; ++di) {
                if (di == 0 && dj == 0) continue;
                const int ri = i + di, rj = j + dj;
                if (ri < 0 || rj < 0 || ri >= W || rj >= H) continue;
                const size_t r = size_t(rj) * W + ri;
                const bool r_miss = std::isinf(result.depth[r]);
                if (p_miss != r_miss) return true;
                if (p_miss) continue;
                const float kr = key[r], tol = 0.01f * std::min(std::abs(kp), std::abs(kr));
                bool explained = false, tested = false;
                const int bi = i - di, bj = j - dj;  // behind p
                if (bi >= 0 && bj >= 0 && bi < W && bj < H && !std::isinf(result.depth[size_t(bj) * W + bi])) {
                    tested = true;
                    explained |= std::abs(2.0f * kp - key[size_t(bj) * W + bi] - kr) <= tol;
                }
                const int fi = ri + di, fj = rj + dj;  // beyond r
                if (fi >= 0 && fj >= 0 && fi < W && fj < H && !std::isinf(result.depth[size_t(fj) * W + fi])) {
                    tested = true;
                    explained |= std::abs(2.0f * kr - key[size_t(fj) * W + fi] - kp) <= tol;
                }
                if (!tested) explained = std::abs(kp - kr) <= tol;  // no third pixel: plain difference
                if (!explained) return true;
            }
        return false;
    };

    // Pass 2: fog per pixel; edge pixels averaged over the filter-importance-sampled grid.
    const bool supersample = settings.aa_samples > 1 && settings.filter_width > 0.0;
    const int n_aa = supersample ? settings.aa_samples : 1;
    const std::vector<double> offsets = filter_offsets(n_aa, settings.filter_width);
    const FogModel fog(scene, settings, !rays.orthographic(), rays.position());
    std::atomic<long long> supersampled{0}, samples{0};
    start = Clock::now();
    run_parallel(
        n_bands, n_threads,
        [&](int band) {
            std::vector<Ray> sub(size_t(n_aa) * n_aa);
            std::vector<float> sub_t(sub.size());
            long long band_supersampled = 0, band_samples = 0;
            for (int j = band * kBandRows; j < std::min(H, (band + 1) * kBandRows); ++j) {
                for (int i = 0; i < W; ++i) {
                    const size_t p = size_t(j) * W + i;
                    double Tr;
                    RGB La;
                    if (!supersample || !is_edge(i, j)) {
                        fog.eval(rays(i + 0.5, j + 0.5), result.depth[p], Tr, La);
                        ++band_samples;
                    } else {
                        // Cast the sub-pixel rays as packets, then average their fog.
                        for (int sy = 0; sy < n_aa; ++sy)
                            for (int sx = 0; sx < n_aa; ++sx)
                                sub[sy * n_aa + sx] = rays(i + 0.5 + offsets[sx], j + 0.5 + offsets[sy]);
                        caster.first_hits(sub.data(), int(sub.size()), sub_t.data());
                        double Tr_sum = 0.0;
                        RGB La_sum(0.0);
                        for (size_t k = 0; k < sub.size(); ++k) {
                            double Tr_k;
                            RGB La_k;
                            fog.eval(sub[k], sub_t[k], Tr_k, La_k);
                            Tr_sum += Tr_k;
                            La_sum += La_k;
                        }
                        Tr = Tr_sum / double(sub.size());
                        La = La_sum / double(sub.size());
                        ++band_supersampled;
                        band_samples += (long long)sub.size();
                    }
                    for (int c = 0; c < 3; ++c) {
                        result.airlight[3 * p + c] = float(La[c]);
                        result.transmittance[3 * p + c] = float(Tr);
                    }
                }
            }
            supersampled += band_supersampled;
            samples += band_samples;
        },
        reporter(kRaycastProgressShare, 1.0));
    result.stats.seconds_airlight = seconds_since(start);
    result.stats.supersampled_pixels = supersampled;
    result.stats.samples = samples;
    return result;
}

}  // namespace airlight
