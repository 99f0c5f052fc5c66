// test_meshes.h: caster meshes for the shadow tests (shadow_volumes_test.cpp,
// bake/shadow_bake_test.cpp).
#pragma once

#include <cstdint>

#include "core/scene.h"
#include "shadow/shadow_volumes.h"

namespace airlight {

// Appends the quad a b c d (two triangles) to _m_.
inline void add_quad(TriangleMesh& m, const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d) {
    const uint32_t base = uint32_t(m.vertices.size() / 3);
    for (const Vec3& p : {a, b, c, d})
        for (int k = 0; k < 3; ++k) m.vertices.push_back(float(p[k]));
    m.triangles.insert(m.triangles.end(), {base, base + 1, base + 2, base, base + 2, base + 3});
}

// An axis-aligned box as 12 triangles (closed, each face wound outward).
inline void add_box(TriangleMesh& m, const Vec3& lo, const Vec3& hi) {
    auto P = [&](int x, int y, int z) { return Vec3(x ? hi.x : lo.x, y ? hi.y : lo.y, z ? hi.z : lo.z); };
    add_quad(m, P(0, 0, 0), P(0, 1, 0), P(1, 1, 0), P(1, 0, 0));
    add_quad(m, P(0, 0, 1), P(1, 0, 1), P(1, 1, 1), P(0, 1, 1));
    add_quad(m, P(0, 0, 0), P(1, 0, 0), P(1, 0, 1), P(0, 0, 1));
    add_quad(m, P(0, 1, 0), P(0, 1, 1), P(1, 1, 1), P(1, 1, 0));
    add_quad(m, P(0, 0, 0), P(0, 0, 1), P(0, 1, 1), P(0, 1, 0));
    add_quad(m, P(1, 0, 0), P(1, 1, 0), P(1, 1, 1), P(1, 0, 1));
}

// The total length of light _l_'s lit spans.
inline double lit_length(const LitIntervals& lit, int l) {
    double sum = 0.0;
    for (int k = lit.begin[l]; k < lit.end[l]; ++k) sum += lit.spans[k].second - lit.spans[k].first;
    return sum;
}

}  // namespace airlight
