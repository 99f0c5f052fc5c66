// spot_light.h: Blender/Cycles spot lights in homogeneous fog (single scattering).
//
// Cycles 3.4 spot intensity (NOTES.md, measured against renders): for a spot of power P,
// colour C, cone angle _size_ and _blend_, with theta measured from the spot axis (the
// lamp's -Z),
//   I(theta) = I0 * cos(theta) * smoothstep(0, (1 - cos(size/2)) * blend, cos(theta) - cos(size/2))
// inside the cone (cos theta > cos(size/2)) and 0 outside, I0 = C P / (4 pi) in W/sr.
// smoothstep(e0, e1, x) = t^2 (3 - 2 t), t = clamp((x - e0) / (e1 - e0), 0, 1); with
// blend = 0 the edge is a hard step (Cycles skips the smoothstep when the width is 0).
//
// Airlight of one view ray o + x d, x in [0, Dvp] (Dvp may be inf), per unit I0 and albedo
// (sigma_s = sigma_t), phase angle as phase.h (cos theta_p = direction of propagation
// light -> x dotted with the view direction towards the eye, i.e. -d):
//   La = sigma_t int_0^Dvp profile(x) p(cos theta_p) exp(-sigma_t (d(x) + x)) / d(x)^2 dx,
// the point-light integrand (Sun 2005 eq. 5 / Biri 2006) times the angular profile. It is
// integrated by adaptive Gauss-Kronrod between breakpoints at the closest approach to the
// light and where the ray crosses the cone and the blend cone (ray-cone intersection,
// solved analytically), so a hard cone edge costs nothing in accuracy.
#pragma once

#include <vector>

#include <glm/glm.hpp>

#include "core/constants.h"
#include "core/phase.h"
#include "core/scene.h"

namespace airlight {

// Blender's smallest Spread (1 deg, RNA hard minimum).
constexpr double kMinSpread = kPi / 180.0 * (1.0 - 1e-6);

// Spot profile constants: cos(size / 2) and the smoothstep width (1 - cos(size/2)) * blend.
//
// The samples of an area light (one-sided Lambert, profile cos(theta)) are spots of 180 deg
// without blend. Cycles 3.4's Spread s < 180 deg (kernel/light/area.h, a soft-box grid of
// slats) multiplies their radiance by max(1 - tan(theta) / tan(h), 0) / (1 - h / tan(h)),
// h = s / 2, the normalisation keeping the power; times cos(theta) that is
//   I(theta) = (sin h cos(theta) - cos h sin(theta)) / (sin h - h cos h) = sin(h - theta) / (...)
// for theta < h (cos_half_angle = cos h, smooth = 0): spread_a cos(theta) - spread_b sin(theta).
struct SpotCone {
    glm::dvec3 axis{0.0, 0.0, -1.0};  // unit spot direction (the lamp's -Z)
    double cos_half_angle = 0.0;     // cos(size / 2), or cos(spread / 2)
    double smooth = 0.0;             // (1 - cos_half_angle) * blend
    double spread_a = 1.0;           // Spread: sin h / (sin h - h cos h)
    double spread_b = 0.0;           // Spread: cos h / (sin h - h cos h); 0: no Spread
    // An IES profile's fit, I(c) = sum_k profile[k] c^k, c = cos(theta), clamped at 0. With
    // profile_alone (make_profile_cone, a point light's) it replaces the cone's factor: I(c)
    // where c > cos_half_angle (the profile's extent; -1: the whole sphere), 0 beyond; else it
    // multiplies the cone's factor (a spot light's). Empty: the cone alone.
    std::vector<double> profile;
    bool profile_alone = false;
    bool has_spread() const { return spread_b > 0.0; }
    bool has_profile() const { return !profile.empty(); }
};

// A point light whose intensity I0 I(c) follows the polynomial _profile_ about _axis_ within
// _extent_ rad of it (pi: the whole sphere) and is dark beyond (SpotCone::profile).
SpotCone make_profile_cone(const glm::dvec3& axis, const std::vector<double>& profile, double extent = kPi);
// Sum_k profile[k] c^k (Horner), unclamped.
double profile_polynomial(const std::vector<double>& profile, double c);
// The cone (or profile, or both: SpotLight::profile_in_cone) of a scene's spot light.
SpotCone make_light_cone(const SpotLight& spot);

// Builds the cone from Blender's spot_size (full cone angle, rad, in (0, pi]) and
// spot_blend ([0, 1]); _axis_ need not be normalised. An area light's _spread_ (full angle,
// rad, [1 deg, pi]) below pi needs spot_size pi and blend 0 (std::invalid_argument otherwise).
SpotCone make_spot_cone(const glm::dvec3& axis, double spot_size, double spot_blend, double spread = kPi);

// The Cycles angular factor cos(theta) * smoothstep(...) (0 outside the cone; with Spread
// sin(h - theta) / (sin h - h cos h)), times max(0, I(c)) with a profile (alone: max(0, I(c))),
// for the cosine _cos_theta_
// between the spot axis and the direction light -> point.
double spot_profile(const SpotCone& cone, double cos_theta);

// The x in (lo, hi) where the line o + x d comes closest in direction to the axis as seen
// from _s_ (the largest cos(theta)), or -1 where none lies there: a Spread profile's kink
// (theta = 0) where the ray crosses the axis. Used as a quadrature breakpoint.
double ray_axis_approach(const glm::dvec3& o, const glm::dvec3& d, const glm::dvec3& s, const glm::dvec3& axis,
                         double lo, double hi);

// The x in (lo, hi) where the line o + x d crosses the cone of half-angle acos(cos_half)
// around _axis_ with apex _s_ (both nappes; sorted). Used as quadrature breakpoints.
std::vector<double> ray_cone_crossings(const glm::dvec3& o, const glm::dvec3& d, const glm::dvec3& s,
                                       const glm::dvec3& axis, double cos_half, double lo, double hi);

// Airlight of a spot at _s_ along the ray from _o_ with unit direction _d_ over [0, Dvp]
// (inf: to infinity), attenuation measured from _o_, per unit I0 and albedo, with the
// phase function _phase_ (isotropic: 1/(4 pi)). Relative tolerance _rel_tol_.
double spot_airlight_quadrature(const SpotCone& cone, const glm::dvec3& s, const PhaseFunction& phase,
                                double sigma_t, const glm::dvec3& o, const glm::dvec3& d, double Dvp,
                                double rel_tol = 1e-6);

}  // namespace airlight
