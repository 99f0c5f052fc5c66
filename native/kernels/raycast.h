// raycast.h: first-hit distances against the scene's triangles (Embree 3).
#pragma once

#include <memory>

#include "camera.h"

namespace airlight {

class RayCaster {
  public:
    explicit RayCaster(const TriangleMesh& mesh);
    ~RayCaster();
    RayCaster(const RayCaster&) = delete;
    RayCaster& operator=(const RayCaster&) = delete;

    // Distance along the ray to the first hit, +inf if none. Thread safe.
    double first_hit(const Ray& ray) const;

    // First-hit distances of _n_ rays at once (Embree packets of 8, coherent), written
    // to _t_ (+inf where none). Faster than _first_hit_ for camera rays. Thread safe.
    void first_hits(const Ray* rays, int n, float* t) const;

  private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

}  // namespace airlight
