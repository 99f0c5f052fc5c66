// camera.h: primary rays through the render's pixel grid, matching Blender's.
#pragma once

#include "scene.h"

namespace airlight {

struct Ray {
    Vec3 o;  // origin
    Vec3 d;  // unit direction
};

// Ray through film position (px, py) in pixels, measured from the top-left corner of
// the image (row 0 is the top row, as in the EXR), so pixel (i, j)'s centre is
// (i + 0.5, j + 0.5). Works for perspective and orthographic projections.
Ray camera_ray(const Camera& cam, double px, double py);

// The same rays with the matrix inverse done once, for generating many rays.
class CameraRays {
  public:
    // Throws std::invalid_argument if the matrices are not finite or not invertible.
    explicit CameraRays(const Camera& cam);
    Ray operator()(double px, double py) const;
    bool orthographic() const { return ortho_; }
    // Camera position in world space (the ray origin of every perspective ray).
    Vec3 position() const { return position_; }

  private:
    glm::dmat4 raster_to_world_;  // clip space -> world, homogeneous
    Vec3 position_;
    double inv_w_ = 0.0, inv_h_ = 0.0;
    bool ortho_ = false;
};

}  // namespace airlight
