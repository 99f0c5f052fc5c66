// gaussian_pass.cpp: Gaussian fog by the tiled splat (passes.h).
#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <numeric>
#include <vector>

#include "bake/passes.h"
#include "core/parallel.h"

namespace airlight {

namespace {

// The splat's centre samples corrected, band by band: each row's rays take what volumetric
// shadows remove from them (FogEvaluator::shadow_gaussians).
void shadow_centres(BakeContext& ctx, const FogEvaluator& fog) {
    const int W = ctx.W, H = ctx.H;
    BakeResult& result = ctx.result;
    parallel_for(ctx.n_bands, ctx.n_threads, [&](int band) {
        thread_local RowRays rr;
        thread_local std::vector<Ray> rays;
        thread_local std::vector<RGB> La;
        if (rr.dx.size() != size_t(W)) rr.resize(size_t(W));
        rays.resize(size_t(W)), La.resize(size_t(W));
        for (int j = band * kBandRows; j < std::min(H, (band + 1) * kBandRows); ++j) {
            ctx.row_rays(j, rr, false);
            float* A = &result.airlight[3 * size_t(j) * W];
            for (int i = 0; i < W; ++i) {
                rays[i].o = ctx.eye;
                rays[i].d = Vec3(rr.dx[i], rr.dy[i], rr.dz[i]);
                La[i] = RGB(A[3 * i], A[3 * i + 1], A[3 * i + 2]);
            }
            const float* depth = &result.depth[size_t(j) * W];
            const float* t_near = ctx.near_clip ? rr.t_near.data() : nullptr;
            fog.shadow_gaussians(rays.data(), depth, t_near, W, La.data());
            for (int i = 0; i < W; ++i)
                for (int c = 0; c < 3; ++c) A[3 * i + c] = float(std::max(0.0, La[i][c]));
        }
    });
}

}  // namespace

double gaussian_pass(BakeContext& ctx, const FogEvaluator& fog) {
    // Gaussian fog with a perspective camera: the centre samples of every pixel come from
    // the tiled splat (gaussian/splat.h) in one pass over tiles; the homogeneous pass then
    // only finds the edge pixels, which the edge pass supersamples (through the same kernels
    // per ray).
    const int W = ctx.W, H = ctx.H, n_threads = ctx.n_threads;
    const ProgressFn& progress = ctx.progress;
    BakeResult& result = ctx.result;
    GaussianSplat& splat = *fog.splat();
    const auto bin_start = Clock::now();
    splat.bin(ctx.D0, ctx.Dx, ctx.Dy, ctx.forward, W, H, ctx.near_clip ? ctx.clip_start : 0.0,
              ctx.settings.gaussian_resolution,
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
    // Of the progress bar after pass 1: the splat's share, or with the refinement a third of it
    // (the refinement the rest).
    constexpr double kSplatShare = 0.6;
    const double end = kRaycastProgressShare + kSplatShare;
    const double splat_end = fog.refiner() ? kRaycastProgressShare + kSplatShare / 3.0 : end;
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
            const double f = kRaycastProgressShare + (splat_end - kRaycastProgressShare) * done / n_tiles;
            if (!progress(f)) throw Cancelled();
        });
    result.stats.gaussian_pairs = static_cast<long long>(fog.refine_pairs());
    result.stats.gaussian_kept_bound = fog.refine_kept_bound();
    result.stats.gaussian_error_bound = fog.refine_error_bound();
    if (fog.has_shadows()) shadow_centres(ctx, fog);
    if (fog.refiner()) {
        // Over its budget the refinement stops and the frame keeps Fogshop's values throughout
        // (edges too), so that whether a frame is refined depends on its work alone.
        std::vector<float> fogshop;
        acquire_image_copy(fogshop, result.airlight);
        const auto refine_start = Clock::now();
        refine_pass(ctx, fog, fogshop, splat_end, end);
        result.stats.seconds_refine = seconds_since(refine_start);
        result.stats.gaussian_refine_work = fog.refine_work_seconds();
        fog.close_refine_budget();
        if (fog.refine_abandoned()) {
            result.airlight = fogshop;
            result.stats.gaussian_refine_abandoned = true;
            result.stats.gaussian_error_bound = std::numeric_limits<double>::infinity();
        } else if (ctx.affine) {  // (the edge pass's samples take its ratios: refine_samples)
            auto frame = std::make_unique<FogEvaluator::RefinedFrame>();
            frame->W = ctx.W, frame->H = ctx.H;
            frame->fogshop = std::move(fogshop);
            acquire_image_copy(frame->refined, result.airlight);
            frame->depth = &result.depth;
            frame->to_film = glm::inverse(glm::dmat3(ctx.Dx, ctx.Dy, ctx.D0));
            fog.keep_refined_frame(std::move(frame));
        }
        recycle_image_buffer(std::move(fogshop));  // (where the frame did not take it)
    }
    return end;
}

}  // namespace airlight
