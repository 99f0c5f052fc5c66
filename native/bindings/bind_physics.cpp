// bind_physics.cpp: special function F, its table, and the per-ray airlight models.
#include <cmath>
#include <stdexcept>

#include "core/constants.h"
#include "bake/bake.h"
#include "models/registry.h"
#include "core/quadrature.h"
#include "core/special_f.h"
#include "homogeneous/sun05.h"
#include "bindings/numpy_util.h"

namespace airlight::bindings {

using namespace pybind11::literals;

namespace {


py::array_t<double> special_F(const py::object& u, const py::object& v, bool exact) {
    auto args = broadcast_doubles({{u, "u"}, {v, "v"}});
    const double* pu = args[0].data();
    const double* pv = args[1].data();
    py::array_t<double> out(std::vector<py::ssize_t>(args[0].shape(), args[0].shape() + args[0].ndim()));
    double* po = out.mutable_data();
    const py::ssize_t n = args[0].size();
    // Check the domain first so that no work starts on bad input.
    for (py::ssize_t i = 0; i < n; ++i) {
        if (!(std::isfinite(pu[i]) && pu[i] >= 0.0))
            throw py::value_error("special_F: u must be finite and >= 0, got " + std::to_string(pu[i]));
        if (!(pv[i] >= 0.0 && pv[i] <= kHalfPi))
            throw py::value_error("special_F: v must be in [0, pi/2], got " + std::to_string(pv[i]));
    }
    py::gil_scoped_release release;
    std::shared_ptr<const SpecialFTable> table;
    if (!exact) table = shared_special_F_table(256, 256);
    for (py::ssize_t i = 0; i < n; ++i) po[i] = exact ? special_F_exact(pu[i], pv[i]) : table->eval(pu[i], pv[i]);
    return out;
}

py::dict special_F_table(int nu, int nT) {
    if (nu < 2 || nT < 2 || nu > 16384 || nT > 16384)
        throw py::value_error("special_F_table: nu and nT must be in [2, 16384]");
    std::shared_ptr<const SpecialFTable> table;
    {
        py::gil_scoped_release release;
        table = shared_special_F_table(nu, nT);
    }
    const std::vector<float>& data = table->data();
    py::array_t<float> arr({py::ssize_t(nu), py::ssize_t(nT)});
    std::copy(data.begin(), data.end(), arr.mutable_data());
    py::dict d("data"_a = arr, "nu"_a = nu, "nT"_a = nT, "k"_a = kSpecialFTableK,
               "interpolation"_a = table->interp() == Interp::Bilinear ? "bilinear" : "nearest");
    return d;
}

py::array_t<double> sun05_airlight_py(const py::object& sigma_t, const py::object& Dsv,
                                      const py::object& cos_gamma, const py::object& Dvp,
                                      const std::string& model) {
    const ModelId id = model_from_name(model);
    auto args = broadcast_doubles({{sigma_t, "sigma_t"}, {Dsv, "Dsv"}, {cos_gamma, "cos_gamma"}, {Dvp, "Dvp"}});
    py::array_t<double> out(std::vector<py::ssize_t>(args[0].shape(), args[0].shape() + args[0].ndim()));
    double* po = out.mutable_data();
    const double *ps = args[0].data(), *pD = args[1].data(), *pc = args[2].data(), *pd = args[3].data();
    const py::ssize_t n = args[0].size();
    py::gil_scoped_release release;
    std::shared_ptr<const SpecialFTable> table;
    if (id == ModelId::Sun05Table) table = shared_special_F_table(256, 256);
    for (py::ssize_t i = 0; i < n; ++i) sun05_check_inputs(ps[i], pD[i], pc[i], pd[i]);
    for (py::ssize_t i = 0; i < n; ++i) {
        switch (id) {
            case ModelId::Sun05Table:
                po[i] = sun05_airlight(ps[i], pD[i], pc[i], pd[i], table.get(), FEval::Table);
                break;
            case ModelId::Sun05Exact:
                po[i] = sun05_airlight(ps[i], pD[i], pc[i], pd[i], nullptr, FEval::Exact);
                break;
            case ModelId::Quadrature:
                po[i] = sun05_airlight_quadrature(ps[i], pD[i], pc[i], pd[i]);
                break;
        }
    }
    return out;
}

}  // namespace

void bind_physics(py::module_& m) {
    m.def("special_F", &special_F, "u"_a, "v"_a, "exact"_a = false,
          R"doc(Sun et al. 2005's special function F(u, v) = int_0^v exp(-u tan xi) dxi.

u, v: array-likes broadcast against each other (u >= 0, v in [0, pi/2]).
exact: False uses the 256 x 256 table the bake uses (fast path); True the exact
evaluator (~1e-12 relative). Returns a float64 array of the broadcast shape.
Raises ValueError outside the domain.)doc");

    m.def("special_F_table", &special_F_table, "nu"_a = 256, "nT"_a = 256,
          R"doc(The tabulated F exactly as the C++ fast path stores it, for GPU upload.

Returns a dict:
  data: float32 array of shape (nu, nT), row-major [i][j], storing
        Q(s, w) = F(u, T) (1 + u) / w  (Q = 1 at w = 0),
  nu, nT: the table size,
  k: the row-mapping constant,
  interpolation: "bilinear" (the C++ lookup; a GPU sampler with linear filtering
        and texel-centre addressing reproduces it).
Lookup of F(u, T = tan v), as sun05_inline.h does it:
  s = sqrt(u / (u + k)),  row    x = s (nu - 1)   (s = 1 is u = inf)
  tau = T (1 + u), w = tau / (1 + tau), column y = w (nT - 1)   (w = 1 is T = inf)
  F = Q(x, y) w / (1 + u)  with Q bilinear between the 4 nearest samples.)doc");

    m.def("sun05_airlight", &sun05_airlight_py, "sigma_t"_a, "Dsv"_a, "cos_gamma"_a, "Dvp"_a,
          "model"_a = "sun05",
          R"doc(Airlight of one view ray (Sun et al. 2005, eq. 11) per unit I0 and albedo.

All four arguments are array-likes broadcast against each other: extinction sigma_t
(1/m, >= 0), viewer-light distance Dsv (> 0), cosine of the angle between the view
ray and the direction to the light, viewer-surface distance Dvp (> 0, may be inf).
model: "sun05" (table F), "sun05_exact" (exact F) or "quadrature" (reference).
Multiply the result by albedo * I0 (W/sr) for radiance. Raises ValueError on
invalid input or an unknown model.)doc");
}

}  // namespace airlight::bindings
