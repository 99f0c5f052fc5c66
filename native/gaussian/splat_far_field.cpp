// splat_far_field.cpp: the far-field grids of the reduced resolution (GaussianSplat::bin
// given the depth; plain path, no noise). The Dvp = inf terms of a broad Gaussian in front of
// the surface are a smooth function of the film position alone, the same in every tile:
// evaluated once on an image-wide grid of spacing h >= 2 s pixels (nine levels, spacings
// 2 s .. 32 s in steps of ~1.41; blocks of 8 x 8 nodes, each with the Gaussians whose cull
// cones meet it, Gaussian-major as the tile lattices) instead of on the lattice of each tile
// it lies in front of, ~(8 sigma / h)^2 evaluations per Gaussian instead of ~25 per tile.
// Each tile interpolates the grids to its lattice nodes with tensor cubic Lagrange weights
// (splat_interp.h: add_far_grid). A Gaussian goes on the coarsest level whose spacing keeps
// the cubic's error at tau (h <= 0.28 (tau / 1e-3)^(1/4) sigma, sigma its angular standard
// deviation 1 / (sqrt 2 a d) in pixels shrunk by 1 + k0; every light at least
// 6 (1e-3 / tau)^(1/4) h pixels' angle times d away; tau = 1e-3 at quarter, 1e-3 / 16 at
// half), that passes the lattice's own light criterion (light_far_) and lies wholly before
// the eye's plane and the near clip ball, where that costs fewer evaluations than its tiles'
// lattices would. A tile reads a level's grid only when that saves evaluations; there a
// Gaussian not wholly in front has its own grid share (far_share) subtracted on the blocks
// behind and replaced by its exact terms on the blocks it cuts (splat_reduced.cpp).
// (tests: GaussianSplat.FarFieldGridsAgainstFull; bench_rbf.py's errors against full.)
#include "gaussian/splat.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <vector>

#include "gaussian/splat_interp.h"

namespace airlight {

using namespace splat;

bool GaussianSplat::far_candidates(const float* depth, const std::vector<int>& rect, FarScratch& far) {
    const std::size_t n = g_.size();
    const int n_tiles = num_tiles();
    far_grids_.clear();
    level_.assign(step_ > 1 ? n : 0, 0);
    tile_far_.assign(step_ > 1 ? std::size_t(n_tiles) : 0, 0);
    tile_far_pairs_.clear();
    splat_end_.clear();
    far_gaussians_ = far_nodes_ = 0;
    if (step_ == 1 || !depth || !plain_ || noise_.on() || n == 0) return false;
    const double f = glm::dot(D0_, forward_);
    const double pix = f > 0.0 ? std::max(glm::length(Dx_), glm::length(Dy_)) / f : 0.0;
    if (!(pix > 0.0)) return false;
    // The level criteria (see the top of the file): the cubic's error at the lattice's tau at
    // quarter resolution; at half a quarter of the lattice's (1e-3 / 16), so that half keeps
    // its max error against full at 0.1 % (bench_rbf.py's transmittance: 0.099 %; 0.101 % at
    // 1e-3 / 8, 0.109 % at the lattice's 1e-3 / 4).
    const double tau = step_ == 4 ? 1e-3 : 1e-3 / 16.0;
    const double cv = 0.28 * std::pow(tau / 1e-3, 0.25), cl = 6.0 * std::pow(1e-3 / tau, 0.25);
    const double q0_len = glm::length(q0_);
    std::vector<unsigned char>& cand = far.cand;
    cand.assign(n, 0);
    bool any = false;
    for (std::size_t i = 0; i < n; ++i) {
        const GaussF& g = g_[i];
        if (!light_far_[i] || g.near || !(g.radius > 0.0) || medium_.amplitude(i) == 0.0) continue;
        const int* r = &rect[4 * i];
        if (r[1] < r[0] || r[3] < r[2]) continue;
        const Vec3 c = medium_.centre(i) - eye_;
        if (!(glm::dot(q0_, c) > g.radius * q0_len * (1.0 + 1e-6))) continue;  // wholly before the eye's plane
        // (exp(-T_i(v, b^r)) on the light side adds a narrower bump of relative size k0 = half
        // the peak optical depth: the cubic's error grows by ~(1 + 4 k0), as from sigma / (1 + k0))
        const double sigma = 1.0 / (std::sqrt(2.0) * medium_.scale(i) * g.dist) / (1.0 + double(g.k0));
        double clearance = std::numeric_limits<double>::infinity();
        for (const Vec3& s : lights_) clearance = std::min(clearance, glm::length(medium_.centre(i) - s) - g.radius);
        for (int k = kMaxFarLevel; k >= 1; --k) {
            const double hw = double(step_ * kFarSpacing[k - 1]) * pix;
            if (hw <= cv * sigma && clearance >= cl * hw * g.dist) {
                cand[i] = (unsigned char)k;
                any = true;
                break;
            }
        }
    }
    if (!any) return false;
    // Each tile's depth range, and per candidate its depth interval, for the fill's counts of
    // its tiles in front / behind / cut (splat_tile_reduced's test by depth range; a cost
    // estimate only).
    std::vector<float>&tmin = far.tmin, &tmax = far.tmax;
    tmin.resize(n_tiles);
    tmax.resize(n_tiles);
    parallel_chunks(std::size_t(n_tiles), threads_, 64, [&](std::size_t tb, std::size_t te) {
        for (std::size_t t = tb; t < te; ++t) {
            const int x0 = int(t) % tiles_x_ * kTile, y0 = int(t) / tiles_x_ * kTile;
            const int x1 = std::min(W_, x0 + kTile), y1 = std::min(H_, y0 + kTile);
            float lo = std::numeric_limits<float>::infinity(), hi = 0.0f;
            for (int j = y0; j < y1; ++j)
                for (int i = x0; i < x1; ++i) {
                    const float d = depth[std::size_t(j) * W_ + i];
                    lo = std::min(lo, d);
                    hi = std::max(hi, d);
                }
            tmin[t] = lo;
            tmax[t] = hi;
        }
    });
    far.span.assign(2 * n, 0.0f);
    for (std::size_t i = 0; i < n; ++i)
        if (cand[i]) {
            far.span[2 * i] = float(g_[i].dist - g_[i].radius);
            far.span[2 * i + 1] = float(g_[i].dist + g_[i].radius);
        }
    far.counts.reset(new std::atomic<std::uint32_t>[3 * n]());
    return true;
}

// build_far_field's steps on the candidates of far_candidates (far).
struct GaussianSplat::FarBuild {
    static constexpr int kBlock = 8;  // grid blocks of kBlock x kBlock nodes
    GaussianSplat& gs;
    const std::vector<int>& rect;
    FarScratch& far;
    std::vector<std::uint32_t> far_list;  // the Gaussians on grids
    unsigned used = 0;                    // bit k - 1: level k has Gaussians
    // Per level: the grid blocks some tile reading the level reaches.
    std::vector<std::vector<char>> block_needed = std::vector<std::vector<char>>(kMaxFarLevel);
    // The grid blocks (level k, node rectangle), each with the list of its level's Gaussians
    // whose cull cones meet its rays; unit_base[k - 1]: level k's first.
    struct Unit {
        int k, P0, Q0, P1, Q1;
        std::vector<std::uint32_t> list;
    };
    std::vector<Unit> units;
    std::vector<int> unit_base = std::vector<int>(kMaxFarLevel + 1, 0);

    FarBuild(GaussianSplat& splat, const std::vector<int>& rect_, FarScratch& far_)
        : gs(splat), rect(rect_), far(far_) {}
    // Grid sizes: the tile lattices' nodes lie at film x in [0, kTile tiles_x_], whose cubic
    // stencils reach nodes P = x / h .. x / h + 3.
    void grid_dims(int k, int& h, int& nx, int& ny) const {
        h = gs.step_ * kFarSpacing[k - 1];
        nx = kTile * gs.tiles_x_ / h + 5;
        ny = kTile * gs.tiles_y_ / h + 5;
    }
    // Node rectangle of Gaussian i at level k: the stencils of its tile rectangle's lattices
    // (it is evaluated on the blocks of it whose rays meet its cull cone, list_gaussians).
    void node_range(std::size_t i, int k, int& P0, int& P1, int& Q0, int& Q1) const {
        int h, nx, ny;
        grid_dims(k, h, nx, ny);
        const int* r = &rect[4 * i];
        P0 = kTile * r[0] / h;
        P1 = std::min(nx - 1, kTile * (r[1] + 1) / h + 3);
        Q0 = kTile * r[2] / h;
        Q1 = std::min(ny - 1, kTile * (r[3] + 1) / h + 3);
    }
    bool choose_gaussians();
    void move_front_pairs();
    void mark_needed_blocks();
    void init_grids();
    void list_gaussians();
    void evaluate();
};

// Which candidates go on their grid (level_, far_list, used): those whose grid evaluations
// cost less than their tiles' lattices would. False (level_ cleared): the grids would save
// fewer than ~1e5 evaluations, not worth their fixed costs (their nodes' directions, the
// blocks' lists, a pass over the tiles; ~1 ms against ~0.3 ms saved).
bool GaussianSplat::FarBuild::choose_gaussians() {
    const std::size_t n = gs.g_.size();
    const std::vector<unsigned char>& cand = far.cand;
    double saved = 0.0;
    for (std::size_t i = 0; i < n; ++i) {
        if (!cand[i]) continue;
        const std::size_t front = far.counts[3 * i], behind = far.counts[3 * i + 1], cut = far.counts[3 * i + 2];
        int P0, P1, Q0, Q1;
        node_range(i, cand[i], P0, P1, Q0, Q1);
        // Evaluations: the grid's nodes near the cone (~0.8 of the rectangle), and a
        // share where tiles using the grid cancel it (behind) or replace it (cut), against
        // the lattice (or coarse lattice) of each tile it lies in front of.
        const double global = 0.8 * double(P1 - P0 + 1) * double(Q1 - Q0 + 1) + 8.0 * double(behind + cut);
        const double local = double(front) * double(gs.lattice_evals(i));
        if (global < local) {
            gs.level_[i] = cand[i];
            used |= 1u << (cand[i] - 1);
            far_list.push_back(std::uint32_t(i));
            saved += local - global;
        }
    }
    if (saved < 1e5) {
        std::fill(gs.level_.begin(), gs.level_.end(), 0);
        return false;
    }
    return true;
}

// Per tile: which grids it reads (they save more evaluations than cancelling costs: its
// Gaussians of that level wholly in front, by the depth range, cost nothing there; each
// one wholly behind costs its share, ~36 nodes at quarter, to cancel, as does each one
// the surface cuts, to replace it by its exact terms on the blocks it cuts). The pairs
// wholly in front on a grid the tile reads then move to the end of its list, past
// splat_end_: the splat does not walk them (at 3000 x 1, ~1.3 M of its ~2.1 M pairs).
// eval_rays still gathers from the whole list: an edge sub-sample may end nearer.
// (the pass reads all the pairs, ~2.1 M at 3000 x 1: per Gaussian its far reach and
// evaluations in compact arrays, integer sums)
void GaussianSplat::FarBuild::move_front_pairs() {
    const std::size_t n = gs.g_.size();
    const int n_tiles = gs.num_tiles();
    const std::vector<float>& tmin = far.tmin;
    gs.tile_far_pairs_.assign(std::size_t(n_tiles), 0);
    gs.splat_end_.assign(gs.bin_start_.begin() + 1, gs.bin_start_.end());
    std::vector<double> reach(n, 0.0);
    std::vector<std::uint32_t> lattice_cost(n, 0);
    for (std::uint32_t i : far_list) {
        reach[i] = gs.g_[i].dist + gs.g_[i].radius;
        lattice_cost[i] = std::uint32_t(gs.lattice_evals(i));
    }
    parallel_chunks(std::size_t(n_tiles), gs.threads_, 256, [&](std::size_t tb, std::size_t te) {
        std::vector<std::uint32_t> moved;
        for (std::size_t t = tb; t < te; ++t) {
            const std::uint32_t e0 = gs.bin_start_[t], e1 = gs.bin_start_[t + 1];
            const double far_lo = double(tmin[t]) * (1.0 - 1e-6);  // as splat_tile_reduced's
            auto front = [&](std::size_t i) { return reach[i] <= far_lo; };
            std::uint32_t save[kMaxFarLevel] = {}, spend[kMaxFarLevel] = {};
            unsigned bits = 0, pairs = 0;
            for (std::uint32_t e = e0; e < e1; ++e) {
                const std::size_t i = gs.bin_index_[e];
                if (!gs.level_[i]) continue;
                const int k = gs.level_[i] - 1;
                bits |= 1u << k;
                ++pairs;
                if (front(i)) save[k] += lattice_cost[i];
                else spend[k] += 36;
            }
            unsigned use = 0;
            for (int k = 0; k < kMaxFarLevel; ++k)
                if ((bits >> k & 1u) && save[k] > spend[k] + 25) use |= 1u << k;
            gs.tile_far_[t] = std::uint16_t(use);
            gs.tile_far_pairs_[t] = pairs;
            if (use == 0) continue;
            moved.clear();
            std::uint32_t w = e0;
            for (std::uint32_t e = e0; e < e1; ++e) {
                const std::uint32_t i = gs.bin_index_[e];
                if (gs.level_[i] && (use >> (gs.level_[i] - 1) & 1u) && front(i))
                    moved.push_back(i);
                else gs.bin_index_[w++] = i;
            }
            std::copy(moved.begin(), moved.end(), gs.bin_index_.begin() + w);
            gs.splat_end_[t] = w;
        }
    });
}

// The grid blocks that some tile reading their level reaches with its lattice's cubic
// stencils (add_far_grid): only those are evaluated (the others' nodes stay 0 and are never
// read; far_share reads only the directions).
void GaussianSplat::FarBuild::mark_needed_blocks() {
    const int n_tiles = gs.num_tiles();
    const int step = gs.step_;
    for (int k = 1; k <= kMaxFarLevel; ++k) {
        if (!(used >> (k - 1) & 1u)) continue;
        int h, nx, ny;
        grid_dims(k, h, nx, ny);
        const int bx = (nx + kBlock - 1) / kBlock, by = (ny + kBlock - 1) / kBlock;
        std::vector<char>& needed = block_needed[k - 1];
        needed.assign(std::size_t(bx) * by, 0);
        for (int t = 0; t < n_tiles; ++t) {
            if (!(gs.tile_far_[t] >> (k - 1) & 1u)) continue;
            const int x0 = (t % gs.tiles_x_) * kTile, y0 = (t / gs.tiles_x_) * kTile;
            const int w = std::min(gs.W_, x0 + kTile) - x0, ht = std::min(gs.H_, y0 + kTile) - y0;
            const int nu = int((w - 0.5) / step) + 2, nv = int((ht - 0.5) / step) + 2;
            const int P0 = x0 / h, P1 = std::min(nx - 1, (x0 + step * (nu - 1)) / h + 3);
            const int Q0 = y0 / h, Q1 = std::min(ny - 1, (y0 + step * (nv - 1)) / h + 3);
            for (int q = Q0 / kBlock; q <= Q1 / kBlock; ++q)
                for (int p = P0 / kBlock; p <= P1 / kBlock; ++p) needed[std::size_t(q) * bx + p] = 1;
        }
    }
}

// The used levels' grids, zeroed, with their nodes' unit ray directions.
void GaussianSplat::FarBuild::init_grids() {
    gs.far_grids_.resize(kMaxFarLevel);
    for (int k = 1; k <= kMaxFarLevel; ++k) {
        if (!(used >> (k - 1) & 1u)) continue;
        FarGrid& grid = gs.far_grids_[k - 1];
        grid_dims(k, grid.h, grid.nx, grid.ny);
        const std::size_t m = std::size_t(grid.nx) * grid.ny;
        for (auto* v : {&grid.T, &grid.R, &grid.G, &grid.B, &grid.dx, &grid.dy, &grid.dz}) v->assign(m, 0.0f);
        for (int Q = 0; Q < grid.ny; ++Q)
            for (int P = 0; P < grid.nx; ++P) {
                const Vec3 r =
                    glm::normalize(gs.D0_ + double(grid.h * (P - 1)) * gs.Dx_ + double(grid.h * (Q - 1)) * gs.Dy_);
                const std::size_t o = std::size_t(Q) * grid.nx + P;
                grid.dx[o] = float(r.x);
                grid.dy[o] = float(r.y);
                grid.dz[o] = float(r.z);
            }
    }
}

// The grids in blocks (units), each with the list of its level's Gaussians whose cull cones
// meet its rays (the cone test of bin(), on the block's corner nodes). A Gaussian is on
// every node of its blocks: elsewhere its terms are < the cull eps.
void GaussianSplat::FarBuild::list_gaussians() {
    for (int k = 1; k <= kMaxFarLevel; ++k) {
        unit_base[k - 1] = int(units.size());
        const FarGrid& grid = gs.far_grids_[k - 1];
        if (grid.T.empty()) continue;
        for (int Q = 0; Q < grid.ny; Q += kBlock)
            for (int P = 0; P < grid.nx; P += kBlock)
                units.push_back({k, P, Q, std::min(grid.nx, P + kBlock) - 1, std::min(grid.ny, Q + kBlock) - 1, {}});
    }
    unit_base[kMaxFarLevel] = int(units.size());
    // Each block's cone: axis through its centre node, cos and sin of its largest angle to
    // a corner node (the nodes' directions are those of a convex film quadrilateral).
    struct BlockCone {
        Vec3 axis;
        double cos_t, sin_t;
    };
    std::vector<BlockCone> block_cone(units.size());
    for (std::size_t u = 0; u < units.size(); ++u) {
        const Unit& un = units[u];
        const FarGrid& grid = gs.far_grids_[un.k - 1];
        auto film = [&](int P, int Q) {
            return gs.D0_ + double(grid.h * (P - 1)) * gs.Dx_ + double(grid.h * (Q - 1)) * gs.Dy_;
        };
        const Vec3 axis = glm::normalize(film(un.P0, un.Q0) + film(un.P1, un.Q1));
        double cmin = 1.0;
        for (int P : {un.P0, un.P1})
            for (int Q : {un.Q0, un.Q1}) cmin = std::min(cmin, glm::dot(axis, glm::normalize(film(P, Q))));
        cmin = std::clamp(cmin - 1e-9, -1.0, 1.0);
        block_cone[u] = {axis, cmin, std::sqrt(std::max(0.0, 1.0 - cmin * cmin))};
    }
    for (std::uint32_t i : far_list) {
        const int k = gs.level_[i];
        const FarGrid& grid = gs.far_grids_[k - 1];
        const int bx = (grid.nx + kBlock - 1) / kBlock;
        int P0, P1, Q0, Q1;
        node_range(i, k, P0, P1, Q0, Q1);
        const GaussF& g = gs.g_[i];
        const Vec3 u = Vec3(g.rx, g.ry, g.rz) / g.dist;
        const double sin_r = std::min(1.0, g.radius / g.dist), cos_r = std::sqrt(1.0 - sin_r * sin_r);
        for (int by = Q0 / kBlock; by <= Q1 / kBlock; ++by)
            for (int bxx = P0 / kBlock; bxx <= P1 / kBlock; ++bxx) {
                if (!block_needed[k - 1][std::size_t(by) * bx + bxx]) continue;
                const std::size_t un = std::size_t(unit_base[k - 1] + by * bx + bxx);
                const BlockCone& c = block_cone[un];
                const double cos_sum = c.cos_t * cos_r - c.sin_t * sin_r;
                if (c.sin_t * cos_r + c.cos_t * sin_r >= 0.0 && glm::dot(c.axis, u) < cos_sum) continue;
                units[un].list.push_back(i);
            }
    }
}

// The blocks' nodes, each block's Gaussians evaluated Gaussian-major like the tile lattices
// (lattice_batch), costliest block first.
void GaussianSplat::FarBuild::evaluate() {
    gs.far_gaussians_ = far_list.size();
    std::vector<std::size_t> order;
    for (std::size_t u = 0; u < units.size(); ++u)
        if (!units[u].list.empty()) order.push_back(u);
    // (costliest first)
    std::stable_sort(order.begin(), order.end(),
                     [&](std::size_t a, std::size_t b) { return units[a].list.size() > units[b].list.size(); });
    std::atomic<std::size_t> evals{0};
    parallel_chunks(order.size(), gs.threads_, 1, [&](std::size_t ub, std::size_t ue) {
        for (std::size_t e = ub; e < ue; ++e) {
            const Unit& un = units[order[e]];
            FarGrid& grid = gs.far_grids_[un.k - 1];
            const int wx = un.P1 - un.P0 + 1, m = wx * (un.Q1 - un.Q0 + 1);
            float lx[kBlock * kBlock], ly[kBlock * kBlock], lz[kBlock * kBlock];
            float T[kBlock * kBlock] = {}, R[kBlock * kBlock] = {}, G[kBlock * kBlock] = {}, B[kBlock * kBlock] = {};
            for (int Q = un.Q0; Q <= un.Q1; ++Q)
                for (int P = un.P0; P <= un.P1; ++P) {
                    const std::size_t o = std::size_t(Q) * grid.nx + P;
                    const int j = (Q - un.Q0) * wx + (P - un.P0);
                    lx[j] = grid.dx[o];
                    ly[j] = grid.dy[o];
                    lz[j] = grid.dz[o];
                }
            gs.lattice_batch(un.list.data(), int(un.list.size()), m, lx, ly, lz, T, R, G, B);
            for (int Q = un.Q0; Q <= un.Q1; ++Q)
                for (int P = un.P0; P <= un.P1; ++P) {
                    const std::size_t o = std::size_t(Q) * grid.nx + P;
                    const int j = (Q - un.Q0) * wx + (P - un.P0);
                    grid.T[o] = T[j];
                    grid.R[o] = R[j];
                    grid.G[o] = G[j];
                    grid.B[o] = B[j];
                }
            evals.fetch_add(std::size_t(m) * un.list.size(), std::memory_order_relaxed);
        }
    });
    gs.far_nodes_ = evals.load();
}

void GaussianSplat::build_far_field(const std::vector<int>& rect, FarScratch& far) {
    FarBuild build(*this, rect, far);
    if (!build.choose_gaussians()) return;
    build.move_front_pairs();
    build.mark_needed_blocks();
    build.init_grids();
    build.list_gaussians();
    build.evaluate();
}

void GaussianSplat::far_share(std::size_t i, int x0, int y0, int s, int nu, int nv, float* const* out) const {
    const FarGrid& grid = far_grids_[level_[i] - 1];
    const int h = grid.h;
    const int P0 = x0 / h, P1 = (x0 + s * (nu - 1)) / h + 3, Q0 = y0 / h, Q1 = (y0 + s * (nv - 1)) / h + 3;
    const int wx = P1 - P0 + 1, wy = Q1 - Q0 + 1, m = wx * wy;
    constexpr int kMaxWindow = 96;  // (16 / h + 4)^2 <= 64 at h >= s 2
    float lx[kMaxWindow], ly[kMaxWindow], lz[kMaxWindow];
    float T[kMaxWindow], R[kMaxWindow], G[kMaxWindow], B[kMaxWindow];
    for (int Q = Q0; Q <= Q1; ++Q)
        for (int P = P0; P <= P1; ++P) {
            const std::size_t o = std::size_t(Q) * grid.nx + P;
            const int k = (Q - Q0) * wx + (P - P0);
            lx[k] = grid.dx[o];
            ly[k] = grid.dy[o];
            lz[k] = grid.dz[o];
        }
    const int m_pad = (m + 15) / 16 * 16;
    for (int k = m; k < m_pad; ++k) {
        lx[k] = lx[m - 1];
        ly[k] = ly[m - 1];
        lz[k] = lz[m - 1];
    }
    for (float* v : {T, R, G, B}) std::fill(v, v + m_pad, 0.0f);  // (not the whole arrays: a call per pair)
    splat_gaussian(i, m_pad, lx, ly, lz, nullptr, T, R, G, B);
    for (int q = 0; q < 4; ++q) std::fill(out[q], out[q] + nu * nv, 0.0f);
    const float* g[4] = {T, R, G, B};
    add_far_grid(g, h, wx, P0, Q0, x0, y0, s, nu, nv, out);
}

}  // namespace airlight
