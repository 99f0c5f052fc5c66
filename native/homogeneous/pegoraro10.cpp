// pegoraro10.cpp: Pegoraro et al. 2010 closed form (see pegoraro10.h for the derivation).
#include "homogeneous/pegoraro10.h"
#include "core/constants.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "core/complex_e1.h"
#include "core/quadrature.h"

namespace airlight {

namespace {

// Largest trigonometric degree K handled (phase order + light order).
constexpr int kMaxDegree = 132;
// The light distribution's largest order (an IES fit of degree 16 times a spot's blend, degree 4).
constexpr int kMaxLightOrder = 20;
// The recurrence runs forward below this H (= sigma_t h); above it, Olver's algorithm.
constexpr double kForwardMaxH = 1.5;
// A blend-annulus piece whose Fourier sum cancels more than this (sum |terms| / |sum|; the
// degree-4 smoothstep polynomial is large on the rest of the circle) is integrated by
// quadrature instead (to 1e-7). The moments G_m carry ~1e-12 relative errors, so 1e6 leaves
// ~1e-6 at worst (typically 1e-9: pegoraro10 tests).
constexpr double kMaxCancellation = 1e6;
// Relative tolerance of the pieces integrated by quadrature (thin blend annuli, Spread).
constexpr double kPieceQuadratureTol = 1e-7;

// v = u + sqrt(1 + u^2) without cancellation for u < 0.
double v_of_u(double u) {
    if (std::isinf(u)) return u > 0.0 ? std::numeric_limits<double>::infinity() : 0.0;
    const double r = std::hypot(1.0, u);
    return u >= 0.0 ? u + r : 1.0 / (r - u);
}

// Geometry of a ray relative to a light: closest approach abscissa _a_, distance _h_
// (regularised to >= 1e-7 |o - s|, 1e-12: a ray through the light diverges physically),
// unit vector _n_ from the light to the closest point.
struct RayFrame {
    double a = 0.0, h = 0.0;
    glm::dvec3 n{1.0, 0.0, 0.0};
};

RayFrame ray_frame(const glm::dvec3& s, const glm::dvec3& o, const glm::dvec3& d) {
    RayFrame f;
    const glm::dvec3 w = o - s;
    f.a = -glm::dot(w, d);
    const glm::dvec3 perp = w + f.a * d;
    const double len = glm::length(perp);
    const double h_min = std::max(1e-7 * glm::length(w), 1e-12);
    if (len > 0.0) f.n = perp / len;
    else f.n = glm::normalize(std::abs(d.x) < 0.9 ? glm::cross(d, glm::dvec3(1, 0, 0)) : glm::cross(d, glm::dvec3(0, 1, 0)));
    f.h = std::max(len, h_min);
    return f;
}

// sigma_t int_{x0}^{x1} P(phi(x)) e^{-sigma_t (x + d)} / d^2 dx with P = sum_m coef[m] e^{i m phi}
// (coef[0.._K_], the negative ones conjugate).
// _cancel_ (if given) receives sum |terms| / |sum|, the digits the Fourier sum cancels.
double segment_integral(const cplx* coef, int K, double sigma_t, double a, double h, double x0, double x1,
                        double* cancel = nullptr) {
    if (cancel) *cancel = 1.0;
    if (!(x1 > x0) || sigma_t == 0.0) return 0.0;
    const double H = sigma_t * h;
    const double v0 = v_of_u((x0 - a) / h);
    const double v1 = std::isinf(x1) ? std::numeric_limits<double>::infinity() : v_of_u((x1 - a) / h);
    if (!(v1 > v0)) return 0.0;
    std::array<cplx, kMaxDegree + 1> G;
    pegoraro_moments(H, v0, v1, K, G.data());
    double sum = coef[0].real() * G[0].real(), mag = std::abs(sum);
    cplx rot = 1.0;  // (-i)^m
    for (int m = 1; m <= K; ++m) {
        rot *= cplx(0.0, -1.0);
        const cplx t = coef[m] * rot * G[m];
        sum += 2.0 * t.real();
        mag += 2.0 * std::abs(t);
    }
    if (cancel) *cancel = mag / std::max(std::abs(sum), 1e-300);
    const double d0 = std::hypot(x0 - a, h);
    return sigma_t / h * std::exp(-sigma_t * (x0 + d0)) * 2.0 * sum;
}

// Fourier coefficients (m >= 0) of p(-sin phi) I(del sin phi + dc cos phi), I = sum light[k] c^k.
int combined_coefficients(const PegoraroPhase& phase, const double* light, int M, double del, double dc, cplx* out) {
    const int N = phase.order();
    const int K = N + M;
    if (K > kMaxDegree) throw std::invalid_argument("pegoraro10: phase order + light order exceeds 132");
    // Laurent coefficients of I(c(phi)), index j + M for e^{i j phi}; c = (beta z + conj(beta)/z)/2.
    if (M > kMaxLightOrder) throw std::invalid_argument("pegoraro10: light order must be 0..20");
    std::array<cplx, 2 * kMaxLightOrder + 1> L{};
    const cplx beta(dc, -del);
    // Horner: I = (((l_M) c + l_{M-1}) c + ...) .
    std::array<cplx, 2 * kMaxLightOrder + 1> T{};
    L[M] = light[M];
    for (int k = M - 1; k >= 0; --k) {
        T.fill(0.0);
        for (int j = -M; j <= M; ++j) {
            const cplx v = L[j + M];
            if (v == 0.0) continue;
            if (j + 1 <= M) T[j + 1 + M] += 0.5 * beta * v;
            if (j - 1 >= -M) T[j - 1 + M] += 0.5 * std::conj(beta) * v;
        }
        T[M] += light[k];
        L = T;
    }
    // Product with the phase's two-sided coefficients.
    auto ph = [&](int j) -> cplx {
        if (j > N || j < -N) return 0.0;
        return j >= 0 ? phase.fourier[j] : std::conj(phase.fourier[-j]);
    };
    for (int m = 0; m <= K; ++m) {
        cplx acc = 0.0;
        for (int j = -M; j <= M; ++j) acc += L[j + M] * ph(m - j);
        out[m] = acc;
    }
    return K;
}

// The product of the polynomial a_0 .. a_M and _profile_ (monomials; empty: 1) into _out_
// (kMaxLightOrder + 1 values); returns its degree. No allocation: it runs per ray and spot.
int times_profile(const double* a, int M, const std::vector<double>& profile, double* out) {
    if (profile.empty()) {
        std::copy(a, a + M + 1, out);
        return M;
    }
    const int degree = M + int(profile.size()) - 1;
    if (degree > kMaxLightOrder) throw std::invalid_argument("pegoraro10: light order must be 0..20");
    std::fill(out, out + degree + 1, 0.0);
    for (int i = 0; i <= M; ++i)
        for (size_t j = 0; j < profile.size(); ++j) out[size_t(i) + j] += a[i] * profile[j];
    return degree;
}

}  // namespace

double PegoraroPhase::eval(double mu) const {
    mu = std::clamp(mu, -1.0, 1.0);
    double p0 = 1.0, p1 = mu, sum = legendre.empty() ? 0.0 : legendre[0];
    for (size_t n = 1; n < legendre.size(); ++n) {
        if (n >= 2) {
            const double p2 = ((2.0 * n - 1.0) * mu * p1 - (n - 1.0) * p0) / double(n);
            p0 = p1;
            p1 = p2;
        }
        sum += legendre[n] * p1;
    }
    return kInv4Pi * sum;
}

PegoraroPhase pegoraro_phase_from_legendre(const std::vector<double>& legendre) {
    if (legendre.empty()) throw std::invalid_argument("pegoraro10: empty Legendre coefficients");
    if (int(legendre.size()) - 1 > kMaxDegree - 4)
        throw std::invalid_argument("pegoraro10: phase order must be <= 128");
    for (double a : legendre)
        if (!std::isfinite(a)) throw std::invalid_argument("pegoraro10: Legendre coefficients must be finite");
    PegoraroPhase p;
    p.legendre = legendre;
    const int N = p.order();
    const int L = 2 * N + 2;  // > 2N: no aliasing for a degree-N trigonometric polynomial
    std::vector<double> samples(L);
    for (int j = 0; j < L; ++j) samples[j] = p.eval(-std::sin(2.0 * kPi * j / L));
    p.fourier.resize(N + 1);
    for (int m = 0; m <= N; ++m) {
        cplx acc = 0.0;
        for (int j = 0; j < L; ++j) acc += samples[j] * std::polar(1.0, -2.0 * kPi * double(m) * j / L);
        p.fourier[m] = acc / double(L);
    }
    return p;
}

PegoraroPhase pegoraro_phase(const PhaseFunction& phase, int order) {
    std::vector<double> a;
    switch (phase.kind) {
        case PhaseKind::Isotropic:
            a = {1.0};
            break;
        case PhaseKind::HenyeyGreenstein: {
            if (order < 0) throw std::invalid_argument("pegoraro10: order must be >= 0");
            if (!(std::abs(phase.g) < 1.0)) throw std::invalid_argument("pegoraro10: |g| must be < 1");
            double gn = 1.0;
            for (int n = 0; n <= order; ++n, gn *= phase.g) a.push_back((2.0 * n + 1.0) * gn);
            break;
        }
        case PhaseKind::Rayleigh:  // 3 (1 + mu^2) / (16 pi) = (1 + P_2 / 2) / (4 pi)
            a = {1.0, 0.0, 0.5};
            break;
        case PhaseKind::HazyMie:
        case PhaseKind::MurkyMie: {  // exact polynomials of degree 8 / 32: project exactly
            const int deg = phase.kind == PhaseKind::HazyMie ? 8 : 32;
            std::vector<double> x, w;
            gauss_legendre(48, x, w);
            a.assign(deg + 1, 0.0);
            for (size_t i = 0; i < x.size(); ++i) {
                const double f = 4.0 * kPi * phase.eval(x[i]);
                double p0 = 1.0, p1 = x[i];
                for (int n = 0; n <= deg; ++n) {
                    double pn = n == 0 ? 1.0 : p1;
                    if (n >= 2) {
                        const double p2 = ((2.0 * n - 1.0) * x[i] * p1 - (n - 1.0) * p0) / double(n);
                        p0 = p1;
                        p1 = p2;
                        pn = p2;
                    }
                    a[n] += 0.5 * (2.0 * n + 1.0) * w[i] * f * pn;
                }
            }
            break;
        }
    }
    return pegoraro_phase_from_legendre(a);
}

int pegoraro_hg_order(double g, double rel_tol, int max_order) {
    const double ag = std::abs(g);
    if (ag == 0.0) return 0;
    const double pmin = (1.0 - ag) / ((1.0 + ag) * (1.0 + ag));  // 4 pi p at the lobe's far side
    for (int N = 0; N <= max_order; ++N) {
        double tail = 0.0, gn = std::pow(ag, N + 1);
        for (int n = N + 1; gn > 1e-18 * (tail + 1e-300); ++n, gn *= ag) tail += (2.0 * n + 1.0) * gn;
        if (tail <= rel_tol * pmin) return N;
    }
    return -1;
}

PegoraroPhase pegoraro_phase_auto(const PhaseFunction& phase, double rel_tol, int max_order) {
    int order = 0;
    if (phase.kind == PhaseKind::HenyeyGreenstein) {
        order = pegoraro_hg_order(phase.g, rel_tol, max_order);
        if (order < 0) order = max_order;
    }
    return pegoraro_phase(phase, order);
}

void pegoraro_moments(double H, double v0, double v1, int K, cplx* G) {
    if (K > kMaxDegree) throw std::invalid_argument("pegoraro_moments: K must be <= 132");
    const bool inf = std::isinf(v1);
    const cplx J = complex_e1_difference_scaled(cplx(H * v0, -H), cplx(inf ? 0.0 : H * v1, -H), inf);
    G[0] = J.imag();
    if (K == 0) return;
    const double e1 = inf ? 0.0 : std::exp(-H * (v1 - v0));  // e^{-H (v1 - v0)}
    const double q0 = 1.0 / (1.0 + v0 * v0), q1 = inf ? 0.0 : 1.0 / (1.0 + v1 * v1);
    const double vq1 = inf ? 0.0 : v1 * q1;
    // Q_n = int e^{..} (1+v^2)^-n, R_n = int e^{..} v (1+v^2)^-n: one step of their recurrence.
    const double Q1 = J.imag(), R1 = J.real();
    const double Q2 = (e1 * vq1 - v0 * q0 + H * R1 + Q1) / 2.0;
    const double R2 = -(e1 * q1 - q0 + H * Q1) / 2.0;
    G[1] = cplx(2.0 * Q2 - Q1, 2.0 * R2);
    if (K == 1) return;
    // e^{2 i psi} = (1 + i v)/(1 - i v) = (2q - 1) + 2 i v q; boundary cos^2 psi = q.
    const cplx w0(2.0 * q0 - 1.0, 2.0 * v0 * q0), w1 = inf ? cplx(-1.0, 0.0) : cplx(2.0 * q1 - 1.0, 2.0 * vq1);
    const cplx I(0.0, 1.0);
    // Forward: stable for small H (errors grow ~linearly in m; beyond m ~ 40 only for H <= 0.3).
    if ((H <= kForwardMaxH && (K <= 40 || H <= 0.3)) || (K <= 4 && H <= 20.0)) {
        cplx p0 = w0, p1 = w1;  // w^m
        for (int m = 1; m < K; ++m) {
            const cplx B = e1 * q1 * p1 - q0 * p0;
            G[m + 1] = (-2.0 * I * B - (2.0 * m + 2.0 * I * H) * G[m] - double(m - 1) * G[m - 1]) / double(m + 1);
            p0 *= w0;
            p1 *= w1;
        }
        return;
    }
    // Olver: rows m = 1 .. N-1 of the recurrence as a tridiagonal system (row 1 does not
    // involve G_0), end value G_N from integration by parts, Thomas algorithm.
    // The end value's error decays slowly going down when H is small: more rows for the
    // high orders (K > 40) that reach this branch below H = 3.
    const int N = 3 * K + 100 + (H < 3.0 && K > 40 ? int(300.0 / H) : 0);
    thread_local std::vector<cplx> cp, rp;
    if (int(cp.size()) < N) {
        cp.resize(N);
        rp.resize(N);
    }
    cplx p0 = w0, p1 = w1;
    for (int m = 1; m < N; ++m) {
        const cplx B = e1 * q1 * p1 - q0 * p0;
        cplx rhs = -2.0 * I * B;
        const double sub = m - 1, sup = m + 1;
        const cplx diag = 2.0 * m + 2.0 * I * H;
        p0 *= w0;
        p1 *= w1;
        if (m == N - 1) rhs -= sup * (e1 * p1 - p0) / (2.0 * I * double(N));  // p = w^N now
        const cplx den = m == 1 ? diag : diag - sub * cp[m - 1];
        cp[m] = (m == N - 1 ? 0.0 : sup) / den;
        rp[m] = (m == 1 ? rhs : rhs - sub * rp[m - 1]) / den;
    }
    cplx next = rp[N - 1];
    for (int m = N - 1; m >= 1; --m) {
        const cplx g = m == N - 1 ? rp[m] : rp[m] - cp[m] * next;
        if (m <= K) G[m] = g;
        next = g;
    }
}

double pegoraro10_airlight(const PegoraroPhase& phase, double sigma_t, double Dsv, double cos_gamma, double Dvp) {
    if (sigma_t == 0.0 || !(Dvp > 0.0)) return 0.0;
    const double c = std::clamp(cos_gamma, -1.0, 1.0);
    const double a = Dsv * c;
    const double h = std::max(Dsv * std::sqrt((1.0 - c) * (1.0 + c)), std::max(1e-7 * Dsv, 1e-12));
    return segment_integral(phase.fourier.data(), phase.order(), sigma_t, a, h, 0.0, Dvp);
}

double pegoraro10_airlight_poly(const PegoraroPhase& phase, const std::vector<double>& light,
                                const glm::dvec3& axis, double sigma_t, const glm::dvec3& s, const glm::dvec3& o,
                                const glm::dvec3& d, double x0, double x1) {
    if (light.empty() || light.size() > kMaxLightOrder + 1)
        throw std::invalid_argument("pegoraro10: light order must be 0..20");
    if (sigma_t == 0.0 || !(x1 > x0)) return 0.0;
    const RayFrame f = ray_frame(s, o, d);
    std::array<cplx, kMaxDegree + 1> coef;
    const int K = combined_coefficients(phase, light.data(), int(light.size()) - 1, glm::dot(d, axis),
                                        glm::dot(f.n, axis), coef.data());
    return segment_integral(coef.data(), K, sigma_t, f.a, f.h, x0, x1);
}

double pegoraro10_spot_airlight(const PegoraroPhase& phase, const SpotCone& cone, const glm::dvec3& s,
                                double sigma_t, const glm::dvec3& o, const glm::dvec3& d, double Dvp) {
    if (sigma_t == 0.0 || !(Dvp > 0.0)) return 0.0;
    if (cone.profile_alone && cone.cos_half_angle <= -1.0)
        return pegoraro10_airlight_poly(phase, cone.profile, cone.axis, sigma_t, s, o, d, 0.0, Dvp);
    const RayFrame f = ray_frame(s, o, d);
    const double del = glm::dot(d, cone.axis), dc = glm::dot(f.n, cone.axis);
    const double c0 = cone.cos_half_angle, sm = cone.smooth, c_blend = c0 + sm;
    // Pieces between the cone and blend-cone crossings.
    std::vector<double> cuts{0.0};
    const auto outer = ray_cone_crossings(o, d, s, cone.axis, c0, 0.0, Dvp);
    cuts.insert(cuts.end(), outer.begin(), outer.end());
    if (sm > 0.0 && c_blend < 1.0) {
        const auto inner = ray_cone_crossings(o, d, s, cone.axis, c_blend, 0.0, Dvp);
        cuts.insert(cuts.end(), inner.begin(), inner.end());
    }
    // The plane through the light normal to the axis separates the cone from its back nappe
    // (and is the cone itself for a 180 deg spot, where the quadratic's double root is lost).
    const double k_axis = glm::dot(d, cone.axis);
    if (k_axis != 0.0) {
        const double xp = -glm::dot(o - s, cone.axis) / k_axis;
        if (xp > 0.0 && xp < Dvp) cuts.push_back(xp);
    }
    if (cone.has_spread()) {  // the Spread profile's kink on the axis
        const double xa = ray_axis_approach(o, d, s, cone.axis, 0.0, Dvp);
        if (xa > 0.0) cuts.push_back(xa);
    }
    std::sort(cuts.begin(), cuts.end());
    cuts.push_back(Dvp);
    const glm::dvec3 w = o - s;
    auto cos_axis = [&](double x) {
        const glm::dvec3 p = w + x * d;
        const double len = glm::length(p);
        return len > 0.0 ? glm::dot(p, cone.axis) / len : -1.0;
    };
    // Smoothstep piece c S((c - c0)/sm) as a degree-4 polynomial in c.
    double annulus[5] = {0, 0, 0, 0, 0};
    if (sm > 0.0) {
        const double al = 1.0 / sm, b0 = -c0 / sm;
        annulus[1] = 3.0 * b0 * b0 - 2.0 * b0 * b0 * b0;
        annulus[2] = 6.0 * al * b0 - 6.0 * al * b0 * b0;
        annulus[3] = 3.0 * al * al - 6.0 * al * al * b0;
        annulus[4] = -2.0 * al * al * al;
    }
    // A piece by quadrature (the phase polynomial, the exact profile).
    auto quadrature_piece = [&](double x0, double x1) {
        auto integrand = [&](double x) {
            const glm::dvec3 p = w + x * d;
            const double dist = glm::length(p);
            if (!(dist > 0.0)) return 0.0;
            const double prof = spot_profile(cone, glm::dot(p, cone.axis) / dist);
            return prof * phase.eval(-glm::dot(p, d) / dist) * std::exp(-sigma_t * (dist + x)) / (dist * dist);
        };
        if (std::isinf(x1)) {
            const double L = std::max({x0, glm::length(w), 1e-300});
            auto g = [&](double t) {
                const double om = 1.0 - t;
                const double v = integrand(x0 + L * t / om);
                return v == 0.0 ? 0.0 : v * L / (om * om);
            };
            return sigma_t * integrate_adaptive(g, 0.0, 1.0, kPieceQuadratureTol);
        }
        return sigma_t * integrate_adaptive(integrand, x0, x1, kPieceQuadratureTol);
    };
    // A spot's IES profile multiplies both pieces' polynomials; a point light's within its
    // extent is the profile alone (no blend).
    const double one = 1.0, linear[2] = {0.0, 1.0};
    std::array<double, kMaxLightOrder + 1> inner_poly, annulus_poly;
    const int M_inner = cone.profile_alone ? times_profile(&one, 0, cone.profile, inner_poly.data())
                                           : times_profile(linear, 1, cone.profile, inner_poly.data());
    const int M_annulus = times_profile(annulus, 4, cone.profile, annulus_poly.data());
    std::array<cplx, kMaxDegree + 1> coef_inner, coef_annulus;
    int K_inner = -1, K_annulus = -1;
    double sum = 0.0;
    for (size_t i = 0; i + 1 < cuts.size(); ++i) {
        const double x0 = cuts[i], x1 = cuts[i + 1];
        if (!(x1 > x0)) continue;
        const double mid = std::isinf(x1) ? x0 + std::max({x0, glm::length(w), 1e-300}) : 0.5 * (x0 + x1);
        const double cm = cos_axis(mid);
        if (!(cm > c0)) continue;
        if (cone.has_spread()) {  // a Spread's sin(h - theta) is no polynomial in cos(theta)
            sum += quadrature_piece(x0, x1);
            continue;
        }
        if (sm == 0.0 || cm >= c_blend) {
            if (K_inner < 0) K_inner = combined_coefficients(phase, inner_poly.data(), M_inner, del, dc,
                                                        coef_inner.data());
            sum += segment_integral(coef_inner.data(), K_inner, sigma_t, f.a, f.h, x0, x1);
            continue;
        }
        if (K_annulus < 0) K_annulus = combined_coefficients(phase, annulus_poly.data(), M_annulus, del, dc,
                                                             coef_annulus.data());
        double cancel = 1.0;
        const double value = segment_integral(coef_annulus.data(), K_annulus, sigma_t, f.a, f.h, x0, x1, &cancel);
        // Ill-conditioned blend polynomial (very thin annulus): quadrature of this piece.
        sum += cancel <= kMaxCancellation ? value : quadrature_piece(x0, x1);
    }
    return sum;
}

}  // namespace airlight
