// gaussian_pass.cpp: Gaussian fog by the tiled splat (passes.h).
#include <algorithm>
#include <cmath>
#include <limits>
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

// The refinement (FogEvaluator::refine_gaussians) of the centre samples: its ratio
// (refined / Fogshop, per channel) on a grid of every kRefineStride-th pixel (and the last row
// and column), interpolated bilinearly to the pixels between grid points that see the same
// surface as the cell's corners (inverse depth, linear in the image for a plane, within
// kRefineDepthTol of the corners' bilinear value; or all the sky); the other pixels (depth
// edges) are refined alone, and so are those where the ratio varies across the cell by more
// than kRefineRatioTol of the accuracy or Fogshop's own value leaves the corners' bilinear
// surface by more than that (a light's image, a spot's cone edge).
constexpr int kRefineStride = 4;
constexpr double kRefineDepthTol = 0.01;
constexpr double kRefineRatioTol = 0.25;
constexpr double kInf = std::numeric_limits<double>::infinity();

// A worker thread's rays and values for refine_centres.
struct RefineScratch {
    RowRays rr;
    std::vector<Ray> rays;
    std::vector<RGB> La;
    std::vector<float> depth, near;
    std::vector<int> xs;
};

RefineScratch& refine_scratch(int W) {
    thread_local RefineScratch scratch;
    if (scratch.rr.dx.size() != size_t(W)) scratch.rr.resize(size_t(W));
    return scratch;
}

void refine_centres(BakeContext& ctx, const FogEvaluator& fog) {
    const int W = ctx.W, H = ctx.H, s = kRefineStride;
    BakeResult& result = ctx.result;
    const int Wc = (W - 1 + s - 1) / s + 1, Hc = (H - 1 + s - 1) / s + 1;
    const double ratio_tol = kRefineRatioTol * fog.refine_target();
    auto grid_x = [&](int I) { return std::min(I * s, W - 1); };
    auto grid_y = [&](int J) { return std::min(J * s, H - 1); };
    std::vector<RGB> ratio(size_t(Wc) * Hc, RGB(1.0));
    std::vector<RGB> delta(size_t(Wc) * Hc, RGB(0.0));  // (where a channel's Fogshop value is 0)
    std::vector<RGB> base(size_t(Wc) * Hc, RGB(0.0));   // Fogshop's values
    // Refines the pixels xs of row y in place (scratch.La: their refined values).
    auto refine_row = [&](int y, RefineScratch& scratch) {
        ctx.row_rays(y, scratch.rr, false);
        const int n = int(scratch.xs.size());
        scratch.rays.resize(size_t(n)), scratch.La.resize(size_t(n));
        scratch.depth.resize(size_t(n)), scratch.near.resize(size_t(n));
        const float* A = &result.airlight[3 * size_t(y) * W];
        for (int k = 0; k < n; ++k) {
            const int x = scratch.xs[k];
            scratch.rays[k].o = ctx.eye;
            scratch.rays[k].d = Vec3(scratch.rr.dx[x], scratch.rr.dy[x], scratch.rr.dz[x]);
            scratch.La[k] = RGB(A[3 * x], A[3 * x + 1], A[3 * x + 2]);
            scratch.depth[k] = result.depth[size_t(y) * W + x];
            scratch.near[k] = ctx.near_clip ? scratch.rr.t_near[x] : 0.0f;
        }
        fog.refine_gaussians(scratch.rays.data(), scratch.depth.data(), ctx.near_clip ? scratch.near.data() : nullptr,
                             n, scratch.La.data());
    };
    // Foresight: an 8 x 5 spread of grid points first (results dropped); its work, scaled to the
    // grid and as much again for the pixels refined alone, stops a frame that would exceed the
    // budget before the grid is spent. The points go one at a time, in an order spread over the
    // image, and each call may do only what is left of the budget at that scale
    // (FogEvaluator::set_refine_scale), so the frame stops as soon as the work so far exceeds it:
    // the whole spread's could only be larger (a dense cloud's first ray can decide it).
    const int Wf = std::min(Wc, 8), Hf = std::min(Hc, 5), Nf = Wf * Hf;
    const double foresight_scale = 2.0 * double(Wc) * Hc / double(Nf);
    auto spread = [](int k, int n, int m) { return n > 1 ? int(std::lround(double(k) * (m - 1) / (n - 1))) : 0; };
    int step = 17;  // coprime with Nf: k -> k step mod Nf visits every point, far apart in turn
    while (std::gcd(step, Nf) != 1) ++step;
    fog.set_refine_scale(foresight_scale);
    parallel_for(Nf, ctx.n_threads, [&](int k) {
        if (fog.refine_abandoned()) return;
        const int q = int((long long)(k) * step % Nf);
        RefineScratch& scratch = refine_scratch(W);
        scratch.xs.assign(1, grid_x(spread(q % Wf, Wf, Wc)));
        refine_row(grid_y(spread(q / Wf, Hf, Hc)), scratch);
    });
    fog.set_refine_scale(1.0);
    fog.foresee_refine_work(foresight_scale);
    if (fog.refine_abandoned()) return;
    // The grid.
    parallel_for(Hc, ctx.n_threads, [&](int J) {
        RefineScratch& scratch = refine_scratch(W);
        scratch.xs.clear();
        for (int I = 0; I < Wc; ++I) scratch.xs.push_back(grid_x(I));
        const int y = grid_y(J);
        refine_row(y, scratch);
        const std::vector<RGB>& La = scratch.La;
        const std::vector<int>& xs = scratch.xs;
        const float* A = &result.airlight[3 * size_t(y) * W];
        for (int I = 0; I < Wc; ++I)
            for (int c = 0; c < 3; ++c) {
                const double f = A[3 * xs[I] + c];
                base[size_t(J) * Wc + I][c] = f;
                if (f > 0.0) ratio[size_t(J) * Wc + I][c] = La[I][c] / f;
                else delta[size_t(J) * Wc + I][c] = La[I][c];
            }
    });
    if (fog.refine_abandoned()) return;  // (counted over the budget in the grid)
    // Every pixel: interpolated where its cell's corners see the same surface, else its own.
    parallel_for(ctx.n_bands, ctx.n_threads, [&](int band) {
        RefineScratch& scratch = refine_scratch(W);
        std::vector<int>& own = scratch.xs;
        for (int y = band * kBandRows; y < std::min(H, (band + 1) * kBandRows); ++y) {
            const int J0 = std::min(y / s, Hc - 1), J1 = std::min(J0 + 1, Hc - 1);
            const int y0 = grid_y(J0), y1 = grid_y(J1);
            const double fy = y1 > y0 ? double(y - y0) / (y1 - y0) : 0.0;
            float* A = &result.airlight[3 * size_t(y) * W];
            const float* D = &result.depth[size_t(y) * W];
            own.clear();
            for (int x = 0; x < W; ++x) {
                const int I0 = std::min(x / s, Wc - 1), I1 = std::min(I0 + 1, Wc - 1);
                const int x0 = grid_x(I0), x1 = grid_x(I1);
                const double fx = x1 > x0 ? double(x - x0) / (x1 - x0) : 0.0;
                const int corner_x[4] = {x0, x1, x0, x1}, corner_y[4] = {y0, y0, y1, y1};
                const size_t cell[4] = {size_t(J0) * Wc + I0, size_t(J0) * Wc + I1, size_t(J1) * Wc + I0,
                                        size_t(J1) * Wc + I1};
                const double w[4] = {(1 - fx) * (1 - fy), fx * (1 - fy), (1 - fx) * fy, fx * fy};
                // The same surface: inverse depths (0 for the sky) on the corners' bilinear plane.
                double inv = 0.0;
                const bool sky = std::isinf(D[x]);
                bool mixed = false;
                for (int q = 0; q < 4; ++q) {
                    const float dq = result.depth[size_t(corner_y[q]) * W + corner_x[q]];
                    if (w[q] == 0.0) continue;
                    mixed = mixed || std::isinf(dq) != sky;
                    if (!std::isinf(dq)) inv += w[q] / dq;
                }
                bool smooth = !mixed && (sky || std::abs(inv - 1.0 / D[x]) <= kRefineDepthTol / D[x]);
                // And a ratio that varies across the cell by less than kRefineRatioTol of the
                // accuracy (where it varies more, as near a light's image, the pixel is its own).
                for (int c = 0; c < 3 && smooth; ++c) {
                    double lo = kInf, hi = -kInf;
                    for (int q = 0; q < 4; ++q) {
                        if (w[q] == 0.0) continue;
                        lo = std::min(lo, ratio[cell[q]][c]), hi = std::max(hi, ratio[cell[q]][c]);
                        smooth = smooth && delta[cell[q]][c] == 0.0;
                    }
                    // Fogshop's own value on the corners' bilinear surface (not across a spot's
                    // cone edge or a light's image; a pixel it leaves dark has no ratio).
                    double lin = 0.0;
                    for (int q = 0; q < 4; ++q) lin += w[q] * base[cell[q]][c];
                    const double own_value = A[3 * x + c];
                    smooth = smooth && hi - lo <= ratio_tol && own_value > 0.0 &&
                             std::abs(lin - own_value) <= ratio_tol * own_value;
                }
                if (!smooth) {
                    own.push_back(x);
                    continue;
                }
                for (int c = 0; c < 3; ++c) {
                    double r = 0.0, add = 0.0;
                    for (int q = 0; q < 4; ++q) r += w[q] * ratio[cell[q]][c], add += w[q] * delta[cell[q]][c];
                    A[3 * x + c] = float(std::max(0.0, A[3 * x + c] * r + add));
                }
            }
            if (own.empty()) continue;
            refine_row(y, scratch);
            for (size_t k = 0; k < own.size(); ++k)
                for (int c = 0; c < 3; ++c) A[3 * own[k] + c] = float(std::max(0.0, scratch.La[k][c]));
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
    result.stats.gaussian_pairs = static_cast<long long>(fog.refine_pairs());
    result.stats.gaussian_kept_bound = fog.refine_kept_bound();
    result.stats.gaussian_refined_pairs =
        fog.refiner() ? static_cast<long long>(fog.refiner()->plan().refined.size()) : 0;
    result.stats.gaussian_error_bound = fog.refine_error_bound();
    if (fog.has_shadows()) shadow_centres(ctx, fog);
    if (fog.refiner()) {
        // Over its budget the refinement stops and the frame keeps Fogshop's values throughout
        // (edges too), so that whether a frame is refined depends on its work alone.
        const std::vector<float> fogshop = result.airlight;
        const auto refine_start = Clock::now();
        refine_centres(ctx, fog);
        result.stats.seconds_refine = seconds_since(refine_start);
        result.stats.gaussian_refine_work = fog.refine_work_seconds();
        fog.close_refine_budget();
        if (fog.refine_abandoned()) {
            result.airlight = fogshop;
            result.stats.gaussian_refine_abandoned = true;
            result.stats.gaussian_error_bound = std::numeric_limits<double>::infinity();
        }
    }
    return end;
}

}  // namespace airlight
