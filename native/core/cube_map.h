// cube_map.h: the cube map of directions that gaussian/centre_depths.cpp bins candidates in
// and gaussian/light_depth_map.h tabulates optical depths on. A direction u != 0 lies on the
// face of its dominant axis m, face 2 m + (u_m < 0), at the face coordinates
// (u_p, u_q) / |u_m| in [-1, 1], p = (m + 1) % 3, q = (m + 2) % 3.
#pragma once

#include <cmath>

#include "core/scene.h"

namespace airlight {

struct CubeFacePoint {
    int face;
    double p, q;  // the face coordinates, in [-1, 1]
};

// The face and face coordinates of direction u != 0 (finite).
inline CubeFacePoint cube_face_point(const Vec3& u) {
    const double ax = std::abs(u.x), ay = std::abs(u.y), az = std::abs(u.z);
    const int m = ax >= ay && ax >= az ? 0 : (ay >= az ? 1 : 2);
    const double um = std::abs(u[m]);
    return {2 * m + (u[m] < 0.0 ? 1 : 0), u[(m + 1) % 3] / um, u[(m + 2) % 3] / um};
}

// The unit direction of face coordinates (p, q) on _face_ (the inverse of cube_face_point).
inline Vec3 cube_direction(int face, double p, double q) {
    const int m = face / 2;
    Vec3 d(0.0);
    d[m] = (face % 2) ? -1.0 : 1.0;
    d[(m + 1) % 3] = p;
    d[(m + 2) % 3] = q;
    return glm::normalize(d);
}

}  // namespace airlight
