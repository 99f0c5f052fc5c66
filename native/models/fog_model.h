// fog_model.h: what a homogeneous fog model computes, one implementation per paper
// (models/<paper>_model.cpp), registered in models/registry.cpp.
//
// The bake's evaluator (bake/fog_evaluator.h) turns view rays into airlight and
// transmittance for every light type and for Gaussian fog; a model supplies the parts that
// differ between the papers: the airlight of a point light along a segment, how spot and
// sun lamps and Gaussian fog are integrated, and the tables it shares with the fast paths.
#pragma once

namespace airlight {

class SpecialFTable;

// How a model integrates the in-scattering of a spot light along a view segment.
enum class SpotMethod {
    ClosedForm,           // Pegoraro 2010's closed form with the phase as a Legendre polynomial
    ClosedFormLowOrder,   // the closed form while the phase polynomial has order <= 8, else quadrature
    Quadrature,           // spot_light.h's adaptive quadrature with analytic cone crossings
};

// How a model integrates Gaussian fog (fog objects).
enum class GaussianMethod {
    Fogshop,     // Zhou et al. 2007's approximation, tiled splat (gaussian/splat.h)
    Quadrature,  // the exact integral per ray (gaussian/airlight.h)
};

class FogModel {
  public:
    virtual ~FogModel() = default;
    // Airlight of a point light per unit albedo x intensity along a view ray: the light at
    // distance _Dsv_ from the ray's start, _cos_gamma_ between the ray and the direction to
    // the light, the segment [0, _Dvp_] (inf: none), attenuated from the start.
    virtual double point_airlight(double Dsv, double cos_gamma, double Dvp) const = 0;
    virtual SpotMethod spot_method() const { return SpotMethod::ClosedFormLowOrder; }
    // Sun lamps: true for the quadrature of the layer integral, false for its closed form
    // (sunlight_layer.h).
    virtual bool sun_quadrature() const { return false; }
    virtual GaussianMethod gaussian_method() const { return GaussianMethod::Fogshop; }
    // Volumetric shadows: true for the reference, which asks the visibility (a shadow ray) at
    // every node of its quadrature, the lit intervals' ends its breakpoints; false for the
    // models that integrate over the lit intervals.
    virtual bool visibility_in_integrand() const { return false; }
    // Fogshop: true when the splat's background (beta0) term is this model's own airlight,
    // false when it is the splat's built-in isotropic Sun 2005 term (from f_table()).
    virtual bool own_gaussian_background() const { return true; }
    // Sun 2005's F table when the model evaluates with it: the bake then takes the SIMD
    // row path (sun05_batch.h) and the splat its table; null otherwise.
    virtual const SpecialFTable* f_table() const { return nullptr; }
};

}  // namespace airlight

namespace airlight {

// Relative tolerance of the quadrature references inside a bake (the reference, not speed).
constexpr double kQuadratureRelTol = 1e-8;
// Pegoraro 2010: Henyey-Greenstein is truncated where its Legendre tail is below
// kPegoraroPhaseTol of the lobe everywhere (airlight error ~1e-7, bench_pegoraro.py), at most
// at order kPegoraroMaxOrder (|g| <= ~0.78; model pegoraro10 refuses wider lobes).
constexpr double kPegoraroPhaseTol = 1e-6;
constexpr int kPegoraroMaxOrder = 96;

}  // namespace airlight
