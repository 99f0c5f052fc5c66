// bake_hoffman02.h: ModelId::Hoffman02, Hoffman & Preetham 2002's daylight aerial perspective
// as a bake model: a Rayleigh + Mie medium with wavelength-dependent extinction lit by sun
// lamps.
//
// Medium per RGB channel c (hoffman02.h): Rayleigh beta_R,c = beta_R(550 nm) (550 / lambda_c)^4
// (scene.medium.rayleigh_550, lambda = 650 / 570 / 475 nm) plus Mie beta_M = medium.sigma_t with
// the medium's Henyey-Greenstein g (Cycles' sign), sigma_c = beta_R,c + beta_M, scattering
// albedo medium.albedo. Along a pixel-centre ray from the near clip point t0 to the first
// hit at depth D (inf: none):
//   Transmittance_c = e^{-sigma_c (D - t0)}
//   Airlight_c      = albedo_c sum_suns E_c (beta_R,c p_R(cos) + beta_M p_HG(cos)) G(sigma_c)
// with G the sun's geometric factor of sunlight_layer.h per channel: HP's unattenuated sun
// ((1 - e^{-sigma_c (D - t0)}) / sigma_c, the paper's closed form) without a fog top, the sun
// dimmed by its path through the layer with one (scene.fog_top). The phase angle is fixed
// along a ray (cos = -w.d), so this is exact single scattering for that medium; its
// reference is hoffman02_quadrature / sunlight_layer_factor_quadrature.
// Sun lamps only: point and spot lights are refused by validate() (the paper models
// daylight), as are fog objects. Pixels are evaluated at their centres (no edge
// supersampling; documented).
#pragma once

#include "bake/bake.h"

namespace airlight {

BakeResult bake_hoffman02(const SceneDescription& scene, const BakeSettings& settings, const ProgressFn& progress);

}  // namespace airlight
