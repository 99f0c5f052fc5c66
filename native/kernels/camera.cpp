// camera.cpp: primary rays through Blender's pixel grid by unprojecting clip space.
#include "camera.h"

#include <cmath>
#include <stdexcept>
#include <string>

namespace airlight {

namespace {

bool all_finite(const glm::dmat4& m) {
    for (int c = 0; c < 4; ++c)
        for (int r = 0; r < 4; ++r)
            if (!std::isfinite(m[c][r])) return false;
    return true;
}

// Homogeneous divide of a clip- or world-space point.
Vec3 dehomogenize(const glm::dvec4& p) { return Vec3(p) / p.w; }

}  // namespace

CameraRays::CameraRays(const Camera& cam) {
    // Validate _cam_'s matrices; Blender's are always finite and invertible.
    if (!all_finite(cam.cam_to_world) || !all_finite(cam.projection))
        throw std::invalid_argument("camera matrices must be finite");
    double det_p = glm::determinant(cam.projection);
    double det_c = glm::determinant(cam.cam_to_world);
    if (!std::isfinite(det_p) || std::abs(det_p) < 1e-300 || !std::isfinite(det_c) ||
        std::abs(det_c) < 1e-300)
        throw std::invalid_argument("camera matrices must be invertible");
    if (cam.width <= 0 || cam.height <= 0)
        throw std::invalid_argument("camera resolution must be positive");

    // Orthographic projections keep w = 1: bottom row (0, 0, 0, 1). glm is column-major,
    // so element (row 3, column 3) is projection[3][3].
    ortho_ = cam.projection[3][3] == 1.0 && cam.projection[2][3] == 0.0;
    raster_to_world_ = cam.cam_to_world * glm::inverse(cam.projection);
    position_ = Vec3(cam.cam_to_world[3]);
    forward_ = -glm::normalize(Vec3(cam.cam_to_world[2]));
    if (!(cam.clip_start >= 0.0) || std::isinf(cam.clip_start) || !(cam.clip_end > cam.clip_start))
        throw std::invalid_argument("camera clip range must satisfy 0 <= clip_start < clip_end (clip_end may be inf), got " +
                                    std::to_string(cam.clip_start) + ", " + std::to_string(cam.clip_end));
    clip_start_ = cam.clip_start;
    clip_end_ = cam.clip_end;
    inv_w_ = 1.0 / cam.width;
    inv_h_ = 1.0 / cam.height;

    // Precompute the affine form of the rays when w is independent of NDC x and y.
    const glm::dmat4& M = raster_to_world_;
    affine_ = std::abs(M[0][3]) + std::abs(M[1][3]) <= 1e-14 * (std::abs(M[2][3]) + std::abs(M[3][3]));
    if (affine_) {
        const double w_near = M[3][3] - M[2][3], w_far = M[3][3] + M[2][3];
        // NDC x = 2 px / W - 1 and y = 1 - 2 py / H, so d/dpx = 2/W M[0], d/dpy = -2/H M[1].
        const Vec3 cx = Vec3(M[0]) * (2.0 * inv_w_), cy = Vec3(M[1]) * (-2.0 * inv_h_);
        const Vec3 base_near = (Vec3(M[3]) - Vec3(M[2]) - Vec3(M[0]) + Vec3(M[1])) / w_near;
        const Vec3 base_far = (Vec3(M[3]) + Vec3(M[2]) - Vec3(M[0]) + Vec3(M[1])) / w_far;
        n0_ = base_near;
        ndx_ = cx / w_near;
        ndy_ = cy / w_near;
        D0_ = base_far - base_near;
        Dx_ = cx / w_far - ndx_;
        Dy_ = cy / w_far - ndy_;
    }
}

Ray CameraRays::unproject(double px, double py) const {
    // Map film position to NDC (row 0 at the top, NDC y up), unproject near and far.
    double x = 2.0 * px * inv_w_ - 1.0;
    double y = 1.0 - 2.0 * py * inv_h_;
    Vec3 p_near = dehomogenize(raster_to_world_ * glm::dvec4(x, y, -1.0, 1.0));
    Vec3 p_far = dehomogenize(raster_to_world_ * glm::dvec4(x, y, 1.0, 1.0));
    Ray ray;
    ray.o = ortho_ ? p_near : position_;
    ray.d = glm::normalize(p_far - p_near);
    return ray;
}

Ray camera_ray(const Camera& cam, double px, double py) { return CameraRays(cam)(px, py); }

}  // namespace airlight
