// test_meshes.h: caster meshes for the shadow tests (shadow_volumes_test.cpp,
// bake/shadow_bake_test.cpp).
#pragma once

#include <cstdint>

#include "core/scene.h"

namespace airlight {

// Appends the quad a b c d (two triangles) to _m_.
inline void add_quad(TriangleMesh& m, const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d) {
    const uint32_t base = uint32_t(m.vertices.size() / 3);
    for (const Vec3& p : {a, b, c, d})
        for (int k = 0; k < 3; ++k) m.vertices.push_back(float(p[k]));
    m.triangles.insert(m.triangles.end(), {base, base + 1, base + 2, base, base + 2, base + 3});
}

}  // namespace airlight
