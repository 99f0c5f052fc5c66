// camera.cpp: primary rays through Blender's pixel grid by unprojecting clip space.
#include "image/camera.h"

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
    if (!(cam.clip_start >= 0.0) || std::isinf(cam.clip_start) || !(cam.clip_end > cam.clip_start))
        throw std::invalid_argument("camera clip range must satisfy 0 <= clip_start < clip_end (clip_end may be inf), got " +
                                    std::to_string(cam.clip_start) + ", " + std::to_string(cam.clip_end));

    // Orthographic projections keep w = 1: bottom row (0, 0, 0, 1). glm is column-major,
    // so element (row 3, column 3) is projection[3][3].
    const glm::dmat4& P = cam.projection;
    ortho_ = P[3][3] == 1.0 && P[2][3] == 0.0;
    raster_to_world_ = cam.cam_to_world * glm::inverse(P);
    position_ = Vec3(cam.cam_to_world[3]);
    forward_ = -glm::normalize(Vec3(cam.cam_to_world[2]));
    clip_start_ = cam.clip_start;
    clip_end_ = cam.clip_end;
    inv_w_ = 1.0 / cam.width;
    inv_h_ = 1.0 / cam.height;
    // Blender's projections (calc_matrix_camera) have the bottom row (0, 0, -1, 0)
    // (perspective) or (0, 0, 0, 1) (orthographic): their rays follow from the x and y rows
    // alone, which are well conditioned at every clip range. (The depth rows are not: with
    // clip_end / clip_start ~ 1e8 the single-precision matrix Blender hands over has
    // -(f + n) / (f - n) rounded to -1, and unprojecting the far plane divides by ~0.)
    const bool blender_form = P[0][3] == 0.0 && P[1][3] == 0.0 &&
                              ((P[2][3] == -1.0 && P[3][3] == 0.0) || ortho_);
    affine_ = true;
    if (blender_form) {
        affine_from_xy_rows(cam);
    } else {
        // A general projective matrix: rays are affine in (px, py) when w of the
        // unprojected near/far points does not depend on the film position.
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
    check_rays(cam);
}

void CameraRays::affine_from_xy_rows(const Camera& cam) {
    // Camera-space film point (X, Y) of NDC (x, y): A (X, Y) = (x, y) - c, with A the 2 x 2
    // upper-left block of the projection and c its Z and W columns' x, y at the film's
    // depth (perspective: Z = -1, where clip w = 1; orthographic: the near plane).
    const glm::dmat4& P = cam.projection;
    const double a00 = P[0][0], a01 = P[1][0], a10 = P[0][1], a11 = P[1][1];
    const double det = a00 * a11 - a01 * a10;
    if (!std::isfinite(det) || det == 0.0)
        throw std::invalid_argument("camera projection maps the film to a line (zero focal length or sensor?)");
    auto solve = [&](double bx, double by) {
        return glm::dvec2((a11 * bx - a01 * by) / det, (a00 * by - a10 * bx) / det);
    };
    const glm::dmat3 R(cam.cam_to_world);
    // d(X, Y)/dpx and d(X, Y)/dpy: NDC x = 2 px / W - 1, y = 1 - 2 py / H.
    const glm::dvec2 ex = solve(2.0 * inv_w_, 0.0), ey = solve(0.0, -2.0 * inv_h_);
    if (!ortho_) {
        // Perspective: the ray through (X, Y, -1) from the eye.
        const glm::dvec2 e0 = solve(-1.0 + P[2][0] - P[3][0], 1.0 + P[2][1] - P[3][1]);
        D0_ = R * Vec3(e0, -1.0);
        Dx_ = R * Vec3(ex, 0.0);
        Dy_ = R * Vec3(ey, 0.0);
        n0_ = position_;
        ndx_ = ndy_ = Vec3(0.0);
        return;
    }
    // Orthographic: origins on the near plane, depth clip_start (Blender's projections have
    // their near plane there; with clip_start = 0 the projection's own near plane, where
    // NDC z = -1), all along one direction.
    double z_near = -clip_start_;
    if (clip_start_ == 0.0) z_near = (-1.0 - P[3][2]) / P[2][2];
    if (!std::isfinite(z_near)) z_near = 0.0;
    const glm::dvec2 e0 = solve(-1.0 - P[2][0] * z_near - P[3][0], 1.0 - P[2][1] * z_near - P[3][1]);
    n0_ = Vec3(cam.cam_to_world * glm::dvec4(e0, z_near, 1.0));
    ndx_ = R * Vec3(ex, 0.0);
    ndy_ = R * Vec3(ey, 0.0);
    D0_ = R * Vec3(solve(P[2][0], P[2][1]), -1.0);
    Dx_ = Dy_ = Vec3(0.0);
}

void CameraRays::check_rays(const Camera& cam) const {
    // Every ray the bake makes lies in the convex hull of the film's corners (affine rays),
    // so finite, forward-pointing corner rays mean finite, forward-pointing rays everywhere
    // (Embree asserts on a NaN or huge origin or direction: a dead Blender, not an error).
    const double W = cam.width, H = cam.height;
    const double corners[4][2] = {{0.0, 0.0}, {W, 0.0}, {0.0, H}, {W, H}};
    constexpr double kLarge = 1e18;  // Embree's FLT_LARGE is 1.844e18
    for (const auto& c : corners) {
        const Ray r = (*this)(c[0], c[1]);
        const bool ok = std::isfinite(r.d.x) && std::isfinite(r.d.y) && std::isfinite(r.d.z) &&
                        std::abs(glm::length(r.d) - 1.0) < 1e-6 && std::abs(r.o.x) < kLarge &&
                        std::abs(r.o.y) < kLarge && std::abs(r.o.z) < kLarge && glm::dot(r.d, forward_) > 1e-9;
        if (!ok)
            throw std::invalid_argument(
                "camera cannot be baked: its rays at the film's corners are not finite or do not point ahead "
                "(the lens, sensor, shift or clip range give a degenerate projection)");
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
