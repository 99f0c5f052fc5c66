// block_faces.h: the shadow volumes' faces one block of the casters at a time, kept from one
// build of the volumes to the next (shadow_volumes.h). A block is an object of the casters'
// soup, or small objects joined (image/embree_blocks.h: soup_blocks); its faces for a light
// depend on its own triangles, the light, the extrusion distance R, the volumes' frame and,
// for a sun, the casters' size only. So an object that moved rebuilds its own faces, and the
// other blocks' faces (and their Embree scenes, shadow_volumes.cpp) are shared, not built
// again. Edges are welded within a block: an edge that two blocks share keeps a quad in each,
// whose crossings cancel.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <mutex>
#include <vector>

#include <embree3/rtcore.h>

#include "core/scene.h"
#include "image/embree_blocks.h"
#include "shadow/shadow_volumes.h"

namespace airlight {

// A block's triangles welded by exact position, in the volumes' frame, with their edges
// grouped: what its faces for any light are made of.
struct BlockGeometry {
    std::vector<Vec3> position;       // the welded vertices, in the frame
    std::vector<uint32_t> triangles;  // 3 per triangle, into position
    // Every triangle's directed edges p -> q grouped by undirected edge (u < v), in (u, v)
    // order: vertex u's are uses[use_first[u] .. use_first[u + 1]), each
    // (v << 32) | (triangle << 1) | (p < q).
    std::vector<uint32_t> use_first;
    std::vector<uint64_t> uses;
};

// The geometry of a block's _n_vertices_ vertices (3 floats each) and _n_triangles_ triangles
// (indices into them), less _frame_; the edges sorted on _n_threads_ threads.
BlockGeometry block_geometry(const float* vertices, size_t n_vertices, const uint32_t* triangles,
                             size_t n_triangles, const Vec3& frame, int n_threads);

// Light _light_'s volume (in the frame) of _geometry_'s triangles, extruded to _reach_ (R);
// _extent_: the casters' size (a sun's rings); the block's first _seen_ triangles are the
// camera's (ShadowFaces::n_seen_caps). Its indices are into its own vertices.
ShadowFaces block_faces(const BlockGeometry& geometry, const ShadowLight& light, double reach, double extent,
                        size_t seen);

struct CasterBlocks;

// The blocks of the last volumes built and their faces per light.
class VolumeBlocks {
  public:
    // One kept block.
    struct Block {
        SoupCopy copy;
        std::vector<char> used;  // per vertex of copy: on a triangle with an area
        Vec3 lo{0.0}, hi{-1.0};  // the box of those (the world; empty: none)
        // Per light: the farthest used vertex from it (the frame's coordinates).
        struct Far {
            ShadowLight light;
            Vec3 frame;
            double far;
        };
        std::vector<Far> far;
        // Per light: its faces, for the key's frame, R, extent (suns) and seen count.
        struct Faces {
            ShadowLight light;
            Vec3 frame;
            double reach, extent;
            size_t seen;
            std::shared_ptr<const ShadowFaces> faces;
            long last_use;
        };
        std::vector<Faces> faces;
        // The block's triangles in the floats of the volumes' frame (those of the caps), for the
        // casters' counts (ShadowVolumes::count_at): built for the first volumes of a frame.
        struct Counting {
            Vec3 frame;
            std::vector<float> vertices;
            RTCScene scene = nullptr;  // over vertices and the copy's triangles
            ~Counting();
        };
        std::shared_ptr<const Counting> counting;
        long last_use = 0;
        // Light _light_'s (the frame's coordinates) farthest used vertex (0: none).
        double vertex_far(const ShadowLight& light, const Vec3& frame);
        // The kept faces of that key, or null.
        std::shared_ptr<const ShadowFaces> find(const ShadowLight& light, const Vec3& frame, double reach,
                                                double extent, size_t seen, long use);
    };

    // The blocks of _casters_ (soup_blocks): the kept ones that equal them (image/embree_blocks.h:
    // match_blocks), new ones for the others. Throws std::invalid_argument on a triangle index
    // out of range. Call with mutex() held.
    CasterBlocks blocks(const TriangleMesh& casters);
    // Ends a build: the blocks it did not use and that the one before did not either are
    // dropped, and faces unused in the last kKeptBuilds builds. Call with mutex() held.
    void finish_build();
    long use() const { return use_; }
    void clear();
    // Faces of a block and light, and counting scenes of a block, built so far.
    long faces_built() const { return faces_built_; }
    long counting_built() const { return counting_built_; }
    void count_faces(long n) { faces_built_ += n; }
    void count_counting() { ++counting_built_; }
    std::mutex& mutex() { return mutex_; }
    static constexpr long kKeptBuilds = 8;

  private:
    std::mutex mutex_;
    std::vector<std::shared_ptr<Block>> kept_;
    long use_ = 1, faces_built_ = 0, counting_built_ = 0;
};

// A soup of casters cut into blocks (image/embree_blocks.h: soup_blocks) and each block's kept
// data.
struct CasterBlocks {
    std::vector<SoupBlock> cuts;
    std::vector<std::shared_ptr<VolumeBlocks::Block>> blocks;
};

// The process's kept blocks (ShadowVolumes' builds share them).
VolumeBlocks& volume_blocks();

}  // namespace airlight
