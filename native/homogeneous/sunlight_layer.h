// sunlight_layer.h: single scattering of a sun lamp (directional light) in homogeneous fog,
// optionally bounded above by a fog layer top at world height h_top.
//
// Why a layer: in Cycles an infinite world-volume fog attenuates a sun to zero (its light
// crosses infinitely much fog), so a sun only lights fog that is bounded. Two models:
//  * h_top = +inf: Hoffman & Preetham 2002's "low camera" assumption: the sunlight
//    reaches every point of the view ray unattenuated (hoffman02.h).
//  * h_top finite: the fog fills the half-space z <= h_top (world Z up, as Blender). The
//    sun, propagating along the unit vector w (the lamp's -Z), enters the fog through
//    the top: at a point of height z <= h_top it has crossed (h_top - z) / mu_s of fog,
//    mu_s = -w.z (> 0 for a sun shining down; mu_s <= 0: its light has crossed infinitely
//    much fog, no sunlight in the layer). Along the view ray x(t) = o + t d only the part
//    inside the layer scatters and attenuates: with [ta, tb] = [t0, t1] ∩ {z(t) <= h_top}
//    (a half-space meets a line in one interval),
//      La = sigma_s p(cos theta) E int_ta^tb e^{-sigma (t - ta)} e^{-sigma (h_top - z(t)) / mu_s} dt,
//    and since z(t) = z_a + (t - ta) d.z both exponents are linear in t: with
//    k = sigma (1 - d.z / mu_s), L = tb - ta, tau_a = sigma (h_top - z_a) / mu_s,
//      G = int = e^{-tau_a} (1 - e^{-k L}) / k                       (k >= 0)
//              = e^{-sigma L - tau_b} (1 - e^{-|k| L}) / |k|         (k < 0, same value
//                written from the far end so that no factor overflows; tau_b at z(tb)).
//    k = 0 gives L; L = inf only for rays with d.z <= 0, where k >= sigma > 0.
//    The phase angle is fixed along the ray (the sun's direction does not change), so
//    any phase function works: cos theta = -dot(w, d) (phase.h's convention: theta = 0
//    looking into the sun).
// The view ray's attenuation here is that of the layer (from the entry point ta); with the
// camera inside the layer (ta = t0) it is the homogeneous e^{-sigma (t - t0)} of the rest
// of the bake. The bake's Transmittance pass and its point and spot lights do not see the
// layer (fog without a top): a camera above the layer gets the sun's airlight right but
// surfaces' transmittance as in unbounded fog.
#pragma once

#include <limits>

namespace airlight {

// G above: the sun's geometric factor along o + t d for t in [t0, t1] (t1 may be +inf),
// o_z = o.z, d_z = d.z of the unit direction d; h_top = +inf for the HP model (then
// G = (1 - e^{-sigma (t1 - t0)}) / sigma, or t1 - t0 for sigma = 0).
// La = sigma_s * p(cos theta) * E * G.
double sunlight_layer_factor(double sigma_t, double h_top, double mu_s, double o_z, double d_z, double t0, double t1);

// G over the span [a, b] of the ray o + t d, attenuated from the fog's start t_start <= a instead
// of from a (sunlight_layer_factor attenuates from the start of its own segment in the layer):
// a lit span of a shadowed ray.
double sunlight_span(double sigma_t, double h_top, double mu_s, double o_z, double d_z, double t_start, double a,
                     double b);

// The sun's optical depth through the layer from height z: beta0 (h_top - z) / mu_s below a
// finite top, 0 above it or without a top (the HP model); +inf where the path to the sun
// crosses infinitely much fog (mu_s <= 0 inside the layer, mu_s < 0). Gaussian fog's light
// paths to a sun add it to the Gaussians' own depth.
double sunlight_layer_depth(double beta0, double h_top, double mu_s, double z);

// Reference for G by adaptive quadrature of the integrand written out independently
// (optical depths of the view and sun paths computed from the geometry at every t).
double sunlight_layer_factor_quadrature(double sigma_t, double h_top, double mu_s, double o_z, double d_z, double t0,
                                   double t1, double rel_tol = 1e-12);

}  // namespace airlight
