// screen_crossings_test.cpp: the rasterized crossings give the lit intervals Embree's traced
// crossings give, ray by ray, on scenes whose volumes reach behind the viewer.
#include "shadow/screen_crossings.h"
#include "shadow/test_meshes.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <tuple>
#include <vector>

namespace airlight {
namespace {

// No cut of the caps (ScreenCrossings keeps them all).
constexpr double kKeepCaps = std::numeric_limits<double>::infinity();


struct View {
    Vec3 eye, D0, Dx, Dy;
    int W, H;
};

// A pinhole camera at _eye_ looking at _target_ (z up), horizontal field of view _fov_.
View look_at(const Vec3& eye, const Vec3& target, double fov, int W, int H) {
    const Vec3 f = glm::normalize(target - eye);
    const Vec3 r = glm::normalize(glm::cross(f, Vec3(0, 0, 1)));
    const Vec3 u = glm::cross(r, f);
    const double sx = 2.0 * std::tan(0.5 * fov) / W;
    // D(px, py) = f + (px - W/2) sx r - (py - H/2) sx u
    return {eye, f - 0.5 * W * sx * r + 0.5 * H * sx * u, sx * r, -sx * u, W, H};
}

// Compares, for the film positions _film_, the lit intervals of both methods; returns the
// fraction of rays whose span counts differ, and, on the rays where the lit lengths differ,
// the largest fraction of points along the ray where the rasterized intervals contradict a
// shadow ray (lit_at).
void compare(const TriangleMesh& casters, const std::vector<ShadowLight>& lights, const View& v,
             const std::vector<glm::dvec2>& film, double& differ, double& worst, double& lit_share) {
    const ShadowVolumes volumes(casters, lights, v.eye);
    // (Any number of faces per tile: these small films hold few tiles.)
    const ScreenCrossings screen(volumes, v.eye, v.D0, v.Dx, v.Dy, v.W, v.H, kKeepCaps, 0.0,
                                 2, size_t(1) << 26, size_t(1) << 20);
    ASSERT_TRUE(screen.ready());
    const int L = volumes.num_lights(), n = int(film.size());
    std::vector<Ray> rays(film.size());
    std::vector<float> t0(film.size(), 0.0f), t1(film.size());
    std::mt19937 rng(3);
    for (int k = 0; k < n; ++k) {
        rays[k] = {v.eye, glm::normalize(v.D0 + film[k].x * v.Dx + film[k].y * v.Dy)};
        t1[k] = k % 3 == 0 ? 200.0f : float(std::uniform_real_distribution<double>(1.0, 60.0)(rng));
        t0[k] = k % 2 ? 0.0f : float(0.05 * t1[k]);
    }
    std::vector<int> count0(size_t(n) * L);
    std::vector<int> at_eye(L);
    for (int l = 0; l < L; ++l) {
        bool ambiguous = false;
        at_eye[l] = volumes.count_at(l, v.eye, &ambiguous);
        ASSERT_FALSE(ambiguous);
    }
    for (int k = 0; k < n; ++k)
        for (int l = 0; l < L; ++l) count0[size_t(k) * L + l] = at_eye[l];
    std::vector<LitIntervals> traced(film.size()), rastered(film.size());
    volumes.lit_intervals(rays.data(), t0.data(), t1.data(), n, count0.data(), traced.data());
    std::vector<std::vector<Crossing>> lists(256);
    for (int k0 = 0; k0 < n; k0 += 256) {
        const int m = std::min(256, n - k0);
        ASSERT_TRUE(screen.crossings(&film[k0], &rays[k0], &t1[k0], m, lists.data()));
        for (int k = 0; k < m; ++k)
            ShadowVolumes::lit_from_crossings(lists[k], L, t0[k0 + k], t1[k0 + k], at_eye.data(), 0xFFFFFFFFu,
                                              rastered[k0 + k]);
    }
    int n_differ = 0;
    double lit = 0.0, total = 0.0;
    worst = 0.0;
    for (int k = 0; k < n; ++k)
        for (int l = 0; l < L; ++l) {
            const double a = lit_length(traced[k], l), b = lit_length(rastered[k], l);
            const bool same = traced[k].end[l] - traced[k].begin[l] == rastered[k].end[l] - rastered[k].begin[l];
            if (!same) ++n_differ;
            if (std::abs(a - b) > 1e-3 * double(t1[k])) {
                // The two disagree (Embree's float traversal loses a crossing now and then):
                // the rasterized intervals must hold against shadow rays along the ray.
                const int N = 200;
                int wrong = 0;
                for (int q = 0; q < N; ++q) {
                    const double t = t0[k] + (q + 0.5) / N * (t1[k] - t0[k]);
                    bool in = false;
                    for (int z = rastered[k].begin[l]; z < rastered[k].end[l]; ++z)
                        in = in || (t >= rastered[k].spans[z].first && t <= rastered[k].spans[z].second);
                    wrong += in != volumes.lit_at(l, rays[k].o + t * rays[k].d);
                }
                worst = std::max(worst, double(wrong) / N);
            }
            lit += b;
            total += double(t1[k] - t0[k]);
        }
    differ = double(n_differ) / (double(n) * L);
    lit_share = lit / total;
}

// Pixel centres of every row (rows), and random sub-samples within a pixel of them.
std::vector<glm::dvec2> film_positions(int W, int H, bool rows) {
    std::vector<glm::dvec2> film;
    std::mt19937 rng(11);
    std::uniform_real_distribution<double> u(-1.5, 1.5);
    for (int j = 0; j < H; ++j)
        for (int i = 0; i < W; ++i) {
            if (rows) film.push_back({i + 0.5, j + 0.5});
            else film.push_back({i + 0.5 + u(rng), j + 0.5 + u(rng)});
        }
    return film;
}

TEST(ScreenCrossings, StreetOfBoxesMatchesEmbree) {
    TriangleMesh m;
    std::mt19937 rng(5);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    add_quad(m, Vec3(-40, -40, 0), Vec3(40, -40, 0), Vec3(40, 40, 0), Vec3(-40, 40, 0));
    for (int k = 0; k < 30; ++k) {
        const Vec3 lo(-20 + 40 * u(rng), -20 + 40 * u(rng), 0.0);
        add_box(m, lo, lo + Vec3(0.3 + 3 * u(rng), 0.3 + 3 * u(rng), 0.5 + 6 * u(rng)));
    }
    std::vector<ShadowLight> lights(3);
    lights[0].position = Vec3(2, 3, 5);
    lights[1].position = Vec3(-8, -5, 3);
    lights[2].directional = true;
    lights[2].direction = glm::normalize(Vec3(0.3, 0.5, -1.0));
    // Looking across the street, and from between the boxes towards the first light (volumes
    // behind the viewer), and straight down from above.
    const View views[] = {look_at(Vec3(-30, -28, 9), Vec3(0, 0, 1), 1.0, 160, 90),
                          look_at(Vec3(1.1, -1.3, 1.7), Vec3(-5, 8, 0.5), 1.6, 160, 90),
                          look_at(Vec3(0.2, 0.1, 35), Vec3(0, 0.01, 0), 1.2, 120, 120)};
    for (const View& v : views)
        for (bool rows : {true, false}) {
            double differ = 0.0, worst = 0.0, lit = 0.0;
            compare(m, lights, v, film_positions(v.W, v.H, rows), differ, worst, lit);
            EXPECT_LT(differ, 2e-3) << "rows " << rows;
            EXPECT_LT(worst, 0.02) << "rows " << rows;
            EXPECT_GT(lit, 0.05);
            EXPECT_LT(lit, 0.98);
        }
}

// 40 slats 2 cm wide at z = 4 (thinner than a pixel's footprint) and a box above them.
TriangleMesh slats_and_box() {
    TriangleMesh m;
    for (int k = 0; k < 40; ++k) {
        const double y = -10.0 + 0.5 * k;
        add_quad(m, Vec3(-10, y, 4), Vec3(-10, y + 0.02, 4), Vec3(10, y + 0.02, 4), Vec3(10, y, 4));
    }
    add_box(m, Vec3(-1, -1, 6), Vec3(1, 1, 6.5));
    return m;
}

// Slats, and a camera inside a shadow.
TEST(ScreenCrossings, SlatsAndACameraInShadowMatchEmbree) {
    const TriangleMesh m = slats_and_box();
    std::vector<ShadowLight> lights(1);
    lights[0].position = Vec3(0.5, 0.3, 9);
    const View v = look_at(Vec3(0.2, 0.1, 5.5), Vec3(3, 2, 0), 1.4, 200, 120);  // under the box
    for (bool rows : {true, false}) {
        double differ = 0.0, worst = 0.0, lit = 0.0;
        compare(m, lights, v, film_positions(v.W, v.H, rows), differ, worst, lit);
        EXPECT_LT(differ, 5e-3) << "rows " << rows;
        EXPECT_LT(worst, 0.02) << "rows " << rows;
        EXPECT_GT(lit, 0.05);
    }
}

// A row of pixel centres takes each face's span at once, and skips the per-pixel test well
// inside it: every pixel must get exactly the crossings its own test gives (one position a
// call), faces seen nearly edge-on (the slats) and reaching behind the viewer included.
TEST(ScreenCrossings, RowsGiveEachPixelItsOwnCrossings) {
    TriangleMesh m = slats_and_box();
    add_quad(m, Vec3(-40, -40, 0), Vec3(40, -40, 0), Vec3(40, 40, 0), Vec3(-40, 40, 0));
    std::vector<ShadowLight> lights(2);
    lights[0].position = Vec3(0.5, 0.3, 9);
    lights[1].directional = true;
    lights[1].direction = glm::normalize(Vec3(0.3, 0.5, -1.0));
    const View views[] = {look_at(Vec3(0.2, 0.1, 5.5), Vec3(3, 2, 0), 1.4, 200, 120),
                          look_at(Vec3(-30, -28, 9), Vec3(0, 0, 1), 1.0, 160, 90),
                          look_at(Vec3(-12, 0.01, 4.0), Vec3(12, 0.0, 4.0), 1.2, 160, 90)};  // along the slats
    auto key = [](const Crossing& c) { return std::make_tuple(c.t, c.light, c.dw); };
    long n_crossings = 0;
    for (const View& v : views) {
        const ShadowVolumes volumes(m, lights, v.eye);
        const ScreenCrossings screen(volumes, v.eye, v.D0, v.Dx, v.Dy, v.W, v.H, kKeepCaps, 0.0,
                                     2, size_t(1) << 26, size_t(1) << 20);
        ASSERT_TRUE(screen.ready());
        std::vector<glm::dvec2> film(size_t(v.W));
        std::vector<Ray> rays(size_t(v.W));
        std::vector<float> t1(size_t(v.W), 500.0f);
        std::vector<std::vector<Crossing>> lists(size_t(v.W));
        std::vector<Crossing> own;
        for (int j = 0; j < v.H; ++j) {
            for (int i = 0; i < v.W; ++i) {
                film[i] = {i + 0.5, j + 0.5};
                rays[i] = {v.eye, glm::normalize(v.D0 + film[i].x * v.Dx + film[i].y * v.Dy)};
            }
            ASSERT_TRUE(screen.crossings(film.data(), rays.data(), t1.data(), v.W, lists.data()));
            for (int i = 0; i < v.W; ++i) {
                ASSERT_TRUE(screen.crossings(&film[i], &rays[i], &t1[i], 1, &own));
                auto sorted = [&](std::vector<Crossing> l) {
                    std::sort(l.begin(), l.end(),
                              [&](const Crossing& a, const Crossing& b) { return key(a) < key(b); });
                    return l;
                };
                const std::vector<Crossing> a = sorted(lists[i]), b = sorted(own);
                ASSERT_EQ(a.size(), b.size()) << "pixel " << i << ", " << j;
                for (size_t q = 0; q < a.size(); ++q) ASSERT_TRUE(key(a[q]) == key(b[q])) << "pixel " << i << ", " << j;
                n_crossings += long(a.size());
            }
        }
    }
    EXPECT_GT(n_crossings, 10000);
}

TEST(ScreenCrossings, OutsideTheFilmIsRefused) {
    TriangleMesh m;
    add_box(m, Vec3(-1, -1, 0), Vec3(1, 1, 1));
    std::vector<ShadowLight> lights(1);
    lights[0].position = Vec3(0, 0, 5);
    const View v = look_at(Vec3(-10, -10, 5), Vec3(0, 0, 0), 1.0, 64, 48);
    const ShadowVolumes volumes(m, lights, v.eye);
    const ScreenCrossings screen(volumes, v.eye, v.D0, v.Dx, v.Dy, v.W, v.H);
    const glm::dvec2 far_off{-20.0, 10.0};
    const Ray ray{v.eye, glm::normalize(v.D0 + far_off.x * v.Dx + far_off.y * v.Dy)};
    const float t1 = 100.0f;
    std::vector<Crossing> list;
    EXPECT_FALSE(screen.crossings(&far_off, &ray, &t1, 1, &list));
    // Too many entries for the cap: not binned.
    const ScreenCrossings tiny(volumes, v.eye, v.D0, v.Dx, v.Dy, v.W, v.H, kKeepCaps, 0.0, 2, 4);
    EXPECT_FALSE(tiny.ready());
}

// Heavy casters (more faces than kMaxFacesPerPixel per pixel): left to Embree before any face
// is built; asked to, the film bins them.
TEST(ScreenCrossings, HeavyCastersAreLeftToEmbree) {
    TriangleMesh m;
    const int n = 40;  // a grid of 2 n^2 = 3200 triangles, its caps and boundary: > 4096 faces
    for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j) {
            const double x = -4.0 + 0.2 * i, y = -4.0 + 0.2 * j;
            add_quad(m, Vec3(x, y, 3), Vec3(x + 0.2, y, 3), Vec3(x + 0.2, y + 0.2, 3), Vec3(x, y + 0.2, 3));
        }
    std::vector<ShadowLight> lights(2);
    lights[0].position = Vec3(0.5, 0.3, 9);
    lights[1].position = Vec3(-0.5, 0.3, 8);
    const View v = look_at(Vec3(-10, -10, 5), Vec3(0, 0, 0), 1.0, 64, 48);
    const ShadowVolumes volumes(m, lights, v.eye);
    const ScreenCrossings heavy(volumes, v.eye, v.D0, v.Dx, v.Dy, v.W, v.H);
    EXPECT_FALSE(heavy.ready());
    EXPECT_EQ(heavy.num_faces(), 0u);  // (decided before building them)
    const ScreenCrossings asked(volumes, v.eye, v.D0, v.Dx, v.Dy, v.W, v.H, kKeepCaps, 0.0, 2,
                                size_t(1) << 26, size_t(1) << 20, 1e9);
    EXPECT_TRUE(asked.ready());
    EXPECT_GT(asked.num_faces(), ScreenCrossings::kMinFacesForFallback);
}

}  // namespace
}  // namespace airlight
