// scene.h: the plain scene description that the native side consumes.
//
// Data flows one way: Blender data -> (addon/airlight/scene_export.py) -> this
// description -> kernels -> passes. Nothing in here knows about Blender or Python.
// Units: scene units (metres), radiance in the units of Cycles' Combined pass.
#pragma once

#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "core/phase.h"

namespace airlight {

using Vec3 = glm::dvec3;
using RGB = glm::dvec3;

// Homogeneous medium: extinction coefficient _sigma_t_ (Sun 2005's beta) in 1/m,
// and single-scattering albedo (the fog colour), so sigma_s = albedo * sigma_t.
// _phase_ (kind + Henyey-Greenstein g, Cycles' sign: g > 0 forward; phase.h) defaults
// to isotropic. Only models that support it (biri06, quadrature) accept an anisotropic
// phase; bake() rejects the Sun 2005 models with one (see phase_is_isotropic).
struct HomogeneousMedium {
    double sigma_t = 0.0;
    // Rayleigh scattering coefficient at 550 nm in 1/m, used by ModelId::Hoffman02 only
    // (models/hoffman02_model.cpp: beta_R ~ 1/lambda^4 per channel on top of sigma_t as Mie).
    double rayleigh_550 = 0.0;
    RGB albedo{1.0, 1.0, 1.0};
    PhaseFunction phase;
};

// True for the isotropic phase, including Henyey-Greenstein with g = 0 (the same function).
inline bool phase_is_isotropic(const PhaseFunction& phase) {
    return phase.kind == PhaseKind::Isotropic || (phase.kind == PhaseKind::HenyeyGreenstein && phase.g == 0.0);
}

// Isotropic point light. _I0_ is the radiant intensity in W/sr per RGB channel:
// a Blender point light of power P and colour C has I0 = C * P / (4 pi) (Cycles).
struct PointLight {
    Vec3 position{0.0};
    RGB I0{0.0};
    // Blender's Radius (shadow_soft_size) in m: Cycles' disk of this radius facing each point
    // (homogeneous/sphere_light.h); 0: a point.
    double radius = 0.0;
    bool casts_shadow = true;  // Blender's Cast Shadow (with BakeSettings::shadows)
    int light_pass = -1;  // its per-light airlight pass (SceneDescription::light_passes); -1: none
};

// Blender spot light (Cycles' profile, spot_light.h): _I0_ = C * P / (4 pi) in W/sr as for
// a point light (Blender gives spot power in W like point power), _axis_ the spot
// direction (the lamp's -Z, normalised by the bake), _spot_size_ the full cone angle in
// rad (0, pi], _spot_blend_ in [0, 1].
struct SpotLight {
    Vec3 position{0.0};
    Vec3 axis{0.0, 0.0, -1.0};
    RGB I0{0.0};
    double spot_size = 0.785398163397448;  // Blender's default 45 deg
    double spot_blend = 0.15;
    // An area light's sample (spot_size pi, blend 0): Cycles' Spread, the full angle in rad,
    // [1 deg, pi]; pi (Blender's default) is the plain cos(theta) lobe (spot_light.h).
    double spread = 3.14159265358979323846;
    double radius = 0.0;  // Blender's Radius in m, as for a point light
    // An IES profile fitted as I(c) = I0 sum_k profile[k] c^k, c the cosine from _axis_
    // (SpotCone::profile). A point light's (profile_in_cone false): over the whole sphere in
    // place of the cone (spot_size pi, blend 0, spread pi). A spot light's (profile_in_cone
    // true): times the spot's own cos(theta) smoothstep(...) inside its cone, as Cycles
    // multiplies the IES Texture into a spot's emission. Empty: the spot's cone alone.
    std::vector<double> profile;
    bool profile_in_cone = false;
    // A point light's profile lights the directions within profile_extent rad of _axis_ and
    // none beyond (an IES file dark past its last lit angle); pi: the whole sphere.
    double profile_extent = 3.14159265358979323846;
    bool casts_shadow = true;
    int light_pass = -1;  // as for a point light
};

// Blender sun lamp (sunlight_layer.h): _direction_ of propagation (the lamp's -Z, normalised by
// the bake), _E_ the irradiance in W/m^2 per RGB channel (= colour * strength, Cycles).
// The lamp's angle (soft shadows) is ignored: a sun of angle 0.
struct SunLight {
    Vec3 direction{0.0, 0.0, -1.0};
    RGB E{0.0};
    // Angular diameter (radians, [0, pi]) of the sun's disk, Blender's Angle: its volumetric
    // shadows' penumbrae (shadow_samples directions over the disk); the airlight takes the
    // disk's centre.
    double angle = 0.0;
    bool casts_shadow = true;
    int light_pass = -1;  // as for a point light
};

// Pinhole or orthographic camera, given the way Blender gives it:
// _cam_to_world_ is the camera object's matrix_world (the camera looks down -Z),
// _projection_ is camera.calc_matrix_camera(depsgraph, x=width, y=height,
// scale_x, scale_y) (OpenGL clip space, including shift and sensor fit).
struct Camera {
    glm::dmat4 cam_to_world{1.0};
    glm::dmat4 projection{1.0};
    int width = 0;   // render resolution in pixels (after percentage)
    int height = 0;
    // Clip range as view-axis depths (Blender's camera.data.clip_start / clip_end).
    // Cycles starts camera rays on the near plane, so the fog begins there, and does not
    // see surfaces beyond the far plane (rays that miss still get fog out to infinity).
    // The defaults (0, inf) integrate from the eye and see everything.
    double clip_start = 0.0;
    double clip_end = std::numeric_limits<double>::infinity();
};

// Triangle soup in world space (all render-visible geometry).
struct TriangleMesh {
    std::vector<float> vertices;      // 3 floats per vertex
    std::vector<uint32_t> triangles;  // 3 indices per triangle
};

// Optional inhomogeneous part of the medium, a sum of Gaussians (Fogshop, Zhou et al.
// 2007; gaussian/medium.h): beta(x) = medium.sigma_t + sum_i c_i exp(-a_i^2 |x - b_i|^2), i.e.
// the homogeneous sigma_t acts as the background beta0. Centres _b_ in m (3 doubles per
// Gaussian), scales _a_ in 1/m (> 0), amplitudes _c_ in 1/m (>= 0). The Gaussians
// scatter with the medium's (isotropic) phase and with their own _albedo_ (3 per Gaussian,
// RGB in [0, inf), e.g. the fog object's `airlight_color`) or, if that is empty, the
// medium's albedo; the background beta0 always uses the medium's. Empty: homogeneous fog.
// Noise (Fogshop section 5.5, gaussian/splat.h): perturbs each Gaussian's optical depth along
// the view rays with world-space gradient noise of cell size _noise_scale_ (m, > 0) and
// strength _noise_amplitude_ (>= 0; 0 = off), looked up at point / scale + _noise_offset_.
struct Gaussians {
    std::vector<double> centres;  // x, y, z per Gaussian
    std::vector<double> scales;
    std::vector<double> amplitudes;
    std::vector<double> albedo;   // r, g, b per Gaussian, or empty
    double noise_amplitude = 0.0;
    double noise_scale = 1.0;
    Vec3 noise_offset{0.0};
    bool empty() const { return scales.empty() && amplitudes.empty() && centres.empty(); }
};

struct SceneDescription {
    Camera camera;
    HomogeneousMedium medium;
    Gaussians gaussians;
    std::vector<PointLight> point_lights;
    TriangleMesh geometry;
    // The triangles that cast volumetric shadows (BakeSettings::shadows): Blender's objects
    // with Ray Visibility > Shadow on. _occluders_from_geometry_: the same as _geometry_.
    TriangleMesh occluders;
    bool occluders_from_geometry = true;
    // The leading triangles of _occluders_ that are the camera's geometry too (the camera's
    // rays end where they meet them); the rest cast shadows only.
    size_t occluders_seen_triangles = 0;
    std::vector<SpotLight> spot_lights;  // airlight by quadrature (spot_light.h)
    // Sun lamps and the world height (Z) of the fog layer's top that bounds the fog they
    // light: +inf is Hoffman & Preetham's unattenuated sun (sunlight_layer.h).
    std::vector<SunLight> sun_lights;
    double fog_top = std::numeric_limits<double>::infinity();
    // Per-light airlight passes (BakeResult::light_airlight): each light adds its airlight to
    // pass light_pass as well as to the total, in the same evaluation (homogeneous fog, models
    // that bake per ray, every pixel exact: validate.cpp refuses the rest). 0: none.
    int light_passes = 0;
};

}  // namespace airlight
