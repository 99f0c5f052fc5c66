// Tests of embree_blocks.h: a soup is cut at its objects' seams only; a cache shares the blocks
// that stay and builds the ones that change; a caster over blocks hits what one over the whole
// soup hits, bit for bit.
#include "image/embree_blocks.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "image/raycast.h"

namespace airlight {
namespace {

// A grid of n x n quads (2 n^2 triangles) in the plane z = _z_ over [x0, x0 + 1] x [0, 1],
// appended to _mesh_ (its own vertices).
void add_grid(TriangleMesh& mesh, int n, float x0, float z) {
    const uint32_t base = uint32_t(mesh.vertices.size() / 3);
    for (int j = 0; j <= n; ++j)
        for (int i = 0; i <= n; ++i) mesh.vertices.insert(mesh.vertices.end(), {x0 + float(i) / n, float(j) / n, z});
    for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i) {
            const uint32_t a = base + uint32_t(j * (n + 1) + i), b = a + 1, c = a + uint32_t(n + 1), d = c + 1;
            mesh.triangles.insert(mesh.triangles.end(), {a, b, d, a, d, c});
        }
}

void expect_block(const SoupBlock& b, size_t tri_begin, size_t tri_end, uint32_t vertex_begin, uint32_t vertex_end) {
    EXPECT_EQ(b.tri_begin, tri_begin);
    EXPECT_EQ(b.tri_end, tri_end);
    EXPECT_EQ(b.vertex_begin, vertex_begin);
    EXPECT_EQ(b.vertex_end, vertex_end);
}

TEST(EmbreeBlocks, CutsAtTheSeamsOnlyAndJoinsSmallRuns) {
    TriangleMesh m;
    add_grid(m, 2, 0.0f, 0.0f);  // 8 triangles, 9 vertices
    add_grid(m, 1, 1.0f, 0.0f);  // 2, 4
    add_grid(m, 3, 2.0f, 0.0f);  // 18, 16
    const auto runs = soup_blocks(m.triangles.data(), m.triangles.size() / 3, 1);
    ASSERT_EQ(runs.size(), 3u);
    expect_block(runs[0], 0, 8, 0, 9);
    expect_block(runs[1], 8, 10, 9, 13);
    expect_block(runs[2], 10, 28, 13, 29);
    // Runs join up to at least 9 triangles: 8 + 2, then 18.
    const auto joined = soup_blocks(m.triangles.data(), m.triangles.size() / 3, 9);
    ASSERT_EQ(joined.size(), 2u);
    expect_block(joined[0], 0, 10, 0, 13);
    expect_block(joined[1], 10, 28, 13, 29);
    // A large run stays a block of its own: small runs before it do not join it (2 + 8, 18).
    TriangleMesh small_first;
    add_grid(small_first, 1, 1.0f, 0.0f);
    add_grid(small_first, 2, 0.0f, 0.0f);
    add_grid(small_first, 3, 2.0f, 0.0f);
    const auto kept_apart = soup_blocks(small_first.triangles.data(), small_first.triangles.size() / 3, 12);
    ASSERT_EQ(kept_apart.size(), 2u);
    expect_block(kept_apart[0], 0, 10, 0, 13);
    expect_block(kept_apart[1], 10, 28, 13, 29);
    // A triangle of the last object that uses a vertex of the first one: no seam after the first.
    TriangleMesh shared = m;
    shared.triangles.insert(shared.triangles.end(), {0u, 27u, 28u});
    const auto one = soup_blocks(shared.triangles.data(), shared.triangles.size() / 3, 1);
    ASSERT_EQ(one.size(), 1u);
    EXPECT_EQ(one[0].vertex_end, 29u);
}

TEST(EmbreeBlocks, ACacheBuildsOnlyTheBlocksThatChanged) {
    TriangleMesh m;
    const int n = 130;  // 33,800 triangles: above kMinBlockTriangles, each grid its own block
    ASSERT_GE(size_t(2 * n * n), BlockCache::kMinBlockTriangles);
    add_grid(m, n, 0.0f, 0.0f);
    add_grid(m, n, 1.0f, 0.5f);
    add_grid(m, n, 2.0f, 1.0f);
    BlockCache cache(RTC_BUILD_QUALITY_MEDIUM);
    auto scene = [&](const TriangleMesh& mesh) {
        return cache.scene(mesh.vertices.data(), mesh.vertices.size() / 3, mesh.triangles.data(),
                           mesh.triangles.size() / 3);
    };
    const auto first = scene(m);
    EXPECT_EQ(first->blocks(), 3u);
    EXPECT_EQ(cache.blocks_built(), 3);
    TriangleMesh copy = m;
    EXPECT_EQ(scene(copy), first);  // equal arrays: the same scene
    EXPECT_EQ(cache.blocks_built(), 3);
    TriangleMesh moved = m;
    moved.vertices[3 * size_t((n + 1) * (n + 1)) + 2] += 0.25f;  // a vertex of the second grid
    const auto second = scene(moved);
    EXPECT_NE(second, first);
    EXPECT_EQ(cache.blocks_built(), 4);
    // The first grid moved to the end (its indices after the others'): a seam where it was, and
    // the same blocks in another order.
    TriangleMesh reordered;
    add_grid(reordered, n, 1.0f, 0.5f);
    add_grid(reordered, n, 2.0f, 1.0f);
    add_grid(reordered, n, 0.0f, 0.0f);
    reordered.vertices[2] += 0.25f;  // the second grid as moved above
    scene(reordered);
    EXPECT_EQ(cache.blocks_built(), 4);
    TriangleMesh bad = m;
    bad.triangles[5] = uint32_t(bad.vertices.size() / 3);
    EXPECT_THROW(scene(bad), std::invalid_argument);
}

TEST(EmbreeBlocks, ACasterOverBlocksHitsWhatOneOverTheSoupHits) {
    // Three overlapping grids (each a block), a fourth small one joined to the last; rays from
    // above and from the side, at the grids and between them.
    TriangleMesh m;
    add_grid(m, 130, 0.0f, 0.0f);
    add_grid(m, 130, 0.5f, 0.3f);
    add_grid(m, 130, 1.0f, 0.6f);
    add_grid(m, 3, 0.2f, 0.9f);
    const RayCaster blocked(m);
    // The same triangles as one object: a triangle joining the first vertex to the last keeps
    // the soup from being cut (that triangle has no area: it hits nothing).
    TriangleMesh whole = m;
    const uint32_t last = uint32_t(whole.vertices.size() / 3 - 1);
    whole.triangles.insert(whole.triangles.end(), {0u, last, last});
    ASSERT_EQ(soup_blocks(whole.triangles.data(), whole.triangles.size() / 3, 1).size(), 1u);
    const RayCaster single(whole);
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> u(-0.2, 2.2);
    const int N = 4000;
    std::vector<Ray> rays(N);
    for (int k = 0; k < N; ++k) {
        // Half from above, half from the side through the stack of grids.
        const Vec3 o = k % 2 ? Vec3(u(rng), 0.5 * u(rng), 2.0) : Vec3(-1.0, 0.5 * u(rng), 0.3 * u(rng));
        const Vec3 target = k % 2 ? Vec3(u(rng), 0.5 * u(rng), 0.3 * u(rng)) : Vec3(2.5, 0.5 * u(rng), 0.3 * u(rng));
        rays[k] = Ray{o, glm::normalize(target - o)};
    }
    std::vector<float> a(N), b(N);
    blocked.first_hits(rays.data(), N, a.data());
    single.first_hits(rays.data(), N, b.data());
    int hits = 0;
    for (int k = 0; k < N; ++k) {
        EXPECT_EQ(a[k], b[k]) << k;
        hits += std::isfinite(a[k]);
    }
    EXPECT_GT(hits, N / 4);
}

}  // namespace
}  // namespace airlight
