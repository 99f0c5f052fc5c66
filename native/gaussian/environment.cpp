// environment.cpp: Fogshop's average optical depth (section 4.2) and the per-point
// environment irradiance; the derivations are in environment.h.
#include "gaussian/environment.h"
#include "core/constants.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <mutex>
#include <numeric>
#include <stdexcept>
#include <string>

namespace airlight {

namespace {

inline void require(bool ok, const char* msg) {  // (no std::string unless it throws: hot loops call it)
    if (!ok) throw std::invalid_argument(msg);
}

// Far-field constants (environment.h): the expansion is used only where every u_i >= kUFar,
// where |rho(u)| <= kRhoBound / u^4.
constexpr double kUFar = 3.0;
constexpr double kRhoBound = 1.2;

// phi(u) = F(u) / u and phi'(u) by the Maclaurin series sum_k (-2u^2)^k / (2k+1)!! (u < 1).
void phi_series(double u, double& phi, double& dphi) {
    const double u2 = u * u;
    double term = 1.0, s = 1.0, ds = 0.0;
    for (int k = 1; k < 40; ++k) {
        term *= -2.0 * u2 / (2.0 * k + 1.0);  // (-2u^2)^k / (2k+1)!!
        s += term;
        ds += 2.0 * k * term / u;
        if (std::abs(term) < 1e-18) break;
    }
    phi = s;
    dphi = u > 0.0 ? ds : 0.0;
}

// Cubic Hermite table of phi(u) = F(u) / u on [0, kTableMax], interleaved (phi, phi') per
// node so that one lookup reads 32 contiguous bytes.
constexpr int kTablePerUnit = 128;
constexpr double kTableMax = 32.0;
constexpr int kTableNodes = int(kTableMax) * kTablePerUnit + 1;

struct PhiTable {
    std::vector<double> v;  // phi(u_k), phi'(u_k), ...
    PhiTable() : v(2 * size_t(kTableNodes)) {
        for (int k = 0; k < kTableNodes; ++k) {
            const double u = double(k) / kTablePerUnit;
            double& phi = v[2 * size_t(k)];
            double& dphi = v[2 * size_t(k) + 1];
            if (u < 1.0) {
                phi_series(u, phi, dphi);
            } else {
                const double F = dawson(u);
                phi = F / u;
                dphi = (1.0 - 2.0 * u * F) / u - F / (u * u);  // (F' u - F) / u^2, F' = 1 - 2uF
            }
        }
    }
};

const PhiTable& phi_table() {
    static const PhiTable table;
    return table;
}

#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__) && !defined(AIRLIGHT_NO_CLONES)
#define AIRLIGHT_AVG_CLONES __attribute__((target_clones("arch=x86-64-v4", "arch=x86-64-v3", "default")))
#else
#define AIRLIGHT_AVG_CLONES
#endif

// T(u) from the table below kTableMax, else sqrt(pi) / (4 u^2) sum_{k <= 5} (2k-1)!! / (2u^2)^k
// (at u >= 32 the next term is 3e-14). Branch-free, so that loops over it vectorise.
inline double average_depth_fast(const double* table, double u) {
    const double x = std::min(u, kTableMax - 1e-9) * kTablePerUnit;
    const int k = int(x);
    const double s = x - k, s2 = s * s, s3 = s2 * s, h = 1.0 / kTablePerUnit;
    const double* t = table + 2 * k;
    const double phi = (2.0 * s3 - 3.0 * s2 + 1.0) * t[0] + (s3 - 2.0 * s2 + s) * h * t[1] +
                       (3.0 * s2 - 2.0 * s3) * t[2] + (s3 - s2) * h * t[3];
    const double iu2 = 1.0 / std::max(u * u, 1.0), z = 0.5 * iu2;
    const double far =
        0.25 * kSqrtPi * iu2 * (1.0 + z * (1.0 + 3.0 * z * (1.0 + 5.0 * z * (1.0 + 7.0 * z * (1.0 + 9.0 * z)))));
    return u < kTableMax ? 0.5 * kSqrtPi * phi : far;
}

// T'(u) of the same model (the Hermite cubic's derivative; the series' beyond kTableMax).
inline double average_depth_fast_derivative(const double* table, double u) {
    if (u >= kTableMax) {
        // d/du sqrt(pi)/4 sum_k (2k-1)!! 2^-k u^(-2k-2)
        const double iu2 = 1.0 / (u * u), z = 0.5 * iu2;
        return -0.25 * kSqrtPi * iu2 / u *
               (2.0 + z * (4.0 + 3.0 * z * (6.0 + 5.0 * z * (8.0 + 7.0 * z * 10.0))));
    }
    const double x = u * kTablePerUnit;
    const int k = int(x);
    const double s = x - k, s2 = s * s, h = 1.0 / kTablePerUnit;
    const double* t = table + 2 * k;
    const double dphi = ((6.0 * s2 - 6.0 * s) * t[0] + (3.0 * s2 - 4.0 * s + 1.0) * h * t[1] +
                         (6.0 * s - 6.0 * s2) * t[2] + (3.0 * s2 - 2.0 * s) * h * t[3]) / h;
    return 0.5 * kSqrtPi * dphi;
}

// T(u) and T'(u) of the same model with one table lookup (the linear models' near Gaussians).
inline void average_depth_fast_with_derivative(const double* table, double u, double& T, double& dT) {
    if (u >= kTableMax) {
        T = average_depth_fast(table, u);
        dT = average_depth_fast_derivative(table, u);
        return;
    }
    const double x = u * kTablePerUnit;
    const int k = int(x);
    const double s = x - k, s2 = s * s, s3 = s2 * s, h = 1.0 / kTablePerUnit;
    const double* t = table + 2 * k;
    T = 0.5 * kSqrtPi *
        ((2.0 * s3 - 3.0 * s2 + 1.0) * t[0] + (s3 - 2.0 * s2 + s) * h * t[1] + (3.0 * s2 - 2.0 * s3) * t[2] +
         (s3 - s2) * h * t[3]);
    dT = 0.5 * kSqrtPi *
         ((6.0 * s2 - 6.0 * s) * t[0] + (3.0 * s2 - 4.0 * s + 1.0) * h * t[1] + (6.0 * s - 6.0 * s2) * t[2] +
          (3.0 * s2 - 2.0 * s) * h * t[3]) / h;
}

// phi'(u) and phi''(u) of phi = F / u (exact: series below 1, the asymptotic series from 16).
void phi_derivatives(double u, double& d1, double& d2) {
    if (u < 1.0) {
        const double u2 = u * u;
        double term = 1.0, s1 = 0.0, s2 = 0.0;  // term = (-2)^k u^(2k) / (2k+1)!!
        for (int k = 1; k < 60; ++k) {
            term *= -2.0 * u2 / (2.0 * k + 1.0);
            s1 += 2.0 * k * term / u;
            s2 += 2.0 * k * (2.0 * k - 1.0) * term / u2;
            if (std::abs(term) < 1e-20) break;
        }
        d1 = s1;
        d2 = u > 0.0 ? s2 : -4.0 / 3.0;
        return;
    }
    if (u >= 16.0) {
        // phi = sum_k (2k-1)!! 2^(-k-1) u^(-2k-2)
        double c = 0.5, s1 = 0.0, s2 = 0.0;
        for (int k = 0; k < 12; ++k) {
            if (k > 0) c *= (2.0 * k - 1.0) * 0.5;
            s1 -= c * (2.0 * k + 2.0) * std::pow(u, -2.0 * k - 3.0);
            s2 += c * (2.0 * k + 2.0) * (2.0 * k + 3.0) * std::pow(u, -2.0 * k - 4.0);
        }
        d1 = s1;
        d2 = s2;
        return;
    }
    const double F = dawson(u), F1 = 1.0 - 2.0 * u * F, F2 = -2.0 * F - 2.0 * u * F1;
    d1 = F1 / u - F / (u * u);
    d2 = F2 / u - 2.0 * F1 / (u * u) + 2.0 * F / (u * u * u);
}

// K(u) >= sup_{v >= u} max(|T''(v)|, |T'(v) / v|): the Hessian of T(|x|) at |x| = v has these
// eigenvalues, so a Gaussian's Tbar_i = c / a T(a r) has Hessian norm <= c a K(a r_min). An
// envelope sampled every 1/256 (x 1.02) on [0, 64) at steps of 1/16; 2.7 / u^4 beyond (T'' ~
// 6 sqrt(pi) / (4 u^4), T' / u ~ -sqrt(pi) / (2 u^4)).
constexpr int kCurvPerUnit = 16;
constexpr double kCurvMax = 64.0;

struct CurvatureEnvelope {
    std::vector<double> K;
    CurvatureEnvelope() {
        const int fine = 256, n = int(kCurvMax) * fine;
        std::vector<double> run(size_t(n) + 1);
        double sup = 2.7 / std::pow(kCurvMax, 4.0);
        for (int j = n; j >= 0; --j) {
            const double v = double(j) / fine;
            double d1, d2;
            phi_derivatives(v, d1, d2);
            const double tv = v > 0.0 ? std::abs(d1) / v : 4.0 / 3.0;  // phi'(v) / v -> phi''(0)
            sup = std::max(sup, 0.5 * kSqrtPi * std::max(std::abs(d2), tv));
            run[size_t(j)] = sup;
        }
        K.resize(size_t(kCurvMax) * kCurvPerUnit + 1);
        for (size_t k = 0; k < K.size(); ++k) K[k] = 1.02 * run[k * (fine / kCurvPerUnit)];
    }
    double operator()(double u) const {
        if (u >= kCurvMax) return 2.7 / (u * u * u * u);
        return K[size_t(u * kCurvPerUnit)];
    }
};

const CurvatureEnvelope& curvature_envelope() {
    static const CurvatureEnvelope env;
    return env;
}

// sum_j ca_j T(a_j |x - b_j|) over Gaussians held as arrays (the near field of a point). The
// terms go through _tmp_ (m doubles) first: a plain map vectorises, a double reduction
// would not (no -ffast-math); four partial sums then hide the adds' latency.
AIRLIGHT_AVG_CLONES
double near_sum(const double* bx, const double* by, const double* bz, const double* a, const double* ca, std::size_t m,
                double x, double y, double z, const double* table, double* tmp) {
    for (std::size_t j = 0; j < m; ++j) {
        const double dx = x - bx[j], dy = y - by[j], dz = z - bz[j];
        tmp[j] = ca[j] * average_depth_fast(table, a[j] * std::sqrt(dx * dx + dy * dy + dz * dz));
    }
    double s0 = 0.0, s1 = 0.0, s2 = 0.0, s3 = 0.0;
    std::size_t j = 0;
    for (; j + 4 <= m; j += 4) {
        s0 += tmp[j];
        s1 += tmp[j + 1];
        s2 += tmp[j + 2];
        s3 += tmp[j + 3];
    }
    for (; j < m; ++j) s0 += tmp[j];
    return (s0 + s1) + (s2 + s3);
}

}  // namespace

double dawson(double x) {
    const double ax = std::abs(x);
    double F;
    if (ax < 0.2) {
        double phi, dphi;
        phi_series(ax, phi, dphi);
        F = ax * phi;
    } else if (ax > 30.0) {
        // F(x) = 1/(2x) sum_k (2k-1)!! / (2x^2)^k; at x > 30 ten terms reach 1e-25.
        const double z = 0.5 / (ax * ax);
        double s = 0.0;
        for (int k = 10; k >= 1; --k) s = (2.0 * k - 1.0) * z * (1.0 + s);
        F = 0.5 / ax * (1.0 + s);
    } else {
        // Rybicki (Numerical Recipes 6.10) with step H = 0.2: aliasing error e^{-(pi / 2H)^2}
        // ~ 1e-27, terms up to ((2n - 1) H)^2 = 40.
        constexpr double H = 0.2;
        constexpr int kTerms = 17;
        static const auto c = [] {
            std::array<double, kTerms + 1> v{};
            for (int i = 1; i <= kTerms; ++i) v[size_t(i)] = std::exp(-((2.0 * i - 1.0) * H) * ((2.0 * i - 1.0) * H));
            return v;
        }();
        const int n0 = 2 * int(0.5 * ax / H + 0.5);
        const double xp = ax - n0 * H;
        double e1 = std::exp(2.0 * xp * H);
        const double e2 = e1 * e1;
        double d1 = n0 + 1.0, d2 = d1 - 2.0, sum = 0.0;
        for (int i = 1; i <= kTerms; ++i, d1 += 2.0, d2 -= 2.0, e1 *= e2) sum += c[size_t(i)] * (e1 / d1 + 1.0 / (d2 * e1));
        F = std::exp(-xp * xp) * sum / kSqrtPi;
    }
    return x < 0.0 ? -F : F;
}

double average_depth_unit(double u) {
    require(u >= 0.0, "average_depth_unit: need u >= 0");
    if (u < 0.2) {
        double phi, dphi;
        phi_series(u, phi, dphi);
        return 0.5 * kSqrtPi * phi;
    }
    if (std::isinf(u)) return 0.0;
    return 0.5 * kSqrtPi * dawson(u) / u;
}

double average_depth_unit_fast(double u) {
    require(u >= 0.0, "average_depth_unit_fast: need u >= 0");
    if (std::isinf(u)) return 0.0;
    return average_depth_fast(phi_table().v.data(), u);
}

// ---------------------------------------------------------------------------------------------
// GaussianAverageDepth

namespace {
constexpr std::uint32_t kLeaf = 8;
constexpr std::size_t kBlock = 256;  // points that share a traversal and a linear model (Morton order) ...
constexpr std::size_t kMid = 64;     // ... parts of them, with their own linear model ...
constexpr std::size_t kGroup = 16;   // ... and groups of those, with their own linear model
constexpr double kBlockShare = 0.75;  // the block's part of the budget the expansions leave

inline std::uint64_t spread_bits(std::uint64_t v) {  // 21 bits -> every third bit
    v &= 0x1fffff;
    v = (v | v << 32) & 0x1f00000000ffffULL;
    v = (v | v << 16) & 0x1f0000ff0000ffULL;
    v = (v | v << 8) & 0x100f00f00f00f00fULL;
    v = (v | v << 4) & 0x10c30c30c30c30c3ULL;
    v = (v | v << 2) & 0x1249249249249249ULL;
    return v;
}
}  // namespace

GaussianAverageDepth::GaussianAverageDepth(const GaussianMedium& medium, double distance) {
    require(std::isfinite(distance) && distance >= 0.0, "average depth: the environment distance must be finite and >= 0");
    const std::size_t n = medium.size();
    require(n < (std::size_t(1) << 31), "average depth: too many Gaussians");
    base_ = medium.beta0() * distance;
    b_.resize(n);
    a_.resize(n);
    c_.resize(n);
    for (std::size_t i = 0; i < n; ++i) {
        b_[i] = medium.centre(i);
        a_[i] = medium.scale(i);
        c_[i] = medium.amplitude(i);
    }
    order_.resize(n);
    std::iota(order_.begin(), order_.end(), 0u);
    if (n > 0) {
        nodes_.reserve(2 * (n / kLeaf + 1));
        build(0, std::uint32_t(n));
        W_all_ = nodes_[0].W;
    }
}

std::uint32_t GaussianAverageDepth::build(std::uint32_t begin, std::uint32_t end) {
    const std::uint32_t ni = std::uint32_t(nodes_.size());
    nodes_.emplace_back();
    Node node;
    node.first = begin;
    node.count = end - begin;
    Vec3 lo(INFINITY), hi(-INFINITY), sb(0.0), sb4(0.0);
    node.a_min = INFINITY;
    node.a_max = 0.0;
    for (std::uint32_t k = begin; k < end; ++k) {
        const std::uint32_t i = order_[k];
        const double a = a_[i], w = c_[i] * kSqrtPi / (4.0 * a * a * a), v = w / (2.0 * a * a);
        lo = glm::min(lo, b_[i]);
        hi = glm::max(hi, b_[i]);
        node.W += w;
        node.V += v;
        node.X += w / (a * a * a * a);
        node.C += c_[i] / a;
        sb += w * b_[i];
        sb4 += v * b_[i];
        node.a_min = std::min(node.a_min, a);
        node.a_max = std::max(node.a_max, a);
    }
    node.B2 = node.W > 0.0 ? sb / node.W : 0.5 * (lo + hi);
    node.B4 = node.V > 0.0 ? sb4 / node.V : node.B2;
    for (std::uint32_t k = begin; k < end; ++k) {
        const std::uint32_t i = order_[k];
        const double a = a_[i], w = c_[i] * kSqrtPi / (4.0 * a * a * a);
        const Vec3 d = b_[i] - node.B2;
        node.Q[0] += w * d.x * d.x;
        node.Q[1] += w * d.y * d.y;
        node.Q[2] += w * d.z * d.z;
        node.Q[3] += w * d.x * d.y;
        node.Q[4] += w * d.x * d.z;
        node.Q[5] += w * d.y * d.z;
        node.R2 = std::max(node.R2, glm::length(d));
        node.R4 = std::max(node.R4, glm::length(b_[i] - node.B4));
    }
    if (end - begin > kLeaf) {
        const Vec3 ext = hi - lo;
        const int axis = ext.x >= ext.y && ext.x >= ext.z ? 0 : (ext.y >= ext.z ? 1 : 2);
        const std::uint32_t mid = begin + (end - begin) / 2;
        std::nth_element(order_.begin() + begin, order_.begin() + mid, order_.begin() + end,
                         [&](std::uint32_t x, std::uint32_t y) { return b_[x][axis] < b_[y][axis]; });
        node.leaf = false;
        node.left = build(begin, mid);
        node.right = build(mid, end);
    } else {
        leaves_.push_back(ni);
    }
    nodes_[ni] = node;
    return ni;
}

struct GaussianAverageDepth::Scratch {  // (per thread)
    std::vector<std::uint32_t> far, near;          // the block's accepted nodes and near Gaussians
    std::vector<std::uint32_t> far_m, near_m;      // what a middle level of the block has left of them
    std::vector<std::uint32_t> far_g, near_g;      // what a group of the block has left of them
    std::vector<std::uint32_t> pending;            // nodes the block leaves to its groups to traverse
    std::vector<std::pair<double, std::uint32_t>> cand;  // (linearisation error, far / near index)
    std::vector<double> soa[6];
};

namespace {
// The bounding sphere (centre C, radius rho) of points p[idx[0..m)].
void bounding_sphere(const Vec3* p, const std::uint32_t* idx, std::size_t m, Vec3& C, double& rho) {
    Vec3 lo(INFINITY), hi(-INFINITY);
    for (std::size_t k = 0; k < m; ++k) {
        lo = glm::min(lo, p[idx[k]]);
        hi = glm::max(hi, p[idx[k]]);
    }
    C = 0.5 * (lo + hi);
    rho = 0.5 * glm::length(hi - lo);
}
}  // namespace

void GaussianAverageDepth::evaluate_block(const Vec3* p, const std::uint32_t* idx, std::size_t m, double* out, double tol,
                                     Scratch& scratch, AverageDepthStats& stats) const {
    const double* table = phi_table().v.data();
    std::vector<std::uint32_t>& far = scratch.far;
    std::vector<std::uint32_t>& near = scratch.near;
    far.clear();
    near.clear();
    // Traversal from node _root_ for the sphere (C, rho): a node is accepted (into _fl_) when its
    // expansion's error bound e fits its share budget W of tol LB / 2; the Gaussians of leaves
    // not accepted go into _nl_. With _pending_, a node not accepted that would be for the
    // smaller radius _route_rho_ goes there instead, for the block's groups to traverse.
    // Returns the sum of the accepted nodes' e.
    double W_pending = 0.0;  // weight of the nodes left pending (their groups' e <= budget W_pending)
    auto accept_error = [&](const Node& n, const Vec3& C, double rho) -> double {
        const double dr = glm::length(n.B2 - C) - rho - n.R2;
        if (!(dr > 0.0 && n.a_min * dr >= kUFar)) return INFINITY;
        const double dr4 = glm::length(n.B4 - C) - rho - n.R4;
        if (!(dr4 > 0.0)) return INFINITY;
        const double dr2 = dr * dr, dr5 = dr2 * dr2 * dr, dr4_2 = dr4 * dr4;
        return 4.0 * n.W * n.R2 * n.R2 * n.R2 / dr5 + 10.0 * n.V * n.R4 * n.R4 / (dr4_2 * dr4_2 * dr4_2) +
               kRhoBound * n.X / (dr5 * dr);
    };
    auto traverse = [&](const Vec3& C, double rho, std::uint32_t root, double budget, double route_rho,
                        std::vector<std::uint32_t>& fl, std::vector<std::uint32_t>& nl,
                        std::vector<std::uint32_t>* pending) {
        double sum = 0.0;
        std::uint32_t stack[128];
        int sp = 0;
        stack[sp++] = root;
        while (sp > 0) {
            const std::uint32_t ni = stack[--sp];
            const Node& n = nodes_[ni];
            if (n.W <= 0.0) continue;  // every c_i = 0
            if (budget > 0.0) {
                const double e = accept_error(n, C, rho);
                if (e <= budget * n.W) {
                    fl.push_back(ni);
                    sum += e;
                    continue;
                }
                if (pending && accept_error(n, C, route_rho) <= budget * n.W) {
                    pending->push_back(ni);
                    W_pending += n.W;
                    continue;
                }
            }
            if (n.leaf) {
                for (std::uint32_t k = 0; k < n.count; ++k) {
                    const std::uint32_t i = order_[n.first + k];
                    if (c_[i] > 0.0) nl.push_back(i);
                }
            } else {
                stack[sp++] = n.right;
                stack[sp++] = n.left;
            }
        }
        return sum;
    };
    // The block (m <= kBlock points): its bounding sphere, the lower bound LB of Tbar over it and
    // the traversal; the expansions' error bounds add up to _spent_ <= tol LB / 2.
    Vec3 block_C(0.0);
    double block_rho = 0.0, LB = 0.0, spent = 0.0, block_budget = 0.0;
    scratch.pending.clear();
    bounding_sphere(p, idx, m, block_C, block_rho);
    if (!nodes_.empty()) {
        const Vec3 C = block_C;
        const double rho = block_rho;
        // Lower bound LB of Tbar over the block (T decreasing, a_i r_i <= a_max (|B2 - C| + rho + R2)),
        // then the error budget per unit node weight.
        double budget = 0.0;
        if (tol > 0.0 && W_all_ > 0.0) {
            LB = base_;
            for (std::uint32_t li : leaves_) {
                const Node& n = nodes_[li];
                if (n.C <= 0.0) continue;
                const double u = n.a_max * (glm::length(n.B2 - C) + rho + n.R2);
                LB += n.C * average_depth_fast(table, u);
            }
            budget = 0.5 * tol * LB / W_all_;  // half for the expansions; the rest for linear models
        }
        block_budget = budget;
        spent = traverse(C, rho, 0, block_budget, 0.125 * rho, far, near, &scratch.pending);
    }
    // Linear models. Terms go into a linear model V + G . (p - C) over a sphere (C, rho) (value
    // and gradient at C), smaller linearisation errors first, while the errors fit _left_:
    //  - an accepted node's expansion E: |E(p) - E(C) - grad E(C) . (p - C)| <= H rho^2 / 2 with
    //    H >= the norm of E's Hessian on the ball |p - C| <= rho (environment.h);
    //  - a near Gaussian: |Tbar_i(p) - Tbar_i(C) - grad . (p - C)| <= c a K(u_min) rho^2 / 2.
    // Taken entries of _fl_ / _nl_ are removed; returns the errors spent.
    const bool linearise = tol > 0.0 && LB > 0.0 && !nodes_.empty();
    constexpr std::uint32_t kFarTag = 0x80000000u, kTaken = 0xffffffffu;
    auto linear_model = [&](const Vec3& C, double rho, double left, std::vector<std::uint32_t>& fl,
                            std::vector<std::uint32_t>& nl, double& V, Vec3& G, std::size_t& far_linear,
                            std::size_t& linear) {
        V = 0.0;
        G = Vec3(0.0);
        far_linear = linear = 0;
        if (!linearise || left <= 0.0) return 0.0;
        const double half_rho2 = 0.5 * rho * rho;
        auto& cand = scratch.cand;
        cand.clear();
        double total = 0.0;
        for (std::size_t j = 0; j < fl.size(); ++j) {
            const Node& n = nodes_[fl[j]];
            // r, r4: lower bounds of |p - B2|, |p - B4| on the sphere (a group's sphere need not
            // lie inside its block's, for which the node was accepted).
            const double r = glm::length(C - n.B2) - rho, r4 = glm::length(C - n.B4) - rho;
            const double ir2 = 1.0 / (r * r), ir4_2 = 1.0 / (r4 * r4);
            const double H = (6.0 * n.W + 60.0 * (n.Q[0] + n.Q[1] + n.Q[2]) * ir2) * ir2 * ir2 +
                             20.0 * n.V * ir4_2 * ir4_2 * ir4_2;
            const double e = r > 0.0 && r4 > 0.0 ? H * half_rho2 : INFINITY;
            total += e;
            cand.emplace_back(e, std::uint32_t(j) | kFarTag);
        }
        if (nodes_[0].C > 0.0) {
            const CurvatureEnvelope& K = curvature_envelope();
            for (std::size_t j = 0; j < nl.size(); ++j) {
                const std::uint32_t i = nl[j];
                const double a = a_[i];
                const double u_min = a * std::max(0.0, glm::length(C - b_[i]) - rho);
                const double e = c_[i] * a * K(u_min) * half_rho2;
                total += e;
                cand.emplace_back(e, std::uint32_t(j));
            }
        }
        auto take = [&](std::uint32_t tag) {
            const std::uint32_t j = tag & ~kFarTag;
            if (tag & kFarTag) {
                // E and its gradient at C (monopole + quadrupole about B2, monopole about B4).
                const Node& n = nodes_[fl[j]];
                const Vec3 d = C - n.B2;
                const double inv = 1.0 / glm::dot(d, d);
                const Vec3 Qd(n.Q[0] * d.x + n.Q[3] * d.y + n.Q[4] * d.z, n.Q[3] * d.x + n.Q[1] * d.y + n.Q[5] * d.z,
                              n.Q[4] * d.x + n.Q[5] * d.y + n.Q[2] * d.z);
                const double dQd = glm::dot(d, Qd), trQ = n.Q[0] + n.Q[1] + n.Q[2];
                const Vec3 d4 = C - n.B4;
                const double is4 = 1.0 / glm::dot(d4, d4);
                V += n.W * inv + (4.0 * dQd * inv - trQ) * inv * inv + n.V * is4 * is4;
                G += (-2.0 * n.W * inv * inv + (4.0 * trQ - 24.0 * dQd * inv) * inv * inv * inv) * d +
                     (8.0 * inv * inv * inv) * Qd - (4.0 * n.V * is4 * is4 * is4) * d4;
                fl[j] = kTaken;
                ++far_linear;
            } else {
                const std::uint32_t i = nl[j];
                const double ca = c_[i] / a_[i];
                const Vec3 d = C - b_[i];
                const double dist = glm::length(d), u = a_[i] * dist;
                double T, dT;
                average_depth_fast_with_derivative(table, u, T, dT);
                V += ca * T;
                if (dist > 0.0) G += (c_[i] * dT / dist) * d;
                nl[j] = kTaken;
                ++linear;
            }
        };
        // Everything when it fits; else rounds that take every term with error <= (what is
        // left) / (terms left): each round's errors add up to at most what was left.
        double used = 0.0;
        if (total <= left) {
            for (const auto& ce : cand) take(ce.second);
            used = total;
        } else {
            std::size_t n_left = cand.size();
            for (int round = 0; round < 8 && n_left > 0; ++round) {
                const double t = (left - used) / double(n_left);
                double sum = 0.0;
                std::size_t kept = 0;
                for (std::size_t k = 0; k < n_left; ++k) {
                    if (cand[k].first <= t) {
                        sum += cand[k].first;
                        take(cand[k].second);
                    } else {
                        cand[kept++] = cand[k];
                    }
                }
                used += sum;
                if (kept == n_left) break;
                n_left = kept;
            }
        }
        if (far_linear > 0) fl.erase(std::remove(fl.begin(), fl.end(), kTaken), fl.end());
        if (linear > 0) nl.erase(std::remove(nl.begin(), nl.end(), kTaken), nl.end());
        return used;
    };
    // The block's linear model takes up to kBlockShare of what the expansions left of tol LB
    // (keeping back what the groups may spend on the pending nodes' expansions, <= budget
    // W_pending: the block's and the groups' accepted nodes are disjoint) ...
    double block_V, group_V;
    Vec3 block_G, group_G;
    std::size_t block_far_linear, block_linear, far_linear, linear;
    const double block_left = kBlockShare * (tol * LB - spent - block_budget * W_pending);
    const double block_spent = linear_model(block_C, block_rho, block_left, far, near, block_V,
                                            block_G, block_far_linear, block_linear);
    stats.far_linear_terms += m * block_far_linear;
    stats.linear_terms += m * block_linear;
    // ... each part of kMid points kBlockShare of what then remains, for the terms the block
    // kept, and each group of kGroup points of the part the rest, for the terms the part kept
    // and those it finds below the pending nodes.
    auto& soa = scratch.soa;
    for (std::size_t mid_first = 0; mid_first < m; mid_first += kMid) {
        const std::size_t mm = std::min(kMid, m - mid_first);
        Vec3 mid_C;
        double mid_rho, mid_V;
        Vec3 mid_G;
        std::size_t mid_far_linear, mid_linear;
        bounding_sphere(p, idx + mid_first, mm, mid_C, mid_rho);
        std::vector<std::uint32_t>& far_m = scratch.far_m;
        std::vector<std::uint32_t>& near_m = scratch.near_m;
        far_m.assign(far.begin(), far.end());
        near_m.assign(near.begin(), near.end());
        const double mid_left = kBlockShare * (tol * LB - spent - block_budget * W_pending - block_spent);
        const double mid_spent =
            linear_model(mid_C, mid_rho, mid_left, far_m, near_m, mid_V, mid_G, mid_far_linear, mid_linear);
        stats.far_linear_terms += mm * mid_far_linear;
        stats.linear_terms += mm * mid_linear;
        for (std::size_t first = mid_first; first < mid_first + mm; first += kGroup) {
            const std::size_t mg = std::min(kGroup, mid_first + mm - first);
            const std::uint32_t* gidx = idx + first;
            Vec3 group_C;
            double group_rho;
            bounding_sphere(p, gidx, mg, group_C, group_rho);
            std::vector<std::uint32_t>& far_g = scratch.far_g;
            std::vector<std::uint32_t>& near_g = scratch.near_g;
            far_g.assign(far_m.begin(), far_m.end());
            near_g.assign(near_m.begin(), near_m.end());
            double group_spent = 0.0;
            for (std::uint32_t ni : scratch.pending)
                group_spent += traverse(group_C, group_rho, ni, block_budget, 0.0, far_g, near_g, nullptr);
            linear_model(group_C, group_rho, tol * LB - spent - block_spent - mid_spent - group_spent, far_g, near_g,
                         group_V, group_G, far_linear, linear);
            // The near Gaussians as arrays (b, a, c / a; soa[5] is scratch).
            for (auto& v : soa) v.resize(near_g.size());
            for (std::size_t j = 0; j < near_g.size(); ++j) {
                const std::uint32_t i = near_g[j];
                soa[0][j] = b_[i].x;
                soa[1][j] = b_[i].y;
                soa[2][j] = b_[i].z;
                soa[3][j] = a_[i];
                soa[4][j] = c_[i] / a_[i];
            }
            for (std::size_t k = 0; k < mg; ++k) {
                const Vec3 x = p[gidx[k]];
                double sum = block_V + glm::dot(block_G, x - block_C) + mid_V + glm::dot(mid_G, x - mid_C) + group_V +
                             glm::dot(group_G, x - group_C);
                for (std::uint32_t ni : far_g) {
                    const Node& n = nodes_[ni];
                    const Vec3 d = x - n.B2;
                    const double r2 = glm::dot(d, d), inv = 1.0 / r2;
                    const double dQd = n.Q[0] * d.x * d.x + n.Q[1] * d.y * d.y + n.Q[2] * d.z * d.z +
                                       2.0 * (n.Q[3] * d.x * d.y + n.Q[4] * d.x * d.z + n.Q[5] * d.y * d.z);
                    const double trQ = n.Q[0] + n.Q[1] + n.Q[2];
                    const Vec3 d4 = x - n.B4;
                    const double s4 = glm::dot(d4, d4);
                    sum += n.W * inv + (4.0 * dQd * inv - trQ) * inv * inv + n.V / (s4 * s4);
                }
                sum += near_sum(soa[0].data(), soa[1].data(), soa[2].data(), soa[3].data(), soa[4].data(),
                                near_g.size(), x.x, x.y, x.z, table, soa[5].data());
                out[gidx[k]] = base_ + sum;
            }
            stats.far_terms += mg * far_g.size();
            stats.near_terms += mg * near_g.size();
            stats.linear_terms += mg * linear;
            stats.far_linear_terms += mg * far_linear;
        }
    }
    stats.points += m;
}

AverageDepthStats GaussianAverageDepth::evaluate(const Vec3* p, std::size_t n, double* out, double tol, int threads) const {
    require(std::isfinite(tol) && tol >= 0.0, "average depth: the tolerance must be finite and >= 0");
    Vec3 lo(INFINITY), hi(-INFINITY);
    for (std::size_t k = 0; k < n; ++k) {
        require(std::isfinite(p[k].x) && std::isfinite(p[k].y) && std::isfinite(p[k].z),
                "average depth: the points must be finite");
        lo = glm::min(lo, p[k]);
        hi = glm::max(hi, p[k]);
    }
    AverageDepthStats total;
    if (n == 0) return total;
    // Morton order, so that blocks of kBlock consecutive points are compact.
    const Vec3 ext = glm::max(hi - lo, Vec3(1e-300));
    std::vector<std::uint64_t> key(n);
    parallel_chunks(n, threads, 65536, [&](std::size_t begin, std::size_t end) {
        for (std::size_t k = begin; k < end; ++k) {
            const Vec3 q = (p[k] - lo) / ext * 1023.999;
            const std::uint64_t code = spread_bits(std::uint64_t(q.x)) | spread_bits(std::uint64_t(q.y)) << 1 |
                                       spread_bits(std::uint64_t(q.z)) << 2;
            key[k] = code << 32 | std::uint64_t(k);
        }
    });
    std::sort(key.begin(), key.end());
    std::vector<std::uint32_t> idx(n);
    for (std::size_t k = 0; k < n; ++k) idx[k] = std::uint32_t(key[k] & 0xffffffffu);
    key = {};
    const std::size_t blocks = (n + kBlock - 1) / kBlock;
    std::mutex mutex;
    parallel_chunks(blocks, threads, 1, [&](std::size_t begin, std::size_t end) {
        Scratch scratch;
        AverageDepthStats stats;
        for (std::size_t g = begin; g < end; ++g) {
            const std::size_t first = g * kBlock, m = std::min(kBlock, n - first);
            evaluate_block(p, idx.data() + first, m, out, tol, scratch, stats);
        }
        std::lock_guard<std::mutex> lock(mutex);
        total.points += stats.points;
        total.near_terms += stats.near_terms;
        total.far_terms += stats.far_terms;
        total.linear_terms += stats.linear_terms;
        total.far_linear_terms += stats.far_linear_terms;
    });
    return total;
}

void GaussianAverageDepth::evaluate_brute(const Vec3* p, std::size_t n, double* out, int threads) const {
    for (std::size_t k = 0; k < n; ++k)
        require(std::isfinite(p[k].x) && std::isfinite(p[k].y) && std::isfinite(p[k].z),
                "average depth: the points must be finite");
    parallel_chunks(n, threads, 256, [&](std::size_t begin, std::size_t end) {
        for (std::size_t k = begin; k < end; ++k) {
            double sum = 0.0;
            for (std::size_t i = 0; i < b_.size(); ++i)
                sum += c_[i] / a_[i] * average_depth_unit(a_[i] * glm::length(p[k] - b_[i]));
            out[k] = base_ + sum;
        }
    });
}

// ---------------------------------------------------------------------------------------------
// PSF band eigenvalues over T

namespace {

constexpr int kBandNodes = 64;
constexpr double kBandTMax = 200.0;

struct PsfBandTable {
    double x_max;
    double g[3][kBandNodes], g2[3][kBandNodes];  // values and natural-spline second derivatives
    PsfBandTable() {
        x_max = std::log1p(std::sqrt(kBandTMax));
        const double h = x_max / (kBandNodes - 1);
        parallel_chunks(kBandNodes, 0, 1, [&](std::size_t begin, std::size_t end) {
            for (std::size_t k = begin; k < end; ++k) {
                const double e = std::expm1(double(k) * h);
                const double T = k == 0 ? 1e-10 : e * e;  // lambda_l / T is continuous at 0
                const std::vector<double> lambda = psf_eigenvalues(T, 2, PsfKind::Exact);
                for (int l = 0; l < 3; ++l) g[l][k] = lambda[size_t(l)] * std::exp(T) / T;
            }
        });
        // Natural cubic spline on the uniform grid (Thomas algorithm).
        for (int l = 0; l < 3; ++l) {
            double cp[kBandNodes], dp[kBandNodes];
            g2[l][0] = g2[l][kBandNodes - 1] = 0.0;
            cp[0] = 0.0;
            dp[0] = 0.0;
            for (int k = 1; k < kBandNodes - 1; ++k) {
                const double rhs = 6.0 * (g[l][k + 1] - 2.0 * g[l][k] + g[l][k - 1]) / (h * h);
                const double denom = 4.0 - cp[k - 1];
                cp[k] = 1.0 / denom;
                dp[k] = (rhs - dp[k - 1]) / denom;
            }
            for (int k = kBandNodes - 2; k >= 1; --k) g2[l][k] = dp[k] - cp[k] * g2[l][k + 1];
        }
    }
    std::array<double, 3> lambda(double T) const {
        std::array<double, 3> out{0.0, 0.0, 0.0};
        if (T <= 0.0) return out;
        const double h = x_max / (kBandNodes - 1);
        const double x = std::min(std::log1p(std::sqrt(T)), x_max);
        const int k = std::min(int(x / h), kBandNodes - 2);
        const double t = x / h - k, s = 1.0 - t;
        const double amplitude = T * std::exp(-T);
        for (int l = 0; l < 3; ++l) {
            const double v = s * g[l][k] + t * g[l][k + 1] +
                             ((s * s * s - s) * g2[l][k] + (t * t * t - t) * g2[l][k + 1]) * h * h / 6.0;
            out[size_t(l)] = amplitude * v;
        }
        return out;
    }
};

const PsfBandTable& psf_band_table() {
    static const PsfBandTable table;
    return table;
}

}  // namespace

std::array<double, 3> psf_band_eigenvalues(double T) {
    require(std::isfinite(T) && T >= 0.0, "psf_band_eigenvalues: need finite T >= 0");
    return psf_band_table().lambda(T);
}

void environment_irradiance_varying(const ShCoefficients& sh_world, const RGB& albedo, const Vec3* normals,
                                    const double* T, std::size_t n, RGB* E_world, RGB* E_fogged, int threads) {
    require(sh_world.L >= 2 && sh_world.c.size() >= 9, "environment_irradiance: need bands up to l = 2");
    for (std::size_t k = 0; k < n; ++k) {
        require(std::isfinite(T[k]) && T[k] >= 0.0, "environment_irradiance: optical depths must be finite and >= 0");
        const Vec3& v = normals[k];
        require(std::isfinite(v.x + v.y + v.z) && glm::dot(v, v) > 0.0,
                "environment_irradiance: normals must be finite and non-zero");
    }
    // Band l's irradiance E_l(n) is a harmonic polynomial of degree l in the unit normal:
    // E_0 = e0, E_1 = g . n, E_2 = n^T M n. Read e0, g and M off sh_irradiance() at fixed
    // normals once (E_2(e_k) = M_kk, E_2((e_j + e_k) / sqrt 2) = (M_jj + M_kk) / 2 + M_jk).
    ShCoefficients band[3];
    for (int l = 0; l < 3; ++l) {
        band[l].L = 2;
        band[l].c.assign(9, RGB(0.0));
        for (int m = -l; m <= l; ++m) band[l].c[size_t(l * (l + 1) + m)] = sh_world.c[size_t(l * (l + 1) + m)];
    }
    const Vec3 e[3] = {Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(0, 0, 1)};
    const RGB e0 = sh_irradiance(band[0], e[2]);
    RGB g[3], M[3][3];
    for (int j = 0; j < 3; ++j) {
        g[j] = 0.5 * (sh_irradiance(band[1], e[j]) - sh_irradiance(band[1], -e[j]));
        M[j][j] = sh_irradiance(band[2], e[j]);
    }
    for (int j = 0; j < 3; ++j)
        for (int k = j + 1; k < 3; ++k)
            M[j][k] = M[k][j] = sh_irradiance(band[2], (e[j] + e[k]) / std::sqrt(2.0)) - 0.5 * (M[j][j] + M[k][k]);
    const PsfBandTable& table = psf_band_table();
    parallel_chunks(n, threads, 4096, [&](std::size_t begin, std::size_t end) {
        for (std::size_t k = begin; k < end; ++k) {
            const std::array<double, 3> lambda = table.lambda(T[k]);
            const Vec3 v = glm::normalize(normals[k]);
            const RGB E1 = v.x * g[0] + v.y * g[1] + v.z * g[2];
            const RGB E2 = v.x * v.x * M[0][0] + v.y * v.y * M[1][1] + v.z * v.z * M[2][2] +
                           2.0 * (v.x * v.y * M[0][1] + v.x * v.z * M[0][2] + v.y * v.z * M[1][2]);
            const RGB Ew = e0 + E1 + E2;
            E_world[k] = Ew;
            E_fogged[k] = std::exp(-T[k]) * Ew + albedo * (lambda[0] * e0 + lambda[1] * E1 + lambda[2] * E2);
        }
    });
}

}  // namespace airlight
