// quadrature.h: exact references by adaptive quadrature.
#pragma once

#include <functional>
#include <vector>

namespace airlight {

// Gauss-Legendre nodes _x_ and weights _w_ of order _n_ on [-1, 1] (Newton on the Legendre
// recurrence; exact for polynomials of degree 2n - 1). Boost.Math's gauss<N> fixes N at
// compile time; the callers choose n at run time. Against Boost's correctly rounded tables
// (benchmarks/libraries/library_bench): abscissae within 1 ulp, weights within 124 ulp (3e-14).
void gauss_legendre(int n, std::vector<double>& x, std::vector<double>& w);

// Gauss-Laguerre nodes _x_ and weights _w_ of order _n_: int_0^inf e^{-x} f(x) dx ~
// sum w_i f(x_i), exact for polynomials of degree 2n - 1 (Boost.Math has no Laguerre rule).
void gauss_laguerre(int n, std::vector<double>& x, std::vector<double>& w);

// Adaptive Gauss-Kronrod (7-15) integration of f over [a, b] (b may be +inf, handled
// by a change of variables) to relative tolerance _rel_tol_: globally adaptive (QUADPACK's
// QAG, the worst panel split first, at most 20000 panels), which the references need.
// Boost.Math's gauss_kronrod<15> is locally recursive: 1.3-1.6x faster on smooth or peaked
// integrands, but on 1/sqrt(x) over [0, 1] it took 1.5e6 evaluations and 4.6 ms for 7e-7
// where this takes 1815 and 14 us for 2e-11 (benchmarks/libraries/library_bench).
double integrate_adaptive(const std::function<double(double)>& f, double a, double b,
                          double rel_tol = 1e-10, double abs_tol = 0.0, int max_depth = 60,
                          int max_panels = 20000);

// Integrates f over [cuts[0], end] piecewise between the sorted breakpoints _cuts_ (each
// piece to rel_tol / 10). When _end_ is +inf the tail beyond the last cut is mapped to
// [0, 1) by x = last + L t / (1 - t), L = max(last, tail_scale). _abs_tol_, shared by the
// pieces, ends the refinement of a piece whose own integral is ~0 (a shadowed one);
// _max_panels_ bounds each piece's work (integrate_adaptive).
double integrate_piecewise(const std::function<double(double)>& f, const std::vector<double>& cuts,
                           double end, double tail_scale, double rel_tol, double abs_tol = 0.0,
                           int max_panels = 20000);

// Integrates f over [lo, hi] by integrate_adaptive between the breakpoints _cuts_ that fall
// inside it (any order; those outside are ignored), each piece to _rel_tol_.
double integrate_cut(const std::function<double(double)>& f, double lo, double hi, std::vector<double> cuts,
                     double rel_tol);

// Reference airlight: adaptive quadrature of Sun 2005 eq. 5 with I0 = 1, omega = 1,
//   La = sigma_t/(4 pi) int_0^Dvp exp(-sigma_t d(x)) / d(x)^2 * exp(-sigma_t x) dx,
//   d(x)^2 = Dsv^2 + x^2 - 2 x Dsv cos_gamma.
double sun05_airlight_quadrature(double sigma_t, double Dsv, double cos_gamma, double Dvp,
                                 double rel_tol = 1e-10);

}  // namespace airlight
