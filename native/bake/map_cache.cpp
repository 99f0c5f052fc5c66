// map_cache.cpp: the light-depth maps kept between bakes (map_cache.h).
#include "bake/map_cache.h"

#include <atomic>
#include <mutex>
#include <utility>

namespace airlight {

namespace {
struct MapCache {
    std::mutex mutex;
    std::vector<CachedMap> maps;
    std::atomic<long long> builds{0};
};
MapCache& map_cache() {
    static MapCache* cache = new MapCache;  // never destroyed: nothing to do at exit
    return *cache;
}
}  // namespace

CachedMap find_cached_map(const MapKey& key) {
    MapCache& cache = map_cache();
    std::lock_guard<std::mutex> lock(cache.mutex);
    for (const CachedMap& held : cache.maps)
        if (held.key == key) return held;
    return CachedMap{};
}

void keep_maps(std::vector<CachedMap> maps) {
    std::size_t bytes = 0;
    for (const CachedMap& m : maps) bytes += m.bytes();
    if (bytes > kMapCacheBytes) maps.clear();
    MapCache& cache = map_cache();
    std::vector<CachedMap> dropped;  // (released outside the lock)
    std::lock_guard<std::mutex> lock(cache.mutex);
    dropped.swap(cache.maps);
    cache.maps = std::move(maps);
}

void clear_cached_maps() { keep_maps({}); }

long long map_builds() { return map_cache().builds.load(); }
void count_map_build() { map_cache().builds.fetch_add(1); }

}  // namespace airlight
