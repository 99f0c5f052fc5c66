// sun_depth_map.h: the Gaussians' optical depth from any point towards a sun lamp, tabulated
// once per sun (an orthographic deep shadow map of Gaussian fog).
//
// Towards the sun (unit direction u = -w) the light depth of a point x is a sum of erfc steps,
//   tau(x) = sum_j c_j sqrt(pi) / (2 a_j) exp(-a_j^2 h_j^2) erfc(a_j (s - s_j)),
//   s = x . u,  s_j = b_j . u,  h_j: the distance from b_j to the half-line x + t u,
// smooth along u at each Gaussian's width and across u at the same scale. So it is tabulated
// on a grid of columns parallel to u: face x face columns over the Gaussians' cull spheres
// projected on the plane normal to u, each sampled at _depth_ heights s from below the lowest
// sphere to above the highest, and read by trilinear interpolation: O(1) a point. Below the
// grid a column keeps its lowest value (every Gaussian lies above), above it and beside it the
// depth is 0. The Gaussians only: the uniform fog's layer depth (sunlight_layer_depth) is the
// caller's.
//
// Accuracy: second order in the spacing, like LightDepthMap (gaussian/sun_depth_map_test.cpp);
// the bake chooses the size by the march's measured error (FogEvaluator::plan_marches).
#pragma once

#include <cstddef>
#include <utility>
#include <vector>

#include "core/buffers.h"
#include "core/scene.h"
#include "gaussian/medium.h"

namespace airlight {

// Where the Gaussians' depth towards the sun in unit direction u may be nonzero: below the top
// of the prism of their cull spheres projected along u (coordinates along e1, e2 and u within
// [lo, hi], beneath hi[2]), and the narrowest Gaussian's width 1 / (a sqrt 2) in it.
struct SunFootprint {
    Vec3 u{0.0, 0.0, 1.0}, e1{1.0, 0.0, 0.0}, e2{0.0, 1.0, 0.0};
    double lo[3] = {0.0, 0.0, 0.0}, hi[3] = {0.0, 0.0, 0.0};
    double narrowest = 0.0;
    bool empty = true;
    // The footprint of _medium_'s Gaussians towards _u_ (unit).
    SunFootprint(const GaussianMedium& medium, const Vec3& u);
    // The part [first, second] of the ray o + t r (r unit) within it; first > second: none.
    std::pair<double, double> clip(const Vec3& o, const Vec3& r) const;
};

class SunDepthMap {
  public:
    // The map of _medium_'s Gaussians towards the sun in unit direction _u_ (the light comes
    // from there: u = -w): _face_ >= 2 columns along each side, _depth_ >= 2 heights a column;
    // built on _threads_ threads (0: all). A column leaves out the Gaussians a march with _window_
    // would leave out of a ray along it (as LightDepthMap's; infinity: none).
    SunDepthMap(const GaussianMedium& medium, const Vec3& u, int face = 64, int depth = 256, int threads = 0,
                double window = GaussianWindow::kNone);

    // The Gaussians' optical depth from _x_ towards the sun (beta0 left out).
    double operator()(const Vec3& x) const;

    const Vec3& towards() const { return print_.u; }
    const SunFootprint& footprint() const { return print_; }
    std::size_t bytes() const { return tau_.size() * sizeof(float); }
    // The longest step along unit _r_ that crosses at most one cell along each of the grid's
    // axes: the interpolant's scale (a march's steps within the grid stay below it).
    double cell_step(const Vec3& r) const;

    // (Its table goes back to the pool of warm memory, core/buffers.h.)
    ~SunDepthMap() { recycle_image_buffer(std::move(tau_)); }
    SunDepthMap(const SunDepthMap&) = delete;
    SunDepthMap& operator=(const SunDepthMap&) = delete;

  private:
    // The depths of the column at grid point (i, j), from its bottom up, into _out_.
    void fill(const GaussianMedium& medium, int i, int j, float* out, std::vector<float>& acc,
              std::vector<double>& below) const;

    SunFootprint print_;  // the grid's box (u and an orthonormal frame of the plane normal to it)
    int face_, depth_;
    double dp_ = 1.0, dq_ = 1.0, ds_ = 1.0;  // the grid's spacings
    GaussianWindow window_;
    std::vector<float> tau_;  // [j][i][k]
};

}  // namespace airlight
