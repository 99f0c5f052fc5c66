// biri06.h: homogeneous single scattering from a point light with ANY phase function
// (Biri, Arques, Michelin 2006, eq. 3-7), its Gamma table, and the quadrature reference.
//
// Geometry of one view ray as in sun05.h: viewer v, light s at distance _Dsv_, _gamma_ the
// angle between the view ray and v->s, surface at _Dvp_ (may be inf). a = Dsv cos gamma is
// the abscissa of the closest approach, h = Dsv sin gamma its distance to the light.
// Phase angle (phase.h convention) at x: cos theta(x) = (a - x) / d(x), d = |x - s|.
//
// Re-derivation of Biri eq. 4-7 (the paper's typesetting is mangled). With x - a = h tan alpha:
//   dx / d^2 = dalpha / h,  x + d = a + h (1 + sin alpha) / cos alpha,  cos theta = -sin alpha,
// so theta = alpha + pi/2 (the paper's p(alpha + pi/2)), and with theta = alpha + pi/2,
// (1 + sin alpha)/cos alpha = tan(theta/2):
//   La = sigma_s int_0^Dvp p(cos theta) e^{-sigma_t (d + x)} / d^2 dx
//      = (sigma_s / h) e^{-sigma_t a} [G(lambda, T1) - G(lambda, T0)],   lambda = sigma_t h,
//   G(lambda, T) = int_0^{2 atan T} p(cos theta) e^{-lambda tan(theta/2)} dtheta,
//   T0 = tan(gamma/2) (theta at the viewer is gamma), T1 = tan(theta1/2), theta1 the phase
//   angle at the surface point (pi when Dvp = inf).
// Biri's Gamma (eq. 6, lower limit alpha = 0, i.e. theta = pi/2) is the same function
// shifted: Gamma(lambda, g) = G(lambda, tan(pi/4 + g/2)) - G(lambda, 1); the constant
// cancels in eq. 7. G starts at theta = 0 instead so that it is >= 0 and monotone in T,
// which lets the table store a quantity proportional to it (relative error), and it is
// Sun 2005's F for the isotropic phase: G = F(lambda, atan T) / (2 pi).
// Per unit I0 and albedo: sigma_s = sigma_t. Multiply by albedo * I0 (W/sr).
#pragma once

#include <memory>
#include <vector>

#include "core/phase.h"

namespace airlight {

// The most backward HG lobe the table resolves: below g = -0.99 the lobe near theta = pi is
// squeezed into the last columns and the airlight errs by more than 1 % (2 % at g = -0.995,
// 16 % at -0.999; biri06.cpp). Forward lobes have no such limit (|g| < 1: 1e-5 at 0.9999).
inline constexpr double kBiri06MinG = -0.99;

// Throws std::invalid_argument for HG g < kBiri06MinG, saying which model takes it.
void biri06_check_phase(const PhaseFunction& phase);

// G(lambda, T) tabulated for one phase function (layout and measured error in biri06.cpp).
// Refuses what biri06_check_phase refuses.
// HG tables are built per g on demand (~20 ms at 256 x 256) and cached: a scene has one g
// per medium, and a per-g table avoids interpolating a lobe whose shape changes fast in g.
class Biri06Table {
  public:
    explicit Biri06Table(const PhaseFunction& phase, int nl = 256, int nT = 256);

    // G(lambda, T), lambda >= 0, T >= 0 (either may be +inf). Never clamps: the axes cover
    // [0, inf] and the end rows/columns hold the analytic limits.
    double eval(double lambda, double T) const;

    const PhaseFunction& phase() const { return phase_; }
    int nl() const { return nl_; }
    int nT() const { return nT_; }
    double K() const { return K_; }  // column stretch: tau = T (K + lambda)
    double k() const { return k_; }  // row scale: s = sqrt(lambda / (lambda + k))
    const std::vector<float>& data() const { return data_; }

  private:
    PhaseFunction phase_;
    int nl_, nT_;
    double K_, k_;
    std::vector<float> data_;
};

// The table for _phase_, built once per (phase, g, nl, nT) and shared (thread-safe).
std::shared_ptr<const Biri06Table> shared_biri06_table(const PhaseFunction& phase, int nl = 256, int nT = 256);

// Exact scaled G difference
//   int_{theta0}^{theta1} p(cos theta) exp(-lambda [tan(theta/2) - tan(theta0/2)]) dtheta,
// 0 <= theta0 <= theta1 <= pi, by adaptive Gauss-Kronrod (~1e-12 relative): no subtraction,
// no overflow. G(lambda, T) = biri06_G_diff_exact(phase, lambda, 0, 2 atan T).
double biri06_G_diff_exact(const PhaseFunction& phase, double lambda, double theta0, double theta1);
double biri06_G_exact(const PhaseFunction& phase, double lambda, double T);

// Biri's eq. 6 as printed, Gamma(lambda, g) = int_0^g p(cos(alpha + pi/2))
// e^{-lambda (sin alpha + 1)/cos alpha} dalpha, g in (-pi/2, pi/2), by direct quadrature in
// alpha (used by the tests to check the re-derivation above).
double biri06_Gamma_paper(const PhaseFunction& phase, double lambda, double g);

enum class GammaEval { Table, Exact };

// Airlight per unit I0 and albedo (see the header comment). _table_ is required for
// GammaEval::Table and must be built for _phase_. The table path falls back to the exact
// difference where the lookup difference would cancel (G1 - G0 < G1 / 16) or overflow;
// biri06.cpp states how often that happens. A ray through the light is regularised as in
// sun05 (sin gamma >= 1e-8); at gamma = pi exactly that puts theta within 1e-8 of pi, where
// the exact path is good to ~1e-6 relative (not 1e-12). Inputs are validated by sun05_check_inputs (throws).
double biri06_airlight(const PhaseFunction& phase, double sigma_t, double Dsv, double cos_gamma, double Dvp,
                       const Biri06Table* table, GammaEval how, bool* used_exact = nullptr);

// Reference: adaptive quadrature in x of
//   La = sigma_t int_0^Dvp p(cos theta(x)) e^{-sigma_t d(x)} / d(x)^2 e^{-sigma_t x} dx
// (per unit I0 and albedo). Equals sun05_airlight_quadrature for the isotropic phase.
double phase_airlight_quadrature(const PhaseFunction& phase, double sigma_t, double Dsv, double cos_gamma,
                                 double Dvp, double rel_tol = 1e-10);

}  // namespace airlight
