// splat_interp.cpp: the reduced resolution's interpolation kernels (see splat_interp.h).
#include "gaussian/splat_interp.h"

#include <cstddef>

#include "core/target_clones.h"

namespace airlight {
namespace splat {

namespace {
constexpr int kTilePixels = GaussianSplat::kTilePixels;
}  // namespace

AIRLIGHT_SIMD_CLONES void sub_interp_cell(int n, int a, const float* __restrict wgt, int nu,
                                          const float* __restrict T, const float* __restrict R,
                                          const float* __restrict G, const float* __restrict B,
                                          float* __restrict aT, float* __restrict aR, float* __restrict aG,
                                          float* __restrict aB) {
    const int b = a + 1, c = a + nu, d = c + 1;
    const float t0 = T[a], t1 = T[b], t2 = T[c], t3 = T[d];
    const float r0 = R[a], r1 = R[b], r2 = R[c], r3 = R[d];
    const float g0 = G[a], g1 = G[b], g2 = G[c], g3 = G[d];
    const float b0 = B[a], b1 = B[b], b2 = B[c], b3 = B[d];
    for (int k = 0; k < n; ++k) {
        const float w0 = wgt[k], w1 = wgt[kTilePixels + k], w2 = wgt[2 * kTilePixels + k],
                    w3 = wgt[3 * kTilePixels + k];
        aT[k] -= w0 * t0 + w1 * t1 + w2 * t2 + w3 * t3;
        aR[k] -= w0 * r0 + w1 * r1 + w2 * r2 + w3 * r3;
        aG[k] -= w0 * g0 + w1 * g1 + w2 * g2 + w3 * g3;
        aB[k] -= w0 * b0 + w1 * b1 + w2 * b2 + w3 * b3;
    }
}

AIRLIGHT_SIMD_CLONES void sub_interp(int n, const int* __restrict lat, const float* __restrict wgt, int nu,
                                     const float* __restrict T, const float* __restrict R,
                                     const float* __restrict G, const float* __restrict B, float* __restrict aT,
                                     float* __restrict aR, float* __restrict aG, float* __restrict aB) {
    for (int k = 0; k < n; ++k) {
        const int a = lat[k], b = a + 1, c = a + nu, d = c + 1;
        const float w0 = wgt[k], w1 = wgt[kTilePixels + k], w2 = wgt[2 * kTilePixels + k],
                    w3 = wgt[3 * kTilePixels + k];
        aT[k] -= w0 * T[a] + w1 * T[b] + w2 * T[c] + w3 * T[d];
        aR[k] -= w0 * R[a] + w1 * R[b] + w2 * R[c] + w3 * R[d];
        aG[k] -= w0 * G[a] + w1 * G[b] + w2 * G[c] + w3 * G[d];
        aB[k] -= w0 * B[a] + w1 * B[b] + w2 * B[c] + w3 * B[d];
    }
}

// Per row, the sums interpolated along y at each node column, spread to the pixels' left and
// right nodes, then one vectorised blend along x (a free function so that the SIMD clones
// apply; the direct 4-tap form needed gathers).
AIRLIGHT_SIMD_CLONES void interp_lattice(int w, int h, int s, int nu, const float* __restrict cT,
                                         const float* __restrict cR, const float* __restrict cG,
                                         const float* __restrict cB, float* __restrict T, float* __restrict R,
                                         float* __restrict G, float* __restrict B) {
    constexpr int kMaxNodes = GaussianSplat::kTile + 1;
    const float inv_s = 1.0f / float(s);
    int ui[GaussianSplat::kTile];
    float wx[GaussianSplat::kTile];
    for (int i = 0; i < w; ++i) {
        const float fx = (float(i) + 0.5f) * inv_s;
        ui[i] = int(fx);
        wx[i] = fx - float(ui[i]);
    }
    const float* c[4] = {cT, cR, cG, cB};
    float* out[4] = {T, R, G, B};
    // Along x once per lattice row (the rows a pixel row needs: v and v + 1), then each
    // pixel row between two of those: the gathers run per lattice row, not per pixel row.
    const int nv = int((float(h) - 0.5f) * inv_s) + 2;
    for (int q = 0; q < 4; ++q) {
        float rows[kMaxNodes][GaussianSplat::kTile];
        for (int v = 0; v < nv; ++v) {
            const float* node = c[q] + v * nu;
            float lo[GaussianSplat::kTile], hi[GaussianSplat::kTile];
            for (int i = 0; i < w; ++i) {
                lo[i] = node[ui[i]];
                hi[i] = node[ui[i] + 1];
            }
            for (int i = 0; i < w; ++i) rows[v][i] = (1.0f - wx[i]) * lo[i] + wx[i] * hi[i];
        }
        for (int j = 0; j < h; ++j) {
            const float fy = (float(j) + 0.5f) * inv_s;
            const int v = int(fy);
            const float wy = fy - float(v);
            const float* top = rows[v];
            const float* bot = rows[v + 1];
            float* o = out[q] + j * w;
            for (int i = 0; i < w; ++i) o[i] += (1.0f - wy) * top[i] + wy * bot[i];
        }
    }
}

AIRLIGHT_SIMD_CLONES void add_interp_factor(int n, const int* __restrict lat, const float* __restrict wgt, int nu,
                                            const float* __restrict FR, const float* __restrict FG,
                                            const float* __restrict FB, const float* __restrict Tvp,
                                            const float* __restrict tr, const float* __restrict far,
                                            float* __restrict aR, float* __restrict aG, float* __restrict aB) {
    for (int k = 0; k < n; ++k) {
        const int a = lat[k], b = a + 1, c = a + nu, d = c + 1;
        const float w0 = wgt[k], w1 = wgt[kTilePixels + k], w2 = wgt[2 * kTilePixels + k],
                    w3 = wgt[3 * kTilePixels + k];
        const float t = tr[k] < far[k] ? Tvp[k] : 0.0f;
        aR[k] += t * (w0 * FR[a] + w1 * FR[b] + w2 * FR[c] + w3 * FR[d]);
        aG[k] += t * (w0 * FG[a] + w1 * FG[b] + w2 * FG[c] + w3 * FG[d]);
        aB[k] += t * (w0 * FB[a] + w1 * FB[b] + w2 * FB[c] + w3 * FB[d]);
    }
}

AIRLIGHT_SIMD_CLONES void add_interp_factor_cell(int n, int a, const float* __restrict wgt, int nu,
                                                 const float* __restrict FR, const float* __restrict FG,
                                                 const float* __restrict FB, const float* __restrict Tvp,
                                                 const float* __restrict tr, const float* __restrict far,
                                                 float* __restrict aR, float* __restrict aG, float* __restrict aB) {
    const int b = a + 1, c = a + nu, d = c + 1;
    const float r0 = FR[a], r1 = FR[b], r2 = FR[c], r3 = FR[d];
    const float g0 = FG[a], g1 = FG[b], g2 = FG[c], g3 = FG[d];
    const float b0 = FB[a], b1 = FB[b], b2 = FB[c], b3 = FB[d];
    for (int k = 0; k < n; ++k) {
        const float w0 = wgt[k], w1 = wgt[kTilePixels + k], w2 = wgt[2 * kTilePixels + k],
                    w3 = wgt[3 * kTilePixels + k];
        const float t = tr[k] < far[k] ? Tvp[k] : 0.0f;
        aR[k] += t * (w0 * r0 + w1 * r1 + w2 * r2 + w3 * r3);
        aG[k] += t * (w0 * g0 + w1 * g1 + w2 * g2 + w3 * g3);
        aB[k] += t * (w0 * b0 + w1 * b1 + w2 * b2 + w3 * b3);
    }
}

AIRLIGHT_SIMD_CLONES void add_surface_factor16(const float* __restrict t, const float* __restrict R4,
                                               const float* __restrict G4, const float* __restrict B4,
                                               float* __restrict aR, float* __restrict aG, float* __restrict aB) {
    static constexpr float kU[16] = {0.0f, 1.0f / 3.0f, 2.0f / 3.0f, 1.0f, 0.0f, 1.0f / 3.0f, 2.0f / 3.0f, 1.0f,
                                     0.0f, 1.0f / 3.0f, 2.0f / 3.0f, 1.0f, 0.0f, 1.0f / 3.0f, 2.0f / 3.0f, 1.0f};
    static constexpr float kV[16] = {0.0f,        0.0f,        0.0f,        0.0f,        1.0f / 3.0f, 1.0f / 3.0f,
                                     1.0f / 3.0f, 1.0f / 3.0f, 2.0f / 3.0f, 2.0f / 3.0f, 2.0f / 3.0f, 2.0f / 3.0f,
                                     1.0f,        1.0f,        1.0f,        1.0f};
    const float r0 = R4[0], r1 = R4[1], r2 = R4[2], r3 = R4[3];
    const float g0 = G4[0], g1 = G4[1], g2 = G4[2], g3 = G4[3];
    const float b0 = B4[0], b1 = B4[1], b2 = B4[2], b3 = B4[3];
    for (int k = 0; k < 16; ++k) {
        const float u = kU[k], v = kV[k];
        const float w0 = (1.0f - u) * (1.0f - v), w1 = u * (1.0f - v), w2 = (1.0f - u) * v, w3 = u * v;
        aR[k] += t[k] * (w0 * r0 + w1 * r1 + w2 * r2 + w3 * r3);
        aG[k] += t[k] * (w0 * g0 + w1 * g1 + w2 * g2 + w3 * g3);
        aB[k] += t[k] * (w0 * b0 + w1 * b1 + w2 * b2 + w3 * b3);
    }
}

namespace {

// Cubic Lagrange weights of the nodes -1, 0, 1, 2 at f in [0, 1).
inline void cubic_weights(float f, float* w) {
    w[0] = -f * (f - 1.0f) * (f - 2.0f) * (1.0f / 6.0f);
    w[1] = (f + 1.0f) * (f - 1.0f) * (f - 2.0f) * 0.5f;
    w[2] = -(f + 1.0f) * f * (f - 2.0f) * 0.5f;
    w[3] = (f + 1.0f) * f * (f - 1.0f) * (1.0f / 6.0f);
}

}  // namespace

AIRLIGHT_SIMD_CLONES void add_far_grid(const float* const* g, int h, int nx, int P0, int Q0, int x0, int y0, int s,
                                       int nu, int nv, float* const* c) {
    constexpr int kMax = GaussianSplat::kTile + 1;
    int pu[kMax], qv[kMax];
    float wu[kMax][4], wv[kMax][4];
    for (int u = 0; u < nu; ++u) {
        const int x = x0 + s * u;
        pu[u] = x / h;
        cubic_weights(float(x - pu[u] * h) / float(h), wu[u]);
    }
    for (int v = 0; v < nv; ++v) {
        const int y = y0 + s * v;
        qv[v] = y / h;
        cubic_weights(float(y - qv[v] * h) / float(h), wv[v]);
    }
    const int Qa = qv[0], Qb = qv[nv - 1] + 3;  // grid rows the stencils reach
    float rows[kMax + 3][kMax];
    for (int q = 0; q < 4; ++q) {
        for (int Q = Qa; Q <= Qb; ++Q) {
            const float* r = g[q] + std::size_t(Q - Q0) * nx;
            for (int u = 0; u < nu; ++u) {
                const float* p = r + (pu[u] - P0);
                rows[Q - Qa][u] = wu[u][0] * p[0] + wu[u][1] * p[1] + wu[u][2] * p[2] + wu[u][3] * p[3];
            }
        }
        for (int v = 0; v < nv; ++v) {
            const int o = qv[v] - Qa;
            float* out = c[q] + v * nu;
            for (int u = 0; u < nu; ++u)
                out[u] += wv[v][0] * rows[o][u] + wv[v][1] * rows[o + 1][u] + wv[v][2] * rows[o + 2][u] +
                          wv[v][3] * rows[o + 3][u];
        }
    }
}

}  // namespace splat
}  // namespace airlight
