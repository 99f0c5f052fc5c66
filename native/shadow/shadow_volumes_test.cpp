// shadow_volumes_test.cpp: lit intervals against analytic shadows and brute-force visibility.
#include "shadow/shadow_volumes.h"
#include "shadow/test_meshes.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

namespace airlight {
namespace {

bool is_lit(const LitIntervals& lit, int l, double t) {
    for (int k = lit.begin[l]; k < lit.end[l]; ++k)
        if (t >= lit.spans[k].first && t <= lit.spans[k].second) return true;
    return false;
}

// Segment p -> q against one triangle (Moller-Trumbore), strictly inside.
bool segment_hits(const Vec3& p, const Vec3& q, const Vec3& a, const Vec3& b, const Vec3& c) {
    const Vec3 d = q - p, e1 = b - a, e2 = c - a, h = glm::cross(d, e2);
    const double det = glm::dot(e1, h);
    if (std::abs(det) < 1e-14) return false;
    const Vec3 s = p - a;
    const double u = glm::dot(s, h) / det;
    if (u < 0.0 || u > 1.0) return false;
    const Vec3 qq = glm::cross(s, e1);
    const double v = glm::dot(d, qq) / det;
    if (v < 0.0 || u + v > 1.0) return false;
    const double t = glm::dot(e2, qq) / det;
    return t > 0.0 && t < 1.0;
}

// An infinite plane z = 0 (a huge quad) under a light at z = 5: the lit half-space is z > 0.
TEST(ShadowVolumes, PlaneLitHalfSpace) {
    TriangleMesh plane;
    add_quad(plane, Vec3(-1e4, -1e4, 0), Vec3(1e4, -1e4, 0), Vec3(1e4, 1e4, 0), Vec3(-1e4, 1e4, 0));
    ShadowLight light;
    light.position = Vec3(0.0, 0.0, 5.0);
    const Vec3 eye(3.0, 0.0, 10.0);
    const ShadowVolumes volumes(plane, {light}, eye);
    EXPECT_EQ(volumes.count_at(0, Vec3(1.0, 2.0, 3.0)), 0);
    EXPECT_EQ(volumes.count_at(0, Vec3(1.0, 2.0, -3.0)), 1);
    // Down through the plane at t = 10: lit above it only.
    std::vector<Ray> rays{{eye, Vec3(0, 0, -1)}, {Vec3(-50, 0, 1), Vec3(1, 0, 0)}, {Vec3(-50, 0, -1), Vec3(1, 0, 0)},
                          {eye, glm::normalize(Vec3(1, 0.3, -0.5))}};
    std::vector<float> t0(rays.size(), 0.0f), t1{20.0f, 100.0f, 100.0f, 60.0f};
    std::vector<LitIntervals> lit(rays.size());
    volumes.lit_intervals(rays.data(), t0.data(), t1.data(), int(rays.size()), nullptr, lit.data());
    EXPECT_NEAR(lit_length(lit[0], 0), 10.0, 1e-4);
    EXPECT_NEAR(lit_length(lit[1], 0), 100.0, 1e-4);
    EXPECT_NEAR(lit_length(lit[2], 0), 0.0, 1e-9);
    const double t_plane = 10.0 / 0.5 * glm::length(Vec3(1, 0.3, -0.5));  // z = 10 - 0.5 t / |.|
    EXPECT_NEAR(lit_length(lit[3], 0), t_plane, 1e-3);
}

// A light inside a closed box: no point outside is lit, every point inside is.
TEST(ShadowVolumes, LightInsideClosedBox) {
    TriangleMesh box;
    add_box(box, Vec3(-1, -1, -1), Vec3(1, 1, 1));
    ShadowLight light;
    light.position = Vec3(0.2, -0.1, 0.3);
    const Vec3 eye(5.0, 4.0, 3.0);
    const ShadowVolumes volumes(box, {light}, eye);
    std::mt19937 rng(3);
    std::uniform_real_distribution<double> U(-1.0, 1.0);
    std::vector<Ray> rays;
    for (int k = 0; k < 64; ++k) rays.push_back({eye, glm::normalize(Vec3(U(rng), U(rng), U(rng)) * 0.3 - eye)});
    std::vector<float> t0(rays.size(), 0.0f), t1(rays.size(), 30.0f);
    std::vector<LitIntervals> lit(rays.size());
    volumes.lit_intervals(rays.data(), t0.data(), t1.data(), int(rays.size()), nullptr, lit.data());
    for (size_t k = 0; k < rays.size(); ++k) {
        // Lit length = the chord inside the box (slab test).
        double tin = 0.0, tout = 30.0;
        for (int c = 0; c < 3; ++c) {
            double a = (-1.0 - rays[k].o[c]) / rays[k].d[c], b = (1.0 - rays[k].o[c]) / rays[k].d[c];
            if (a > b) std::swap(a, b);
            tin = std::max(tin, a), tout = std::min(tout, b);
        }
        EXPECT_NEAR(lit_length(lit[k], 0), std::max(0.0, tout - tin), 1e-4) << k;
    }
}

// Random triangle soups (open, non-manifold, overlapping, some zero-area) and point and sun
// lights: the lit state at points along random rays equals brute-force visibility, away from
// the boundaries (1e-4 of the ray's length).
TEST(ShadowVolumes, MatchesBruteForceVisibility) {
    for (int seed = 1; seed <= 4; ++seed) {
        std::mt19937 rng(seed);
        std::uniform_real_distribution<double> U(-1.0, 1.0);
        TriangleMesh soup;
        std::vector<Vec3> tri;
        for (int k = 0; k < 40; ++k) {
            const Vec3 c(4 * U(rng), 4 * U(rng), 2 * U(rng));
            for (int v = 0; v < 3; ++v) {
                const Vec3 p = k % 13 == 0 && v == 2 ? tri[tri.size() - 1] : c + Vec3(U(rng), U(rng), U(rng));
                tri.push_back(p);
                for (int q = 0; q < 3; ++q) soup.vertices.push_back(float(p[q]));
                soup.triangles.push_back(uint32_t(tri.size() - 1));
            }
        }
        add_box(soup, Vec3(-1, -1, -3), Vec3(1, 1, -2.5));  // a closed box among them
        for (size_t k = soup.triangles.size() - 36; k < soup.triangles.size(); ++k) (void)k;
        std::vector<Vec3> all;  // the triangles as the brute force sees them (float positions)
        for (uint32_t i : soup.triangles)
            all.emplace_back(soup.vertices[3 * i], soup.vertices[3 * i + 1], soup.vertices[3 * i + 2]);
        ShadowLight point, sun;
        point.position = Vec3(0.5, -0.3, 4.0);
        sun.directional = true;
        sun.direction = glm::normalize(Vec3(0.3, 0.2, -1.0));
        const Vec3 eye(0.0, -12.0, 1.0);
        const ShadowVolumes volumes(soup, {point, sun}, eye);
        std::vector<Ray> rays;
        for (int k = 0; k < 48; ++k) rays.push_back({eye, glm::normalize(Vec3(5 * U(rng), 12.0, 3 * U(rng)))});
        std::vector<float> t0(rays.size(), 0.0f), t1(rays.size(), 25.0f);
        std::vector<LitIntervals> lit(rays.size());
        volumes.lit_intervals(rays.data(), t0.data(), t1.data(), int(rays.size()), nullptr, lit.data());
        int checked = 0, wrong = 0;
        for (size_t k = 0; k < rays.size(); ++k)
            for (int l = 0; l < 2; ++l)
                for (int q = 0; q < 200; ++q) {
                    const double t = 25.0 * (q + 0.5) / 200.0;
                    bool near_boundary = false;
                    for (int s = lit[k].begin[l]; s < lit[k].end[l]; ++s)
                        near_boundary |= std::abs(t - lit[k].spans[s].first) < 2.5e-3 ||
                                         std::abs(t - lit[k].spans[s].second) < 2.5e-3;
                    if (near_boundary) continue;
                    const Vec3 p = rays[k].o + t * rays[k].d;
                    const Vec3 to = l == 0 ? point.position : p - 1e3 * sun.direction;
                    bool blocked = false;
                    for (size_t f = 0; f + 2 < all.size() && !blocked; f += 3)
                        blocked = segment_hits(p, to, all[f], all[f + 1], all[f + 2]);
                    ++checked;
                    wrong += blocked == is_lit(lit[k], l, t);
                }
        EXPECT_EQ(wrong, 0) << "seed " << seed << ": " << wrong << " of " << checked << " points disagree";
    }
}

// A strip from 5 cm to 50 m from the light, in 40 pieces: its vertices' rings reach the
// extrusion distance R (400 m here) after different numbers of steps (the far ones stop
// there while the near ones go on). Points of its shadow out to 0.95 R, crossed sideways,
// agree with brute-force visibility.
TEST(ShadowVolumes, CasterFromNearTheLightToFarShadowsOutToTheExtrusion) {
    TriangleMesh strip;
    const int pieces = 40;
    for (int k = 0; k < pieces; ++k) {
        const double x0 = 0.05 * std::pow(1000.0, double(k) / pieces);
        const double x1 = 0.05 * std::pow(1000.0, double(k + 1) / pieces);
        add_quad(strip, Vec3(x0, -0.5, 0.5), Vec3(x1, -0.5, 0.5), Vec3(x1, 0.5, 0.5), Vec3(x0, 0.5, 0.5));
    }
    std::vector<Vec3> all;
    for (uint32_t i : strip.triangles)
        all.emplace_back(strip.vertices[3 * i], strip.vertices[3 * i + 1], strip.vertices[3 * i + 2]);
    ShadowLight light;
    light.position = Vec3(0.0, 0.0, 1.0);
    const ShadowVolumes volumes(strip, {light}, Vec3(0.0, -45.0, 1.0));  // R = 8 x 50 m
    std::vector<Ray> rays;
    for (const double x : {5.0, 20.0, 60.0, 150.0, 300.0})
        for (const double z : {-20.0, -60.0, -100.0}) rays.push_back({Vec3(x, -150.0, z), Vec3(0.0, 1.0, 0.0)});
    std::vector<float> t0(rays.size(), 0.0f), t1(rays.size(), 300.0f);
    std::vector<LitIntervals> lit(rays.size());
    volumes.lit_intervals(rays.data(), t0.data(), t1.data(), int(rays.size()), nullptr, lit.data());
    int checked = 0, wrong = 0, shadowed = 0;
    for (size_t k = 0; k < rays.size(); ++k)
        for (int q = 0; q < 300; ++q) {
            const double t = q + 0.5;
            const Vec3 p = rays[k].o + t * rays[k].d;
            if (glm::length(p - light.position) > 0.95 * 400.0) continue;
            bool near_boundary = false;
            for (int s = lit[k].begin[0]; s < lit[k].end[0]; ++s)
                near_boundary |=
                    std::abs(t - lit[k].spans[s].first) < 0.1 || std::abs(t - lit[k].spans[s].second) < 0.1;
            if (near_boundary) continue;
            bool blocked = false;
            for (size_t f = 0; f + 2 < all.size() && !blocked; f += 3)
                blocked = segment_hits(p, light.position, all[f], all[f + 1], all[f + 2]);
            ++checked;
            shadowed += blocked;
            wrong += blocked == is_lit(lit[k], 0, t);
        }
    EXPECT_EQ(wrong, 0) << wrong << " of " << checked << " points disagree";
    EXPECT_GT(shadowed, checked / 4);
    EXPECT_GT(checked, 2000);
}

// The lights' volumes are built in parallel, a light a work item: any thread count builds the
// same faces, weights and counts.
TEST(ShadowVolumes, AnyThreadCountBuildsTheSameVolumes) {
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> U(-1.0, 1.0);
    TriangleMesh soup;
    for (int k = 0; k < 30; ++k) {
        const Vec3 lo(4 * U(rng), 4 * U(rng), U(rng));
        add_box(soup, lo, lo + Vec3(0.5 + std::abs(U(rng)), 0.5 + std::abs(U(rng)), 1.0 + std::abs(U(rng))));
    }
    std::vector<ShadowLight> lights(5);
    for (size_t l = 0; l < lights.size(); ++l) lights[l].position = Vec3(3 * U(rng), 3 * U(rng), 4.0 + U(rng));
    lights[2].directional = true;
    lights[2].direction = glm::normalize(Vec3(0.2, -0.3, -1.0));
    const Vec3 eye(0.0, -12.0, 2.0);
    const size_t seen = soup.triangles.size() / 3;
    // (Each built anew: the volumes keep their blocks' faces for the next build.)
    ShadowVolumes::clear_shared();
    const ShadowVolumes one(soup, lights, eye, seen, 1);
    ShadowVolumes::clear_shared();
    const ShadowVolumes three(soup, lights, eye, seen, 3);
    ASSERT_EQ(one.num_faces(), three.num_faces());
    for (int l = 0; l < one.num_lights(); ++l) {
        ASSERT_EQ(one.faces(l).size(), 1u);
        ASSERT_EQ(three.faces(l).size(), 1u);
        const ShadowFaces &a = *one.faces(l)[0], &b = *three.faces(l)[0];
        EXPECT_NE(&a, &b);
        EXPECT_EQ(a.vertices, b.vertices);
        EXPECT_EQ(a.triangles, b.triangles);
        EXPECT_EQ(a.weights, b.weights);
        EXPECT_EQ(a.whole_sides, b.whole_sides);
        EXPECT_GT(a.triangles.size(), a.n_caps * 3);
        for (const Vec3& p : {Vec3(1.0, 1.0, -1.0), Vec3(-2.0, 3.0, 0.2), Vec3(0.5, -0.5, 2.5)})
            EXPECT_EQ(one.count_at(l, p), three.count_at(l, p));
    }
}

// A light shadowed by nothing: one span over the whole segment; an empty caster mesh too.
TEST(ShadowVolumes, NoCastersLeavesEverythingLit) {
    ShadowLight light;
    light.position = Vec3(0.0, 0.0, 3.0);
    const ShadowVolumes volumes(TriangleMesh{}, {light}, Vec3(0.0));
    const Ray r{Vec3(0.0), Vec3(1, 0, 0)};
    const float t0 = 0.5f, t1 = std::numeric_limits<float>::infinity();
    LitIntervals lit;
    volumes.lit_intervals(&r, &t0, &t1, 1, nullptr, &lit);
    ASSERT_EQ(lit.end[0] - lit.begin[0], 1);
    EXPECT_EQ(lit.spans[0].first, 0.5);
    EXPECT_TRUE(std::isinf(lit.spans[0].second));
}

// A light in the plane of a caster (a flat sheet through the light; also what a thin slab
// 1000 km from the origin becomes in floats): the sheet shadows nothing, and the counts at
// the rays' origins agree with the volumes (before, count_at counted the sheet at the light
// itself and left every ray dark).
TEST(ShadowVolumes, CasterThroughTheLightShadowsNothing) {
    TriangleMesh sheet;
    add_quad(sheet, Vec3(-5, 0, -5), Vec3(5, 0, -5), Vec3(5, 0, 5), Vec3(-5, 0, 5));
    ShadowLight light;
    light.position = Vec3(0.0, 0.0, 0.5);  // inside the sheet's plane y = 0, inside the sheet
    const ShadowVolumes volumes(sheet, {light}, Vec3(0.0, -3.0, 0.0));
    for (const Vec3& p : {Vec3(1.0, 2.0, -1.0), Vec3(-2.0, -4.0, 3.0), Vec3(0.3, 0.5, 0.2)})
        EXPECT_EQ(volumes.count_at(0, p), 0);
    const Ray r{Vec3(0.2, -3.0, 0.1), glm::normalize(Vec3(0.1, 1.0, 0.05))};
    const float t0 = 0.0f, t1 = 20.0f;
    LitIntervals lit;
    volumes.lit_intervals(&r, &t0, &t1, 1, nullptr, &lit);
    EXPECT_NEAR(lit_length(lit, 0), 20.0, 1e-5);
}

}  // namespace
}  // namespace airlight
