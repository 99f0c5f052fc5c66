// sun05_surface.h: Sun et al. 2005 surface radiance through fog (eq. 13-19, appendix B).
//
// A surface point p lit by an isotropic point light s of intensity I0 through homogeneous
// fog (extinction beta, albedo omega) receives the attenuated direct light and the light
// scattered once in the fog ("glow", eq. 15). For a BRDF that is constant (Lambert, f_r =
// k_d) or a Phong lobe reparameterised about the reflected view direction (cos^n):
//   Lp = I0 f_r [ e^{-Tsp} cos^m(theta_s) / Dsp^2 + omega beta G(Tsp, theta_s, m) / (2 pi Dsp) ]
// (eq. 17/18 with beta^2 / (2 pi Tsp) = beta / (2 pi Dsp), which stays finite as beta -> 0),
// m = 1 for Lambert (the paper's G0), m = n for Phong (the paper's Gn; theta_s then the
// angle between the light and the reflected view direction). With gamma the angle between an
// incident direction w_i and the light direction, psi its azimuth about the light direction:
//   G(T, theta_s, m) = int_0^pi H(T, gamma) W_m(gamma, theta_s) dgamma,
//   H(T, gamma) = e^{-T cos gamma} [F(T sin gamma, pi/2) - F(T sin gamma, gamma/2)]
//               = int_{gamma/2}^{pi/2} exp(-T cos(gamma - xi) / cos xi) dxi
//                 (no cancellation, no overflow: the exponent is -T - 2 T sin(gamma/2)
//                 sin(xi - gamma/2) / cos xi),
//   W_m(gamma, theta_s) = int_0^{2 pi} max(0, cos theta_i)^m dpsi,
//   cos theta_i = cos gamma cos theta_s + sin gamma sin theta_s cos psi
// (the paper's eq. 16 over the hemisphere in coordinates centred on the light direction:
// dw = sin gamma dgamma dpsi cancels eq. 16's 1/sin gamma). theta_s may exceed pi/2: a
// surface facing away from the light still receives glow. The fog is unbounded and unshadowed
// (the paper's assumption): Tvp = inf along every incident direction.
#pragma once

#include <functional>
#include <string>
#include <mutex>
#include <vector>

namespace airlight {

// Exact G(T, theta_s, m) (T >= 0, theta_s in [0, pi], m >= 1 real) by adaptive quadrature,
// ~1e-10 relative. m = 1: the inner azimuth integral in closed form.
double sun05_surface_G_exact(double T, double theta_s, double m);

// e^{T} G(T, theta_s, m), the same without underflow at large T.
double sun05_surface_G_scaled_exact(double T, double theta_s, double m);

// H(T, gamma) e^{T} (see above), ~1e-10 relative.
double sun05_surface_H_scaled(double T, double gamma);

// W_m(gamma, theta_s) (see above): closed form for m = 1, Gauss-Legendre otherwise.
double sun05_surface_W(double gamma, double theta_s, double m);

// The grid of the G tables, shared by SurfaceGTable and the phase-aware PhaseSurfaceGTable
// (biri06_surface.h): rows T_i = expm1((i / (nT - 1))^2 ln(1 + kTMax)) (0 ... kTMax), columns
// theta_j = pi j / (ntheta - 1), entries e^{T} G(T_i, theta_j, m) = int_0^pi H(T_i, g) e^{T_i}
// W_m(g, theta_j) dg by 8-point Gauss-Legendre panels between the kinks of every column's W_m
// and the row's extra breakpoints; bilinear lookup.
//
// Beyond kTMax (thick fog) a tail grid takes over, built on first use: the glow then comes
// from a cone ~1/T wide about the light, where e^{T} H ~ 4 pi p(1) / (T gamma) for gamma >> 1/T,
// so T e^{T} G = c(theta) ln T + B(theta) + O(ln T / T), c = 4 pi p(1) W_m(0, theta) (the
// forward phase value _forward_weight_ = 4 pi p(1); 1 for the isotropic phase). The tail
// stores Q = T e^{T} G - c ln T on rows log-spaced from kTMax to kTTail (same columns, same
// node rule), bilinear in (ln T, theta); beyond kTTail Q is held at its last row (its drift
// there, ~ln T / T, is below 1e-6 of T e^{T} G). Every density then costs the same per pixel.
class SurfaceGGrid {
  public:
    static constexpr double kTMax = 64.0;
    static constexpr double kTTail = 1e8;
    static constexpr int kTailRows = 40;
    // _row_cuts_(T, cuts) appends a row's extra gamma breakpoints; _H_scaled_(T, gamma) is
    // e^{T} H(T, gamma). Rows go to _threads_ worker threads (0: all). The two functions are
    // kept for the tail's build (they must outlive the grid's owner's use of it).
    // _cache_key_ (the owner's H and parameters; empty: not cached) keys its rows in the
    // table cache (table_cache.h).
    SurfaceGGrid(int nT, int ntheta, double m, int threads,
                 const std::function<void(double, std::vector<double>&)>& row_cuts,
                 const std::function<double(double, double)>& H_scaled, double forward_weight = 1.0,
                 const std::string& cache_key = "");
    // e^{T} G(T, theta_s) for every T >= 0 (the tail beyond kTMax).
    double lookup(double T, double theta_s) const;
    static double row_T(int i, int nT);
    static double row_position(double T, int nT);

  private:
    double lookup_body(double T, double theta_s) const;
    std::string grid_key(const char* part) const;
    double lookup_tail(double T, double theta_s) const;
    // Integrates row _T_ for every column into _out_[0, ntheta).
    void integrate_row(double T, double* out) const;
    void build_tail() const;

    int nT_, ntheta_;
    double m_, forward_weight_;
    int threads_;
    std::function<void(double, std::vector<double>&)> row_cuts_;
    std::function<double(double, double)> H_scaled_;
    std::string cache_key_;
    std::vector<double> data_;  // row-major [iT][itheta]
    mutable std::once_flag tail_once_;
    mutable std::vector<double> tail_;  // Q, row-major [row][itheta]
};

// Tabulated G for one exponent m (layout and measured error in sun05_surface.cpp).
class SurfaceGTable {
  public:
    // _nT_ x _ntheta_ samples; builds with _threads_ worker threads (0: all).
    explicit SurfaceGTable(double m = 1.0, int nT = 96, int ntheta = 64, int threads = 0);
    // G(T, theta_s) for every T >= 0 (beyond kTMax the grid's tail, SurfaceGGrid).
    double eval(double T, double theta_s) const;
    // e^{T} G(T, theta_s) (no exp: for callers that have e^{-T} already).
    double eval_scaled(double T, double theta_s) const;
    double exponent() const { return m_; }

  private:
    double m_;
    SurfaceGGrid grid_;
};

// Reference for tests: the surface single-scattering integral (eq. 15) by brute force,
// nested adaptive quadrature over incident directions and the distance along each one of
// (beta / 4 pi) e^{-beta r} / r^2 e^{-beta t} cos^m theta_i (I0 = 1, omega = 1), light at
// distance _D_ and angle _theta_s_ from the normal. Equals beta G(beta D, theta_s, m) /
// (2 pi D). Slow (seconds): tests only.
double sun05_surface_glow_reference(double beta, double D, double theta_s, double m, double rel_tol = 1e-7);

}  // namespace airlight
