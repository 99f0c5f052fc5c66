// preview_tiles.h: the per-tile Gaussian lists of the viewport preview's tile pass
// (shaders/rbf_tiles_frag.glsl). Plain C++17 + GLM, header-only, so that the binding
// (bind_preview.cpp: _native.rbf_tile_lists) and the standalone GPU harness
// (benchmarks/gpu_preview/) build the very same lists. The reference is the add-on's numpy
// version, addon/airlight/preview_gaussians.tile_lists (same steps;
// tests/gpu/test_preview_gaussians.py compares them list for list). Not a kernel: only the GPU preview uses it (the bake bins in
// GaussianSplat::bin with its own camera conventions).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <stdexcept>
#include <vector>

#include <glm/glm.hpp>

namespace airlight::preview {

struct TileLists {
    std::vector<std::int32_t> first, count, entries;
};

// Lists for n Gaussians (centres 3n, cull radii n) seen through P (projection @ view) in
// a W x H image whose splat target has ceil(W / S) x ceil(H / S) texels (texel q stands
// for the full-resolution pixel q S + S / 2), tiles of tile x tile texels; see
// preview_gaussians.tile_lists (same steps, same order of operations where it matters).
inline TileLists tile_lists(const double* centres, const double* radii, std::size_t n, const glm::dmat4& P, int W, int H,
                     int S, int tile, bool cone_test) {
    const int lw = (W + S - 1) / S, lh = (H + S - 1) / S;
    const int tx_n = (lw + tile - 1) / tile, ty_n = (lh + tile - 1) / tile;
    auto row = [&](int k) { return glm::dvec4(P[0][k], P[1][k], P[2][k], P[3][k]); };
    const glm::dvec4 r0 = row(0), r1 = row(1), r3 = row(3);
    const double off = S / 2 + 0.5;
    // Tile cones (perspective views only).
    const bool persp = cone_test && (r3.x != 0.0 || r3.y != 0.0 || r3.z != 0.0);
    glm::dvec3 eye(0.0);
    std::vector<glm::dvec3> axis;
    std::vector<double> cos_t, sin_t;
    if (persp) {
        const glm::dmat3 A = glm::transpose(glm::dmat3(glm::dvec3(r0), glm::dvec3(r1), glm::dvec3(r3)));
        eye = glm::inverse(A) * -glm::dvec3(r0.w, r1.w, r3.w);
        const glm::dmat4 inv = glm::inverse(P);
        auto direction = [&](double x, double y) {
            const glm::dvec4 f = inv * glm::dvec4(x / W * 2.0 - 1.0, y / H * 2.0 - 1.0, 1.0, 1.0);
            return glm::normalize(glm::dvec3(f) / f.w - eye);
        };
        axis.resize(std::size_t(tx_n) * ty_n);
        cos_t.resize(axis.size());
        sin_t.resize(axis.size());
        for (int ty = 0; ty < ty_n; ++ty)
            for (int tx = 0; tx < tx_n; ++tx) {
                const double x0 = double(tx) * tile * S + off, x1 = (double(tx) * tile + tile - 1) * S + off;
                const double y0 = double(ty) * tile * S + off, y1 = (double(ty) * tile + tile - 1) * S + off;
                const std::size_t t = std::size_t(ty) * tx_n + tx;
                axis[t] = direction(0.5 * (x0 + x1), 0.5 * (y0 + y1));
                double c = 1.0;
                for (double x : {x0, x1})
                    for (double y : {y0, y1}) c = std::min(c, glm::dot(axis[t], direction(x, y)));
                c = std::clamp(c - 1e-6, -1.0, 1.0);
                cos_t[t] = c;
                sin_t[t] = std::sqrt(std::max(0.0, 1.0 - c * c));
            }
    }
    // Tile rectangle per Gaussian (x1 < x0: none).
    std::vector<int> rect(4 * n, 0);
    for (std::size_t i = 0; i < n; ++i) {
        int* r = &rect[4 * i];
        r[1] = -1;
        const glm::dvec3 b(centres[3 * i], centres[3 * i + 1], centres[3 * i + 2]);
        const double R2 = radii[i] * radii[i];
        const double bw = glm::dot(glm::dvec3(r3), b) + r3.w;
        const double A = bw * bw - R2 * glm::dot(glm::dvec3(r3), glm::dvec3(r3));
        const bool finite = A > 1e-12 * bw * bw && bw > 0.0;
        if (!(radii[i] > 0.0) || (!finite && bw < 0.0 && A > 0.0)) continue;
        double lo[2] = {-1.0, -1.0}, hi[2] = {1.0, 1.0};
        if (finite)
            for (int axis_i = 0; axis_i < 2; ++axis_i) {
                const glm::dvec4 rr = row(axis_i);
                const double a = glm::dot(glm::dvec3(rr), b) + rr.w;
                const double Bh = a * bw - R2 * glm::dot(glm::dvec3(rr), glm::dvec3(r3));
                const double C = a * a - R2 * glm::dot(glm::dvec3(rr), glm::dvec3(rr));
                const double root = std::sqrt(std::max(Bh * Bh - A * C, 0.0));
                lo[axis_i] = std::max((Bh - root) / A, -1.0);
                hi[axis_i] = std::min((Bh + root) / A, 1.0);
            }
        if (!(lo[0] < hi[0]) || !(lo[1] < hi[1])) continue;
        const double size[2] = {double(W), double(H)};
        const double qmax[2] = {double(lw - 1), double(lh - 1)};
        double qlo[2], qhi[2];
        bool vis = true;
        for (int k = 0; k < 2; ++k) {
            qlo[k] = std::floor(((lo[k] + 1.0) * 0.5 * size[k] - off) / S) - 1.0;
            qhi[k] = std::ceil(((hi[k] + 1.0) * 0.5 * size[k] - off) / S) + 1.0;
            vis = vis && qhi[k] >= 0.0 && qlo[k] <= qmax[k];
        }
        if (!vis) continue;
        r[0] = int(std::clamp(qlo[0], 0.0, qmax[0])) / tile;
        r[1] = int(std::clamp(qhi[0], 0.0, qmax[0])) / tile;
        r[2] = int(std::clamp(qlo[1], 0.0, qmax[1])) / tile;
        r[3] = int(std::clamp(qhi[1], 0.0, qmax[1])) / tile;
    }
    // Two passes over (Gaussian, tile): count, then fill in Gaussian order.
    auto for_each_tile = [&](std::size_t i, auto&& fn) {
        const int* r = &rect[4 * i];
        if (r[1] < r[0]) return;
        glm::dvec3 u(0.0);
        double sin_r = 1.0, cos_r = 0.0;
        bool inside = true;
        if (persp) {
            const glm::dvec3 c = glm::dvec3(centres[3 * i], centres[3 * i + 1], centres[3 * i + 2]) - eye;
            const double dist = glm::length(c);
            inside = dist <= radii[i] * (1.0 + 1e-9);
            if (!inside) {
                u = c / dist;
                sin_r = radii[i] / dist;
                cos_r = std::sqrt(std::max(0.0, 1.0 - sin_r * sin_r));
            }
        }
        for (int ty = r[2]; ty <= r[3]; ++ty)
            for (int tx = r[0]; tx <= r[1]; ++tx) {
                const std::size_t t = std::size_t(ty) * tx_n + tx;
                if (!inside) {
                    const double ct = cos_t[t], st = sin_t[t];
                    if (!(st * cos_r + ct * sin_r < 0.0) && !(glm::dot(axis[t], u) >= ct * cos_r - st * sin_r))
                        continue;
                }
                fn(t);
            }
    };
    TileLists out;
    const std::size_t n_tiles = std::size_t(tx_n) * ty_n;
    out.count.assign(n_tiles, 0);
    for (std::size_t i = 0; i < n; ++i) for_each_tile(i, [&](std::size_t t) { ++out.count[t]; });
    out.first.assign(n_tiles, 0);
    std::int64_t total = 0;
    for (std::size_t t = 0; t < n_tiles; ++t) {
        out.first[t] = std::int32_t(total);
        total += out.count[t];
    }
    if (total > INT32_MAX) throw std::invalid_argument("rbf_tile_lists: more than 2^31 entries");
    out.entries.resize(std::size_t(total));
    std::vector<std::int32_t> fill(out.first);
    for (std::size_t i = 0; i < n; ++i)
        for_each_tile(i, [&](std::size_t t) { out.entries[std::size_t(fill[t]++)] = std::int32_t(i); });
    return out;
}

}  // namespace airlight::preview
