// edges.cpp: see edges.h.
#include "bake/edges.h"

#include <algorithm>
#include <cmath>

#include "core/target_clones.h"

namespace airlight {

namespace {

constexpr int kLine[4][2] = {{1, 0}, {0, 1}, {1, 1}, {1, -1}};

// Kink bits (see bake(): bit l set if the key's second difference along line l exceeds
// 1 % or the line mixes hits and misses) of pixels 1 .. n - 2 of the row _mid_ between
// rows _up_ and _down_. Keys are >= 0, 0 where the ray missed: with mn, mx the least and
// greatest key on a line, "mixes" is mn = 0 < mx, and all-miss lines (mx = 0) pass the
// 1 % test exactly. NaN counts as a kink.
AIRLIGHT_ROW_CLONES
void kink_interior(const float* __restrict up, const float* __restrict mid, const float* __restrict down, int n,
                   unsigned char* __restrict out) {
    auto kink = [](float kp, float ka, float kb) -> int {
        const float mn = std::min(kp, std::min(ka, kb)), mx = std::max(kp, std::max(ka, kb));
        const float d = std::abs(ka + kb - 2.0f * kp);
        return int(!(d <= 0.01f * mn)) | (int(mn == 0.0f) & int(mx > 0.0f));
    };
    for (int i = 1; i < n - 1; ++i) {
        const float kp = mid[i];
        out[i] = (unsigned char)(kink(kp, mid[i - 1], mid[i + 1]) | kink(kp, up[i], down[i]) << 1 |
                                 kink(kp, up[i - 1], down[i + 1]) << 2 | kink(kp, down[i - 1], up[i + 1]) << 3);
    }
}

}  // namespace

// Kinks of pixel (i, j), any position (the image border included).
unsigned EdgeMap::kinks(int i, int j) const {
    const int W = ctx_.W, H = ctx_.H;
    const BakeResult& result = ctx_.result;
    const std::vector<float>& key = ctx_.key;
    const size_t p = size_t(j) * W + i;
    const bool p_miss = std::isinf(result.depth[p]);
    const float kp = key[p];
    unsigned bits = 0;
    for (int l = 0; l < 4; ++l) {
        const int ai = i - kLine[l][0], aj = j - kLine[l][1], bi = i + kLine[l][0], bj = j + kLine[l][1];
        if (ai < 0 || ai >= W || aj < 0 || aj >= H || bi < 0 || bi >= W || bj < 0 || bj >= H) {
            bits |= 1u << l;
            continue;
        }
        const size_t a = size_t(aj) * W + ai, b = size_t(bj) * W + bi;
        const bool a_miss = std::isinf(result.depth[a]), b_miss = std::isinf(result.depth[b]);
        if (p_miss || a_miss || b_miss) {
            if (!(p_miss && a_miss && b_miss)) bits |= 1u << l;
            continue;
        }
        const float ka = key[a], kb = key[b];
        const float tol = 0.01f * std::min(std::abs(kp), std::min(std::abs(ka), std::abs(kb)));
        if (!(std::abs(ka + kb - 2.0f * kp) <= tol)) bits |= 1u << l;  // NaN counts as a kink
    }
    return bits;
}

// The same for a whole row _j_ into _out_[0, W): branch-free on the interior (misses
// are key 0 there), the border pixels by _kinks_.
void EdgeMap::kink_row(int j, unsigned char* out) const {
    const int W = ctx_.W, H = ctx_.H;
    const std::vector<float>& key = ctx_.key;
    if (j == 0 || j == H - 1 || W < 3) {
        for (int i = 0; i < W; ++i) out[i] = (unsigned char)kinks(i, j);
        return;
    }
    out[0] = (unsigned char)kinks(0, j);
    out[W - 1] = (unsigned char)kinks(W - 1, j);
    kink_interior(&key[size_t(j - 1) * W], &key[size_t(j) * W], &key[size_t(j + 1) * W], W, out);
}

// Edge flags of rows [j0, j1) from the kinks of rows [j0 - 1, j1 + 1), kept in a
// buffer with a zero border (one row above and below, one column each side).
void EdgeMap::rows(int j0, int j1, std::vector<unsigned char>& kink, std::vector<unsigned char>& edge) const {
    const int W = ctx_.W, H = ctx_.H;
    const int k0 = std::max(0, j0 - 1), k1 = std::min(H, j1 + 1);
    const size_t stride = size_t(W) + 2;
    kink.assign(size_t(k1 - k0 + 2) * stride, 0);
    for (int j = k0; j < k1; ++j) kink_row(j, &kink[size_t(j - k0 + 1) * stride + 1]);
    edge.assign(size_t(j1 - j0) * W, 0);
    for (int j = j0; j < j1; ++j) {
        const unsigned char* c = &kink[size_t(j - k0 + 1) * stride + 1];
        const unsigned char* u = c - stride;
        const unsigned char* d = c + stride;
        unsigned char* e = &edge[size_t(j - j0) * W];
        for (int i = 0; i < W; ++i) {
            const unsigned n = ((c[i - 1] | c[i + 1]) & 1u) | ((u[i] | d[i]) & 2u) | ((u[i - 1] | d[i + 1]) & 4u) |
                               ((d[i - 1] | u[i + 1]) & 8u);
            e[i] = (unsigned char)((c[i] & n) != 0);
        }
    }
}

}  // namespace airlight
