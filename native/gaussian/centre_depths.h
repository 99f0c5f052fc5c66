// centre_depths.h: optical depths from a point to every Gaussian centre, T(s, b_i) (Fogshop,
// Zhou et al. 2007, §5: the per-(light, Gaussian) factor f1 = exp(-T(s, b_i) - T(v, b_i)) of
// eq. 13 and the preview's T_vb, T_sb). The segments from one source s (the eye or a light)
// to the centres form a star; a sun lamp's from the centres towards the sun are parallel
// half-lines. Both are binned once per source instead of walking the medium's hierarchy
// once per segment (centre_depths.cpp says how). Used by the bake's splat set-up
// (gaussian/splat.h) and the viewport preview's factors (gaussian/preview_factors.h).
#pragma once

#include <cstddef>
#include <vector>

#include "core/scene.h"
#include "gaussian/medium.h"

namespace airlight {

// For each source s_r in _sources_ and target Gaussian i in [first, last),
//   out[r (last - first) + i - first] = sum over j in [cand_first, cand_last), j != i, of T_j(s_r, b_i),
// no beta0, culled as GaussianMedium::for_each_near (each skipped Gaussian < cull_eps), in float
// (fast_erf.h). _method_ picks how the work on the star is organised (centre_depths.cpp): 0 by
// cost, 1 per target, 2 per candidate, 3 binned by direction around the source. All give the
// same sums to float rounding (tested). Throws std::invalid_argument on a non-finite source,
// ranges outside the medium or a method outside 0..3.
std::vector<double> gaussian_depths_to_centres(const GaussianMedium& medium, const std::vector<Vec3>& sources,
                                               std::size_t first, std::size_t last, std::size_t cand_first,
                                               std::size_t cand_last, int threads = 0, int method = 0);

// T(s_r, b_i) without Gaussian i, beta0 included, for s_0 = _eye_ and s_1..L = _lights_,
// every Gaussian: out[r n + i] (the factors f1 of the splat and of FogshopAirlight).
std::vector<double> gaussian_centre_depths(const GaussianMedium& medium, const Vec3& eye, const std::vector<Vec3>& lights,
                                           int threads = 0);

// The same towards a sun lamp (GaussianSplatLights): out[i] = sum over j != i of T_j on the
// half-line b_i + t u, t >= 0 (u unit, towards the sun), culled, in float, no beta0 (binned
// on a grid over the plane normal to u). Throws std::invalid_argument unless u is a finite
// unit vector.
std::vector<double> gaussian_sun_depths(const GaussianMedium& medium, const Vec3& u, int threads = 0);

// The homogeneous medium's optical depth beta0 L over a length L: 0 for beta0 = 0 even when
// L = inf (an empty medium along a ray to infinity).
inline double background_depth(double beta0, double L) { return beta0 == 0.0 ? 0.0 : beta0 * L; }

}  // namespace airlight
