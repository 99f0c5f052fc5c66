// hoffman02.cpp: Hoffman & Preetham 2002 sun aerial perspective (see hoffman02.h).
#include "homogeneous/hoffman02.h"

#include <cmath>
#include <stdexcept>

#include "core/phase.h"
#include "core/quadrature.h"

namespace airlight {

void hoffman02_rayleigh_rgb(double beta_R_550, double beta_R[3]) {
    for (int c = 0; c < 3; ++c) {
        const double r = kHoffman02RefLambdaNm / kHoffman02LambdaNm[c];
        beta_R[c] = beta_R_550 * (r * r) * (r * r);
    }
}

void hoffman02(const Hoffman02Medium& m, const double E_sun[3], double cos_theta, double s, double F_ex[3],
               double L_in[3]) {
    const PhaseFunction rayleigh{PhaseKind::Rayleigh, 0.0}, mie{PhaseKind::HenyeyGreenstein, m.g};
    const double pR = rayleigh.eval(cos_theta), pM = mie.eval(cos_theta);
    for (int c = 0; c < 3; ++c) {
        const double beta = m.beta_R[c] + m.beta_M[c];
        F_ex[c] = std::exp(-beta * s);
        // (1 - F_ex) / beta times the angular coefficients; beta = 0 -> no fog at all.
        L_in[c] = beta > 0.0 ? (m.beta_R[c] * pR + m.beta_M[c] * pM) / beta * E_sun[c] * -std::expm1(-beta * s) : 0.0;
    }
}

double hoffman02_cos_theta(const double sun_dir[3], const double view_dir[3]) {
    const double ls = std::sqrt(sun_dir[0] * sun_dir[0] + sun_dir[1] * sun_dir[1] + sun_dir[2] * sun_dir[2]);
    const double lv = std::sqrt(view_dir[0] * view_dir[0] + view_dir[1] * view_dir[1] + view_dir[2] * view_dir[2]);
    if (!(ls > 0.0) || !(lv > 0.0)) throw std::invalid_argument("hoffman02: zero direction");
    return -(sun_dir[0] * view_dir[0] + sun_dir[1] * view_dir[1] + sun_dir[2] * view_dir[2]) / (ls * lv);
}

void hoffman02_quadrature(const Hoffman02Medium& m, const double E_sun[3], const double sun_dir[3],
                          const double view_dir[3], double s, double L_in[3]) {
    const PhaseFunction rayleigh{PhaseKind::Rayleigh, 0.0}, mie{PhaseKind::HenyeyGreenstein, m.g};
    double ls = 0.0, lv = 0.0;
    for (int k = 0; k < 3; ++k) {
        ls += sun_dir[k] * sun_dir[k];
        lv += view_dir[k] * view_dir[k];
    }
    ls = std::sqrt(ls);
    lv = std::sqrt(lv);
    for (int c = 0; c < 3; ++c) {
        const double beta = m.beta_R[c] + m.beta_M[c];
        auto f = [&](double x) {
            // Point X = x view_dir; the scattered direction is X -> viewer = -X / |X|.
            double cos_theta = 0.0;
            for (int k = 0; k < 3; ++k) cos_theta += (sun_dir[k] / ls) * (-(x * view_dir[k] / lv) / x);
            return (m.beta_R[c] * rayleigh.eval(cos_theta) + m.beta_M[c] * mie.eval(cos_theta)) * E_sun[c] *
                   std::exp(-beta * x);
        };
        L_in[c] = beta > 0.0 ? integrate_adaptive(f, 0.0, s, 1e-12) : 0.0;
    }
}

}  // namespace airlight
