// light_depth_map.h: the Gaussians' optical depth from a point light to any point,
// tabulated once per light in the light's own frame (a deep shadow map of Gaussian fog).
//
// The exact light-path depth of eq. 31 sums, at every point of a view ray, the Gaussians near
// the segment from the light: with thousands of broad, overlapping Gaussians that is hundreds
// of erf terms a point (150-580 in the 3000-Gaussian benchmark scene), the whole cost of an
// exact integral (QUADRATURE: 35-65 us a point, 19,000-140,000 points a ray). Along one
// direction w from the light the depth is a sum of erf steps,
//   tau(w, r) = sum_j c_j sqrt(pi) / (2 a_j) exp(-a_j^2 h_j^2) [erf(a_j (r - p_j)) + erf(a_j p_j)],
//   p_j = (b_j - s) . w,  h_j^2 = |b_j - s|^2 - p_j^2,
// smooth in r at the scale of each Gaussian's width and in w at its width over its distance.
// So it is tabulated on a cube map of directions (core/cube_map.h; face x face grid points a face,
// edges and corners included, and a ring of one more past its edges, so that a read never
// leaves a face) times _radial_ distances from 0 to the farthest cull sphere, and read by
// Catmull-Rom interpolation across the directions (4 x 4 grid points) and linear in distance:
// O(1) a point. The Gaussians only: beta0's depth beta0 |x - s| is exact, the caller's.
//
// Accuracy: a Gaussian of width w at distance rho along the light's path moves across a cell
// by rho times its angle, so bilinear reads erred most on points whose light paths cross the
// cloud far from the light (the ground near the camera behind a cloud around a lamp: +1.2 % of
// the airlight on the 3000-Gaussian benchmark at 64 a face, the cells 0.5 m wide at 15 m
// beside Gaussians 1-3 m wide). The bicubic reads err a fifteenth of that there (+0.07 %
// measured on the frame's rays, FogEvaluator::view_map_error) and a fifth on rays through
// the Gaussians; 48 a face now errs less than 64 did. Tested against exact depths in
// gaussian/march_test.cpp.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

#include "core/buffers.h"
#include "core/scene.h"
#include "gaussian/medium.h"

namespace airlight {

class LightDepthMap {
  public:
    // The map of _medium_'s Gaussians around point light _s_: _face_ >= 2 grid points along
    // each cube face's side, _radial_ >= 2 distances; built on _threads_ threads (0: all). A
    // grid direction leaves out the Gaussians a march with _window_ would leave out of a ray
    // along it (medium.h GaussianWindow; infinity: none).
    LightDepthMap(const GaussianMedium& medium, const Vec3& s, int face = 64, int radial = 256, int threads = 0,
                  double window = GaussianWindow::kNone);
    // The map of a spot light, whose light reaches only the directions within _half_angle_
    // (rad) of _axis_: the directions beyond it by more than two of the grid's largest
    // spacings are left out (read as 0: a march never asks there, where the light's profile is
    // 0), and so are the faces that hold none of the others. A 60 degree cone fills about a
    // sixth of the sphere. _half_angle_ >= pi: the whole sphere.
    LightDepthMap(const GaussianMedium& medium, const Vec3& s, const Vec3& axis, double half_angle, int face = 64,
                  int radial = 256, int threads = 0, double window = GaussianWindow::kNone);

    // The Gaussians' optical depth from the light to _x_ (beta0 left out).
    double operator()(const Vec3& x) const;

    const Vec3& light() const { return s_; }
    double max_radius() const { return r_max_; }
    // The farthest from _s_ any of _medium_'s cull spheres reaches (a map's max_radius).
    static double reach(const GaussianMedium& medium, const Vec3& s);
    // The spacing of its distances (a read interpolates linearly between two).
    double radial_step() const { return dr_; }
    std::size_t bytes() const { return tau_.size() * sizeof(float); }
    // The cube faces the map holds (6 but for a spot's).
    int faces_held() const { return int(std::count_if(slot_, slot_ + 6, [](int k) { return k >= 0; })); }

    // (Its table goes back to the pool of warm memory, core/buffers.h.)
    ~LightDepthMap() { recycle_image_buffer(std::move(tau_)); }
    LightDepthMap(const LightDepthMap&) = delete;
    LightDepthMap& operator=(const LightDepthMap&) = delete;

  private:
    // The ring of grid points each face holds beyond its edges (a read's bicubic takes one
    // point past the two around it).
    static constexpr int kApron = 1;
    // The unit direction of grid point (i, j) of cube face f (-kApron <= i, j < face + kApron:
    // over the face's edge, directions past its corners' p, q = +-1).
    Vec3 direction(int f, int i, int j) const;
    // Where the distances of grid point (i, j) of the face in slot _slot_ begin in tau_.
    std::size_t index(int slot, int i, int j) const {
        const std::size_t side = std::size_t(face_ + 2 * kApron);
        return ((std::size_t(slot) * side + std::size_t(j + kApron)) * side + std::size_t(i + kApron)) * radial_;
    }
    // The Catmull-Rom weights of points -1, 0, 1, 2 at t in [0, 1].
    static void catmull_rom(double t, double w[4]);
    // The depths along direction _w_ at the map's distances, into _out_ (radial_ values), from
    // the Gaussians of _near_ (a superset of those whose cull sphere the direction reaches).
    void fill(const GaussianMedium& medium, const std::vector<std::uint32_t>& near, const Vec3& w, float* out,
              std::vector<float>& acc, std::vector<double>& beyond) const;

    // Whether unit direction _w_ is within the cone's reach (always for a point light).
    bool lit(const Vec3& w) const { return glm::dot(w, axis_) >= cos_reach_; }

    Vec3 s_, axis_{0.0, 0.0, -1.0};
    int face_, radial_;
    double r_max_ = 0.0, dr_ = 1.0, cos_reach_ = -2.0;
    GaussianWindow window_;
    int slot_[6] = {0, 1, 2, 3, 4, 5};  // each face's place in tau_, -1 where left out
    std::vector<float> tau_;            // [slot][j + kApron][i + kApron][radial]
};

}  // namespace airlight
