// airlight_batch.cpp: Fogshop's Gaussian terms in float, vectorised (airlight_batch.h).
#include "gaussian/airlight_batch.h"

#include "core/fast_erf.h"
#include "core/target_clones.h"

namespace airlight {

namespace {

AIRLIGHT_SIMD_CLONES void erf_span(const float* k, const float* x1, const float* x2, std::size_t n, float* sum) {
    for (std::size_t j = 0; j < n; ++j) sum[j] += k[j] * fast_erf_diff(x1[j], x2[j]);
}

AIRLIGHT_SIMD_CLONES void point_terms(const float* k, const float* view0, const float* view1, const float* near0,
                                      const float* near1, const float* kl, const float* light_h, const float* light0,
                                      const float* light1, const float* factor, const float* Tlit, std::size_t n,
                                      float near_depth, float* out) {
    for (std::size_t j = 0; j < n; ++j) {
        const float Tvr = k[j] * fast_erf_diff(view0[j], view1[j]);
        const float Tnear = near_depth - k[j] * fast_erf_diff(near0[j], near1[j]);
        const float Tsr = kl[j] * fast_expf_le88(light_h[j]) * fast_erf_diff(light0[j], light1[j]);
        out[j] = factor[j] * fast_expf_le88(Tnear - Tsr - Tvr) * Tlit[j];
    }
}

}  // namespace

void FogshopTermBatch::resize(std::size_t n) {
    for (auto* v : {&k, &view0, &view1, &near0, &near1, &kl, &light_h, &light0, &light1, &factor, &Tlit, &x1, &x2,
                    &out})
        v->resize(n);
}

void add_lit_span(FogshopTermBatch& b, std::size_t n) {
    erf_span(b.k.data(), b.x1.data(), b.x2.data(), n, b.Tlit.data());
}

void fogshop_point_terms(FogshopTermBatch& b, std::size_t n, float near_depth) {
    point_terms(b.k.data(), b.view0.data(), b.view1.data(), b.near0.data(), b.near1.data(), b.kl.data(),
                b.light_h.data(), b.light0.data(), b.light1.data(), b.factor.data(), b.Tlit.data(), n, near_depth,
                b.out.data());
}

}  // namespace airlight
