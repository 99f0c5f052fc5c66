// spot_airlight.glsl: airlight of a Blender/Cycles spot light in homogeneous fog for the
// GPU preview; the C++ (native/homogeneous/spot_light.cpp, spot_airlight_quadrature)
// integrates the same integrand adaptively, here it is a fixed rule:
//   La = sigma_t int profile(x) p(cos theta_p) exp(-sigma_t (d(x) + x)) / d(x)^2 dx
// over the part of [0, Dvp] inside the cone (one interval: the cone's half-angle is at
// most pi/2, so it is convex). The interval comes from the analytic ray-cone crossings;
// it is split again where the ray crosses the blend cone (the smoothstep's kink). Each
// piece is integrated in the angle alpha, x = a + h tan(alpha) (a, h: the closest approach
// to the light), where dx / d^2 = dalpha / h takes the 1/d^2 peak out, by
// SPOT_PANELS x 8-point Gauss-Legendre panels. test_preview_phase_spot_sun.py measures it
// against the bake.
// Needs sun05_airlight.glsl (kGLx, kGLw, kPi) and biri06_airlight.glsl (biri06_phase) in
// front of it.
//
// Cone (make_spot_cone): axis unit (the lamp's -Z), cos_half = cos(spot_size / 2),
// smooth = (1 - cos_half) * spot_blend; profile (spot_profile) = cos(theta) *
// smoothstep(0, smooth, cos(theta) - cos_half) inside the cone, 0 outside. An area light's
// sample with a Spread (SpotCone: cos_half = cos(spread / 2), smooth 0): spread = (spread_a,
// spread_b), profile spread_a cos(theta) - spread_b sin(theta), whose kink where the ray
// crosses the axis splits the piece; spread_b = 0: none.

#ifndef SPOT_PANELS
#define SPOT_PANELS 2
#endif
// With volumetric shadows (PREVIEW_SHADOWS 1, shadow_maps.glsl in front): panels per
// piece of a shadowed spot, whose nodes each carry the light's visibility.
#ifndef SPOT_SHADOW_PANELS
#define SPOT_SHADOW_PANELS 4
#endif
#ifndef PREVIEW_SHADOWS
#define PREVIEW_SHADOWS 0
#endif

float spot_profile(float cos_half, float smooth_w, vec2 spread, float cos_theta)
{
  if (!(cos_theta > cos_half)) return 0.0;
  if (spread.y > 0.0)
    return max(0.0, spread.x * cos_theta - spread.y * sqrt(max(0.0, 1.0 - cos_theta * cos_theta)));
  float t = cos_theta - cos_half;
  if (smooth_w > 0.0 && t < smooth_w) {
    float u = t / smooth_w;
    return cos_theta * u * u * (3.0 - 2.0 * u);
  }
  return cos_theta;
}

bool spot_inside(vec3 v, vec3 axis, float cos_half)
{
  return dot(v, axis) >= cos_half * length(v);
}

// The interval [x0, x1] of [lo, hi] (hi may be inf) where o + x d lies inside the cone
// of half-angle acos(cos_half) (cos_half >= 0) around _axis_ with apex _s_; false if empty.
bool spot_cone_interval(vec3 o, vec3 d, vec3 s, vec3 axis, float cos_half, float lo, float hi,
                        out float x0, out float x1)
{
  vec3 w = o - s;
  float k = dot(d, axis), m = dot(w, axis), c2 = cos_half * cos_half;
  float A = k * k - c2, B = 2.0 * (k * m - c2 * dot(d, w)), C = m * m - c2 * dot(w, w);
  float r[2] = float[2](hi, hi);
  if (abs(A) < 1e-12) {
    if (B != 0.0) r[0] = -C / B;
  }
  else {
    float disc = B * B - 4.0 * A * C;
    if (disc >= 0.0) {
      float q = -0.5 * (B + (B >= 0.0 ? sqrt(disc) : -sqrt(disc)));
      float ra = q / A, rb = (q != 0.0) ? C / q : ra;
      r[0] = min(ra, rb);
      r[1] = max(ra, rb);
    }
  }
  float pts[4] = float[4](lo, clamp(r[0], lo, hi), clamp(r[1], lo, hi), hi);
  if (pts[2] < pts[1]) {
    float t = pts[1];
    pts[1] = pts[2];
    pts[2] = t;
  }
  x0 = hi;
  x1 = lo;
  bool any_in = false;
  for (int i = 0; i < 3; i++) {
    float a = pts[i], b = pts[i + 1];
    if (!(b > a)) continue;
    float mid = isinf(b) ? a + 1.0 + abs(a) : 0.5 * (a + b);
    if (spot_inside(w + mid * d, axis, cos_half)) {
      x0 = min(x0, a);
      x1 = max(x1, b);
      any_in = true;
    }
  }
  return any_in && x1 > x0;
}

// Alpha of x on the ray (x = a + h tan(alpha)); x = inf gives pi/2.
float spot_alpha(float x, float a, float h)
{
  return isinf(x) ? 0.5 * kPi : atan(x - a, h);
}

// Airlight of the spot at _s_ along o + x d, x in [0, Dvp] (Dvp may be inf), attenuation
// from _o_, per unit I0 and albedo; phase as in biri06_airlight.glsl when use_phase, else
// isotropic.
// _shadow_row_ >= 0 (PREVIEW_SHADOWS 1 only): each node's integrand times the light's
// visibility from that shadow map (shadow_lit), SPOT_SHADOW_PANELS panels per piece.
// The x in (lo, hi) where o + x d comes closest in direction to _axis_ seen from _s_
// (ray_axis_approach in spot_light.cpp), else lo.
float spot_axis_approach(vec3 o, vec3 d, vec3 s, vec3 axis, float lo, float hi)
{
  vec3 w = o - s;
  float a = -dot(w, d);
  vec3 q = w + a * d;
  float h = length(q);
  if (!(h > 0.0)) return lo;
  float dc = dot(q, axis) / h;
  if (!(dc > 0.0)) return lo;
  float x = a + h * dot(d, axis) / dc;
  return (x > lo && x < hi) ? x : lo;
}

float spot_airlight_shadowed(vec3 s, vec3 axis, float cos_half, float smooth_w, vec2 spread, float sigma_t,
                             vec3 o, vec3 d, float Dvp, bool use_phase, vec4 phase, int shadow_row)
{
  if (sigma_t == 0.0 || !(Dvp > 0.0)) return 0.0;
  float x0, x1;
  if (!spot_cone_interval(o, d, s, axis, cos_half, 0.0, Dvp, x0, x1)) return 0.0;
  // Breakpoints: the blend cone's interval ends inside [x0, x1].
  float cuts[4] = float[4](x0, x0, x1, x1);
  float cos_blend = cos_half + smooth_w;
  float b0, b1;
  if (smooth_w > 0.0 && cos_blend < 1.0 && spot_cone_interval(o, d, s, axis, cos_blend, x0, x1, b0, b1)) {
    cuts[1] = b0;
    cuts[2] = b1;
  }
  if (spread.y > 0.0) {  // the Spread profile's kink on the axis
    cuts[1] = spot_axis_approach(o, d, s, axis, x0, x1);
    cuts[2] = cuts[1];
  }
  vec3 rel = s - o;
  float a = dot(rel, d);
  float h = max(length(cross(rel, d)), 1e-6 * max(length(rel), 1e-6));
  float sum = 0.0;
  for (int piece = 0; piece < 3; piece++) {
    float lo = spot_alpha(cuts[piece], a, h), hi = spot_alpha(cuts[piece + 1], a, h);
    if (!(hi > lo)) continue;
    int panels = shadow_row >= 0 ? SPOT_SHADOW_PANELS : SPOT_PANELS;
    float len = (hi - lo) / float(panels);
    for (int panel = 0; panel < panels; panel++) {
      float part = 0.0;
      for (int k = 0; k < 8; k++) {
        float alpha = lo + len * (float(panel) + kGLx[k]);
        float x = a + h * tan(alpha);
        vec3 v = o + x * d - s;
        float dist = h / cos(alpha);
        float prof = spot_profile(cos_half, smooth_w, spread, dot(v, axis) / dist);
        float p = use_phase ? biri06_phase(phase, -dot(v, d) / dist) : 0.07957747154594767;
        float lit = 1.0;
#if PREVIEW_SHADOWS
        if (shadow_row >= 0) lit = shadow_lit(shadow_row, o + x * d);
#endif
        part += kGLw[k] * prof * p * exp(-sigma_t * (dist + x)) * lit;
      }
      sum += part * len;
    }
  }
  return sigma_t * sum / h;
}

float spot_airlight(vec3 s, vec3 axis, float cos_half, float smooth_w, vec2 spread, float sigma_t, vec3 o,
                    vec3 d, float Dvp, bool use_phase, vec4 phase)
{
  return spot_airlight_shadowed(s, axis, cos_half, smooth_w, spread, sigma_t, o, d, Dvp, use_phase, phase, -1);
}
