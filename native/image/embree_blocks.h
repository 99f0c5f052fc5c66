// embree_blocks.h: Embree scenes of a triangle soup whose objects keep their BVHs from one
// scene to the next. A bake's soup is its objects one after another, each indexing only its
// own vertices; a frame in which one object moved differs from the last one in that object
// only. The soup is cut into blocks at those seams (soup_blocks), each block is an Embree
// scene of its own (its BVH), and a soup of several blocks is a scene of identity instances of
// them (Embree 3's two-level traversal: the same hits, at the cost of a second level). A
// BlockCache keeps the blocks of the last soup it was given and compares the next soup's
// blocks with them exactly, so a moved object rebuilds its block's BVH and the instances over
// the blocks, not every BVH.
#pragma once

#include <embree3/rtcore.h>

#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <vector>

namespace airlight {

// A run of a soup's triangles [tri_begin, tri_end) that indexes only the vertices
// [vertex_begin, vertex_end).
struct SoupBlock {
    size_t tri_begin = 0, tri_end = 0;
    uint32_t vertex_begin = 0, vertex_end = 0;
    bool operator==(const SoupBlock& o) const {
        return tri_begin == o.tri_begin && tri_end == o.tri_end && vertex_begin == o.vertex_begin &&
               vertex_end == o.vertex_end;
    }
};

// The soup cut before every triangle whose indices and those after it are all above every
// index before it (the seams between objects) into runs; a run of _min_triangles_ or more is a
// block, and the runs between such join in order into blocks of at least _min_triangles_ (the
// last of them may have fewer). Indices need not be in range.
std::vector<SoupBlock> soup_blocks(const uint32_t* triangles, size_t n_triangles, size_t min_triangles);

// A copy of one block of a soup, to find it in the next soup: its vertices and its triangles
// (indices into its own vertices).
struct SoupCopy {
    std::vector<float> vertices;
    std::vector<uint32_t> triangles;
    uint64_t hash = 0;
    SoupCopy() = default;
    SoupCopy(const float* soup_vertices, const uint32_t* soup_triangles, const SoupBlock& b, uint64_t hash);
    // Whether this is exactly _b_ of the soup.
    bool equals(const float* soup_vertices, const uint32_t* soup_triangles, const SoupBlock& b) const;
};

// A hash of block _b_ of the soup (its vertices' bits and its triangles as offsets).
uint64_t block_hash(const float* vertices, const uint32_t* triangles, const SoupBlock& b);

// For each block _cuts_[b] of the soup, the index of a copy in _kept_ equal to it, or -1 (each
// copy matches once): the copy in the same place is compared first (an unchanged object:
// no hash to compute), then those of the same hash. _hashes_ gets each block's hash.
std::vector<long> match_blocks(const std::vector<const SoupCopy*>& kept, const float* vertices,
                               const uint32_t* triangles, const std::vector<SoupBlock>& cuts,
                               std::vector<uint64_t>& hashes);

// The Embree device of every block and of the scenes that instance them (instances must
// share their scenes' device), made on first use and never released.
RTCDevice blocks_device();

// A robust Embree scene on blocks_device() of _n_triangles_ triangles (3 indices each) over
// _n_vertices_ vertices (3 floats each) that it reads where they are: both arrays must outlive
// it, and the vertices' have room for a float past the last (Embree reads 16 bytes at the last
// vertex). _filter_ (optional): the geometry's intersect filter. Throws std::runtime_error
// when Embree fails.
RTCScene new_block_scene(const float* vertices, size_t n_vertices, const uint32_t* triangles, size_t n_triangles,
                         RTCBuildQuality quality, RTCFilterFunctionN filter = nullptr);
// The scene over _scenes_ (of blocks_device()): null for none, the one scene (retained) for
// one, else identity instances of them, instance k of scenes[k] with ray mask masks[k] (if
// given: then instances of one scene too). Embree's transform of a ray by them is exact, and
// costs nothing measurable. Release it with rtcReleaseScene.
RTCScene new_instance_scene(const std::vector<RTCScene>& scenes, const std::vector<unsigned>& masks = {});
// Commits _scene_ (of blocks_device()) and returns it, or releases it and throws
// std::runtime_error ("Embree: _what_: ...") when Embree reported an error.
RTCScene committed(RTCScene scene, const char* what);

// The scene of one soup: its blocks' scenes, or the instances over them.
class BlockedScene {
  public:
    ~BlockedScene();
    BlockedScene(const BlockedScene&) = delete;
    BlockedScene& operator=(const BlockedScene&) = delete;
    // Null for a soup without triangles (every ray misses).
    RTCScene scene() const { return scene_; }
    size_t blocks() const { return blocks_.size(); }

  private:
    friend class BlockCache;
    struct Block;
    BlockedScene() = default;
    RTCScene scene_ = nullptr;
    std::vector<std::shared_ptr<const Block>> blocks_;
};

class BlockCache {
  public:
    // Blocks join runs of the soup up to this many triangles: a moved object rebuilds this
    // many at least (~10 ms), and a scene of 1e5 small objects has at most n / this instances.
    static constexpr size_t kMinBlockTriangles = size_t(1) << 15;

    // _quality_: the blocks' BVHs'.
    explicit BlockCache(RTCBuildQuality quality);
    ~BlockCache();
    BlockCache(const BlockCache&) = delete;
    BlockCache& operator=(const BlockCache&) = delete;

    // The scene of the soup (3 floats a vertex, 3 indices a triangle; throws
    // std::invalid_argument on an index past n_vertices), its blocks shared with the last soup's where they are equal
    // (vertices and triangles compared exactly, as offsets into their own vertices), the same
    // BlockedScene when every block is. The blocks of the last soup that this one does not
    // share are dropped before any is built. Thread safe. Throws std::runtime_error when Embree
    // fails.
    // _before_build_ (optional) is called before that, when the soup is not the last one:
    // for the caller to let go of what holds the last soup's blocks.
    std::shared_ptr<const BlockedScene> scene(const float* vertices, size_t n_vertices, const uint32_t* triangles,
                                              size_t n_triangles, const std::function<void()>& before_build = {});
    // Drops the kept blocks and scene.
    void clear();
    // Blocks built so far (those not shared), for tests and the stats.
    long blocks_built() const;

  private:
    RTCBuildQuality quality_;
    mutable std::mutex mutex_;
    std::vector<std::shared_ptr<const BlockedScene::Block>> kept_;  // the last soup's blocks
    std::shared_ptr<const BlockedScene> last_;
    long built_ = 0;
};

}  // namespace airlight
