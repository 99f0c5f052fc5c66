// screen_crossings.cpp: see screen_crossings.h. Built with -ffp-contract=off (CMakeLists.txt):
// the watertightness rests on edge functions that negate exactly.
#include "shadow/screen_crossings.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>

#include "core/parallel.h"

namespace airlight {

namespace {

Vec3 cross(const Vec3& a, const Vec3& b) {
    return Vec3(a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x);
}

double dot(const Vec3& a, const Vec3& b) { return a.x * b.x + a.y * b.y + a.z * b.z; }

// The half-open rule for positions exactly on an edge: the face whose edge normal points in
// +x, or along the edge in +y, takes them (its neighbour's normal is the exact negation).
bool tie_inside(const Vec3& e) { return e.x > 0.0 || (e.x == 0.0 && e.y > 0.0); }

}  // namespace

bool ScreenCrossings::covers(const Face& f, double x, double y) {
    for (int k = 0; k < 3; ++k) {
        const double v = f.e[k][0] * x + f.e[k][1] * y + f.e[k][2];
        if (!(v > 0.0 || (v == 0.0 && f.tie[k]))) return false;
    }
    return true;
}

ScreenCrossings::ScreenCrossings(const ShadowVolumes& volumes, const Vec3& viewer, const Vec3& D0, const Vec3& Dx,
                                 const Vec3& Dy, int W, int H, double cap_reach, double cap_beyond, int threads,
                                 size_t max_entries, size_t max_faces_per_tile, double max_faces_per_pixel) {
    if (W <= 0 || H <= 0) return;
    // Too many faces for the film's pixels: not ready (Embree traces). The caps the test below
    // may leave out (a finite _cap_reach_: casters the rays end on) are not counted.
    size_t n_faces = 0;
    for (int l = 0; l < volumes.num_lights(); ++l)
        for (const auto& part : volumes.faces(l)) {
            const ShadowFaces& sf = *part;
            const size_t left_out = std::isfinite(cap_reach) ? std::min(sf.n_seen_caps, sf.n_whole()) : 0;
            n_faces += sf.n_whole() - left_out;
        }
    if (double(n_faces) > std::max(double(kMinFacesForFallback), max_faces_per_pixel * double(W) * double(H))) return;
    const glm::dmat3 M(Dx, Dy, D0);  // columns: q = M^-1 P has q.z > 0 ahead of the viewer
    if (!(std::abs(glm::determinant(M)) > 0.0)) return;
    const glm::dmat3 Minv = glm::inverse(M);
    D0_ = D0, Dx_ = Dx, Dy_ = Dy;
    nx_ = int(std::ceil((W + 2.0 * kMargin) / kTileW));
    ny_ = int(std::ceil((H + 2.0 * kMargin) / kTileH));
    std::vector<Face> faces;
    std::vector<Box> boxes;
    std::vector<Vec3> P, q;  // the vertices relative to the viewer, and in the film's frame
    const Vec3 eye = viewer - volumes.frame();
    for (int l = 0; l < volumes.num_lights(); ++l)
        for (const auto& part : volumes.faces(l)) {
            const ShadowFaces& sf = *part;
            P.resize(sf.vertices.size());
            q.resize(sf.vertices.size());
            for (size_t k = 0; k < q.size(); ++k) P[k] = sf.vertices[k] - eye, q[k] = Minv * P[k];
            // The whole sides (one quad each, not ring by ring): the same tiling of the film, with
            // a third or less of the faces.
            for (size_t t = 0; t < sf.n_whole(); ++t) {
                const uint32_t* tri = sf.whole_triangle(t);
                const uint32_t i0 = tri[0], i1 = tri[1], i2 = tri[2];
                const Vec3 &q0 = q[i0], &q1 = q[i1], &q2 = q[i2];
                if (!(q0.z > 0.0 || q1.z > 0.0 || q2.z > 0.0)) continue;  // wholly behind the viewer
                const Vec3 &P0 = P[i0], &P1 = P[i1], &P2 = P[i2];
                if (t < sf.n_seen_caps && ShadowVolumes::cap_left_out(P0, P1, P2, cap_reach, cap_beyond)) continue;
                const Vec3 c12 = cross(q1, q2), c20 = cross(q2, q0), c01 = cross(q0, q1);
                const double det = dot(q0, c12);
                Face f;
                f.N = cross(P1 - P0, P2 - P0);
                f.NP0 = dot(f.N, P0);
                if (!(det != 0.0) || !(f.NP0 != 0.0)) continue;  // seen edge-on: no ray crosses it
                const double s = det > 0.0 ? 1.0 : -1.0;
                const Vec3 e[3] = {s * c12, s * c20, s * c01};
                for (int k = 0; k < 3; ++k) {
                    f.e[k][0] = e[k].x, f.e[k][1] = e[k].y, f.e[k][2] = e[k].z;
                    f.tie[k] = tie_inside(e[k]);
                }
                // Nearer than any crossing (a little under: the distance's own rounding).
                const double near = origin_distance(P0, P1, P2);
                f.near = float(near * (1.0 - 1e-6));
                f.light = int16_t(l);
                const int w = sf.whole_weight(t);
                f.dw = int16_t(f.NP0 < 0.0 ? w : -w);  // against the normal: entering (record_crossings)
                faces.push_back(f);
                Box b;  // empty (x0 > x1) unless all three vertices lie ahead of the viewer
                if (q0.z > 0.0 && q1.z > 0.0 && q2.z > 0.0)
                    for (const Vec3* v : {&q0, &q1, &q2}) {
                        const double x = v->x / v->z, y = v->y / v->z;
                        b.x0 = std::min(b.x0, x), b.x1 = std::max(b.x1, x);
                        b.y0 = std::min(b.y0, y), b.y1 = std::max(b.y1, y);
                    }
                boxes.push_back(b);
            }
        }
    bin(faces, boxes, max_entries, max_faces_per_tile, std::max(1, threads));
}

void ScreenCrossings::bin(const std::vector<Face>& faces, const std::vector<Box>& boxes, size_t max_entries,
                          size_t max_per_tile, int threads) {
    // Each face's tiles: those of its film bounding box (the whole film for a face reaching
    // behind the viewer) that no edge function rejects at all four corners (a rectangle
    // grown by 1e-3 px over the rounding of the corners' values).
    const double x_lo = -kMargin, y_lo = -kMargin;
    auto tiles_of = [&](size_t i, int& tx0, int& tx1, int& ty0, int& ty1) {
        const Box& b = boxes[i];
        const double pad = 1e-3;
        tx0 = 0, tx1 = nx_ - 1, ty0 = 0, ty1 = ny_ - 1;
        if (b.x0 <= b.x1) {  // else the face reaches behind the viewer: the whole film
            if (b.x1 + pad < x_lo || b.y1 + pad < y_lo) return false;
            tx0 = int(std::max(double(tx0), std::floor((b.x0 - pad - x_lo) / kTileW)));
            tx1 = int(std::min(double(tx1), std::floor((b.x1 + pad - x_lo) / kTileW)));
            ty0 = int(std::max(double(ty0), std::floor((b.y0 - pad - y_lo) / kTileH)));
            ty1 = int(std::min(double(ty1), std::floor((b.y1 + pad - y_lo) / kTileH)));
        }
        return tx0 <= tx1 && ty0 <= ty1;
    };
    // Whether face _f_ may cover tiles [tx0, tx1] x [ty0, ty1] (no edge rejects all corners).
    auto overlaps_block = [&](const Face& f, int tx0, int tx1, int ty0, int ty1) {
        const double pad = 1e-3;
        const double xs[2] = {x_lo + tx0 * kTileW - pad, x_lo + (tx1 + 1) * kTileW + pad};
        const double ys[2] = {y_lo + ty0 * kTileH - pad, y_lo + (ty1 + 1) * kTileH + pad};
        for (int k = 0; k < 3; ++k) {
            bool any = false;
            for (double x : xs)
                for (double y : ys) any = any || f.e[k][0] * x + f.e[k][1] * y + f.e[k][2] >= 0.0;
            if (!any) return false;
        }
        return true;
    };
    // The tiles face _f_ may cover within [tx0, tx1] x [ty0, ty1], to _visit_: blocks of
    // kBlock x kBlock tiles first (a face reaching behind the viewer spans the whole film).
    constexpr int kBlock = 8;
    auto for_tiles = [&](const Face& f, int tx0, int tx1, int ty0, int ty1, auto&& visit) {
        for (int by = ty0; by <= ty1; by += kBlock)
            for (int bx = tx0; bx <= tx1; bx += kBlock) {
                const int ex = std::min(tx1, bx + kBlock - 1), ey = std::min(ty1, by + kBlock - 1);
                if ((ex > bx || ey > by) && !overlaps_block(f, bx, ex, by, ey)) continue;
                for (int ty = by; ty <= ey; ++ty)
                    for (int tx = bx; tx <= ex; ++tx)
                        if (overlaps_block(f, tx, tx, ty, ty)) visit(size_t(ty) * nx_ + tx);
            }
    };
    // The faces nearest first, in one chunk per thread; each chunk lists its (tile, face)
    // pairs in that order, and a stable counting sort by tile keeps it: each tile's faces come
    // out nearest first, so a query stops at the first beyond its rays' ends.
    const size_t n_tiles = size_t(nx_) * size_t(ny_);
    std::vector<uint32_t> order(faces.size());
    for (size_t i = 0; i < order.size(); ++i) order[i] = uint32_t(i);
    std::sort(order.begin(), order.end(), [&](uint32_t a, uint32_t b) { return faces[a].near < faces[b].near; });
    const int n_chunks = std::max(1, std::min(threads, int(order.size() / 256) + 1));
    std::vector<std::vector<std::pair<uint32_t, uint32_t>>> pairs(static_cast<size_t>(n_chunks));  // (tile, face)
    std::atomic<size_t> total{0}, tested{0};
    std::atomic<bool> over{false};
    parallel_for(n_chunks, n_chunks, [&](int c) {
        const size_t q0 = order.size() * size_t(c) / n_chunks, q1 = order.size() * size_t(c + 1) / n_chunks;
        for (size_t q = q0; q < q1 && !over.load(std::memory_order_relaxed); ++q) {
            const uint32_t i = order[q];
            int tx0, tx1, ty0, ty1;
            if (!tiles_of(i, tx0, tx1, ty0, ty1)) continue;
            const size_t before = pairs[c].size();
            // Too many tiles to test or to hold: not ready (Embree traces).
            if (tested.fetch_add(size_t(tx1 - tx0 + 1) * size_t(ty1 - ty0 + 1)) > 8 * max_entries) over = true;
            for_tiles(faces[i], tx0, tx1, ty0, ty1, [&](size_t tile) { pairs[c].emplace_back(uint32_t(tile), i); });
            if (total.fetch_add(pairs[c].size() - before) > max_entries) over = true;
        }
    });
    if (over) return;
    // Many faces over each tile (a field of small open casters: every triangle's volume a
    // sliver across the film) cost more per pixel than Embree's traversal: not ready (on
    // films of kMinTilesForFallback tiles or more; smaller ones cost little either way).
    size_t n_pairs = 0;
    for (const auto& chunk : pairs) n_pairs += chunk.size();
    if (n_tiles >= kMinTilesForFallback && n_pairs > max_per_tile * n_tiles) return;
    std::vector<uint32_t> count(n_tiles, 0);
    for (const auto& chunk : pairs)
        for (const auto& [tile, face] : chunk) ++count[tile];
    begin_.assign(n_tiles + 1, 0);
    for (size_t k = 0; k < n_tiles; ++k) begin_[k + 1] = begin_[k] + count[k];
    entries_.resize(begin_[n_tiles]);
    std::vector<uint32_t> fill(begin_.begin(), begin_.end() - 1);
    for (const auto& chunk : pairs)
        for (const auto& [tile, face] : chunk) entries_[fill[tile]++] = face;
    faces_ = faces;
    ready_ = true;
}

void ScreenCrossings::push(const Face& f, const Ray& ray, float t1, std::vector<Crossing>& list) const {
    // t = NP0 / g in (0, t1), without the division for the faces behind the ray's end.
    const double g = dot(f.N, ray.d), end = double(t1) * g;
    if (f.NP0 > 0.0 ? (g > 0.0 && f.NP0 < end) : (g < 0.0 && f.NP0 > end))
        list.push_back({float(f.NP0 / g), f.light, f.dw});
}

double ScreenCrossings::span_near(const Face& f, double xa, double xb, double y) const {
    // The rays of the span form a fan in a plane through the viewer; where N . D keeps its
    // sign over the span (both ends hit the face's plane ahead) their hits on the face's plane
    // run along the segment between the ends' hits, so no hit is nearer than that segment.
    const Vec3 da = glm::normalize(D0_ + xa * Dx_ + y * Dy_), db = glm::normalize(D0_ + xb * Dx_ + y * Dy_);
    const double ta = f.NP0 / dot(f.N, da), tb = f.NP0 / dot(f.N, db);
    if (!(ta > 0.0 && tb > 0.0 && ta < 1e300 && tb < 1e300)) return f.near;
    const Vec3 a = ta * da, b = tb * db, ab = b - a;
    const double len2 = dot(ab, ab);
    const double u = len2 > 0.0 ? std::clamp(-dot(a, ab) / len2, 0.0, 1.0) : 0.0;
    return std::max(double(f.near), glm::length(a + u * ab) * (1.0 - 1e-6));
}

bool ScreenCrossings::crossings(const glm::dvec2* film, const Ray* rays, const float* t1, int n,
                                std::vector<Crossing>* lists, const uint32_t* masks) const {
    if (!ready_) return false;
    const double x_lo = -kMargin, y_lo = -kMargin;
    auto binned = [&](int k) {
        const double tx = std::floor((film[k].x - x_lo) / kTileW), ty = std::floor((film[k].y - y_lo) / kTileH);
        return tx >= 0.0 && tx < nx_ && ty >= 0.0 && ty < ny_;
    };
    bool row = n > 1;
    for (int k = 1; k < n && row; ++k) row = film[k].y == film[0].y && film[k].x == film[0].x + k;
    if (row) {  // (its ends bound it)
        if (!binned(0) || !binned(n - 1)) return false;
        row_crossings(film, rays, t1, n, lists, masks);
        return true;
    }
    for (int k = 0; k < n; ++k)
        if (!binned(k)) return false;
    // Scattered samples (an edge pixel's sub-samples) in groups of up to kGroup in one tile:
    // a face that misses the group's bounding box is passed over once for all of them.
    constexpr int kGroup = 16;
    auto tile_of = [&](int k) {
        return size_t(std::floor((film[k].y - y_lo) / kTileH)) * nx_ + size_t(std::floor((film[k].x - x_lo) / kTileW));
    };
    for (int k = 0; k < n;) {
        const size_t tile = tile_of(k);
        int k_end = k + 1;
        while (k_end < n && k_end - k < kGroup && tile_of(k_end) == tile) ++k_end;
        double bx0 = film[k].x, bx1 = bx0, by0 = film[k].y, by1 = by0;
        float t_max = 0.0f;
        for (int i = k; i < k_end; ++i) {
            lists[i].clear();
            bx0 = std::min(bx0, film[i].x), bx1 = std::max(bx1, film[i].x);
            by0 = std::min(by0, film[i].y), by1 = std::max(by1, film[i].y);
            t_max = std::max(t_max, t1[i]);
        }
        const double pad = 1e-3;
        const double xs[2] = {bx0 - pad, bx1 + pad}, ys[2] = {by0 - pad, by1 + pad};
        for (uint32_t q = begin_[tile]; q < begin_[tile + 1]; ++q) {
            const Face& f = faces_[entries_[q]];
            if (!(f.near < t_max)) break;
            bool misses = false;
            for (int e = 0; e < 3 && !misses; ++e) {
                bool any = false;
                for (double x : xs)
                    for (double y : ys) any = any || f.e[e][0] * x + f.e[e][1] * y + f.e[e][2] >= 0.0;
                misses = !any;
            }
            if (misses) continue;
            for (int i = k; i < k_end; ++i)
                if (f.near < t1[i] && asked(masks, i, f) && covers(f, film[i].x, film[i].y))
                    push(f, rays[i], t1[i], lists[i]);
        }
        k = k_end;
    }
    return true;
}

void ScreenCrossings::row_crossings(const glm::dvec2* film, const Ray* rays, const float* t1, int n,
                                    std::vector<Crossing>* lists, const uint32_t* masks) const {
    const double x_lo = -kMargin, y_lo = -kMargin;
    const double y = film[0].y, x0 = film[0].x;
    for (int k = 0; k < n; ++k) lists[k].clear();
    const size_t ty = size_t(std::floor((y - y_lo) / kTileH));
    int k = 0;
    while (k < n) {
        // The samples k .. k_end - 1 in tile column tx.
        const int tx = int(std::floor((film[k].x - x_lo) / kTileW));
        int k_end = k + 1;
        while (k_end < n && int(std::floor((film[k_end].x - x_lo) / kTileW)) == tx) ++k_end;
        const size_t tile = ty * nx_ + size_t(tx);
        float t_max = 0.0f;
        for (int i = k; i < k_end; ++i) t_max = std::max(t_max, t1[i]);
        for (uint32_t q = begin_[tile]; q < begin_[tile + 1]; ++q) {
            const Face& f = faces_[entries_[q]];
            if (!(f.near < t_max)) break;
            // The face's span on the row: each edge function is A x + C there; its root,
            // widened by a sample each side, bounds the samples covers() then decides. Samples
            // a whole sample inside every root ([in_lo, in_hi]) are covered whatever the
            // rounding, where the edge's value there, about A, dwarfs its evaluation's error
            // (a few ulps of |A x| + |B y| + |D|): covers() decides the rest.
            double lo = k, hi = k_end - 1, in_lo = lo, in_hi = hi;
            for (int e = 0; e < 3 && lo <= hi; ++e) {
                const double A = f.e[e][0], B = f.e[e][1] * y, C = B + f.e[e][2];
                const bool sure = std::abs(A) > 1e-9 * (std::abs(A) * (std::abs(x0) + n) + std::abs(B) +
                                                         std::abs(f.e[e][2]));
                if (A > 0.0) {
                    const double root = std::floor(-C / A - x0);
                    lo = std::max(lo, root - 1.0);
                    in_lo = sure ? std::max(in_lo, root + 2.0) : hi + 1.0;
                } else if (A < 0.0) {
                    const double root = std::ceil(-C / A - x0);
                    hi = std::min(hi, root + 1.0);
                    in_hi = sure ? std::min(in_hi, root - 2.0) : lo - 1.0;
                } else if (C < 0.0) {
                    hi = lo - 1.0;
                } else if (!(C > 0.0)) {
                    in_hi = lo - 1.0;  // (on the edge: its tie decides)
                }
            }
            lo = std::max(lo, double(k)), hi = std::min(hi, double(k_end - 1));
            if (!(lo <= hi)) continue;
            const double near = span_near(f, x0 + lo, x0 + hi, y);
            const int i_lo = int(lo), i_hi = int(hi);
            const int sure_lo = int(std::clamp(in_lo, lo, hi + 1.0)), sure_hi = int(std::clamp(in_hi, lo - 1.0, hi));
            for (int i = i_lo; i <= i_hi; ++i)
                if (near < t1[i] && asked(masks, i, f) && ((i >= sure_lo && i <= sure_hi) || covers(f, film[i].x, y)))
                    push(f, rays[i], t1[i], lists[i]);
        }
        k = k_end;
    }
}

}  // namespace airlight
