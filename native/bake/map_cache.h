// map_cache.h: the light-depth maps of the last bake, kept for the next one. A map depends on
// the Gaussians, the light and its own size and window, not on the camera: the next frame of
// an animation whose fog and lights stand still, or a stereo pair's other eye, takes it as it
// is (a 64-face map of the 3000-Gaussian benchmark cloud takes ~250 ms to build, a quarter of
// that 1080p bake at 1 %). The measured check of a map against exact light depths, which does
// depend on the camera, runs again (FogEvaluator::plan_marches). Thread safe.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

#include "core/scene.h"
#include "gaussian/light_depth_map.h"
#include "gaussian/sun_depth_map.h"

namespace airlight {

// What a map is built from: GaussianMedium::fingerprint, a point or spot light's position s
// and its cone (axis, half angle; a point light's pi), or the direction towards a sun (u), the
// face and radial sizes and the march's window.
struct MapKey {
    std::uint64_t medium = 0;
    bool sun = false;
    Vec3 s{0.0}, axis{0.0}, u{0.0};
    double half_angle = 0.0, window = 0.0;
    int face = 0, radial = 0;
    bool operator==(const MapKey& o) const {
        return medium == o.medium && sun == o.sun && s == o.s && axis == o.axis && u == o.u &&
               half_angle == o.half_angle && window == o.window && face == o.face && radial == o.radial;
    }
};

struct CachedMap {
    MapKey key;
    std::shared_ptr<const LightDepthMap> map;    // points and spots
    std::shared_ptr<const SunDepthMap> sun_map;  // suns
    std::size_t bytes() const { return map ? map->bytes() : sun_map ? sun_map->bytes() : 0; }
};

// The held map built from _key_ (neither pointer set: none).
CachedMap find_cached_map(const MapKey& key);
// Holds _maps_ (a bake's) in place of those held, where together they take at most
// kMapCacheBytes (else none).
void keep_maps(std::vector<CachedMap> maps);
constexpr std::size_t kMapCacheBytes = std::size_t(256) << 20;
// Drops the held maps (their memory goes back to core/buffers.h's pool).
void clear_cached_maps();
// The maps the bakes of this process built (count_map_build: one more), for tests.
long long map_builds();
void count_map_build();

}  // namespace airlight
