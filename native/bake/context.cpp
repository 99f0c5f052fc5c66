// context.cpp: see context.h.
#include "bake/context.h"

#include <cmath>
#include <stdexcept>
#include <string>

#include "core/parallel.h"
#include "core/target_clones.h"

namespace airlight {

namespace {

// Directions of the _n_ rays D = Dj + (i + 0.5) Dx for Embree, scaled to unit length
// along the view axis _forward_ (D / (D . forward)): the ray parameter t is then the
// view-axis depth, so the clip range is [clip_start, clip_end] for every ray and the
// edge key 1 / depth is 1 / t; _len_ = |D / (D . forward)| = 1 / cos_view converts t
// to distance. Float, no square root in double, one division.
AIRLIGHT_ROW_CLONES
void row_directions_cast(const Vec3& Dj, const Vec3& Dx, const Vec3& forward, int n, float* __restrict fx,
                         float* __restrict fy, float* __restrict fz, float* __restrict len) {
    // All float (Embree's precision; GCC vectorises loops of one element width best).
    const float jx = float(Dj.x), jy = float(Dj.y), jz = float(Dj.z);
    const float ix = float(Dx.x), iy = float(Dx.y), iz = float(Dx.z);
    const float vx = float(forward.x), vy = float(forward.y), vz = float(forward.z);
    for (int i = 0; i < n; ++i) {
        const float px = float(i) + 0.5f;
        const float X = jx + px * ix, Y = jy + px * iy, Z = jz + px * iz;
        const float rc = 1.0f / (X * vx + Y * vy + Z * vz);
        const float x = X * rc, y = Y * rc, z = Z * rc;
        fx[i] = x;
        fy[i] = y;
        fz[i] = z;
        len[i] = std::sqrt(x * x + y * y + z * z);
    }
}

// The same rays' unit directions in double (the fog's cos(gamma) near a light needs it)
// and, in float, the near-plane distance t_near = near |D| / (D . forward).
AIRLIGHT_ROW_CLONES
void row_directions_fog(const Vec3& Dj, const Vec3& Dx, const Vec3& forward, float near, int n,
                        double* __restrict dx, double* __restrict dy, double* __restrict dz,
                        float* __restrict t_near) {
    for (int i = 0; i < n; ++i) {
        const double px = i + 0.5;
        const double X = Dj.x + px * Dx.x, Y = Dj.y + px * Dx.y, Z = Dj.z + px * Dx.z;
        const double inv = 1.0 / std::sqrt(X * X + Y * Y + Z * Z);
        dx[i] = X * inv;
        dy[i] = Y * inv;
        dz[i] = Z * inv;
    }
    if (near == 0.0f) {
        for (int i = 0; i < n; ++i) t_near[i] = 0.0f;
        return;
    }
    const float jx = float(Dj.x), jy = float(Dj.y), jz = float(Dj.z);
    const float ix = float(Dx.x), iy = float(Dx.y), iz = float(Dx.z);
    const float vx = float(forward.x), vy = float(forward.y), vz = float(forward.z);
    for (int i = 0; i < n; ++i) {
        const float px = float(i) + 0.5f;
        const float X = jx + px * ix, Y = jy + px * iy, Z = jz + px * iz;
        t_near[i] = near * (std::sqrt(X * X + Y * Y + Z * Z) / (X * vx + Y * vy + Z * vz));
    }
}

std::vector<float>& key_image(size_t n) {
    thread_local std::vector<float> key_cache;
    if (key_cache.size() != n) allocate_image(key_cache, n);
    return key_cache;
}

BakeResult& allocated(BakeResult& result, int W, int H, int light_passes) {
    const size_t n_pixels = size_t(W) * size_t(H);
    result.width = W;
    result.height = H;
    allocate_image(result.depth, n_pixels);
    allocate_image(result.airlight, 3 * n_pixels);
    allocate_image(result.transmittance, 3 * n_pixels);
    if (light_passes > 0) allocate_image(result.light_airlight, 3 * n_pixels * size_t(light_passes));
    return result;
}

}  // namespace

BakeContext::BakeContext(const SceneDescription& scene_, const BakeSettings& settings_, const ProgressFn& progress_,
                         BakeResult& result_)
    : scene(scene_),
      settings(settings_),
      progress(progress_),
      rays(scene_.camera),
      W(scene_.camera.width),
      H(scene_.camera.height),
      n_pixels(size_t(W) * size_t(H)),
      n_threads(resolve_threads(settings_.threads)),
      n_bands((H + kBandRows - 1) / kBandRows),
      result(allocated(result_, W, H, scene_.light_passes)),
      shared_caster(RayCaster::shared(scene_.geometry)),
      caster(*shared_caster),
      invalid_before(caster.invalid_rays()),
      forward(rays.forward()),
      ortho(rays.orthographic()),
      clipped(rays.clipped()),
      eye(rays.position()),
      affine(rays.affine_perspective()),
      clip_start(rays.clip_start()),
      clip_end(rays.clip_end()),
      near_clip(rays.clipped() && rays.clip_start() > 0.0),
      key(key_image(n_pixels)) {
    if (affine) rays.affine_direction(D0, Dx, Dy);
}

std::function<void(int)> BakeContext::reporter(double begin, double end) const {
    return [this, begin, end](int done) {
        if (!progress) return;
        double fraction = done == n_bands ? end : begin + (end - begin) * done / n_bands;
        if (!progress(fraction)) throw Cancelled();
    };
}

void BakeContext::row_rays(int j, RowRays& r, bool for_cast) const {
    const Vec3 Dj = D0 + (j + 0.5) * Dy;
    if (for_cast)
        row_directions_cast(Dj, Dx, forward, W, r.fx.data(), r.fy.data(), r.fz.data(), r.len.data());
    else
        row_directions_fog(Dj, Dx, forward, float(clip_start), W, r.dx.data(), r.dy.data(), r.dz.data(),
                           r.t_near.data());
}

void BakeContext::pixel_rays(int j, const int* xs, int n, RowRays& r) const {
    const Vec3 Dj = D0 + (j + 0.5) * Dy;
    for (int k = 0; k < n; ++k)
        row_directions_fog(Dj + double(xs[k]) * Dx, Dx, forward, float(clip_start), 1, &r.dx[k], &r.dy[k], &r.dz[k],
                           &r.t_near[k]);
}

void BakeContext::cast(const Ray* r, int n, float* depth, float* t0, CastScratch& scratch) const {
    if (!ortho) {
        RowRays& s = scratch.soa;
        if (s.fx.size() < size_t(n)) s.resize(size_t(n));
        for (int k = 0; k < n; ++k) {
            double t_near = 0.0, t_far = std::numeric_limits<double>::infinity();
            if (clipped) rays.clip_range(r[k], t_near, t_far);
            s.fx[k] = float(r[k].d.x);
            s.fy[k] = float(r[k].d.y);
            s.fz[k] = float(r[k].d.z);
            s.t_near[k] = t0[k] = float(t_near);
            s.t_far[k] = float(t_far);
        }
        caster.first_hits(eye, s.fx.data(), s.fy.data(), s.fz.data(), s.t_near.data(), s.t_far.data(), n, depth);
        return;
    }
    if (!clipped) {
        for (int k = 0; k < n; ++k) t0[k] = 0.0f;
        caster.first_hits(r, n, depth);
        return;
    }
    std::vector<Ray>& moved = scratch.moved;
    moved.resize(size_t(n));
    std::vector<double> t_near(static_cast<size_t>(n)), t_far(static_cast<size_t>(n));
    for (int k = 0; k < n; ++k) {
        rays.clip_range(r[k], t_near[k], t_far[k]);
        moved[k] = {r[k].o + t_near[k] * r[k].d, r[k].d};
        t0[k] = float(t_near[k]);
    }
    caster.first_hits(moved.data(), n, depth);
    for (int k = 0; k < n; ++k)
        depth[k] = double(depth[k]) <= t_far[k] - t_near[k]
                       ? float(t_near[k] + double(depth[k]))
                       : std::numeric_limits<float>::infinity();
}

void BakeContext::check_traced() const {
    if (const long n = caster.invalid_rays() - invalid_before)
        throw std::invalid_argument("the camera cannot be baked: " + std::to_string(n) +
                                    " of its rays are not finite (check the camera's lens, sensor, shift and "
                                    "clip range, and the scene's scale)");
}

}  // namespace airlight
