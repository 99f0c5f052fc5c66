// context.h: what every pass of a bake shares: the camera's rays, the ray caster, the
// image size, threads and progress, the output images, and the pixel-row helpers.
#pragma once

#include <chrono>
#include <functional>
#include <limits>
#include <memory>
#include <vector>

#include "bake/bake.h"
#include "image/camera.h"
#include "image/raycast.h"

namespace airlight {

// Rows per work item of the passes that go over the image in bands.
constexpr int kBandRows = 16;
// Share of the progress bar given to pass 1 (ray casting).
constexpr double kRaycastProgressShare = 0.3;

using Clock = std::chrono::steady_clock;
inline double seconds_since(Clock::time_point start) {
    return std::chrono::duration<double>(Clock::now() - start).count();
}

// Unit directions of a row's centre rays (double for the fog's cos(gamma), float for
// Embree), cos of the angle to the view axis and the clip range along each ray.
struct RowRays {
    std::vector<double> dx, dy, dz;
    std::vector<float> fx, fy, fz, t_near, t_far;
    std::vector<float> len;  // pass 1: |D| over its view-axis component
    void resize(size_t n) {
        for (auto* v : {&dx, &dy, &dz}) v->resize(n);
        for (auto* v : {&fx, &fy, &fz, &len, &t_near, &t_far}) v->resize(n);
    }
};

// Scratch of BakeContext::cast, reused between calls.
struct CastScratch {
    RowRays soa;
    std::vector<Ray> moved;
};

class BakeContext {
  public:
    // Sets up the camera's rays (refuses a camera that cannot be baked), the ray caster over
    // the scene's geometry (Embree's BVH) and the output images.
    BakeContext(const SceneDescription& scene, const BakeSettings& settings, const ProgressFn& progress,
                BakeResult& result);

    const SceneDescription& scene;
    const BakeSettings& settings;
    const ProgressFn& progress;
    const CameraRays rays;
    const int W, H;
    const size_t n_pixels;
    const int n_threads, n_bands;
    BakeResult& result;
    // The ray caster over the scene's geometry, shared with earlier bakes of the same mesh
    // (RayCaster::shared), and its refused rays before this bake.
    const std::shared_ptr<const RayCaster> shared_caster;
    const RayCaster& caster;
    const long invalid_before;
    const Vec3 forward;  // unit view axis
    const bool ortho, clipped;
    const Vec3 eye;      // camera position
    // Perspective cameras with Blender's matrices (affine rays) generate each row's
    // directions incrementally, D0 + px Dx + py Dy, normalised once, as arrays.
    const bool affine;
    Vec3 D0{0.0}, Dx{0.0}, Dy{0.0};
    const double clip_start, clip_end;
    const bool near_clip;  // the fog starts at a near plane (clip_start > 0)
    // Per pixel, a key that is affine in pixel coordinates on any plane (1 / view-axis depth
    // for perspective, the distance itself for orthographic rays; 0 where the ray misses),
    // so the edge test sees silhouettes and creases but not the slope of an oblique plane.
    // Kept per calling thread between bakes; written by pass 1 before it is read.
    std::vector<float>& key;

    // Reports the progress of one pass over _n_bands_ items, mapped to [begin, end] of the
    // whole bake; throws Cancelled when the callback asks to stop.
    std::function<void(int)> reporter(double begin, double end) const;
    // Row _j_'s centre rays: pass 1 wants float directions scaled to unit view-axis depth
    // (row_directions_cast), pass 2 unit directions in double and t_near
    // (row_directions_fog): _for_cast_ selects. Affine cameras only.
    void row_rays(int j, RowRays& r, bool for_cast) const;
    // Pass 2's rays (row_rays) of the _n_ pixels _xs_ of row _j_ alone, the k-th at index k.
    void pixel_rays(int j, const int* xs, int n, RowRays& r) const;
    // First hits of _n_ camera rays inside the clip range, as Cycles sees them: nearer
    // surfaces clipped away, surfaces beyond t_far hidden (inf). _depth_ is measured from
    // the ray origin (the eye for perspective rays). Perspective rays share the origin and
    // go to Embree with [t_near, t_far]; orthographic ones are cast from the near plane.
    // _t0_ (size n) receives t_near.
    void cast(const Ray* r, int n, float* depth, float* t0, CastScratch& scratch) const;
    // Refuses the bake if the caster was handed rays Embree cannot take (CameraRays checks
    // the camera's; this catches any other pass's): they were not traced.
    void check_traced() const;
};

}  // namespace airlight
