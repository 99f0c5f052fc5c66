// preview_common.glsl: the view ray, surface distance and fog of one viewport pixel,
// shared by fog_preview_frag.glsl (full or reduced resolution) and
// preview_upsample_frag.glsl (which re-evaluates pixels at depth discontinuities).
// Needs sun05_airlight.glsl in front of it and these inputs:
//   Ftab        F table (R32F) from _native.special_F_table()
//   depth_tex   full-resolution scene depth of the region (R32F): the linear distance
//               _Dvp_ along the view ray (inf = nothing hit) or, with
//               PREVIEW_WINDOW_DEPTH defined to 1, the window depth in [0, 1] (1 = none)
//   lights      RGBA32F, light_count x 2 texels: row 0 = position (world), row 1 =
//               albedo * I0 (W/sr per RGB channel)
//   inv_persp   inverse of (projection * view) of the region
//   eye         xyz = view origin (world), w = 1 for perspective, 0 for orthographic
//   viewport    zw = full-resolution size of the region in pixels
//   sigma_t     extinction coefficient (1/m); light_count = number of lights

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

// Premultiplied fog of one ray: rgb = airlight of all point lights, a = 1 - Tr.
vec4 preview_fog(vec3 origin, vec3 dir, float Dvp)
{
  vec3 La = vec3(0.0);
  for (int i = 0; i < light_count; i++) {
    vec3 to_light = texelFetch(lights, ivec2(i, 0), 0).xyz - origin;
    vec3 I0 = texelFetch(lights, ivec2(i, 1), 0).rgb;
    float Dsv = length(to_light);
    if (Dsv <= 0.0) {
      continue;
    }
    // float32 cannot hold a cosine between 1 - 2^-24 and 1 (angles below 3.5e-4 rad):
    // a ray that close to the light is read as gamma = 3.5e-4 rather than as a ray
    // exactly through the light (which sun05_airlight regularises to sin(gamma) = 1e-8,
    // 1e4 times brighter than any nearby pixel). 0.99999994 = 1 - 2^-24.
    float cos_gamma = clamp(dot(to_light, dir) / Dsv, -1.0, 0.99999994);
    La += I0 * sun05_airlight(Ftab, sigma_t, Dsv, cos_gamma, Dvp);
  }
  float Tr = exp(-sigma_t * Dvp);
  return vec4(La, 1.0 - Tr);
}
