// preview_factors.h: the per-edit factors of a viewport preview that splats the Gaussians
// itself (Fogshop, Zhou et al. 2007, §5.1; addon/airlight/preview_gaussians.py draws them):
// the optical depths from the eye and each light to every Gaussian centre
// (gaussian/centre_depths.h), Gaussian i's own share of them, and C_sv per light.
#pragma once

#include <cstddef>
#include <vector>

#include "core/scene.h"
#include "gaussian/medium.h"

namespace airlight {

// For the eye v, lights s_l (m of them) and Gaussians b_i (n):
//   T_vb[i]       = T(v, b_i): optical depth of the whole medium (beta0 and every Gaussian,
//                   i's own half included) on the segment v -> b_i;
//   own_vb[i]     = T_i(v, b_i): Gaussian i's own share of it;
//   T_sb[l n + i], own_sb[l n + i]: the same from light l;
//   Csv[l]        = exp(-(T(s_l, v) - beta0 D_sv)): the Gaussians alone on s_l -> v (eq. 16);
//   Dsv[l]        = |s_l - v|;  radius[i] = the cull radius R_i (gaussian/medium.h).
// f1 (eq. 13) is exp(-T_sb - T_vb); the bake uses exp(-(T_sb - own_sb) - (T_vb - own_vb))
// with Gaussian i's own attenuation taken along the true path (gaussian/airlight.h).
// Optical depths are culled with the medium's cull_eps (each skipped Gaussian < eps).
struct GaussianPreviewFactors {
    std::vector<double> T_vb, own_vb, T_sb, own_sb, Csv, Dsv, radius;
};

// Incremental form (an edit that appended Gaussians): with _previous_ = the factors of
// the first _first_new_ Gaussians (same positions, scales, amplitudes, eye, lights and
// beta0), only Gaussians [first_new, n) get the full computation; the others add the new
// Gaussians' line integrals to their previous T (optical depth is a sum over Gaussians).
// Equal to the full call to float rounding (tested).
// View-change form (_eye_only_, the viewport orbiting): the light rows T_sb, own_sb depend
// only on the Gaussians, beta0 and the lights, not on the eye. With _previous_ = the
// factors of the same Gaussians, lights and beta0 (at any eye; its T_sb, own_sb of all n
// Gaussians), only the eye row (T_vb, own_vb), C_sv and D_sv are computed, the light rows
// copied: 1 segment per Gaussian instead of 1 + m, the same sums as the full call
// (first_new is ignored). Throws std::invalid_argument on mismatched sizes or non-finite
// points.
GaussianPreviewFactors rbf_preview_factors(const GaussianMedium& medium, const Vec3& eye,
                                           const std::vector<Vec3>& lights, int threads = 0,
                                           const GaussianPreviewFactors* previous = nullptr,
                                           std::size_t first_new = 0, bool eye_only = false);

}  // namespace airlight
