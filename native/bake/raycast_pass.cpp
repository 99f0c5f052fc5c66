// raycast_pass.cpp: pass 1 of the bake (passes.h), the first hit through every pixel centre.
#include <cmath>
#include <vector>

#include "bake/passes.h"
#include "core/parallel.h"

namespace airlight {

void raycast_pass(BakeContext& ctx) {
    // First-hit distance through every pixel centre, a row at a time. Also keep
    // a per-pixel key that is affine in pixel coordinates on any plane (1 / view-axis
    // depth for perspective, the distance itself for orthographic rays; 0 where the ray
    // misses), so the edge test below sees silhouettes and creases but not the slope of
    // an oblique plane.
    const int W = ctx.W, H = ctx.H, n_bands = ctx.n_bands, n_threads = ctx.n_threads;
    const CameraRays& rays = ctx.rays;
    const RayCaster& caster = ctx.caster;
    const Vec3 forward = ctx.forward, eye = ctx.eye;
    const bool ortho = ctx.ortho, affine = ctx.affine;
    const double clip_start = ctx.clip_start, clip_end = ctx.clip_end;
    BakeResult& result = ctx.result;
    std::vector<float>& key = ctx.key;
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
                    ctx.row_rays(j, r, true);
                    caster.first_hits(eye, r.fx.data(), r.fy.data(), r.fz.data(), near_depth.data(), far_depth.data(),
                                      W, depth);
                    for (int i = 0; i < W; ++i) {
                        k[i] = 1.0f / depth[i];  // inf -> 0
                        depth[i] *= r.len[i];
                    }
                    continue;
                }
                for (int i = 0; i < W; ++i) row[i] = rays(i + 0.5, j + 0.5);
                ctx.cast(row.data(), W, depth, t0.data(), scratch);
                for (int i = 0; i < W; ++i)
                    k[i] = std::isinf(depth[i]) ? 0.0f
                           : ortho          ? depth[i]
                                            : float(1.0 / (double(depth[i]) * glm::dot(row[i].d, forward)));
            }
        },
        ctx.reporter(0.0, kRaycastProgressShare));
    result.stats.seconds_raycast = seconds_since(start);
    ctx.check_traced();

}

}  // namespace airlight
