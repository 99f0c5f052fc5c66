// sun05.h: homogeneous, isotropic single scattering from a point light
// (Sun, Ramamoorthi, Narasimhan, Nayar 2005, section 3).
//
// Geometry of one view ray: viewer v, unit direction, surface at distance _Dvp_
// (may be +inf), light s at distance _Dsv_ from v, _gamma_ the angle between the
// view ray and the direction v->s. _Tsv_ = sigma_t Dsv, _Tvp_ = sigma_t Dvp.
#pragma once

#include "core/special_f.h"

namespace airlight {

// Which evaluation path of F to use.
enum class FEval { Table, Exact };

// Airlight La (eq. 11 / 12) per unit I0 and per unit albedo, i.e. the value for
// I0 = 1 W/sr and omega = 1. Multiply by omega * I0 (per RGB channel).
//   cos_gamma: cosine of the angle between view direction and direction to the light
//   Dsv: viewer-light distance (> 0), Dvp: viewer-surface distance (> 0, may be inf)
//   sigma_t: extinction (>= 0).
// Finite for every valid input; handles sigma_t -> 0, gamma -> 0 / pi, Dvp -> 0,
// Dvp = inf and large optical depths as documented in sun05.cpp.
// A view ray passing exactly through the light (gamma = 0 with the light in front
// of the surface) diverges physically; the kernel regularises it to a large finite
// value (sin gamma >= 1e-8, Dsv >= 1e-6), see sun05.cpp. The table path itself is
// header-only in sun05_inline.h (sun05_airlight_table) for callers that want it inlined.
double sun05_airlight(double sigma_t, double Dsv, double cos_gamma, double Dvp,
                      const SpecialFTable* table, FEval how);

// Validates inputs and throws std::invalid_argument with a clear message on NaN or
// negative values. The bake validates once per scene; this is for single-point calls.
void sun05_check_inputs(double sigma_t, double Dsv, double cos_gamma, double Dvp);

}  // namespace airlight
