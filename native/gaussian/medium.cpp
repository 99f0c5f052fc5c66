// medium.cpp: the Gaussian store, its cull-sphere hierarchy and exact optical depth.
//
// Numerics of eq. 31 (tested against mpmath in tests/native/test_rbf_medium.py and against
// quadrature of the density in medium_test.cpp):
// - erf(x2) - erf(x1) loses every digit once both arguments are beyond ~6 with one sign
//   (erf rounds to +-1); there it is erfc(x1) - erfc(x2) (or the mirror for negatives),
//   which keeps full relative accuracy down to the underflow of erfc (~1e-308 at x ~ 26.5).
// - When the interval is short (w max(1, |x|) < 1e-2) even the erfc difference cancels; it
//   is then integrated directly, 2/sqrt(pi) int exp(-t^2) dt with 4-point Gauss-Legendre,
//   which is exact to rounding because exp(-t^2) varies by < 2 % across the interval.
// - h^2 comes from the cross product, not |b - o|^2 - t*^2, so Gaussians far along the
//   line keep their distance digits.
#include "gaussian/medium.h"
#include "core/constants.h"
#include "core/parallel.h"

#include <algorithm>
#include <cstring>
#include <limits>
#include <mutex>
#include <sstream>
#include <stdexcept>

namespace airlight {

namespace {


// 4-point Gauss-Legendre on [0, 1].
constexpr double kGL4x[4] = {0.06943184420297371, 0.33000947820757187, 0.6699905217924281,
                             0.9305681557970262};
constexpr double kGL4w[4] = {0.17392742256872692, 0.3260725774312731, 0.3260725774312731,
                             0.17392742256872692};

[[noreturn]] void fail(const std::string& what) { throw std::invalid_argument("RbfMedium: " + what); }

}  // namespace

double erf_diff(double x1, double x2) {
    if (!(x2 > x1)) return 0.0;
    // Short interval: direct quadrature (the difference of erf or erfc would cancel).
    const double w = x2 - x1;
    const double m = std::max({1.0, std::abs(x1), std::abs(x2)});
    if (w * m < 1e-2) {
        double s = 0.0;
        for (int k = 0; k < 4; ++k) {
            const double t = x1 + w * kGL4x[k];
            s += kGL4w[k] * std::exp(-t * t);
        }
        return kTwoOverSqrtPi * w * s;
    }
    if (x1 >= 0.0) return std::erfc(x1) - std::erfc(x2);   // erfc(inf) = 0
    if (x2 <= 0.0) return std::erfc(-x2) - std::erfc(-x1);  // erfc(-(-inf)) = 0
    return std::erf(x2) - std::erf(x1);                      // straddles 0: both terms add
}

double gaussian_line_integral(double c, double a, const Vec3& b, const Vec3& o, const Vec3& r, double t0,
                              double t1) {
    if (c == 0.0 || !(t1 > t0)) return 0.0;
    const Vec3 rel = b - o;
    const double ts = glm::dot(rel, r);
    const Vec3 cr = glm::cross(rel, r);
    const double h2 = glm::dot(cr, cr);
    const double x1 = a * (t0 - ts);
    const double x2 = std::isinf(t1) ? std::numeric_limits<double>::infinity() : a * (t1 - ts);
    return c * kSqrtPi / (2.0 * a) * std::exp(-a * a * h2) * erf_diff(x1, x2);
}

GaussianMedium::GaussianMedium(std::vector<double> centres, std::vector<double> scales, std::vector<double> amplitudes,
                     double beta0, double cull_eps)
    : a_(std::move(scales)), c_(std::move(amplitudes)), beta0_(beta0), eps_(cull_eps) {
    const std::size_t n = a_.size();
    if (centres.size() != 3 * n || c_.size() != n) {
        std::ostringstream os;
        os << "got " << centres.size() / 3.0 << " centres, " << n << " scales and " << c_.size()
           << " amplitudes; they must match";
        fail(os.str());
    }
    if (!std::isfinite(beta0) || beta0 < 0.0) {
        std::ostringstream os;
        os << "beta0 = " << beta0 << " is invalid (need a finite background density >= 0 in 1/m)";
        fail(os.str());
    }
    if (!(cull_eps > 0.0) || !std::isfinite(cull_eps)) fail("cull_eps must be finite and > 0");
    bx_.resize(n);
    by_.resize(n);
    bz_.resize(n);
    for (std::size_t i = 0; i < n; ++i) {
        const double x = centres[3 * i], y = centres[3 * i + 1], z = centres[3 * i + 2];
        if (!std::isfinite(x) || !std::isfinite(y) || !std::isfinite(z)) {
            std::ostringstream os;
            os << "centre " << i << " = (" << x << ", " << y << ", " << z << ") is not finite";
            fail(os.str());
        }
        if (!std::isfinite(a_[i]) || !(a_[i] > 0.0)) {
            std::ostringstream os;
            os << "scale a[" << i << "] = " << a_[i] << " is invalid (need finite a > 0 in 1/m)";
            fail(os.str());
        }
        if (!std::isfinite(c_[i]) || c_[i] < 0.0) {
            std::ostringstream os;
            os << "amplitude c[" << i << "] = " << c_[i] << " is invalid (need finite c >= 0 in 1/m)";
            fail(os.str());
        }
        bx_[i] = x;
        by_[i] = y;
        bz_[i] = z;
    }
    build();
}

double GaussianMedium::density(const Vec3& x) const {
    double beta = beta0_;
    for (std::size_t i = 0; i < size(); ++i) {
        const double dx = x.x - bx_[i], dy = x.y - by_[i], dz = x.z - bz_[i];
        beta += c_[i] * std::exp(-a_[i] * a_[i] * (dx * dx + dy * dy + dz * dz));
    }
    return beta;
}

double GaussianMedium::density_near(const Vec3& x) const {
    double beta = beta0_;
    for_each_near(x, Vec3(0.0, 0.0, 1.0), 0.0, [&](std::size_t i) {
        const double dx = x.x - bx_[i], dy = x.y - by_[i], dz = x.z - bz_[i];
        beta += c_[i] * std::exp(-a_[i] * a_[i] * (dx * dx + dy * dy + dz * dz));
    });
    return beta;
}

double GaussianMedium::gaussian_optical_depth(std::size_t i, const Vec3& o, const Vec3& r, double t0,
                                         double t1) const {
    return gaussian_line_integral(c_[i], a_[i], centre(i), o, r, t0, t1);
}

namespace {
// beta0 L with 0 * inf = 0.
double background_depth(double beta0, double L) { return beta0 == 0.0 ? 0.0 : beta0 * L; }
}  // namespace

double GaussianMedium::optical_depth_ray(const Vec3& o, const Vec3& r, double tmax, std::size_t skip,
                                    bool with_beta0) const {
    double T = 0.0;
    for_each_near(o, r, tmax, [&](std::size_t i) {
        if (i != skip) T += gaussian_optical_depth(i, o, r, 0.0, tmax);
    });
    return with_beta0 ? T + background_depth(beta0_, tmax) : T;
}

double GaussianMedium::optical_depth_ray(const Vec3& o, const Vec3& r, double tmax) const {
    return optical_depth_ray(o, r, tmax, npos, true);
}

double GaussianMedium::optical_depth(const Vec3& p, const Vec3& q) const {
    const Vec3 d = q - p;
    const double L = glm::length(d);
    if (!(L > 0.0)) return 0.0;
    return optical_depth_ray(p, d / L, L);
}

double GaussianMedium::optical_depth_all_ray(const Vec3& o, const Vec3& r, double tmax) const {
    double T = 0.0;
    for (std::size_t i = 0; i < size(); ++i) T += gaussian_optical_depth(i, o, r, 0.0, tmax);
    return T + background_depth(beta0_, tmax);
}

double GaussianMedium::optical_depth_all(const Vec3& p, const Vec3& q) const {
    const Vec3 d = q - p;
    const double L = glm::length(d);
    if (!(L > 0.0)) return 0.0;
    return optical_depth_all_ray(p, d / L, L);
}

void parallel_chunks(std::size_t n, int threads, std::size_t chunk,
                     const std::function<void(std::size_t, std::size_t)>& fn) {
    if (n == 0) return;
    chunk = std::max<std::size_t>(chunk, 1);
    const std::size_t n_chunks = (n + chunk - 1) / chunk;
    const int n_threads = int(std::min<std::size_t>(std::size_t(resolve_threads(threads)), n_chunks));
    parallel_for(int(n_chunks), n_threads, [&](int c) {
        const std::size_t b = std::size_t(c) * chunk;
        fn(b, std::min(n, b + chunk));
    });
}

void GaussianMedium::optical_depth_batch(const Vec3* p, const Vec3* q, std::size_t n, double* out, bool culled,
                                    int threads) const {
    parallel_chunks(n, threads, 1024, [&](std::size_t b, std::size_t e) {
        for (std::size_t j = b; j < e; ++j) out[j] = culled ? optical_depth(p[j], q[j]) : optical_depth_all(p[j], q[j]);
    });
}

void GaussianMedium::optical_depth_ray_batch(const Vec3* o, const Vec3* r, const double* tmax, std::size_t n,
                                        double* out, bool culled, int threads) const {
    parallel_chunks(n, threads, 1024, [&](std::size_t b, std::size_t e) {
        for (std::size_t j = b; j < e; ++j)
            out[j] = culled ? optical_depth_ray(o[j], r[j], tmax[j]) : optical_depth_all_ray(o[j], r[j], tmax[j]);
    });
}

std::uint64_t GaussianMedium::fingerprint() const {
    std::uint64_t h = 14695981039346656037ull;
    auto mix = [&](double x) {
        std::uint64_t bits;
        std::memcpy(&bits, &x, sizeof bits);
        for (int k = 0; k < 8; ++k) h = (h ^ ((bits >> (8 * k)) & 0xFF)) * 1099511628211ull;
    };
    mix(double(size())), mix(eps_), mix(window_);
    for (std::size_t i = 0; i < size(); ++i) mix(bx_[i]), mix(by_[i]), mix(bz_[i]), mix(a_[i]), mix(c_[i]);
    return h;
}

double GaussianMedium::cull_radius_for(double c, double a, double eps) {
    const double lg = std::log(c * kSqrtPi / (a * eps));
    return lg > 0.0 ? std::sqrt(lg) / a : 0.0;
}

// Hierarchy: cull spheres (Gaussians with R_i = 0 never reach eps and are left out),
// median split on the widest centre axis, leaves of <= 4.
void GaussianMedium::build() {
    const std::size_t n = size();
    radius_.assign(n, 0.0);
    for (std::size_t i = 0; i < n; ++i) radius_[i] = cull_radius_for(c_[i], a_[i], eps_);
    build_hierarchy();
}

GaussianMedium GaussianMedium::windowed(double window) const {
    GaussianMedium out;
    out.bx_ = bx_, out.by_ = by_, out.bz_ = bz_, out.a_ = a_, out.c_ = c_;
    out.beta0_ = beta0_, out.eps_ = eps_, out.window_ = window;
    const GaussianWindow window_of(window);
    out.radius_.resize(size());
    for (std::size_t i = 0; i < size(); ++i)
        out.radius_[i] = std::min(radius_[i], std::sqrt(window_of(c_[i] * kSqrtPi / a_[i])) / a_[i]);
    out.build_hierarchy();
    return out;
}

void GaussianMedium::build_hierarchy() {
    order_.clear();
    nodes_.clear();
    for (std::size_t i = 0; i < size(); ++i)
        if (radius_[i] > 0.0) order_.push_back(static_cast<std::uint32_t>(i));
    if (order_.empty()) return;
    nodes_.reserve(order_.size() + 1);
    build_node(0, static_cast<std::uint32_t>(order_.size()), 0);
}

std::uint32_t GaussianMedium::build_node(std::uint32_t begin, std::uint32_t end, int depth) {
    const std::uint32_t self = static_cast<std::uint32_t>(nodes_.size());
    nodes_.push_back(Node{});
    Node box{};
    double clo[3], chi[3];
    for (int k = 0; k < 3; ++k) {
        box.lo[k] = clo[k] = std::numeric_limits<double>::infinity();
        box.hi[k] = chi[k] = -std::numeric_limits<double>::infinity();
    }
    for (std::uint32_t j = begin; j < end; ++j) {
        const std::uint32_t i = order_[j];
        const double b[3] = {bx_[i], by_[i], bz_[i]};
        for (int k = 0; k < 3; ++k) {
            box.lo[k] = std::min(box.lo[k], b[k] - radius_[i]);
            box.hi[k] = std::max(box.hi[k], b[k] + radius_[i]);
            clo[k] = std::min(clo[k], b[k]);
            chi[k] = std::max(chi[k], b[k]);
        }
    }
    const std::uint32_t count = end - begin;
    // Depth is bounded by log2(n) since every split halves; the traversal stack holds 64.
    if (count <= 4 || depth >= 60) {
        box.first_or_right = begin;
        box.count = count;
        nodes_[self] = box;
        return self;
    }
    int axis = 0;
    for (int k = 1; k < 3; ++k)
        if (chi[k] - clo[k] > chi[axis] - clo[axis]) axis = k;
    const std::vector<double>& key = axis == 0 ? bx_ : (axis == 1 ? by_ : bz_);
    const std::uint32_t mid = begin + count / 2;
    std::nth_element(order_.begin() + begin, order_.begin() + mid, order_.begin() + end,
                     [&key](std::uint32_t p, std::uint32_t q) { return key[p] < key[q]; });
    build_node(begin, mid, depth + 1);
    const std::uint32_t right = build_node(mid, end, depth + 1);
    box.first_or_right = right;
    box.count = 0;
    nodes_[self] = box;
    return self;
}

}  // namespace airlight
