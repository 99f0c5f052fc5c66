// edges.h: which pixels lie on depth discontinuities (silhouettes, creases): the edge
// pixels the edge pass supersamples and the homogeneous lattice evaluates exactly.
#pragma once

#include <vector>

#include "bake/context.h"

namespace airlight {

// Edge test, in two steps. A pixel has a "kink" along one of the 4 lines through it
// (horizontal, vertical, 2 diagonals) if the key's second difference along that line
// exceeds 1 %, if the line mixes hits and misses, or if it leaves the image. Pixel p
// and its neighbour r on a line are discontinuous when both kink along it: then
// neither side's linear extrapolation predicts the other. p is an edge pixel if it
// is discontinuous with any of its 8 neighbours.
// Works on pass 1's depth and key images (BakeContext).
class EdgeMap {
  public:
    explicit EdgeMap(const BakeContext& ctx) : ctx_(ctx) {}
    // Kink bits of pixel (i, j), any position (the image border included): bit l for line l
    // of {horizontal, vertical, diagonal, antidiagonal}.
    unsigned kinks(int i, int j) const;
    // The same for a whole row _j_ into _out_[0, W): branch-free on the interior (misses
    // are key 0 there), the border pixels by _kinks_.
    void kink_row(int j, unsigned char* out) const;
    // Edge flags of rows [j0, j1) into _edge_ (W per row) from the kinks of rows [j0 - 1,
    // j1 + 1), kept in _kink_ with a zero border (one row above and below, one column each side).
    void rows(int j0, int j1, std::vector<unsigned char>& kink, std::vector<unsigned char>& edge) const;

  private:
    const BakeContext& ctx_;
};

}  // namespace airlight
