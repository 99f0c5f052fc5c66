// airlight_batch.h: Fogshop's Gaussian terms (airlight.h: eq. 11-13 over lit spans) for one
// point light and the Gaussians near one view ray, in float with core/fast_erf.h's kernels
// (~1e-5 relative): FogshopAirlight::eval_rgb_spans's fast form fills the batch (the
// geometry in double) and these loops take its erf differences and exps, vectorised.
#pragma once

#include <cstddef>
#include <vector>

namespace airlight {

// Per Gaussian j, as arrays: the view line's k = c sqrt(pi) / (2a) e^{-a^2 h^2} and erf
// arguments of T_i(v, b_i^r) (view0, view1) and of the part before the near plane (near0,
// near1; both 0 without one); the light line's c sqrt(pi) / (2a) (kl), exponent -a^2 h_s^2
// (light_h) and erf arguments (light0, light1); p / d^2 f1 (factor); and T_i over the lit spans.
struct FogshopTermBatch {
    std::vector<float> k, view0, view1, near0, near1, kl, light_h, light0, light1, factor, Tlit;
    std::vector<float> x1, x2;  // one lit span's erf arguments (add_lit_span)
    std::vector<float> out;
    void resize(std::size_t n);
};

// Tlit[j] += k[j] (erf(x2[j]) - erf(x1[j])) for j < n (x1 <= x2; x2 may be +inf).
void add_lit_span(FogshopTermBatch& b, std::size_t n);

// out[j] = factor[j] exp(near_depth - k (near erfs) - kl e^{light_h} (light erfs) - k (view
// erfs)) Tlit[j] for j < n; _near_depth_ (beta0 t_start + the Gaussians' depth before the near
// plane) must be <= 80.
void fogshop_point_terms(FogshopTermBatch& b, std::size_t n, float near_depth);

}  // namespace airlight
