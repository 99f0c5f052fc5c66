// light_depth_map.cpp: building and reading the light-space depth map (light_depth_map.h).
#include "gaussian/light_depth_map.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "core/build_progress.h"
#include "core/constants.h"
#include "core/cube_map.h"
#include "gaussian/erf_steps.h"

namespace airlight {

namespace {

constexpr int kTile = 8;  // grid directions a side that share a walk of the hierarchy

}  // namespace

LightDepthMap::LightDepthMap(const GaussianMedium& medium, const Vec3& s, int face, int radial, int threads,
                             double window)
    : LightDepthMap(medium, s, Vec3(0.0, 0.0, -1.0), kPi, face, radial, threads, window) {}

LightDepthMap::LightDepthMap(const GaussianMedium& medium, const Vec3& s, const Vec3& axis, double half_angle, int face,
                             int radial, int threads, double window)
    : s_(s), face_(face), radial_(radial), window_(window) {
    if (face < 2 || radial < 2) throw std::invalid_argument("LightDepthMap: face and radial must be >= 2");
    if (!std::isfinite(s.x) || !std::isfinite(s.y) || !std::isfinite(s.z))
        throw std::invalid_argument("LightDepthMap: the light's position is not finite");
    // A read interpolates the 4 x 4 grid points around its direction, at most two cells'
    // diagonal away, and a cell spans at most 2 / (face - 1) rad of the sphere (at a face's
    // centre).
    const double reach = half_angle + 3.0 * 2.0 / (face - 1);
    if (reach < kPi) {
        const double len = glm::length(axis);
        if (!(len > 0.0) || !std::isfinite(len) || !(half_angle >= 0.0))
            throw std::invalid_argument("LightDepthMap: the cone's axis or angle is not valid");
        axis_ = axis / len;
        cos_reach_ = std::cos(reach);
    }
    r_max_ = LightDepthMap::reach(medium, s);
    dr_ = r_max_ > 0.0 ? r_max_ / (radial - 1) : 1.0;
    // The faces with a grid point in reach; each holds its face x face points and a ring of
    // one more around them (kApron: directions over the face's edge, for the bicubic read).
    const int side = face + 2 * kApron;
    int held = 0;
    for (int f = 0; f < 6; ++f) {
        bool any = false;
        for (int j = -kApron; j < face + kApron && !any; ++j)
            for (int i = -kApron; i < face + kApron && !any; ++i) any = lit(direction(f, i, j));
        slot_[f] = any ? held++ : -1;
    }
    acquire_image_buffer(tau_, std::size_t(held) * side * side * radial, 0.0f);
    if (r_max_ == 0.0) return;
    // Tiles of kTile x kTile grid directions gather their Gaussians in one walk of the medium's
    // hierarchy (the cone around them), each direction keeping those its own walk would reach:
    // one walk a direction took most of a 1e5-Gaussian map's build.
    const int tiles = (side + kTile - 1) / kTile;
    parallel_chunks(std::size_t(6 * tiles * tiles), threads, 1, [&](std::size_t begin, std::size_t end) {
        std::vector<float> acc(radial);
        std::vector<double> beyond(radial + 1);
        std::vector<std::uint32_t> near;
        std::vector<Vec3> ws;
        for (std::size_t tile = begin; tile < end; ++tile) {
            const int f = int(tile) / (tiles * tiles), i0 = int(tile) % tiles * kTile - kApron,
                      j0 = int(tile) / tiles % tiles * kTile - kApron;
            if (slot_[f] < 0) continue;
            const int i1 = std::min(face + kApron, i0 + kTile), j1 = std::min(face + kApron, j0 + kTile);
            ws.clear();
            Vec3 axis(0.0);
            for (int j = j0; j < j1; ++j)
                for (int i = i0; i < i1; ++i) ws.push_back(direction(f, i, j)), axis += ws.back();
            axis = glm::normalize(axis);
            double cos_half = 1.0;
            for (const Vec3& w : ws) cos_half = std::min(cos_half, glm::dot(w, axis));
            near.clear();
            medium.for_each_in_cone(s_, axis, std::max(0.0, cos_half - 1e-9),
                                    [&](std::size_t g) { near.push_back(std::uint32_t(g)); });
            for (int j = j0; j < j1; ++j)
                for (int i = i0; i < i1; ++i) {
                    const Vec3& w = ws[std::size_t((j - j0) * (i1 - i0) + (i - i0))];
                    if (lit(w)) fill(medium, near, w, &tau_[index(slot_[f], i, j)], acc, beyond);
                }
            build_progress_check();  // progress and cancel of the bake building it
        }
    });
}

double LightDepthMap::reach(const GaussianMedium& medium, const Vec3& s) {
    double r = 0.0;
    for (std::size_t j = 0; j < medium.size(); ++j)
        if (medium.cull_radius(j) > 0.0) r = std::max(r, glm::length(medium.centre(j) - s) + medium.cull_radius(j));
    return r;
}

Vec3 LightDepthMap::direction(int f, int i, int j) const {
    return cube_direction(f, -1.0 + 2.0 * i / (face_ - 1), -1.0 + 2.0 * j / (face_ - 1));
}

void LightDepthMap::fill(const GaussianMedium& medium, const std::vector<std::uint32_t>& near, const Vec3& w,
                         float* out, std::vector<float>& acc, std::vector<double>& beyond) const {
    std::fill(acc.begin(), acc.end(), 0.0);
    std::fill(beyond.begin(), beyond.end(), 0.0);
    const int last = radial_ - 1;
    thread_local ErfSteps steps;
    steps.clear();
    for (const std::uint32_t g : near)
        if (medium.segment_reaches(g, s_, w, r_max_)) steps.add(medium, g, s_, w, window_, dr_, last);
    // (T_j: 0 at r = 0, the whole step K erfc(-a p) past its bins)
    add_erf_steps(steps, float(dr_), last, acc.data(), beyond.data());
    double whole = 0.0;
    for (int k = 0; k <= last; ++k) {
        whole += beyond[k];
        out[k] = float(double(acc[k]) + whole);
    }
}

double LightDepthMap::operator()(const Vec3& x) const {
    if (r_max_ == 0.0) return 0.0;
    const Vec3 d = x - s_;
    if (d == Vec3(0.0)) return 0.0;
    const CubeFacePoint c = cube_face_point(d);
    const int f = slot_[c.face];
    if (f < 0) return 0.0;  // (out of a spot's reach)
    const double fu = std::clamp((c.p + 1.0) * 0.5 * (face_ - 1), 0.0, face_ - 1.0);
    const double fv = std::clamp((c.q + 1.0) * 0.5 * (face_ - 1), 0.0, face_ - 1.0);
    const int i0 = std::min(int(fu), face_ - 2), j0 = std::min(int(fv), face_ - 2);
    const double fr = std::min(glm::length(d) / dr_, radial_ - 1.0);
    const int k0 = std::min(int(fr), radial_ - 2);
    const double wr = fr - k0;
    // Catmull-Rom across the directions (points i0 - 1 .. i0 + 2, the apron's at the face's
    // edges), linear in distance.
    double wu[4], wv[4];
    catmull_rom(fu - i0, wu), catmull_rom(fv - j0, wv);
    const float* base = &tau_[index(f, i0 - 1, j0 - 1) + std::size_t(k0)];
    const std::size_t row = std::size_t(face_ + 2 * kApron) * radial_;
    double tau = 0.0;
    for (int dj = 0; dj < 4; ++dj) {
        const float* p = base + dj * row;
        double line = 0.0;
        for (int di = 0; di < 4; ++di, p += radial_) line += wu[di] * ((1.0 - wr) * p[0] + wr * p[1]);
        tau += wv[dj] * line;
    }
    return std::max(0.0, tau);  // (the cubic may undershoot a step's foot)
}

void LightDepthMap::catmull_rom(double t, double w[4]) {
    const double t2 = t * t, t3 = t2 * t;
    w[0] = 0.5 * (-t3 + 2.0 * t2 - t);
    w[1] = 0.5 * (3.0 * t3 - 5.0 * t2 + 2.0);
    w[2] = 0.5 * (-3.0 * t3 + 4.0 * t2 + t);
    w[3] = 0.5 * (t3 - t2);
}

}  // namespace airlight
