// sun05_psf.h: the airlight point-spread function of Sun et al. 2005 (section 6) and its
// use on environment maps: glows around bright parts of the World seen through fog
// (eq. 25-27) and the fog-aware irradiance that the environment gives surfaces.
//
// PSF (eq. 20, Dvp = inf): the airlight from a point source at distance Dsv, normalised by
// I0 / Dsv^2, as a function of the angle gamma between the view ray and the source:
//   PSF(gamma; Tsv) = Dsv^2 La(gamma, Dsv, inf, beta) / I0
//                   = Tsv e^{-Tsv cos g} [F(Tsv sin g, pi/2) - F(Tsv sin g, g/2)] / (2 pi sin g)
// (per unit albedo; it depends on beta and Dsv only through Tsv = beta Dsv). Near gamma = 0 it
// grows like Tsv e^{-Tsv} / (4 sin gamma): integrable over the sphere.
// NPSF (eq. 21, with the sign of NOTES.md: the paper prints e^{cos g - 1} in the numerator):
//   NPSF(gamma) = [F(sin g, pi/2) - F(sin g, g/2)] e^{1 - cos g} / (2 pi sin g),
//   PSF(gamma; Tsv) ~ Tsv e^{-Tsv} NPSF(gamma)                                   (eq. 22)
// The factorisation is the paper's empirical one; psf_factorisation_error() measures it.
//
// Environment maps (eq. 25-27): the World is a set of small sources all at distance Dsv, so
// a texel of radiance L and solid angle dw is a source of I0 = L dw Dsv^2, and the airlight
// seen in direction w is  La(w) = albedo sum_texels L(w') dw' PSF(angle(w, w')), a convolution
// on the sphere with a radially symmetric kernel. By Funk-Hecke it is diagonal in spherical
// harmonics: (L conv k)_lm = lambda_l L_lm with lambda_l = 2 pi int_{-1}^{1} k(mu) P_l(mu) dmu
// (= sqrt(4 pi / (2l + 1)) k_l for the kernel's Y_l0 coefficient k_l: the paper's eq. 25).
// What reaches the eye is L e^{-Tsv} (eq. 27, the Transmittance pass) + La (eq. 26).
//
// Equirectangular maps use Blender's convention for the Environment Texture node with its
// default mapping: u = 1/2 - atan2(d.y, d.x) / (2 pi), v = 1 - acos(d.z) / pi (v = 1 straight
// up; checked against a Cycles render in tests/blender/test_environment.py). Row 0 of the
// arrays here is the TOP of the image (v = 1), like the bake's passes.
#pragma once

#include <functional>
#include <vector>

#include "core/scene.h"

namespace airlight {

// Exact PSF(gamma; Tsv) per unit albedo (eq. 20 with Dvp = inf), through the exact F.
// Tsv > 0, cos_gamma in [-1, 1]. Finite for every gamma > 0 (gamma = 0 returns +inf).
double sun05_psf(double Tsv, double cos_gamma);
// NPSF(gamma) (eq. 21). Finite for gamma > 0.
double sun05_npsf(double cos_gamma);
// The same from the angle itself (gamma in [0, pi]): exact near 0 and pi, where the cosine
// alone has lost the angle.
double sun05_psf_angle(double Tsv, double gamma);
double sun05_npsf_angle(double gamma);

// Funk-Hecke eigenvalues lambda_l = 2 pi int_0^pi k(gamma) P_l(cos gamma) sin(gamma) dgamma,
// l = 0 .. L, by adaptive quadrature (k may have an integrable 1/gamma singularity at 0).
// Composite Gauss-Legendre, graded towards gamma = 0: ~1e-9 relative for the PSF kernels
// (tested against adaptive quadrature and Fogshop's published NPSF coefficients).
std::vector<double> zonal_eigenvalues(const std::function<double(double)>& kernel_of_gamma, int L);

enum class PsfKind { Exact, Factorised };
// lambda_l of the PSF for optical thickness Tsv: Exact (eq. 20) or Factorised (eq. 22:
// Tsv e^{-Tsv} times the NPSF's eigenvalues, computed once and cached).
std::vector<double> psf_eigenvalues(double Tsv, int L, PsfKind kind);

// RGB equirectangular image, row-major, row 0 = top (straight up).
struct EnvironmentMap {
    int width = 0, height = 0;
    std::vector<float> rgb;  // 3 floats per texel
};

// Cycles' equirectangular mapping (see the header comment): unit direction -> (u, v) in
// [0, 1]^2 (v = 1 is up) and back.
void equirect_uv(const Vec3& d, double& u, double& v);
Vec3 equirect_direction(double u, double v);

// Bilinear lookup of _map_ in unit direction _d_ (wraps in u, clamps in v).
RGB environment_lookup(const EnvironmentMap& map, const Vec3& d);

// Real spherical harmonics up to band L: (L + 1)^2 RGB coefficients, index l (l + 1) + m.
struct ShCoefficients {
    int L = 0;
    std::vector<RGB> c;
};
// Projection of an equirectangular map (texel solid angles summed exactly per row).
ShCoefficients sh_project(const EnvironmentMap& map, int L);
// Evaluation on an equirectangular grid (rows = texel centres as in sh_project).
EnvironmentMap sh_reconstruct(const ShCoefficients& sh, int width, int height);
// Zonal convolution: c_lm *= lambda_l (lambda.size() must be > L).
void sh_convolve(ShCoefficients& sh, const std::vector<double>& lambda);
// Irradiance E(n) = int L(w) max(0, n.w) dw from the bands l <= 2 of _sh_ (Ramamoorthi and
// Hanrahan 2001: A0 = pi, A1 = 2 pi / 3, A2 = pi / 4). Needs sh.L >= 2.
RGB sh_irradiance(const ShCoefficients& sh, const Vec3& n);

// Reference: direct convolution out(w) = sum_texels map(w') dw' k(angle(w, w')) on an
// equirectangular grid of out_width x out_height. O(texels^2): small maps only.
EnvironmentMap convolve_direct(const EnvironmentMap& map, const std::function<double(double)>& kernel_of_cos,
                               int out_width, int out_height, int threads = 0);

// The World seen through homogeneous fog (eq. 25-27), per unit albedo (multiply by the
// medium's albedo): _glow_ is the airlight La(w) as an equirectangular map of the given size,
// _transmittance_ = e^{-Tsv} multiplies the World itself. _sh_order_ bands (the paper's path:
// factorised PSF, eq. 22-25) or, with sh_order < 0, the direct convolution with the exact PSF
// (reference; small maps only). Throws std::invalid_argument on bad input (NaN or negative
// texels, sigma_t < 0, distance <= 0, empty map).
struct EnvironmentFog {
    EnvironmentMap glow;
    double transmittance = 1.0;
    ShCoefficients sh_world;     // the World's own coefficients, bands <= 2
    std::vector<double> lambda;  // the PSF's eigenvalues used, bands 0 .. max(2, sh_order)
};
// Irradiance of a surface with normal _n_ from the World without fog (_E_world_) and through
// the fog (_E_fogged_: the attenuated World plus its airlight, eq. 26-27, with the medium's
// albedo on the airlight), from the bands l <= 2 (Lambert's kernel leaves < 1 % beyond).
void environment_irradiance(const EnvironmentFog& fog, const RGB& albedo, const Vec3& n, RGB& E_world,
                            RGB& E_fogged);
EnvironmentFog environment_fog(const EnvironmentMap& world, double sigma_t, double distance, int sh_order,
                               int out_width, int out_height, PsfKind kind = PsfKind::Factorised,
                               int threads = 0);

}  // namespace airlight
