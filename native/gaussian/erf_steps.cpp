// erf_steps.cpp: the depth maps' float kernels (erf_steps.h).
#include "gaussian/erf_steps.h"

#include <algorithm>
#include <cmath>

#include "core/constants.h"
#include "core/fast_erf.h"
#include "core/target_clones.h"

namespace airlight {

namespace {

// Beyond this many widths of its projection a Gaussian's step is whole (erf(3) = 1 - 2.2e-5):
// the bins past it get the whole step, those before it nothing, each off by at most 1.1e-5 of
// the Gaussian's depth there (the maps' measured errors, 2.5e-4 of the airlight at 0.1 %, are
// 20x that). 4.5 took 58 bins a Gaussian on the 3000-Gaussian cloud, 3 takes 42.
constexpr double kStepReach = 3.0;
// The float kernel's widest vector: a Gaussian's bins are whole vectors of it (a short loop's
// scalar remainder was half its time; the bins added past the reach take the whole step to
// 2e-10, those before it ~0).
constexpr int kPad = 16;

}  // namespace

void ErfSteps::add(const GaussianMedium& medium, std::size_t g, const Vec3& o, const Vec3& r,
                   const GaussianWindow& window, double bin, int last) {
    const double a_g = medium.scale(g), c_g = medium.amplitude(g);
    const Vec3 rel = medium.centre(g) - o;
    const double p_g = glm::dot(rel, r);
    const double ah2_g = a_g * a_g * std::max(0.0, glm::dot(rel, rel) - p_g * p_g);
    // (the pairs a march's window leaves out of the 3000-Gaussian cloud's map at 1 % took ~10 %
    // of its set-up)
    if (ah2_g >= window(c_g * kSqrtPi / a_g)) return;
    const double reach = kStepReach / a_g;
    int lo_g = std::max(0, int(std::ceil((p_g - reach) / bin)));
    int hi_g = std::min(last, int(std::floor((p_g + reach) / bin)));
    if (lo_g <= hi_g) {
        const int n = ((hi_g - lo_g + kPad) / kPad) * kPad;
        hi_g = std::min(last, lo_g + n - 1);
        lo_g = std::max(0, hi_g - n + 1);
    }
    k.push_back(float(c_g * kSqrtPi / (2.0 * a_g))), ah2.push_back(float(ah2_g));
    a.push_back(float(a_g)), p.push_back(float(p_g)), x1.push_back(-float(a_g) * float(p_g));
    lo.push_back(lo_g), hi.push_back(hi_g);
}

void ErfSteps::clear() {
    for (auto* v : {&k, &ah2, &a, &p, &x1}) v->clear();
    lo.clear(), hi.clear();
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
