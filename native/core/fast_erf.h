// fast_erf.h: float exp, erfc and erf differences for the Gaussian splatting kernel
// (gaussian/splat*.cpp), written so that GCC vectorises loops that call them (no branches, no
// libm calls, no tables).
// Kept over SLEEF's vectorised functions because they measure faster in the kernels' loops
// (benchmarks/libraries/library_bench, AVX2, -O3, ns per value): exp 0.33 against
// Sleef_expf8_u10's 0.42 (same 7.7e-8 error); erfc 0.87 against Sleef_erfcf8_u15's 12.8
// (4e-6 against 8.5e-8: the kernels need 1e-5); erfcx, which SLEEF lacks, 0.20 against
// 13.6 for SLEEF's erfc times exp(x^2), which also overflows beyond x ~ 9.4.
//
// - fast_expf: Cephes' expf (range reduction by ln 2 in two parts, degree-5 polynomial,
//   2^n by exponent bits). Relative error <= 3e-7 for x in [-87, 88]; x < -87 gives 0
//   (the caller's optical depths are >= 0, so underflow only loses negligible light),
//   x > 88 is clamped (not used with such arguments here). fast_expf_le88 is the same
//   without that clamp, for exponents known to be <= 88 (minus optical depths, minus
//   squared distances): the clamp was measured at ~3 % of a Gaussian bake.
// - fast_erfc_pos: erfc(x) for x >= 0 by the Chebyshev-fitted form of Numerical Recipes
//   (erfcc: t = 1 / (1 + x/2), erfc = t exp(-x^2 - 1.26551223 + t P(t)), fractional error
//   < 1.2e-7 in exact arithmetic). In float, with fast_expf, the relative error is
//   <= 2e-6 for x <= 4 and grows like x^2 * 6e-8 beyond (rounding of -x^2): 1e-5 at x = 9,
//   where erfc ~ 4e-37; above ~9.3 the result is 0. x = +inf gives 0.
// - fast_erfcx_pos: the scaled erfcx(x) = exp(x^2) erfc(x) for x >= 0 as t Q(t), t = 1 / (1 +
//   x/2), Q of degree 8 fitted for relative error (a Lawson-weighted least-squares fit in
//   double: 4.3e-7; in float, <= 6.6e-7 up to x = 1e6, tested in gaussian/splat_test.cpp). No exp:
//   the kernels fold exp(-x^2) into the exponent of the Gaussian factor that multiplies it,
//   k0 e^{-a^2 h^2} erfc(x) = k0 e^{-(a^2 h^2 + x^2)} erfcx(x), and where a^2 h^2 + x^2 is
//   a constant of the Gaussian and the ray's origin (a^2 |b - o|^2, |d| = 1) the exp goes
//   altogether. x = +inf gives 0.
// - fast_erf_diff(x1, x2) = erf(x2) - erf(x1) for x1 <= x2, from erfc of |x| only, so the
//   tails keep their relative accuracy (as erf_diff in gaussian/medium.cpp does in double):
//     x1 >= 0: erfc(x1) - erfc(x2);  x2 <= 0: erfc(-x2) - erfc(-x1);  else 2 - erfc(-x1) - erfc(x2).
//   Error bound (asserted in gaussian/splat_test.cpp against the double erf_diff):
//     |fast - exact| <= 1e-5 exact + (4e-6 + 2.4e-7 m^2) max(erfc(|x1|), erfc(|x2|)) + 1e-37,
//   m = the larger finite one of |x1|, |x2| (both terms' errors): relative 1e-5 except where the difference itself cancels (a
//   short interval in one tail), where the error stays that fraction of the larger erfc
//   (1e-37: results in float's subnormal range).
#pragma once

#include <algorithm>
#include <cstdint>
#include <cstring>

namespace airlight {

// kUpper = false: the caller's x is <= 88 (the kernels' exponents are minus optical depths
// or minus squared distances), so the upper clamp is left out (one instruction per call).
template <bool kUpper = true>
inline float fast_expf_t(float x) {
    // Clamp (also maps -inf to -87.5: result 0 below).
    const float under = x < -87.0f ? 0.0f : 1.0f;
    x = std::max(x, -87.5f);
    if constexpr (kUpper) x = std::min(x, 88.0f);
    // n = round(x / ln 2), by the magic-number trick (no float -> int conversion of a
    // possibly out-of-range value, no branch): the low mantissa bits of fx + 1.5 * 2^23
    // hold round(x / ln 2) for |x / ln 2| < 2^22.
    const float magic = 12582912.0f;  // 1.5 * 2^23
    const float big = x * 1.44269504088896341f + magic;
    const float fn = big - magic;
    std::int32_t bits_big;
    std::memcpy(&bits_big, &big, sizeof bits_big);
    const std::int32_t n = bits_big - 0x4B400000;  // integer value of round(x / ln 2)
    float r = x - fn * 0.693359375f;
    r = r + fn * 2.12194440e-4f;
    const float r2 = r * r;
    float p = 1.9875691500e-4f;
    p = p * r + 1.3981999507e-3f;
    p = p * r + 8.3334519073e-3f;
    p = p * r + 4.1665795894e-2f;
    p = p * r + 1.6666665459e-1f;
    p = p * r + 5.0000001201e-1f;
    p = p * r2 + r + 1.0f;
    // 2^n by the exponent bits (n in [-126, 127] here).
    const std::int32_t bits = (n + 127) << 23;
    float scale;
    std::memcpy(&scale, &bits, sizeof scale);
    return p * scale * under;
}
inline float fast_expf(float x) { return fast_expf_t<true>(x); }
// exp(x) for x <= 88 (the kernels' minus optical depths and squared distances).
inline float fast_expf_le88(float x) { return fast_expf_t<false>(x); }

// erfc(x) for x >= 0 (x may be +inf: 0).
inline float fast_erfc_pos(float x) {
    const float t = 1.0f / (1.0f + 0.5f * x);
    float p = 0.17087277f;
    p = p * t - 0.82215223f;
    p = p * t + 1.48851587f;
    p = p * t - 1.13520398f;
    p = p * t + 0.27886807f;
    p = p * t - 0.18628806f;
    p = p * t + 0.09678418f;
    p = p * t + 0.37409196f;
    p = p * t + 1.00002368f;
    p = p * t - 1.26551223f;
    const float arg = p - x * x;  // <= 0 (p(1) = 0 at x = 0); -inf for x = inf: gives 0
    return t * fast_expf_le88(arg);
}

// exp(x^2) erfc(x) for x >= 0 (x may be +inf: 0).
inline float fast_erfcx_pos(float x) {
    const float t = 1.0f / (1.0f + 0.5f * x);
    float q = -4.385453665e-02f;
    q = q * t + 2.209448160e-01f;
    q = q * t - 3.771587521e-01f;
    q = q * t + 1.762806124e-01f;
    q = q * t + 2.778955593e-02f;
    q = q * t + 1.857297309e-01f;
    q = q * t + 2.460552806e-01f;
    q = q * t + 2.821190569e-01f;
    q = q * t + 2.820946695e-01f;
    return t * q;
}

// erf(x2) - erf(x1) for x1 <= x2 (x2 may be +inf; 0 if x2 <= x1 is not guaranteed:
// the caller passes ordered arguments).
inline float fast_erf_diff(float x1, float x2) {
    const float e1 = fast_erfc_pos(x1 < 0.0f ? -x1 : x1);
    const float e2 = fast_erfc_pos(x2 < 0.0f ? -x2 : x2);
    const float pos = e1 - e2;           // both >= 0
    const float neg = e2 - e1;           // both <= 0
    const float mid = 2.0f - e1 - e2;    // straddles 0
    return x1 >= 0.0f ? pos : (x2 <= 0.0f ? neg : mid);
}

}  // namespace airlight
