// pegoraro10.h: closed-form single scattering for polynomial phase functions and light
// distributions (Pegoraro, Schott, Parker, EGSR 2010), homogeneous medium.
//
// Airlight of the view ray o + x d, x in [0, Dvp] (Dvp may be inf), from a point source at
// s with angular distribution I(c) (c = cosine between the light's axis and the direction
// light -> x), per unit I0 and albedo (sigma_s = sigma_t), phase p(mu) in 1/sr (phase.h:
// mu = cosine between propagation directions):
//   La = sigma_t int p(mu(x)) I(c(x)) exp(-sigma_t (d(x) + x)) / d(x)^2 dx.
// With the closest approach a (abscissa) and h (distance light-ray), x = a + h tan(phi),
// the paper's v = u + sqrt(1 + u^2) = tan(psi), psi = phi/2 + pi/4, turns this into
//   La = (sigma_t / h) e^{-sigma_t (a + h v0)} 2 int_{psi0}^{psi1} P(phi) e^{-H (tan psi - v0)} dpsi,
// H = sigma_t h, where P(phi) = p(-sin phi) I(del sin phi + dc cos phi) is a trigonometric
// polynomial of degree K = phase order + light order (del = d.axis, dc = n.axis, n the unit
// vector from the light to the closest point). So
//   int P e^{..} dpsi = sum_m c_m (-i)^m G_m,  G_m = int e^{2 i m psi} e^{-H (tan psi - v0)} dpsi,
// c_m the Fourier coefficients of P. G_0 = Im J and G_1 come from the complex exponential
// integral (J = e^{z0} [E1(z0) - E1(z1)], z = H (v - i), complex_e1.h); the others from the
// three-term recurrence obtained by integrating d/dpsi[cos^2 psi e^{2 i m psi} e^{-H tan psi}]:
//   (m+1) G_{m+1} + (2m + 2iH) G_m + (m-1) G_{m-1} = -2i [cos^2 psi e^{2imps} e^{-H(tan psi - v0)}]_{psi0}^{psi1}.
// This replaces the paper's expansion in powers of v / (1 + v^2) (eq. 14-22), whose partial
// fractions lose all digits at high order; the Fourier basis has |e^{2imps}| = 1. The
// recurrence is run forward for H <= 1.5 and K <= 40 (any K for H <= 0.3; K <= 4 up to
// H = 20) and otherwise solved as a boundary-value problem (Olver's algorithm: tridiagonal
// system up to 3K + 100 (+300/H below H = 3 for K > 40) rows with the integration-by-parts asymptote as
// end value); tests/native/test_pegoraro.py checks G_m to 1e-8 up to m = 100 in both regimes.
//
// Phase functions enter through their Legendre coefficients (eq. 11-13): 4 pi p(mu) =
// sum_n a_n P_n(mu), a_0 = 1. Henyey-Greenstein has a_n = (2n+1) g^n (infinite: truncated
// at the order asked for); Rayleigh (order 2), hazy Mie (8) and murky Mie (32) are exact
// polynomials. Polynomials are evaluated through the Legendre recurrence, never expanded
// into monomials (that expansion loses ~9 digits at order 32).
//
// Spot lights (Cycles 3.4 profile, spot_light.h): I(c) = c inside the blend cone and
// c smoothstep((c - cos_half) / smooth) in the blend annulus, 0 outside: exact polynomials of
// degree 1 and 4 on pieces of the ray delimited by analytic cone crossings, so no fitting
// is needed (fit error 0). An annulus piece whose degree-4 polynomial is ill-conditioned
// over the whole circle (its Fourier sum cancels by more than 1e6) is integrated by quadrature.
// So are the lit pieces of an area light's sample with a Spread below 180 deg: its profile
// sin(h - theta) is no polynomial in cos(theta), and a polynomial fit on [cos h, 1] converges
// slowly (sqrt(1 - c^2) at c = 1: degree 8 leaves 4 % on the axis) and cancels over the circle.
#pragma once

#include <complex>
#include <vector>

#include <glm/glm.hpp>

#include "core/phase.h"
#include "homogeneous/spot_light.h"

namespace airlight {

// A phase function as a Legendre polynomial, with the Fourier coefficients of p(-sin phi).
struct PegoraroPhase {
    std::vector<double> legendre;              // a_0 .. a_N, 4 pi p(mu) = sum a_n P_n(mu)
    std::vector<std::complex<double>> fourier;  // c_0 .. c_N of p(-sin phi) (c_{-m} = conj c_m)
    int order() const { return int(legendre.size()) - 1; }
    double eval(double mu) const;  // the polynomial p(mu) in 1/sr
};

// The phase polynomial of _phase_: exact for isotropic / Rayleigh / hazy / murky Mie
// (_order_ ignored), Henyey-Greenstein truncated at _order_ (>= 0).
PegoraroPhase pegoraro_phase(const PhaseFunction& phase, int order);
// Builds one from Legendre coefficients (a_0 should be 1 for a normalised phase).
PegoraroPhase pegoraro_phase_from_legendre(const std::vector<double>& legendre);
// Henyey-Greenstein order whose pointwise truncation bound sum_{n>N} (2n+1)|g|^n is at most
// _rel_tol_ times 4 pi p_min (the lobe's smallest value, so the bound is relative everywhere);
// -1 if no order up to _max_order_ meets it (|g| -> 1 needs hundreds).
int pegoraro_hg_order(double g, double rel_tol, int max_order = 96);
// pegoraro_phase with the HG order from pegoraro_hg_order (_max_order_ where none meets
// _rel_tol_); exact phases: their own order.
PegoraroPhase pegoraro_phase_auto(const PhaseFunction& phase, double rel_tol, int max_order = 96);

// G_m, m = 0.._K_, for H > 0 and 0 <= v0 < v1 (v1 may be inf), scaled by e^{H v0}.
void pegoraro_moments(double H, double v0, double v1, int K, std::complex<double>* G);

// Point light with the phase polynomial (isotropic distribution): same arguments as
// sun05_airlight (per unit I0 and albedo; Dvp may be inf). A ray through the light (h = 0)
// diverges physically: h is regularised to >= 1e-7 Dsv (a large finite value), as sun05.
double pegoraro10_airlight(const PegoraroPhase& phase, double sigma_t, double Dsv, double cos_gamma, double Dvp);

// General light distribution I(c) = sum_k light[k] c^k about _axis_ (unit), over the part
// of the ray [x0, x1] (x1 may be inf; 0 <= x0), light at _s_, ray o + x d (d unit).
double pegoraro10_airlight_poly(const PegoraroPhase& phase, const std::vector<double>& light,
                                const glm::dvec3& axis, double sigma_t, const glm::dvec3& s, const glm::dvec3& o,
                                const glm::dvec3& d, double x0, double x1);

// Blender spot light (exact piecewise profile), like spot_airlight_quadrature.
double pegoraro10_spot_airlight(const PegoraroPhase& phase, const SpotCone& cone, const glm::dvec3& s,
                                double sigma_t, const glm::dvec3& o, const glm::dvec3& d, double Dvp);

}  // namespace airlight
