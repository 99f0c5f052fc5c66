// sunlight_glow.cpp: the glow of a sun lamp on a Lambert surface in a fog layer (see
// sunlight_glow.h).
//
// Integration: directions in spherical coordinates about the sun, w = cos(gamma) l +
// sin(gamma) (cos(psi) a + sin(psi) b) with a the unit vector towards +Z orthogonal to l and
// b = l x a (so b.z = 0). The phase function depends on gamma alone (its lobe is resolved by
// breakpoints at multiples of PhaseFunction::lobe_width), and for a fixed gamma
//   n.w = A + B cos(psi - psi_n)  (positive on one interval of psi, found in closed form),
//   w.z = cos(gamma) l.z + sin(gamma) a.z cos(psi)  (the layer's horizon, where the fog
//   factor jumps at tau = 0, is split off in closed form too),
// so each piece of the psi integral is smooth. The gamma breakpoints are where the cone of
// half-angle gamma about l touches the horizon of n or of Z.
//
// Table (SunlightGlowTable): normals by polar angle theta in [0, pi] (n_theta nodes) and
// azimuth phi in [0, pi] from the sun's (n_phi nodes; Q is even in phi), and with a top
// s = tau / (1 + tau) on [0, s_max] (n_tau nodes, s_max at tau = 1e6), storing e^{tau} Q.
// Its entries come from a second decomposition of the same integral (theta_nodes below:
// polar angle from Z, then azimuth), so TableMatchesExact also checks the two rules
// against each other. Measured at the default 48 x 49 x 25 (sunlight_glow_test.cpp): max
// |table - exact| <= 7.9e-3 of the largest Q of the sample set (isotropic with a top; 1.6e-3
// to 2.8e-3 for Henyey-Greenstein g = -0.3 ... 0.9), mean <= 5.4e-4; a table builds in
// 0.2-0.6 s on one thread (no top: one tau plane, 0.14-0.25 s).
#include "surface/sunlight_glow.h"
#include "core/table_cache.h"
#include "core/parallel.h"
#include "core/constants.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <stdexcept>
#include <thread>

#include "core/quadrature.h"
#include "homogeneous/sunlight_layer.h"

namespace airlight {

namespace {

constexpr double kTauMax = 1e6;

// The surface's weight of an incident direction: max(0, x)^m with x = n.w (Lambert, m = 1)
// or x = r.w about the mirrored view direction r (Phong, m = n).
inline double lobe(double x, double m) {
    if (!(x > 0.0)) return 0.0;
    return m == 1.0 ? x : std::pow(x, m);
}

// Angular width scale of the cos^m lobe (none for the Lambert cosine).
inline double lobe_width(double m) { return m > 1.0 ? 1.0 / std::sqrt(m) : 0.0; }

struct SunFrame {
    glm::dvec3 l, a, b;
    double mu_s;
};

SunFrame sun_frame(const glm::dvec3& to_sun) {
    SunFrame f;
    const double len = glm::length(to_sun);
    if (!(len > 0.0) || !std::isfinite(len)) throw std::invalid_argument("sun_layer_glow: sun direction must be finite and non-zero");
    f.l = to_sun / len;
    f.mu_s = f.l.z;
    glm::dvec3 a = glm::dvec3(0.0, 0.0, 1.0) - f.l.z * f.l;
    if (glm::length(a) < 1e-12) a = glm::dvec3(1.0, 0.0, 0.0) - f.l.x * f.l;
    f.a = glm::normalize(a);
    f.b = glm::cross(f.l, f.a);
    return f;
}

// e^{tau} sigma G(w) for a point at optical depth tau below the top (sunlight_layer.h with
// sigma = 1), written so that no factor overflows: every exponent is <= 0 since mu, mu_s <= 1.
// Without a top: 1 (the sun unattenuated, the ray infinitely long in fog).
double fog_factor_scaled(bool has_top, double tau, double mu_s, double mu) {
    if (!has_top) return 1.0;
    if (!(mu_s > 0.0)) return 0.0;
    const double k = 1.0 - mu / mu_s;
    if (mu <= 0.0) return std::exp(tau * (1.0 - 1.0 / mu_s)) / k;  // k >= 1: the ray never leaves
    const double L = tau / mu;  // to the top
    if (k >= 0.0) {
        const double frac = k * L > 1e-12 ? -std::expm1(-k * L) / k : L;
        return std::exp(tau * (1.0 - 1.0 / mu_s)) * frac;
    }
    return std::exp(tau * (1.0 - 1.0 / mu)) * (-std::expm1(k * L) / -k);
}

// The psi pieces at polar angle gamma: the interval where n.w > 0 split at the Z horizon.
// Returns the piece boundaries in _cuts_ (empty: no direction of this cone faces n).
void psi_pieces(const SunFrame& f, const glm::dvec3& n, double m, double gamma, std::vector<double>& cuts,
                double& A, double& B, double& psi_n) {
    cuts.clear();
    const double cg = std::cos(gamma), sg = std::sin(gamma);
    const double na = glm::dot(n, f.a), nb = glm::dot(n, f.b);
    A = cg * glm::dot(n, f.l);
    B = sg * std::hypot(na, nb);
    psi_n = std::atan2(nb, na);
    double lo, hi;
    if (A >= B) {
        lo = psi_n - kPi;
        hi = psi_n + kPi;
    } else if (A <= -B) {
        return;
    } else {
        const double half = std::acos(std::clamp(-A / B, -1.0, 1.0));
        lo = psi_n - half;
        hi = psi_n + half;
    }
    cuts.push_back(lo);
    const double az = f.a.z;
    if (sg * az > 0.0) {
        const double c = -cg * f.l.z / (sg * az);
        if (c > -1.0 && c < 1.0) {
            const double ph = std::acos(c);
            for (double base : {ph, -ph})
                for (int k = -2; k <= 2; ++k) {
                    const double x = base + 2.0 * kPi * k;
                    if (x > lo && x < hi) cuts.push_back(x);
                }
        }
    }
    // A cos^m lobe about psi_n: its angular width lw spans about lw / B in psi.
    const double lw = lobe_width(m);
    if (lw > 0.0 && B > 1e-9)
        for (double c : {0.25, 1.0, 3.0}) {
            const double d = c * lw / B;
            if (d >= kPi) break;
            for (double x : {psi_n - d, psi_n + d})
                if (x > lo && x < hi) cuts.push_back(x);
        }
    cuts.push_back(hi);
    std::sort(cuts.begin(), cuts.end());
}

std::vector<double> gamma_cuts(const PhaseFunction& phase, const SunFrame& f, const glm::dvec3& n, double m) {
    std::vector<double> cuts = {0.0, kPi};
    const double w = phase.lobe_width();
    for (double k = 0.125; k * w < kPi; k *= 4.0) cuts.push_back(k * w);
    const double lw = lobe_width(m), gn = std::acos(std::clamp(glm::dot(n, f.l), -1.0, 1.0));
    if (lw > 0.0)
        for (double c : {-3.0, -1.0, -0.25, 0.25, 1.0, 3.0}) cuts.push_back(std::clamp(gn + c * lw, 0.0, kPi));
    for (double c : {std::abs(0.5 * kPi - std::acos(std::clamp(glm::dot(n, f.l), -1.0, 1.0))),
                     std::abs(0.5 * kPi - std::acos(std::clamp(f.l.z, -1.0, 1.0)))}) {
        cuts.push_back(c);
        cuts.push_back(kPi - c);
    }
    std::sort(cuts.begin(), cuts.end());
    cuts.erase(std::unique(cuts.begin(), cuts.end(), [](double x, double y) { return y - x < 1e-12; }),
               cuts.end());
    return cuts;
}

// The integrand of Q at (gamma, psi) without the phase and sin(gamma): fog factor x n.w.
template <class FogFactor>
double psi_integrand(const SunFrame& f, double m, double gamma, double psi, double A, double B, double psi_n,
                     const FogFactor& fog) {
    const double mu = std::cos(gamma) * f.l.z + std::sin(gamma) * f.a.z * std::cos(psi);
    return fog(mu) * lobe(A + B * std::cos(psi - psi_n), m);
}

struct FixedRule {
    std::vector<double> xg, wg, xp, wp;
    FixedRule() {
        gauss_legendre(8, xg, wg);
        gauss_legendre(12, xp, wp);
    }
};

const FixedRule& fixed_rule() {
    static const FixedRule rule;
    return rule;
}

// The table's rule, in the other natural coordinates: directions by polar angle theta from
// +Z and azimuth phi about Z from the sun's (e1, e2 the horizontal frame of the table). The
// fog factor depends on theta alone, so
//   e^{tau} Q(tau, n) = (1 / pi) int_0^pi sin(theta) e^{tau} sigma G(tau, cos theta) K(theta, n) dtheta,
//   K(theta, n) = int_0^{2 pi} p(l.w) max(0, n.w) dphi,
// and K is computed once per normal for every tau of the table. Breakpoints: the horizon
// (theta = pi/2: the fog factor jumps there at tau = 0), the sun's polar angle +- multiples
// of the phase lobe width, and where the circle of polar angle theta touches n's horizon.
// Gauss-Legendre 8 nodes per theta piece (<= 0.35 rad), 12 per phi piece.
struct ThetaNode {
    double mu, weight;  // cos(theta), (1 / pi) x quadrature weight x sin(theta) x K(theta, n)
};

std::vector<ThetaNode> theta_nodes(const PhaseFunction& phase, double mu_s, const glm::dvec3& n_local, double m) {
    const FixedRule& R = fixed_rule();
    const double w = phase.lobe_width();
    const double theta_s = std::acos(std::clamp(mu_s, -1.0, 1.0)), rs = std::sqrt(std::max(0.0, 1.0 - mu_s * mu_s));
    const double theta_n = std::acos(std::clamp(n_local.z, -1.0, 1.0));
    std::vector<double> cuts = {0.0, 0.5 * kPi, kPi, std::abs(0.5 * kPi - theta_n), kPi - std::abs(0.5 * kPi - theta_n)};
    for (double k = 0.125; k * w < kPi; k *= 4.0) {
        cuts.push_back(theta_s - k * w);
        cuts.push_back(theta_s + k * w);
    }
    const double lw = lobe_width(m);
    if (lw > 0.0)
        for (double c : {-3.0, -1.0, -0.25, 0.25, 1.0, 3.0}) cuts.push_back(theta_n + c * lw);
    for (double& c : cuts) c = std::clamp(c, 0.0, kPi);
    std::sort(cuts.begin(), cuts.end());
    cuts.erase(std::unique(cuts.begin(), cuts.end(), [](double x, double y) { return y - x < 1e-12; }), cuts.end());
    const double nh = std::hypot(n_local.x, n_local.y), phi_n = std::atan2(n_local.y, n_local.x);
    std::vector<ThetaNode> nodes;
    std::vector<double> pc;
    for (size_t k = 0; k + 1 < cuts.size(); ++k) {
        const int sub = std::max(1, int(std::ceil((cuts[k + 1] - cuts[k]) / 0.35)));
        const double h = (cuts[k + 1] - cuts[k]) / sub;
        for (int s = 0; s < sub; ++s)
            for (size_t i = 0; i < R.xg.size(); ++i) {
                const double theta = cuts[k] + s * h + 0.5 * h * (R.xg[i] + 1.0);
                const double mu = std::cos(theta), r = std::sin(theta);
                // n.w = C + B cos(phi - phi_n) > 0 on one interval of phi.
                const double C = n_local.z * mu, B = r * nh;
                double lo, hi;
                if (C >= B) {
                    lo = phi_n - kPi;
                    hi = phi_n + kPi;
                } else if (C <= -B) {
                    continue;
                } else {
                    const double half = std::acos(std::clamp(-C / B, -1.0, 1.0));
                    lo = phi_n - half;
                    hi = phi_n + half;
                }
                pc.assign({lo, hi});
                // The phase lobe about phi = 0 (mod 2 pi): its angular half-width m w spans
                // about m w / (r rs) in phi.
                if (r * rs > 1e-9)
                    for (double k = 0.125; k * w < 4.0 * r * rs; k *= 4.0)
                        for (double base : {k * w / (r * rs), -k * w / (r * rs)})
                            for (int q = -2; q <= 2; ++q) {
                                const double x = base + 2.0 * kPi * q;
                                if (x > lo && x < hi) pc.push_back(x);
                            }
                if (lw > 0.0 && B > 1e-9)
                    for (double c : {0.25, 1.0, 3.0}) {
                        const double d = c * lw / B;
                        if (d >= kPi) break;
                        for (double x : {phi_n - d, phi_n + d})
                            if (x > lo && x < hi) pc.push_back(x);
                    }
                std::sort(pc.begin(), pc.end());
                double K = 0.0;
                for (size_t q = 0; q + 1 < pc.size(); ++q) {
                    const double hp = pc[q + 1] - pc[q];
                    double piece = 0.0;
                    for (size_t j = 0; j < R.xp.size(); ++j) {
                        const double phi = pc[q] + 0.5 * hp * (R.xp[j] + 1.0);
                        const double cos_l = r * rs * std::cos(phi) + mu * mu_s;
                        piece += R.wp[j] * phase.eval(cos_l) * lobe(C + B * std::cos(phi - phi_n), m);
                    }
                    K += 0.5 * hp * piece;
                }
                nodes.push_back({mu, 0.5 * h * R.wg[i] * r * K / kPi});
            }
    }
    return nodes;
}

// e^{tau} Q by nested adaptive quadrature with the fog factor _fog_.
double glow_adaptive(const PhaseFunction& phase, const SunFrame& f, const glm::dvec3& n, double m,
                     const std::function<double(double)>& fog, double rel_tol) {
    const std::vector<double> gc = gamma_cuts(phase, f, n, m);
    auto outer = [&](double gamma) {
        std::vector<double> pc;
        double A, B, psi_n;
        psi_pieces(f, n, m, gamma, pc, A, B, psi_n);
        double inner = 0.0;
        for (size_t q = 0; q + 1 < pc.size(); ++q)
            inner += integrate_adaptive(
                [&](double psi) { return psi_integrand(f, m, gamma, psi, A, B, psi_n, fog); }, pc[q], pc[q + 1],
                0.1 * rel_tol, 1e-300);
        return std::sin(gamma) * phase.eval(std::cos(gamma)) * inner;
    };
    double total = 0.0;
    for (size_t k = 0; k + 1 < gc.size(); ++k) total += integrate_adaptive(outer, gc[k], gc[k + 1], rel_tol, 1e-300);
    return total / kPi;
}

void check_inputs(bool has_top, double tau, const glm::dvec3& normal, double m) {
    if (!(m >= 1.0 && m <= 10000.0)) throw std::invalid_argument("sun_layer_glow: the exponent m must be in [1, 10000]");
    if (has_top && !(tau >= 0.0)) throw std::invalid_argument("sun_layer_glow: tau must be >= 0");
    const double len = glm::length(normal);
    if (!(std::abs(len - 1.0) < 1e-6)) throw std::invalid_argument("sun_layer_glow: the normal must be a unit vector");
}

}  // namespace

double sunlight_glow_exact(const PhaseFunction& phase, const glm::dvec3& to_sun, bool has_top, double tau,
                            const glm::dvec3& normal, double m, double rel_tol) {
    check_inputs(has_top, tau, normal, m);
    const SunFrame f = sun_frame(to_sun);
    if (has_top && !(f.mu_s > 0.0)) return 0.0;
    if (has_top && std::isinf(tau)) return 0.0;
    auto fog = [&](double mu) { return fog_factor_scaled(has_top, tau, f.mu_s, mu); };
    const double scale = has_top ? std::exp(-tau) : 1.0;
    return scale * glow_adaptive(phase, f, normal, m, fog, rel_tol);
}

double sunlight_glow_reference(const PhaseFunction& phase, const glm::dvec3& to_sun, bool has_top, double tau,
                                const glm::dvec3& normal, double m, double rel_tol) {
    check_inputs(has_top, tau, normal, m);
    const SunFrame f = sun_frame(to_sun);
    if (has_top && !(f.mu_s > 0.0)) return 0.0;
    // sigma = 1, p at height 0, the top at tau (or none): the path integral along each ray.
    const double h_top = has_top ? tau : std::numeric_limits<double>::infinity();
    auto fog = [&](double mu) {
        return sunlight_layer_factor_quadrature(1.0, h_top, f.mu_s, 0.0, mu, 0.0, std::numeric_limits<double>::infinity(),
                                           0.1 * rel_tol);
    };
    return glow_adaptive(phase, f, normal, m, fog, rel_tol);
}

SunlightGlowTable::SunlightGlowTable(const PhaseFunction& phase, const glm::dvec3& to_sun, bool has_top, double m,
                                     int n_tau, int n_theta, int n_phi, int threads)
    : phase_(phase), m_(m), has_top_(has_top), n_tau_(has_top ? n_tau : 1), n_theta_(n_theta), n_phi_(n_phi) {
    if (!(m >= 1.0 && m <= 10000.0)) throw std::invalid_argument("SunlightGlowTable: the exponent m must be in [1, 10000]");
    if ((has_top && n_tau < 2) || n_theta < 2 || n_phi < 2)
        throw std::invalid_argument("SunlightGlowTable: need at least 2 nodes per axis");
    const SunFrame f = sun_frame(to_sun);
    to_sun_ = f.l;
    lit_ = !has_top || f.mu_s > 0.0;
    glm::dvec3 h(f.l.x, f.l.y, 0.0);
    e1_ = glm::length(h) > 1e-12 ? glm::normalize(h) : glm::dvec3(1.0, 0.0, 0.0);
    e2_ = glm::cross(glm::dvec3(0.0, 0.0, 1.0), e1_);
    data_.assign(size_t(n_tau_) * n_theta_ * n_phi_, 0.0);
    if (!lit_) return;
    const double s_max = kTauMax / (1.0 + kTauMax);
    const size_t n = size_t(n_theta_) * n_phi_;  // normals; each fills its whole tau column
    auto work = [&](size_t first, size_t step) {
        for (size_t k = first; k < n; k += step) {
            const int ith = int(k / n_phi_), iph = int(k % n_phi_);
            const double th = kPi * ith / (n_theta_ - 1), ph = kPi * iph / (n_phi_ - 1);
            // The normal in the table's frame (e1 towards the sun's azimuth, e2, Z).
            const glm::dvec3 n_local(std::sin(th) * std::cos(ph), std::sin(th) * std::sin(ph), std::cos(th));
            const std::vector<ThetaNode> nodes = theta_nodes(phase_, f.mu_s, n_local, m_);
            for (int it = 0; it < n_tau_; ++it) {
                const double s = n_tau_ > 1 ? s_max * it / (n_tau_ - 1) : 0.0;
                const double tau = s / (1.0 - s);
                double q = 0.0;
                for (const ThetaNode& node : nodes) q += node.weight * fog_factor_scaled(has_top_, tau, f.mu_s, node.mu);
                data_[(size_t(it) * n_theta_ + ith) * n_phi_ + iph] = q;
            }
        }
    };
    const int t = resolve_threads(threads);
    const std::string key = "sun_glow v1 phase=" + std::to_string(int(phase.kind)) + " g=" + key_number(phase.g) +
                            " sun=" + key_number(to_sun_.x) + "," + key_number(to_sun_.y) + "," + key_number(to_sun_.z) +
                            " top=" + std::to_string(int(has_top)) + " m=" + key_number(m) + " n=" +
                            std::to_string(n_tau_) + "," + std::to_string(n_theta_) + "," + std::to_string(n_phi_);
    load_or_build(key, data_, [&] {
        parallel_for(t, t, [&](int i) { work(size_t(i), size_t(t)); });  // one stripe per item
    });
}

void SunlightGlowTable::frame(const glm::dvec3& n, double& theta, double& phi) const {
    theta = std::acos(std::clamp(n.z, -1.0, 1.0));
    phi = std::abs(std::atan2(glm::dot(n, e2_), glm::dot(n, e1_)));
}

double SunlightGlowTable::eval(double tau, const glm::dvec3& normal) const {
    if (!lit_) return 0.0;
    double theta, phi;
    frame(normal, theta, phi);
    const double x = std::clamp(theta / kPi * (n_theta_ - 1), 0.0, double(n_theta_ - 1));
    const double y = std::clamp(phi / kPi * (n_phi_ - 1), 0.0, double(n_phi_ - 1));
    const int i = std::min(int(x), n_theta_ - 2), j = std::min(int(y), n_phi_ - 2);
    const double fx = x - i, fy = y - j;
    auto plane = [&](int it) {
        const double* d = &data_[size_t(it) * n_theta_ * n_phi_];
        return (1 - fx) * ((1 - fy) * d[i * n_phi_ + j] + fy * d[i * n_phi_ + j + 1]) +
               fx * ((1 - fy) * d[(i + 1) * n_phi_ + j] + fy * d[(i + 1) * n_phi_ + j + 1]);
    };
    if (!has_top_) return plane(0);
    const double t = std::max(0.0, std::isnan(tau) ? 0.0 : tau);
    const double s_max = kTauMax / (1.0 + kTauMax);
    if (t >= kTauMax) return 0.0;
    const double z = std::clamp(t / (1.0 + t) / s_max * (n_tau_ - 1), 0.0, double(n_tau_ - 1));
    const int k = std::min(int(z), n_tau_ - 2);
    const double fz = z - k;
    return std::exp(-t) * ((1 - fz) * plane(k) + fz * plane(k + 1));
}

}  // namespace airlight
