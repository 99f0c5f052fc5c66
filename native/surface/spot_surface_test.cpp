// spot_surface_test.cpp: the bake's spot glow (SpotGlowModel x the point-light glow) and the
// naive profile-toward-p estimate against the brute-force integral of the spot's profile along
// every incident ray (spot_surface_glow_reference). Prints the measured errors.
#include "core/constants.h"
#include "surface/spot_surface.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "surface/biri06_surface.h"

namespace airlight {
namespace {


struct Errors {
    double model, naive;
};

// One surface point p with normal n below a spot at s: prints and returns the relative errors.
Errors measure(const char* where, const SpotCone& cone, const glm::dvec3& s, const PhaseFunction& phase,
               double beta, const glm::dvec3& p, const glm::dvec3& n, double rel_tol) {
    const double D = glm::length(s - p);
    const double theta_s = std::acos(std::clamp(glm::dot(n, (s - p) / D), -1.0, 1.0));
    const double ref = spot_surface_glow_reference(cone, s, phase, beta, p, n, 1.0, rel_tol);
    const double point = beta * biri06_surface_G_exact(phase, beta * D, theta_s, 1.0) / (2.0 * kPi * D);
    const SpotGlowModel model(cone, phase);
    const double ours = model.factor(beta * D, s, p) * point;
    const double naive = spot_glow_profile(cone, s, p) * point;
    std::printf("spot glow %-9s %-26s: reference %.4g, model %.4g (%+.3f), profile at p %.4g (%+.3f), point %.4g\n",
                phase_name(phase.kind), where, ref, ours, ours / ref - 1.0, naive, naive / ref - 1.0, point);
    EXPECT_GT(ref, 0.0);
    EXPECT_LT(ref, point);  // a spot lights less fog than a point light of the same I0
    return {ours / ref - 1.0, naive / ref - 1.0};
}

// A surface facing the light: the model is exact up to its tables (see spot_surface.h).
TEST(SpotSurface, ModelExactFacingTheLight) {
    const glm::dvec3 s(0.0, 0.0, 3.0);
    const SpotCone cone = make_spot_cone(glm::dvec3(0.0, 0.0, -1.0), kPi / 4.0, 0.15);
    for (const PhaseFunction& phase : {PhaseFunction{}, PhaseFunction{PhaseKind::HenyeyGreenstein, 0.6}})
        for (double x : {0.0, 1.2, 2.5}) {
            const glm::dvec3 p(x, 0.0, 0.0), n = glm::normalize(s - p);
            const Errors e = measure(x == 0.0 ? "facing, on axis" : x < 2.0 ? "facing, cone edge" : "facing, outside",
                                     cone, s, phase, 0.3, p, n, 1e-3);
            EXPECT_NEAR(e.model, 0.0, 1e-2) << "x " << x;
        }
}

// A 45 deg spot (blend 0.15) 3 m above a floor (normal +z), fog beta = 0.3: on the axis,
// inside, at the cone's edge (tan(22.5 deg) 3 = 1.24 m), outside. The floor is tilted from the
// light direction there, which the model ignores: it overestimates, measured +0.09 / +0.35 /
// +0.54 / +1.08 (isotropic; HG 0.6: +0.03 / +0.14 / +0.22 / +0.49) inside / edge / outside / far
// outside, vs +3.5 ... -1 for the profile toward p. Tolerances: the measured errors with headroom.
TEST(SpotSurface, FloorUnderSpot) {
    const glm::dvec3 s(0.0, 0.0, 3.0), n(0.0, 0.0, 1.0);
    const SpotCone cone = make_spot_cone(glm::dvec3(0.0, 0.0, -1.0), kPi / 4.0, 0.15);
    struct Case {
        const char* where;
        double x, tol;
    };
    for (const PhaseFunction& phase : {PhaseFunction{}, PhaseFunction{PhaseKind::HenyeyGreenstein, 0.6}})
        for (const Case& c : {Case{"floor, on axis", 0.0, 0.01}, Case{"floor, inside (0.8 m)", 0.8, 0.12},
                              Case{"floor, cone edge (1.2 m)", 1.2, 0.45}, Case{"floor, outside (1.6 m)", 1.6, 0.7},
                              Case{"floor, far outside (3 m)", 3.0, 1.3}}) {
            const Errors e = measure(c.where, cone, s, phase, 0.3, glm::dvec3(c.x, 0.0, 0.0), n, 1e-3);
            EXPECT_NEAR(e.model, 0.0, c.tol) << c.where;
        }
}

}  // namespace
}  // namespace airlight
