// baseline_fog.h: what Blender's Mist pass / OpenGL fog does, as the bar every model must beat:
//   L = L0 e^{-sigma_t D} + C_fog (1 - e^{-sigma_t D}),
// one constant fog colour, no dependence on the lights or the view direction.
#pragma once

#include <cstddef>

namespace airlight {

// The baseline's airlight term C_fog (1 - e^{-sigma_t D}) (D may be inf).
inline double baseline_fog_airlight(double C_fog, double sigma_t, double D);

// Least-squares C_fog over an image: minimises sum_i (La_i - C (1 - e^{-sigma_t D_i}))^2,
// i.e. C = sum La_i f_i / sum f_i^2 with f_i = 1 - e^{-sigma_t D_i}. Returns 0 if all f_i = 0.
double baseline_fog_fit(const double* La, const double* D, std::size_t n, double sigma_t);

struct ErrorStats {
    double mean = 0.0, p99 = 0.0, max = 0.0;
};
// Relative error |got - want| / want over the pixels with want > 0.
ErrorStats relative_error_stats(const double* got, const double* want, std::size_t n);

}  // namespace airlight

#include <cmath>

inline double airlight::baseline_fog_airlight(double C_fog, double sigma_t, double D) {
    return C_fog * -std::expm1(-sigma_t * D);
}
