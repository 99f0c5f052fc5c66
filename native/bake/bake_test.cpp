// bake_test.cpp: camera rays, Embree first hits and the bake against analytic geometry.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <random>
#include <string>

#include <glm/gtc/matrix_transform.hpp>

#include "core/constants.h"
#include "bake/bake.h"
#include "homogeneous/biri06.h"
#include "image/camera.h"
#include "image/raycast.h"
#include "gaussian/airlight.h"
#include "gaussian/medium.h"
#include "core/quadrature.h"
#include "homogeneous/sun05.h"

namespace airlight {
namespace {


// OpenGL projection like Blender's calc_matrix_camera with horizontal sensor fit.
glm::dmat4 blender_perspective(double fov_x, int W, int H, double n = 0.1, double f = 100.0) {
    double r = n * std::tan(fov_x / 2), t = r * H / W;
    return glm::frustum(-r, r, -t, t, n, f);
}

Camera test_camera(const glm::dmat4& cam_to_world, const glm::dmat4& projection, int W = 64, int H = 48) {
    Camera cam;
    cam.cam_to_world = cam_to_world;
    cam.projection = projection;
    cam.width = W;
    cam.height = H;
    return cam;
}

glm::dmat4 rotated_camera() {
    glm::dmat4 m = glm::translate(glm::dmat4(1.0), Vec3(1.0, -2.0, 3.0));
    return glm::rotate(m, 0.7, glm::normalize(Vec3(0.3, 1.0, -0.2)));
}

TEST(Camera, CentreRayLooksDownMinusZ) {
    const glm::dmat4 c2w = rotated_camera();
    Camera cam = test_camera(c2w, blender_perspective(kPi / 3, 64, 48));
    Ray ray = camera_ray(cam, 32.0, 24.0);
    Vec3 forward = -glm::normalize(Vec3(c2w[2]));
    EXPECT_NEAR(glm::length(ray.o - Vec3(c2w[3])), 0.0, 1e-12);
    EXPECT_NEAR(glm::dot(ray.d, forward), 1.0, 1e-12);
}

TEST(Camera, CornerRaysHitTheFieldOfView) {
    const double fov_x = kPi / 3;
    const int W = 64, H = 48;
    Camera cam = test_camera(glm::dmat4(1.0), blender_perspective(fov_x, W, H), W, H);
    // Film corner (0, 0) is the top-left: x = -tan(fov/2), y = +tan(fov/2) H / W at z = -1.
    Ray ray = camera_ray(cam, 0.0, 0.0);
    Vec3 want = glm::normalize(Vec3(-std::tan(fov_x / 2), std::tan(fov_x / 2) * H / W, -1.0));
    EXPECT_NEAR(glm::length(ray.d - want), 0.0, 1e-12);
    // Right edge centre: exactly half the horizontal field of view.
    ray = camera_ray(cam, W, H / 2.0);
    EXPECT_NEAR(std::acos(-ray.d.z), fov_x / 2, 1e-12);
    EXPECT_GT(ray.d.x, 0.0);
}

TEST(Camera, OrthographicRaysAreParallel) {
    const glm::dmat4 c2w = rotated_camera();
    Camera cam = test_camera(c2w, glm::ortho(-2.0, 2.0, -1.5, 1.5, 0.1, 100.0));
    Vec3 forward = -glm::normalize(Vec3(c2w[2]));
    Ray a = camera_ray(cam, 0.5, 0.5), b = camera_ray(cam, 63.5, 47.5);
    EXPECT_NEAR(glm::dot(a.d, forward), 1.0, 1e-12);
    EXPECT_NEAR(glm::dot(b.d, forward), 1.0, 1e-12);
    // Origins on the near plane, 4 x 3 apart at the corners (minus one pixel).
    EXPECT_NEAR(glm::dot(a.o - Vec3(c2w[3]), forward), 0.1, 1e-12);
    EXPECT_NEAR(glm::length(a.o - b.o), std::hypot(4.0 * 63 / 64, 3.0 * 47 / 48), 1e-12);
    EXPECT_TRUE(CameraRays(cam).orthographic());
}

TEST(Camera, RejectsSingularMatrices) {
    Camera cam = test_camera(glm::dmat4(1.0), glm::dmat4(0.0));
    EXPECT_THROW(CameraRays{cam}, std::invalid_argument);
}

// Blender hands over its projection in single precision: with clip_end / clip_start ~ 1e8
// -(f + n) / (f - n) rounds to -1 and the far plane unprojects to infinity. The rays come
// from the matrix's x and y rows, so they stay the exact pinhole rays (they aborted Blender
// through an Embree assertion before).
glm::dmat4 single_precision(const glm::dmat4& m) {
    glm::dmat4 out;
    for (int c = 0; c < 4; ++c)
        for (int r = 0; r < 4; ++r) out[c][r] = double(float(m[c][r]));
    return out;
}

TEST(Camera, WideClipRangeKeepsExactRays) {
    const glm::dmat4 c2w = rotated_camera();
    const int W = 64, H = 48;
    const Camera exact = test_camera(c2w, blender_perspective(kPi / 3, W, H, 0.1, 100.0), W, H);
    for (const auto& clip : {std::pair<double, double>{1e-3, 1e5}, {1e-6, 100.0}, {1e-6, 1e9}}) {
        Camera cam = test_camera(c2w, single_precision(blender_perspective(kPi / 3, W, H, clip.first, clip.second)), W, H);
        cam.clip_start = clip.first;
        cam.clip_end = clip.second;
        const CameraRays rays(cam), want(exact);
        for (double px : {0.0, 17.5, 64.0})
            for (double py : {0.0, 31.5, 48.0}) {
                const Ray a = rays(px, py), b = want(px, py);
                EXPECT_TRUE(std::isfinite(a.d.x) && std::isfinite(a.d.y) && std::isfinite(a.d.z));
                EXPECT_NEAR(glm::length(a.d - b.d), 0.0, 1e-6) << clip.first << " " << clip.second;
                EXPECT_NEAR(glm::length(a.o - b.o), 0.0, 1e-12);
            }
    }
}

TEST(Camera, OrthographicWideClipRangeKeepsOrigins) {
    const glm::dmat4 c2w = rotated_camera();
    Camera cam = test_camera(c2w, single_precision(glm::ortho(-2.0, 2.0, -1.5, 1.5, 1e-6, 1e9)));
    cam.clip_start = 1e-6;
    cam.clip_end = 1e9;
    const Ray a = camera_ray(cam, 0.5, 0.5);
    const Vec3 forward = -glm::normalize(Vec3(c2w[2]));
    EXPECT_NEAR(glm::dot(a.d, forward), 1.0, 1e-12);
    EXPECT_NEAR(glm::dot(a.o - Vec3(c2w[3]), forward), 1e-6, 1e-9);
}

// A projection that maps the film onto a line, or rays that would leave Embree's range, is
// refused with a message rather than handed on.
TEST(Camera, RefusesDegenerateProjections) {
    glm::dmat4 flat = blender_perspective(kPi / 3, 64, 48);
    flat[0][0] = 0.0;
    EXPECT_THROW(CameraRays{test_camera(glm::dmat4(1.0), flat)}, std::invalid_argument);
    glm::dmat4 far = glm::translate(glm::dmat4(1.0), Vec3(1e19, 0.0, 0.0));
    EXPECT_THROW(CameraRays{test_camera(far, blender_perspective(kPi / 3, 64, 48))}, std::invalid_argument);
}

TriangleMesh square(double z, double s = 10.0) {
    TriangleMesh m;
    m.vertices = {float(-s), float(-s), float(z), float(s), float(-s), float(z),
                  float(s),  float(s),  float(z), float(-s), float(s), float(z)};
    m.triangles = {0, 1, 2, 0, 2, 3};
    return m;
}

TEST(RayCaster, HitsPlaneAtAnalyticDistance) {
    RayCaster caster(square(-5.0));
    std::mt19937 rng(1);
    std::uniform_real_distribution<double> u(-0.5, 0.5);
    for (int k = 0; k < 100; ++k) {
        Ray ray{Vec3(u(rng), u(rng), 0.0), glm::normalize(Vec3(u(rng), u(rng), -1.0))};
        EXPECT_NEAR(caster.first_hit(ray), 5.0 / -ray.d.z, 1e-5);
    }
    EXPECT_TRUE(std::isinf(caster.first_hit({Vec3(0.0), Vec3(0, 0, 1)})));
    EXPECT_TRUE(std::isinf(caster.first_hit({Vec3(50, 0, 0), Vec3(0, 0, -1)})));
}

TEST(RayCaster, PacketsAgreeWithSingleRays) {
    RayCaster caster(square(-5.0, 1.0));
    std::mt19937 rng(2);
    std::uniform_real_distribution<double> u(-0.4, 0.4);
    std::vector<Ray> rays(37);  // not a multiple of 8
    for (Ray& r : rays) r = {Vec3(0.0), glm::normalize(Vec3(u(rng), u(rng), -1.0))};
    std::vector<float> t(rays.size());
    caster.first_hits(rays.data(), int(rays.size()), t.data());
    for (size_t i = 0; i < rays.size(); ++i) {
        double want = caster.first_hit(rays[i]);
        if (std::isinf(want)) EXPECT_TRUE(std::isinf(t[i]));
        else EXPECT_NEAR(t[i], want, 1e-5);
    }
}

TEST(RayCaster, EmptyMeshAndBadIndices) {
    RayCaster empty(TriangleMesh{});
    EXPECT_TRUE(std::isinf(empty.first_hit({Vec3(0.0), Vec3(0, 0, -1)})));
    TriangleMesh bad = square(-1.0);
    bad.triangles[5] = 4;
    EXPECT_THROW(RayCaster{bad}, std::invalid_argument);
}

// Rays Embree would assert on (NaN or huge origins or directions, tnear > tfar) are not
// traced: they read back NaN and are counted, so the bake refuses instead of aborting.
TEST(RayCaster, RefusesInvalidRaysInsteadOfAborting) {
    RayCaster caster(square(-5.0));
    const double nan = std::numeric_limits<double>::quiet_NaN();
    EXPECT_TRUE(std::isnan(caster.first_hit({Vec3(0.0), Vec3(nan, 0.0, -1.0)})));
    std::vector<Ray> rays(20, Ray{Vec3(0.0), Vec3(0.0, 0.0, -1.0)});
    rays[3].o.x = 1e30;
    rays[17].d = Vec3(nan);
    std::vector<float> t(rays.size());
    caster.first_hits(rays.data(), int(rays.size()), t.data());
    EXPECT_TRUE(std::isnan(t[3]) && std::isnan(t[17]));
    EXPECT_NEAR(t[0], 5.0, 1e-5);
    std::vector<float> dx(16, 0.0f), dy(16, 0.0f), dz(16, -1.0f), tn(16, 0.0f), tf(16, 1e30f), out(16);
    tn[5] = 2.0f;
    tf[5] = 1.0f;  // tnear > tfar
    dz[9] = std::numeric_limits<float>::infinity();
    caster.first_hits(Vec3(0.0), dx.data(), dy.data(), dz.data(), tn.data(), tf.data(), 16, out.data());
    EXPECT_TRUE(std::isnan(out[5]) && std::isnan(out[9]));
    EXPECT_NEAR(out[0], 5.0, 1e-5);
    EXPECT_EQ(caster.invalid_rays(), 5);
}

SceneDescription test_scene(int W = 40, int H = 30) {
    SceneDescription scene;
    scene.camera = test_camera(glm::dmat4(1.0), blender_perspective(kPi / 3, W, H), W, H);
    scene.medium.sigma_t = 0.1;
    scene.point_lights.push_back({Vec3(1.0, 2.0, -3.0), RGB(1.0, 2.0, 3.0)});
    scene.geometry = square(-6.0, 100.0);
    return scene;
}

TEST(Bake, PixelsMatchPerRayModel) {
    SceneDescription scene = test_scene();
    BakeSettings settings;
    settings.aa_samples = 1;
    settings.model = ModelId::Sun05Exact;
    BakeResult r = bake(scene, settings);
    const CameraRays rays(scene.camera);
    for (int j = 0; j < 30; j += 7)
        for (int i = 0; i < 40; i += 5) {
            Ray ray = rays(i + 0.5, j + 0.5);
            double Dvp = 6.0 / -ray.d.z;
            size_t p = size_t(j) * 40 + i;
            EXPECT_NEAR(r.depth[p], Dvp, 1e-5 * Dvp);
            EXPECT_NEAR(r.transmittance[3 * p], std::exp(-0.1 * Dvp), 1e-6);
            Vec3 sv = scene.point_lights[0].position;
            double La = sun05_airlight(0.1, glm::length(sv), glm::dot(ray.d, sv) / glm::length(sv), Dvp,
                                       nullptr, FEval::Exact);
            for (int c = 0; c < 3; ++c) EXPECT_NEAR(r.airlight[3 * p + c], (c + 1) * La, 1e-5 * (c + 1) * La);
        }
    EXPECT_EQ(r.stats.supersampled_pixels, 0);  // a plane has no depth discontinuity
}

// Cycles' clip range: fog from the near plane (attenuated from there, not from the eye),
// surfaces beyond the far plane unseen. Reference: GK quadrature of eq. 5 from the moved
// origin o' = o + (clip_start / cos) d.
TEST(Bake, ClipRangeMatchesQuadratureFromNearPlane) {
    SceneDescription scene = test_scene();
    scene.camera.clip_start = 2.5;
    scene.camera.clip_end = 7.0;  // the plane at view depth 6 stays visible
    BakeSettings settings;
    settings.aa_samples = 1;
    settings.model = ModelId::Sun05Exact;
    BakeResult r = bake(scene, settings);
    const CameraRays rays(scene.camera);
    const Vec3 s = scene.point_lights[0].position;
    for (int j = 0; j < 30; j += 7)
        for (int i = 0; i < 40; i += 5) {
            Ray ray = rays(i + 0.5, j + 0.5);
            const double cos_view = -ray.d.z, t_near = 2.5 / cos_view, Dvp = 6.0 / cos_view;
            const size_t p = size_t(j) * 40 + i;
            EXPECT_NEAR(r.depth[p], Dvp, 1e-5 * Dvp);  // still from the eye
            EXPECT_NEAR(r.transmittance[3 * p], std::exp(-0.1 * (Dvp - t_near)), 1e-6);
            const Vec3 o = ray.o + t_near * ray.d, sv = s - o;
            const double La = sun05_airlight_quadrature(0.1, glm::length(sv), glm::dot(ray.d, sv) / glm::length(sv),
                                                        Dvp - t_near, 1e-10);
            EXPECT_NEAR(r.airlight[3 * p], La, 1e-5 * La);
        }
    // A far plane nearer than the surface hides it: misses, fog out to infinity, T = 0.
    scene.camera.clip_end = 5.0;
    BakeResult far = bake(scene, settings);
    for (int j = 0; j < 30; j += 7)
        for (int i = 0; i < 40; i += 5) {
            Ray ray = rays(i + 0.5, j + 0.5);
            const double t_near = 2.5 / -ray.d.z;
            const size_t p = size_t(j) * 40 + i;
            EXPECT_TRUE(std::isinf(far.depth[p]));
            EXPECT_EQ(far.transmittance[3 * p], 0.0f);
            const Vec3 sv = s - (ray.o + t_near * ray.d);
            const double La = sun05_airlight_quadrature(0.1, glm::length(sv), glm::dot(ray.d, sv) / glm::length(sv),
                                                        std::numeric_limits<double>::infinity(), 1e-10);
            EXPECT_NEAR(far.airlight[3 * p], La, 1e-5 * La);
        }
    scene.camera.clip_end = 2.0;  // <= clip_start
    EXPECT_THROW(bake(scene, settings), std::invalid_argument);
}

// The table model's one-evaluation near-plane path (sun05_geometry_shift in the SIMD
// batch), with the light beyond the near plane and between the eye and the near plane
// (where the old difference La(eye, t1) - La(eye, t0) was weakest), against quadrature
// from the near point (measured max 4e-5; bound 1e-3, the table p99 in sun05_batch_test.cpp).
TEST(Bake, TableModelFromNearPlaneMatchesQuadrature) {
    for (double clip_start : {2.5, 4.0}) {  // the light is at view depth 3
        SceneDescription scene = test_scene();
        scene.camera.clip_start = clip_start;
        scene.camera.clip_end = 7.0;
        BakeSettings settings;
        settings.aa_samples = 1;
        BakeResult r = bake(scene, settings);
        const CameraRays rays(scene.camera);
        const Vec3 s = scene.point_lights[0].position;
        double worst = 0.0;
        for (int j = 0; j < 30; j += 3)
            for (int i = 0; i < 40; i += 3) {
                Ray ray = rays(i + 0.5, j + 0.5);
                const double cos_view = -ray.d.z, t_near = clip_start / cos_view, Dvp = 6.0 / cos_view;
                const size_t p = size_t(j) * 40 + i;
                EXPECT_NEAR(r.transmittance[3 * p], std::exp(-0.1 * (Dvp - t_near)), 1e-6);
                const Vec3 sv = s - (ray.o + t_near * ray.d);
                const double La = sun05_airlight_quadrature(0.1, glm::length(sv),
                                                            glm::dot(ray.d, sv) / glm::length(sv), Dvp - t_near, 1e-10);
                worst = std::max(worst, std::abs(r.airlight[3 * p] / La - 1));
                EXPECT_NEAR(r.airlight[3 * p], La, 1e-3 * La) << clip_start << " " << i << " " << j;
            }
        std::printf("table model from the near plane at view depth %g: max rel %.3g vs quadrature\n", clip_start,
                    worst);
    }
}

// Anisotropic media: the biri06 model (Gamma table of the medium's phase) and the
// quadrature model (phase-aware) per pixel against phase_airlight_quadrature from the
// near point, for each phase kind, a light in the frame (forward lobe visible) and one
// outside, with the near plane before and beyond the in-frame light (view depth 4).
// Bounds: the table's measured error (biri06.cpp: max 8.9e-4 for smooth lobes, up to
// 6e-3 for HG |g| >= 0.95), the quadrature model's tolerance 1e-8 plus float32 output
// and near distances (measured 7.5e-7).
TEST(Bake, PhaseModelsMatchPhaseQuadrature) {
    struct Case {
        PhaseFunction phase;
        double bound;
    };
    const Case cases[] = {
        {{PhaseKind::HenyeyGreenstein, 0.6}, 1e-3},  {{PhaseKind::HenyeyGreenstein, -0.4}, 1e-3},
        {{PhaseKind::HenyeyGreenstein, 0.95}, 6e-3}, {{PhaseKind::Rayleigh, 0.0}, 1e-3},
        {{PhaseKind::HazyMie, 0.0}, 1e-3},           {{PhaseKind::MurkyMie, 0.0}, 1e-3},
    };
    for (double clip_start : {0.0, 2.5, 5.0})
        for (const Case& c : cases) {
            SceneDescription scene = test_scene();
            scene.point_lights.push_back({Vec3(0.5, 0.3, -4.0), RGB(2.0, 1.0, 0.5)});
            scene.medium.phase = c.phase;
            scene.medium.albedo = RGB(0.9, 0.8, 0.7);
            scene.camera.clip_start = clip_start;
            BakeSettings settings;
            settings.aa_samples = 1;
            settings.model = ModelId::Biri06;
            BakeResult r = bake(scene, settings);
            settings.model = ModelId::Quadrature;
            BakeResult q = bake(scene, settings);
            const CameraRays rays(scene.camera);
            double worst = 0.0, worst_q = 0.0, sum = 0.0;
            int n = 0;
            for (int j = 0; j < 30; j += 2)
                for (int i = 0; i < 40; i += 2) {
                    const Ray ray = rays(i + 0.5, j + 0.5);
                    const double cos_view = -ray.d.z, t_near = clip_start / cos_view, Dvp = 6.0 / cos_view;
                    const Vec3 o = ray.o + t_near * ray.d;
                    const size_t p = size_t(j) * 40 + i;
                    EXPECT_NEAR(r.transmittance[3 * p], std::exp(-0.1 * (Dvp - t_near)), 1e-6);
                    RGB La(0.0);
                    for (const PointLight& light : scene.point_lights) {
                        const Vec3 sv = light.position - o;
                        const double Dsv = glm::length(sv);
                        La += light.I0 * scene.medium.albedo *
                              phase_airlight_quadrature(c.phase, 0.1, Dsv, glm::dot(ray.d, sv) / Dsv, Dvp - t_near,
                                                        1e-11);
                    }
                    for (int k = 0; k < 3; ++k) {
                        const double e = std::abs(r.airlight[3 * p + k] / La[k] - 1);
                        worst = std::max(worst, e);
                        sum += e, ++n;
                        worst_q = std::max(worst_q, std::abs(q.airlight[3 * p + k] / La[k] - 1));
                    }
                }
            std::printf("biri06 bake vs phase quadrature, %s g=%g clip_start %g: mean rel %.2g max %.2g "
                        "(quadrature model max %.2g)\n",
                        phase_name(c.phase.kind), c.phase.g, clip_start, sum / n, worst, worst_q);
            EXPECT_LE(worst, c.bound) << phase_name(c.phase.kind) << " g=" << c.phase.g << " near " << clip_start;
            EXPECT_LE(worst_q, 5e-6) << phase_name(c.phase.kind) << " g=" << c.phase.g << " near " << clip_start;
        }
}

// The Sun 2005 models are isotropic only: an anisotropic phase is refused, HG g = 0 is
// the isotropic phase (same image), and biri06 with the isotropic phase agrees with sun05.
TEST(Bake, PhaseSupportPerModel) {
    SceneDescription scene = test_scene();
    BakeSettings settings;
    settings.aa_samples = 1;
    BakeResult iso = bake(scene, settings);
    scene.medium.phase = {PhaseKind::HenyeyGreenstein, 0.0};
    BakeResult hg0 = bake(scene, settings);
    EXPECT_EQ(iso.airlight, hg0.airlight);
    for (ModelId model : {ModelId::Sun05Table, ModelId::Sun05Exact}) {
        settings.model = model;
        for (PhaseFunction phase : {PhaseFunction{PhaseKind::HenyeyGreenstein, 0.3}, PhaseFunction{PhaseKind::Rayleigh, 0.0}}) {
            scene.medium.phase = phase;
            try {
                bake(scene, settings);
                ADD_FAILURE() << "sun05 accepted an anisotropic phase";
            } catch (const std::invalid_argument& e) {
                EXPECT_NE(std::string(e.what()).find("biri06"), std::string::npos) << e.what();
            }
        }
    }
    scene.medium.phase = {PhaseKind::HenyeyGreenstein, 1.0};
    settings.model = ModelId::Biri06;
    EXPECT_THROW(bake(scene, settings), std::invalid_argument);
    scene.medium.phase = {};
    BakeResult biri = bake(scene, settings);
    for (size_t p = 0; p < iso.airlight.size(); ++p)
        EXPECT_NEAR(biri.airlight[p], iso.airlight[p], 2e-3 * iso.airlight[p]);
}

TEST(Bake, ThreadCountDoesNotChangeTheResult) {
    SceneDescription scene = test_scene();
    scene.geometry = square(-6.0, 3.0);  // silhouette edges: supersampling runs too
    BakeSettings one, many;
    one.threads = 1;
    many.threads = 3;
    BakeResult a = bake(scene, one), b = bake(scene, many);
    EXPECT_GT(a.stats.supersampled_pixels, 0);
    EXPECT_EQ(a.airlight, b.airlight);
    EXPECT_EQ(a.transmittance, b.transmittance);
}

TEST(Bake, ValidatesInput) {
    BakeSettings settings;
    SceneDescription scene = test_scene();
    scene.camera.width = 0;
    EXPECT_THROW(bake(scene, settings), std::invalid_argument);
    scene = test_scene();
    scene.medium.sigma_t = std::nan("");
    EXPECT_THROW(bake(scene, settings), std::invalid_argument);
    scene = test_scene();
    scene.point_lights[0].I0.y = -1.0;
    EXPECT_THROW(bake(scene, settings), std::invalid_argument);
    scene = test_scene();
    scene.geometry.vertices[4] = std::numeric_limits<float>::infinity();
    EXPECT_THROW(bake(scene, settings), std::invalid_argument);
}

TEST(Bake, ProgressIsMonotoneAndCancels) {
    SceneDescription scene = test_scene(64, 100);
    std::vector<double> seen;
    bake(scene, BakeSettings{}, [&](double f) {
        seen.push_back(f);
        return true;
    });
    ASSERT_GE(seen.size(), 3u);
    for (size_t i = 1; i < seen.size(); ++i) EXPECT_GE(seen[i], seen[i - 1]);
    EXPECT_EQ(seen.back(), 1.0);
    EXPECT_THROW(bake(scene, BakeSettings{}, [](double f) { return f < 0.5; }), Cancelled);
}

// Gaussian fog (Fogshop): thin smooth fog of broad Gaussians over a background sigma_t,
// a floor in the lower half of the image (upper half: misses, fog to infinity), two lights
// outside the cloud, near plane at view depth 0.5. Reference per pixel centre: the exact
// transmittance exp(-optical depth over all Gaussians, unculled) from the near point to
// the hit, and the airlight by gaussian_airlight_quadrature from the near point. Bounds: the
// Fogshop approximation's thin-fog bound from gaussian/airlight_test.cpp (mean 1 %, p99 3 %),
// the transmittance to 1e-6 (float output, culling <= 1e-7 per Gaussian), the bake's
// quadrature model to 1e-6 relative (tolerance 1e-8 plus float output).
SceneDescription gaussian_scene(double amplitude_scale) {
    SceneDescription scene;
    const int W = 32, H = 24;
    scene.camera = test_camera(glm::dmat4(1.0), blender_perspective(kPi / 3, W, H), W, H);
    scene.camera.clip_start = 0.5;
    scene.medium.sigma_t = 0.01;
    scene.medium.albedo = RGB(0.9, 0.8, 0.7);
    std::mt19937_64 rng(5);
    std::uniform_real_distribution<double> U(0.0, 1.0);
    for (int i = 0; i < 12; ++i) {
        scene.gaussians.centres.insert(scene.gaussians.centres.end(),
                                       {16.0 * U(rng) - 8.0, 4.0 * U(rng) - 2.0, -(20.0 + 16.0 * U(rng))});
        scene.gaussians.scales.push_back(0.15 + 0.15 * U(rng));
        scene.gaussians.amplitudes.push_back(amplitude_scale * (0.02 + 0.04 * U(rng)));
    }
    scene.point_lights.push_back({Vec3(4.0, 30.0, -28.0), RGB(100.0, 80.0, 60.0)});
    scene.point_lights.push_back({Vec3(-20.0, 10.0, -5.0), RGB(30.0, 30.0, 40.0)});
    // Floor y = -3 from z = +1 to z = -200.
    scene.geometry.vertices = {-300, -3, 1, 300, -3, 1, 300, -3, -200, -300, -3, -200};
    scene.geometry.triangles = {0, 1, 2, 0, 2, 3};
    return scene;
}

GaussianMedium medium_of(const SceneDescription& scene) {
    return GaussianMedium(scene.gaussians.centres, scene.gaussians.scales, scene.gaussians.amplitudes,
                     scene.medium.sigma_t);
}

TEST(BakeGaussians, FogshopAndTransmittanceMatchReferences) {
    const SceneDescription scene = gaussian_scene(0.01);
    BakeSettings settings;
    settings.aa_samples = 1;
    const BakeResult r = bake(scene, settings);
    settings.model = ModelId::Quadrature;
    const BakeResult q = bake(scene, settings);
    const GaussianMedium m = medium_of(scene);
    const CameraRays rays(scene.camera);
    std::vector<double> err;
    double worst_T = 0.0, worst_q = 0.0, gauss_share = 0.0;
    int hits = 0, misses = 0;
    for (int j = 0; j < 24; ++j)
        for (int i = 0; i < 32; ++i) {
            const Ray ray = rays(i + 0.5, j + 0.5);
            double t_near, t_far;
            rays.clip_range(ray, t_near, t_far);
            const size_t p = size_t(j) * 32 + i;
            const double depth = r.depth[p];
            std::isinf(depth) ? ++misses : ++hits;
            const Vec3 o = ray.o + t_near * ray.d;
            const double T = std::isinf(depth) ? m.optical_depth_all_ray(o, ray.d, depth)
                                               : m.optical_depth_all(o, ray.o + depth * ray.d);
            gauss_share = std::max(gauss_share, T - scene.medium.sigma_t * (depth - t_near));
            for (int c = 0; c < 3; ++c) EXPECT_NEAR(r.transmittance[3 * p + c], std::exp(-T), 1e-6) << i << " " << j;
            worst_T = std::max(worst_T, std::abs(double(r.transmittance[3 * p]) - std::exp(-T)));
            RGB ref(0.0);
            for (const PointLight& light : scene.point_lights)
                ref += scene.medium.albedo * light.I0 *
                       gaussian_airlight_quadrature(m, light.position, o, ray.d, depth - t_near, 1e-10);
            for (int c = 0; c < 3; ++c) {
                err.push_back(std::abs(r.airlight[3 * p + c] / ref[c] - 1.0));
                EXPECT_NEAR(q.airlight[3 * p + c], ref[c], 1e-6 * ref[c]) << i << " " << j;
                worst_q = std::max(worst_q, std::abs(q.airlight[3 * p + c] / ref[c] - 1.0));
                // The Fogshop models splat in float (gaussian/splat.h), the quadrature model sums
                // in double: both within 1e-6 of the exact transmittance (checked above).
                EXPECT_NEAR(q.transmittance[3 * p + c], r.transmittance[3 * p + c], 1e-6);
            }
        }
    EXPECT_GT(hits, 100);
    EXPECT_GT(misses, 100);
    // The Gaussians matter here (else the test would only check the background).
    EXPECT_GT(gauss_share, 0.01);
    double mean = 0.0;
    for (double e : err) mean += e;
    mean /= double(err.size());
    std::sort(err.begin(), err.end());
    const double p99 = err[size_t(0.99 * double(err.size()))];
    std::printf("[ bake gaussians ] fogshop vs quadrature: mean %.4f p99 %.4f max %.4f; quadrature model max %.2g; "
                "transmittance max abs %.2g; Gaussian optical depth up to %.3f\n",
                mean, p99, err.back(), worst_q, worst_T, gauss_share);
    EXPECT_LT(mean, 0.01);
    EXPECT_LT(p99, 0.03);
}

// Supersampled edges, threads and an orthographic camera go through the same path.
TEST(BakeGaussians, OrthographicAndSupersampledAreFinite) {
    SceneDescription scene = gaussian_scene(0.25);
    // A wall at z = -50 behind the cloud (the orthographic rays run parallel to the floor).
    scene.geometry.vertices.insert(scene.geometry.vertices.end(), {-300, -300, -50, 300, -300, -50, 300, 300, -50, -300, 300, -50});
    scene.geometry.triangles.insert(scene.geometry.triangles.end(), {4, 5, 6, 4, 6, 7});
    BakeSettings settings;
    settings.model = ModelId::Sun05Exact;
    const BakeResult persp = bake(scene, settings);
    EXPECT_GT(persp.stats.supersampled_pixels, 0);
    scene.camera.projection = glm::ortho(-10.0, 10.0, -7.5, 7.5, 0.1, 100.0);
    const BakeResult ortho = bake(scene, settings);
    for (const BakeResult* r : {&persp, &ortho})
        for (size_t k = 0; k < r->airlight.size(); ++k) {
            ASSERT_TRUE(std::isfinite(r->airlight[k]) && r->airlight[k] >= 0.0f) << k;
            ASSERT_TRUE(r->transmittance[k] >= 0.0f && r->transmittance[k] <= 1.0f) << k;
        }
    // Orthographic centre pixel: rays start on the near plane; T from there to the hit.
    const CameraRays rays(scene.camera);
    const GaussianMedium m = medium_of(scene);
    for (int j : {4, 12, 20}) {
        const Ray ray = rays(16.5, j + 0.5);
        double t_near, t_far;
        rays.clip_range(ray, t_near, t_far);
        const size_t p = size_t(j) * 32 + 16;
        ASSERT_FALSE(std::isinf(ortho.depth[p]));
        EXPECT_NEAR(ortho.transmittance[3 * p],
                    std::exp(-m.optical_depth_all(ray.o + t_near * ray.d, ray.o + double(ortho.depth[p]) * ray.d)),
                    1e-6);
    }
}

TEST(BakeGaussians, RejectsBadInput) {
    BakeSettings settings;
    SceneDescription scene = gaussian_scene(0.01);
    scene.gaussians.scales[3] = 0.0;
    EXPECT_THROW(bake(scene, settings), std::invalid_argument);
    scene = gaussian_scene(0.01);
    scene.gaussians.amplitudes.pop_back();
    EXPECT_THROW(bake(scene, settings), std::invalid_argument);
    scene = gaussian_scene(0.01);
    scene.gaussians.centres[4] = std::nan("");
    EXPECT_THROW(bake(scene, settings), std::invalid_argument);
    // (Anisotropic phases, biri06 / pegoraro10, spots and suns with Gaussians are accepted:
    // tests/native/test_bake_gaussians_lights.py.) Hoffman-Preetham daylight takes none.
    scene = gaussian_scene(0.01);
    scene.point_lights.clear();
    settings.model = ModelId::Hoffman02;
    try {
        bake(scene, settings);
        ADD_FAILURE() << "hoffman02 with Gaussians accepted";
    } catch (const std::invalid_argument& e) {
        EXPECT_NE(std::string(e.what()).find("fog objects"), std::string::npos) << e.what();
    }
}

}  // namespace
}  // namespace airlight
