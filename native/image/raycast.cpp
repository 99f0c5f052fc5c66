// raycast.cpp: first-hit distances with Embree 3 (a robust scene of the mesh's objects: embree_blocks.h).
#include "image/raycast.h"

#include "image/embree_blocks.h"

#include <embree3/rtcore.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <functional>
#include <limits>
#include <mutex>
#include <stdexcept>
#include <string>

namespace airlight {

namespace {

constexpr float kInf = std::numeric_limits<float>::infinity();
constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();

// A ray Embree accepts: finite origin and direction within its FLT_LARGE (1.844e18),
// 0 <= tnear <= tfar (tfar may be inf). Embree asserts on anything else (an abort).
inline bool valid_ray(const float* org, const float* dir, float tnear, float tfar) {
    constexpr float kLarge = 1.8e18f;
    return std::abs(org[0]) < kLarge && std::abs(org[1]) < kLarge && std::abs(org[2]) < kLarge &&
           std::abs(dir[0]) < kLarge && std::abs(dir[1]) < kLarge && std::abs(dir[2]) < kLarge &&
           (dir[0] != 0.0f || dir[1] != 0.0f || dir[2] != 0.0f) && tnear >= 0.0f && tnear <= tfar;
}

}  // namespace

struct RayCaster::Impl {
    std::shared_ptr<const BlockedScene> blocked;  // (its blocks' BVHs may be other casters' too)
    RTCScene scene = nullptr;  // blocked's; null for an empty mesh: every ray misses
    mutable std::atomic<long> invalid{0};  // rays refused by valid_ray (never traced)
};

namespace {

// (The blocks' cache checks every index against the vertices.)
void check_mesh(const TriangleMesh& mesh) {
    if (mesh.vertices.size() % 3 != 0 || mesh.triangles.size() % 3 != 0)
        throw std::invalid_argument("mesh arrays must hold 3 values per vertex / triangle");
}

// The mesh's scene from _cache_ (an object a block: embree_blocks.h), robust (watertight) and
// of high quality: camera rays outnumber the triangles.
std::shared_ptr<const BlockedScene> blocked_scene(const TriangleMesh& mesh, BlockCache& cache,
                                                  const std::function<void()>& before_build = {}) {
    check_mesh(mesh);
    return cache.scene(mesh.vertices.data(), mesh.vertices.size() / 3, mesh.triangles.data(),
                       mesh.triangles.size() / 3, before_build);
}

}  // namespace

RayCaster::RayCaster(const TriangleMesh& mesh) : impl_(new Impl) {
    BlockCache cache(RTC_BUILD_QUALITY_HIGH);
    impl_->blocked = blocked_scene(mesh, cache);
    impl_->scene = impl_->blocked->scene();
}

RayCaster::RayCaster(std::shared_ptr<const BlockedScene> scene) : impl_(new Impl) {
    impl_->blocked = std::move(scene);
    impl_->scene = impl_->blocked->scene();
}

RayCaster::~RayCaster() = default;

long RayCaster::invalid_rays() const { return impl_->invalid.load(); }

namespace {

struct SharedCaster {
    std::mutex mutex;
    BlockCache blocks{RTC_BUILD_QUALITY_HIGH};  // the kept mesh's blocks (compared exactly)
    std::shared_ptr<const RayCaster> caster;
    long builds = 0;
};

SharedCaster& shared_caster() {
    static SharedCaster instance;
    return instance;
}

}  // namespace

std::shared_ptr<const RayCaster> RayCaster::shared(const TriangleMesh& mesh) {
    SharedCaster& kept = shared_caster();
    std::lock_guard<std::mutex> lock(kept.mutex);
    // (The kept caster lets go of its blocks before new ones are built: those not shared go.)
    std::shared_ptr<const BlockedScene> scene = blocked_scene(mesh, kept.blocks, [&] { kept.caster.reset(); });
    if (kept.caster && kept.caster->impl_->blocked == scene) return kept.caster;
    kept.caster.reset(new RayCaster(std::move(scene)));
    ++kept.builds;
    return kept.caster;
}

void RayCaster::clear_shared() {
    SharedCaster& kept = shared_caster();
    std::lock_guard<std::mutex> lock(kept.mutex);
    kept.caster.reset();
    kept.blocks.clear();
}

long RayCaster::shared_builds() {
    SharedCaster& kept = shared_caster();
    std::lock_guard<std::mutex> lock(kept.mutex);
    return kept.builds;
}

long RayCaster::shared_blocks_built() {
    return shared_caster().blocks.blocks_built();
}

double RayCaster::first_hit(const Ray& ray) const {
    if (!impl_->scene) return std::numeric_limits<double>::infinity();
    // Trace one ray with tnear = 0 and an unbounded tfar.
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    RTCRayHit rh;
    rh.ray.org_x = float(ray.o.x);
    rh.ray.org_y = float(ray.o.y);
    rh.ray.org_z = float(ray.o.z);
    rh.ray.dir_x = float(ray.d.x);
    rh.ray.dir_y = float(ray.d.y);
    rh.ray.dir_z = float(ray.d.z);
    rh.ray.tnear = 0.0f;
    rh.ray.tfar = kInf;
    rh.ray.time = 0.0f;
    rh.ray.mask = 0xFFFFFFFFu;
    rh.ray.id = 0;
    rh.ray.flags = 0;
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
    const float org[3] = {rh.ray.org_x, rh.ray.org_y, rh.ray.org_z}, dir[3] = {rh.ray.dir_x, rh.ray.dir_y, rh.ray.dir_z};
    if (!valid_ray(org, dir, rh.ray.tnear, rh.ray.tfar)) {
        ++impl_->invalid;
        return std::numeric_limits<double>::quiet_NaN();
    }
    rtcIntersect1(impl_->scene, &context, &rh);
    if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return std::numeric_limits<double>::infinity();
    return double(rh.ray.tfar);
}

namespace {

// The lanes' fields every packet sets the same way (no motion blur, every geometry, no hit yet).
inline void reset_packet_lanes(RTCRayHit16& rh) {
    for (int k = 0; k < 16; ++k) {
        rh.ray.time[k] = 0.0f;
        rh.ray.mask[k] = 0xFFFFFFFFu;
        rh.ray.id[k] = unsigned(k);
        rh.ray.flags[k] = 0;
        rh.hit.geomID[k] = RTC_INVALID_GEOMETRY_ID;
        rh.hit.instID[0][k] = RTC_INVALID_GEOMETRY_ID;
    }
}

// Traces _n_ rays in coherent packets of 16 (the tail's unused lanes masked off):
// set(i, org, dir, tnear, tfar) fills in ray i (tnear 0 and tfar inf unless set), done(k, i,
// rayhit) reads lane k, ray i's hit.
// Lanes failing valid_ray are masked off, counted in _invalid_ and read back as NaN.
template <typename Set, typename Done>
void trace_packets(RTCScene scene, int n, std::atomic<long>& invalid, Set&& set, Done&& done) {
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    context.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
    for (int base = 0; base < n; base += 16) {
        alignas(64) int valid[16];
        alignas(64) RTCRayHit16 rh;
        reset_packet_lanes(rh);
        for (int k = 0; k < 16; ++k) {
            const bool live = base + k < n;
            const int i = live ? base + k : n - 1;
            valid[k] = live ? -1 : 0;
            float org[3], dir[3], tnear = 0.0f, tfar = kInf;
            set(i, org, dir, tnear, tfar);
            if (live && !valid_ray(org, dir, tnear, tfar)) {
                valid[k] = 0;
                ++invalid;
                org[0] = org[1] = org[2] = 0.0f;
                dir[0] = 1.0f;
                dir[1] = dir[2] = 0.0f;
                tnear = 0.0f;
                tfar = kNaN;  // read back as the lane's "hit"
            }
            rh.ray.org_x[k] = org[0];
            rh.ray.org_y[k] = org[1];
            rh.ray.org_z[k] = org[2];
            rh.ray.dir_x[k] = dir[0];
            rh.ray.dir_y[k] = dir[1];
            rh.ray.dir_z[k] = dir[2];
            rh.ray.tnear[k] = tnear;
            rh.ray.tfar[k] = tfar;
        }
        rtcIntersect16(valid, scene, &context, &rh);
        for (int k = 0; k < 16 && base + k < n; ++k) {
            if (!valid[k]) rh.hit.geomID[k] = 0;  // refused: done() reads tfar = NaN
            done(k, base + k, rh);
        }
    }
}

void ray_arrays(const Ray& ray, float* org, float* dir) {
    org[0] = float(ray.o.x);
    org[1] = float(ray.o.y);
    org[2] = float(ray.o.z);
    dir[0] = float(ray.d.x);
    dir[1] = float(ray.d.y);
    dir[2] = float(ray.d.z);
}

}  // namespace

void RayCaster::first_hits(const Ray* rays, int n, float* t) const {
    if (!impl_->scene) {
        for (int i = 0; i < n; ++i) t[i] = kInf;
        return;
    }
    trace_packets(
        impl_->scene, n, impl_->invalid,
        [&](int i, float* org, float* dir, float&, float&) { ray_arrays(rays[i], org, dir); },
        [&](int k, int i, const RTCRayHit16& rh) {
            t[i] = rh.hit.geomID[k] == RTC_INVALID_GEOMETRY_ID ? kInf : rh.ray.tfar[k];
        });
}

void RayCaster::first_hits(const Vec3& o, const float* dx, const float* dy, const float* dz,
                           const float* t_near, const float* t_far, int n, float* t) const {
    if (!impl_->scene) {
        for (int i = 0; i < n; ++i) t[i] = kInf;
        return;
    }
    // Coherent rays from the shared origin (the bake's pixel rows). The packet is filled
    // with straight loops over its 16 lanes (trace_packets' per-lane callback stayed scalar:
    // ~8 ms CPU of a 1080p bake in setting up and reading back packets).
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    context.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
    const float ox = float(o.x), oy = float(o.y), oz = float(o.z);
    alignas(64) RTCRayHit16 rh;
    alignas(64) int valid[16];
    for (int base = 0; base < n; base += 16) {
        const int m = std::min(16, n - base);
        if (m == 16) {
            for (int k = 0; k < 16; ++k) {
                rh.ray.dir_x[k] = dx[base + k];
                rh.ray.dir_y[k] = dy[base + k];
                rh.ray.dir_z[k] = dz[base + k];
                rh.ray.tnear[k] = t_near[base + k];
                rh.ray.tfar[k] = t_far[base + k];
            }
        } else {  // the tail: unused lanes repeat the last ray, masked off
            for (int k = 0; k < 16; ++k) {
                const int i = base + std::min(k, m - 1);
                rh.ray.dir_x[k] = dx[i];
                rh.ray.dir_y[k] = dy[i];
                rh.ray.dir_z[k] = dz[i];
                rh.ray.tnear[k] = t_near[i];
                rh.ray.tfar[k] = t_far[i];
            }
        }
        reset_packet_lanes(rh);
        int refused = 0;
        for (int k = 0; k < 16; ++k) {
            valid[k] = k < m ? -1 : 0;
            rh.ray.org_x[k] = ox;
            rh.ray.org_y[k] = oy;
            rh.ray.org_z[k] = oz;
            const float org[3] = {ox, oy, oz}, dir[3] = {rh.ray.dir_x[k], rh.ray.dir_y[k], rh.ray.dir_z[k]};
            if (!valid_ray(org, dir, rh.ray.tnear[k], rh.ray.tfar[k])) {
                refused += k < m;
                valid[k] = 0;
                rh.ray.dir_x[k] = 1.0f;
                rh.ray.dir_y[k] = rh.ray.dir_z[k] = 0.0f;
                rh.ray.tnear[k] = 0.0f;
                rh.ray.tfar[k] = 0.0f;
            }
        }
        if (refused) impl_->invalid += refused;
        rtcIntersect16(valid, impl_->scene, &context, &rh);
        float hit_t[16];
        for (int k = 0; k < 16; ++k)
            hit_t[k] = !valid[k]                                   ? kNaN
                       : rh.hit.geomID[k] == RTC_INVALID_GEOMETRY_ID ? kInf
                                                                    : rh.ray.tfar[k];
        for (int k = 0; k < m; ++k) t[base + k] = hit_t[k];
    }
}

void RayCaster::first_hits_normals(const Ray* rays, const float* t_near, const float* t_far, int n, float* t,
                                   float* ng) const {
    if (!impl_->scene) {
        for (int i = 0; i < n; ++i) {
            t[i] = kInf;
            ng[3 * i] = ng[3 * i + 1] = ng[3 * i + 2] = 0.0f;
        }
        return;
    }
    trace_packets(
        impl_->scene, n, impl_->invalid,
        [&](int i, float* org, float* dir, float& tn, float& tf) {
            ray_arrays(rays[i], org, dir);
            tn = t_near[i];
            tf = t_far[i];
        },
        [&](int k, int i, const RTCRayHit16& rh) {
            if (rh.hit.geomID[k] == RTC_INVALID_GEOMETRY_ID) {
                t[i] = kInf;
                ng[3 * i] = ng[3 * i + 1] = ng[3 * i + 2] = 0.0f;
                return;
            }
            t[i] = rh.ray.tfar[k];
            // Embree's Ng comes back unnormalised.
            const double x = rh.hit.Ng_x[k], y = rh.hit.Ng_y[k], z = rh.hit.Ng_z[k];
            const double len = std::sqrt(x * x + y * y + z * z);
            const double inv = len > 0.0 ? 1.0 / len : 0.0;
            ng[3 * i] = float(x * inv);
            ng[3 * i + 1] = float(y * inv);
            ng[3 * i + 2] = float(z * inv);
        });
}

}  // namespace airlight
