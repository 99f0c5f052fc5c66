// glow_shadow.h: volumetric shadows on the fog's glow on surfaces (surface_pass.h).
//
// The glow at a surface point p (Sun 2005 eq. 13; G of sun05_surface.h) is the light the fog
// scatters onto p from the whole hemisphere above it; with shadows only the lit fog
// scatters. Each light's glow is scaled by the share of it that comes from lit fog,
//   R(p) = sum_j A_lit(p, w_j) / sum_j A(p, w_j),
// A the light's single-scattered radiance along the half-line p + t w_j (isotropic: Sun
// 2005's closed form for points and spots, e^{-sigma t} for suns), A_lit the same over its
// lit spans (shadow_volumes.h) short of the half-line's first hit (the geometry hides the fog
// behind it from p), w_j kDirections cosine-weighted directions about the normal.
// The unshadowed glow is exact (the G tables); R carries the shadow's share from the same
// fixed directions in numerator and denominator, so their sampling error largely cancels
// (measured against Cycles in tests/blender/test_cycles_surface_shadow.py). R is smooth over
// a surface (the glow integrates a hemisphere), so the surface pass takes it on a grid and
// interpolates it where the grid's nodes lie on the same surface.
#pragma once

#include <vector>

#include "core/scene.h"
#include "image/raycast.h"
#include "shadow/shadow_volumes.h"

namespace airlight {

class GlowShadow {
  public:
    static constexpr int kDirections = 16;

    // _positional_volume_ / _sun_volume_: per point-then-spot light and per sun (the scene's
    // order) its light in _volumes_ (-1: unshadowed); sigma: the fog's extinction for A.
    // _cut_: a cut of the caps of the casters the camera sees (ShadowVolumes::lit_intervals),
    // the one the camera's rays take: the half-lines end at
    // their first hit with the camera's geometry, which holds those casters, so they cross
    // none of their caps before their end and the cut leaves out nothing they cross (and
    // shares the camera rays' traversal instead of building one of every cap).
    GlowShadow(const ShadowVolumes& volumes, std::vector<int> positional_volume, std::vector<Vec3> positions,
               std::vector<int> sun_volume, std::vector<Vec3> sun_directions, double sigma,
               const CapCut& cut = CapCut());

    // Lights: the positional ones, then the suns.
    size_t num_lights() const { return positional_volume_.size() + sun_volume_.size(); }
    // Whether any light is shadowed (else every R is 1).
    bool any() const { return any_; }
    // R of every light at _p_ with unit normal _n_ into out[0 .. num_lights()), the half-lines
    // stopped by _caster_'s geometry (the camera's, with a cut). Thread safe.
    void ratios(const Vec3& p, const Vec3& n, const RayCaster& caster, double* out) const;

  private:
    const ShadowVolumes& volumes_;
    std::vector<int> positional_volume_;
    std::vector<Vec3> positions_;
    std::vector<int> sun_volume_;
    std::vector<Vec3> sun_directions_;
    double sigma_;
    CapCut cut_;
    bool any_ = false;
};

}  // namespace airlight
