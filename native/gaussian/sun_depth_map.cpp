// sun_depth_map.cpp: building and reading the sun's depth map (sun_depth_map.h).
#include "gaussian/sun_depth_map.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "core/build_progress.h"
#include "gaussian/erf_steps.h"

namespace airlight {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

}  // namespace

SunFootprint::SunFootprint(const GaussianMedium& medium, const Vec3& towards) {
    const double len = glm::length(towards);
    if (!(len > 0.0) || !std::isfinite(len))
        throw std::invalid_argument("SunDepthMap: the sun's direction is not valid");
    u = towards / len;
    // (Any frame of the plane normal to u: from the axis least aligned with it.)
    const Vec3 helper = std::abs(u.x) < 0.9 ? Vec3(1.0, 0.0, 0.0) : Vec3(0.0, 1.0, 0.0);
    e1 = glm::normalize(glm::cross(helper, u));
    e2 = glm::cross(u, e1);
    double a_max = 0.0;
    for (int k = 0; k < 3; ++k) lo[k] = kInf, hi[k] = -kInf;
    for (std::size_t j = 0; j < medium.size(); ++j) {
        const double R = medium.cull_radius(j);
        if (!(R > 0.0)) continue;
        const Vec3 b = medium.centre(j);
        const double c[3] = {glm::dot(b, e1), glm::dot(b, e2), glm::dot(b, u)};
        for (int k = 0; k < 3; ++k) lo[k] = std::min(lo[k], c[k] - R), hi[k] = std::max(hi[k], c[k] + R);
        a_max = std::max(a_max, medium.scale(j));
    }
    empty = !(hi[0] >= lo[0]);
    narrowest = empty ? 0.0 : 1.0 / (a_max * std::sqrt(2.0));
}

std::pair<double, double> SunFootprint::clip(const Vec3& o, const Vec3& r) const {
    if (empty) return {1.0, 0.0};
    double t0 = 0.0, t1 = kInf;
    const Vec3 axes[3] = {e1, e2, u};
    for (int k = 0; k < 3 && t0 <= t1; ++k) {
        const double x = glm::dot(o, axes[k]), dx = glm::dot(r, axes[k]);
        const double a = k < 2 ? lo[k] : -kInf, b = hi[k];  // (below the prism is in it)
        if (dx == 0.0) {
            if (x < a || x > b) return {1.0, 0.0};
            continue;
        }
        double ta = (a - x) / dx, tb = (b - x) / dx;
        if (ta > tb) std::swap(ta, tb);
        t0 = std::max(t0, ta), t1 = std::min(t1, tb);
    }
    return {t0, t1};
}

SunDepthMap::SunDepthMap(const GaussianMedium& medium, const Vec3& u, int face, int depth, int threads,
                         double window)
    : print_(medium, u), face_(face), depth_(depth), window_(window) {
    if (face < 2 || depth < 2) throw std::invalid_argument("SunDepthMap: face and depth must be >= 2");
    if (print_.empty) return;  // no Gaussian: 0 everywhere
    const double* lo = print_.lo;
    const double* hi = print_.hi;
    dp_ = (hi[0] - lo[0]) / (face - 1), dq_ = (hi[1] - lo[1]) / (face - 1), ds_ = (hi[2] - lo[2]) / (depth - 1);
    acquire_image_buffer(tau_, std::size_t(face) * face * depth, 0.0f);
    parallel_chunks(std::size_t(face), threads, 1, [&](std::size_t begin, std::size_t end) {
        std::vector<float> acc(depth);
        std::vector<double> below(depth);
        for (std::size_t j = begin; j < end; ++j) {
            for (int i = 0; i < face; ++i) fill(medium, i, int(j), &tau_[(j * face + i) * depth], acc, below);
            build_progress_check();  // progress and cancel of the bake building it
        }
    });
}

void SunDepthMap::fill(const GaussianMedium& medium, int i, int j, float* out, std::vector<float>& acc,
                       std::vector<double>& below) const {
    std::fill(acc.begin(), acc.end(), 0.0f);
    std::fill(below.begin(), below.end(), 0.0);
    const int last = depth_ - 1;
    const SunFootprint& f = print_;
    const Vec3 c = (f.lo[0] + i * dp_) * f.e1 + (f.lo[1] + j * dq_) * f.e2 + f.lo[2] * f.u;  // the column's bottom
    thread_local ErfSteps steps;
    steps.clear();
    medium.for_each_near(c, f.u, last * ds_, [&](std::size_t g) { steps.add(medium, g, c, f.u, window_, ds_, last); });
    // (T_g(s) = K erfc(a (s - p)): 2 K below its bins, 0 above them)
    add_erfc_steps(steps, float(ds_), last, acc.data(), below.data());
    double whole = 0.0;
    for (int k = last; k >= 0; --k) {
        whole += below[k];
        out[k] = float(double(acc[k]) + whole);
    }
}

double SunDepthMap::cell_step(const Vec3& r) const {
    const SunFootprint& f = print_;
    return std::min({dp_ / std::abs(glm::dot(r, f.e1)), dq_ / std::abs(glm::dot(r, f.e2)),
                     ds_ / std::abs(glm::dot(r, f.u))});
}

double SunDepthMap::operator()(const Vec3& x) const {
    const SunFootprint& f = print_;
    if (f.empty) return 0.0;
    const double fp = (glm::dot(x, f.e1) - f.lo[0]) / dp_, fq = (glm::dot(x, f.e2) - f.lo[1]) / dq_;
    const double fs = std::max(0.0, (glm::dot(x, f.u) - f.lo[2]) / ds_);
    if (!(fp >= 0.0 && fp <= face_ - 1.0 && fq >= 0.0 && fq <= face_ - 1.0 && fs <= depth_ - 1.0)) return 0.0;
    const int i0 = std::min(int(fp), face_ - 2), j0 = std::min(int(fq), face_ - 2), k0 = std::min(int(fs), depth_ - 2);
    const double wp = fp - i0, wq = fq - j0, ws = fs - k0;
    const float* base = &tau_[(std::size_t(j0) * face_ + i0) * depth_ + k0];
    auto at = [&](int di, int dj) {
        const float* p = base + (std::size_t(dj) * face_ + di) * depth_;
        return (1.0 - ws) * p[0] + ws * p[1];
    };
    return (1.0 - wq) * ((1.0 - wp) * at(0, 0) + wp * at(1, 0)) + wq * ((1.0 - wp) * at(0, 1) + wp * at(1, 1));
}

}  // namespace airlight
