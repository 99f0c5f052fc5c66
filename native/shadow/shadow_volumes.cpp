// shadow_volumes.cpp: see shadow_volumes.h.
#include "shadow/shadow_volumes.h"

#include <embree3/rtcore.h>

#include "core/parallel.h"
#include "image/embree_blocks.h"
#include "shadow/block_faces.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <limits>
#include <list>
#include <mutex>
#include <stdexcept>
#include <string>

namespace airlight {

namespace {

// One light's faces of one block of the casters as Embree traces them: its quads and the
// caps a cut keeps, and their weights (per primitive).
struct PartScene {
    RTCScene scene = nullptr;
    std::vector<int16_t> weights;
    ~PartScene() {
        if (scene) rtcReleaseScene(scene);
    }
};

// Embree's context extended with where the filter writes (one list per ray of a packet).
struct CrossingContext {
    RTCIntersectContext context;
    std::vector<Crossing>* lists;  // indexed by the ray's id
    const int16_t* light;          // per instance (a light's faces of a block): its light
    const PartScene* const* parts;  // per instance: its weights
};

void record_crossings(const RTCFilterFunctionNArguments* args) {
    auto* ctx = reinterpret_cast<const CrossingContext*>(args->context);
    for (unsigned i = 0; i < args->N; ++i) {
        if (args->valid[i] != -1) continue;
        const unsigned id = RTCRayN_id(args->ray, args->N, i);
        const unsigned inst = RTCHitN_instID(args->hit, args->N, i, 0), prim = RTCHitN_primID(args->hit, args->N, i);
        const float dn = RTCRayN_dir_x(args->ray, args->N, i) * RTCHitN_Ng_x(args->hit, args->N, i) +
                         RTCRayN_dir_y(args->ray, args->N, i) * RTCHitN_Ng_y(args->hit, args->N, i) +
                         RTCRayN_dir_z(args->ray, args->N, i) * RTCHitN_Ng_z(args->hit, args->N, i);
        const int w = ctx->parts[inst]->weights[prim];
        // Against the outward normal: entering the volume.
        ctx->lists[id].push_back({RTCRayN_tfar(args->ray, args->N, i), ctx->light[inst], int16_t(dn < 0.0f ? w : -w)});
        args->valid[i] = 0;  // rejected: the traversal goes on to the next crossing
    }
}

// The part scenes built for the last traversals, kept while their faces are (a block's faces
// for a light: block_faces.h) and they were used by one of the last kKeptParts traversals: a
// moved object builds its own again, the other blocks' are instanced as they were.
struct KeptParts {
    struct Entry {
        std::weak_ptr<const ShadowFaces> faces;
        const ShadowFaces* key;
        CapCut cut;  // (the default where the faces have no seen caps to leave out)
        std::shared_ptr<const PartScene> scene;
        long last_use;
    };
    static constexpr long kKeptParts = 8;
    std::mutex mutex;
    std::vector<Entry> entries;
    long use = 0;
};

KeptParts& kept_parts() {
    static KeptParts instance;
    return instance;
}

// The Embree scene of _faces_ with the caps _cut_ leaves out left out (_viewer_ in
// the frame's coordinates, as the faces').
std::shared_ptr<const PartScene> part_scene(const ShadowFaces& faces, const CapCut& cut, const Vec3& viewer) {
    auto part = std::make_shared<PartScene>();
    const std::vector<int16_t>& weights = faces.weights;
    std::vector<uint32_t> triangles;
    triangles.reserve(faces.triangles.size());
    part->weights.reserve(weights.size());
    for (size_t k = 0; k < weights.size(); ++k) {
        const uint32_t* v = &faces.triangles[3 * k];
        if (k < faces.n_seen_caps && cut.cuts() &&
            ShadowVolumes::cap_left_out(faces.vertices[v[0]] - viewer, faces.vertices[v[1]] - viewer,
                                        faces.vertices[v[2]] - viewer, cut.reach, cut.beyond))
            continue;
        triangles.insert(triangles.end(), v, v + 3);
        part->weights.push_back(weights[k]);
    }
    const RTCDevice device = blocks_device();
    RTCGeometry g = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
    auto* gv = static_cast<float*>(rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                                           3 * sizeof(float), faces.vertices.size()));
    auto* gi = static_cast<uint32_t*>(rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                                              3 * sizeof(uint32_t), triangles.size() / 3));
    for (size_t k = 0; k < faces.vertices.size(); ++k)
        for (int c = 0; c < 3; ++c) gv[3 * k + c] = float(faces.vertices[k][c]);  // floats to begin with
    std::copy(triangles.begin(), triangles.end(), gi);
    rtcSetGeometryIntersectFilterFunction(g, record_crossings);
    rtcCommitGeometry(g);
    RTCScene scene = rtcNewScene(device);
    rtcSetSceneFlags(scene, RTC_SCENE_FLAG_ROBUST);  // watertight: no crossing lost on a shared edge
    rtcAttachGeometry(scene, g);
    rtcReleaseGeometry(g);
    part->scene = committed(scene, "building the shadow volumes");
    return part;
}

// Counts every caster triangle on a segment (count_at).
struct CountContext {
    RTCIntersectContext context;
    int count;
};

void count_hits(const RTCFilterFunctionNArguments* args) {
    auto* ctx = reinterpret_cast<CountContext*>(const_cast<RTCIntersectContext*>(args->context));
    for (unsigned i = 0; i < args->N; ++i) {
        if (args->valid[i] != -1) continue;
        ++ctx->count;
        args->valid[i] = 0;
    }
}

// The segment from _p_ (in the volumes' frame) toward _light_ (_reach_: a sun's extrusion
// distance), clipped in double to the casters' box [lo, hi] before it goes to Embree in floats:
// from a point 1e9 m out the float origin is off by ~60 m, more than a caster's size, while from
// the box's face it is exact to the casters' own rounding. False: nothing to trace (the point
// is at the light, or the segment misses the box: lit).
bool light_ray(const ShadowLight& light, double reach, const Vec3& p, const Vec3& lo, const Vec3& hi, RTCRay& ray) {
    const Vec3 to = light.directional ? -glm::normalize(light.direction) : light.position - p;
    const double dist = light.directional ? reach : glm::length(to);
    if (!(dist > 0.0) || !(hi.x >= lo.x)) return false;
    const Vec3 d = to / glm::length(to);
    // Off the point by 1e-6 of its distance from the frame (and from the light): the caster a
    // point lies on (a wall's own face, in floats) does not count as between it and the light.
    // Short of the light by 1e-6 of the way: a triangle through the light (its plane holds it)
    // shadows nothing, as in the volumes, where it has no frustum.
    double t0 = 1e-6 * (glm::length(p) + (light.directional ? 0.0 : dist));
    double t1 = light.directional ? dist : dist * (1.0 - 1e-6);
    for (int c = 0; c < 3; ++c) {
        if (d[c] == 0.0) {
            if (p[c] < lo[c] || p[c] > hi[c]) return false;
            continue;
        }
        double ta = (lo[c] - p[c]) / d[c], tb = (hi[c] - p[c]) / d[c];
        if (ta > tb) std::swap(ta, tb);
        t0 = std::max(t0, ta), t1 = std::min(t1, tb);
    }
    if (!(t1 >= t0)) return false;
    const Vec3 o = p + t0 * d;
    ray.org_x = float(o.x), ray.org_y = float(o.y), ray.org_z = float(o.z);
    ray.dir_x = float(d.x), ray.dir_y = float(d.y), ray.dir_z = float(d.z);
    ray.tnear = 0.0f;
    ray.tfar = float(t1 - t0);
    ray.time = 0.0f;
    ray.mask = 0xFFFFFFFFu;
    ray.id = 0;
    ray.flags = 0;
    return true;
}

}  // namespace

struct ShadowVolumes::Traversal {
    CapCut cut;
    RTCScene scene = nullptr;  // an instance per light and block of the casters (its part); null: none
    std::vector<std::shared_ptr<const PartScene>> held;  // per instance
    std::vector<const PartScene*> parts;                 // the same
    std::vector<int16_t> light;                          // per instance
    ~Traversal() {
        if (scene) rtcReleaseScene(scene);
    }
};

struct ShadowVolumes::Impl {
    // The casters' blocks (block_faces.h), their counting scenes in the frame's floats, and the
    // scene over those (count_at, lit_at; null without casters).
    std::vector<std::shared_ptr<VolumeBlocks::Block>> blocks;
    std::vector<std::shared_ptr<const VolumeBlocks::Block::Counting>> counting;
    RTCScene casters = nullptr;
    std::vector<double> reach;                  // per light: the extrusion distance R
    // What R depends on besides the viewer (reach_for): per light the farthest caster vertex
    // (suns: the extent; 0 without casters), the box of the casters and point lights.
    std::vector<double> vertex_far;
    Vec3 mid{0.0};
    double extent = 1.0;
    std::vector<FaceParts> faces;  // per light, per block (ShadowVolumes::faces)
    // Embree's scenes of the volumes, built on the first traced query of their caps' cut (the
    // film's rasterized crossings need none): the last kKeptTraversals cuts (each camera
    // position has its own; a query holds the one it traverses).
    static constexpr size_t kKeptTraversals = 3;
    std::mutex traversals_mutex;
    std::list<std::shared_ptr<const Traversal>> traversals;  // most recently used first
    Vec3 lo{0.0}, hi{-1.0};                     // the casters' box, padded (count_at, lit_at)
    // The volumes are built about the casters' centre (Embree works in floats: a scene 1000 km
    // from the world's origin keeps its shadows to ~1e-7 of its size, not to 6 cm), which no
    // camera moves: the faces are the same for every viewer that gives the same reaches. (On
    // a grid: an object moving the box a little keeps it, ShadowVolumes::frame().)
    Vec3 frame{0.0};

    // R of light _light_ (index l, the frame's coordinates) for a camera at _viewer_: 8 times
    // the farthest of the casters and the viewer from the light (a sun: from the box's centre,
    // or the box's size), rounded up to a power of 2 (a camera moving about a light keeps its
    // R), at most 1e7 times the box's size (shadow_volumes.h).
    double reach_for(const ShadowLight& light, size_t l, const Vec3& viewer) const {
        const Vec3 from = light.directional ? mid : light.position;
        const double far = std::max(glm::length(viewer - from), vertex_far[l]);
        return std::min(std::exp2(std::ceil(std::log2(8.0 * std::max(far, extent * 1e-6)))), 1e7 * extent);
    }
    ~Impl() {
        traversals.clear();
        if (casters) rtcReleaseScene(casters);
    }
};

ShadowVolumes::~ShadowVolumes() = default;

ShadowVolumes::ShadowVolumes(const TriangleMesh& casters, const std::vector<ShadowLight>& world_lights,
                             const Vec3& world_viewer, size_t seen_triangles, int n_threads)
    : ShadowVolumes(casters, world_lights, world_viewer, seen_triangles, n_threads, nullptr) {}

ShadowVolumes::ShadowVolumes(const TriangleMesh& casters, const std::vector<ShadowLight>& world_lights,
                             const Vec3& world_viewer, size_t seen_triangles, int n_threads, const CasterBlocks* given)
    : impl_(new Impl), lights_(world_lights) {
    if (lights_.size() > size_t(std::numeric_limits<int16_t>::max()))
        throw std::invalid_argument("shadow volumes: too many lights");
    // The casters a block at a time (block_faces.h): the blocks kept from the last builds
    // where they are the same, each with its box of the vertices of triangles with an area (a
    // degenerate triangle shadows nothing, and moves neither the frame nor the extrusion
    // distance). (shared() holds the kept blocks' lock and gives them.)
    VolumeBlocks& kept = volume_blocks();
    std::unique_lock<std::mutex> lock;
    CasterBlocks own;
    if (!given) {
        lock = std::unique_lock<std::mutex>(kept.mutex());
        own = kept.blocks(casters);
        given = &own;
    }
    const std::vector<SoupBlock>& cuts = given->cuts;
    const std::vector<std::shared_ptr<VolumeBlocks::Block>>& blocks = given->blocks;
    impl_->blocks = blocks;
    bool any_used = false;
    Vec3 clo(std::numeric_limits<double>::infinity()), chi(-std::numeric_limits<double>::infinity());  // their box
    for (const auto& block : blocks)
        if (block->hi.x >= block->lo.x) {
            clo = glm::min(clo, block->lo), chi = glm::max(chi, block->hi);
            any_used = true;
        }
    // Everything below in the casters' frame (Impl::frame).
    // (The centre on a grid of 1/64 of the casters' size rounded up to a power of 2: an object
    // that moves its edge of the box by less than a cell keeps the frame, and so every other
    // block's faces and counting BVH.)
    const Vec3 size = chi - clo;
    const double cell = any_used ? std::exp2(std::ceil(std::log2(std::max({size.x, size.y, size.z}))) - 6.0) : 0.0;
    const Vec3 centre = 0.5 * (clo + chi);
    impl_->frame = !any_used ? world_viewer : cell > 0.0 ? glm::round(centre / cell) * cell : centre;
    const Vec3 frame = impl_->frame;
    clo -= frame, chi -= frame;
    const Vec3 viewer = world_viewer - frame;
    for (ShadowLight& l : lights_)
        if (!l.directional) l.position -= frame;
    const std::vector<ShadowLight>& lights = lights_;
    impl_->reach.resize(lights.size());
    impl_->vertex_far.resize(lights.size());

    // The scene's extent (the casters and point lights, not the viewer), for the extrusion
    // distance.
    Vec3 lo = clo, hi = chi;
    for (const ShadowLight& l : lights)
        if (!l.directional) lo = glm::min(lo, l.position), hi = glm::max(hi, l.position);
    const double extent = any_used ? std::max(glm::length(hi - lo), 1e-30) : 1.0;
    // (A sun's rings are spaced by this: the casters' size rounded up to a power of 2.)
    const double caster_size =
        any_used ? std::exp2(std::ceil(std::log2(std::max(glm::length(chi - clo), 1e-30)))) : 1.0;
    impl_->extent = extent;
    impl_->mid = any_used ? 0.5 * (lo + hi) : Vec3(0.0);
    const Vec3 pad(1e-5 * extent);  // above the floats' rounding of the vertices
    if (any_used) impl_->lo = clo - pad, impl_->hi = chi + pad;

    // The casters' triangles for the counts, in the frame's floats (those of the caps), each
    // block's kept while it and the frame stay: the welded triangles are the same triangles.
    {
        std::vector<RTCScene> scenes;
        for (const auto& block : blocks) {
            if (!block->counting || block->counting->frame != frame) {
                auto counting = std::make_shared<VolumeBlocks::Block::Counting>();
                counting->frame = frame;
                const std::vector<float>& v = block->copy.vertices;
                counting->vertices.reserve(v.size() + 4);  // (Embree reads 16 bytes at the last vertex)
                for (size_t k = 0; k < v.size(); ++k) {
                    const float x = v[k] == 0.0f ? 0.0f : v[k];  // (-0 as the weld's +0)
                    counting->vertices.push_back(float(double(x) - frame[int(k % 3)]));
                }
                const std::vector<uint32_t>& t = block->copy.triangles;
                counting->scene = new_block_scene(counting->vertices.data(), v.size() / 3, t.data(), t.size() / 3,
                                                  RTC_BUILD_QUALITY_MEDIUM, count_hits);
                block->counting = std::move(counting);
                kept.count_counting();
            }
            impl_->counting.push_back(block->counting);
            scenes.push_back(block->counting->scene);
        }
        impl_->casters = new_instance_scene(scenes);
    }

    // Per light, the extrusion distance (shadow_volumes.h), from the farthest caster vertex.
    for (size_t l = 0; l < lights.size(); ++l) {
        double vertex_far = 0.0;
        for (const auto& block : blocks)
            if (block->hi.x >= block->lo.x)
                vertex_far = std::max(vertex_far, lights[l].directional ? extent : block->vertex_far(lights[l], frame));
        impl_->vertex_far[l] = vertex_far;
        impl_->reach[l] = impl_->reach_for(lights[l], l, viewer);
    }
    // Each block's faces per light: kept, or built (the block welded once, its lights' faces on
    // _n_threads_ threads, a light each).
    const long use = kept.use();
    std::vector<FaceParts> parts(lights.size(), FaceParts(blocks.size()));
    for (size_t b = 0; b < blocks.size(); ++b) {
        VolumeBlocks::Block& block = *blocks[b];
        const size_t seen = seen_triangles > cuts[b].tri_begin
                                ? std::min(seen_triangles - cuts[b].tri_begin, cuts[b].tri_end - cuts[b].tri_begin)
                                : 0;
        // (A sun's rings are spaced by the casters' size, not the point lights': a pass of the
        // sun alone shares its faces.)
        auto key_extent = [&](size_t l) { return lights[l].directional ? caster_size : 0.0; };
        std::vector<size_t> missing;
        for (size_t l = 0; l < lights.size(); ++l) {
            parts[l][b] = block.find(lights[l], frame, impl_->reach[l], key_extent(l), seen, use);
            if (!parts[l][b]) missing.push_back(l);
        }
        if (missing.empty()) continue;
        const BlockGeometry geometry = block_geometry(block.copy.vertices.data(), block.copy.vertices.size() / 3,
                                                      block.copy.triangles.data(), block.copy.triangles.size() / 3,
                                                      frame, n_threads);
        parallel_for(int(missing.size()), n_threads, [&](int i) {
            const size_t l = missing[size_t(i)];
            parts[l][b] = std::make_shared<const ShadowFaces>(
                block_faces(geometry, lights[l], impl_->reach[l], caster_size, seen));
        });
        for (const size_t l : missing)
            block.faces.push_back({lights[l], frame, impl_->reach[l], key_extent(l), seen, parts[l][b], use});
        kept.count_faces(long(missing.size()));
    }
    kept.finish_build();
    impl_->faces = std::move(parts);
    for (const FaceParts& light_faces : impl_->faces)
        for (const auto& part : light_faces) n_faces_ += part->weights.size();
}

double origin_distance(const Vec3& a, const Vec3& b, const Vec3& c) {
    using glm::dot;
    const Vec3 p(0.0), ab = b - a, ac = c - a, ap = p - a;
    const double d1 = dot(ab, ap), d2 = dot(ac, ap);
    if (d1 <= 0.0 && d2 <= 0.0) return glm::length(a);
    const Vec3 bp = p - b;
    const double d3 = dot(ab, bp), d4 = dot(ac, bp);
    if (d3 >= 0.0 && d4 <= d3) return glm::length(b);
    const double vc = d1 * d4 - d3 * d2;
    if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) return glm::length(a + (d1 / (d1 - d3)) * ab);
    const Vec3 cp = p - c;
    const double d5 = dot(ab, cp), d6 = dot(ac, cp);
    if (d6 >= 0.0 && d5 <= d6) return glm::length(c);
    const double vb = d5 * d2 - d1 * d6;
    if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) return glm::length(a + (d2 / (d2 - d6)) * ac);
    const double va = d3 * d6 - d5 * d4;
    if (va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0)
        return glm::length(b + ((d4 - d3) / ((d4 - d3) + (d5 - d6))) * (c - b));
    const double denom = 1.0 / (va + vb + vc);
    return glm::length(a + ab * (vb * denom) + ac * (vc * denom));
}

bool ShadowVolumes::cap_left_out(const Vec3& a, const Vec3& b, const Vec3& c, double cap_reach, double cap_beyond) {
    return std::max({glm::length(a), glm::length(b), glm::length(c)}) < cap_beyond &&
           origin_distance(a, b, c) > cap_reach;
}

std::shared_ptr<const ShadowVolumes::Traversal> ShadowVolumes::traversal(const CapCut& cut) const {
    std::lock_guard<std::mutex> lock(impl_->traversals_mutex);
    std::list<std::shared_ptr<const Traversal>>& kept = impl_->traversals;
    for (auto it = kept.begin(); it != kept.end(); ++it)
        if ((*it)->cut == cut) {
            kept.splice(kept.begin(), kept, it);
            return kept.front();
        }
    auto built = std::make_shared<Traversal>();
    Traversal& t = *built;
    t.cut = cut;
    const Vec3 viewer = cut.viewer - impl_->frame;  // (cap_left_out's origin)
    {
        // Each light's parts: kept, or built (the caps the cut leaves out left out).
        KeptParts& kept_scenes = kept_parts();
        std::lock_guard<std::mutex> parts_lock(kept_scenes.mutex);
        const long use = ++kept_scenes.use;
        for (size_t l = 0; l < impl_->faces.size(); ++l)
            for (const std::shared_ptr<const ShadowFaces>& faces : impl_->faces[l]) {
                const CapCut key = cut.cuts() && faces->n_seen_caps > 0 ? cut : CapCut();
                std::shared_ptr<const PartScene> part;
                for (KeptParts::Entry& e : kept_scenes.entries)
                    if (e.key == faces.get() && e.cut == key && !e.faces.expired()) {
                        e.last_use = use;
                        part = e.scene;
                        break;
                    }
                if (!part) {
                    part = part_scene(*faces, key, viewer);
                    kept_scenes.entries.push_back({faces, faces.get(), key, part, use});
                }
                t.held.push_back(part);
                t.parts.push_back(part.get());
                t.light.push_back(int16_t(l));
            }
        auto& entries = kept_scenes.entries;
        entries.erase(std::remove_if(entries.begin(), entries.end(),
                                     [&](const KeptParts::Entry& e) {
                                         return e.faces.expired() || e.last_use <= use - KeptParts::kKeptParts;
                                     }),
                      entries.end());
    }
    // Identity instances (image/embree_blocks.h), masked by their light's light_mask bit.
    std::vector<RTCScene> scenes;
    std::vector<unsigned> masks;
    for (size_t i = 0; i < t.parts.size(); ++i) {
        scenes.push_back(t.parts[i]->scene);
        masks.push_back(light_mask(int(t.light[i])));
    }
    t.scene = new_instance_scene(scenes, masks);
    kept.push_front(std::move(built));
    if (kept.size() > Impl::kKeptTraversals) kept.pop_back();  // (a query may still hold it)
    return kept.front();
}

int ShadowVolumes::count_at(int l, const Vec3& world_p, bool* ambiguous) const {
    // A segment through an edge that two caster triangles share hits both (Embree's watertight
    // test), though the point is inside one frustum only: the count would be off by one for the
    // whole ray (measured: a camera on the plane through the light and a quad's diagonal got
    // its every ray shadowed). Three segments from points moved off _p_ by 1e-6 of its distance,
    // in three directions across the segment, cannot all graze one edge; their median is the
    // count of the frusta the point is inside (a point within 1e-6 of a true frustum boundary
    // takes either side's count, as the crossings along the ray do).
    const Vec3 p = world_p - impl_->frame;
    const ShadowLight& light = lights_[size_t(l)];
    const Vec3 to = light.directional ? -light.direction : light.position - p;
    const double len = glm::length(to);
    if (ambiguous) *ambiguous = false;
    if (!(len > 0.0)) return 0;
    const Vec3 d = to / len;
    const Vec3 a = glm::normalize(std::abs(d.x) < 0.9 ? glm::cross(d, Vec3(1, 0, 0)) : glm::cross(d, Vec3(0, 1, 0)));
    const Vec3 b = glm::cross(d, a);
    const double eps = 1e-6 * (glm::length(p) + (light.directional ? impl_->reach[size_t(l)] / 8.0 : len));
    const Vec3 offsets[3] = {a, -0.5 * a + 0.8660254037844386 * b, -0.5 * a - 0.8660254037844386 * b};
    int counts[3];
    for (int k = 0; k < 3; ++k) {
        RTCRayHit rh;
        if (!light_ray(light, impl_->reach[size_t(l)], p + eps * offsets[k], impl_->lo, impl_->hi, rh.ray)) {
            counts[k] = 0;
            continue;
        }
        CountContext ctx;
        rtcInitIntersectContext(&ctx.context);
        ctx.count = 0;
        rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
        rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
        if (impl_->casters) rtcIntersect1(impl_->casters, &ctx.context, &rh);
        counts[k] = ctx.count;
    }
    std::sort(counts, counts + 3);
    if (ambiguous) *ambiguous = counts[0] != counts[2];
    return counts[1];
}

bool ShadowVolumes::lit_at(int l, const Vec3& world_p) const {
    RTCRay ray;
    if (!light_ray(lights_[size_t(l)], impl_->reach[size_t(l)], world_p - impl_->frame, impl_->lo, impl_->hi, ray)) return true;
    RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    if (!impl_->casters) return true;
    rtcOccluded1(impl_->casters, &ctx, &ray);  // the counting filter is an intersect filter only
    return ray.tfar >= 0.0f;                    // set to -inf on a hit
}

int ShadowVolumes::origin_count(int l, const Ray& r, double a, double b, double& from) const {
    // From max(a, 1e-4 of the scene's size) on, 4 times farther while the perturbed segments
    // of count_at disagree (the point is within their 1e-6 of a frustum boundary: a ray
    // leaving an eye on a boundary at a small angle), at most to the ray's end.
    const double scale = glm::length(r.o - impl_->frame) + glm::length(impl_->hi - impl_->lo);
    from = std::max(a, 1e-4 * scale);
    for (int k = 0;; ++k) {
        bool ambiguous = false;
        const int c = count_at(l, r.o + from * r.d, &ambiguous);
        if (!ambiguous || k == 12 || !(4.0 * from < b)) return c;
        from *= 4.0;
    }
}

void ShadowVolumes::lit_intervals(const Ray* rays, const float* t0, const float* t1, int n, const int* count0,
                                  LitIntervals* out, const uint32_t* masks, const CapCut& cut) const {
    // The cut holds for rays counted at their origins that start within its reach (crossings
    // before a ray's start update its count); any other call traverses every cap.
    bool cuts = count0 != nullptr && cut.cuts();
    for (int k = 0; k < n && cuts; ++k) cuts = double(t0[k]) <= cut.reach;
    const std::shared_ptr<const Traversal> held = traversal(cuts ? cut : CapCut());
    const Traversal& volumes = *held;
    const int L = num_lights();
    thread_local std::vector<Crossing> lists[16];
    thread_local std::vector<int> count;
    thread_local std::vector<double> from;
    count.resize(static_cast<size_t>(L));
    from.resize(static_cast<size_t>(L));
    CrossingContext ctx;
    ctx.lists = lists;
    ctx.light = volumes.light.data();
    ctx.parts = volumes.parts.data();
    for (int base = 0; base < n; base += 16) {
        const int m = std::min(16, n - base);
        alignas(64) RTCRayHit16 rh;
        alignas(64) int valid[16];
        for (int k = 0; k < 16; ++k) {
            const int i = base + std::min(k, m - 1);
            const Ray& r = rays[i];
            const Vec3 o = r.o - impl_->frame;
            lists[k].clear();
            const uint32_t mask = masks ? masks[i] : 0xFFFFFFFFu;
            valid[k] = k < m && t1[i] > 0.0f && mask != 0 ? -1 : 0;
            rh.ray.org_x[k] = float(o.x), rh.ray.org_y[k] = float(o.y), rh.ray.org_z[k] = float(o.z);
            rh.ray.dir_x[k] = float(r.d.x), rh.ray.dir_y[k] = float(r.d.y), rh.ray.dir_z[k] = float(r.d.z);
            rh.ray.tnear[k] = 0.0f;
            rh.ray.tfar[k] = std::isinf(t1[i]) ? std::numeric_limits<float>::infinity() : t1[i];
            rh.ray.time[k] = 0.0f;
            rh.ray.mask[k] = mask;
            rh.ray.id[k] = unsigned(k);
            rh.ray.flags[k] = 0;
            rh.hit.geomID[k] = RTC_INVALID_GEOMETRY_ID;
            rh.hit.instID[0][k] = RTC_INVALID_GEOMETRY_ID;
        }
        rtcInitIntersectContext(&ctx.context);
        ctx.context.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
        if (volumes.scene) rtcIntersect16(valid, volumes.scene, &ctx.context, &rh);  // (null: no casters)
        for (int k = 0; k < m; ++k) {
            const int i = base + k;
            const Ray& r = rays[i];
            std::vector<Crossing>& list = lists[k];
            std::sort(list.begin(), list.end(), [](const Crossing& a, const Crossing& b) { return a.t < b.t; });
            const uint32_t mask = masks ? masks[i] : 0xFFFFFFFFu;
            const double a = t0[i], b = t1[i];
            // Without count0 each light's count is taken a little way along the ray (origin_count),
            // and the crossings up to there are in it already.
            for (int l = 0; l < L; ++l) {
                from[l] = a;
                if (!(mask & light_mask(l))) count[l] = 0;
                else if (count0) count[l] = count0[size_t(i) * L + l];
                else count[l] = origin_count(l, r, a, b, from[l]);
            }
            sweep(list, L, a, b, count.data(), from.data(), count0 != nullptr, mask, out[i]);
        }
    }
}

void ShadowVolumes::sweep(const std::vector<Crossing>& list, int L, double a, double b, const int* count,
                          const double* from, bool counted_at_origin, uint32_t mask, LitIntervals& lit) {
    lit.clear(L);
    // Per light, sweep its crossings (sorted by t): lit where the count is 0 (clamped at 0: a
    // crossing lost to rounding must not leave the rest of the ray dark).
    uint32_t crossed = 0;  // the lights with a crossing on the ray (bits as light_mask)
    for (const Crossing& x : list) crossed |= light_mask(x.light);
    for (int l = 0; l < L; ++l) {
        lit.begin[l] = int(lit.spans.size());
        if (!(mask & light_mask(l)) || (!(crossed & light_mask(l)) && count[l] == 0)) {
            // Not asked for, or no crossing and lit at the start: lit all along.
            if (b > a) lit.spans.emplace_back(a, b);
            else lit.partial |= light_mask(l);  // (no span at all)
            lit.end[l] = int(lit.spans.size());
            continue;
        }
        int c = count[l];
        double start = a;
        bool open = false;
        size_t q = 0;
        for (; q < list.size() && double(list[q].t) <= a; ++q)
            if (list[q].light == l && counted_at_origin) c = std::max(0, c + list[q].dw);
        while (q < list.size() && double(list[q].t) <= (from ? from[l] : a)) ++q;
        if (c == 0) open = true;
        for (; q < list.size() && double(list[q].t) < b; ++q) {
            if (list[q].light != l) continue;
            const int next = std::max(0, c + list[q].dw);
            const double t = list[q].t;
            if (c == 0 && next > 0 && open) {
                if (t > start) lit.spans.emplace_back(start, t);
                open = false;
            } else if (c > 0 && next == 0) {
                start = t;
                open = true;
            }
            c = next;
        }
        if (open && b > start) lit.spans.emplace_back(start, b);
        lit.end[l] = int(lit.spans.size());
        const bool whole = lit.end[l] - lit.begin[l] == 1 && lit.spans[size_t(lit.begin[l])].first == a &&
                           lit.spans[size_t(lit.begin[l])].second == b;
        if (!whole) lit.partial |= light_mask(l);
    }
}

void ShadowVolumes::lit_from_crossings(std::vector<Crossing>& list, int L, double t0, double t1, const int* count0,
                                       uint32_t mask, LitIntervals& out) {
    if (list.size() > 1)
        std::sort(list.begin(), list.end(), [](const Crossing& a, const Crossing& b) { return a.t < b.t; });
    sweep(list, L, t0, t1, count0, nullptr, true, mask, out);
}

namespace {

bool same_lights(const std::vector<ShadowLight>& a, const std::vector<ShadowLight>& b) {
    if (a.size() != b.size()) return false;
    for (size_t k = 0; k < a.size(); ++k)
        if (a[k].directional != b[k].directional || a[k].position != b[k].position || a[k].direction != b[k].direction)
            return false;
    return true;
}

struct KeptVolumes {
    CasterBlocks casters;  // (the blocks compared exactly by VolumeBlocks::blocks)
    std::vector<ShadowLight> lights;
    size_t seen_triangles = 0;
    std::shared_ptr<const ShadowVolumes> volumes;
    long last_use = 0;
};

struct SharedVolumes {
    std::mutex mutex;
    std::vector<KeptVolumes> kept;
    long uses = 0, builds = 0;
};

SharedVolumes& shared_volumes() {
    static SharedVolumes instance;
    return instance;
}

}  // namespace

std::shared_ptr<const ShadowVolumes> ShadowVolumes::shared(const TriangleMesh& casters,
                                                           const std::vector<ShadowLight>& lights, const Vec3& viewer,
                                                           size_t seen_triangles, int n_threads) {
    SharedVolumes& s = shared_volumes();
    std::lock_guard<std::mutex> lock(s.mutex);
    VolumeBlocks& blocks = volume_blocks();
    std::lock_guard<std::mutex> blocks_lock(blocks.mutex());
    CasterBlocks given = blocks.blocks(casters);
    for (KeptVolumes& k : s.kept)
        if (k.seen_triangles == seen_triangles && same_lights(k.lights, lights) && k.casters.cuts == given.cuts &&
            k.casters.blocks == given.blocks && k.volumes->reaches(viewer) == k.volumes->impl_->reach) {
            k.last_use = ++s.uses;
            return k.volumes;
        }
    if (s.kept.size() >= kKeptVolumes) {  // the least recently used goes before the new one is built
        auto oldest = std::min_element(s.kept.begin(), s.kept.end(), [](const KeptVolumes& a, const KeptVolumes& b) {
            return a.last_use < b.last_use;
        });
        s.kept.erase(oldest);
    }
    std::shared_ptr<const ShadowVolumes> volumes(
        new ShadowVolumes(casters, lights, viewer, seen_triangles, n_threads, &given));
    ++s.builds;
    s.kept.push_back({std::move(given), lights, seen_triangles, volumes, ++s.uses});
    return volumes;
}

void ShadowVolumes::clear_shared() {
    SharedVolumes& s = shared_volumes();
    std::lock_guard<std::mutex> lock(s.mutex);
    s.kept.clear();
    volume_blocks().clear();
}

long ShadowVolumes::caster_blocks_built() {
    std::lock_guard<std::mutex> lock(volume_blocks().mutex());
    return volume_blocks().counting_built();
}

long ShadowVolumes::block_faces_built() {
    std::lock_guard<std::mutex> lock(volume_blocks().mutex());
    return volume_blocks().faces_built();
}

long ShadowVolumes::shared_builds() {
    SharedVolumes& s = shared_volumes();
    std::lock_guard<std::mutex> lock(s.mutex);
    return s.builds;
}

std::vector<double> ShadowVolumes::reaches(const Vec3& viewer) const {
    std::vector<double> out(lights_.size());
    for (size_t l = 0; l < lights_.size(); ++l) out[l] = impl_->reach_for(lights_[l], l, viewer - impl_->frame);
    return out;
}

const ShadowVolumes::FaceParts& ShadowVolumes::faces(int l) const { return impl_->faces[size_t(l)]; }

Vec3 ShadowVolumes::frame() const { return impl_->frame; }

}  // namespace airlight
