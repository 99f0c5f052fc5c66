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

}  // namespace airlight
