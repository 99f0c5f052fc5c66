// phase.h: phase functions p(cos theta) normalised to 1 over the sphere (units 1/sr).
//
// Angle convention (the whole code base): theta is the angle between PROPAGATION
// directions, i.e. between the light's direction of travel (light -> x) and the scattered
// direction (x -> viewer). For single scattering toward a viewer at v from a light at s:
//   cos theta(x) = dot((x - s)/|x - s|, (v - x)/|v - x|).
// theta = 0 is forward scattering: looking from v straight at the light.
//
// Henyey-Greenstein uses Cycles' sign, g > 0 forward (Cycles "Anisotropy"):
//   p = (1 - g^2) / (4 pi (1 + g^2 - 2 g cos theta)^{3/2}).
// NOTE: Hoffman & Preetham 2002 print the numerator as (1 - g)^2 and call negative g
// forward; neither matches this (normalised, Cycles-sign) form, which is the one used here.
// Rayleigh 3 (1 + mu^2) / (16 pi); Nishita hazy Mie (1 + 9 s^8) / (8 pi) and murky Mie
// 33 (1 + 50 s^32) / (332 pi), s = (1 + mu) / 2 (cos^2(theta/2)). The printed constants are
// right: 2 pi int_{-1}^{1} p dmu = 1 exactly for all four (phase_test.cpp checks it).
#pragma once

#include "core/constants.h"

#include <cmath>
#include <string>

namespace airlight {

enum class PhaseKind { Isotropic, HenyeyGreenstein, Rayleigh, HazyMie, MurkyMie };

struct PhaseFunction {
    PhaseKind kind = PhaseKind::Isotropic;
    double g = 0.0;  // Henyey-Greenstein asymmetry in (-1, 1); ignored by the others

    // p(cos theta) in 1/sr; _mu_ = cos theta is clamped to [-1, 1].
    double eval(double mu) const;
    // The same from the half angle, _s2_ = sin^2(theta/2) = (1 - mu)/2 and _c2_ =
    // cos^2(theta/2) = (1 + mu)/2, for integrands that know them to full relative precision:
    // HG's 1 + g^2 - 2 g mu is then (1 - g)^2 + 4 g s2 (g >= 0) or (1 + g)^2 + 4 |g| c2
    // (g < 0), a sum of positive terms. From mu it cancels to a relative noise of
    // ~1e-16 / (1 - |g|)^2 in a sharp lobe (2e-10 at |g| = 0.999), which no 1e-12 quadrature
    // could converge through (the Biri 2006 table build hung for |g| >= 0.998).
    double eval_half_angle(double s2, double c2) const;
    // Width scale of the lobe in theta (1 for smooth lobes, ~(1 - |g|) for HG); used to
    // lay out tables and quadrature breakpoints.
    double lobe_width() const;
};

// Henyey-Greenstein with the Cycles sign (g > 0 forward).
inline double phase_hg(double mu, double g) {
    const double denom = 1.0 + g * g - 2.0 * g * mu;
    return kInv4Pi * (1.0 - g * g) / (denom * std::sqrt(denom));
}

// Parses "isotropic", "hg" (alias "henyey_greenstein"), "rayleigh", "hazy_mie", "murky_mie";
// throws std::invalid_argument listing the valid names. Validates g (|g| < 1, finite).
PhaseFunction phase_from_name(const std::string& name, double g = 0.0);
const char* phase_name(PhaseKind kind);

}  // namespace airlight
