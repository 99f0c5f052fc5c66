// bake.cpp: per-pixel airlight and transmittance for one camera view, as a pipeline of
// passes (passes.h): camera rays and depth, Gaussian fog, homogeneous fog, edge pixels,
// surfaces. The passes run over row bands or tiles on worker threads (core/parallel.h);
// the calling thread works too and reports progress.
#include "bake/bake.h"

#include <memory>

#include "bake/fog_evaluator.h"
#include "bake/passes.h"
#include "bake/glow_shadow.h"
#include "bake/surface_pass.h"
#include "bake/validate.h"
#include "core/build_progress.h"
#include "models/registry.h"

namespace airlight {

namespace {
// A spread of kViewsX x kViewsY of the frame's pixels, their rays to their surfaces (the
// light-depth maps' check: FogEvaluator's views); none where the rays do not share the eye.
std::vector<ViewRay> view_rays(const BakeContext& ctx) {
    constexpr int kViewsX = 12, kViewsY = 7;
    std::vector<ViewRay> views;
    if (!ctx.affine || ctx.W < 1 || ctx.H < 1) return views;
    std::vector<int> xs;
    for (int i = 0; i < kViewsX; ++i) xs.push_back(int((i + 0.5) * ctx.W / kViewsX));
    RowRays rr;
    rr.resize(xs.size());
    for (int j = 0; j < kViewsY; ++j) {
        const int y = int((j + 0.5) * ctx.H / kViewsY);
        ctx.pixel_rays(y, xs.data(), int(xs.size()), rr);
        for (size_t k = 0; k < xs.size(); ++k) {
            ViewRay v;
            v.d = glm::normalize(Vec3(rr.dx[k], rr.dy[k], rr.dz[k]));
            v.near = ctx.near_clip ? rr.t_near[k] : 0.0;
            v.depth = ctx.result.depth[size_t(y) * ctx.W + xs[k]];
            views.push_back(v);
        }
    }
    return views;
}
}  // namespace

BakeResult bake(const SceneDescription& scene, const BakeSettings& settings, const ProgressFn& user_progress) {
    validate(scene, settings);
    // The fraction last reported; the tables built inside the bake (the model's at the end
    // of the raycast, the surface pass's) report it again while they build (a 4096^2 table
    // takes seconds), so the bar stays alive and a cancel stops the build
    // (core/build_progress.h).
    double reported = 0.0;
    ProgressFn progress;
    if (user_progress)
        progress = [&user_progress, &reported](double fraction) {
            reported = fraction;
            return user_progress(fraction);
        };
    const BuildProgressScope table_builds([&] {
        if (progress && !progress(reported)) throw Cancelled();
    });
    const ModelEntry& model_entry_ = model_entry(settings.model);
    if (model_entry_.bake) return model_entry_.bake(scene, settings, progress);  // whole-image models

    BakeResult result;
    const auto geometry_start = Clock::now();
    BakeContext ctx(scene, settings, progress, result);
    result.stats.seconds_geometry = seconds_since(geometry_start);
    if (progress && !progress(0.0)) throw Cancelled();
    raycast_pass(ctx);

    const auto fog_setup_start = Clock::now();
    const std::unique_ptr<FogModel> model = model_entry_.make(scene, settings);
    const FogEvaluator fog(scene, settings, *model, !ctx.rays.orthographic(), ctx.rays.position(), view_rays(ctx));
    result.stats.seconds_fog_setup = seconds_since(fog_setup_start);
    result.stats.seconds_shadow_volumes = fog.seconds_shadow_volumes();

    const auto start = Clock::now();
    const bool splatted = ctx.affine && fog.splat() != nullptr;
    const double centres_begin = splatted ? gaussian_pass(ctx, fog) : kRaycastProgressShare;
    const double edges_begin = centres_begin + 0.5 * (1.0 - centres_begin);
    const EdgeMap edges(ctx);
    const EdgePixels edge_pixels = homogeneous_pass(ctx, fog, edges, splatted, centres_begin, edges_begin);
    edge_pass(ctx, fog, edge_pixels, edges_begin);
    fog.keep_refined_frame(nullptr);  // (the refine pass's frame, 24 bytes a pixel, has served)
    result.stats.seconds_airlight = seconds_since(start);
    result.stats.gaussian_background_rays = fog.background_rays();
    result.stats.gaussian_marched_lights = static_cast<long long>(fog.marched_lights());
    result.stats.gaussian_marched_rays = fog.marched_rays();

    if (settings.surface) {
        const auto surface_start = Clock::now();
        std::unique_ptr<GlowShadow> glow_shadow;
        if (const ShadowVolumes* volumes = fog.shadow_volumes()) {
            std::vector<int> positional = fog.scene_point_volumes();
            const std::vector<int>& spots = fog.scene_spot_volumes();
            positional.insert(positional.end(), spots.begin(), spots.end());
            std::vector<Vec3> positions, sun_directions;
            for (const PointLight& l : scene.point_lights) positions.push_back(l.position);
            for (const SpotLight& l : scene.spot_lights) positions.push_back(l.position);
            for (const SunLight& l : scene.sun_lights) sun_directions.push_back(glm::normalize(l.direction));
            glow_shadow = std::make_unique<GlowShadow>(*volumes, std::move(positional), std::move(positions),
                                                       fog.scene_sun_volumes(), std::move(sun_directions),
                                                       scene.medium.sigma_t, fog.cap_cut());
        }
        bake_surface_pass(scene, settings, ctx.rays, ctx.caster, ctx.n_threads, result, glow_shadow.get());
        result.stats.seconds_surface = seconds_since(surface_start);
    }
    ctx.check_traced();
    return result;
}

}  // namespace airlight
