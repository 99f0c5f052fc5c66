// fog_evaluator.h: transmittance and airlight of view rays for every light type and for
// Gaussian fog, with the fog model of the bake (models/fog_model.h supplies what differs
// between the papers: a point light's airlight along a segment, how spots, suns and Gaussian
// fog are integrated, the table of the fast row path).
#pragma once

#include <atomic>
#include <cstdint>
#include <limits>
#include <memory>
#include <vector>

#include "bake/bake.h"
#include "bake/map_cache.h"
#include "core/buffers.h"
#include "core/scene.h"
#include "gaussian/airlight.h"
#include "gaussian/light_depth_map.h"
#include "gaussian/medium.h"
#include "gaussian/refine.h"
#include "gaussian/splat.h"
#include "gaussian/sun_depth_map.h"
#include "homogeneous/pegoraro10.h"
#include "homogeneous/sphere_light.h"
#include "homogeneous/spot_light.h"
#include "image/camera.h"
#include "models/fog_model.h"
#include "shadow/screen_crossings.h"
#include "shadow/shadow_volumes.h"

namespace airlight {

struct GaussianMarch;

// Per-light data, precomputed once per bake.
struct LightData {
    Vec3 s;          // position
    RGB weight;      // albedo * I0
    double Dsv = 0;  // distance to the camera position (perspective rays share the origin)
    double radius = 0;  // Blender's Radius (homogeneous/sphere_light.h); 0: a point
    std::shared_ptr<const SphereFalloff> falloff;  // its disk's falloff (radius > 0)
    int pass = -1;   // its per-light pass (SceneDescription::light_passes); -1: none
};

// A ray of the frame, from the eye along unit _d_ over [near, depth] (depth inf: the sky).
struct ViewRay {
    Vec3 d{0.0, 0.0, 1.0};
    double near = 0.0, depth = 0.0;
};

// Evaluates transmittance and airlight of view rays with a fog model.
class FogEvaluator {
  public:
    // _views_: a spread of the frame's rays, to their surfaces (the raycast's): the light-depth
    // maps' check marches them too (march_map_error).
    FogEvaluator(const SceneDescription& scene, const BakeSettings& settings, const FogModel& model, bool shared_origin,
                 const Vec3& origin, std::vector<ViewRay> views = {});

    // Background (beta0) term of the splat's light l (GaussianSplatLights::background): point
    // lights n_gaussian_points_ first, then spots, then suns; per unit albedo I0 (suns: albedo E)
    // along origin_ + t d over [t0, Dvp], attenuated from t0, with the bake's model.
    double gaussian_background(size_t l, const Vec3& d, double t0, double Dvp) const;

    // Transmittance of the ray _r_ from t0 to _depth_ (inf: none), as eval_many computes it.
    double transmittance(const Ray& r, double t0, double depth) const;

    // Gaussian fog through the tiled splat (perspective, Fogshop models): null otherwise.
    GaussianSplat* splat() const { return splat_.get(); }
    // The Gaussian medium (null for homogeneous fog).
    const GaussianMedium* gaussian_medium() const { return gaussian_.get(); }

    // True if _eval_soa_ applies (perspective camera, table model, fog): then a near
    // distance t0 costs nothing extra (one evaluation of the segment, sun05_batch.h).
    bool soa() const { return shared_origin_ && model_.f_table() && sigma_t_ > 0.0 && !gaussian_; }

    // The transmittance part of _eval_soa_ alone (soa() only), the same values.
    void transmittance_soa(const float* Dvp, const float* t0, int n, float* Tr) const;
    bool has_spots() const { return !spots_.empty(); }
    // Volumetric shadows are on for at least one light (BakeSettings::shadows and casters).
    bool has_shadows() const { return shadows_ != nullptr; }
    // Volumetric shadows on Gaussian fog with the Fogshop models (point lights, and spots with a
    // perspective camera; suns there stay unshadowed): adds to La[k] what the shadows take from ray k, Fogshop over the
    // lit spans (FogshopAirlight::eval_rgb_spans) less Fogshop over the whole segment [t0,
    // Dvp]. The splat's centre samples (gaussian_pass) and eval_gaussians' rays take it.
    void shadow_gaussians(const Ray* rays, const float* Dvp, const float* t0, int n, RGB* La) const;
    // Gaussian refinement (BakeSettings::gaussian_accuracy, gaussian/refine.h): adds to La[k] the
    // marched lights' airlight less their Fogshop values, and the exact uniform-fog terms less
    // Fogshop's where those miss the target, over the lit spans with shadows. After
    // shadow_gaussians on the same rays.
    void refine_gaussians(const Ray* rays, const float* Dvp, const float* t0, int n, RGB* La) const;
    // refine_gaussians for the edge pass's sub-samples (neighbours in the image): a sample
    // between refined centres on its surface whose ratios agree takes theirs (frame_ratio), else
    // one next to the last refined sample on the same surface takes its refined / Fogshop ratio.
    void refine_samples(const Ray* rays, const float* Dvp, const float* t0, int n, RGB* La) const;
    // The refine pass's frame, kept for the edge pass: per pixel the centre's Fogshop value and
    // its refined one (W x H x 3), the depths, and the camera's affine rays (pixel (i, j)'s
    // centre looks along D0 + (i + 1/2) Dx + (j + 1/2) Dy).
    struct RefinedFrame {
        int W = 0, H = 0;
        std::vector<float> fogshop, refined;  // (on the pool's memory, handed back at the end)
        const std::vector<float>* depth = nullptr;
        glm::dmat3 to_film{1.0};  // inverse of the columns (Dx, Dy, D0)
        ~RefinedFrame() { recycle_image_buffer(std::move(fogshop)), recycle_image_buffer(std::move(refined)); }
    };
    void keep_refined_frame(std::unique_ptr<RefinedFrame> frame) const { refined_frame_ = std::move(frame); }
    // Two depths along unit _d_ see the same surface, for a ratio of refined to Fogshop values:
    // inverse depths within 1 %, both the sky, or both past the Gaussians with the uniform fog
    // between them bounded below _tol_ times _value_ (uniform_fog_bound).
    bool same_ratio_depths(const Vec3& d, double D1, double D2, double value, double tol) const;
    // The refinement (null when off or when nothing needs it).
    const GaussianRefiner* refiner() const { return refiner_.get(); }
    size_t refine_pairs() const { return refine_pairs_; }
    // The refinement's marched lights, and the (ray, light) marches so far.
    size_t marched_lights() const { return marched_.size(); }
    long long marched_rays() const { return marched_rays_.load(); }
    double refine_kept_bound() const { return refine_kept_bound_; }
    // The relative error bound the refinement leaves (0 without it), and the (ray, light)
    // pairs whose uniform-fog term it corrected so far.
    double refine_error_bound() const { return refine_error_bound_; }
    double refine_target() const { return refine_target_; }
    // The distance from the eye past which no Gaussian's cull sphere lies: rays that end
    // beyond it cross the same Gaussians whatever their depth (refine_pass).
    double gaussians_end() const { return gaussians_end_; }
    // An upper bound on the uniform fog's single scattering between D1 and D2 (D1 <= D2, D2
    // may be inf) on the ray from the eye along unit _d_, summed over the channels: the lights
    // unshadowed, at their phase function's and spot's peak, the light's depth left out.
    double uniform_fog_bound(const Vec3& d, double D1, double D2) const;
    // Whether the surfaces at depths _D_ along the four unit rays _d_ from the eye (a cell's
    // corners) lie before a Gaussian's centre on some of them and past it on others: there
    // Fogshop's term of that Gaussian changes form (the ray's end passes the centre's
    // projection), and its error a band across the cell narrower than the cell (refine_pass).
    bool surface_cuts_gaussian(const Vec3 d[4], const double D[4]) const;
    // The budget (BakeSettings::gaussian_refine_budget): counted over the centre samples until
    // close_refine_budget(); once over it every refinement call returns at once.
    bool refine_abandoned() const { return refine_abandoned_.load(); }
    void close_refine_budget() const { refine_counting_.store(false); }
    // Abandons the refinement if the work so far, times _factor_, exceeds the budget.
    void foresee_refine_work(double factor) const {
        if (double(refine_spent_.load()) * factor > double(refine_budget_)) refine_abandoned_.store(true);
    }
    // The factor by which refine_gaussians scales the work it may still do within the budget
    // (the foresight's scale while it runs; 1 after): a frame over the budget stops within one
    // integrand evaluation of knowing it, not one batch of rays.
    void set_refine_scale(double factor) const { refine_scale_.store(factor); }
    double refine_work_seconds() const { return kRefineSecondsPerWork * double(refine_spent_.load()); }
    long long background_rays() const { return background_rays_.load(); }
    // The shadow volumes (null without shadows), and per light of the scene (its point lights,
    // spots and suns in the description's order) its light in them (-1: unshadowed); with
    // soft-shadow samples, the first sample's volume (the surfaces' glow takes its shadow from
    // that point of the sphere or the sun's disk: the one nearest its centre).
    const ShadowVolumes* shadow_volumes() const { return shadows_.get(); }
    // The wall time of getting the shadow volumes (built or shared) in the constructor.
    double seconds_shadow_volumes() const { return seconds_shadow_volumes_; }
    const std::vector<int>& scene_point_volumes() const { return scene_point_volume_; }
    const std::vector<int>& scene_spot_volumes() const { return scene_spot_volume_; }
    const std::vector<int>& scene_sun_volumes() const { return scene_sun_volume_; }
    // The cut of the seen casters' caps the camera's rays leave out (ShadowVolumes::lit_intervals;
    // the default where there is none): any ray that ends at its first hit with the camera's
    // geometry may leave them out too.
    const CapCut& cap_cut() const { return cap_cut_; }

    // The per-light passes of the scene (SceneDescription::light_passes; 0: none).
    int light_passes() const { return n_passes_; }

    // Hot path (soa() only): _n_ rays from the shared origin with unit directions (dx,
    // dy, dz)[k] (structure of arrays, so the per-light dot products and accumulations
    // vectorise), segment [t0[k], Dvp[k]] (t0 null: 0). Writes Tr[k] = exp(-sigma_t (Dvp -
    // t0)) and the airlight summed over the lights to rgb[3 k .. 3 k + 2].
    // _film_ (optional): the rays' film positions (pixels, CameraRays' convention), which let
    // the volumetric shadows rasterize the volumes' crossings (screen_crossings.h) instead of
    // tracing them.
    // _passes_ (optional, light_passes() > 0): each pass's airlight, ray-major: pass g of ray k
    // at passes[3 (k G + g) .. + 2] for G passes; the lights' own terms of the same evaluation.
    void eval_soa(const double* dx, const double* dy, const double* dz, const float* Dvp, const float* t0, int n,
                  float* Tr, float* rgb, const glm::dvec2* film = nullptr, float* passes = nullptr) const;

    // The same for _n_ rays at once, light by light: the iterations of the inner loop
    // are independent, so the CPU overlaps the long dependency chains of the model.
    // _t0_ (near distances, may be null): the fog of the segment [t0, Dvp] with
    // attenuation from the near point, as Cycles integrates it. soa() folds t0 into the
    // table evaluation; the other models move the viewer to the near point o + t0 d (same
    // direction, so the same phase angles along the ray; Dsv and gamma from there), one
    // evaluation per ray and light with no difference to cancel.
    // _film_ as for eval_soa; _passes_ (optional) the per-light passes, ray-major (pass g of
    // ray k at passes[k G + g]).
    void eval_many(const Ray* rays, const float* Dvp, const float* t0, int n, double* Tr, RGB* La,
                   const glm::dvec2* film = nullptr, RGB* passes = nullptr) const;

    // Airlight of all sun lamps along o + t d over [t_near, Dvp] (inf: none): sigma_s p E G
    // with the closed form G of sunlight_layer.h (its quadrature for the quadrature model). The
    // phase angle is the same all along the ray.
    // _passes_ (optional): each sun's term is added to its pass there too (spot_airlight and
    // light_size_airlight the same).
    RGB sun_airlight(const Vec3& o, const Vec3& d, double t_near, double Dvp, const LitIntervals* lit = nullptr,
                     RGB* passes = nullptr) const;

    // Airlight of all spot lights along the ray o + t d over [t_near, Dvp] (Dvp from o; inf:
    // none), attenuated from the near point (the viewer moved there, as eval_many does for
    // the other models). Pegoraro 2010 closed form with the medium's phase (pegoraro10.h), or
    // quadrature (spot_light.h): model 'quadrature', and phases above order 8 unless 'pegoraro10'.
    RGB spot_airlight(const Vec3& o, const Vec3& d, double t_near, double Dvp, const LitIntervals* lit = nullptr,
                      RGB* passes = nullptr) const;

    // The lights' Radius (homogeneous/sphere_light.h), homogeneous fog: what the point and spot
    // lights' disks change in their airlight along o + t d over [t_near, Dvp] (inf: none),
    // attenuated from t_near; within kSphereReach radii of each light, over its lit spans
    // with shadows. eval_soa and eval_many add it (and clip the sum at 0, pass by pass).
    RGB light_size_airlight(const Vec3& o, const Vec3& d, double t_near, double Dvp, const LitIntervals* lit,
                            RGB* passes = nullptr) const;
    bool has_light_size() const { return has_light_size_; }

  private:
    // A light scatters if albedo * I0 is nonzero, or (Gaussian fog with its own colours) if
    // I0 is: a black background medium can carry coloured fog objects.
    static bool keeps_light(const SceneDescription& scene, const PointLight& light);

    // Gaussian fog: Tr = exp(-(sigma_t (t1 - t0) + sum_i T_i)) with the culled optical depth,
    // La = sum_l I0_l [albedo L_0,l + sum_i albedo_i L_i,l] (Fogshop) over the same segment
    // [t0, t1], attenuated from the near point o + t0 d: exp(T(eye, near point)) (La_eye(t1) -
    // La_eye(t0)), exact for the integral (the eye-side attenuation of every point beyond t0
    // carries the factor exp(-T(eye, near point))). Perspective cameras: the centre samples
    // come from the tiled splat and the rays here (edge samples) from its per-ray twin, both
    // float (gaussian/splat.h). Orthographic rays (own origins) set the exact double Fogshop up per
    // ray; the quadrature model integrates from the near point directly.
    void eval_gaussians(const Ray* rays, const float* Dvp, const float* t0, int n, double* Tr, RGB* La) const;

    double airlight(double Dsv, double cos_gamma, double Dvp) const { return model_.point_airlight(Dsv, cos_gamma, Dvp); }

    // Volumetric shadows: the shadow volumes of the lights that cast shadows, and per point
    // light (lights_' order), spot and sun its light in them (-1: unshadowed).
    void set_up_shadows(const SceneDescription& scene, const BakeSettings& settings);
    void set_up_refinement(const BakeSettings& settings, const Camera& camera);
    // A marched light (gaussian/march.h): a point, spot or sun light whose whole airlight (every
    // Gaussian and the uniform fog) is marched on the refined rays in place of its pairs' exact
    // terms (its index in gaussian_lights_, then the suns), with its light-depth map (null:
    // exact light depths; plan_marches says when).
    struct MarchedLight {
        size_t light = 0;
        CachedMap map;  // its light-depth map (map for points and spots, sun_map for suns), and its key
        std::size_t bytes() const { return map.bytes(); }
    };
    // Takes the lights with pairs to refine out of _plan_ into marched_, with their maps.
    void plan_marches(GaussianRefinePlan& plan, int threads);
    // The march of _marched_'s light (per unit I0 or E) along o + t d over [0, len], with its map
    // (_mapped_) or exact light depths, at the refinement's accuracy; _march_ takes the albedos.
    RGB march_light(const MarchedLight& marched, bool mapped, const Vec3& o, const Vec3& d, double len,
                    GaussianMarch& march) const;
    // The largest relative error of the march's airlight with _marched_'s map against exact
    // light depths on a few rays from the eye through the Gaussians (those a spot's cone lights)
    // and on the frame's rays (view_map_error);
    // _exact_: the exact marches of those rays, computed on the first call (empty) and kept. The
    // rays on _threads_ threads (0: all).
    double march_map_error(const MarchedLight& marched, std::vector<double>& exact, int threads) const;
    // The largest relative error of a point or spot light's airlight with its map's light
    // depths against exact ones on the frame's rays (views_), each summed over the same nodes.
    double view_map_error(const MarchedLight& marched, int threads) const;
    // The distances a marched light's map holds over _extent_ (its farthest from the light, or
    // a sun's depth across the cloud), given the width _width_ of its narrow Gaussians.
    int map_radial(double extent, double width, int most) const;
    // refine_gaussians' uniform-fog part for one ray d over [near, end] (Tg_near: the
    // Gaussians' depth before near; lit: its lit intervals, null when untraced: lit all along),
    // _view_ gathered on demand.
    void refine_background(const Vec3& d, double near, double end, double Tg_near, const LitIntervals* lit,
                           GaussianRefiner::ViewDepth& view, RGB& La) const;
    // refine_gaussians' rays (FogEvaluator::refine_gaussians keeps the budget around it).
    void refine_rays(const Ray* rays, const float* Dvp, const float* t0, int n, RGB* La) const;
    // The marched lights' share of refine_rays on ray d over [near, end] (lit: its lit
    // intervals, null when untraced): each one's march less its Fogshop value, added to La.
    void march_lights(const Vec3& d, double near, double end, const LitIntervals* lit, RGB& La) const;
    // Fogshop's airlight on ray d from the near plane _near_ (eye_fogshop_, or _local_ set up at
    // the near point: t_start 0) over spans[l] of every light l (gaussian_lights_, then the
    // suns; an empty span list leaves a light out), with the splat's background, phase and
    // spot profiles: the values the splat's pixels hold (_fast_: in float, as the splat has them).
    RGB fogshop_spans(const FogshopAirlight& fogshop, bool at_eye, const Vec3& d, double near, const RaySpans* spans,
                      bool fast = false) const;
    // Volume of the Fogshop light l (gaussian_lights_, then the suns) in shadows_; -1: none.
    int gaussian_volume(size_t l) const;
    // Light l's emission profile towards u (1 but for spots), for FogshopAirlight's terms.
    double gaussian_profile(size_t l, const Vec3& u) const;
    // The lit intervals of _n_ rays within [t0, t1] (t0 null: 0), in a buffer of the calling
    // thread: rasterized where the rays' film positions are given and the volumes were binned
    // (screen_), else traced.
    const LitIntervals* lit_intervals(const Ray* rays, const float* t0, const float* t1, int n,
                                      const uint32_t* masks = nullptr, const glm::dvec2* film = nullptr) const;
    // Per ray, the shadowed lights that matter there (light_mask bits): _values_ holds each
    // point light's unshadowed airlight per unit weight, light-major (m per light).
    const uint32_t* shadow_masks(const float* values, int m) const;
    // A point light's airlight over the lit spans of light _v_ along o + t d, each span
    // attenuated from _t_start_ (the fog's start); the reference model integrates the
    // visibility itself over [t_start, t_end] (shadowed_quadrature.h).
    double point_airlight_lit(const LightData& light, int v, const Vec3& o, const Vec3& d, double t_start, double t_end,
                              const LitIntervals& lit) const;
    // eval_soa's shadows: _value_ (the batch's airlight of _light_ for _m_ rays from origin_)
    // recomputed over the lit spans of light _v_ where a ray is not lit all along.
    void relight_spans(const LightData& light, int v, const double* cos_gamma, const float* near, const float* Dvp,
                       int m, const LitIntervals* lit, float* value) const;
    // relight_spans averaged over the light's _n_ shadow samples, volumes v .. v + n - 1.
    void relight_samples(const LightData& light, int v, int n, const double* cos_gamma, const float* near,
                         const float* Dvp, int m, const LitIntervals* lit, float* value) const;

    // The visibility of light _v_ (for the reference model).
    bool visible(int v, const Vec3& p) const { return shadows_->lit_at(v, p); }
    // The ends of light _v_'s lit spans as distances from _t_start_ (the reference's breakpoints).
    static std::vector<double> span_ends(const LitIntervals& lit, int v, double t_start);

    const FogModel& model_;
    double sigma_t_;
    PhaseFunction phase_;
    bool isotropic_;
    bool shared_origin_;
    std::vector<ViewRay> views_;
    Vec3 origin_;
    PegoraroPhase pegoraro_phase_;  // spots (all models but quadrature) and model pegoraro10
    bool spot_closed_form_ = false;  // spots by pegoraro10_spot_airlight (else quadrature)
    std::vector<LightData> lights_;
    struct SpotData {
        SpotCone cone;
        Vec3 s;
        RGB weight;  // albedo * I0
        double radius = 0.0;
        std::shared_ptr<const SphereFalloff> falloff;
        int pass = -1;
    };
    // One spot's airlight along from + t d over [0, len], attenuated from _from_, per unit weight.
    double spot_segment(const SpotData& spot, const Vec3& from, const Vec3& d, double len) const;
    int n_passes_ = 0;  // SceneDescription::light_passes
    // eval_soa's and eval_many's: adds the light-size terms (light_size_airlight) of the ray
    // o + t d to _La_ and to the ray's passes (null: none), each clipped at 0.
    void add_light_size(const Vec3& o, const Vec3& d, double t_near, double Dvp, const LitIntervals* lit, RGB& La,
                        RGB* passes) const;
    bool has_light_size_ = false;  // a point or spot light with a radius, in homogeneous fog
    double light_size_tol_ = 1e-3;  // BakeSettings::light_size_tolerance
    std::vector<SpotData> spots_;
    struct SunData {
        Vec3 w;       // unit propagation direction
        double mu_s;  // -w.z: the cosine of the sun's path through the layer to the vertical
        RGB weight;   // albedo * sigma_t * E
        int pass = -1;
    };
    std::vector<SunData> suns_;
    double fog_top_ = std::numeric_limits<double>::infinity();
    // Gaussian fog (null without): the medium (beta0 = sigma_t), the lights' positions in
    // lights_' order, and Fogshop set up at the shared viewpoint.
    std::unique_ptr<GaussianMedium> gaussian_;
    // The same windowed with the refinement's march window (plan_marches): its marches gather
    // from it and its depth maps are built over it.
    std::unique_ptr<GaussianMedium> windowed_;
    std::vector<Vec3> gaussian_lights_;
    std::vector<RGB> gaussian_I0_;         // I0 of the lights in lights_' order
    std::vector<double> gaussian_albedo_;  // 3 per Gaussian (the medium's if none given)
    RGB medium_albedo_{1.0};
    size_t n_gaussian_points_ = 0;  // point lights at the front of gaussian_lights_ (spots follow)
    struct GaussianSpotData {
        SpotCone cone;
        Vec3 s;
        RGB I0;
    };
    struct GaussianSunData {
        Vec3 w;       // unit propagation direction
        double mu_s;  // -w.z
        RGB E;
    };
    std::vector<GaussianSpotData> gaussian_spots_;
    std::vector<GaussianSunData> gaussian_suns_;
    std::unique_ptr<GaussianSplat> splat_;
    std::shared_ptr<const ShadowVolumes> shadows_;  // (ShadowVolumes::shared)
    double seconds_shadow_volumes_ = 0.0;
    // The volumes' faces binned on the film, for rays from the shared origin whose film
    // positions are known (null: other cameras, or too many faces).
    std::unique_ptr<ScreenCrossings> screen_;
    // Gaussian fog with shadows (Fogshop, perspective): Fogshop at the eye for the point lights.
    std::unique_ptr<FogshopAirlight> eye_fogshop_;
    std::unique_ptr<GaussianRefiner> refiner_;
    std::vector<MarchedLight> marched_;
    // Every light of the Gaussian fog is marched: a refined ray's airlight is the marches' sum
    // (what the splat put in its pixel is every light's Fogshop value, which they replace).
    bool all_marched_ = false;
    mutable std::atomic<long long> marched_rays_{0};
    size_t refine_pairs_ = 0;         // the refinement plan's pairs (refiner_ may be null)
    double refine_kept_bound_ = 0.0;  // and the largest bound it left to Fogshop
    double refine_target_ = 0.0;       // the asked relative accuracy (gaussian_accuracy)
    double pixel_angle_ = 0.0;         // a pixel's angle at the image centre (radians)
    double gaussians_end_ = std::numeric_limits<double>::infinity();  // gaussians_end()
    double refine_error_bound_ = 0.0;
    mutable std::atomic<long long> background_rays_{0};
    // The accuracy's shares (set_up_refinement): the plan keeps the pairs whose bound is below
    // kPlanShare of it (with beta0 = 0 also the uniform fog's share) and marches the lights of the
    // others, whose light-depth maps err by at most kMarchedShare (plan_marches); the uniform
    // fog's term of the lights not marched takes kBackgroundShare (refine_background).
    static constexpr double kPlanShare = 0.25, kMarchedShare = 0.25, kBackgroundShare = 0.5;
    // Nominal CPU seconds per unit of refine_work (one Gaussian's term in an integrand, with
    // its share of the quadrature's overhead): 5.5e-8 s measured on this machine's cores
    // (benchmarks/bench_gaussian_accuracy.py, 3000 Gaussians).
    static constexpr double kRefineSecondsPerWork = 5.5e-8;
    // The marched lights' light-depth maps (plan_marches): 32 to 256 grid points a face's
    // side (kMarchMapMaxFace), as the measured error asks, 64 to 256 distances (map_radial), at
    // most kMarchMapMaxBytes for all the lights together (a sun's map is a sixth of a point's a
    // face: its largest, 512 a side, 256 MB). Below 1 % a point's or spot's map takes 512
    // distances: on the refine tests' ground scene at 0.1 % (need 0.00025) 256 erred
    // 0.00029-0.00030 on the frame's rays at 152 and at 184 a face (the distances' linear
    // reads), 512 0.00006. The march's units of work (GaussianMarch::work, ~4 ns with the float
    // kernels) per refine_work unit (5.5e-8 s).
    static constexpr int kMarchMapMinRadial = 64, kMarchMapMaxRadial = 512, kSunMapMaxRadial = 256;
    static constexpr int kMarchMapMaxFace = 256, kSunMapMaxFace = 512;
    // A map's distances at most this many of its narrow Gaussians' widths apart at 1 %
    // (map_radial; after a map that erred too much, the most).
    static constexpr double kMapRadialWidths = 0.35;
    // The largest fall of a map's measured error per doubling of its face (plan_marches), the
    // first face at 1 % (scaled to the target; a sun's, whose reads are bilinear, larger), the
    // least, and the margin on a predicted one.
    static constexpr double kMapFallBound = 10.0;
    static constexpr int kMapFace1 = 48, kSunMapFace1 = 64, kMapMinFace = 32;
    static constexpr double kMapFaceMargin = 1.1;
    static constexpr std::size_t kMarchMapMaxBytes = std::size_t(1) << 30;
    static constexpr long kMarchWorkPerUnit = 12;
    std::uint64_t refine_budget_ = 0;
    mutable std::atomic<std::uint64_t> refine_spent_{0};
    mutable std::atomic<bool> refine_abandoned_{false}, refine_counting_{true};
    mutable std::atomic<double> refine_scale_{1.0};
    // (Set between the refine pass and the edge pass, read-only after: keep_refined_frame.)
    mutable std::unique_ptr<const RefinedFrame> refined_frame_;
    bool frame_ratio(const Vec3& d, double Dvp, const RGB& fogshop, RGB& ratio) const;
    std::vector<int> light_volume_, spot_volume_, sun_volume_;
    // Per point light, spot and sun its shadow samples (BakeSettings::shadow_samples): volumes
    // light_volume_[l] .. + light_samples_[l] - 1 (1: its centre's alone).
    std::vector<int> light_samples_, spot_samples_, sun_samples_;
    // The mean of f(volume) over the _n_ shadow samples of a light from volume _v_ (f(v) for one).
    template <class F>
    static double sample_mean(int v, int n, F f) {
        if (n <= 1) return f(v);
        double sum = 0.0;
        for (int j = 0; j < n; ++j) sum += f(v + j);
        return sum / n;
    }
    // The mask bits of those volumes.
    static uint32_t sample_mask(int v, int n) {
        uint32_t mask = 0;
        for (int j = 0; j < n; ++j) mask |= ShadowVolumes::light_mask(v + j);
        return mask;
    }
    std::vector<int> scene_point_volume_, scene_spot_volume_, scene_sun_volume_;
    std::vector<int> origin_count_;  // per light of shadows_: its count at origin_
    bool origin_ambiguous_ = false;  // origin_ on a frustum boundary: rays count at their start
    // The casters' caps the camera's rays can cross (ShadowVolumes::lit_intervals): of the
    // casters the camera sees, those within the cut's reach of the eye or reaching past its
    // beyond; of the others, all (the default cut: no caster is seen).
    CapCut cap_cut_;
    std::vector<double> light_peak_;  // per point light: its largest channel of albedo x I0
};

}  // namespace airlight
