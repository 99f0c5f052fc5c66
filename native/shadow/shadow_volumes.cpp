// shadow_volumes.cpp: see shadow_volumes.h.
#include "shadow/shadow_volumes.h"

#include <embree3/rtcore.h>

#include "core/parallel.h"
#include "image/embree_blocks.h"

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

// The volumes' quads go from ring to ring, each this much farther from the light (see the
// constructor), at most this many rings.
constexpr double kRingGrowth = 2.0;
constexpr int kMaxRings = 48;

// Vertices welded by exact position (shared edges of triangles that do not share indices).
struct Welded {
    std::vector<Vec3> position;
    std::vector<uint32_t> triangles;  // 3 per triangle, into position
};

// Welds by exact position in an open-addressing table (a std::unordered_map's node per vertex
// cost 2.4 s for the 5e6 vertices of 1e7 triangles): the welded vertices keep the order of
// their first use.
Welded weld(const TriangleMesh& mesh) {
    Welded out;
    const size_t n_vertices = mesh.vertices.size() / 3;
    std::vector<uint32_t> remap(n_vertices);
    size_t capacity = 16;
    while (capacity < 2 * n_vertices) capacity *= 2;
    std::vector<uint32_t> slot(capacity, UINT32_MAX);  // welded index, or none
    out.position.reserve(n_vertices);
    for (size_t k = 0; k < n_vertices; ++k) {
        std::array<float, 3> p{mesh.vertices[3 * k], mesh.vertices[3 * k + 1], mesh.vertices[3 * k + 2]};
        for (float& c : p)
            if (c == 0.0f) c = 0.0f;  // -0 and +0 weld
        std::array<uint32_t, 3> key;  // (the hash's; the positions compare as doubles of the floats)
        std::memcpy(key.data(), p.data(), sizeof(key));
        const Vec3 position(p[0], p[1], p[2]);
        uint64_t h = (uint64_t(key[0]) * 0x9E3779B97F4A7C15ull) ^ (uint64_t(key[1]) * 0xC2B2AE3D27D4EB4Full) ^
                     (uint64_t(key[2]) * 0x165667B19E3779F9ull);
        h ^= h >> 29;
        for (size_t i = size_t(h) & (capacity - 1);; i = (i + 1) & (capacity - 1)) {
            if (slot[i] == UINT32_MAX) {
                slot[i] = uint32_t(out.position.size());
                out.position.push_back(position);
                remap[k] = slot[i];
                break;
            }
            if (out.position[slot[i]] == position) {
                remap[k] = slot[i];
                break;
            }
        }
    }
    out.triangles.resize(mesh.triangles.size());
    for (size_t k = 0; k < mesh.triangles.size(); ++k) out.triangles[k] = remap[mesh.triangles[k]];
    return out;
}

// Embree's context extended with where the filter writes (one list per ray of a packet).
struct CrossingContext {
    RTCIntersectContext context;
    std::vector<Crossing>* lists;  // indexed by the ray's id
    const std::vector<std::vector<int16_t>>* weights;  // per light (geomID), per primitive
};

void record_crossings(const RTCFilterFunctionNArguments* args) {
    auto* ctx = reinterpret_cast<const CrossingContext*>(args->context);
    for (unsigned i = 0; i < args->N; ++i) {
        if (args->valid[i] != -1) continue;
        const unsigned id = RTCRayN_id(args->ray, args->N, i);
        const unsigned geom = RTCHitN_geomID(args->hit, args->N, i), prim = RTCHitN_primID(args->hit, args->N, i);
        const float dn = RTCRayN_dir_x(args->ray, args->N, i) * RTCHitN_Ng_x(args->hit, args->N, i) +
                         RTCRayN_dir_y(args->ray, args->N, i) * RTCHitN_Ng_y(args->hit, args->N, i) +
                         RTCRayN_dir_z(args->ray, args->N, i) * RTCHitN_Ng_z(args->hit, args->N, i);
        const int w = (*ctx->weights)[geom][prim];
        // Against the outward normal: entering the volume.
        ctx->lists[id].push_back({RTCRayN_tfar(args->ray, args->N, i), int16_t(geom), int16_t(dn < 0.0f ? w : -w)});
        args->valid[i] = 0;  // rejected: the traversal goes on to the next crossing
    }
}

// The sine of the angle between a caster's plane and the direction to the light below which
// the caster gets no shadow volume (it is seen edge-on).
constexpr double kEdgeOn = 1e-6;

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

// The casters' blocks of the last volumes built (their counting BVHs).
BlockCache& caster_blocks() {
    static BlockCache cache(RTC_BUILD_QUALITY_MEDIUM, count_hits);
    return cache;
}

void embree_error(void* user, RTCError code, const char* str) {
    auto* message = static_cast<std::string*>(user);
    if (message->empty()) *message = std::string(str ? str : "unknown error") + " (code " + std::to_string(int(code)) + ")";
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
    RTCScene scene = nullptr;  // one geometry per light: its quads and the caps kept
    std::vector<std::vector<int16_t>> weights;  // per light, per primitive
    ~Traversal() {
        if (scene) rtcReleaseScene(scene);
    }
};

struct ShadowVolumes::Impl {
    RTCDevice device = nullptr;
    std::shared_ptr<const BlockedScene> casters;  // the caster triangles (count_at, lit_at)
    std::vector<double> reach;                  // per light: the extrusion distance R
    // What R depends on besides the viewer (reach_for): per light the farthest caster vertex
    // (suns: the extent; 0 without casters), the box of the casters and point lights.
    std::vector<double> vertex_far;
    Vec3 mid{0.0};
    double extent = 1.0;
    std::vector<ShadowFaces> faces;             // per light (ShadowVolumes::faces)
    // Embree's scenes of the volumes, built on the first traced query of their caps' cut (the
    // film's rasterized crossings need none): the last kKeptTraversals cuts (each camera
    // position has its own; a query holds the one it traverses).
    static constexpr size_t kKeptTraversals = 3;
    std::mutex traversals_mutex;
    std::list<std::shared_ptr<const Traversal>> traversals;  // most recently used first
    Vec3 lo{0.0}, hi{-1.0};                     // the casters' box, padded (count_at, lit_at)
    // The volumes are built about the casters' centre (Embree works in floats: a scene 1000 km
    // from the world's origin keeps its shadows to ~1e-7 of its size, not to 6 cm), which no
    // camera moves: the faces are the same for every viewer that gives the same reaches.
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
    std::string error;

    ~Impl() {
        traversals.clear();
        if (device) rtcReleaseDevice(device);
    }
    void check(const char* what) const {
        if (!error.empty()) throw std::runtime_error(std::string("Embree (shadow volumes): ") + what + ": " + error);
    }
};

ShadowVolumes::~ShadowVolumes() = default;

ShadowVolumes::ShadowVolumes(const TriangleMesh& casters, const std::vector<ShadowLight>& world_lights,
                             const Vec3& world_viewer, size_t seen_triangles, int n_threads)
    : impl_(new Impl), lights_(world_lights) {
    if (lights_.size() > size_t(std::numeric_limits<int16_t>::max()))
        throw std::invalid_argument("shadow volumes: too many lights");
    // Everything below in the casters' frame (Impl::frame).
    Welded mesh = weld(casters);
    // The vertices of triangles with an area: a degenerate triangle shadows nothing, and moves
    // neither the frame nor the extrusion distance.
    std::vector<char> used(mesh.position.size(), 0);
    for (size_t k = 0; k + 2 < mesh.triangles.size(); k += 3) {
        const uint32_t* t = &mesh.triangles[k];
        const Vec3 &a = mesh.position[t[0]], &b = mesh.position[t[1]], &c = mesh.position[t[2]];
        if (glm::length(glm::cross(b - a, c - a)) > 0.0) used[t[0]] = used[t[1]] = used[t[2]] = 1;
    }
    bool any_used = false;
    Vec3 clo(std::numeric_limits<double>::infinity()), chi(-std::numeric_limits<double>::infinity());  // their box
    for (size_t k = 0; k < mesh.position.size(); ++k)
        if (used[k]) {
            clo = glm::min(clo, mesh.position[k]), chi = glm::max(chi, mesh.position[k]);
            any_used = true;
        }
    impl_->frame = any_used ? 0.5 * (clo + chi) : world_viewer;
    clo -= impl_->frame, chi -= impl_->frame;
    const Vec3 viewer = world_viewer - impl_->frame;
    for (ShadowLight& l : lights_)
        if (!l.directional) l.position -= impl_->frame;
    const std::vector<ShadowLight>& lights = lights_;
    for (Vec3& p : mesh.position) p -= impl_->frame;
    const size_t nv = mesh.position.size(), nt = mesh.triangles.size() / 3;
    impl_->device = rtcNewDevice(nullptr);
    if (!impl_->device) throw std::runtime_error("Embree: rtcNewDevice failed (shadow volumes)");
    rtcSetDeviceErrorFunction(impl_->device, embree_error, &impl_->error);
    impl_->reach.resize(lights.size());
    impl_->vertex_far.resize(lights.size());
    impl_->faces.resize(lights.size());

    // The scene's extent (the casters and point lights, not the viewer), for the extrusion
    // distance.
    Vec3 lo = clo, hi = chi;
    for (const ShadowLight& l : lights)
        if (!l.directional) lo = glm::min(lo, l.position), hi = glm::max(hi, l.position);
    const double extent = any_used ? std::max(glm::length(hi - lo), 1e-30) : 1.0;
    impl_->extent = extent;
    impl_->mid = any_used ? 0.5 * (lo + hi) : Vec3(0.0);
    const Vec3 pad(1e-5 * extent);  // above the floats' rounding of the vertices
    if (any_used) impl_->lo = clo - pad, impl_->hi = chi + pad;

    {
        // The casters' triangles for the counts, in the frame's floats (those of the caps), each
        // object a block whose BVH later builds share while it and the frame stay
        // (image/embree_blocks.h): the welded triangles are the same triangles.
        std::vector<float> shifted(casters.vertices.size());
        for (size_t k = 0; k < shifted.size(); ++k) {
            const float x = casters.vertices[k] == 0.0f ? 0.0f : casters.vertices[k];  // (-0 as the weld's +0)
            shifted[k] = float(double(x) - impl_->frame[int(k % 3)]);
        }
        impl_->casters = caster_blocks().scene(shifted.data(), shifted.size() / 3, casters.triangles.data(),
                                               casters.triangles.size() / 3);
    }

    // Every triangle's directed edges (p -> q, as wound), grouped by undirected edge (u < v) in
    // (u, v) order: each light sums its sides' orientations edge by edge from them, without a
    // hash map. A counting sort on u, then each u's few uses sorted by v (a std::sort of the
    // 3e7 uses of 1e7 triangles took 2 s).
    if (3 * nt >= size_t(UINT32_MAX)) throw std::invalid_argument("shadow volumes: too many caster triangles");
    std::vector<uint32_t> use_first(nv + 1, 0);  // per u: where its uses start
    for (size_t k = 0; k < 3 * nt; ++k) {
        const uint32_t p = mesh.triangles[k], q = mesh.triangles[k % 3 == 2 ? k - 2 : k + 1];
        ++use_first[std::min(p, q) + 1];
    }
    for (size_t u = 0; u < nv; ++u) use_first[u + 1] += use_first[u];
    // Per use: (v << 32) | (triangle << 1) | (p < q).
    std::vector<uint64_t> uses(3 * nt);
    {
        std::vector<uint32_t> fill(use_first.begin(), use_first.end() - 1);
        for (size_t k = 0; k < 3 * nt; ++k) {
            const uint32_t p = mesh.triangles[k], q = mesh.triangles[k % 3 == 2 ? k - 2 : k + 1];
            uses[fill[std::min(p, q)]++] = (uint64_t(std::max(p, q)) << 32) | (uint64_t(k / 3) << 1) | (p < q ? 1u : 0u);
        }
    }
    const int parts = std::max(n_threads, 1);
    parallel_for(parts, parts, [&](int part) {
        for (size_t u = nv * size_t(part) / size_t(parts), end = nv * size_t(part + 1) / size_t(parts); u < end; ++u)
            std::sort(uses.begin() + use_first[u], uses.begin() + use_first[u + 1]);
    });
    // The lights' volumes, one a work item (each writes its own faces, weights and reach).
    parallel_for(int(lights.size()), n_threads, [&](int light_index) {
        const size_t l = size_t(light_index);
        std::vector<int8_t> orient(nt);       // per triangle: +1 as wound, -1 reversed, 0 none
        std::vector<uint32_t> ring_slot(nv);  // a silhouette vertex's place in each ring
        const ShadowLight& light = lights[l];
        const Vec3 s = light.position, w = glm::normalize(light.direction);
        // The extrusion distance (shadow_volumes.h).
        double vertex_far = 0.0;
        for (size_t k = 0; k < nv; ++k)
            if (used[k])
                vertex_far = std::max(vertex_far, light.directional ? extent : glm::length(mesh.position[k] - s));
        impl_->vertex_far[l] = vertex_far;
        const double R = impl_->reach_for(light, l, viewer);
        impl_->reach[l] = R;
        // Outward normal of the side through edge p -> q of a triangle wound counter-clockwise
        // as the light sees it: (q - p) x (s - p), or (q - p) x (-w) for a sun.
        auto toward_light = [&](const Vec3& p) { return light.directional ? -w : s - p; };
        std::vector<uint32_t> caps;
        caps.reserve(3 * nt);
        size_t n_seen_caps = 0;  // (the caps come in the casters' order)
        for (size_t k = 0; k < nt; ++k) {
            orient[k] = 0;
            uint32_t a = mesh.triangles[3 * k], b = mesh.triangles[3 * k + 1], c = mesh.triangles[3 * k + 2];
            const Vec3 pa = mesh.position[a], pb = mesh.position[b], pc = mesh.position[c];
            const Vec3 n = glm::cross(pb - pa, pc - pa);
            const double facing = glm::dot(n, toward_light(pa));
            // Zero area, or the light within kEdgeOn of the triangle's plane: no frustum. A frustum
            // that thin has side quads closer together than the floats Embree holds them in, so
            // a ray crossing them could enter and not leave (measured: a fin whose plane held the
            // light to float32 rounding, 3e-9 rad, shadowed every ray crossing its plane); the
            // shadow it drops is a wedge kEdgeOn wide seen from the light.
            if (!(std::abs(facing) > kEdgeOn * glm::length(n) * glm::length(toward_light(pa))) || glm::length(n) == 0.0)
                continue;
            if (facing < 0.0) std::swap(b, c);  // counter-clockwise seen from the light (its edges reversed)
            orient[k] = facing < 0.0 ? -1 : 1;
            caps.insert(caps.end(), {a, b, c});
            if (k < seen_triangles) ++n_seen_caps;
        }
        // Per undirected edge (u < v): the summed orientation of its sides (+1 for u -> v);
        // the silhouette is where it is not 0.
        std::vector<std::pair<uint64_t, int>> silhouette;
        for (size_t u = 0; u < nv; ++u)
            for (size_t q = use_first[u], end = use_first[u + 1]; q < end;) {
                const uint32_t v = uint32_t(uses[q] >> 32);
                int weight = 0;
                for (; q < end && uint32_t(uses[q] >> 32) == v; ++q)
                    weight += orient[uint32_t(uses[q]) >> 1] * ((uses[q] & 1u) ? 1 : -1);
                if (weight != 0) silhouette.emplace_back((uint64_t(u) << 32) | v, weight);
            }
        // Only the silhouette's vertices get rings (ring r of vertex k: ring_vertex(r, k)).
        std::fill(ring_slot.begin(), ring_slot.end(), UINT32_MAX);  // (none)
        std::vector<uint32_t> ringed;  // the silhouette's vertices, in order
        for (const auto& [key, weight] : silhouette)
            for (const uint32_t k : {uint32_t(key >> 32), uint32_t(key & 0xffffffffu)})
                if (ring_slot[k] == UINT32_MAX) ring_slot[k] = uint32_t(ringed.size()), ringed.push_back(k);
        const size_t n_ringed = ringed.size();
        auto ring_vertex = [&](int r, uint32_t k) {
            return r == 0 ? k : uint32_t(nv + size_t(r - 1) * n_ringed + ring_slot[k]);
        };
        // Vertices: the welded ones, then rings of copies pushed away from the light (each
        // welded vertex has its own, so neighbouring quads meet exactly). A quad runs from one
        // ring to the next, each ring kRingGrowth times as far from the light as the one before,
        // up to R: Embree's float intersection errs by ~1e-7 of a triangle's size, so a quad
        // spanning 0..R would place a crossing 3 m from the light ~1e-7 R off (measured: 0.2 %
        // of the airlight of a wall's shaft with R ~ 9 km); ring by ring it is ~1e-7 of the
        // crossing's own distance. Short steps also keep the quads' bounding boxes tight: the
        // sides of a silhouette of many short edges fan out from the light as slivers, and a
        // ray through the fan visits every box that overlaps it there (measured: a 10^6-
        // triangle grid's glow rays took 2.5x as long with quads 64 times as long as near).
        // A vertex's rings stop at R (scale_at), the steps past it are left out.
        double d_min = std::numeric_limits<double>::infinity();
        for (const uint32_t k : ringed)
            d_min = std::min(d_min, light.directional ? extent : std::max(glm::length(mesh.position[k] - s), 1e-30));
        int rings = 1;
        while (rings < kMaxRings && d_min * std::pow(kRingGrowth, rings) < R) ++rings;
        std::vector<double> reach_scale(n_ringed);  // per ringed vertex: the scale that takes it to R
        for (size_t i = 0; i < n_ringed; ++i) {
            const double dp = light.directional ? extent : std::max(glm::length(mesh.position[ringed[i]] - s), 1e-300);
            reach_scale[i] = std::max(R / dp, kRingGrowth);  // (at least one step past the caster)
        }
        auto scale_at = [&](int r, uint32_t k) {  // ring r's distance over vertex k's (r >= 1)
            const double limit = reach_scale[ring_slot[k]];
            return r == rings ? limit : std::min(std::pow(kRingGrowth, r), limit);
        };
        // (In Embree's floats. Written once each: at 1e7 triangles a light's volume was half
        // page faults, zeroing and copies of its arrays.)
        ShadowFaces& faces = impl_->faces[l];
        std::vector<Vec3>& vertices = faces.vertices;
        auto as_float = [](const Vec3& p) { return Vec3(float(p.x), float(p.y), float(p.z)); };
        vertices.reserve(nv + size_t(rings) * n_ringed);
        for (size_t k = 0; k < nv; ++k) vertices.push_back(as_float(mesh.position[k]));
        vertices.resize(nv + size_t(rings) * n_ringed);
        for (const uint32_t k : ringed) {
            const Vec3 p = mesh.position[k];
            const double dp = light.directional ? extent : std::max(glm::length(p - s), 1e-300);
            for (int r = 1; r <= rings; ++r) {
                const double scale = scale_at(r, k);
                const Vec3 f = light.directional ? p + (dp * (scale - 1.0)) * w : s + (p - s) * scale;
                vertices[ring_vertex(r, k)] = as_float(f);
            }
        }
        // Whether vertex k's ring r + 1 is where its ring r is (both at R).
        auto stays = [&](int r, uint32_t k) { return r >= 1 && scale_at(r + 1, k) == scale_at(r, k); };
        const size_t n_sides = 2 * silhouette.size();  // triangles: two a quad
        std::vector<uint32_t>& ib = faces.triangles;  // the caps, then the sides ring by ring
        ib = std::move(caps);
        ib.reserve(ib.size() + 3 * n_sides * size_t(rings));
        faces.n_caps = ib.size() / 3;
        faces.n_seen_caps = n_seen_caps;
        std::vector<int16_t>& weights = faces.weights;
        weights.reserve(faces.n_caps + n_sides * size_t(rings));
        weights.assign(faces.n_caps, 1);
        // The same sides each one quad from the casters to R (ShadowFaces::whole_sides).
        std::vector<uint32_t>& whole = faces.whole_sides;
        whole.reserve(3 * n_sides);
        std::vector<int16_t>& whole_weights = faces.whole_side_weights;
        whole_weights.reserve(n_sides);
        for (const auto& [key, weight] : silhouette) {
            const int16_t m = int16_t(std::min(std::abs(weight), int(std::numeric_limits<int16_t>::max())));
            const uint32_t k_u = uint32_t(key >> 32), k_v = uint32_t(key & 0xffffffffu);
            for (int r = 0; r < rings; ++r) {
                const uint32_t u = ring_vertex(r, k_u), v = ring_vertex(r, k_v);
                const uint32_t uf = ring_vertex(r + 1, k_u), vf = ring_vertex(r + 1, k_v);
                // (u, vf, v) and (u, uf, vf) have the outward normal (v - u) x (s - u): the far
                // points lie away from the light. Where v stays (v = vf) the first has no
                // area, where u stays the second.
                if (!stays(r, k_v)) {
                    if (weight > 0) ib.insert(ib.end(), {u, vf, v});
                    else ib.insert(ib.end(), {u, v, vf});
                    weights.push_back(m);
                }
                if (!stays(r, k_u)) {
                    if (weight > 0) ib.insert(ib.end(), {u, uf, vf});
                    else ib.insert(ib.end(), {u, vf, uf});
                    weights.push_back(m);
                }
            }
            const uint32_t u = k_u, v = k_v, uf = ring_vertex(rings, k_u), vf = ring_vertex(rings, k_v);
            if (weight > 0) whole.insert(whole.end(), {u, vf, v, u, uf, vf});
            else whole.insert(whole.end(), {u, v, vf, u, vf, uf});
            whole_weights.push_back(m);
            whole_weights.push_back(m);
        }
    });
    for (const ShadowFaces& faces : impl_->faces) n_faces_ += faces.weights.size();
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
    t.scene = rtcNewScene(impl_->device);
    rtcSetSceneFlags(t.scene, RTC_SCENE_FLAG_ROBUST);  // watertight: no crossing lost on a shared edge
    t.weights.resize(impl_->faces.size());
    // One geometry per light, masked by its light_mask bit: its quads, and its caps but those
    // the cut leaves out. (A build Embree fails is not kept.)
    std::vector<uint32_t> triangles;
    for (size_t l = 0; l < impl_->faces.size(); ++l) {
        const ShadowFaces& faces = impl_->faces[l];
        const std::vector<int16_t>& weights = faces.weights;
        triangles.clear();
        triangles.reserve(faces.triangles.size());
        t.weights[l].reserve(weights.size());
        for (size_t k = 0; k < weights.size(); ++k) {
            const uint32_t* v = &faces.triangles[3 * k];
            if (k < faces.n_seen_caps && cut.cuts() &&
                cap_left_out(faces.vertices[v[0]] - viewer, faces.vertices[v[1]] - viewer,
                             faces.vertices[v[2]] - viewer, cut.reach, cut.beyond))
                continue;
            triangles.insert(triangles.end(), v, v + 3);
            t.weights[l].push_back(weights[k]);
        }
        RTCGeometry g = rtcNewGeometry(impl_->device, RTC_GEOMETRY_TYPE_TRIANGLE);
        auto* gv = static_cast<float*>(rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                                               3 * sizeof(float), faces.vertices.size()));
        auto* gi = static_cast<uint32_t*>(rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                                                  3 * sizeof(uint32_t), triangles.size() / 3));
        for (size_t k = 0; k < faces.vertices.size(); ++k)
            for (int c = 0; c < 3; ++c) gv[3 * k + c] = float(faces.vertices[k][c]);  // floats to begin with
        std::copy(triangles.begin(), triangles.end(), gi);
        rtcSetGeometryIntersectFilterFunction(g, record_crossings);
        rtcSetGeometryMask(g, light_mask(int(l)));
        rtcCommitGeometry(g);
        rtcAttachGeometryByID(t.scene, g, unsigned(l));
        rtcReleaseGeometry(g);
    }
    rtcCommitScene(t.scene);
    impl_->check("building the volumes");
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
        if (impl_->casters->scene()) rtcIntersect1(impl_->casters->scene(), &ctx.context, &rh);
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
    if (!impl_->casters->scene()) return true;
    rtcOccluded1(impl_->casters->scene(), &ctx, &ray);  // the counting filter is an intersect filter only
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
    ctx.weights = &volumes.weights;
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
        rtcIntersect16(valid, volumes.scene, &ctx.context, &rh);
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
    TriangleMesh casters;  // copies, compared exactly
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
    for (KeptVolumes& k : s.kept)
        if (k.seen_triangles == seen_triangles && same_lights(k.lights, lights) &&
            k.casters.vertices == casters.vertices && k.casters.triangles == casters.triangles &&
            k.volumes->reaches(viewer) == k.volumes->impl_->reach) {
            k.last_use = ++s.uses;
            return k.volumes;
        }
    if (s.kept.size() >= kKeptVolumes) {  // the least recently used goes before the new one is built
        auto oldest = std::min_element(s.kept.begin(), s.kept.end(), [](const KeptVolumes& a, const KeptVolumes& b) {
            return a.last_use < b.last_use;
        });
        s.kept.erase(oldest);
    }
    auto volumes = std::make_shared<const ShadowVolumes>(casters, lights, viewer, seen_triangles, n_threads);
    ++s.builds;
    s.kept.push_back({casters, lights, seen_triangles, volumes, ++s.uses});
    return volumes;
}

void ShadowVolumes::clear_shared() {
    SharedVolumes& s = shared_volumes();
    std::lock_guard<std::mutex> lock(s.mutex);
    s.kept.clear();
    caster_blocks().clear();
}

long ShadowVolumes::caster_blocks_built() { return caster_blocks().blocks_built(); }

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

const ShadowFaces& ShadowVolumes::faces(int l) const { return impl_->faces[size_t(l)]; }

Vec3 ShadowVolumes::frame() const { return impl_->frame; }

}  // namespace airlight
