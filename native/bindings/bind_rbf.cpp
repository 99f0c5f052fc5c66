// bind_rbf.cpp: the Gaussian (RBF) medium.
#include "numpy_util.h"
namespace airlight::bindings {
void bind_rbf(py::module_&) {}
}  // namespace airlight::bindings
