// refine_pass.cpp: the Gaussian refinement of the splat's centre samples (passes.h).
//
// FogEvaluator::refine_gaussians refines a ray: a marched light's whole airlight, the exact
// terms of spot and sun pairs (gaussian/refine.h). A ray costs 0.1-1 ms with thousands of
// Gaussians, so the pass refines few of them and carries their ratio (refined / Fogshop, per
// channel) to the pixels between, where Fogshop's own value keeps the detail (a Gaussian's
// edge, the ground's slope): the ratio is Fogshop's error, which varies at the scale of the
// Gaussians and of the light's distance, not of a pixel. Cells of kCellSize pixels with a
// refined ray at each corner are checked at their centre and their edges' midpoints (the
// corners' bilinear ratio there against the refined rays, from a grid of every kCellSize / 2-th
// pixel at the first level). A cell that fails takes instead the biquadratic ratio through
// its nine samples where that meets the 16 samples a split would take next (the ratio curves
// where the ground runs through the cloud), else it splits, until it passes or is kMinCell
// pixels across, where a cell whose centre does not pass is refined whole. It splits in two
// across the one way its samples missed (the ground's band through the cloud curves the ratio
// along y alone) where Fogshop's values in it span at most kOneWaySpread (not a light's image),
// else in four. A cell that passes where its surface passes a Gaussian's centre (Fogshop's term
// changes form there: a band of its error narrower than the cell) must also pass at its
// quarters' centres; a cell's
// pixels must also see the corners' surface (inverse depth on their bilinear plane, or all
// the sky), else it splits, and at the smallest size the pixels that do not are refined
// alone. A frame that would exceed the refinement's budget stops early (foresight, below).
#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <functional>
#include <limits>
#include <mutex>
#include <numeric>
#include <unordered_map>
#include <vector>

#include "bake/passes.h"
#include "core/parallel.h"

namespace airlight {

namespace {

// The largest cells: kCellSize pixels, and at most kCellAngle radians across (about 4 degrees:
// a brush-sized Gaussian's image tens of metres away, the scale the ratio varies at). With the
// biquadratic, 64-pixel cells marched 18.8k rays on the 3000-Gaussian benchmark at 1 %, 1080p,
// with the centre's tolerance (below) at 0.5 (32: 22.8k; 128: 16.5k, its errors higher), and
// half as many at 5 %.
constexpr int kCellSize = 64;
constexpr double kCellAngle = 0.07;
constexpr int kMinCell = 2;
// The smallest cells a biquadratic ratio may fill (its quarter points apart from its nodes).
constexpr int kQuadraticCell = 4;
// The smallest cells probed where their surface cuts a Gaussian (cell).
constexpr int kProbeCell = 16;
// Cells split one way only (split_ways): where Fogshop's values span at most kOneWaySpread, and
// at most kMaxAspect times as long as they are wide. Without the spread's test a light's image,
// which peaks between the samples of a row, erred 7 % at p99 on the 3000-Gaussian benchmark at
// 5 % (2.3 % in four); with it, 1 % marches 12.7k -> 10.8k rays, the errors as they were.
constexpr double kOneWaySpread = 4.0;
constexpr int kMaxAspect = 4;
constexpr double kDepthTol = 0.01;
// The centre's test, in the asked accuracy: the bilinear ratio there within this of the refined
// ray. Measured on both benchmark clouds (bench_gaussian_accuracy.py, points and suns, 1080p):
// 0.5 marched 18.7k rays on the 3000-Gaussian one at 1 %, with a p99 error a third of the
// accuracy; 0.75 marches 12.7k, its p99 at most 0.66 of the accuracy at 5, 1 and 0.1 % on
// every one; 1.0 marches 9.2k, but at 5 % its centres passed cells whose other pixels erred
// more: p99 16.5 %.
constexpr double kRatioTol = 0.75;
// Pixels past the Gaussians share a ratio where the uniform fog between their depths is below
// this of the centre's test's tolerance (far_alike).
constexpr double kFarTol = 0.5;

// A pixel's Fogshop value (the splat's) and its refined one.
struct Sample {
    RGB base{0.0}, refined{0.0};
};

class CellRefiner {
  public:
    CellRefiner(BakeContext& ctx, const FogEvaluator& fog, const std::vector<float>& fogshop, int stride)
        : ctx_(ctx), fog_(fog), fogshop_(fogshop), tol_(kRatioTol * fog.refine_target()), stride_(stride),
          Wg_((ctx.W - 1 + stride - 1) / stride + 1), Hg_((ctx.H - 1 + stride - 1) / stride + 1) {}

    // The grid of every stride-th pixel (and the last row and column), refined a row at a time.
    int grid_width() const { return Wg_; }
    int grid_height() const { return Hg_; }
    int grid_x(int I) const { return std::min(I * stride_, ctx_.W - 1); }
    int grid_y(int J) const { return std::min(J * stride_, ctx_.H - 1); }
    void refine_grid(int threads, const std::function<void(int)>& progress) {
        grid_.resize(size_t(Wg_) * Hg_);
        run_parallel(Hg_, threads, [&](int J) {
            thread_local std::vector<int> xs;
            thread_local std::vector<Sample> out;
            xs.clear();
            for (int I = 0; I < Wg_; ++I) xs.push_back(grid_x(I));
            refine_row(grid_y(J), xs, out);
            std::copy(out.begin(), out.end(), grid_.begin() + std::ptrdiff_t(size_t(J) * Wg_));
        }, progress);
    }
    bool on_grid(int x, int y) const {
        return !grid_.empty() && (x % stride_ == 0 || x == ctx_.W - 1) && (y % stride_ == 0 || y == ctx_.H - 1);
    }
    // A refined pixel: from the grid where it is a grid point, else from the frame's samples so
    // far, else refined now (neighbouring cells share their edges' midpoints, and at the
    // smallest size their pixels: with samples kept per top-level cell, a tenth of the rays were
    // refined twice).
    Sample at(int x, int y) const {
        if (on_grid(x, y)) {
            const int I = x == ctx_.W - 1 ? Wg_ - 1 : x / stride_, J = y == ctx_.H - 1 ? Hg_ - 1 : y / stride_;
            return grid_[size_t(J) * Wg_ + I];
        }
        const std::uint64_t key = (std::uint64_t(std::uint32_t(y)) << 32) | std::uint32_t(x);
        Shard& shard = shards_[(key * 0x9E3779B97F4A7C15ull) >> (64 - kShardBits)];
        {
            const std::lock_guard<std::mutex> lock(shard.mutex);
            const auto it = shard.known.find(key);
            if (it != shard.known.end()) return it->second;
        }
        const Sample got = sample(x, y);  // (two threads may both refine it: the same value)
        const std::lock_guard<std::mutex> lock(shard.mutex);
        shard.known.emplace(key, got);
        return got;
    }
    // The pixels whose ratio came from a biquadratic (stats gaussian_quadratic_pixels).
    long long quadratic_pixels() const { return quadratic_pixels_.load(); }

    // Refines pixels xs of row y (out: their samples).
    void refine_row(int y, const std::vector<int>& xs, std::vector<Sample>& out) const {
        thread_local RowRays rr;
        thread_local std::vector<Ray> rays;
        thread_local std::vector<RGB> La;
        thread_local std::vector<float> depth, near;
        const int W = ctx_.W, n = int(xs.size());
        if (rr.dx.size() < size_t(n)) rr.resize(size_t(n));
        ctx_.pixel_rays(y, xs.data(), n, rr);  // (a row's rays cost 40x a sample's: few are sampled)
        rays.resize(size_t(n)), La.resize(size_t(n)), depth.resize(size_t(n)), near.resize(size_t(n));
        out.resize(size_t(n));
        for (int k = 0; k < n; ++k) {
            const int x = xs[k];
            rays[k].o = ctx_.eye;
            rays[k].d = Vec3(rr.dx[k], rr.dy[k], rr.dz[k]);
            out[k].base = base(x, y);
            La[k] = out[k].base;
            depth[k] = ctx_.result.depth[size_t(y) * W + x];
            near[k] = ctx_.near_clip ? rr.t_near[k] : 0.0f;
        }
        fog_.refine_gaussians(rays.data(), depth.data(), ctx_.near_clip ? near.data() : nullptr, n, La.data());
        for (int k = 0; k < n; ++k) out[k].refined = La[k];
    }

    Sample sample(int x, int y) const {
        thread_local std::vector<int> xs(1);
        thread_local std::vector<Sample> out;
        xs.assign(1, x);
        refine_row(y, xs, out);
        return out[0];
    }

    // The cell with corners (x0, y0) .. (x1, y1) and their samples c (00, 10, 01, 11); it owns
    // columns [x0, x1) and rows [y0, y1), and x1 / y1 too where _last_x_ / _last_y_.
    void cell(int x0, int y0, int x1, int y1, const Sample c[4], bool last_x, bool last_y) const {
        if (fog_.refine_abandoned()) return;
        const int xe = last_x ? x1 : x1 - 1, ye = last_y ? y1 : y1 - 1;
        if (dark(x0, y0, x1, y1, c)) {  // (as outside a spot's cone, or the sky beyond the fog)
            for (int y = y0; y <= ye; ++y)
                for (int x = x0; x <= xe; ++x) store(x, y, on_grid(x, y) ? at(x, y).refined : RGB(0.0));
            return;
        }
        const bool smallest = x1 - x0 <= kMinCell && y1 - y0 <= kMinCell;
        const bool surface = same_surface(x0, y0, x1, y1);
        const int xm = (x0 + x1) / 2, ym = (y0 + y1) / 2;
        // The centre and the edges' midpoints (e: top, bottom, left, right) against the corners.
        Sample m, e[4];
        if (!smallest) {
            m = at(xm, ym);
            const bool fit = surface && fits(x0, y0, x1, y1, c, xm, ym, m);
            // The ratio along x (the top and bottom edges' midpoints) and along y (the left and
            // right edges').
            bool along_x = surface, along_y = surface;
            if (x1 - x0 > kMinCell) {
                e[0] = at(xm, y0), e[1] = at(xm, y1);
                along_x = along_x && fits(x0, y0, x1, y1, c, xm, y0, e[0]) && fits(x0, y0, x1, y1, c, xm, y1, e[1]);
            }
            if (y1 - y0 > kMinCell) {
                e[2] = at(x0, ym), e[3] = at(x1, ym);
                along_y = along_y && fits(x0, y0, x1, y1, c, x0, ym, e[2]) && fits(x0, y0, x1, y1, c, x1, ym, e[3]);
            }
            // A cell that passes where its surface cuts a Gaussian (surface_cuts) is probed at
            // its quarters' centres too (where a split would sample next): Fogshop's error
            // there is a band narrower than the cell, which can pass between the five samples
            // above (6.4 % at 1 % on the ground of the 34-Gaussian benchmark).
            bool probed = true;
            if (fit && along_x && along_y && std::max(x1 - x0, y1 - y0) >= kProbeCell && surface_cuts(x0, y0, x1, y1))
                for (int k = 0; probed && k < 4; ++k) {
                    const int px = k % 2 ? (xm + x1) / 2 : (x0 + xm) / 2, py = k / 2 ? (ym + y1) / 2 : (y0 + ym) / 2;
                    probed = fits(x0, y0, x1, y1, c, px, py, at(px, py));
                }
            if (!(fit && along_x && along_y && probed)) {
                // The ratio curved across the cell (the ground's slope through the cloud): a
                // biquadratic through the nine samples, where it meets the 16 samples a split
                // would take next (quadratic_fits: no ray is spent if it fails).
                if (surface && x1 - x0 >= kQuadraticCell && y1 - y0 >= kQuadraticCell) {
                    const Nodes q = nodes(x0, y0, x1, y1, c, m, e);
                    if (quadratic_fits(q)) {
                        fill_quadratic(q, last_x, last_y);
                        return;
                    }
                }
                // In two across the one way whose samples missed, else in four (split_ways); the
                // centre against its row's and column's ends too (a light's image peaks there).
                if (x1 - x0 > kMinCell && y1 - y0 > kMinCell) {
                    const Sample row[4] = {e[2], e[3], e[2], e[3]}, column[4] = {e[0], e[0], e[1], e[1]};
                    along_x = along_x && fits(x0, ym, x1, ym, row, xm, ym, m);
                    along_y = along_y && fits(xm, y0, xm, y1, column, xm, ym, m);
                }
                bool across_x = true, across_y = true;
                split_ways(x0, y0, x1, y1, along_x, along_y, across_x, across_y);
                split(x0, y0, x1, y1, c, xm, ym, m, e, last_x, last_y, across_x, across_y);
                return;
            }
        }
        // At the smallest size a cell whose centre does not fit (a light's image) is refined
        // whole, as are the pixels off the corners' surface.
        bool alone = false;
        if (smallest) {
            if (x1 - x0 == kMinCell && y1 - y0 == kMinCell) {
                m = at(xm, ym);
                alone = !fits(x0, y0, x1, y1, c, xm, ym, m);
            } else {
                alone = true;  // (a cell one pixel across, at the image's edge)
            }
        }
        // Interpolated, but the samples' own pixels (and, at the smallest size, the pixels off
        // the corners' surface, refined alone).
        for (int y = y0; y <= ye; ++y)
            for (int x = x0; x <= xe; ++x) {
                RGB v;
                if ((x == x0 || x == x1) && (y == y0 || y == y1))
                    v = c[(x == x1 ? 1 : 0) + (y == y1 ? 2 : 0)].refined;
                else if (on_grid(x, y))
                    v = at(x, y).refined;
                else if (x == xm && y == ym && (!smallest || (x1 - x0 == kMinCell && y1 - y0 == kMinCell)))
                    v = m.refined;
                else if (!smallest && x == xm && (y == y0 || y == y1) && x1 - x0 > kMinCell)
                    v = e[y == y0 ? 0 : 1].refined;
                else if (!smallest && y == ym && (x == x0 || x == x1) && y1 - y0 > kMinCell)
                    v = e[x == x0 ? 2 : 3].refined;
                else if (alone || (!surface && !pixel_on_surface(x, y, x0, y0, x1, y1)))
                    v = at(x, y).refined;
                else {
                    bool unknown = false;
                    v = interpolate(x, y, x0, y0, x1, y1, c, &unknown);
                    if (unknown) v = at(x, y).refined;
                }
                store(x, y, v);
            }
    }

  private:
    // The samples off the grid, in shards by their pixel's hash.
    static constexpr int kShardBits = 6;
    struct Shard {
        std::mutex mutex;
        std::unordered_map<std::uint64_t, Sample> known;
    };

    void store(int x, int y, const RGB& v) const {
        float* A = &ctx_.result.airlight[3 * (size_t(y) * ctx_.W + x)];
        for (int ch = 0; ch < 3; ++ch) A[ch] = float(std::max(0.0, v[ch]));
    }

    static bool is_zero(const RGB& v) { return v.x == 0.0 && v.y == 0.0 && v.z == 0.0; }

    // No fog in the cell: none at its corners, refined or Fogshop's, nor Fogshop's at its pixels
    // and those around it (where Fogshop's fog ends, the exact fog may end a pixel away).
    bool dark(int x0, int y0, int x1, int y1, const Sample c[4]) const {
        for (int q = 0; q < 4; ++q)
            if (!is_zero(c[q].base) || !is_zero(c[q].refined)) return false;
        for (int y = std::max(0, y0 - 1); y <= std::min(ctx_.H - 1, y1 + 1); ++y)
            for (int x = std::max(0, x0 - 1); x <= std::min(ctx_.W - 1, x1 + 1); ++x)
                if (!is_zero(base(x, y))) return false;
        return true;
    }

    RGB base(int x, int y) const {
        const float* f = &fogshop_[3 * (size_t(y) * ctx_.W + x)];
        return RGB(f[0], f[1], f[2]);
    }

    static void weights(int x, int y, int x0, int y0, int x1, int y1, double w[4]) {
        const double fx = x1 > x0 ? double(x - x0) / (x1 - x0) : 0.0, fy = y1 > y0 ? double(y - y0) / (y1 - y0) : 0.0;
        w[0] = (1 - fx) * (1 - fy), w[1] = fx * (1 - fy), w[2] = (1 - fx) * fy, w[3] = fx * fy;
    }

    // Fogshop's value at (x, y) times the corners' bilinear ratio (per channel). A corner where
    // Fogshop is 0 and the refined value is not adds the refined value's bilinear part instead;
    // one where both are 0 (outside a spot's cone, in a shadow) tells nothing of the ratio, and
    // its weight goes to the others' (it was taken as ratio 0, which halved the pixels along a
    // cone's edge in the image). _unknown_ (optional): set where the pixel has fog of Fogshop's
    // but no corner gives a ratio or a value (the caller refines it).
    RGB interpolate(int x, int y, int x0, int y0, int x1, int y1, const Sample c[4], bool* unknown = nullptr) const {
        double w[4];
        weights(x, y, x0, y0, x1, y1, w);
        const RGB b = base(x, y);
        RGB v(0.0);
        if (unknown) *unknown = false;
        for (int ch = 0; ch < 3; ++ch) {
            double ratio = 0.0, add = 0.0, wr = 0.0, w_none = 0.0;
            for (int q = 0; q < 4; ++q) {
                if (c[q].base[ch] > 0.0) ratio += w[q] * c[q].refined[ch] / c[q].base[ch], wr += w[q];
                else if (c[q].refined[ch] > 0.0) add += w[q] * c[q].refined[ch];
                else w_none += w[q];
            }
            v[ch] = (wr > 0.0 ? b[ch] * ratio * (wr + w_none) / wr : 0.0) + add;
            if (unknown && b[ch] > 0.0 && (w_none > 0.0 || !(wr > 0.0 || add > 0.0))) *unknown = true;
        }
        return v;
    }

    // The refined centre _m_ against the corners' interpolation there.
    bool fits(int x0, int y0, int x1, int y1, const Sample c[4], int xm, int ym, const Sample& m) const {
        for (int ch = 0; ch < 3; ++ch) {
            bool dark = false, lit = false;
            for (int q = 0; q < 4; ++q) {
                if (!(c[q].base[ch] > 0.0) && c[q].refined[ch] > 0.0) return false;  // (no ratio there)
                (c[q].base[ch] > 0.0 ? lit : dark) = true;
            }
            // A dark corner beside a lit one: the edge of a spot's cone (or a shadow) crosses the
            // cell, where Fogshop's fog and the exact fog end a pixel apart.
            if (dark && lit) return false;
        }
        return close(interpolate(xm, ym, x0, y0, x1, y1, c), m.refined);
    }

    // An interpolated value _guess_ within the tolerance of the _refined_ one, every channel.
    bool close(const RGB& guess, const RGB& refined) const {
        for (int ch = 0; ch < 3; ++ch)
            if (!(std::abs(guess[ch] - refined[ch]) <= tol_ * refined[ch])) return false;
        return true;
    }

    // A cell's nine samples on its 3 x 3 grid (corners, edges' midpoints, centre): their
    // refined / Fogshop ratios, [row][col], and whether every one has Fogshop fog (a node
    // without it gives no ratio).
    struct Nodes {
        int x[3], y[3];
        RGB ratio[3][3];
        bool lit = true;
    };
    static Nodes nodes(int x0, int y0, int x1, int y1, const Sample c[4], const Sample& m, const Sample e[4]) {
        Nodes q{{x0, (x0 + x1) / 2, x1}, {y0, (y0 + y1) / 2, y1}, {}};
        const Sample* s[3][3] = {{&c[0], &e[0], &c[1]}, {&e[2], &m, &e[3]}, {&c[2], &e[1], &c[3]}};
        for (int r = 0; r < 3; ++r)
            for (int k = 0; k < 3; ++k)
                for (int ch = 0; ch < 3; ++ch) {
                    const Sample& n = *s[r][k];
                    q.lit = q.lit && n.base[ch] > 0.0;
                    q.ratio[r][k][ch] = n.base[ch] > 0.0 ? n.refined[ch] / n.base[ch] : 0.0;
                }
        return q;
    }
    // The quadratic Lagrange weights of nodes t[0..2] at t.
    static void lagrange(const int t[3], double at, double w[3]) {
        const double a = t[0], b = t[1], c = t[2];
        w[0] = (at - b) * (at - c) / ((a - b) * (a - c));
        w[1] = (at - a) * (at - c) / ((b - a) * (b - c));
        w[2] = (at - a) * (at - b) / ((c - a) * (c - b));
    }
    // Fogshop's value at (x, y) times the nodes' biquadratic ratio (per channel).
    RGB quadratic(const Nodes& q, int x, int y) const {
        double wx[3], wy[3];
        lagrange(q.x, x, wx), lagrange(q.y, y, wy);
        RGB ratio(0.0);
        for (int r = 0; r < 3; ++r)
            for (int k = 0; k < 3; ++k) ratio += (wy[r] * wx[k]) * q.ratio[r][k];
        return base(x, y) * ratio;
    }
    // The 5 x 5 grid of the cell's quarters: the nodes and, between them, the samples a split
    // would take next (its cells' centres and edges' midpoints).
    static void quarters(const Nodes& q, int g[5], int h[5]) {
        for (int k = 0; k < 3; ++k) g[2 * k] = q.x[k], h[2 * k] = q.y[k];
        for (int k = 0; k < 2; ++k) g[2 * k + 1] = (q.x[k] + q.x[k + 1]) / 2, h[2 * k + 1] = (q.y[k] + q.y[k + 1]) / 2;
    }
    // The biquadratic against the refined rays at the 16 quarter points between the nodes (a
    // split's next samples: none is spent if it fails); every node lit.
    bool quadratic_fits(const Nodes& q) const {
        if (!q.lit) return false;
        int g[5], h[5];
        quarters(q, g, h);
        for (int r = 0; r < 5; ++r)
            for (int k = 0; k < 5; ++k) {
                if (r % 2 == 0 && k % 2 == 0) continue;  // (a node)
                if (!close(quadratic(q, g[k], h[r]), at(g[k], h[r]).refined)) return false;
            }
        return true;
    }
    // The cell's pixels from the biquadratic, but the refined rays' own.
    void fill_quadratic(const Nodes& q, bool last_x, bool last_y) const {
        const int xe = last_x ? q.x[2] : q.x[2] - 1, ye = last_y ? q.y[2] : q.y[2] - 1;
        int g[5], h[5];
        quarters(q, g, h);
        long long filled = 0;
        for (int y = q.y[0]; y <= ye; ++y) {
            const bool row = std::find(h, h + 5, y) != h + 5;
            for (int x = q.x[0]; x <= xe; ++x) {
                const bool sampled = on_grid(x, y) || (row && std::find(g, g + 5, x) != g + 5);
                store(x, y, sampled ? at(x, y).refined : quadratic(q, x, y));
                filled += sampled ? 0 : 1;
            }
        }
        quadratic_pixels_.fetch_add(filled, std::memory_order_relaxed);
    }

    // Whether a cell whose samples missed splits across x (at xm) and across y: across the one
    // way alone where the samples along the other fit (_along_x_: the top and bottom edges'
    // midpoints and the centre on its row), Fogshop's values in the cell span at most
    // kOneWaySpread and the halves are at most kMaxAspect times as long as wide; else both.
    void split_ways(int x0, int y0, int x1, int y1, bool along_x, bool along_y, bool& across_x, bool& across_y) const {
        across_x = across_y = true;
        if (along_x == along_y || base_spread(x0, y0, x1, y1) > kOneWaySpread) return;
        if (along_x && x1 - x0 < kMaxAspect * (y1 - y0)) across_x = false;
        if (along_y && y1 - y0 < kMaxAspect * (x1 - x0)) across_y = false;
    }

    // Four cells about the centre m, or two where the cell is kMinCell across one way or is
    // split only across x (_across_x_: at xm) or y.
    void split(int x0, int y0, int x1, int y1, const Sample c[4], int xm, int ym, const Sample& m, const Sample e[4],
               bool last_x, bool last_y, bool across_x, bool across_y) const {
        const bool split_x = across_x && x1 - x0 > kMinCell, split_y = across_y && y1 - y0 > kMinCell;
        const Sample &top = e[0], &bottom = e[1], &left = e[2], &right = e[3];
        if (split_x && split_y) {
            const Sample q00[4] = {c[0], top, left, m}, q10[4] = {top, c[1], m, right};
            const Sample q01[4] = {left, m, c[2], bottom}, q11[4] = {m, right, bottom, c[3]};
            cell(x0, y0, xm, ym, q00, false, false);
            cell(xm, y0, x1, ym, q10, last_x, false);
            cell(x0, ym, xm, y1, q01, false, last_y);
            cell(xm, ym, x1, y1, q11, last_x, last_y);
        } else if (split_x) {
            const Sample l[4] = {c[0], top, c[2], bottom}, r[4] = {top, c[1], bottom, c[3]};
            cell(x0, y0, xm, y1, l, false, last_y);
            cell(xm, y0, x1, y1, r, last_x, last_y);
        } else {
            const Sample t[4] = {c[0], c[1], left, right}, b[4] = {left, right, c[2], c[3]};
            cell(x0, y0, x1, ym, t, last_x, false);
            cell(x0, ym, x1, y1, b, last_x, last_y);
        }
    }

    // The pixel sees the corners' surface: inverse depths (0 for the sky) on their bilinear
    // plane, or all of them lie past the Gaussians (far_alike).
    bool pixel_on_surface(int x, int y, int x0, int y0, int x1, int y1) const {
        const std::vector<float>& D = ctx_.result.depth;
        const int W = ctx_.W;
        double w[4];
        weights(x, y, x0, y0, x1, y1, w);
        const int cx[4] = {x0, x1, x0, x1}, cy[4] = {y0, y0, y1, y1};
        const float d = D[size_t(y) * W + x];
        const bool sky = std::isinf(d);
        double inv = 0.0, near = d, far = d;
        bool plane = true;
        for (int q = 0; q < 4; ++q) {
            const float dq = D[size_t(cy[q]) * W + cx[q]];
            if (w[q] == 0.0) continue;
            near = std::min(near, double(dq)), far = std::max(far, double(dq));
            if (std::isinf(dq) != sky) plane = false;
            if (!sky) inv += w[q] / dq;
        }
        if (plane && (sky || std::abs(inv - 1.0 / d) <= kDepthTol / d)) return true;
        return far_alike(x, y, near, far);
    }

    // Rays past the Gaussians (a distant ground and the sky at the horizon) differ only by the
    // uniform fog between their depths U, which moves the refined and the Fogshop values alike:
    // the ratio moves by at most ~|1 - ratio| U / Fogshop plus their difference on U. Where U's
    // bound is below kFarTol of the tolerance of the pixel's Fogshop value, the cell needs no
    // split there (the horizon's splits were 45 % of the refined rays of the 1080p benchmark).
    bool far_alike(int x, int y, double near, double far) const {
        if (!(near >= fog_.gaussians_end()) || !ctx_.affine) return false;
        const double base_sum = base(x, y).x + base(x, y).y + base(x, y).z;
        const Vec3 d = glm::normalize(ctx_.D0 + (x + 0.5) * ctx_.Dx + (y + 0.5) * ctx_.Dy);
        return fog_.uniform_fog_bound(d, near, far) <= kFarTol * tol_ * base_sum;
    }

    // The largest over the smallest of Fogshop's values (their sums over the channels) in the
    // cell; infinity where one is 0 and another not.
    double base_spread(int x0, int y0, int x1, int y1) const {
        double lo = std::numeric_limits<double>::infinity(), hi = 0.0;
        for (int y = y0; y <= y1; ++y)
            for (int x = x0; x <= x1; ++x) {
                const RGB b = base(x, y);
                const double v = b.x + b.y + b.z;
                lo = std::min(lo, v), hi = std::max(hi, v);
            }
        return hi > 0.0 ? hi / lo : 1.0;
    }

    // The cell's surface cuts a Gaussian (FogEvaluator::surface_cuts_gaussian: by its corners'
    // rays); with a camera whose rays do not share the eye, any cell.
    bool surface_cuts(int x0, int y0, int x1, int y1) const {
        if (!ctx_.affine) return true;
        const int cx[4] = {x0, x1, x0, x1}, cy[4] = {y0, y0, y1, y1};
        Vec3 d[4];
        double D[4];
        for (int q = 0; q < 4; ++q) {
            d[q] = glm::normalize(ctx_.D0 + (cx[q] + 0.5) * ctx_.Dx + (cy[q] + 0.5) * ctx_.Dy);
            D[q] = ctx_.result.depth[size_t(cy[q]) * ctx_.W + cx[q]];
        }
        return fog_.surface_cuts_gaussian(d, D);
    }

    bool same_surface(int x0, int y0, int x1, int y1) const {
        for (int y = y0; y <= y1; ++y)
            for (int x = x0; x <= x1; ++x)
                if (!pixel_on_surface(x, y, x0, y0, x1, y1)) return false;
        return true;
    }

    BakeContext& ctx_;
    const FogEvaluator& fog_;
    const std::vector<float>& fogshop_;
    const double tol_;
    const int stride_, Wg_, Hg_;
    std::vector<Sample> grid_;
    mutable std::atomic<long long> quadratic_pixels_{0};
    mutable std::array<Shard, std::size_t(1) << kShardBits> shards_;
};

}  // namespace

void refine_pass(BakeContext& ctx, const FogEvaluator& fog, const std::vector<float>& fogshop, double progress_begin,
                 double progress_end) {
    const int W = ctx.W, H = ctx.H;
    // The cells' size: kCellSize, halved while wider than kCellAngle at the image's centre; the
    // grid holds their corners, centres and edges' midpoints (every pixel below 2).
    const Vec3 centre = ctx.D0 + 0.5 * W * ctx.Dx + 0.5 * H * ctx.Dy;
    const double pixel_angle = glm::length(ctx.Dx) / glm::length(centre);
    int s = kCellSize;
    while (s > 1 && s * pixel_angle > kCellAngle) s /= 2;
    CellRefiner refiner(ctx, fog, fogshop, std::max(1, s / 2));
    s = std::max(s, 2);
    const int Wg = refiner.grid_width(), Hg = refiner.grid_height();
    // Foresight: an 8 x 5 spread of grid points first (results dropped); its work, scaled to
    // the grid and as much again for the cells' splits, stops a frame that would exceed the
    // budget before the grid is spent. The points go one at a time, in an order spread over the
    // image, and each call may do only what is left of the budget at that scale
    // (FogEvaluator::set_refine_scale), so the frame stops as soon as the work so far exceeds it:
    // the whole spread's could only be larger (a dense cloud's first ray can decide it).
    const int Wf = std::min(Wg, 8), Hf = std::min(Hg, 5), Nf = Wf * Hf;
    const double foresight_scale = 2.0 * double(Wg) * Hg / double(Nf);
    auto spread = [](int k, int n, int m) { return n > 1 ? int(std::lround(double(k) * (m - 1) / (n - 1))) : 0; };
    int step = 17;  // coprime with Nf: k -> k step mod Nf visits every point, far apart in turn
    while (std::gcd(step, Nf) != 1) ++step;
    fog.set_refine_scale(foresight_scale);
    parallel_for(Nf, ctx.n_threads, [&](int k) {
        if (fog.refine_abandoned()) return;
        const int q = int((long long)(k) * step % Nf);
        refiner.sample(refiner.grid_x(spread(q % Wf, Wf, Wg)), refiner.grid_y(spread(q / Wf, Hf, Hg)));
    });
    fog.set_refine_scale(1.0);
    fog.foresee_refine_work(foresight_scale);
    if (fog.refine_abandoned()) return;
    // Progress (and cancel): the grid to a third of the way, the cells the rest.
    auto reporter = [&](double begin, double end, int n) {
        return [&, begin, end, n](int done) {
            if (ctx.progress && !ctx.progress(begin + (end - begin) * done / std::max(1, n))) throw Cancelled();
        };
    };
    const double grid_end = progress_begin + (progress_end - progress_begin) / 3.0;
    refiner.refine_grid(ctx.n_threads, reporter(progress_begin, grid_end, Hg));
    if (fog.refine_abandoned()) return;
    // The cells (the last ones own the image's last column and row).
    const int cells_x = std::max(1, (W - 1 + s - 1) / s), cells_y = std::max(1, (H - 1 + s - 1) / s);
    run_parallel(cells_x * cells_y, ctx.n_threads, [&](int k) {
        const int I = k % cells_x, J = k / cells_x;
        const int x0 = std::min(I * s, W - 1), x1 = std::min((I + 1) * s, W - 1);
        const int y0 = std::min(J * s, H - 1), y1 = std::min((J + 1) * s, H - 1);
        const Sample c[4] = {refiner.at(x0, y0), refiner.at(x1, y0), refiner.at(x0, y1), refiner.at(x1, y1)};
        refiner.cell(x0, y0, x1, y1, c, I + 1 == cells_x, J + 1 == cells_y);
    }, reporter(grid_end, progress_end, cells_x * cells_y));
    ctx.result.stats.gaussian_quadratic_pixels = refiner.quadratic_pixels();
}

}  // namespace airlight
