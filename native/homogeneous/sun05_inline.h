// sun05_inline.h: the hot (table) path of the Sun 2005 airlight, header-only so the
// bake can inline it. shaders/sun05_airlight.glsl mirrors these functions line for
// line with the same names; change both together.
//
// Reduction used everywhere (derived from eq. 5 with x - a = h tan(theta)):
//   a = Dsv cos(gamma)  closest-approach abscissa,  h = Dsv sin(gamma)  closest distance,
//   n(x) = d(x) + x - a  (so sigma_t (d + x) = sigma_t (a + n)),   t = n / h = tan(xi),
//   La = sigma_t / (2 pi h) e^{-sigma_t a} [F(u, t1) - F(u, t0)],  u = sigma_t h   (eq. 11)
//      = sigma_t / (2 pi) e^{-sigma_t Dsv} E,  E = int_{n0}^{n1} e^{-sigma_t (n - n0)} / (h^2 + n^2) dn
//   n0 = Dsv (1 - cos gamma), n1 = d_p + Dvp - a (d_p: light-surface distance), both
//   computed without cancellation; dn = n1 - n0 = Dvp (n0 + n1) / (d_p + Dsv).
// The F difference is used when it is well conditioned (F1 - F0 > kCancel F1); otherwise
// E is integrated directly with 8-point Gauss-Legendre in a variable matched to the
// integrand (sun05_direct_E), which also covers h = 0 (gamma = pi exactly).
#pragma once

#include <algorithm>
#include <cmath>

#include "core/constants.h"
#include "core/special_f.h"

namespace airlight {

namespace sun05 {

// Below this sin(gamma) (the smallest nonzero value a double cos(gamma) can give is
// ~1.05e-8) a ray through the light is regularised to sin(gamma) = kSinGammaMin: the
// exact value diverges like 1/gamma, while a pixel integrates it to a finite value.
constexpr double kSinGammaMin = 1e-8;
// The viewer inside the light (Dsv -> 0) diverges like 1/Dsv; Dsv is clamped to this.
constexpr double kDsvMin = 1e-6;
// F1 - F0 must exceed kCancel F1 for the table difference to be used.
constexpr double kCancel = 0.125;

// 4-point Gauss-Legendre on [0, 1].
constexpr double kGL4x[4] = {0.06943184420297371, 0.33000947820757187, 0.6699905217924281,
                             0.9305681557970262};
constexpr double kGL4w[4] = {0.17392742256872692, 0.3260725774312731, 0.3260725774312731,
                             0.17392742256872692};
// 8-point Gauss-Legendre on [0, 1].
constexpr double kGLx[8] = {0.019855071751231856, 0.10166676129318664, 0.2372337950418355,
                            0.4082826787521751,   0.5917173212478249,  0.7627662049581645,
                            0.8983332387068134,   0.9801449282487681};
constexpr double kGLw[8] = {0.05061426814518813, 0.11119051722668724, 0.15685332293894363,
                            0.18134189168918100, 0.18134189168918100, 0.15685332293894363,
                            0.11119051722668724, 0.05061426814518813};

}  // namespace sun05

// Bilinear lookup of the stored Q(s, w) (row-major [i over s][j over w]).
inline double special_F_table_Q(const float* data, int nu, int nT, double s, double w) {
    const double x = s * (nu - 1), y = w * (nT - 1);
    const int i = std::min(static_cast<int>(x), nu - 2), j = std::min(static_cast<int>(y), nT - 2);
    const double fx = x - i, fy = y - j;
    const float* r0 = data + static_cast<long>(i) * nT + j;
    const float* r1 = r0 + nT;
    return (1.0 - fx) * ((1.0 - fy) * r0[0] + fy * r0[1]) + fx * ((1.0 - fy) * r1[0] + fy * r1[1]);
}

// Nearest-neighbour lookup of Q(s, w): the closest sample, rounded as SpecialFTable::eval_tan
// does (half away from zero); cheaper (one load, no blend) and ~20x less accurate (special_f.cpp).
inline double special_F_table_Q_nearest(const float* data, int nu, int nT, double s, double w) {
    const int i = std::clamp(static_cast<int>(s * (nu - 1) + 0.5), 0, nu - 1);
    const int j = std::clamp(static_cast<int>(w * (nT - 1) + 0.5), 0, nT - 1);
    return data[static_cast<long>(i) * nT + j];
}

// Q(s, w) with the chosen interpolation.
inline double special_F_table_Q(const float* data, int nu, int nT, double s, double w, Interp interp) {
    return interp == Interp::Nearest ? special_F_table_Q_nearest(data, nu, nT, s, w)
                                     : special_F_table_Q(data, nu, nT, s, w);
}

// Row coordinate s in [0, 1] of _u_ (s = 1 is u = inf).
inline double special_F_table_s(double u) { return std::sqrt(u / (u + kSpecialFTableK)); }

// F(u, T) from the table; T_is_inf selects T = +inf (w = 1). u, T >= 0 finite.
inline double special_F_table_eval(const float* data, int nu, int nT, double u, double T, bool T_is_inf) {
    const double s = special_F_table_s(u);
    const double tau = T * (1.0 + u);
    const double w = T_is_inf ? 1.0 : tau / (1.0 + tau);
    return special_F_table_Q(data, nu, nT, s, w) * w / (1.0 + u);
}

// F(u, t0) and F(u, t1) from the table with t = n / h, sharing the row coordinate
// (w = tau / (1 + tau) with tau = n (1 + u) / h takes one division).
inline void special_F_table_pair(const float* data, int nu, int nT, double u, double h, double n0, double n1,
                                 bool n1_is_inf, double* F0, double* F1, Interp interp = Interp::Bilinear) {
    const double s = special_F_table_s(u);
    // F = Q w / (1 + u) = Q n / (h + n (1 + u)).
    const double m0 = n0 * (1.0 + u), m1 = n1 * (1.0 + u);
    const double r0 = 1.0 / (h + m0), r1 = 1.0 / (h + m1);
    const double w0 = m0 * r0;
    const double w1 = n1_is_inf ? 1.0 : m1 * r1;
    *F0 = special_F_table_Q(data, nu, nT, s, w0, interp) * n0 * r0;
    *F1 = special_F_table_Q(data, nu, nT, s, w1, interp) * (n1_is_inf ? 1.0 / (1.0 + u) : n1 * r1);
}

// Ray geometry of one (view ray, light) pair, see the header comment.
struct Sun05Geometry {
    double Dsv, a, h, n0, n1, dn;  // dn is filled by sun05_geometry_dn (direct paths only)
    double d_p;                    // light-surface distance
    bool Dvp_inf;
    bool behind_limit;  // gamma = 0 exactly with the light behind the surface: closed form
};

inline Sun05Geometry sun05_geometry(double Dsv, double cos_gamma, double Dvp) {
    Sun05Geometry g;
    g.Dsv = std::max(Dsv, sun05::kDsvMin);
    const double c = std::clamp(cos_gamma, -1.0, 1.0);
    double omc = 1.0 - c, opc = 1.0 + c;
    double sin_g = std::sqrt(omc * opc);
    g.a = g.Dsv * c;
    g.behind_limit = false;
    // Ray (almost) through the light with the light in front of the surface: regularise.
    if (sin_g < sun05::kSinGammaMin && c > 0.0) {
        if (Dvp < g.Dsv && omc == 0.0) {
            g.behind_limit = true;
        } else {
            sin_g = sun05::kSinGammaMin;
            omc = 0.5 * sin_g * sin_g;
            opc = 2.0 - omc;
        }
    }
    g.h = g.Dsv * sin_g;
    g.n0 = g.Dsv * omc;
    g.Dvp_inf = std::isinf(Dvp);
    if (g.Dvp_inf) {
        g.n1 = g.dn = g.d_p = INFINITY;
    } else {
        const double dx = Dvp - g.a;
        g.d_p = std::sqrt(g.h * g.h + dx * dx);
        g.n1 = dx >= 0.0 ? g.d_p + dx : g.h * g.h / (g.d_p - dx);
        g.dn = 0.0;
    }
    return g;
}

// n1 - n0 without cancellation: d_p - Dsv + Dvp = Dvp (n0 + n1) / (d_p + Dsv).
inline void sun05_geometry_dn(Sun05Geometry& g, double Dvp) {
    if (!g.Dvp_inf) g.dn = Dvp * (g.n0 + g.n1) / (g.d_p + g.Dsv);
}

// int_0^len e^{-sigma_t l} / (h^2 + (n0 + l)^2) dl, by 8-point Gauss-Legendre after
// the substitution that makes the exponential uniform (len may be inf).
inline double sun05_direct_exp(double sigma_t, double h, double n0, double len) {
    const double x = sigma_t * len;
    const double q = -std::expm1(-x);  // 1 - e^{-sigma_t len}, = 1 for len = inf
    double sum = 0.0;
    for (int k = 0; k < 8; ++k) {
        const double n = n0 - std::log1p(-sun05::kGLx[k] * q) / sigma_t;
        sum += sun05::kGLw[k] / (h * h + n * n);
    }
    return sum * q / sigma_t;
}

// int_{na}^{nb} e^{-sigma_t (n - n0)} / (h^2 + n^2) dn with n = 1/s, graded toward s = 1/nb
// (nb may be inf); needs na >= h so that 1 / (1 + h^2 s^2) is smooth.
inline double sun05_direct_inv(double sigma_t, double h, double n0, double na, double nb) {
    const double sa = 1.0 / na, sb = 1.0 / nb;  // sb = 0 for nb = inf
    const double span = sa - sb;
    double sum = 0.0;
    for (int k = 0; k < 8; ++k) {
        const double rho = sun05::kGLx[k];
        const double s = sb + span * rho * rho;
        sum += sun05::kGLw[k] * 2.0 * rho * std::exp(-sigma_t * (1.0 / s - n0)) / (1.0 + h * h * s * s);
    }
    return sum * span;
}

// E = int_{n0}^{n1} e^{-sigma_t (n - n0)} / (h^2 + n^2) dn evaluated directly.
inline double sun05_direct_E(double sigma_t, const Sun05Geometry& g) {
    const double m = std::max(g.n0, g.h);           // scale over which 1/(h^2+n^2) varies
    if (g.dn <= m && sigma_t * g.dn <= 1.0) {
        // Short interval, everything smooth: 4-point Gauss-Legendre in n.
        double sum = 0.0;
        for (int k = 0; k < 4; ++k) {
            const double l = sun05::kGL4x[k] * g.dn, n = g.n0 + l;
            sum += sun05::kGL4w[k] * std::exp(-sigma_t * l) / (g.h * g.h + n * n);
        }
        return sum * g.dn;
    }
    const double reach = std::min(g.dn, 8.0 / sigma_t);  // where the exponential has decayed
    if (g.n0 + reach <= 2.0 * m) return sun05_direct_exp(sigma_t, g.h, g.n0, g.dn);
    double E = 0.0, start = g.n0;
    if (g.n0 < g.h) {
        E += sun05_direct_exp(sigma_t, g.h, g.n0, g.h - g.n0);
        start = g.h;
    }
    return E + sun05_direct_inv(sigma_t, g.h, g.n0, start, g.n1);
}

// Moves the viewer of _g_ (from sun05_geometry) forward along the ray to x = _t0_ > 0
// (the near clip plane), so the airlight below covers only the segment [t0, Dvp] and is
// attenuated from the new viewer, as Cycles integrates from the near plane. The
// reduction is invariant under the shift: h and n1 stay, a -> a - t0, Dsv -> the
// distance d0 from o + t0 d to the light, n0 -> n(t0) = d0 + t0 - a (cancellation-free,
// like n1), so La over [t0, t1] = sigma_t / (2 pi h) e^{-sigma_t (a - t0)} [F(u, n1 / h)
// - F(u, n(t0) / h)]: the same cost as from the eye, two table columns. Dvp - t0 is the
// new view-segment length; the caller has checked Dvp > t0. Not for behind_limit.
inline void sun05_geometry_shift(Sun05Geometry& g, double t0) {
    const double dx0 = t0 - g.a;
    const double d0 = std::sqrt(g.h * g.h + dx0 * dx0);
    g.n0 = dx0 >= 0.0 ? d0 + dx0 : g.h * g.h / (d0 - dx0);
    g.a = -dx0;
    g.Dsv = std::max(d0, sun05::kDsvMin);
}

// Closed form for gamma = 0 with the light behind the surface (Dvp < Dsv).
inline double sun05_behind_limit(double sigma_t, double Dsv, double Dvp) {
    return sigma_t * std::exp(-sigma_t * Dsv) * Dvp / (4.0 * kPi * Dsv * (Dsv - Dvp));
}

// Airlight per unit I0 and albedo, table path. Inputs assumed valid (see sun05_check_inputs).
// _t0_ > 0: only the part of the view ray beyond x = t0 (the near clip plane), attenuated
// from there (sun05_geometry_shift); t0 = 0 is the whole ray from the eye. _interp_: the
// table lookup (the table's own SpecialFTable::interp()).
inline double sun05_airlight_table(const float* data, int nu, int nT, double sigma_t, double Dsv,
                                   double cos_gamma, double Dvp, double t0 = 0.0,
                                   Interp interp = Interp::Bilinear) {
    if (!(sigma_t > 0.0) || !(Dvp > t0) || !(t0 >= 0.0)) return 0.0;
    Sun05Geometry g = sun05_geometry(Dsv, cos_gamma, Dvp);
    if (g.behind_limit) {
        // gamma = 0, light behind the surface: the shifted viewer sees the same limit.
        if (t0 > 0.0) return sun05_behind_limit(sigma_t, std::max(g.Dsv - t0, sun05::kDsvMin), Dvp - t0);
        return sun05_behind_limit(sigma_t, g.Dsv, Dvp);
    }
    if (t0 > 0.0) {
        sun05_geometry_shift(g, t0);
        Dvp -= t0;
    }
    if (g.h > 0.0) {
        const double u = sigma_t * g.h;
        double F0, F1;
        special_F_table_pair(data, nu, nT, u, g.h, g.n0, g.n1, g.Dvp_inf, &F0, &F1, interp);
        const double G = F1 - F0;
        if (G > sun05::kCancel * F1)
            return sigma_t / (2.0 * kPi * g.h) * std::exp(-sigma_t * g.a) * G;
    }
    sun05_geometry_dn(g, Dvp);
    return sigma_t / (2.0 * kPi) * std::exp(-sigma_t * g.Dsv) * sun05_direct_E(sigma_t, g);
}

}  // namespace airlight
