// sun05_batch.h: the Sun 2005 table path for many view rays at once (SIMD).
//
// Same reduction and table as sun05_inline.h (read its header comment), evaluated in
// float, branch-free, so the compiler vectorises it (AVX-512 / AVX2 clones with a
// baseline fallback, chosen at load time). Lanes where the float path is not safe are
// handed to the scalar double sun05_airlight_table afterwards, so their results are
// exactly today's:
//   - the F difference is not well conditioned with a 1 % margin over the scalar test
//     (F1 - F0 <= 1.01 kCancel F1), so a lane the batch keeps is one the scalar path
//     also evaluates from the table;
//   - sin(gamma) < kSinGammaMin (through or behind the light), Dvp <= 0 or NaN,
//     an overflow-prone exponent e^{-sigma_t a} (sigma_t a < -60), a non-finite result.
// Float error of the kept lanes against the double table path: F0 and F1 each carry
// ~3e-7 relative, the difference amplifies it by F1 / G < 1 / kCancel, so the lanes
// agree to ~1e-6 / kCancel relative (sun05_batch_test.cpp asserts it); negligible next
// to the table's own error (special_f.cpp) amplified the same way.
#pragma once

#include "core/special_f.h"

namespace airlight {

// out[k] = sun05_airlight_table(table, nu, nT, sigma_t, Dsv, cos_gamma[k], Dvp[k]) for
// k < n, the view rays sharing the viewer-light distance _Dsv_ (perspective camera).
// cos_gamma is double because 1 - cos(gamma) near the light needs it (a float
// cos(gamma) would put 6e-8 / gamma^2 relative error on the distance of closest
// approach); Dvp may be +inf (ray leaves the scene). _t0_ (optional, null: all 0): the
// near distances, each in [0, Dvp): the airlight of the segment [t0, Dvp] only,
// attenuated from o + t0 d (the near clip plane, as Cycles integrates it), in one
// evaluation (sun05_geometry_shift); lanes with Dvp <= t0 give 0. Returns the number
// of lanes evaluated by the scalar fallback (the measure of how often the fast path fails).
// _interp_: the table lookup (the table's SpecialFTable::interp()); with Nearest a lane may
// pick the neighbouring sample where float and double rounding of the index differ.
int sun05_airlight_table_batch(const float* table, int nu, int nT, double sigma_t, double Dsv,
                               const double* cos_gamma, const float* Dvp, int n, float* out,
                               const float* t0 = nullptr, Interp interp = Interp::Bilinear);

// Tr[k] = exp(-sigma_t Dvp[k]) (0 for Dvp = inf, 1 for sigma_t = 0), float, ~2e-7
// relative for exponents down to -87 (0 below).
void transmittance_batch(float sigma_t, const float* Dvp, int n, float* Tr);

}  // namespace airlight
