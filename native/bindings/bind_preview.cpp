// bind_preview.cpp: kernels the viewport preview's GLSL mirrors, exposed for the GPU
// agreement tests (tests/gpu/test_12_preview_noise.py holds shaders/rbf_noise.glsl to
// native/kernels/noise.h with it).
#include <cmath>
#include <vector>

#include "kernels/noise.h"
#include "numpy_util.h"

namespace airlight::bindings {

using namespace pybind11::literals;

void bind_preview(py::module_& m) {
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
