// block_faces.cpp: see block_faces.h.
#include "shadow/block_faces.h"

#include "core/parallel.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <limits>
#include <stdexcept>
#include <string>

namespace airlight {

namespace {

// The volumes' quads go from ring to ring, each this much farther from the light (see
// block_faces), at most this many rings.
constexpr double kRingGrowth = 2.0;
constexpr int kMaxRings = 48;

// The sine of the angle between a caster's plane and the direction to the light below which
// the caster gets no shadow volume (it is seen edge-on).
constexpr double kEdgeOn = 1e-6;

bool same_light(const ShadowLight& a, const ShadowLight& b) {
    return a.directional == b.directional && a.position == b.position && a.direction == b.direction;
}

// Whether triangle a b c of floats has an area (in doubles, as the welded positions).
bool has_area(const float* a, const float* b, const float* c) {
    const Vec3 pa(a[0], a[1], a[2]), pb(b[0], b[1], b[2]), pc(c[0], c[1], c[2]);
    return glm::length(glm::cross(pb - pa, pc - pa)) > 0.0;
}

}  // namespace

BlockGeometry block_geometry(const float* vertices, size_t n_vertices, const uint32_t* triangles,
                             size_t n_triangles, const Vec3& frame, int n_threads) {
    BlockGeometry out;
    // Welded by exact position in an open-addressing table (a std::unordered_map's node per
    // vertex cost 2.4 s for the 5e6 vertices of 1e7 triangles): the welded vertices keep the
    // order of their first use.
    std::vector<uint32_t> remap(n_vertices);
    size_t capacity = 16;
    while (capacity < 2 * n_vertices) capacity *= 2;
    std::vector<uint32_t> slot(capacity, UINT32_MAX);  // welded index, or none
    std::vector<Vec3>& position = out.position;
    position.reserve(n_vertices);
    for (size_t k = 0; k < n_vertices; ++k) {
        std::array<float, 3> p{vertices[3 * k], vertices[3 * k + 1], vertices[3 * k + 2]};
        for (float& c : p)
            if (c == 0.0f) c = 0.0f;  // -0 and +0 weld
        std::array<uint32_t, 3> key;  // (the hash's; the positions compare as doubles of the floats)
        std::memcpy(key.data(), p.data(), sizeof(key));
        const Vec3 welded(p[0], p[1], p[2]);
        uint64_t h = (uint64_t(key[0]) * 0x9E3779B97F4A7C15ull) ^ (uint64_t(key[1]) * 0xC2B2AE3D27D4EB4Full) ^
                     (uint64_t(key[2]) * 0x165667B19E3779F9ull);
        h ^= h >> 29;
        for (size_t i = size_t(h) & (capacity - 1);; i = (i + 1) & (capacity - 1)) {
            if (slot[i] == UINT32_MAX) {
                slot[i] = uint32_t(position.size());
                position.push_back(welded);
                remap[k] = slot[i];
                break;
            }
            if (position[slot[i]] == welded) {
                remap[k] = slot[i];
                break;
            }
        }
    }
    out.triangles.resize(3 * n_triangles);
    for (size_t k = 0; k < 3 * n_triangles; ++k) out.triangles[k] = remap[triangles[k]];
    const size_t nv = position.size(), nt = n_triangles;
    for (Vec3& p : position) p -= frame;
    // Every triangle's directed edges (p -> q, as wound), grouped by undirected edge (u < v) in
    // (u, v) order: each light sums its sides' orientations edge by edge from them, without a
    // hash map. A counting sort on u, then each u's few uses sorted by v (a std::sort of the
    // 3e7 uses of 1e7 triangles took 2 s).
    if (3 * nt >= size_t(UINT32_MAX)) throw std::invalid_argument("shadow volumes: too many caster triangles");
    std::vector<uint32_t>& use_first = out.use_first;
    use_first.assign(nv + 1, 0);  // per u: where its uses start
    for (size_t k = 0; k < 3 * nt; ++k) {
        const uint32_t p = out.triangles[k], q = out.triangles[k % 3 == 2 ? k - 2 : k + 1];
        ++use_first[std::min(p, q) + 1];
    }
    for (size_t u = 0; u < nv; ++u) use_first[u + 1] += use_first[u];
    std::vector<uint64_t>& uses = out.uses;
    uses.resize(3 * nt);
    {
        std::vector<uint32_t> fill(use_first.begin(), use_first.end() - 1);
        for (size_t k = 0; k < 3 * nt; ++k) {
            const uint32_t p = out.triangles[k], q = out.triangles[k % 3 == 2 ? k - 2 : k + 1];
            uses[fill[std::min(p, q)]++] =
                (uint64_t(std::max(p, q)) << 32) | (uint64_t(k / 3) << 1) | (p < q ? 1u : 0u);
        }
    }
    const int parts = std::max(n_threads, 1);
    parallel_for(parts, parts, [&](int part) {
        for (size_t u = nv * size_t(part) / size_t(parts), end = nv * size_t(part + 1) / size_t(parts); u < end; ++u)
            std::sort(uses.begin() + use_first[u], uses.begin() + use_first[u + 1]);
    });
    return out;
}

ShadowFaces block_faces(const BlockGeometry& mesh, const ShadowLight& light, double R, double extent, size_t seen) {
    const size_t nv = mesh.position.size(), nt = mesh.triangles.size() / 3;
    const std::vector<uint32_t>& use_first = mesh.use_first;
    const std::vector<uint64_t>& uses = mesh.uses;
    std::vector<int8_t> orient(nt);       // per triangle: +1 as wound, -1 reversed, 0 none
    std::vector<uint32_t> ring_slot(nv);  // a silhouette vertex's place in each ring
    const Vec3 s = light.position, w = glm::normalize(light.direction);
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
        if (k < seen) ++n_seen_caps;
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
    ShadowFaces faces;
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
    return faces;
}

double VolumeBlocks::Block::vertex_far(const ShadowLight& light, const Vec3& frame) {
    for (const Far& f : far)
        if (same_light(f.light, light) && f.frame == frame) return f.far;
    double out = 0.0;
    const size_t nv = used.size();
    for (size_t k = 0; k < nv; ++k)
        if (used[k]) {
            const float* v = &copy.vertices[3 * k];
            const Vec3 p = Vec3(v[0], v[1], v[2]) - frame;
            out = std::max(out, glm::length(p - light.position));
        }
    far.push_back({light, frame, out});
    return out;
}

std::shared_ptr<const ShadowFaces> VolumeBlocks::Block::find(const ShadowLight& light, const Vec3& frame,
                                                             double reach, double extent, size_t seen, long use) {
    for (Faces& f : faces)
        if (same_light(f.light, light) && f.frame == frame && f.reach == reach && f.extent == extent &&
            f.seen == seen) {
            f.last_use = use;
            return f.faces;
        }
    return nullptr;
}

VolumeBlocks::Block::Counting::~Counting() {
    if (scene) rtcReleaseScene(scene);
}

CasterBlocks VolumeBlocks::blocks(const TriangleMesh& casters) {
    const size_t n_vertices = casters.vertices.size() / 3, nt = casters.triangles.size() / 3;
    for (size_t k = 0; k < 3 * nt; ++k)
        if (casters.triangles[k] >= n_vertices)
            throw std::invalid_argument("triangle index " + std::to_string(casters.triangles[k]) +
                                        " out of range (vertex count " + std::to_string(n_vertices) + ")");
    CasterBlocks result;
    result.cuts = soup_blocks(casters.triangles.data(), nt, BlockCache::kMinBlockTriangles);
    const std::vector<SoupBlock>& cuts = result.cuts;
    const float* vertices = casters.vertices.data();
    const uint32_t* triangles = casters.triangles.data();
    std::vector<const SoupCopy*> copies;
    for (const auto& block : kept_) copies.push_back(&block->copy);
    std::vector<uint64_t> hashes;
    const std::vector<long> match = match_blocks(copies, vertices, triangles, cuts, hashes);
    std::vector<std::shared_ptr<Block>> out(cuts.size());
    for (size_t b = 0; b < cuts.size(); ++b) {
        if (match[b] >= 0) {
            out[b] = kept_[size_t(match[b])];
        } else {
            const SoupBlock& c = cuts[b];
            auto block = std::make_shared<Block>();
            block->copy = SoupCopy(vertices, triangles, c, hashes[b]);
            const std::vector<float>& v = block->copy.vertices;
            block->used.assign(v.size() / 3, 0);
            const std::vector<uint32_t>& t = block->copy.triangles;
            for (size_t k = 0; k < t.size(); k += 3)
                if (has_area(&v[3 * t[k]], &v[3 * t[k + 1]], &v[3 * t[k + 2]]))
                    block->used[t[k]] = block->used[t[k + 1]] = block->used[t[k + 2]] = 1;
            Vec3 lo(std::numeric_limits<double>::infinity()), hi(-std::numeric_limits<double>::infinity());
            for (size_t k = 0; k < block->used.size(); ++k)
                if (block->used[k]) {
                    const Vec3 p(v[3 * k], v[3 * k + 1], v[3 * k + 2]);
                    lo = glm::min(lo, p), hi = glm::max(hi, p);
                }
            block->lo = lo, block->hi = hi;
            out[b] = std::move(block);
        }
        out[b]->last_use = use_;
    }
    // The soup's blocks in its order (the next soup's are compared with them place by place
    // first), then the older ones.
    std::vector<std::shared_ptr<Block>> kept = out;
    for (size_t k = 0; k < kept_.size(); ++k)
        if (std::find(match.begin(), match.end(), long(k)) == match.end()) kept.push_back(kept_[k]);
    kept_ = std::move(kept);
    result.blocks = std::move(out);
    return result;
}

void VolumeBlocks::finish_build() {
    kept_.erase(std::remove_if(kept_.begin(), kept_.end(),
                               [&](const std::shared_ptr<Block>& b) { return b->last_use < use_ - 1; }),
                kept_.end());
    for (const auto& block : kept_) {
        auto& faces = block->faces;
        faces.erase(std::remove_if(faces.begin(), faces.end(),
                                   [&](const Block::Faces& f) { return f.last_use <= use_ - kKeptBuilds; }),
                    faces.end());
        if (block->far.size() > size_t(4 * kKeptBuilds)) block->far.clear();
    }
    ++use_;
}

void VolumeBlocks::clear() {
    std::lock_guard<std::mutex> lock(mutex_);
    kept_.clear();
}

VolumeBlocks& volume_blocks() {
    static VolumeBlocks instance;
    return instance;
}

}  // namespace airlight
