// block_faces_test.cpp: the volumes' faces kept a block of the casters at a time
// (block_faces.h): a moved object rebuilds its own, and the volumes are a fresh build's.
#include "shadow/block_faces.h"
#include "shadow/shadow_volumes.h"
#include "shadow/test_meshes.h"

#include <gtest/gtest.h>

#include <random>
#include <vector>

namespace airlight {
namespace {

// A grid of n x n quads (2 n^2 triangles) over [x0, x1] x [y0, y1] at height z, appended to m.
void add_grid(TriangleMesh& m, int n, double x0, double x1, double y0, double y1, double z) {
    const uint32_t base = uint32_t(m.vertices.size() / 3);
    for (int j = 0; j <= n; ++j)
        for (int i = 0; i <= n; ++i)
            for (const double c : {x0 + (x1 - x0) * i / n, y0 + (y1 - y0) * j / n, z}) m.vertices.push_back(float(c));
    for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i) {
            const uint32_t a = base + uint32_t(j * (n + 1) + i), row = uint32_t(n) + 1;
            m.triangles.insert(m.triangles.end(), {a, a + 1, a + row + 1, a, a + row + 1, a + row});
        }
}

// Two floor grids of 33,800 triangles each (blocks of their own) meeting along x = 0, their
// vertices there equal but not shared, and a box above them (a block of its own).
TriangleMesh floors_and_box(double box_x, double box_z = 1.0) {
    TriangleMesh soup;
    add_grid(soup, 130, -4.0, 0.0, -4.0, 4.0, 0.0);
    add_grid(soup, 130, 0.0, 4.0, -4.0, 4.0, 0.0);
    add_box(soup, Vec3(box_x, -0.5, box_z), Vec3(box_x + 0.6, 0.5, box_z + 0.4));
    return soup;
}

std::vector<ShadowLight> lights() {
    ShadowLight point, sun;
    point.position = Vec3(0.3, 0.2, 3.0);
    sun.directional = true;
    sun.direction = glm::normalize(Vec3(0.2, 0.1, -1.0));
    return {point, sun};
}

// Rays from below the floors to above them, across the seam and the box's shadows.
std::vector<Ray> rays_across(const Vec3& eye, int n) {
    std::mt19937 rng(5);
    std::uniform_real_distribution<double> U(-1.0, 1.0);
    std::vector<Ray> rays;
    for (int k = 0; k < n; ++k) rays.push_back({eye, glm::normalize(Vec3(0.3 * U(rng), 0.8 * U(rng), 2.0) - eye)});
    return rays;
}

TEST(BlockFaces, AMovedObjectBuildsItsOwnFacesAndTheVolumesAreAFreshBuilds) {
    const Vec3 eye(-0.2, -6.0, -1.5);
    ShadowVolumes::clear_shared();
    const long built = ShadowVolumes::block_faces_built();
    const ShadowVolumes before(floors_and_box(-0.3), lights(), eye);
    EXPECT_EQ(ShadowVolumes::block_faces_built(), built + 6);  // 3 blocks, 2 lights
    ASSERT_EQ(before.faces(0).size(), 3u);
    const ShadowVolumes moved(floors_and_box(0.1), lights(), eye);
    EXPECT_EQ(ShadowVolumes::block_faces_built(), built + 8);  // the box's block
    for (int l = 0; l < 2; ++l) {
        EXPECT_EQ(moved.faces(l)[0], before.faces(l)[0]);  // (the same faces)
        EXPECT_NE(moved.faces(l)[2], before.faces(l)[2]);
    }
    // A light of the last volumes alone shares its faces.
    const ShadowVolumes sun_alone(floors_and_box(0.1), {lights()[1]}, eye);
    EXPECT_EQ(ShadowVolumes::block_faces_built(), built + 8);
    EXPECT_EQ(sun_alone.faces(0)[1], moved.faces(1)[1]);

    ShadowVolumes::clear_shared();
    const ShadowVolumes fresh(floors_and_box(0.1), lights(), eye);
    EXPECT_EQ(ShadowVolumes::block_faces_built(), built + 14);
    const std::vector<Ray> rays = rays_across(eye, 64);
    std::vector<float> t0(rays.size(), 0.0f), t1(rays.size(), 12.0f);
    std::vector<LitIntervals> kept(rays.size()), anew(rays.size());
    moved.lit_intervals(rays.data(), t0.data(), t1.data(), int(rays.size()), nullptr, kept.data());
    fresh.lit_intervals(rays.data(), t0.data(), t1.data(), int(rays.size()), nullptr, anew.data());
    for (size_t k = 0; k < rays.size(); ++k) {
        EXPECT_EQ(kept[k].spans, anew[k].spans) << "ray " << k;
        EXPECT_EQ(kept[k].begin, anew[k].begin) << "ray " << k;
    }
    for (int l = 0; l < 2; ++l)
        for (size_t b = 0; b < 3; ++b) {
            EXPECT_EQ(moved.faces(l)[b]->vertices, fresh.faces(l)[b]->vertices);
            EXPECT_EQ(moved.faces(l)[b]->triangles, fresh.faces(l)[b]->triangles);
            EXPECT_EQ(moved.faces(l)[b]->weights, fresh.faces(l)[b]->weights);
        }
}

// The box is the top of the casters' box: raising it moves their centre, not the volumes'
// frame (on a grid of 1/64 of their size), so the floors keep their faces and counting BVHs;
// raised by more than a cell it moves the frame, and every block is built again.
TEST(BlockFaces, AnObjectMovingTheCastersBoxByLessThanACellKeepsTheFrame) {
    const Vec3 eye(-0.2, -6.0, -1.5);
    ShadowVolumes::clear_shared();
    const ShadowVolumes before(floors_and_box(-0.3), lights(), eye);
    const long faces = ShadowVolumes::block_faces_built(), counting = ShadowVolumes::caster_blocks_built();
    const ShadowVolumes raised(floors_and_box(-0.3, 1.01), lights(), eye);
    EXPECT_EQ(raised.frame(), before.frame());
    EXPECT_EQ(ShadowVolumes::block_faces_built(), faces + 2);
    EXPECT_EQ(ShadowVolumes::caster_blocks_built(), counting + 1);
    const ShadowVolumes far_up(floors_and_box(-0.3, 2.0), lights(), eye);
    EXPECT_NE(far_up.frame(), before.frame());
    EXPECT_EQ(ShadowVolumes::block_faces_built(), faces + 2 + 6);
    EXPECT_EQ(ShadowVolumes::caster_blocks_built(), counting + 1 + 3);
}

// The two floors' seam is a silhouette of each block (an open mesh's border), a quad in each
// whose crossings cancel: points along rays under and over the floors, across the seam and
// the box's shadow, are lit where the casters' own count (count_at: Embree on the triangles)
// says so.
TEST(BlockFaces, BlocksMeetingAtASeamShadowAsOneMesh) {
    const Vec3 eye(-0.2, -6.0, -1.5);
    ShadowVolumes::clear_shared();
    const ShadowVolumes volumes(floors_and_box(-0.3), lights(), eye);
    ASSERT_EQ(volumes.faces(0).size(), 3u);
    const std::vector<Ray> rays = rays_across(eye, 48);
    std::vector<float> t0(rays.size(), 0.0f), t1(rays.size(), 12.0f);
    std::vector<LitIntervals> lit(rays.size());
    volumes.lit_intervals(rays.data(), t0.data(), t1.data(), int(rays.size()), nullptr, lit.data());
    int checked = 0, wrong = 0, shadowed = 0;
    for (size_t k = 0; k < rays.size(); ++k)
        for (int l = 0; l < 2; ++l)
            for (int q = 0; q < 200; ++q) {
                const double t = 12.0 * (q + 0.5) / 200.0;
                bool near_boundary = false;
                for (int s = lit[k].begin[l]; s < lit[k].end[l]; ++s)
                    near_boundary |= std::abs(t - lit[k].spans[s].first) < 2.5e-3 ||
                                     std::abs(t - lit[k].spans[s].second) < 2.5e-3;
                bool ambiguous = false;
                const int count = volumes.count_at(l, rays[k].o + t * rays[k].d, &ambiguous);
                if (near_boundary || ambiguous) continue;
                ++checked;
                shadowed += count > 0;
                bool in_span = false;
                for (int s = lit[k].begin[l]; s < lit[k].end[l]; ++s)
                    in_span |= t >= lit[k].spans[s].first && t <= lit[k].spans[s].second;
                wrong += (count == 0) != in_span;
            }
    EXPECT_EQ(wrong, 0) << wrong << " of " << checked << " points disagree";
    EXPECT_GT(shadowed, checked / 10);
    EXPECT_LT(shadowed, checked);
}

}  // namespace
}  // namespace airlight
