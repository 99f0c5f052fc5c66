// embree_blocks.cpp: see embree_blocks.h.
#include "image/embree_blocks.h"

#include <algorithm>
#include <cstring>
#include <limits>
#include <stdexcept>
#include <string>

namespace airlight {

namespace {

// The first error Embree reported on the blocks' device since the last take().
struct DeviceErrors {
    std::mutex mutex;
    std::string message;
    std::string take() {
        std::lock_guard<std::mutex> lock(mutex);
        std::string out;
        out.swap(message);
        return out;
    }
};

DeviceErrors& device_errors() {
    static DeviceErrors errors;
    return errors;
}

void record_error(void*, RTCError code, const char* str) {
    DeviceErrors& errors = device_errors();
    std::lock_guard<std::mutex> lock(errors.mutex);
    if (errors.message.empty())
        errors.message = std::string(str ? str : "unknown error") + " (code " + std::to_string(int(code)) + ")";
}

}  // namespace

// (Never released: kept scenes outlive main() in static caches.)
RTCDevice blocks_device() {
    static RTCDevice device = [] {
        RTCDevice d = rtcNewDevice(nullptr);
        if (!d)
            throw std::runtime_error("Embree: rtcNewDevice failed (error " +
                                     std::to_string(int(rtcGetDeviceError(nullptr))) + ")");
        rtcSetDeviceErrorFunction(d, record_error, nullptr);
        return d;
    }();
    return device;
}

namespace {

uint64_t mix(uint64_t h, uint32_t word) {
    h ^= word;
    h *= 0x100000001B3ull;  // FNV-1a's prime, on whole words
    return h;
}

}  // namespace

// One block: its vertices and triangles (indices into its own vertices) and their BVH.
struct BlockedScene::Block {
    SoupCopy copy;
    RTCScene scene = nullptr;
    ~Block() {
        if (scene) rtcReleaseScene(scene);
    }
};

SoupCopy::SoupCopy(const float* soup_vertices, const uint32_t* soup_triangles, const SoupBlock& b, uint64_t h)
    : vertices(soup_vertices + 3 * size_t(b.vertex_begin), soup_vertices + 3 * size_t(b.vertex_end)),
      triangles(3 * (b.tri_end - b.tri_begin)), hash(h) {
    const uint32_t* t = soup_triangles + 3 * b.tri_begin;
    for (size_t k = 0; k < triangles.size(); ++k) triangles[k] = t[k] - b.vertex_begin;
}

bool SoupCopy::equals(const float* soup_vertices, const uint32_t* soup_triangles, const SoupBlock& b) const {
    const size_t nv = size_t(b.vertex_end - b.vertex_begin), nt = b.tri_end - b.tri_begin;
    if (vertices.size() != 3 * nv || triangles.size() != 3 * nt) return false;
    if (std::memcmp(vertices.data(), soup_vertices + 3 * size_t(b.vertex_begin), 3 * nv * sizeof(float)) != 0)
        return false;
    const uint32_t* t = soup_triangles + 3 * b.tri_begin;
    for (size_t k = 0; k < 3 * nt; ++k)
        if (triangles[k] != t[k] - b.vertex_begin) return false;
    return true;
}

uint64_t block_hash(const float* vertices, const uint32_t* triangles, const SoupBlock& b) {
    uint64_t h = 0xCBF29CE484222325ull;
    h = mix(h, b.vertex_end - b.vertex_begin);
    h = mix(h, uint32_t(b.tri_end - b.tri_begin));
    const float* v = vertices + 3 * size_t(b.vertex_begin);
    for (size_t k = 0; k < 3 * size_t(b.vertex_end - b.vertex_begin); ++k) {
        uint32_t bits;
        std::memcpy(&bits, v + k, sizeof(bits));
        h = mix(h, bits);
    }
    const uint32_t* t = triangles + 3 * b.tri_begin;
    for (size_t k = 0; k < 3 * (b.tri_end - b.tri_begin); ++k) h = mix(h, t[k] - b.vertex_begin);
    return h;
}

std::vector<long> match_blocks(const std::vector<const SoupCopy*>& kept, const float* vertices,
                               const uint32_t* triangles, const std::vector<SoupBlock>& cuts,
                               std::vector<uint64_t>& hashes) {
    std::vector<long> match(cuts.size(), -1);
    hashes.assign(cuts.size(), 0);
    std::vector<char> used(kept.size(), 0);
    for (size_t b = 0; b < cuts.size(); ++b) {
        if (b < kept.size() && kept[b]->equals(vertices, triangles, cuts[b])) {
            match[b] = long(b);
            hashes[b] = kept[b]->hash;
            used[b] = 1;
            continue;
        }
        hashes[b] = block_hash(vertices, triangles, cuts[b]);
        for (size_t k = 0; k < kept.size(); ++k)
            if (!used[k] && kept[k]->hash == hashes[b] && kept[k]->equals(vertices, triangles, cuts[b])) {
                match[b] = long(k);
                used[k] = 1;
                break;
            }
    }
    return match;
}

std::vector<SoupBlock> soup_blocks(const uint32_t* triangles, size_t n_triangles, size_t min_triangles) {
    std::vector<SoupBlock> out;
    if (n_triangles == 0) return out;
    auto tri_min = [&](size_t k) { return std::min({triangles[3 * k], triangles[3 * k + 1], triangles[3 * k + 2]}); };
    auto tri_max = [&](size_t k) { return std::max({triangles[3 * k], triangles[3 * k + 1], triangles[3 * k + 2]}); };
    // The seams: before triangle k when all its indices are above every earlier one (the
    // candidates, a forward pass), and so are all the later ones (their smallest index at
    // each candidate, a backward pass). (No array per triangle: the 1e7 triangles of a heavy
    // scene cost 40 MB zeroed a bake.)
    std::vector<size_t> candidates;
    std::vector<uint32_t> earlier_max;  // per candidate: the largest index before it
    uint32_t seen_max = tri_max(0);
    for (size_t k = 1; k < n_triangles; ++k) {
        if (tri_min(k) > seen_max) candidates.push_back(k), earlier_max.push_back(seen_max);
        seen_max = std::max(seen_max, tri_max(k));
    }
    std::vector<char> seam(candidates.size(), 0);
    uint32_t later_min = std::numeric_limits<uint32_t>::max();
    for (size_t k = n_triangles, c = candidates.size(); k-- > 0 && c > 0;) {
        later_min = std::min(later_min, tri_min(k));
        if (candidates[c - 1] == k) --c, seam[c] = earlier_max[c] < later_min;
    }
    // The runs between seams.
    std::vector<SoupBlock> runs;
    SoupBlock run{0, 0, tri_min(0), tri_max(0)};
    for (size_t k = 1, c = 0; k <= n_triangles; ++k) {
        while (c < candidates.size() && candidates[c] < k) ++c;
        if (k == n_triangles || (c < candidates.size() && candidates[c] == k && seam[c])) {
            run.tri_end = k;
            run.vertex_end += 1;  // (it held the largest index)
            runs.push_back(run);
            if (k < n_triangles) run = SoupBlock{k, 0, tri_min(k), tri_max(k)};
            continue;
        }
        run.vertex_begin = std::min(run.vertex_begin, tri_min(k));
        run.vertex_end = std::max(run.vertex_end, tri_max(k));
    }
    // A run of min_triangles or more is a block; the runs between such join into blocks of at
    // least min_triangles (a small object's block is not a large neighbour's).
    auto size = [](const SoupBlock& r) { return r.tri_end - r.tri_begin; };
    bool open = false;
    for (const SoupBlock& r : runs) {
        if (size(r) >= min_triangles) {
            out.push_back(r);
            open = false;
            continue;
        }
        if (open) {
            out.back().tri_end = r.tri_end;
            out.back().vertex_end = r.vertex_end;
        } else {
            out.push_back(r);
            open = true;
        }
        if (size(out.back()) >= min_triangles) open = false;
    }
    return out;
}

RTCScene committed(RTCScene scene, const char* what) {
    rtcCommitScene(scene);
    const std::string message = device_errors().take();
    if (!message.empty()) {
        rtcReleaseScene(scene);
        throw std::runtime_error(std::string("Embree: ") + what + ": " + message);
    }
    return scene;
}

RTCScene new_block_scene(const float* vertices, size_t n_vertices, const uint32_t* triangles, size_t n_triangles,
                         RTCBuildQuality quality, RTCFilterFunctionN filter) {
    const RTCDevice device = blocks_device();
    RTCGeometry g = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
    rtcSetSharedGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, vertices, 0, 3 * sizeof(float),
                               n_vertices);
    rtcSetSharedGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, triangles, 0, 3 * sizeof(uint32_t),
                               n_triangles);
    if (filter) rtcSetGeometryIntersectFilterFunction(g, filter);
    rtcCommitGeometry(g);
    RTCScene scene = rtcNewScene(device);
    rtcSetSceneFlags(scene, RTC_SCENE_FLAG_ROBUST);
    rtcSetSceneBuildQuality(scene, quality);
    rtcAttachGeometry(scene, g);
    rtcReleaseGeometry(g);
    return committed(scene, "building a block of the scene");
}

RTCScene new_instance_scene(const std::vector<RTCScene>& scenes, const std::vector<unsigned>& masks) {
    if (scenes.empty()) return nullptr;
    if (scenes.size() == 1 && masks.empty()) {
        rtcRetainScene(scenes[0]);
        return scenes[0];
    }
    static const float identity[12] = {1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0};  // (column-major 3x4)
    const RTCDevice device = blocks_device();
    RTCScene scene = rtcNewScene(device);
    rtcSetSceneFlags(scene, RTC_SCENE_FLAG_ROBUST);
    for (size_t k = 0; k < scenes.size(); ++k) {
        RTCGeometry g = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_INSTANCE);
        rtcSetGeometryInstancedScene(g, scenes[k]);
        rtcSetGeometryTimeStepCount(g, 1);
        rtcSetGeometryTransform(g, 0, RTC_FORMAT_FLOAT3X4_COLUMN_MAJOR, identity);
        if (!masks.empty()) rtcSetGeometryMask(g, masks[k]);
        rtcCommitGeometry(g);
        rtcAttachGeometryByID(scene, g, unsigned(k));
        rtcReleaseGeometry(g);
    }
    return committed(scene, "building the scene's instances");
}

BlockedScene::~BlockedScene() {
    if (scene_) rtcReleaseScene(scene_);
}

BlockCache::BlockCache(RTCBuildQuality quality) : quality_(quality) {}

BlockCache::~BlockCache() = default;

void BlockCache::clear() {
    std::lock_guard<std::mutex> lock(mutex_);
    last_.reset();
    kept_.clear();
}

long BlockCache::blocks_built() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return built_;
}

std::shared_ptr<const BlockedScene> BlockCache::scene(const float* vertices, size_t n_vertices,
                                                      const uint32_t* triangles, size_t n_triangles,
                                                      const std::function<void()>& before_build) {
    if (n_vertices > size_t(std::numeric_limits<uint32_t>::max()))
        throw std::invalid_argument("Embree blocks: more than 2^32 vertices");
    const std::vector<SoupBlock> cuts = soup_blocks(triangles, n_triangles, kMinBlockTriangles);
    for (size_t k = 0; k < 3 * n_triangles; ++k)
        if (triangles[k] >= n_vertices)
            throw std::invalid_argument("triangle index " + std::to_string(triangles[k]) +
                                        " out of range (vertex count " + std::to_string(n_vertices) + ")");
    std::lock_guard<std::mutex> lock(mutex_);
    // Each block's kept match, if any.
    std::vector<const SoupCopy*> copies;
    for (const auto& block : kept_) copies.push_back(&block->copy);
    std::vector<uint64_t> hashes;
    const std::vector<long> match = match_blocks(copies, vertices, triangles, cuts, hashes);
    std::vector<std::shared_ptr<const BlockedScene::Block>> blocks(cuts.size());
    bool all_kept = last_ && cuts.size() == kept_.size();
    for (size_t b = 0; b < cuts.size(); ++b) {
        if (match[b] >= 0) blocks[b] = kept_[size_t(match[b])];
        all_kept = all_kept && match[b] == long(b);
    }
    if (all_kept) return last_;
    // (The memory of the blocks not shared goes before the new ones are built.)
    if (before_build) before_build();
    last_.reset();
    kept_.clear();
    for (size_t b = 0; b < cuts.size(); ++b) {
        if (blocks[b]) continue;
        const SoupBlock& c = cuts[b];
        auto block = std::make_shared<BlockedScene::Block>();
        const size_t nv = size_t(c.vertex_end - c.vertex_begin), nt = c.tri_end - c.tri_begin;
        block->copy = SoupCopy(vertices, triangles, c, hashes[b]);
        // (Embree reads 16 bytes at the last vertex: the vector's capacity holds 4 floats more.)
        block->copy.vertices.reserve(block->copy.vertices.size() + 4);
        block->scene = new_block_scene(block->copy.vertices.data(), nv, block->copy.triangles.data(), nt, quality_);
        blocks[b] = std::move(block);
        ++built_;
    }
    std::shared_ptr<BlockedScene> out(new BlockedScene());
    out->blocks_ = blocks;
    std::vector<RTCScene> scenes;
    for (const auto& block : blocks) scenes.push_back(block->scene);
    out->scene_ = new_instance_scene(scenes);
    kept_ = std::move(blocks);
    last_ = out;
    return out;
}

}  // namespace airlight
