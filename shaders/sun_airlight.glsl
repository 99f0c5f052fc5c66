// sun_airlight.glsl: single scattering of a sun lamp (directional light) in homogeneous
// fog for the GPU preview: sun_layer_factor is the GLSL twin of sunlight_layer_factor in
// native/homogeneous/sunlight_layer.h
// (the sun lamps of the bake; the derivation is there):
//   La = sigma_s p(cos theta) E G,  cos theta = -dot(w, d)  (w: the sun's propagation
//   direction, the lamp's -Z; theta = 0 looking into the sun), E = colour * strength,
// with G the geometric factor of the view segment [t0, t1] of o + t d:
//   h_top = inf (Hoffman & Preetham 2002: unattenuated sunlight): G = (1 - e^{-sigma L}) / sigma;
//   h_top finite (fog fills z <= h_top, the sun fades through it, mu_s = -w.z):
//   G = e^{-tau_a} (1 - e^{-k L}) / k  (k = sigma (1 - d.z / mu_s) >= 0), or written from
//   the far end for k < 0, over the part [ta, tb] of the segment below the top.
// Needs sun05_airlight.glsl in front of it (airlight_expm1, kInfinite); h_top >= kInfinite
// (or inf) means no top.

float sun_one_minus_exp_over(float k, float L)
{
  if (k == 0.0) return L;
  if (isinf(L) || L >= kInfinite) return 1.0 / k;
  return -airlight_expm1(-k * L) / k;
}

float sun_layer_factor(float sigma_t, float h_top, float mu_s, float o_z, float d_z, float t0, float t1)
{
  if (!(t1 > t0)) return 0.0;
  if (isinf(h_top) || h_top >= kInfinite) return sun_one_minus_exp_over(sigma_t, t1 - t0);
  if (!(mu_s > 0.0)) return 0.0;
  float ta = t0, tb = t1;
  float rise = h_top - o_z;
  if (d_z > 0.0) {
    tb = min(tb, rise / d_z);
  }
  else if (d_z < 0.0) {
    ta = max(ta, rise / d_z);
  }
  else if (rise < 0.0) {
    return 0.0;
  }
  if (!(tb > ta)) return 0.0;
  float L = tb - ta;
  float k = sigma_t * (1.0 - d_z / mu_s);
  if (k >= 0.0) {
    float tau_a = sigma_t * max(0.0, rise - ta * d_z) / mu_s;
    return exp(-tau_a) * sun_one_minus_exp_over(k, L);
  }
  float tau_b = sigma_t * max(0.0, rise - tb * d_z) / mu_s;
  return exp(-sigma_t * L - tau_b) * sun_one_minus_exp_over(-k, L);
}
