// environment.h: environment lighting in inhomogeneous (Gaussian) fog, Fogshop (Zhou et
// al. 2007) section 4.2. The World's light reaching a point p is attenuated and scattered as
// in homogeneous fog (Sun 2005 eq. 26-27, sun05_psf.h) with the optical depth replaced by the
// average optical depth around p (Fogshop eq. 26):
//   Tbar(p) = (1/4pi) int_S T(p + D w, p) dw = beta0 D + sum_i Tbar_i(p),
//   Tbar_i(p) = c_i T(a_i |p - b_i|) / a_i                (D >> the Gaussians' extent),
//   T(u) = (1/4pi) int_S int_0^inf exp(-|u + t w|^2) dt dw      (the paper tabulates it).
//
// Closed form of T(u). With x = t w, dt dw = d^3x / |x|^2, so T(u) = (1/4pi) int e^{-|u + x|^2}
// / |x|^2 d^3x. The mean of 1/|y - u|^2 over the sphere |y| = s is ln|(s + u)/(s - u)| / (2 s u),
// hence T(u) = (1/(2u)) int_0^inf s e^{-s^2} ln|(s + u)/(s - u)| ds; integrating by parts,
// T(u) = (1/2) PV int_0^inf e^{-s^2} / (u^2 - s^2) ds = (1/(4u)) PV int_R e^{-s^2} / (u - s) ds,
// and PV int_R e^{-s^2} / (u - s) ds = 2 sqrt(pi) F(u) (F = Dawson's integral), so
//   T(u) = (sqrt(pi) / 2) F(u) / u,   T(0) = sqrt(pi) / 2,
//   T(u) = sqrt(pi) / (4 u^2) (1 + 1/(2u^2) + 3/(4u^4) + 15/(8u^6) + ...)   (u -> inf).
// Checked against scipy.special.dawsn and a 2D quadrature of the definition in
// tests/native/test_rbf_environment.py and environment_test.cpp.
//
// Far field (Barnes-Hut). Write w_i = c_i sqrt(pi) / (4 a_i^3), r_i = |p - b_i|, u_i = a_i r_i
// and g(u) = 2 u F(u); then Tbar_i = w_i g(u_i) / r_i^2 with g(u) = 1 + 1/(2u^2) + rho(u),
// |rho(u)| <= 1.2 / u^4 for u >= 3 (scanned: sup u^4 |rho| = 1.14 there). A node of the tree of
// Gaussians is replaced, for a point p, by
//   W / d^2 + (4 d^T Q d / d^2 - tr Q) / d^4     (1/r^2 kernel: monopole + quadrupole about the
//                                                   w-centroid B2, Q = sum w_i (b_i - B2)(b_i - B2)^T)
//   + V / |p - B4|^4                              (the 1/(2u^2) term: monopole about the
//                                                   v-centroid B4, v_i = w_i / (2 a_i^2)),
// d = p - B2. Taylor remainders (|d^3/ds^3 |x|^-2| <= 24 / |x|^5 and the Hessian of |x|^-4 has
// norm <= 20 / |x|^6) bound its error by
//   e = 4 W R2^3 / (d - R2)^5 + 10 V R4^2 / (d4 - R4)^6 + 1.2 X / (d - R2)^6,  X = sum w_i / a_i^4,
// with R2, R4 the node's radii about B2, B4 and d, d4 lower bounds of |p - B2|, |p - B4|
// (valid when every u_i >= 3).
//
// Points are evaluated in blocks of 256 (Morton order), split into parts of 64 and those into
// groups of 16; each is held as its bounding sphere (centre C, radius rho). A block first
// computes a lower bound LB <= Tbar(p) of all its points (T is decreasing: per leaf, sum c_i /
// a_i T(a_max (distance + R2))), then traverses the tree: a node is accepted when e <= (tol / 2) LB W_node
// / W_all for the block's sphere; a node not accepted that would be for radius rho / 8 is left
// pending, and each group traverses the pending nodes with its own sphere and the same test.
// The block's and its groups' accepted nodes are disjoint: their e add up to S <= tol LB / 2.
//
// Linear models (a local expansion of order 1). A term f, an accepted node's expansion E or a
// near Gaussian's Tbar_i, enters a sphere's linear model V + G . (p - C) (f and grad f at C)
// with the Taylor remainder |f(p) - f(C) - grad f(C) . (p - C)| <= (rho^2 / 2) sup ||Hess f||
// over the ball |p - C| <= rho:
//  - E: along a unit direction the n-th derivative of |x|^-2 is n! U_n(cos) / |x|^(n+2) and
//    that of |x|^-4 is n! C_n^(2)(cos) / |x|^(n+4) (Chebyshev and Gegenbauer polynomials,
//    |U_n| <= n + 1, |C_n^(2)| <= (n+1)(n+2)(n+3)/6: the 6 / |x|^4, 24 / |x|^5, 20 / |x|^6
//    above). The quadrupole term is (1/2) sum w_i s_i^T Hess(|x|^-2)(d) s_i (s_i = b_i - B2),
//    so its Hessian is bounded by the fourth derivative, 120 / |x|^6 (a symmetric form's norm is
//    its sup on the diagonal), times tr Q / 2:
//      ||Hess E|| <= 6 W / r^4 + 60 tr Q / r^6 + 20 V / r4^6,  r = |C - B2| - rho, r4 = |C - B4| - rho
//    (both > 0, else E is not linearised). Adjacent pixels' hit points lie within a fraction of
//    a metre, so most accepted nodes cost one evaluation (value and gradient) per block, part
//    or group instead of one per point.
//  - Tbar_i: its Hessian has norm <= c_i a_i K(u) with K(u) >= sup_{v >= u} max(|T''(v)|,
//    |T'(v) / v|) (a sampled envelope), u = a_i (|C - b_i| - rho).
// The block's model takes terms while their remainders add up to at most 3/4 (tol LB - S_block
// - (tol / 2) LB W_pending / W_all) (S_block: its accepted nodes' e; the last term bounds what its
// groups may accept among the pending nodes, of weight W_pending); each part's model, of the
// terms the block kept, 3/4 of what then remains; each group's model, of the terms its part
// kept and the group's own, while the remainders fit tol LB - S - (the block's and the part's);
// smaller remainders first (in rounds: every term <= what is left / terms left). The others
// are summed exactly (near Gaussians) or through E (nodes) at every point. So
//   |Tbar_approx(p) - Tbar(p)| <= S + (block's, part's and group's remainders) <= tol LB <= tol Tbar(p)
// (plus the T(u) table's 1e-10 relative), which environment_test.cpp checks against the
// brute-force sum on random clouds, on dense surfaces and on patches whose blocks would break
// it if E's remainder were dropped; the measured errors are 5-10x below the bound
// (bench_rbf_environment.py).
//
// The irradiance a surface of normal n gets from the World through the fog (sun05_psf.h's
// environment_irradiance) needs the PSF's eigenvalues lambda_l(T), l <= 2, for every pixel's
// own Tbar. PsfBandTable holds g_l(T) = lambda_l(T) e^T / T (smooth, finite at T = 0:
// lambda_0 / T -> pi^2 / 4) as natural cubic splines over x = ln(1 + sqrt T), 64 nodes on
// T in [0, 200] (exact PSF eigenvalues, built once per process); beyond T = 200, lambda_l
// (< 1e-84) is held at g_l(200).
#pragma once

#include <array>
#include <cstddef>
#include <vector>

#include "gaussian/medium.h"
#include "core/scene.h"
#include "homogeneous/sun05_psf.h"

namespace airlight {

// Dawson's integral F(x) = e^{-x^2} int_0^x e^{t^2} dt (series near 0, Rybicki's exponentially
// convergent sum elsewhere): ~1e-15 relative.
double dawson(double x);

// T(u) of the header comment, u >= 0 (u = |u|): exact through dawson() ...
double average_depth_unit(double u);
// ... and fast: cubic Hermite table of F(u)/u on [0, 32] (step 1/128, derivatives exact),
// five terms of the asymptotic series beyond. Relative error < 1e-10 (environment_test.cpp).
double average_depth_unit_fast(double u);

struct AverageDepthStats {
    std::size_t points = 0;
    std::size_t near_terms = 0;  // exact per-Gaussian evaluations
    std::size_t far_terms = 0;     // node expansions evaluated at every point
    std::size_t linear_terms = 0;  // Gaussians taken through a linear model (no per-point cost)
    std::size_t far_linear_terms = 0;  // node expansions taken through a linear model (once per block, part or group)
};

// Tbar(p) over the Gaussians of an GaussianMedium (its beta0 times _distance_ D for the
// homogeneous part). Keeps its own tree of node moments (the medium's BVH is for rays).
class GaussianAverageDepth {
  public:
    // _distance_ D >= 0 (finite): the environment's distance. Throws std::invalid_argument.
    GaussianAverageDepth(const GaussianMedium& medium, double distance);

    std::size_t size() const { return b_.size(); }

    // Tbar at _n_ points (finite; throws std::invalid_argument otherwise) into _out_, with
    // the far-field expansion under relative tolerance _tol_ >= 0 (0: every Gaussian exact).
    // Multithreaded (threads = 0: all cores). Returns how many terms were evaluated.
    AverageDepthStats evaluate(const Vec3* p, std::size_t n, double* out, double tol, int threads = 0) const;
    // Reference: beta0 D + sum_i c_i / a_i T(a_i |p - b_i|) over all Gaussians, exact dawson().
    void evaluate_brute(const Vec3* p, std::size_t n, double* out, int threads = 0) const;

  private:
    struct Node {
        double W = 0.0, V = 0.0, X = 0.0, C = 0.0;  // sum w_i, v_i, w_i / a_i^4, c_i / a_i
        Vec3 B2{0.0}, B4{0.0};                        // w- and v-centroids
        double Q[6] = {0, 0, 0, 0, 0, 0};             // xx, yy, zz, xy, xz, yz about B2
        double R2 = 0.0, R4 = 0.0, a_min = 0.0, a_max = 0.0;
        std::uint32_t first = 0, count = 0;  // Gaussians order_[first, first + count)
        std::uint32_t left = 0, right = 0;   // children (leaf: count <= kLeaf and left == 0)
        bool leaf = true;
    };
    struct Scratch;  // per-thread work arrays of evaluate_block
    std::uint32_t build(std::uint32_t begin, std::uint32_t end);
    void evaluate_block(const Vec3* p, const std::uint32_t* idx, std::size_t m, double* out, double tol,
                        Scratch& scratch, AverageDepthStats& stats) const;

    std::vector<Vec3> b_;
    std::vector<double> a_, c_;
    double base_ = 0.0;  // beta0 D
    double W_all_ = 0.0;
    std::vector<Node> nodes_;
    std::vector<std::uint32_t> order_, leaves_;
};

// lambda_l(T) of the exact PSF (psf_eigenvalues(T, 2, PsfKind::Exact)) for l = 0, 1, 2 from the
// table of the header comment; T >= 0 (T = 0 gives 0). Built on first use (thread safe).
std::array<double, 3> psf_band_eigenvalues(double T);

// environment_irradiance() with a per-point optical depth: E_world(n_k) and E_fogged(n_k) =
// e^{-T_k} E_world + albedo sum_l lambda_l(T_k) E_l(n_k) (E_l: band l's irradiance), for
// _n_ normals (non-zero) and T_k >= 0 finite. sh_world needs bands <= 2. Multithreaded.
void environment_irradiance_varying(const ShCoefficients& sh_world, const RGB& albedo, const Vec3* normals,
                                    const double* T, std::size_t n, RGB* E_world, RGB* E_fogged,
                                    int threads = 0);

}  // namespace airlight
