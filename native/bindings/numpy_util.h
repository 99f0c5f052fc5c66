// numpy_util.h: argument checking and array conversion shared by the binding files.
#pragma once

#include <glm/glm.hpp>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

namespace airlight::bindings {

namespace py = pybind11;

template <typename T>
using CArray = py::array_t<T, py::array::c_style | py::array::forcecast>;

// TypeError naming _name_ unless _a_ holds real numbers (bool, integer or floating dtype):
// numpy would cast complex values to their real part (dropping the imaginary one) and None,
// strings or objects to NaN or garbage.
inline void require_real_dtype(const py::array& a, const py::handle& obj, const char* name) {
    const char kind = a.dtype().kind();
    if (kind == 'b' || kind == 'i' || kind == 'u' || kind == 'f') return;
    const std::string what = obj.is_none() ? std::string("None")
                             : kind == 'c'   ? "a complex array (dtype " + std::string(py::str(a.dtype())) +
                                                 "), whose imaginary part would be dropped"
                                             : "dtype " + std::string(py::str(a.dtype()));
    throw py::type_error(std::string(name) + ": expected real numbers, got " + what);
}

// Converts _obj_ to a C-contiguous array of T; TypeError naming _name_ when _obj_ does not
// hold real numbers (require_real_dtype), ValueError when it cannot be converted at all.
template <typename T>
CArray<T> as_array(const py::handle& obj, const char* name) {
    py::array raw = py::array::ensure(obj);
    if (raw) require_real_dtype(raw, obj, name);
    auto a = raw ? CArray<T>::ensure(raw) : CArray<T>::ensure(obj);
    if (!a) throw py::value_error(std::string(name) + ": cannot convert to a numeric array");
    return a;
}

// Refuses a string the C++ side would pass on as a C string (a file path, an EXR channel
// name): a NUL byte inside it would silently cut it there (a different, truncated file name).
inline void require_no_nul(const std::string& s, const char* name) {
    const size_t at = s.find('\0');
    if (at != std::string::npos)
        throw py::value_error(std::string(name) + ": contains a NUL byte (at index " + std::to_string(at) +
                              "), which would truncate it; refused");
}

// "(3, 4)" for error messages.
inline std::string shape_str(const py::array& a) {
    std::string s = "(";
    for (py::ssize_t i = 0; i < a.ndim(); ++i) s += (i ? ", " : "") + std::to_string(a.shape(i));
    return s + (a.ndim() == 1 ? ",)" : ")");
}

// Requires shape (rows, cols) with _cols_ fixed, or (rows,) == (0,) for an empty list,
// and (if _rows_ >= 0) the given row count. Returns the row count.
inline py::ssize_t require_rows_of(const py::array& a, py::ssize_t cols, const char* name,
                                   py::ssize_t rows = -1) {
    bool empty_list = a.ndim() == 1 && a.shape(0) == 0;
    if (!empty_list && (a.ndim() != 2 || a.shape(1) != cols))
        throw py::value_error(std::string(name) + ": expected shape (N, " + std::to_string(cols) +
                              "), got " + shape_str(a));
    py::ssize_t n = empty_list ? 0 : a.shape(0);
    if (rows >= 0 && n != rows)
        throw py::value_error(std::string(name) + ": expected " + std::to_string(rows) +
                              " rows, got " + std::to_string(n));
    return n;
}

// (M, 3) integer triangle indices as uint32 (ValueError: not integers, negative or too big).
inline std::vector<uint32_t> to_triangles(const py::object& obj) {
    py::array raw = py::array::ensure(obj);
    if (!raw) throw py::value_error("triangles: cannot convert to an array");
    if (raw.size() > 0 && raw.dtype().kind() != 'i' && raw.dtype().kind() != 'u')
        throw py::value_error("triangles: expected an integer array, got dtype " +
                              std::string(py::str(raw.dtype())));
    if (raw.dtype().is(py::dtype::of<uint32_t>())) {
        // (The add-on's: every value in range, copied without an int64 array and a check each:
        // 1e7 triangles took 0.2 s that way.)
        auto a = CArray<uint32_t>::ensure(raw);
        py::ssize_t m = require_rows_of(a, 3, "triangles");
        return std::vector<uint32_t>(a.data(), a.data() + 3 * m);
    }
    auto a = as_array<long long>(raw, "triangles");
    py::ssize_t m = require_rows_of(a, 3, "triangles");
    std::vector<uint32_t> out(size_t(3 * m));
    const long long* p = a.data();
    for (size_t i = 0; i < out.size(); ++i) {
        if (p[i] < 0 || p[i] > 0xFFFFFFFFll)
            throw py::value_error("triangles: index " + std::to_string(p[i]) + " out of range");
        out[i] = uint32_t(p[i]);
    }
    return out;
}

// A (4, 4) float64 array (numpy row-major) as a glm (column-major) matrix.
inline glm::dmat4 to_mat4(const py::object& obj, const char* name) {
    auto a = as_array<double>(obj, name);
    if (a.ndim() != 2 || a.shape(0) != 4 || a.shape(1) != 4)
        throw py::value_error(std::string(name) + ": expected shape (4, 4), got " + shape_str(a));
    glm::dmat4 m;
    for (int r = 0; r < 4; ++r)
        for (int c = 0; c < 4; ++c) m[c][r] = a.at(r, c);
    return m;
}

// A numpy array that owns _data_ (moved, no copy) with the given shape.
template <typename T>
py::array_t<T> to_numpy(std::vector<T>&& data, std::vector<py::ssize_t> shape) {
    auto* owner = new std::vector<T>(std::move(data));
    py::capsule free_owner(owner, [](void* p) { delete static_cast<std::vector<T>*>(p); });
    return py::array_t<T>(shape, owner->data(), free_owner);
}

// Broadcasts the given arrays against each other (numpy rules) as contiguous float64.
inline std::vector<CArray<double>> broadcast_doubles(const std::vector<std::pair<py::object, const char*>>& args) {
    py::module_ np = py::module_::import("numpy");
    py::list converted;
    for (const auto& [obj, name] : args) converted.append(as_array<double>(obj, name));
    py::object shaped;
    try {
        shaped = np.attr("broadcast_arrays")(*converted);
    } catch (const py::error_already_set& e) {
        throw py::value_error(std::string("arguments cannot be broadcast together: ") + e.what());
    }
    std::vector<CArray<double>> out;
    for (const py::handle& a : shaped) out.push_back(py::cast<CArray<double>>(np.attr("ascontiguousarray")(a)));
    return out;
}

void bind_physics(py::module_& m);
void bind_bake(py::module_& m);
void bind_rbf(py::module_& m);
void bind_models(py::module_& m);
void bind_pegoraro(py::module_& m);
void bind_env(py::module_& m);
void bind_preview(py::module_& m);
void bind_rbf_environment(py::module_& m);
void bind_surface(py::module_& m);
void bind_shadow(py::module_& m);

}  // namespace airlight::bindings
