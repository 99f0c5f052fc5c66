// bind_shadow.cpp: whether a light reaches points past a set of casters, by the bake's own
// shadow rays (ShadowVolumes::lit_at, Embree) over numpy arrays, with the GIL released: the
// reference that the viewport preview's shadow maps (shaders/shadow_maps.glsl) are held to.
#include <cmath>
#include <vector>

#include "shadow/shadow_volumes.h"
#include "bindings/numpy_util.h"

namespace airlight::bindings {

using namespace pybind11::literals;

namespace {

py::array_t<bool> shadow_visibility_py(const py::object& vertices, const py::object& triangles,
                                       const py::object& points, const py::object& position,
                                       const py::object& direction) {
    if (position.is_none() == direction.is_none())
        throw py::value_error("shadow_visibility: give exactly one of position (a point or spot light) "
                              "and direction (a sun)");
    auto v = as_array<float>(vertices, "vertices");
    const py::ssize_t nv = require_rows_of(v, 3, "vertices");
    for (py::ssize_t i = 0; i < 3 * nv; ++i)
        if (!std::isfinite(v.data()[i])) throw py::value_error("vertices: must be finite (found NaN or inf)");
    TriangleMesh casters;
    casters.vertices.assign(v.data(), v.data() + 3 * nv);
    casters.triangles = to_triangles(triangles);
    for (uint32_t index : casters.triangles)
        if (index >= uint32_t(nv)) throw py::value_error("triangles: index " + std::to_string(index) + " out of range");
    auto p = as_array<double>(points, "points");
    const py::ssize_t n = require_rows_of(p, 3, "points");
    for (py::ssize_t i = 0; i < 3 * n; ++i)
        if (!std::isfinite(p.data()[i])) throw py::value_error("points: must be finite (found NaN or inf)");
    ShadowLight light;
    const bool sun = position.is_none();
    auto l = as_array<double>(sun ? direction : position, sun ? "direction" : "position");
    if (l.size() != 3 || !std::isfinite(l.data()[0]) || !std::isfinite(l.data()[1]) || !std::isfinite(l.data()[2]))
        throw py::value_error("shadow_visibility: the light needs 3 finite numbers");
    const Vec3 lv(l.data()[0], l.data()[1], l.data()[2]);
    if (sun) {
        if (!(glm::length(lv) > 0.0)) throw py::value_error("direction: must not be zero");
        light.directional = true;
        light.direction = glm::normalize(lv);
    } else {
        light.position = lv;
    }
    py::array_t<bool> out(n);
    bool* po = out.mutable_data();
    const double* pp = p.data();
    py::gil_scoped_release release;
    const ShadowVolumes volumes(casters, {light}, sun ? Vec3(0.0) : lv);
    for (py::ssize_t i = 0; i < n; ++i) po[i] = volumes.lit_at(0, Vec3(pp[3 * i], pp[3 * i + 1], pp[3 * i + 2]));
    return out;
}

}  // namespace

void bind_shadow(py::module_& m) {
    m.def("shadow_visibility", &shadow_visibility_py, "vertices"_a, "triangles"_a, "points"_a, py::kw_only(),
          "position"_a = py::none(), "direction"_a = py::none(),
          R"doc(Whether a light reaches each point past the casters, by the bake's shadow rays.

vertices (N, 3) float32 and triangles (M, 3) integers: the casters (world space);
points (K, 3): where to ask; position (3,): a point or spot light there, or direction (3,):
a sun whose light travels that way (exactly one of the two).
Returns (K,) bool, True where the segment to the light (for a sun, the half-line towards it)
crosses no caster triangle.)doc");
}

}  // namespace airlight::bindings
