// module.cpp: the private `_native` module. Kernels stay plain C++; the bindings
// convert whole numpy arrays and release the GIL around work.
#include "bake/bake.h"
#include "models/registry.h"
#include "bindings/numpy_util.h"

#include <pybind11/stl.h>

namespace py = pybind11;
using namespace pybind11::literals;

PYBIND11_MODULE(_native, m) {
    m.doc() = "Airlight native kernels: analytic single-scattering fog (Sun et al. 2005) and the bake.";
    m.attr("__version__") = "0.1.0";

    py::register_exception<airlight::Cancelled>(m, "BakeCancelled");

    m.def(
        "models",
        []() {
            py::list out;
            for (const airlight::ModelInfo& info : airlight::model_registry())
                out.append(py::make_tuple(info.name, info.description));
            return out;
        },
        "The registered fog models as a list of (name, description); the first is the default.");
    m.def(
        "whole_image_models",
        []() {
            py::list out;
            for (const airlight::ModelInfo& info : airlight::model_registry())
                if (info.bake) out.append(info.name);
            return out;
        },
        "The models that bake the whole image themselves rather than per ray: bake() cannot split "
        "their airlight into per-light passes (light_pass_index).");

    airlight::bindings::bind_physics(m);
    airlight::bindings::bind_bake(m);
    airlight::bindings::bind_rbf(m);
    airlight::bindings::bind_models(m);
    airlight::bindings::bind_pegoraro(m);
    airlight::bindings::bind_env(m);
    airlight::bindings::bind_preview(m);
    airlight::bindings::bind_rbf_environment(m);
    airlight::bindings::bind_surface(m);
    airlight::bindings::bind_shadow(m);
}
