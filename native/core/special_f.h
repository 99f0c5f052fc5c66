// special_f.h: Sun et al. 2005's special function
//   F(u, v) = int_0^v exp(-u tan xi) dxi,   u >= 0, 0 <= v <= pi/2
// written in the variable T = tan v (no trigonometry in the hot path):
//   F(u, T) = int_0^T exp(-u t) / (1 + t^2) dt.
// Served by an exact evaluator (reference) and a table (fast path) whose layout
// and worst-case error are documented in special_f.cpp.
#pragma once

#include <memory>

#include <vector>

namespace airlight {

// Exact F(u, v) to ~1e-12 relative, for u >= 0, v in [0, pi/2] (v = pi/2 allowed).
double special_F_exact(double u, double v);
// Same, in T = tan v (T may be +inf).
double special_F_exact_tan(double u, double T);
// Exact scaled difference e^{u t0} [F(u, t0 + dt) - F(u, t0)]
//   = e^{u t0} int_{t0}^{t0+dt} e^{-u t} / (1 + t^2) dt   (dt may be +inf),
// evaluated directly (no subtraction), ~1e-12 relative.
double special_F_diff_exact(double u, double t0, double dt);

// Table layout (see special_f.cpp and sun05_inline.h, mirrored by the GLSL preview):
//   s = sqrt(u / (u + kSpecialFTableK))    in [0, 1]  (row index i = s (nu - 1))
//   w = tau / (1 + tau), tau = T (1 + u)   in [0, 1]  (column index j = w (nT - 1))
//   stored Q(s, w) = F(u, T) (1 + u) / w   (Q = 1 at w = 0), so F = Q w / (1 + u).
#ifndef AIRLIGHT_F_TABLE_K
#define AIRLIGHT_F_TABLE_K 1.0
#endif
inline constexpr double kSpecialFTableK = AIRLIGHT_F_TABLE_K;

// Interpolation used for table lookups.
enum class Interp { Nearest, Bilinear };

// Tabulated F. Construction is deterministic; the table is shared by the bake and,
// uploaded as a texture, by the GLSL preview (the same data and the same mapping).
class SpecialFTable {
  public:
    // _nu_ x _nT_ samples over the remapped axes documented in special_f.cpp.
    explicit SpecialFTable(int nu = 256, int nT = 256, Interp interp = Interp::Bilinear);

    // F(u, T=tan v). Never clamps silently: outside the tabulated range it uses the
    // asymptotic form or the exact evaluator.
    double eval_tan(double u, double T) const;
    double eval(double u, double v) const;  // convenience, v in [0, pi/2]

    int nu() const { return nu_; }
    int nT() const { return nT_; }
    Interp interp() const { return interp_; }
    // Row-major [iu][iT] float data of the stored quantity (see special_f.cpp), for upload.
    const std::vector<float>& data() const { return data_; }

  private:
    int nu_, nT_;
    Interp interp_;
    std::vector<float> data_;
};

// The F table for (nu, nT, interp), built once and shared for the life of the process
// (thread safe).
std::shared_ptr<const SpecialFTable> shared_special_F_table(int nu, int nT, Interp interp = Interp::Bilinear);

}  // namespace airlight
