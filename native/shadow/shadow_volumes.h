// shadow_volumes.h: the lit intervals of view rays, for volumetric shadows and light shafts
// (Biri, Arques, Michelin 2006, section III-D, eq. 14: the in-scattering integrated over the
// lit segments of each view ray only).
//
// A point x is lit by a light when the segment from x to the light (for a sun, the half-line
// towards it) crosses no shadow-casting triangle. Every caster triangle shadows the frustum
// behind it as seen from the light (its shadow volume, Crow 1977); the number of those frusta
// that hold x is the number of triangles on the segment x -> light, so x is lit exactly where
// that count is 0. Along a view ray the count changes only where the ray crosses a frustum's
// boundary, so the lit intervals follow from the ray's crossings of the volumes' faces and the
// count at its origin (Heidmann's counting, done along the ray instead of in a stencil buffer):
//   - each triangle's frustum has its triangle as near cap and one quad per edge, the plane
//     through the light and the edge, extruded away from the light to a far distance R;
//   - the quads of an edge shared by two triangles (after welding equal vertex positions) add:
//     between two triangles that face the light the same way they cancel (the ray leaves one
//     frustum and enters the next), at a silhouette they double; so only edges with a nonzero
//     weight become quads (the silhouettes of closed meshes, every edge of an open one);
//   - crossing a quad or cap against its outward normal enters (count + weight), along it exits.
// This is exact for the casters' triangles (no shadow map, no sampling: an occluder of any
// size is seen), for any triangle soup (open, non-manifold or zero-area triangles included;
// a triangle whose plane holds the light, to 1e-6 rad, shadows nothing and is left out). It holds to the
// extrusion distance R (8 times the farthest caster or viewer from the light rounded up to a
// power of 2, clamped to 1e7 times the scene's size): beyond it the count is that at R (a ray
// that far from the light gets ~1/R of its airlight there).
// Queries go to Embree 3 in packets of 16 coherent rays with an intersection filter that
// records every crossing of every light's volumes in one traversal.
#pragma once

#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <vector>

#include "core/scene.h"
#include "image/camera.h"

namespace airlight {

struct CasterBlocks;  // (shadow/block_faces.h)

// A light for the shadow volumes: a point (point and spot lights) or a direction (suns).
struct ShadowLight {
    bool directional = false;
    Vec3 position{0.0};            // point lights
    Vec3 direction{0.0, 0.0, -1.0};  // suns: the unit direction the light travels
};

// The lit intervals of one ray for each light, [a, b] pairs in ray units, sorted.
struct LitIntervals {
    // Per light l: intervals [begin[l], end[l]) of _spans_; fully lit rays have the one span
    // [t0, t1], fully shadowed ones none.
    std::vector<int> begin, end;
    std::vector<std::pair<double, double>> spans;
    // The lights (ShadowVolumes::light_mask bits) not lit all along [t0, t1]: a light whose
    // bit is clear has the one span [t0, t1].
    uint32_t partial = 0;
    // Light _v_ lights [t0, t1] all along: its one span is that segment.
    bool fully_lit(int v, double t0, double t1) const {
        return end[v] - begin[v] == 1 && spans[begin[v]].first == t0 && spans[begin[v]].second == t1;
    }
    // Room for _n_lights_ (the sweep writes every light's begin and end).
    void clear(int n_lights) {
        begin.resize(size_t(n_lights));
        end.resize(size_t(n_lights));
        spans.clear();
        partial = 0;
    }
};

// A crossing of light _light_'s volumes at _t_ along a ray: the count there changes by _dw_.
struct Crossing {
    float t;
    int16_t light;
    int16_t dw;
};

// One light's volume faces (quads as two triangles, and caps) as built for Embree: vertices in
// the volumes' frame (the casters' centre at the origin: frame()), 3 indices per triangle, and
// per triangle the weight a crossing against its Embree normal (v1 - v0) x (v2 - v0) adds to
// the count.
struct ShadowFaces {
    std::vector<Vec3> vertices;
    std::vector<uint32_t> triangles;
    std::vector<int16_t> weights;
    size_t n_caps = 0;  // the first n_caps triangles are the casters' own (the near caps)
    // The first n_seen_caps caps are those of the casters the camera's rays end on
    // (ShadowVolumes' _seen_triangles_): the only caps a cut may leave out.
    size_t n_seen_caps = 0;
    // The same volume with each side quad whole, from the caster's edge to the last ring
    // (Embree's float intersection needs the rings; a test in doubles does not): the caps
    // (the first n_caps triangles), then two triangles per side, whose indices and weights
    // are these (whole_triangle, whole_weight).
    std::vector<uint32_t> whole_sides;
    std::vector<int16_t> whole_side_weights;
    size_t n_whole() const { return n_caps + whole_side_weights.size(); }
    const uint32_t* whole_triangle(size_t t) const {
        return t < n_caps ? &triangles[3 * t] : &whole_sides[3 * (t - n_caps)];
    }
    int whole_weight(size_t t) const { return t < n_caps ? weights[t] : whole_side_weights[t - n_caps]; }
};

// The distance from the origin to triangle a b c (Ericson, Real-Time Collision Detection 5.1.5).
double origin_distance(const Vec3& a, const Vec3& b, const Vec3& c);

// The caps a camera's rays cannot cross (ShadowVolumes::lit_intervals): rays from _viewer_
// (the world) that end where they meet the casters the camera sees cross those casters' own
// triangles only within _reach_ of the viewer or farther than _beyond_. The defaults keep
// every cap.
struct CapCut {
    double reach = std::numeric_limits<double>::infinity();
    double beyond = 0.0;
    Vec3 viewer{0.0};
    bool cuts() const { return std::isfinite(reach); }
    bool operator==(const CapCut& o) const { return reach == o.reach && beyond == o.beyond && viewer == o.viewer; }
};

class ShadowVolumes {
  public:
    // The volumes of _casters_ for _lights_; _viewer_ is the camera position (with the casters
    // it sets R: reaches()). The first _seen_triangles_ casters are the camera's geometry too
    // (all by default). The lights' volumes are built on _n_threads_ threads
    // (core/parallel.h), a light each.
    ShadowVolumes(const TriangleMesh& casters, const std::vector<ShadowLight>& lights, const Vec3& viewer,
                  size_t seen_triangles = std::numeric_limits<size_t>::max(), int n_threads = 1);
    ~ShadowVolumes();
    ShadowVolumes(const ShadowVolumes&) = delete;
    ShadowVolumes& operator=(const ShadowVolumes&) = delete;
    // The volumes of the same arguments, shared with an earlier call's when that call's
    // casters, lights and seen count were the same (compared exactly) and _viewer_ gives them
    // the same extrusion distances (reaches(): a camera within the casters' reach of each
    // light): the faces do not depend on the viewer otherwise (frame()), so they are the ones
    // a new build would make. The last kKeptVolumes sets are kept, so that a frame's
    // soft-shadow probe and its bake, its per-light passes and an animation's frames over
    // static casters and lights (the camera moving or not) build them once. The least recently
    // used set is dropped before another is built, or by clear_shared(). Thread safe.
    static std::shared_ptr<const ShadowVolumes> shared(const TriangleMesh& casters,
                                                       const std::vector<ShadowLight>& lights, const Vec3& viewer,
                                                       size_t seen_triangles, int n_threads = 1);
    static void clear_shared();
    // Builds of shared() so far (those it did not share), for tests and the stats.
    static long shared_builds();
    // The counting BVHs of the casters' blocks (shadow/block_faces.h: an object, or small ones
    // joined) that builds of volumes built, the others shared with the volumes built before
    // them while the block and the frame stayed.
    static long caster_blocks_built();
    // The faces of one block of the casters for one light (shadow/block_faces.h) that builds of
    // volumes built, the others shared with the volumes built before them.
    static long block_faces_built();
    static constexpr size_t kKeptVolumes = 2;
    // Per light, the extrusion distance R (shadow_volumes.h) that volumes of these casters and
    // lights built for a camera at _viewer_ (the world) have.
    std::vector<double> reaches(const Vec3& viewer) const;

    int num_lights() const { return int(lights_.size()); }
    // Number of caster triangles between _p_ and light _l_ (0: lit). _ambiguous_ (optional):
    // set when _p_ lies on a frustum boundary (its three perturbed segments disagree), where
    // rays leaving _p_ in different directions start with different counts. Thread safe.
    int count_at(int l, const Vec3& p, bool* ambiguous = nullptr) const;
    // Whether _p_ sees light _l_ (count_at == 0, by an occlusion ray: faster). Thread safe.
    bool lit_at(int l, const Vec3& p) const;
    // The lit intervals within [t0[k], t1[k]] (t1 may be inf) of the _n_ rays o[k] + t d[k]
    // (unit d) for every light, into out[k]; _count0_ (num_lights() per ray) holds each
    // light's count at the rays' origins. Rays sharing an origin pass the counts of count_at
    // once. With _count0_ null each ray's count is taken at o + s d, s = max(t0, 1e-4 of the
    // scene's size) or farther until count_at is not _ambiguous_ there, and the crossings
    // before it are left out: for an origin on a frustum boundary, whose count depends on
    // the ray's direction. _masks_ (optional): per ray, the lights asked for (light_mask
    // bits); the others come back lit all along, and a ray asking for none is not traced.
    // Thread safe.
    // _cut_ (rays, with _count0_, that start within cut.reach of cut.viewer and end where they
    // meet the casters the camera sees): those casters' own triangles
    // (ShadowFaces::n_seen_caps) that cap_left_out leaves out are left out of the traversal,
    // as ScreenCrossings leaves them out (no such ray crosses them before its end), in a scene
    // of the volumes built once per cut; the default keeps them all.
    void lit_intervals(const Ray* rays, const float* t0, const float* t1, int n, const int* count0,
                       LitIntervals* out, const uint32_t* masks = nullptr, const CapCut& cut = CapCut()) const;
    // The lit intervals of one ray from its crossings (any order; sorted here): each light's
    // count starts at count0[l] at the ray's origin, crossings at t <= t0 update it, and the
    // ray is lit within [t0, t1] where the count is 0 (clamped at 0). Lights not in _mask_
    // come back lit all along.
    static void lit_from_crossings(std::vector<Crossing>& list, int n_lights, double t0, double t1, const int* count0,
                                   uint32_t mask, LitIntervals& out);
    // Light _l_'s faces a block of the casters at a time (shadow/block_faces.h), each with its
    // own vertices: the same triangles Embree traces, in doubles.
    using FaceParts = std::vector<std::shared_ptr<const ShadowFaces>>;
    const FaceParts& faces(int l) const;
    // The volumes' frame: the centre of the casters' box in the world, on a grid of 1/64 of
    // the box's size rounded up to a power of 2 (faces are relative to it; without casters the
    // first viewer's position).
    Vec3 frame() const;
    // Whether cap triangle a b c (relative to the viewer) is left out for (cap_reach,
    // cap_beyond): wholly farther than cap_reach and nearer than cap_beyond.
    static bool cap_left_out(const Vec3& a, const Vec3& b, const Vec3& c, double cap_reach, double cap_beyond);
    // The mask bit of light _l_ (lights beyond 32 share bits: asking for one traces both).
    static uint32_t light_mask(int l) { return 1u << (l % 32); }
    // Quads (two triangles each) and caps built, for the figures.
    size_t num_faces() const { return n_faces_; }

  private:
    // The constructor's, of the casters' _blocks_ (null: the constructor takes them, with
    // the kept blocks' lock held while it builds).
    ShadowVolumes(const TriangleMesh& casters, const std::vector<ShadowLight>& lights, const Vec3& viewer,
                  size_t seen_triangles, int n_threads, const CasterBlocks* blocks);
    // The sweep of lit_intervals over one ray's sorted crossings: each light starts at
    // count[l] and skips the crossings up to from[l] (null: a), or, _counted_at_origin_,
    // applies those at t <= a.
    static void sweep(const std::vector<Crossing>& list, int n_lights, double a, double b, const int* count,
                      const double* from, bool counted_at_origin, uint32_t mask, LitIntervals& out);
    // Embree's scene of the volumes with the caps that _cut_ leaves out left out, and its
    // weights per light and primitive (all caps: the default); built once each, and kept
    // for the next queries while few other cuts were asked for since.
    struct Traversal;
    std::shared_ptr<const Traversal> traversal(const CapCut& cut) const;
    // Light _l_'s count on ray _r_ (t in [a, b]) a little way along it, at t = _from_ (set).
    int origin_count(int l, const Ray& r, double a, double b, double& from) const;
    struct Impl;
    std::unique_ptr<Impl> impl_;
    std::vector<ShadowLight> lights_;
    size_t n_faces_ = 0;
};

}  // namespace airlight
