// bind_models.cpp: anisotropic and sun models (phase functions, Biri 2006, Hoffman-Preetham).
#include "numpy_util.h"

namespace airlight::bindings {
void bind_models(py::module_&) {}
}  // namespace airlight::bindings
