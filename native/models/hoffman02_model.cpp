// hoffman02_model.cpp: ModelId::Hoffman02, Hoffman & Preetham 2002's daylight aerial perspective
// as a bake model: a Rayleigh + Mie medium with wavelength-dependent extinction lit by sun
// lamps.
//
// Medium per RGB channel c (hoffman02.h): Rayleigh beta_R,c = beta_R(550 nm) (550 / lambda_c)^4
// (scene.medium.rayleigh_550, lambda = 650 / 570 / 475 nm) plus Mie beta_M = medium.sigma_t with
// the medium's Henyey-Greenstein g (Cycles' sign), sigma_c = beta_R,c + beta_M, scattering
// albedo medium.albedo. Along a pixel-centre ray from the near clip point t0 to the first
// hit at depth D (inf: none):
//   Transmittance_c = e^{-sigma_c (D - t0)}
//   Airlight_c      = albedo_c sum_suns E_c (beta_R,c p_R(cos) + beta_M p_HG(cos)) G(sigma_c)
// with G the sun's geometric factor of sunlight_layer.h per channel: HP's unattenuated sun
// ((1 - e^{-sigma_c (D - t0)}) / sigma_c, the paper's closed form) without a fog top, the sun
// dimmed by its path through the layer with one (scene.fog_top). The phase angle is fixed
// along a ray (cos = -w.d), so this is exact single scattering for that medium; its
// reference is hoffman02_quadrature / sunlight_layer_factor_quadrature.
// Sun lamps only: point and spot lights are refused by validate() (the paper models
// daylight), as are fog objects. Pixels are evaluated at their centres (no edge
// supersampling; documented).

#include "bake/bake.h"
#include "core/parallel.h"

#include <algorithm>
#include <cmath>
#include <thread>
#include <vector>

#include <stdexcept>
#include <string>

#include "image/camera.h"
#include "homogeneous/hoffman02.h"
#include "core/phase.h"
#include "homogeneous/sunlight_layer.h"
#include "models/registry.h"

namespace airlight {

namespace {

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
    const int n_threads = std::min(resolve_threads(settings.threads), H);
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
    parallel_for(n_threads, n_threads, work);  // one stripe of rows per item
    if (progress && !progress(1.0)) throw Cancelled();
    return result;
}

// Hoffman & Preetham model daylight: sun lamps in a Rayleigh + Mie (HG) medium.
void validate(const SceneDescription& scene, const BakeSettings& settings) {
    auto require = [](bool ok, const std::string& msg) {
        if (!ok) throw std::invalid_argument(msg);
    };
    require(scene.point_lights.empty() && scene.spot_lights.empty(),
            "model 'hoffman02' (Hoffman & Preetham 2002) scatters sun lamps only: exclude the point "
            "and spot lights from the fog or use another model");
    require(scene.gaussians.empty(), "model 'hoffman02' does not take fog objects (Gaussians)");
    require(!settings.surface, "model 'hoffman02' has no surface-shading pass (per-channel extinction): "
                               "bake it with surface=False");
    const PhaseFunction& phase = scene.medium.phase;
    require(phase.kind == PhaseKind::Isotropic || phase.kind == PhaseKind::HenyeyGreenstein,
            "model 'hoffman02': the Mie part is Henyey-Greenstein (the Rayleigh part is built in); got phase '" +
                std::string(phase_name(phase.kind)) + "'");
}

}  // namespace

ModelEntry hoffman02_entry() {
    ModelEntry e{ModelId::Hoffman02, "hoffman02",
                 "Hoffman & Preetham 2002 daylight: Rayleigh (1/lambda^4 per channel) + Mie haze lit by sun lamps only"};
    e.validate = validate;
    e.bake = bake_hoffman02;
    return e;
}

}  // namespace airlight
