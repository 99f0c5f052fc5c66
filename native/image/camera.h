// camera.h: primary rays through the render's pixel grid, matching Blender's.
#pragma once

#include <limits>

#include "core/scene.h"

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
    // Throws std::invalid_argument if the matrices are not finite or not invertible, or the
    // rays they give are not finite and ahead of the camera.
    explicit CameraRays(const Camera& cam);
    Ray operator()(double px, double py) const {
        if (!affine_) return unproject(px, py);
        Ray ray;
        ray.o = ortho_ ? n0_ + px * ndx_ + py * ndy_ : position_;
        ray.d = glm::normalize(D0_ + px * Dx_ + py * Dy_);
        return ray;
    }
    bool orthographic() const { return ortho_; }
    // The part of _ray_ (from this class) that Cycles renders: [t_near, t_far] along it,
    // from the view-axis depths clip_start and clip_end (t = depth / cos of the angle to
    // the view axis for perspective rays, measured from the ray origin; orthographic rays
    // already start on the projection's near plane). t_near >= 0; t_far may be inf.
    void clip_range(const Ray& ray, double& t_near, double& t_far) const {
        const double cos_view = glm::dot(ray.d, forward_);
        const double z0 = ortho_ ? glm::dot(ray.o - position_, forward_) : 0.0;
        t_near = clip_start_ > z0 ? (clip_start_ - z0) / cos_view : 0.0;
        t_far = (clip_end_ - z0) / cos_view;
    }
    bool clipped() const { return clip_start_ > 0.0 || clip_end_ < std::numeric_limits<double>::infinity(); }
    // Camera position in world space (the ray origin of every perspective ray).
    Vec3 position() const { return position_; }
    // Unit view axis (camera -Z) and the clip range as view-axis depths.
    Vec3 forward() const { return forward_; }
    double clip_start() const { return clip_start_; }
    double clip_end() const { return clip_end_; }
    // Perspective rays with an affine unnormalised direction D(px, py) = D0 + px Dx + py
    // Dy (Blender's matrices): _operator()_ returns (position(), normalize(D)). Lets a
    // caller generate a row of rays incrementally. False for orthographic or projective.
    bool affine_perspective() const { return affine_ && !ortho_; }
    void affine_direction(Vec3& D0, Vec3& Dx, Vec3& Dy) const {
        D0 = D0_;
        Dx = Dx_;
        Dy = Dy_;
    }

  private:
    Ray unproject(double px, double py) const;  // the general (projective) case
    void affine_from_xy_rows(const Camera& cam);  // Blender's perspective and orthographic forms
    void check_rays(const Camera& cam) const;     // throws std::invalid_argument

    glm::dmat4 raster_to_world_;  // clip space -> world, homogeneous
    // When w of the unprojected near/far points does not depend on the film position
    // (always so for Blender's matrices), rays are affine in (px, py): near point
    // n0 + px ndx + py ndy, unnormalised direction D0 + px Dx + py Dy.
    bool affine_ = false;
    Vec3 n0_, ndx_, ndy_, D0_, Dx_, Dy_;
    Vec3 position_;
    Vec3 forward_;  // unit view axis (camera -Z)
    double clip_start_ = 0.0, clip_end_ = std::numeric_limits<double>::infinity();
    double inv_w_ = 0.0, inv_h_ = 0.0;
    bool ortho_ = false;
};

}  // namespace airlight
