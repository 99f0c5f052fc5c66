// splat_kernels.h: the splat's float kernels of Fogshop's per-(ray, Gaussian) terms (Zhou et
// al. 2007, §5.2-5.3, noise §5.5; the quantities are those of gaussian/splat.h). Each is one
// branch-free loop over the lanes, which GCC vectorises in AVX-512 / AVX2 clones with the
// float functions of fast_erf.h and noise.h:
//  - ray-major (one lane per ray, one call per Gaussian): view_terms, noise_dirs, light_terms,
//    light_terms_phase, sun_terms_phase;
//  - Gaussian-major (one lane per Gaussian, one call per lattice ray): lattice_gaussian_major.
// Internal to the splat (namespace splat); the templates are instantiated in
// splat_kernels.cpp for every combination the splat uses.
#pragma once

#include "core/phase.h"
#include "gaussian/splat.h"

#include <vector>

namespace airlight {
namespace splat {

using GaussF = GaussianSplat::GaussF;
using GaussLightF = GaussianSplat::GaussLightF;
using LightF = GaussianSplat::LightF;

// View-ray part of one Gaussian for n rays: optical depth over [0, tend] (Tvp), over
// [0, b^r] (Tvr) and the clamped projection tr. Noise (splat_gaussian): the same on the
// perturbed directions of noise_dirs gives the perturbed Tvp.
// kInf (reduced resolution's lattice rays): every tend is +inf, the far erfc term is 0.
// kFar (GaussianSplat::GaussF::far_eye): the ray's start lies >= kFarStart / a before the
// Gaussian, so its erfc E1 = erfc(a ts) < 2e-10 is left out (one erfc fewer per lane).
template <bool kInf = false, bool kFar = false>
void view_terms(GaussF g, int n, const float* dx, const float* dy, const float* dz, const float* tend,
                float* Tvp_out, float* Tvr_out, float* tr_out);

// The noise-perturbed view directions for n rays (Fogshop 5.5: lookup at b^r = eye + tr d
// in world space, the unperturbed ray's), in a loop of its own so that it vectorises;
// view_terms on these directions then gives the perturbed Tvp.
void noise_dirs(float nscale, const float* eye, float ninv_scale, float nox, float noy, float noz, int n,
                const float* dx, const float* dy, const float* dz, const float* tr, float* qx_out, float* qy_out,
                float* qz_out);

// Light part: adds w exp(-T_i(s, b^r) - Tvr) Tvp / |b^r - s|^2 to the RGB accumulators.
// kFar (GaussianSplat::GaussF::far_lights): the light lies >= kFarStart / a before the Gaussian
// along every path s -> b^r with b^r in the cull sphere, so the erfc at s is left out.
template <bool kFar = false>
void light_terms(GaussF g, GaussLightF gl, LightF lf, int n, const float* dx, const float* dy, const float* dz,
                 const float* Tvp, const float* Tvr, const float* tr, float* R, float* G, float* B);

// light_terms with the phase function _kind_ (g1 = g, g2 = 1 - g^2, g3 = 1 + g^2 for
// Henyey-Greenstein; an unknown kind counts as isotropic) and, if _spot_, the spot profile
// of light lf: adds w 4 pi p(cos theta) profile exp(-T_i(s, b^r) - Tvr) Tvp / |b^r - s|^2.
void light_terms_phase(PhaseKind kind, bool spot, GaussF g, GaussLightF gl, LightF lf, float g1, float g2, float g3,
                       int n, const float* dx, const float* dy, const float* dz, const float* Tvp, const float* Tvr,
                       const float* tr, float* R, float* G, float* B);

// Sun lamp term with the phase function _kind_ (as light_terms_phase): w 4 pi p(cos theta)
// exp(-T_i(b^r -> sun) - Tvr) Tvp, with Gaussian i's half-line depth from b^r = eye + tr d
// towards the sun (unit (ux, uy, uz) = -w): k0 e^{-a^2 |(b - b^r) x u|^2} erfc(-a (b - b^r).u).
void sun_terms_phase(PhaseKind kind, GaussF g, GaussLightF gl, float ux, float uy, float uz, float g1, float g2,
                     float g3, int n, const float* dx, const float* dy, const float* dz, const float* Tvp,
                     const float* Tvr, const float* tr, float* R, float* G, float* B);

// acc[k] += x[k] for n values.
void add_to(const float* x, int n, float* acc);

// The lattice of a tile at reduced resolution in Gaussian-major order (plain path: isotropic
// point lights, no noise): for each of the m lattice rays (lx, ly, lz), the Dvp = inf terms
// of the n Gaussians gathered in structure-of-arrays form (n a multiple of 16, padded with
// k0 = 0 and zero weights), summed over the Gaussians into T, R, G, B. The same arithmetic
// as view_terms<true> and light_terms, one SIMD lane per Gaussian instead of per ray:
// long loops, no padding of the (16/s + 1)^2 rays, one call per tile instead of per pair.
// Per-(Gaussian, light) data at [l n + k]; ke is GaussF::ke, ske GaussLightF::ke; scratch: 6 n
// floats.
struct LatticeSoA {
    std::vector<float> rx, ry, rz, a, a2, k0, ke, sx, sy, sz, wr, wg, wb, ske, scratch;
    int n = 0;
};
// kFar: every Gaussian of q is far from the eye and the lights (GaussF::far_eye, far_lights).
template <bool kFar>
void lattice_gaussian_major(LatticeSoA& q, int L, const LightF* lf, int m, const float* lx, const float* ly,
                            const float* lz, float* T, float* R, float* G, float* B);

}  // namespace splat
}  // namespace airlight
