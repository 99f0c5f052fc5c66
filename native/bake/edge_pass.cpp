// edge_pass.cpp: the edge pixels supersampled through the render's pixel filter (passes.h).
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <limits>
#include <vector>

#include "core/buffers.h"
#include "bake/edge_clusters.h"
#include "bake/passes.h"
#include "core/parallel.h"

namespace airlight {

namespace {

// Rays to evaluate (segments [t0, t]) and their fog; _P_ their G per-light passes, ray-major.
struct RayBatch {
    std::vector<Ray> ray;
    std::vector<float> t, t0;
    std::vector<double> Tr;
    std::vector<RGB> La, P;
    void resize(size_t n, int G) {
        ray.resize(n), t.resize(n), t0.resize(n), Tr.resize(n), La.resize(n), P.resize(n * size_t(G));
    }
};

// Scratch from a pool (ScratchPool): the sub-pixel rays and results of a run of edge pixels
// (~3 MB for two rows of them).
struct EdgeScratch {
    std::vector<Ray> sub;
    std::vector<glm::dvec2> sub_film;  // the sub-samples' film positions
    std::vector<float> sub_t, sub_t0;
    std::vector<double> sub_Tr;
    std::vector<RGB> sub_La;
    std::vector<RGB> sub_P, pixel_P;  // the sub-samples' per-light passes (ray-major), a pixel's sums
    std::vector<int> edge_px;
    // Edge clusters (edge_sample_clusters): per row, sample order and cluster ends
    // per pixel, and one representative ray per cluster.
    std::vector<int> cl_order, cl_ends, cl_first;
    RayBatch cl;
    std::vector<unsigned char> cl_refined;
    std::vector<int> ref_k;  // samples of refined clusters (into sub)
    RayBatch ref;
    CastScratch cast_scratch;
};

}  // namespace

void edge_pass(BakeContext& ctx, const FogEvaluator& fog, const EdgePixels& found, double progress_begin) {
    const SceneDescription& scene = ctx.scene;
    const BakeSettings& settings = ctx.settings;
    const ProgressFn& progress = ctx.progress;
    const CameraRays& rays = ctx.rays;
    const int W = ctx.W, H = ctx.H, n_threads = ctx.n_threads;
    const bool near_clip = ctx.near_clip;
    BakeResult& result = ctx.result;
    const std::vector<std::vector<std::pair<int, int>>>& band_edges = found.per_band;
    const double edges_begin = progress_begin;
    const bool supersample = settings.aa_samples > 1 && settings.filter_width > 0.0;
    const int n_aa = supersample ? settings.aa_samples : 1;
    const std::vector<glm::dvec2> pattern = filter_pattern(n_aa, settings.filter_width);
    // Fog of _n_ rays from the near plane (t0, from cast) to _depth_ (from the origin, inf:
    // none), as Cycles integrates it (FogEvaluator::eval_many).
    // _P_: their per-light passes (G per ray).
    const int G = fog.light_passes();
    auto eval = [&](const Ray* r, const float* depth, const float* t0, int n, double* Tr, RGB* La, RGB* P,
                    const glm::dvec2* film = nullptr) {
        fog.eval_many(r, depth, near_clip ? t0 : nullptr, n, Tr, La, film, G ? P : nullptr);
    };
    std::atomic<long long> supersampled{0}, samples{0}, edge_ns{0};
    // Edge pixels: one fog evaluation per cluster of sub-samples (edge_sample_clusters), or
    // per sub-sample (edge_cluster_tol = 0: the reference; and with spot lights, whose cone
    // edge makes the fog a kinked function of the ray: the mean ray erred by up to 40 % of
    // the spot's airlight on such pixels).
    // (Volumetric shadows too: a shadow's edge on the surface makes the fog a kinked function
    // of the sample's ray as a spot's cone does. Measured: clustering where the samples cross
    // the same shadow-volume faces still evaluated 55 % of the street's edge samples one by
    // one, and cost more than it saved.)
    const bool clustered =
        supersample && settings.edge_cluster_tol > 0.0 && scene.spot_lights.empty() && !fog.has_shadows();
    const double cluster_tol = settings.edge_cluster_tol;
    const double sigma_bg = scene.medium.sigma_t;  // the background extinction (Gaussians' too)
    // Airlight and transmittance error estimates above which a cluster's samples are
    // evaluated one by one (EdgeClusterBounds).
    constexpr double kEdgeAirlightTol = 5e-4, kEdgeTransmittanceTol = 5e-4;
    const EdgeClusterBounds bounds(scene, clustered ? fog.gaussian_medium() : nullptr);
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
    // Per edge pixel: airlight, transmittance, then its G passes (3 each).
    const size_t stride = 4 + 3 * size_t(G);
    std::vector<float> edge_out(stride * edge_i.size());
    run_parallel(
        int(edge_runs.size()), n_threads,
        [&](int run) {
            static ScratchPool<EdgeScratch> edge_pool;
            ScratchPool<EdgeScratch>::Lease lease(edge_pool);
            EdgeScratch& bs = *lease;
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
            long long band_supersampled = 0, band_samples = 0;
            // Results go to edge_out (4 floats per edge pixel: airlight, transmittance) and
            // into the images after the pass: the images keep the centre samples meanwhile,
            // which the hits == 0 fallback below reads.
            float* out = &edge_out[stride * size_t(er.first)];
            // The sub-pixel rays of all the run's pixels at once: cast as packets and
            // evaluated in full SIMD chunks, then averaged per pixel.
            const auto edge_start = Clock::now();
            const size_t m = edge_px.size() * n_sub;
            sub.resize(m);
            sub_t.resize(m);
            sub_t0.resize(m);
            sub_Tr.resize(m);
            sub_La.resize(m);
            bs.sub_P.resize(m * size_t(G));
            bs.pixel_P.resize(size_t(G));
            bs.sub_film.resize(m);
            for (size_t e = 0; e < edge_px.size(); ++e)
                for (size_t k = 0; k < n_sub; ++k) {
                    const glm::dvec2 f(edge_px[e] + 0.5 + pattern[k].x, j + 0.5 + pattern[k].y);
                    bs.sub_film[e * n_sub + k] = f;
                    sub[e * n_sub + k] = rays(f.x, f.y);
                }
            ctx.cast(sub.data(), int(m), sub_t.data(), sub_t0.data(), cast_scratch);
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
                bs.cl.resize(n_cl, G);
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
                eval(bs.cl.ray.data(), bs.cl.t.data(), bs.cl.t0.data(), int(n_cl), bs.cl.Tr.data(),
                         bs.cl.La.data(), bs.cl.P.data());
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
                    bs.ref.resize(n_ref, G);
                    for (size_t q = 0; q < n_ref; ++q) {
                        bs.ref.ray[q] = sub[bs.ref_k[q]];
                        bs.ref.t[q] = sub_t[bs.ref_k[q]];
                        bs.ref.t0[q] = sub_t0[bs.ref_k[q]];
                    }
                    eval(bs.ref.ray.data(), bs.ref.t.data(), bs.ref.t0.data(), int(n_ref), bs.ref.Tr.data(),
                             bs.ref.La.data(), bs.ref.P.data());
                    for (size_t q = 0; q < n_ref; ++q) {
                        sub_Tr[bs.ref_k[q]] = bs.ref.Tr[q];
                        sub_La[bs.ref_k[q]] = bs.ref.La[q];
                        for (int g = 0; g < G; ++g)
                            bs.sub_P[size_t(bs.ref_k[q]) * G + g] = bs.ref.P[q * G + g];
                    }
                }
                band_samples += (long long)(n_cl + bs.ref_k.size()) - (long long)edge_px.size();
            } else {
                // (with shadows: their crossings rasterized at the sub-samples' film positions)
                eval(sub.data(), sub_t.data(), sub_t0.data(), int(m), sub_Tr.data(), sub_La.data(), bs.sub_P.data(),
                     bs.sub_film.data());
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
                std::vector<RGB>& P = bs.pixel_P;
                std::fill(P.begin(), P.end(), RGB(0.0));
                // Adds _count_ times the passes at _from_ to the pixel's.
                auto add_passes = [&](const RGB* from, double count) {
                    for (int g = 0; g < G; ++g) P[size_t(g)] += count * from[g];
                };
                if (!clustered) {
                    for (size_t k = s0; k < s0 + n_sub; ++k) {
                        Tr_all += sub_Tr[k];
                        La += sub_La[k];
                        add_passes(bs.sub_P.data() + k * G, 1.0);
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
                                add_passes(bs.sub_P.data() + k * G, 1.0);
                                if (!std::isinf(sub_t[k])) Tr_hits += sub_Tr[k], ++hits;
                            }
                            continue;
                        }
                        La += double(end - b) * bs.cl.La[c];
                        add_passes(bs.cl.P.data() + size_t(c) * G, double(end - b));
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
                float* o = out + stride * e;
                for (int c = 0; c < 3; ++c) o[c] = float(La[c]);
                o[3] = float(Tr);
                for (int g = 0; g < G; ++g)
                    for (int c = 0; c < 3; ++c) o[4 + 3 * g + c] = float(P[size_t(g)][c] / double(n_sub));
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
            const float* v = &edge_out[stride * size_t(er.first + e)];
            for (int c = 0; c < 3; ++c) {
                result.airlight[3 * p + c] = v[c];
                result.transmittance[3 * p + c] = v[3];
            }
            for (int g = 0; g < G; ++g)
                for (int c = 0; c < 3; ++c) result.light_airlight[3 * (size_t(g) * ctx.n_pixels + p) + c] = v[4 + 3 * g + c];
        }
    result.stats.supersampled_pixels = supersampled;
    result.stats.seconds_edges = 1e-9 * double(edge_ns);
    result.stats.samples += samples;
}

}  // namespace airlight
