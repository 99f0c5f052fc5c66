// splat_interp.h: the reduced resolution's interpolation kernels (gaussian/splat_reduced.cpp):
// a tile's lattice (nodes every s pixels at film x0 + s u, y0 + s v; nu per row) to its
// pixels, bilinearly; the far-field grids (gaussian/splat_far_field.cpp) to a tile's lattice,
// by tensor cubic Lagrange weights. A pixel's lattice cell is its top-left node lat[k] with
// the bilinear weights wgt[j kTilePixels + k], j = 0..3 for the nodes a, a + 1, a + nu,
// a + nu + 1 (the tile's pixels regrouped into 4x4 blocks, splat_reduced.cpp). Internal to
// the splat; one vectorised loop each (AIRLIGHT_SIMD_CLONES).
#pragma once

#include "gaussian/splat.h"

namespace airlight {
namespace splat {

// Bilinear interpolation of a tile's lattice sums (cT, cR, cG, cB: nodes every s pixels, nu
// per row) to its w x h pixel centres, added to T, R, G, B.
void interp_lattice(int w, int h, int s, int nu, const float* cT, const float* cR, const float* cG, const float* cB,
                    float* T, float* R, float* G, float* B);

// Subtracts the bilinear interpolation of the lattice values (T, R, G, B; lattice rows of
// nu) at n pixels (cells lat, weights wgt) from the accumulators aT, aR, aG, aB.
void sub_interp(int n, const int* lat, const float* wgt, int nu, const float* T, const float* R, const float* G,
                const float* B, float* aT, float* aR, float* aG, float* aB);
// sub_interp for n pixels inside one lattice cell (top-left index a).
void sub_interp_cell(int n, int a, const float* wgt, int nu, const float* T, const float* R, const float* G,
                     const float* B, float* aT, float* aR, float* aG, float* aB);

// A Gaussian the surface cuts (cut_light_factor): adds Tvp times the bilinear interpolation
// of the lattice light factor (FR, FG, FB) at n pixels whose projection b^r lies before their
// surface (tr < far), nothing at the others.
void add_interp_factor(int n, const int* lat, const float* wgt, int nu, const float* FR, const float* FG,
                       const float* FB, const float* Tvp, const float* tr, const float* far, float* aR, float* aG,
                       float* aB);
// add_interp_factor for n pixels inside one lattice cell (top-left index a).
void add_interp_factor_cell(int n, int a, const float* wgt, int nu, const float* FR, const float* FG,
                            const float* FB, const float* Tvp, const float* tr, const float* far, float* aR,
                            float* aG, float* aB);

// On one 4x4 block (16 pixels, row-major): adds t times the bilinear interpolation of the
// corner pixels' light factors (R4, G4, B4: corners (0,0), (3,0), (0,3), (3,3)).
void add_surface_factor16(const float* t, const float* R4, const float* G4, const float* B4, float* aR, float* aG,
                          float* aB);

// Adds a far-field grid (GaussianSplat::FarGrid: spacing h pixels, nx nodes per row, node
// (P, Q) at film (h (P - 1), h (Q - 1)); channels g[0..4)) at a tile's lattice nodes (film
// x0 + s u, y0 + s v, nu x nv) to c[0..4), by tensor cubic Lagrange interpolation: along x
// on the grid rows the stencils reach, then along y. The grid may be a window of the full
// one: its node (P0, Q0) first, nx per row.
void add_far_grid(const float* const* g, int h, int nx, int P0, int Q0, int x0, int y0, int s, int nu, int nv,
                  float* const* c);

}  // namespace splat
}  // namespace airlight
