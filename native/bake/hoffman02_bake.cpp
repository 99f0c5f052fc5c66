// bake_hoffman02.cpp: the Hoffman & Preetham 2002 bake model (see bake_hoffman02.h).
#include "bake/hoffman02_bake.h"

#include <algorithm>
#include <cmath>
#include <thread>
#include <vector>

#include "image/camera.h"
#include "homogeneous/hoffman02.h"
#include "core/phase.h"
#include "homogeneous/sunlight_layer.h"

namespace airlight {

BakeResult bake_hoffman02(const SceneDescription& scene, const BakeSettings& settings, const ProgressFn& progress) {
    // The first hits come from the ordinary bake of the scene with no fog and no lights
    // (cheap: its airlight is 0), so the depth and clip conventions are the bake's own.
    SceneDescription geometry = scene;
    geometry.medium.sigma_t = 0.0;
    geometry.medium.rayleigh_550 = 0.0;
    geometry.medium.phase = PhaseFunction{};
    geometry.sun_lights.clear();
    BakeSettings depth_settings = settings;
    depth_settings.model = ModelId::Sun05Table;
    depth_settings.aa_samples = 1;
    depth_settings.surface = false;
    auto half = [&progress](double f) { return progress ? progress(0.5 * f) : true; };
    BakeResult result = bake(geometry, depth_settings, half);

    Hoffman02Medium m;
    hoffman02_rayleigh_rgb(scene.medium.rayleigh_550, m.beta_R);
    for (double& b : m.beta_M) b = scene.medium.sigma_t;
    m.g = scene.medium.phase.kind == PhaseKind::HenyeyGreenstein ? scene.medium.phase.g : 0.0;
    const PhaseFunction rayleigh{PhaseKind::Rayleigh, 0.0}, mie{PhaseKind::HenyeyGreenstein, m.g};
    struct Sun {
        Vec3 w;
        double mu_s;
        RGB E;
    };
    std::vector<Sun> suns;
    for (const SunLight& s : scene.sun_lights) {
        const Vec3 w = glm::normalize(s.direction);
        suns.push_back({w, -w.z, s.E});
    }
    const RGB albedo = scene.medium.albedo;
    const CameraRays rays(scene.camera);
    const int W = scene.camera.width, H = scene.camera.height;
    int n_threads = settings.threads > 0 ? settings.threads : int(std::thread::hardware_concurrency());
    n_threads = std::max(1, std::min(n_threads, H));
    auto work = [&](int first) {
        for (int j = first; j < H; j += n_threads) {
            for (int i = 0; i < W; ++i) {
                const size_t px = size_t(j) * W + i;
                const Ray ray = rays(i + 0.5, j + 0.5);
                double t_near, t_far;
                rays.clip_range(ray, t_near, t_far);
                const double D = double(result.depth[px]);  // inf where nothing is hit
                const double seg = std::max(0.0, D - t_near);
                float* T = &result.transmittance[3 * px];
                float* A = &result.airlight[3 * px];
                for (int c = 0; c < 3; ++c) {
                    const double sigma = m.beta_R[c] + m.beta_M[c];
                    T[c] = float(sigma > 0.0 ? std::exp(-sigma * seg) : 1.0);
                    A[c] = 0.0f;
                }
                if (!(D > t_near)) continue;
                for (const Sun& sun : suns) {
                    const double cos_theta = -glm::dot(sun.w, ray.d);
                    const double pR = rayleigh.eval(cos_theta), pM = mie.eval(cos_theta);
                    for (int c = 0; c < 3; ++c) {
                        const double sigma = m.beta_R[c] + m.beta_M[c];
                        if (!(sigma > 0.0)) continue;
                        const double G = sunlight_layer_factor(sigma, scene.fog_top, sun.mu_s, ray.o.z, ray.d.z, t_near, D);
                        A[c] += float(albedo[c] * sun.E[c] * (m.beta_R[c] * pR + m.beta_M[c] * pM) * G);
                    }
                }
            }
        }
    };
    std::vector<std::thread> pool;
    for (int k = 1; k < n_threads; ++k) pool.emplace_back(work, k);
    work(0);
    for (std::thread& t : pool) t.join();
    if (progress && !progress(1.0)) throw Cancelled();
    return result;
}

}  // namespace airlight
