// preview_common.glsl: the view ray, surface distance and fog of one viewport pixel,
// shared by fog_preview_frag.glsl (full or reduced resolution) and
// preview_upsample_frag.glsl (which re-evaluates pixels at depth discontinuities).
// Needs sun05_airlight.glsl in front of it and these inputs:
//   Ftab        F table (R32F) from _native.special_F_table()
//   depth_tex   full-resolution scene depth of the region (R32F): the linear distance
//               _Dvp_ along the view ray (inf = nothing hit) or, with
//               PREVIEW_WINDOW_DEPTH defined to 1, the window depth in [0, 1] (1 = none)
//   lights      RGBA32F, light_count x 2 texels: row 0 = position (world), row 1 =
//               rgb: albedo * I0 (W/sr per RGB channel), a: C_sv, the transmittance of
//               the Gaussian fog on the segment light -> eye (Fogshop eq. 15-17; 1
//               without fog objects), which scales the homogeneous airlight
//   inv_persp   inverse of (projection * view) of the region
//   eye         xyz = view origin (world), w = 1 for perspective, 0 for orthographic
//   clip        xyz = unit view axis (world, into the scene), w = clip_start: the near
//               plane's view-axis depth, where the fog begins (Cycles starts camera rays
//               there); the far plane needs no input, the depth pass already clips there
//   viewport    zw = full-resolution size of the region in pixels
//   pv_sigma_t  extinction coefficient (1/m); light_count = number of lights
//   (inv_persp, eye, clip, viewport, pv_sigma_t, light_count, pv_phase, pv_scale, pv_mode
//   are members of the uniform buffer of preview_params.glsl, read through defines)
//   PREVIEW_PHASE  1: the airlight of a non-isotropic phase function through the Biri
//               2006 table (biri06_airlight.glsl, needs it in front; inputs Gtab and
//               pv_phase = (kind, g, K, k)); 0: Sun 2005 (isotropic)
//   PREVIEW_SPOTS  1: spot lights (spot_airlight.glsl, needs it in front): spots,
//               RGBA32F spot_count x 4 texels: row 0 = (position, cos(size / 2)), row 1 =
//               (unit axis, (1 - cos(size / 2)) blend), row 2 = albedo * I0, row 3 =
//               (spread_a, spread_b, 0, 0) (an area light's Spread; spread_b 0: none); with
//               the phase of PREVIEW_PHASE
//   PREVIEW_SUNS   1: sun lamps (sun_airlight.glsl, needs it in front): suns, RGBA32F
//               sun_count x 2 texels: row 0 = (unit propagation direction w (the lamp's
//               -Z), fog top height h_top (inf: none)), row 1 = albedo * colour * strength
//   PREVIEW_SHADOWS  1: volumetric shadows (shadow_maps.glsl, needs it in front): the
//               shadow-map row of each light (-1: unshadowed) in lights row 2 .a, spots
//               row 2 .a and suns row 1 .a; a shadowed light's airlight is marched
//               (preview_point_lit_share, preview_sun_shadowed; spots: the visibility in
//               spot_airlight's quadrature nodes)

#ifndef PREVIEW_SHADOWS
#  define PREVIEW_SHADOWS 0
#endif
// Steps of the march along a view ray per shadowed point light or sun.
#ifndef SHADOW_STEPS
#  define SHADOW_STEPS 32
#endif

vec3 preview_unproject(vec2 ndc_xy, float ndc_z)
{
  vec4 p = inv_persp * vec4(ndc_xy, ndc_z, 1.0);
  return p.xyz / p.w;
}

// View ray through the centre of full-resolution pixel _px_: from the eye
// (perspective) or from the near plane (orthographic).
void preview_ray(ivec2 px, out vec2 ndc, out vec3 origin, out vec3 dir)
{
  ndc = (vec2(px) + 0.5) / viewport.zw * 2.0 - 1.0;
  vec3 p_near = preview_unproject(ndc, -1.0);
  vec3 p_far = preview_unproject(ndc, 1.0);
  origin = (eye.w > 0.5) ? eye.xyz : p_near;
  dir = normalize(p_far - p_near);
}

const float PREVIEW_INF = uintBitsToFloat(0x7F800000u);

// Surface distance at full-resolution pixel _px_ (inf where nothing is hit).
float preview_distance(ivec2 px, vec2 ndc, vec3 origin, vec3 dir)
{
  float d = texelFetch(depth_tex, px, 0).r;
#if PREVIEW_WINDOW_DEPTH
  if (d >= 1.0) {
    return PREVIEW_INF;
  }
  vec3 p = preview_unproject(ndc, d * 2.0 - 1.0);
  return max(dot(p - origin, dir), 0.0);
#else
  return d;
#endif
}

// Distance along the view ray _dir_ from _origin_ (preview_ray) to the near clip plane:
// clip_start / cos(angle to the view axis) from the eye; 0 for orthographic rays, which
// already start on the projection's near plane.
float preview_near(vec3 dir)
{
  return (eye.w > 0.5) ? clip.w / max(dot(dir, clip.xyz), 1e-6) : 0.0;
}

// Airlight of a point light over [0, x] of the view ray from p0 (per unit I0): the
// model's closed form or table (Sun 2005, or Biri 2006 for PREVIEW_PHASE 1).
float preview_point_airlight(float Dsv, float cos_gamma, float x)
{
#if PREVIEW_PHASE
  return biri06_airlight(Gtab, pv_phase, pv_sigma_t, Dsv, cos_gamma, x);
#else
  return sun05_airlight(Ftab, pv_sigma_t, Dsv, cos_gamma, x);
#endif
}

// A point light's Radius (Blender's shadow_soft_size; native homogeneous/sphere_light.h):
// Cycles 3.4 takes it as the disk facing each point, whose falloff per unit intensity is
//   F_r(d) = (2 d / r^2) int_{1/D}^{1/d} e^{-sigma_t / u} du,  D = sqrt(d^2 + r^2)
// (u = 1 / rho, over which the integrand is smooth: 4-point Gauss-Legendre; 2 / r^2 at the
// light, the point's e^{-sigma_t d} / d^2 far from it).
float preview_disk_falloff(float d, float r)
{
  float lo = inversesqrt(d * d + r * r), hi = 1.0 / max(d, 1e-6 * r);
  float sum = 0.0;
  for (int k = 0; k < 4; k++) {
    sum += kGL4w[k] * exp(-pv_sigma_t / mix(lo, hi, kGL4x[k]));
  }
  return 2.0 * d / (r * r) * (hi - lo) * sum;
}

#ifndef PREVIEW_SPOT_SIZE_PANELS
#define PREVIEW_SPOT_SIZE_PANELS 4
#endif
// The disk light's in-scattering over the part [ta, tb] of [0, D] of the ray p0 + x dir
// within the reach of the light at _s_ (where the disk differs from the point by more
// than 1e-3: sqrt(0.75e3) radii, cut at 10 optical depths where sigma_t r is large), per unit
// albedo I0, attenuated from p0: Gauss-Legendre in the angle about the closest approach a
// (x = a + w tan(phi), w^2 = h^2 + r^2 / 2, which flattens F_r's peak), 8 nodes on each side of
// a (a spot: PREVIEW_SPOT_SIZE_PANELS x 8). A spot (spot >= 0: its row of the spots texture)
// weighs each node by its cone's profile, and a shadowed one (row >= 0) by its visibility there. tb <= ta: the ray stays out of reach.
float preview_disk_light(vec3 s, vec3 p0, vec3 dir, float D, float r, int spot, int row, out float ta,
                         out float tb)
{
  vec3 rel = s - p0;
  float a = dot(rel, dir);
  float h2 = max(dot(rel, rel) - a * a, 0.0);
  float reach = min(27.386128 * r, max(10.0 / max(pv_sigma_t, 1e-30), 10.0 * r));
  ta = 0.0;
  tb = 0.0;
  if (h2 >= reach * reach) return 0.0;
  float chord = sqrt(reach * reach - h2);
  ta = max(0.0, a - chord);
  tb = min(D, a + chord);
  if (!(tb > ta)) return 0.0;
  float w = sqrt(h2 + 0.5 * r * r);
  float phi_a = atan((ta - a) / w), phi_b = atan((tb - a) / w), phi_m = clamp(0.0, phi_a, phi_b);
  float disk = 0.0;
#if PREVIEW_SPOTS
  // The spot's cone (its rows of the spots texture, once).
  vec4 cone0 = vec4(0.0), cone1 = vec4(0.0), cone3 = vec4(0.0);
  if (spot >= 0) {
    cone0 = texelFetch(spots, ivec2(spot, 0), 0);
    cone1 = texelFetch(spots, ivec2(spot, 1), 0);
    cone3 = texelFetch(spots, ivec2(spot, 3), 0);
  }
#endif
  // (A spot's cone edge crosses the window: PREVIEW_SPOT_SIZE_PANELS panels a side.)
  int panels = spot >= 0 ? PREVIEW_SPOT_SIZE_PANELS : 1;
  for (int side = 0; side < 2; side++) {
    float from = (side == 0) ? phi_a : phi_m, to = (side == 0) ? phi_m : phi_b;
    for (int panel = 0; panel < panels; panel++) {
      float lo = mix(from, to, float(panel) / float(panels)), hi = mix(from, to, float(panel + 1) / float(panels));
      for (int k = 0; k < 8; k++) {
        float phi = mix(lo, hi, kGLx[k]);
        float c = cos(phi);
        float x = a + w * tan(phi);
        vec3 sx = rel - x * dir;
        float d = length(sx);
#if PREVIEW_PHASE
        float value = biri06_phase(pv_phase, dot(sx, dir) / max(d, 1e-30));
#else
        float value = 0.25 / kPi;
#endif
#if PREVIEW_SPOTS
        if (spot >= 0) value *= spot_profile(cone0.w, cone1.w, cone3.xy, -dot(sx, cone1.xyz) / max(d, 1e-30));
#endif
#if PREVIEW_SHADOWS
        if (row >= 0) value *= shadow_lit(row, p0 + x * dir);
#endif
        disk += (hi - lo) * kGLw[k] * w / (c * c) * value * exp(-pv_sigma_t * x) * preview_disk_falloff(d, r);
      }
    }
  }
  return pv_sigma_t * disk;
}

// A point light's disk less its point over the ray (preview_disk_light's window), per unit
// albedo I0, as the bake adds it (light_size_airlight): the point by the preview's own closed
// form over the same segment, so that the two cancel far from the light.
float preview_light_size_excess(vec3 s, vec3 p0, vec3 dir, float D, float r)
{
  float ta, tb;
  float disk = preview_disk_light(s, p0, dir, D, r, -1, -1, ta, tb);
  if (!(tb > ta)) return 0.0;
  vec3 rel = s - p0;
  vec3 rel_a = rel - ta * dir;
  float Dsv_a = length(rel_a);
  if (!(Dsv_a > 0.0)) return disk;
  return disk - exp(-pv_sigma_t * ta) *
                    preview_point_airlight(Dsv_a, clamp(dot(rel_a, dir) / Dsv_a, -1.0, 0.99999994), tb - ta);
}

#if PREVIEW_SHADOWS
// Lit share of a point light's airlight over [0, D] of the ray p0 + x dir (rel = light -
// p0): the single-scattering integrand sampled at the middles of SHADOW_STEPS steps equal
// in the angle seen from the light (x = a + h tan(alpha), a, h: the closest approach; there
// dx / d^2 = dalpha / h takes the 1 / d^2 peak out, and D = inf maps to alpha = pi / 2),
// each weighted by the light's visibility there, over the same sum unweighted. The caller
// multiplies it with the closed form (Yusov 2013's loop, with the closed form's own total):
// fully lit rays get the closed form exactly, fully shadowed ones 0.
float preview_point_lit_share(int row, vec3 p0, vec3 dir, vec3 rel, float Dsv, float D)
{
  float a = dot(rel, dir);
  float h = max(length(cross(rel, dir)), 1e-6 * max(Dsv, 1e-6));
  float lo = atan(-a, h);
  float hi = isinf(D) ? 0.5 * kPi : atan(D - a, h);
  float step_a = (hi - lo) / float(SHADOW_STEPS);
  float lit = 0.0, all = 0.0;
  for (int k = 0; k < SHADOW_STEPS; k++) {
    float alpha = lo + step_a * (float(k) + 0.5);
    float x = a + h * tan(alpha);
    float d = h / cos(alpha);
#if PREVIEW_PHASE
    float w = biri06_phase(pv_phase, -dot(x * dir - rel, dir) / d);
#else
    float w = 1.0;
#endif
    w *= exp(-pv_sigma_t * (x + d));
    all += w;
    lit += w * shadow_lit(row, p0 + x * dir);
  }
  return all > 0.0 ? lit / all : 1.0;
}
#endif

#if PREVIEW_SHADOWS && PREVIEW_SUNS
// Shadowed sun_layer_factor over [0, D]: SHADOW_STEPS steps of equal view-ray
// transmittance from t_a, where the ray is first in the fog layer (0 without a top), to D
// (inf maps to Tr = 0), each the closed form over the step times the visibility at its
// middle. sun_layer_factor(x0, x1) attenuates the view from x0 (the layer's own
// convention: no extinction above the top), so each step is carried back to t_a by
// e^{-sigma_t (x0 - t_a)}.
float preview_sun_shadowed(int row, vec4 s0, vec3 p0, vec3 dir, float D)
{
  float h_top = s0.w;
  float ta = 0.0;
  if (!(isinf(h_top) || h_top >= kInfinite) && dir.z < 0.0) {
    ta = max(0.0, (h_top - p0.z) / dir.z);
  }
  if (!(D > ta)) return 0.0;
  float u_end = isinf(D) ? 1.0 : -airlight_expm1(-pv_sigma_t * (D - ta));
  float du = u_end / float(SHADOW_STEPS);
  float sum = 0.0, x0 = ta;
  for (int k = 1; k <= SHADOW_STEPS; k++) {
    float x1 = (k == SHADOW_STEPS) ? D : min(ta - airlight_log1p(-du * float(k)) / pv_sigma_t, D);
    float xm = ta - airlight_log1p(-du * (float(k) - 0.5)) / pv_sigma_t;
    float G = sun_layer_factor(pv_sigma_t, h_top, -s0.z, p0.z, dir.z, x0, x1);
    sum += G * exp(-pv_sigma_t * (x0 - ta)) * shadow_lit(row, p0 + xm * dir);
    x0 = x1;
  }
  return sum;
}
#endif

// Premultiplied fog of one ray from _origin_ to the surface at distance _Dvp_ (inf: no
// surface), clipped as Cycles renders it: rgb = airlight of all point lights over
// [t0, Dvp], attenuated from the near-plane point p0 = origin + t0 dir on, a = 1 - Tr with
// Tr = exp(-sigma_t (Dvp - t0)). The medium is homogeneous, so that is the airlight of a
// viewer at p0 (one sun05_airlight per light, no difference of two evaluations: its F
// arguments are the same as in the bake's exp(sigma_t t0) (La(eye, Dvp) - La(eye, t0))).
vec4 preview_fog(vec3 origin, vec3 dir, float Dvp)
{
  float t0 = preview_near(dir);
  vec3 p0 = origin + t0 * dir;
  float D = max(Dvp - t0, 0.0);  // inf stays inf
  vec3 La = vec3(0.0);
  for (int i = 0; i < light_count; i++) {
    vec3 to_light = texelFetch(lights, ivec2(i, 0), 0).xyz - p0;
    vec4 I0 = texelFetch(lights, ivec2(i, 1), 0);
    float Dsv = length(to_light);
    if (Dsv <= 0.0) {
      continue;
    }
    // float32 cannot hold a cosine between 1 - 2^-24 and 1 (angles below 3.5e-4 rad):
    // a ray that close to the light is read as gamma = 3.5e-4 rather than as a ray
    // exactly through the light (which sun05_airlight regularises to sin(gamma) = 1e-8,
    // 1e4 times brighter than any nearby pixel). 0.99999994 = 1 - 2^-24.
    float cos_gamma = clamp(dot(to_light, dir) / Dsv, -1.0, 0.99999994);
    float radius = texelFetch(lights, ivec2(i, 0), 0).w;  // the light's Radius (0: a point)
    float value = preview_point_airlight(Dsv, cos_gamma, D);
    if (radius > 0.0) {
      value += preview_light_size_excess(to_light + p0, p0, dir, D, radius);
    }
#if PREVIEW_SHADOWS
    int row = int(texelFetch(lights, ivec2(i, 2), 0).a);
    if (row >= 0) {
      value *= preview_point_lit_share(row, p0, dir, to_light, Dsv, D);
    }
#endif
    La += (I0.rgb * I0.a) * value;
  }
#if PREVIEW_SPOTS
  int spot_count = textureSize(spots, 0).x;
  for (int i = 0; i < spot_count; i++) {
    vec4 s0 = texelFetch(spots, ivec2(i, 0), 0);
    vec4 s1 = texelFetch(spots, ivec2(i, 1), 0);
    vec4 I0 = texelFetch(spots, ivec2(i, 2), 0);
    vec4 s3 = texelFetch(spots, ivec2(i, 3), 0);
    int row = PREVIEW_SHADOWS != 0 ? int(I0.a) : -1;
    float value = spot_airlight_shadowed(s0.xyz, s1.xyz, s0.w, s1.w, s3.xy, pv_sigma_t, p0, dir, D,
                                         PREVIEW_PHASE != 0, pv_phase, row);
    if (s3.z > 0.0) {  // the spot's Radius: its disk less its point over the disk's window
      float ta, tb;
      value += preview_disk_light(s0.xyz, p0, dir, D, s3.z, i, row, ta, tb);
      if (tb > ta) {
        value -= exp(-pv_sigma_t * ta) * spot_airlight_shadowed(s0.xyz, s1.xyz, s0.w, s1.w, s3.xy, pv_sigma_t,
                                                                p0 + ta * dir, dir, tb - ta, PREVIEW_PHASE != 0,
                                                                pv_phase, row);
      }
    }
    La += I0.rgb * value;
  }
#endif
#if PREVIEW_SUNS
  int sun_count = textureSize(suns, 0).x;
  for (int i = 0; i < sun_count; i++) {
    vec4 s0 = texelFetch(suns, ivec2(i, 0), 0);
    vec4 E = texelFetch(suns, ivec2(i, 1), 0);
    float mu = -dot(s0.xyz, dir);
#if PREVIEW_PHASE
    float p = biri06_phase(pv_phase, mu);
#else
    float p = 0.07957747154594767;
#endif
#if PREVIEW_SHADOWS
    if (E.a >= 0.0 && pv_sigma_t > 0.0) {
      La += (pv_sigma_t * p) * E.rgb * preview_sun_shadowed(int(E.a), s0, p0, dir, D);
      continue;
    }
#endif
    La += (pv_sigma_t * p) * E.rgb * sun_layer_factor(pv_sigma_t, s0.w, -s0.z, p0.z, dir.z, 0.0, D);
  }
#endif
  float Tr = exp(-pv_sigma_t * D);
  return vec4(La, 1.0 - Tr);
}

#ifndef PREVIEW_ENV  // shaders that never draw the World (the splat pass) leave it out
#  define PREVIEW_ENV 0
#endif
#if PREVIEW_ENV
// The World seen through the fog (addon/airlight/environment.py, native sun05_psf.h): the
// glow map env_glow (equirectangular, Blender's mapping u = 1/2 - atan2(y, x) / (2 pi),
// v = 1 - acos(z) / pi; row 0 = top) looked up bilinearly in direction _dir_ exactly as
// the C++ environment_lookup does (u wraps, rows clamp).
vec3 preview_env_lookup(vec3 dir)
{
  ivec2 size = textureSize(env_glow, 0);
  float u = 0.5 - atan(dir.y, dir.x) * 0.15915494309189535;
  u = u - floor(u);
  float v = 1.0 - acos(clamp(dir.z / length(dir), -1.0, 1.0)) * 0.3183098861837907;
  vec2 xy = vec2(u * float(size.x) - 0.5, (1.0 - v) * float(size.y) - 0.5);
  vec2 f = floor(xy);
  vec2 a = xy - f;
  ivec2 p0 = ivec2(f);
  vec3 sum = vec3(0.0);
  for (int k = 0; k < 4; k++) {
    ivec2 o = ivec2(k & 1, k >> 1);
    int i = (p0.x + o.x) % size.x;
    i = i < 0 ? i + size.x : i;
    int j = clamp(p0.y + o.y, 0, size.y - 1);
    vec2 w = mix(vec2(1.0) - a, a, vec2(o));
    sum += w.x * w.y * texelFetch(env_glow, ivec2(i, j), 0).rgb;
  }
  return sum;
}

// Where the ray meets no surface: add the World's glow and let the World through with
// Tr = pv_env_T = e^{-sigma_t distance} (eq. 26-27), as the bake does for those pixels.
void preview_env(vec3 dir, float Dvp, inout vec4 fog)
{
  if (isinf(Dvp)) {
    fog.rgb += preview_env_lookup(dir);
    fog.a = 1.0 - pv_env_T;
  }
}
#endif

