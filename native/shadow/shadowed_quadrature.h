// shadowed_quadrature.h: the reference for volumetric shadows: single scattering along a view
// segment by adaptive quadrature with the light's visibility inside the integrand, asked of a
// visibility test at every node (shadow rays), independent of the lit intervals the bake's
// models integrate over (shadow_volumes.h). The jumps of the visibility are found by scanning
// it along the segment (512 points) and bisecting, and become the rule's breakpoints; shadows
// narrower than the scan's spacing can be missed; given the jumps (the bake's "quadrature"
// model passes its lit intervals' ends) it skips the scan. Slow: a shadow ray per node.
//
// Per unit albedo and light intensity (suns: irradiance), along start + x d, x in [0, seg]
// (seg may be inf), attenuated from start, with the medium's phase (phase.h convention:
// cos theta = -(light's propagation direction) . d):
//   point:  sigma_t int p(cos theta) e^{-sigma_t (x + r)} / r^2 V dx,  r = |start + x d - s|
//   spot:   the same times the spot profile (spot_light.h)
//   sun:    sigma_t p int e^{-sigma_t x} e^{-tau_sun(x)} V dx over the fog layer (sunlight_layer.h:
//           the view path from the layer's entry, the sun's through the layer's top)
#pragma once

#include <functional>
#include <vector>

#include "core/phase.h"
#include "core/scene.h"
#include "homogeneous/spot_light.h"

namespace airlight {

// True where the point is lit.
using Visibility = std::function<bool(const Vec3&)>;

// _jumps_ (optional): where the visibility is known to change (x from start, e.g. the ends of
// the lit intervals of shadow_volumes.h), the breakpoints instead of the scan; the visibility
// is still asked at every node, so a jump missing from the list costs subdivisions, not
// accuracy.
double point_airlight_visible(const PhaseFunction& phase, double sigma_t, const Vec3& s, const Vec3& start,
                              const Vec3& d, double seg, const Visibility& visible, double rel_tol,
                              const std::vector<double>* jumps = nullptr);
double spot_airlight_visible(const SpotCone& cone, const PhaseFunction& phase, double sigma_t, const Vec3& s,
                             const Vec3& start, const Vec3& d, double seg, const Visibility& visible, double rel_tol,
                             const std::vector<double>* jumps = nullptr);
// The sun's factor G of sunlight_layer.h with visibility (times sigma_t p E for the airlight).
double sunlight_factor_visible(double sigma_t, double h_top, double mu_s, const Vec3& start, const Vec3& d,
                               double seg, const Visibility& visible, double rel_tol,
                               const std::vector<double>* jumps = nullptr);

}  // namespace airlight
