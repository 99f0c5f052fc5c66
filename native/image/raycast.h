// raycast.h: first-hit distances against the scene's triangles (Embree 3).
#pragma once

#include <memory>

#include "image/camera.h"

namespace airlight {

class BlockedScene;

class RayCaster {
  public:
    explicit RayCaster(const TriangleMesh& mesh);
    ~RayCaster();

    // The caster of _mesh_, shared with the previous call when that call's mesh was the same
    // (vertices and triangles compared exactly): Embree's BVH of a static scene is built once
    // for the bakes of one process (per-light passes, lens and shutter samples, an
    // animation's frames; 2e6 triangles: ~0.6 s a build). A mesh that differs from the last
    // one in some of its objects (the soup's blocks: image/embree_blocks.h) builds the BVHs of
    // those only, and the instances over all of them. One mesh's blocks are kept until another
    // comes or clear_shared(). Thread safe. Rays refused on a shared caster count on it for all
    // its users: compare invalid_rays() before and after.
    static std::shared_ptr<const RayCaster> shared(const TriangleMesh& mesh);
    // Drops the kept mesh and its BVH (their memory returns once no bake holds them).
    static void clear_shared();
    // Builds of shared() so far (those it did not share), for tests and the stats.
    static long shared_builds();
    // The blocks (objects' BVHs) those builds built, the others shared.
    static long shared_blocks_built();
    RayCaster(const RayCaster&) = delete;
    RayCaster& operator=(const RayCaster&) = delete;

    // Distance along the ray to the first hit, +inf if none. Thread safe.
    double first_hit(const Ray& ray) const;

    // First-hit distances of _n_ rays at once (Embree packets of 8, coherent), written
    // to _t_ (+inf where none). Faster than _first_hit_ for camera rays. Thread safe.
    void first_hits(const Ray* rays, int n, float* t) const;

    // First hits of _n_ rays from one origin _o_ along directions (dx, dy, dz)[k] (any
    // length), inside [t_near[k], t_far[k]] in units of the direction (Cycles' clip
    // range), written to _t_ (+inf where none). Packets of 16 coherent rays. Thread safe.
    void first_hits(const Vec3& o, const float* dx, const float* dy, const float* dz, const float* t_near,
                    const float* t_far, int n, float* t) const;

    // First hits of _n_ rays with their own origins inside [t_near[k], t_far[k]] (units
    // of the unit directions), with the unit geometric normal (Embree's Ng, the triangle's
    // winding normal, not interpolated) of each hit in _ng_[3 k .. 3 k + 2] (0 where none).
    // Packets of 16. Thread safe. Used by the surface-shading pass (bake/surface_pass.cpp).
    void first_hits_normals(const Ray* rays, const float* t_near, const float* t_far, int n, float* t,
                            float* ng) const;

    // Rays refused so far because Embree would assert on them (a NaN or huge origin or
    // direction, tnear < 0 or tnear > tfar): they are not traced and read back as NaN.
    // Callers check this after a pass and refuse the bake (bake.cpp).
    long invalid_rays() const;

  private:
    explicit RayCaster(std::shared_ptr<const BlockedScene> scene);
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

}  // namespace airlight
