// erf_steps.cpp: the depth maps' float kernels (erf_steps.h).
#include "gaussian/erf_steps.h"

#include <algorithm>

#include "core/fast_erf.h"
#include "core/target_clones.h"

namespace airlight {

void ErfSteps::clear() {
    for (auto* v : {&k, &ah2, &a, &p, &x1}) v->clear();
    lo.clear(), hi.clear();
}

void ErfSteps::push(float k_j, float ah2_j, float a_j, float p_j, int lo_j, int hi_j) {
    k.push_back(k_j), ah2.push_back(ah2_j), a.push_back(a_j), p.push_back(p_j), x1.push_back(-a_j * p_j);
    lo.push_back(lo_j), hi.push_back(hi_j);
}

namespace {

// K_j = k_j e^{-ah2_j} and e1_j = erfc(|x1_j|), vectorised across the Gaussians.
AIRLIGHT_SIMD_CLONES void step_factors(ErfSteps& steps) {
    const std::size_t n = steps.size();
    steps.K.resize(n), steps.e1.resize(n);
    float *K = steps.K.data(), *e1 = steps.e1.data();
    const float *k = steps.k.data(), *ah2 = steps.ah2.data(), *x1 = steps.x1.data();
    for (std::size_t j = 0; j < n; ++j) {
        K[j] = k[j] * fast_expf_le88(-ah2[j]);
        e1[j] = fast_erfc_pos(x1[j] < 0.0f ? -x1[j] : x1[j]);
    }
}

AIRLIGHT_SIMD_CLONES void erf_bins(const ErfSteps& steps, float dr, int last, float* acc, double* beyond) {
    for (std::size_t j = 0; j < steps.size(); ++j) {
        const float K = steps.K[j], x1 = steps.x1[j], e1 = steps.e1[j], a = steps.a[j], p = steps.p[j];
        const int lo = steps.lo[j], hi = steps.hi[j];
        for (int b = lo; b <= hi; ++b) {
            const float x2 = a * (float(b) * dr - p);
            const float e2 = fast_erfc_pos(x2 < 0.0f ? -x2 : x2);
            // (fast_erf_diff with erfc(|x1|) once: each tail keeps its relative accuracy)
            const float d = x1 >= 0.0f ? e1 - e2 : (x2 <= 0.0f ? e2 - e1 : 2.0f - e1 - e2);
            acc[b] += K * d;
        }
        if (hi < last) beyond[std::max(hi + 1, lo)] += double(K * (x1 >= 0.0f ? e1 : 2.0f - e1));
    }
}

AIRLIGHT_SIMD_CLONES void erfc_bins(const ErfSteps& steps, float ds, int last, float* acc, double* below) {
    for (std::size_t j = 0; j < steps.size(); ++j) {
        const float K = steps.K[j], a = steps.a[j], p = steps.p[j];
        const int lo = steps.lo[j], hi = steps.hi[j];
        for (int b = lo; b <= hi; ++b) {
            const float x = a * (float(b) * ds - p);
            const float e = fast_erfc_pos(x < 0.0f ? -x : x);
            acc[b] += K * (x >= 0.0f ? e : 2.0f - e);
        }
        if (lo > 0) below[std::min(lo, last + 1) - 1] += 2.0 * double(K);
    }
}

}  // namespace

void add_erf_steps(ErfSteps& steps, float dr, int last, float* acc, double* beyond) {
    step_factors(steps);
    erf_bins(steps, dr, last, acc, beyond);
}

void add_erfc_steps(ErfSteps& steps, float ds, int last, float* acc, double* below) {
    step_factors(steps);
    erfc_bins(steps, ds, last, acc, below);
}

}  // namespace airlight
