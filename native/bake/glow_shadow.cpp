// glow_shadow.cpp: the lit share of the glow on surfaces (glow_shadow.h).
#include "bake/glow_shadow.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "core/constants.h"
#include "core/special_f.h"
#include "homogeneous/sun05.h"

namespace airlight {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// Cosine-weighted directions about +z: Hammersley points (j + 1/2)/N and the radical
// inverse, mapped to the disk (Malley): deterministic, so a surface's R is smooth.
struct Directions {
    Vec3 w[GlowShadow::kDirections];
    Directions() {
        for (int j = 0; j < GlowShadow::kDirections; ++j) {
            unsigned bits = unsigned(j), rev = 0;
            for (int b = 0; b < 4; ++b) rev = (rev << 1) | ((bits >> b) & 1u);
            const double u = (j + 0.5) / GlowShadow::kDirections, v = (rev + 0.5) / 16.0;
            const double r = std::sqrt(u), phi = 2.0 * kPi * v;
            w[j] = Vec3(r * std::cos(phi), r * std::sin(phi), std::sqrt(std::max(0.0, 1.0 - u)));
        }
    }
};

const Directions& directions() {
    static const Directions d;
    return d;
}

}  // namespace

GlowShadow::GlowShadow(const ShadowVolumes& volumes, std::vector<int> positional_volume, std::vector<Vec3> positions,
                       std::vector<int> sun_volume, std::vector<Vec3> sun_directions, double sigma,
                       const CapCut& cut)
    : volumes_(volumes),
      positional_volume_(std::move(positional_volume)),
      positions_(std::move(positions)),
      sun_volume_(std::move(sun_volume)),
      sun_directions_(std::move(sun_directions)),
      sigma_(sigma),
      cut_(cut) {
    for (int v : positional_volume_) any_ = any_ || v >= 0;
    for (int v : sun_volume_) any_ = any_ || v >= 0;
}

void GlowShadow::ratios(const Vec3& p, const Vec3& n, const RayCaster& caster, double* out) const {
    const size_t P = positional_volume_.size(), L = num_lights();
    std::fill(out, out + L, 1.0);
    if (!any_ || !(sigma_ > 0.0)) return;
    // The hemisphere's rays, from just off the surface.
    const Vec3 a = glm::normalize(std::abs(n.x) < 0.9 ? glm::cross(n, Vec3(1, 0, 0)) : glm::cross(n, Vec3(0, 1, 0)));
    const Vec3 b = glm::cross(n, a);
    const Vec3 o = p + (1e-5 * (glm::length(p) + 1.0)) * n;
    Ray rays[kDirections];
    float t0[kDirections], t1[kDirections];
    for (int j = 0; j < kDirections; ++j) {
        const Vec3& w = directions().w[j];
        rays[j] = Ray{o, glm::normalize(w.x * a + w.y * b + w.z * n)};
        t0[j] = 0.0f;
        t1[j] = std::numeric_limits<float>::infinity();
    }
    float hit[kDirections];
    caster.first_hits(rays, kDirections, hit);
    for (int j = 0; j < kDirections; ++j) t1[j] = hit[j];  // +inf where none
    const int V = volumes_.num_lights();
    thread_local std::vector<int> count0;
    count0.resize(size_t(V) * kDirections);
    for (int v = 0; v < V; ++v) {
        const int c = volumes_.count_at(v, o);
        for (int j = 0; j < kDirections; ++j) count0[size_t(j) * V + v] = c;
    }
    thread_local std::vector<LitIntervals> lit(kDirections);
    lit.resize(kDirections);
    volumes_.lit_intervals(rays, t0, t1, kDirections, count0.data(), lit.data(), nullptr, cut_);
    const SpecialFTable* table = shared_special_F_table(256, 256).get();
    auto positional = [&](const Vec3& s, const Vec3& from, const Vec3& d, double len) {
        const Vec3 sv = s - from;
        const double D = glm::length(sv);
        const double cos_gamma = D > 0.0 ? std::clamp(glm::dot(d, sv) / D, -1.0, 1.0) : 1.0;
        return sun05_airlight(sigma_, D, cos_gamma, len, table, FEval::Table);
    };
    for (size_t l = 0; l < L; ++l) {
        const int v = l < P ? positional_volume_[l] : sun_volume_[l - P];
        if (v < 0) continue;
        double lit_sum = 0.0, full_sum = 0.0;
        for (int j = 0; j < kDirections; ++j) {
            const Vec3& d = rays[j].d;
            const LitIntervals& li = lit[j];
            if (l < P) {
                const Vec3& s = positions_[l];
                full_sum += positional(s, o, d, kInf);
                for (int q = li.begin[v]; q < li.end[v]; ++q) {
                    const double ta = li.spans[q].first, tb = li.spans[q].second;
                    if (tb > ta) lit_sum += std::exp(-sigma_ * ta) * positional(s, o + ta * d, d, tb - ta);
                }
            } else {
                full_sum += 1.0;  // sigma int_0^inf e^{-sigma t} dt
                for (int q = li.begin[v]; q < li.end[v]; ++q) {
                    const double ta = li.spans[q].first, tb = li.spans[q].second;
                    lit_sum += std::exp(-sigma_ * ta) - (std::isinf(tb) ? 0.0 : std::exp(-sigma_ * tb));
                }
            }
        }
        out[l] = full_sum > 0.0 ? std::clamp(lit_sum / full_sum, 0.0, 1.0) : 1.0;
    }
}

}  // namespace airlight
