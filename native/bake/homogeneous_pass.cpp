// homogeneous_pass.cpp: the homogeneous fog at every pixel centre (passes.h), exactly or on
// a lattice, and the edge pixels for the edge pass.
#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>
#include <vector>

#include "core/buffers.h"
#include "bake/passes.h"
#include "core/constants.h"
#include "core/parallel.h"

namespace airlight {

namespace {


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
constexpr double kLatticeTol = 5e-4;

// The lattice's set-up: its spacing (0: off), the light directions whose images it keeps
// exact and the cosine of the cone about them.
struct Lattice {
    int s = 0;
    std::vector<Vec3> light_dirs;
    double cos_ex = 1.0;
};

Lattice plan_lattice(const BakeContext& ctx, const FogEvaluator& fog) {
    const SceneDescription& scene = ctx.scene;
    const int W = ctx.W, H = ctx.H;
    const Vec3 eye = ctx.eye, forward = ctx.forward, D0 = ctx.D0, Dx = ctx.Dx, Dy = ctx.Dy;
    Lattice out;
    const int lattice = ctx.settings.homogeneous_resolution;
    // (Not with volumetric shadows: a shaft's edge crosses cells that pass the smoothness tests.)
    const bool use_lattice = lattice > 1 && ctx.affine && fog.soa() && !fog.has_spots() && !fog.has_shadows() &&
                             fog.light_passes() == 0;
    std::vector<Vec3>& light_dirs = out.light_dirs;
    double& cos_ex = out.cos_ex;
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
    if (use_lattice) out.s = lattice;
    return out;
}

struct LatticeScratch {
    std::vector<RowRays> rows;  // rays of rows j0 .. min(j1, H - 1)
    std::vector<double> dx, dy, dz;
    std::vector<float> Dvp, t0, Tr, rgb, nodes, centres;
    std::vector<int> pi, pj;
    std::vector<unsigned char> exact;
};

// Airlight and transmittance of rows [j0, j1) of a band; _kink_ as edge_rows left it.
void lattice_band(const BakeContext& ctx, const FogEvaluator& fog, const Lattice& lat, int j0, int j1,
                  const std::vector<unsigned char>& kink, LatticeScratch& ls) {
    const int W = ctx.W, H = ctx.H, lattice = lat.s;
    const bool near_clip = ctx.near_clip;
    const std::vector<Vec3>& light_dirs = lat.light_dirs;
    const double cos_ex = lat.cos_ex;
    BakeResult& result = ctx.result;
    const int s = lattice;
    const int j_last = std::min(H - 1, j1);  // the node row below the band is needed too
    const int n_rows = j_last - j0 + 1;
    if (int(ls.rows.size()) < n_rows) ls.rows.resize(size_t(n_rows));
    for (int r = 0; r < n_rows; ++r) {
        if (ls.rows[r].dx.size() != size_t(W)) ls.rows[r].resize(size_t(W));
        ctx.row_rays(j0 + r, ls.rows[r], false);
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
}

// Scratch of one band, from a pool (ScratchPool): its rows' rays and results.
struct CentreScratch {
    std::vector<Ray> row;
    std::vector<float> t0, row_Tr;
    std::vector<double> row_Tr_d;
    std::vector<RGB> row_La;
    std::vector<float> row_passes;   // the per-light passes of a row, ray-major (eval_soa)
    std::vector<RGB> row_passes_d;   // (eval_many)
    std::vector<unsigned char> kink, edge;
    RowRays r;
    std::vector<glm::dvec2> film;  // the row's pixel centres (the shadows rasterize there)
};

}  // namespace

EdgePixels homogeneous_pass(BakeContext& ctx, const FogEvaluator& fog, const EdgeMap& edges, bool splatted,
                            double progress_begin, double progress_end) {
    const int W = ctx.W, H = ctx.H, n_bands = ctx.n_bands, n_threads = ctx.n_threads;
    const CameraRays& rays = ctx.rays;
    const bool affine = ctx.affine, near_clip = ctx.near_clip;
    const bool supersample = ctx.settings.aa_samples > 1 && ctx.settings.filter_width > 0.0;
    BakeResult& result = ctx.result;
    const Lattice lat = plan_lattice(ctx, fog);
    const bool use_lattice = lat.s > 1;
    std::atomic<long long> samples{0};
    // Per band, its edge pixels (row, column) for the edge pass.

    EdgePixels found(static_cast<size_t>(n_bands));
    std::vector<std::vector<std::pair<int, int>>>& band_edges = found.per_band;
    run_parallel(
        n_bands, n_threads,
        [&](int band) {
            static ScratchPool<CentreScratch> band_pool;
            ScratchPool<CentreScratch>::Lease lease(band_pool);
            CentreScratch& bs = *lease;
            std::vector<float>& t0 = bs.t0;
            t0.resize(W);
            std::vector<unsigned char>&kink = bs.kink, &edge = bs.edge;
            const int j0 = band * kBandRows, j1 = std::min(H, (band + 1) * kBandRows);
            if (supersample || use_lattice) edges.rows(j0, j1, kink, edge);
            if (use_lattice) {  // ~1.5 MB of scratch per band
                static ScratchPool<LatticeScratch> lattice_pool;
                ScratchPool<LatticeScratch>::Lease lease(lattice_pool);
                lattice_band(ctx, fog, lat, j0, j1, kink, *lease);
            }
            long long band_samples = 0;
            const bool fast = affine && fog.soa();
            RowRays& r = bs.r;
            std::vector<Ray>& row = bs.row;
            std::vector<double>& row_Tr_d = bs.row_Tr_d;
            std::vector<RGB>& row_La = bs.row_La;
            std::vector<float>& row_Tr = bs.row_Tr;
            row_Tr.resize(W);
            const int G = fog.light_passes();
            if (fast) {
                r.resize(W);
                bs.row_passes.resize(3 * size_t(G) * W);
            } else {
                row.resize(W);
                row_Tr_d.resize(W);
                row_La.resize(W);
                bs.row_passes_d.resize(size_t(G) * W);
            }
            // Row j's passes into the pass images (from ray-major pass g of pixel i at [i G + g]).
            auto put_passes = [&](size_t p0, auto value) {
                for (int g = 0; g < G; ++g) {
                    float* P = &result.light_airlight[3 * (size_t(g) * ctx.n_pixels + p0)];
                    for (int i = 0; i < W; ++i)
                        for (int c = 0; c < 3; ++c) P[3 * i + c] = value(size_t(i) * G + g, c);
                }
            };
            for (int j = j0; j < j1; ++j) {
                // Centre samples of the whole row (edge pixels are overwritten below).
                const size_t p0 = size_t(j) * W;
                const float* depth = &result.depth[p0];
                float* A = &result.airlight[3 * p0];
                float* T = &result.transmittance[3 * p0];
                if (splatted || use_lattice) {
                    // Already written by the splat or the lattice.
                } else if (fast) {
                    ctx.row_rays(j, r, false);
                    bs.film.resize(W);
                    for (int i = 0; i < W; ++i) bs.film[i] = {i + 0.5, j + 0.5};
                    fog.eval_soa(r.dx.data(), r.dy.data(), r.dz.data(), depth, near_clip ? r.t_near.data() : nullptr,
                                 W, row_Tr.data(), A, bs.film.data(), G ? bs.row_passes.data() : nullptr);
                    put_passes(p0, [&](size_t q, int c) { return bs.row_passes[3 * q + c]; });
                } else {
                    for (int i = 0; i < W; ++i) {
                        row[i] = rays(i + 0.5, j + 0.5);
                        double t_near = 0.0, t_far;
                        if (near_clip) rays.clip_range(row[i], t_near, t_far);
                        t0[i] = float(t_near);
                    }
                    bs.film.resize(W);
                    for (int i = 0; i < W; ++i) bs.film[i] = {i + 0.5, j + 0.5};
                    fog.eval_many(row.data(), depth, near_clip ? t0.data() : nullptr, W, row_Tr_d.data(), row_La.data(),
                                  bs.film.data(), G ? bs.row_passes_d.data() : nullptr);
                    for (int i = 0; i < W; ++i) {
                        row_Tr[i] = float(row_Tr_d[i]);
                        for (int c = 0; c < 3; ++c) A[3 * i + c] = float(row_La[i][c]);
                    }
                    put_passes(p0, [&](size_t q, int c) { return float(bs.row_passes_d[q][c]); });
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
        ctx.reporter(progress_begin, progress_end));
    ctx.result.stats.samples += samples;
    return found;
}

}  // namespace airlight
