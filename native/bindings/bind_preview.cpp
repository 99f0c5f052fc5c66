// bind_preview.cpp: for the viewport preview (addon/airlight/preview_gaussians.py):
// - gradient_noise3: native/core/noise.h, for the GPU agreement test that holds
//   shaders/rbf_noise.glsl to it (tests/gpu/test_preview_noise.py);
// - rbf_tile_lists: the per-tile Gaussian lists of the preview's tile pass
//   (preview_tiles.h; the same lists as preview_gaussians.tile_lists builds with numpy,
//   the reference, ~70x faster at full resolution).
#include <cmath>
#include <vector>

#include "core/noise.h"
#include "bindings/numpy_util.h"
#include "bindings/preview_tiles.h"

namespace airlight::bindings {

using namespace pybind11::literals;

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
            preview::TileLists lists;
            {
                py::gil_scoped_release release;
                lists = preview::tile_lists(b.data(), r.data(), std::size_t(n), P, width, height, scale, tile, cone_test);
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
        R"doc(The vector gradient noise of native/core/noise.h (Fogshop section 5.5, the bake's
noise perturbation) at float32 points (n, 3): float32 (n, 3), one gradient_noise3 per row.
For tests of its GLSL twin shaders/rbf_noise.glsl.)doc");
}

}  // namespace airlight::bindings
