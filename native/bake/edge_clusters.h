// edge_clusters.h: the sub-samples of edge pixels (silhouettes, creases): where they lie in
// the pixel (Cycles' Blackman-Harris film filter), how they group into clusters that share
// one fog evaluation, and the error bound that decides when a cluster is evaluated per sample.
#pragma once

#include <vector>

#include <glm/glm.hpp>

#include "core/scene.h"
#include "gaussian/medium.h"
#include "image/camera.h"

namespace airlight {

// Sub-pixel offsets for edge pixels: _n_ x _n_ = N points with N distinct offsets on
// each axis, so a horizontal or vertical edge's coverage is resolved to 1/N (a regular
// n x n grid has only n distinct rows: measured on Cycles' floor-edge scene, its edge rows
// came out ~12 % dark). The points are a rank-1 lattice {((k + 1/2) / N, (a k mod N + 1/2)
// / N)} with the generator _a_ that maximises the shortest lattice vector on the torus
// (Korobov's choice: well spread in 2D, one point per row and per column), mapped per
// axis through the inverse CDF of Cycles' Blackman-Harris filter of support [-w, w]
// (separable filter, so that is importance sampling with equal weights, as Cycles does).
std::vector<glm::dvec2> filter_pattern(int n, double w);

// Clusters of one edge pixel's _n_ sub-samples for the supersampling in bake() (pass 2):
// the fog of a sub-sample is a smooth function of its ray and its segment [t0, depth], and
// within one pixel's filter footprint the rays differ by ~1 pixel, so what sets samples apart
// is the surface they hit (or that they hit none). Writes the sample indices 0 .. n-1 sorted
// by _depth_ (misses, inf, last) to _order_ and appends to _ends_ the end (index into
// _order_) of each cluster: all misses in one; the hits split greedily, nearest first, into
// runs whose farthest depth is at most (1 + _tol_) times their nearest. A NaN depth (never
// cast) is a cluster of its own.
void edge_sample_clusters(const float* depth, int n, double tol, int* order, std::vector<int>& ends);

// Error estimate for a cluster of edge sub-samples (edge_sample_clusters) evaluated at one
// representative ray (mean origin and direction, mean depth D, mean near distance t0),
// relative to the representative's airlight La (per channel), in O(samples + lights):
//  - Each point light l: unattenuated, its in-scattering along [t0, D] is W_l g with
//    g = int_t0^D dt / d(t)^2 = (atan((D - t*) / h) - atan((t0 - t*) / h)) / h (h the
//    ray's closest approach, t* its abscissa). The samples' mean g differs from the
//    representative's by second order: ~g E|delta|^2 / (h - L)^2 in the direction (g ~ 1/h;
//    delta the samples' lateral offsets from the representative at t*, L the largest: the
//    light's image within ~L / h of the pixel) plus Var(D_k) / d_end^3 in the depth (a
//    surface next to the light). Times 2 (a weight non-uniform along the ray, ~1/d^2 against g ~ 1/h)
//    and the light's share of La: at most 1, and at most W_l g / La with W_l <= sigma_s
//    I_l P exp(-sigma_bg (|s - o| - t0)) / (4 pi) (homogeneous fog).
//  - Hits: the attenuation's and the density's share of the integrand's variation over
//    the depths, mean_k int_D^D_k (f(t) - f(D)) dt ~ 1/2 Var(D_k) f'(D), |f_l'| <= f_l
//    (sigma (2 sigma + G / d) + rho') (the phase's slope G, the Gaussians' density rho and
//    its slope near the surface points); suns under a fog top (f drops to 0 there) take
//    the first-order bound mean |D_k - D| f. (Spot lights: no clusters, see bake().)
// The transmittance is rescaled per sample by the background (exact), leaving the
// Gaussians' part: ~Var (rho' / 2 + rho^2 / 2 + rho sigma_bg).
class EdgeClusterBounds {
  public:
    EdgeClusterBounds(const SceneDescription& scene, const GaussianMedium* gaussians);

    // Relative error estimates (airlight: the largest over the channels of _La_, the
    // representative's; transmittance) of the cluster of the _n_ samples rays[idx[q]],
    // depth[idx[q]] (all hits or all misses) represented by the ray _rep_ with near distance
    // _t0_ (0 without a near clip) and depth _D_.
    void errors(const Ray* rays, const float* depth, const int* idx, int n, const Ray& rep, double t0, double D,
                const RGB& La, double& err_La, double& err_Tr) const;

  private:
    struct Light {
        Vec3 s;
        RGB w;  // largest albedo x I0
    };
    struct Sun {
        Vec3 w;
        RGB w_E;  // largest albedo x E
    };

    // 4 pi p over the scattering angles along [t0, D] towards _s_: 1 (isotropic) or the
    // largest of p at the closest approach and the ends.
    double phase_bound(const Ray& r, double t0, double D, const Vec3& s) const;

    double sigma_bg_;
    PhaseFunction phase_;
    const GaussianMedium* gaussian_;
    bool isotropic_ = true, sunlight_layer_ = false;
    double phase_grad_ = 0.0;
    std::vector<Light> lights_;
    std::vector<Sun> suns_;
};

}  // namespace airlight
