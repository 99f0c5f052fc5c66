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

  private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

}  // namespace airlight
