// complex_e1.h: the complex exponential integral E1(z) = int_z^inf e^{-t}/t dt
// (principal branch, cut along the negative real axis), for Pegoraro et al. 2010.
//
// Recipe (as scipy's complex exp1): power series E1 = -gamma - log z - sum (-z)^k/(k k!)
// for |z| < 5 (and, on the negative real side where the series does not cancel,
// |arg(-z)| < atan(1/2) and |z| < 40); elsewhere the continued fraction DLMF 6.9.1
// (modified Lentz). On the cut the sign of Im z picks the side: E1(-x + i0) = -Ei(x) - i pi,
// E1(-x - i0) = -Ei(x) + i pi (signed zero honoured through std::log).
#pragma once

#include <complex>

namespace airlight {

using cplx = std::complex<double>;

// E1(z); z = 0 returns inf (the log singularity).
cplx complex_e1(cplx z);

// The scaled S(z) = e^z E1(z), finite where e^z or E1 alone overflow (large |z|).
cplx complex_e1_scaled(cplx z);

// e^{za} [E1(za) - E1(zb)] = int_za^zb e^{-(t - za)}/t dt along the straight segment (which
// must not cross the cut), without the cancellation of the two nearly equal terms when
// zb is close to za (|zb - za| <= 0.1 |za|: an 8-point Gauss-Legendre rule on the segment). zb may be
// complex infinity's stand-in: pass _zb_infinite_ = true for e^{za} E1(za).
cplx complex_e1_difference_scaled(cplx za, cplx zb, bool zb_infinite = false);

}  // namespace airlight
