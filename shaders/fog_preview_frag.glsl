// fog_preview_frag.glsl: viewport preview of homogeneous single-scattering fog.
// One full-screen pass; per pixel: the view ray from the inverse of the window's
// perspective matrix, the surface distance _Dvp_ from the scene depth, the airlight of
// every point light by sun05_airlight() (sun05_airlight.glsl, the GLSL twin of the C++
// kernel), and the transmittance Tr = exp(-sigma_t Dvp). Output is premultiplied:
// rgb = airlight, alpha = 1 - Tr, so ALPHA_PREMULT blending gives L = La + Tr L_scene.
//
//   Ftab        F table (R32F) from _native.special_F_table()
//   depth_tex   window-space depth in [0, 1] of the region (R32F); 1 = nothing hit
//   lights      RGBA32F, light_count x 2 texels: row 0 = position (world), row 1 =
//               albedo * I0 (W/sr per RGB channel)
//   inv_persp   inverse of (projection * view) of the region
//   eye         xyz = view origin (world), w = 1 for perspective, 0 for orthographic
//   viewport    xy = lower-left corner of the region in the framebuffer, zw = its size
//   sigma_t     extinction coefficient (1/m); light_count = number of lights

vec3 preview_unproject(vec2 ndc_xy, float ndc_z)
{
  vec4 p = inv_persp * vec4(ndc_xy, ndc_z, 1.0);
  return p.xyz / p.w;
}

void main()
{
  vec2 pixel = gl_FragCoord.xy - viewport.xy;
  vec2 ndc = pixel / viewport.zw * 2.0 - 1.0;
  float depth = texelFetch(depth_tex, ivec2(pixel), 0).r;

  // View ray: from the eye (perspective) or from the near plane (orthographic).
  vec3 p_near = preview_unproject(ndc, -1.0);
  vec3 p_far = preview_unproject(ndc, 1.0);
  vec3 origin = (eye.w > 0.5) ? eye.xyz : p_near;
  vec3 dir = normalize(p_far - p_near);

  // Surface distance; background pixels see no surface (Dvp = inf).
  float Dvp = uintBitsToFloat(0x7F800000u);
  if (depth < 1.0) {
    vec3 p = preview_unproject(ndc, depth * 2.0 - 1.0);
    Dvp = max(dot(p - origin, dir), 0.0);
  }

  // Airlight of all point lights.
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
  frag_color = vec4(La, 1.0 - Tr);
}
