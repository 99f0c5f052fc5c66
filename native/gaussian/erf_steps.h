// erf_steps.h: the Gaussians' depth steps along one column of a depth map, in float SIMD.
//
// Along a line from a point (a grid direction of the light-depth map, a column of the sun's),
// Gaussian j's optical depth up to distance r is an erf step of width ~1 / a_j around p_j, the
// centre's projection on the line, scaled by K_j = k_j e^{-ah2_j} (k_j = c_j sqrt(pi) / (2 a_j),
// ah2_j = a_j^2 h_j^2 at the line's closest approach h_j). A map's fill gathers its column's
// Gaussians here and tabulates all their steps in one call of a float kernel: called per
// Gaussian, the kernel's dispatch and its scalar set-up took a third of a map's build.
#pragma once

#include <cstddef>
#include <vector>

#include "core/scene.h"
#include "gaussian/medium.h"

namespace airlight {

struct ErfSteps {
    // Per Gaussian: k, ah2, a, p, x1 = -a p, and the bins [lo, hi] the kernel tabulates.
    std::vector<float> k, ah2, a, p, x1;
    std::vector<int> lo, hi;
    std::vector<float> K, e1;  // (the kernels' scratch: K_j, erfc(|x1_j|))

    void clear();
    // Gaussian g of _medium_ on the line o + t r (r unit) with bins of _bin_ from t = 0 to
    // _last_, unless _window_ leaves it out of the line (GaussianWindow: as a march would).
    // Its bins: those within kStepReach widths of its centre's projection, in whole vectors.
    void add(const GaussianMedium& medium, std::size_t g, const Vec3& o, const Vec3& r,
             const GaussianWindow& window, double bin, int last);
    std::size_t size() const { return k.size(); }
};

// From the point: T_j(r) = K_j (erf(a_j (r - p_j)) - erf(x1_j)), 0 at r = 0. For every j,
// acc[b] += T_j(b dr) for b in [lo_j, hi_j], and past them the whole step K_j erfc(x1_j) into
// beyond[max(hi_j + 1, lo_j)] where hi_j < last (the caller sums _beyond_ outwards).
void add_erf_steps(ErfSteps& steps, float dr, int last, float* acc, double* beyond);

// Towards the sun: T_j(s) = K_j erfc(a_j (s - p_j)), 2 K_j below the step. For every j,
// acc[b] += T_j(b ds) for b in [lo_j, hi_j], and below them 2 K_j into below[min(lo_j, last + 1)
// - 1] where lo_j > 0 (the caller sums _below_ downwards).
void add_erfc_steps(ErfSteps& steps, float ds, int last, float* acc, double* below);

}  // namespace airlight
