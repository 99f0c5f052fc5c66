// bake.h: per-pixel fog passes for one camera view, multithreaded over rows.
#pragma once

#include <atomic>
#include <functional>
#include <memory>
#include <vector>

#include "core/buffers.h"
#include "models/model_id.h"
#include "core/scene.h"
#include "core/special_f.h"

namespace airlight {

struct BakeSettings {
    ModelId model = ModelId::Sun05Table;
    int threads = 0;            // 0: all hardware threads
    // Antialiasing: pixels whose first-hit distances disagree with a neighbour's are
    // supersampled with N = _aa_samples_^2 samples (a rank-1 lattice: N distinct offsets
    // per axis) importance-sampled from a Blackman-Harris filter of width _filter_width_
    // pixels (Cycles' default film filter: 1.5 px, support +-1.5 px), so fog edges line up
    // with the render's antialiased edges. There the airlight is the mean over all
    // samples and the transmittance the mean over the samples that hit a surface (see
    // bake.cpp: exact for the composite render * T + A over a black world).
    int aa_samples = 4;
    double filter_width = 1.5;
    int table_nu = 256, table_nT = 256;
    // Lookup in the Sun 2005 F table (sun05 model): bilinear, or nearest sample (cheaper,
    // ~20x the error: special_f.cpp). Biri06's Gamma table is always bilinear.
    Interp table_interp = Interp::Bilinear;
    // Surface shading (surface_pass.h, Sun 2005 eq. 13-19): also bake the per-light
    // attenuation from each light to the first hit and the Lambert glow. Off: the bake is
    // unchanged. The Lambert G table (sun05_surface.h) is _surface_table_nT_ x _ntheta_.
    bool surface = false;
    int surface_table_nT = 128, surface_table_ntheta = 128;
    // Glossy glow (Sun 2005 eq. 18, Gn) for a normalised Phong lobe of this exponent n about
    // the mirrored view direction; 0: none. Its G table is _surface_phong_table_n_ squared.
    double surface_phong_exponent = 0.0;
    int surface_phong_table_n = 64;
    // Lambert glow by Biri 2006's own eq. 10 (Gamma_L(T) x cos theta_s, clamped at 0; any
    // phase) instead of the hemisphere-clamped G (Sun's G0, or the phase-aware G_p): the
    // paper's model, kept selectable for comparison; it is 15-83 % low facing the light and
    // gives no glow facing away (biri06_surface.h), so it is off by default.
    bool surface_glow_biri_eq10 = false;
    // Gaussian fog (perspective, Fogshop models): the Gaussian terms are evaluated every
    // _gaussian_resolution_ pixels (1 full, 2 half, 4 quarter) and interpolated where the
    // surface does not cut a Gaussian, exactly per pixel where it does (gaussian/splat.h).
    int gaussian_resolution = 1;
    // Homogeneous airlight on a lattice of 1 (every pixel, exact), 2 or 4 pixels, interpolated
    // where smooth and exact at depth edges, near point lights' images and where a cell's
    // centre disagrees with its interpolation by more than 5e-4 (bake.cpp lattice_band); the
    // model sun05 with a perspective camera and no spots or Gaussians only (else exact).
    int homogeneous_resolution = 1;
    // Edge supersampling (aa_samples > 1): one fog evaluation per cluster of an edge pixel's
    // sub-samples (all misses; hits whose farthest depth is at most 1 + _edge_cluster_tol_
    // times their nearest) at the cluster's mean ray and depth, each sample's transmittance
    // rescaled to its own depth; clusters whose error estimate exceeds 5e-4 of the airlight
    // (a light's image or a light next to the surface, a dense Gaussian there) are evaluated
    // per sample (bake.cpp edge_sample_clusters, EdgeClusterBounds). 0, and scenes with spot
    // lights: every sub-sample evaluated (the reference).
    double edge_cluster_tol = 0.1;
    // Volumetric shadows (shadow/shadow_volumes.h): the in-scattering of every light that casts
    // shadows is integrated over the lit intervals of each view ray only. Off: the passes are
    // those of unshadowed fog, bit for bit.
    bool shadows = false;
    // How the camera's rays find their crossings of the shadow volumes: rasterized on the film
    // (shadow/screen_crossings.h; perspective cameras, falling back to tracing where it does
    // not apply) or traced through Embree for every ray (the check of the rasterization).
    bool shadow_crossings_traced = false;
    // Soft shadows (penumbrae): a point or spot light with a Radius casts its shadows from this
    // many points of its sphere (homogeneous/sphere_light.h sphere_light_shadow_samples), each
    // a shadow volume, and the fog is lit by their mean; 1: from its centre (hard shadows).
    // Homogeneous fog (fog objects take their lights as points).
    int shadow_samples = 1;
    // Gaussian fog with the Fogshop models (perspective, no noise): > 0 refines every (light,
    // Gaussian) pair whose bound on Fogshop's relative error exceeds this accuracy by the exact
    // integral over the Gaussian's support (gaussian/refine.h), each to a tenth of it. 0: Fogshop's
    // approximation alone, bit for bit.
    double gaussian_accuracy = 0.0;
    // The refinement's budget in nominal CPU seconds (its work counted per Gaussian term of an
    // integrand evaluation, FogEvaluator::kRefineSecondsPerWork each): a frame whose centre
    // samples would need more (foreseen from the refinement's grid, or counted) keeps Fogshop's
    // approximation alone and says so (stats gaussian_refine_abandoned).
    double gaussian_refine_budget = 60.0;
    // A light's Radius (homogeneous/sphere_light.h) is taken on the rays where it changes that
    // light's airlight by more than this relative amount, and skipped beyond (its reach grows as
    // 1 / sqrt of it: 27 radii at the default 1e-3). Automatic passes a quarter of its accuracy.
    double light_size_tolerance = 1e-3;
};

struct BakeStats {
    double seconds_raycast = 0.0;
    double seconds_airlight = 0.0;
    long long supersampled_pixels = 0;
    long long samples = 0;
    double seconds_surface = 0.0;  // the surface-shading pass (0 when off)
    // The edge supersampling inside seconds_airlight (sub-pixel rays, their fog, the
    // averages), summed over the worker threads.
    double seconds_edges = 0.0;
    // Fog objects through the tiled splat: binning the Gaussians into tiles and building
    // the far-field grids (GaussianSplat::bin), inside seconds_airlight.
    double seconds_bin = 0.0;
    // Building the fog model between the raycast and the airlight pass (FogModel: the
    // fog objects' medium and cull hierarchy, the splat's per-(light, Gaussian) optical
    // depths, the model's tables on first use), outside both.
    double seconds_fog_setup = 0.0;
    // The bake's context before the raycast, nearly all of it the camera's BVH
    // (RayCaster::shared: the objects that changed built, the others shared), and inside
    // seconds_fog_setup the shadow volumes and their casters'
    // BVH (ShadowVolumes::shared; 0 when shared or without volumetric shadows).
    double seconds_geometry = 0.0;
    double seconds_shadow_volumes = 0.0;
    // Gaussian refinement (settings.gaussian_accuracy > 0): the (light, Gaussian) pairs, the
    // largest bound on Fogshop's error of a pair left to it, and the wall time of the centre
    // samples' refinement inside seconds_airlight (edge samples not counted).
    long long gaussian_pairs = 0;
    double gaussian_kept_bound = 0.0;
    double seconds_refine = 0.0;
    // The uniform fog's term with the Gaussians' exact attenuation (FogEvaluator::
    // refine_gaussians): the (ray, light) pairs corrected, and the bound on the relative error
    // the refinement leaves on any ray (the pairs', marched lights' and uniform fog's shares).
    long long gaussian_background_rays = 0;
    // Point lights whose whole airlight the refinement marched (gaussian/march.h) in place of
    // their pairs' exact terms, and the (ray, light) marches.
    long long gaussian_marched_lights = 0;
    long long gaussian_marched_rays = 0;
    // The pixels between refined rays whose ratio came from a biquadratic through a cell's nine
    // (refine_pass.cpp; the rest take the corners' bilinear ratio).
    long long gaussian_quadratic_pixels = 0;
    bool gaussian_refine_abandoned = false;  // over its budget: Fogshop alone (bound inf)
    double gaussian_refine_work = 0.0;       // the refinement's work, in nominal CPU seconds
    double gaussian_error_bound = 0.0;
};

// Output images are row-major, top row first, 3 floats (RGB) per pixel.
struct BakeResult {
    int width = 0, height = 0;
    std::vector<float> airlight;       // in-scattered radiance, Cycles Combined units
    // exp(-sigma_t (depth - t_near)) from the near clip plane to the first surface (0 where
    // none and sigma_t > 0: the fog goes on to infinity, as in Cycles' world volume).
    std::vector<float> transmittance;
    // 1 float per pixel: distance from the ray origin (the eye for perspective cameras, the
    // near plane for orthographic ones) to the first hit at the pixel centre inside the
    // clip range (inf: none, or beyond clip_end).
    std::vector<float> depth;
    // Surface shading (settings.surface only; empty otherwise), at pixel centres, RGB:
    // surface_attenuation = e^{-T(light l, first hit)}, image after image for the fogged
    // lights l (point lights, then spot lights, in SceneDescription order; 1 where no hit):
    // 3 * width * height floats per light; surface_glow = the Lambert glow of all point and spot
    // lights per unit diffuse colour (surface_pass.h).
    int surface_lights = 0;
    std::vector<float> surface_attenuation;
    std::vector<float> surface_glow;
    // settings.surface_phong_exponent > 0 only: the point and spot lights' glossy glow per
    // unit glossy colour, (n + 2) / (2 pi) sum_l albedo I0 sigma_t Gn(T, theta'_s) / (2 pi D).
    std::vector<float> surface_gloss_glow;
    // settings.surface only: the geometric normal of the first hit at each pixel centre,
    // turned towards the camera (3 floats per pixel, 0 where the ray hits nothing), for
    // image-space shading done after the bake (the environment's irradiance ratio).
    std::vector<float> surface_normals;
    // scene.light_passes > 0 only: per pass its lights' airlight, image after image (3 *
    // width * height floats each); the passes of all lights sum to _airlight_ but for float
    // rounding.
    std::vector<float> light_airlight;
    BakeStats stats;
};

// Progress callback: called from the calling thread with a fraction in [0, 1];
// return false to cancel (bake then throws airlight::Cancelled).
using ProgressFn = std::function<bool(double)>;

struct Cancelled : std::exception {
    const char* what() const noexcept override { return "bake cancelled"; }
};

// Validates the scene (throws std::invalid_argument with a clear message on NaN,
// negative density, zero resolution, ...) and bakes.
BakeResult bake(const SceneDescription& scene, const BakeSettings& settings,
                const ProgressFn& progress = nullptr);


}  // namespace airlight
