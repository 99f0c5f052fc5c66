// bind_preview.cpp: for the viewport preview (addon/airlight/preview_gaussians.py):
// - gradient_noise3: native/kernels/noise.h, for the GPU agreement test that holds
//   shaders/rbf_noise.glsl to it (tests/gpu/test_12_preview_noise.py);
// - rbf_tile_lists: the per-tile Gaussian lists of the preview's tile pass
//   (shaders/rbf_tiles_frag.glsl), the same lists as preview_gaussians.tile_lists builds
//   with numpy (the reference; test_09 compares them), ~50x faster at full resolution. It
//   lives here, not in a kernel, because only the GPU preview uses it (the bake bins in
//   RbfSplat::bin with its own tile and camera conventions).
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include <stdexcept>

#include <glm/glm.hpp>

#include "kernels/noise.h"
#include "numpy_util.h"

namespace airlight::bindings {

using namespace pybind11::literals;

namespace {

struct TileLists {
    std::vector<std::int32_t> first, count, entries;
};

// See preview_gaussians.tile_lists (same steps, same order of operations where it matters).
TileLists tile_lists(const double* centres, const double* radii, std::size_t n, const glm::dmat4& P, int W, int H,
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

}  // namespace

void bind_preview(py::module_& m) {
    m.def(
        "rbf_tile_lists",
        [](const py::object& centres, const py::object& radii, const py::object& persp, int width, int height,
           int scale, int tile, bool cone_test) {
            auto b = as_array<double>(centres, "centres");
            const py::ssize_t n = require_rows_of(b, 3, "centres");
            auto r = as_array<double>(radii, "radii");
            if (r.ndim() != 1 || r.shape(0) != n)
                throw py::value_error("radii: expected shape (" + std::to_string(n) + ",), got " + shape_str(r));
            auto p = as_array<double>(persp, "persp");
            if (p.ndim() != 2 || p.shape(0) != 4 || p.shape(1) != 4)
                throw py::value_error("persp: expected shape (4, 4), got " + shape_str(p));
            if (width < 1 || height < 1 || scale < 1 || tile < 1)
                throw py::value_error("width, height, scale and tile must be >= 1");
            glm::dmat4 P;
            for (int i = 0; i < 4; ++i)
                for (int j = 0; j < 4; ++j) P[j][i] = p.data()[4 * i + j];  // row-major in, glm column-major
            for (int k = 0; k < 16; ++k)
                if (!std::isfinite(p.data()[k])) throw py::value_error("persp: not finite");
            for (py::ssize_t k = 0; k < 3 * n; ++k)
                if (!std::isfinite(b.data()[k])) throw py::value_error("centres: not finite");
            for (py::ssize_t k = 0; k < n; ++k)
                if (!std::isfinite(r.data()[k]) || r.data()[k] < 0.0)
                    throw py::value_error("radii: must be finite and >= 0");
            TileLists lists;
            {
                py::gil_scoped_release release;
                lists = tile_lists(b.data(), r.data(), std::size_t(n), P, width, height, scale, tile, cone_test);
            }
            const int lw = (width + scale - 1) / scale, lh = (height + scale - 1) / scale;
            const py::ssize_t tx_n = (lw + tile - 1) / tile, ty_n = (lh + tile - 1) / tile;
            const py::ssize_t m_entries = py::ssize_t(lists.entries.size());
            return py::make_tuple(to_numpy(std::move(lists.first), {ty_n, tx_n}),
                                  to_numpy(std::move(lists.count), {ty_n, tx_n}),
                                  to_numpy(std::move(lists.entries), {m_entries}));
        },
        "centres"_a, "radii"_a, "persp"_a, "width"_a, "height"_a, "scale"_a, "tile"_a, "cone_test"_a = true,
        R"doc(Per-tile Gaussian lists of the viewport preview's tile pass: (first, count) int32 of shape
(tiles_y, tiles_x) and entries int32 (m,), Gaussian indices ascending within a tile. The
splat target is ceil(width / scale) x ceil(height / scale) texels, texel q standing for
the full-resolution pixel q scale + scale // 2; a tile is tile x tile texels. A Gaussian
(centre, cull radius) is listed in every tile its projected sphere's screen bounds (one
texel of margin) touch and, for a perspective persp (projection @ view, row-major) with
cone_test, whose cone of view rays the sphere meets. Same lists as the add-on's
preview_gaussians.tile_lists (numpy). The GIL is released during the work.)doc");


    m.def(
        "gradient_noise3",
        [](const py::object& points) {
            auto p = as_array<float>(points, "points");
            const py::ssize_t n = require_rows_of(p, 3, "points");
            const float* x = p.data();
            for (py::ssize_t k = 0; k < 3 * n; ++k)
                if (!std::isfinite(x[k])) throw py::value_error("points: not finite");
            std::vector<float> out(3 * n);
            {
                py::gil_scoped_release release;
                for (py::ssize_t k = 0; k < n; ++k)
                    gradient_noise3(x[3 * k], x[3 * k + 1], x[3 * k + 2], out[3 * k], out[3 * k + 1], out[3 * k + 2]);
            }
            return to_numpy(std::move(out), {n, 3});
        },
        "points"_a,
        R"doc(The vector gradient noise of native/kernels/noise.h (Fogshop section 5.5, the bake's
noise perturbation) at float32 points (n, 3): float32 (n, 3), one gradient_noise3 per row.
For tests of its GLSL twin shaders/rbf_noise.glsl.)doc");
}

}  // namespace airlight::bindings
