// hoffman02.h: Hoffman & Preetham 2002 aerial perspective for a sun (directional light)
// in a homogeneous Rayleigh + Mie medium, per RGB channel.
//
//   F_ex(s) = e^{-(betaR + betaM) s}
//   L_in(s, theta) = (betaR p_R(theta) + betaM p_HG(theta; g)) / (betaR + betaM) * E_sun * (1 - F_ex(s))
//   L = L0 F_ex + L_in
// which is the exact single-scattering integral for constant density when the sunlight
// reaches every point of the view segment unattenuated and unshadowed (the paper's "low
// camera and targets" caveat: the sun's own path through the medium is ignored).
// theta is the phase angle of phase.h: between the sunlight's propagation direction and
// the direction x -> viewer, so cos theta = -dot(sun_dir, view_dir); looking at the sun is
// theta = 0. p_HG uses Cycles' sign (g > 0 forward) and the normalised (1 - g^2) numerator,
// NOT the paper's printed (1 - g)^2 with negative-g-forward (see phase.h).
// Albedo is 1 here as in the paper: betaR, betaM are scattering = extinction coefficients.
//
// Blender sun lamp: strength S is the irradiance in W/m^2 (Cycles) and colour C, so
// E_sun = C * S per channel; sun_dir (propagation) = the lamp's -Z axis,
// -normalize(matrix_world.col[2].xyz).
#pragma once

namespace airlight {

// Wavelengths (nm) representing the R, G, B channels for betaR ~ 1/lambda^4.
inline constexpr double kHoffman02LambdaNm[3] = {650.0, 570.0, 475.0};
inline constexpr double kHoffman02RefLambdaNm = 550.0;

// betaR per channel from the Rayleigh coefficient at 550 nm: betaR_c = beta550 (550/lambda_c)^4.
void hoffman02_rayleigh_rgb(double beta_R_550, double beta_R[3]);

struct Hoffman02Medium {
    double beta_R[3] = {0.0, 0.0, 0.0};  // Rayleigh scattering (= extinction) per channel, 1/m
    double beta_M[3] = {0.0, 0.0, 0.0};  // Mie scattering (= extinction) per channel, 1/m
    double g = 0.0;                       // HG asymmetry of the Mie part (Blender "Anisotropy")
};

// Closed form: extinction F_ex[c] and in-scattered radiance L_in[c] along a view segment of
// length _s_ (may be inf) with phase-angle cosine _cos_theta_ and sun irradiance E_sun[c].
void hoffman02(const Hoffman02Medium& m, const double E_sun[3], double cos_theta, double s, double F_ex[3],
               double L_in[3]);

// cos theta for a sun propagating along _sun_dir_ seen along _view_dir_ (both normalised here).
double hoffman02_cos_theta(const double sun_dir[3], const double view_dir[3]);

// Reference: adaptive quadrature of the single-scattering integral
//   L_in = int_0^s sum_k beta_k p_k(cos theta(x)) E_sun e^{-beta x} dx,
// with cos theta(x) recomputed at every x from the positions (viewer at the origin, point
// x view_dir, light arriving along sun_dir) and the phase functions of phase.h.
void hoffman02_quadrature(const Hoffman02Medium& m, const double E_sun[3], const double sun_dir[3],
                          const double view_dir[3], double s, double L_in[3]);

}  // namespace airlight
