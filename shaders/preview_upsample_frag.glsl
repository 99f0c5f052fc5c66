// preview_upsample_frag.glsl: composites the reduced-resolution fog over the full-
// resolution viewport with depth-aware (joint bilateral) upsampling.
//
// Low-res texel (i, j) holds the exact airlight of full-resolution pixel
// (i, j) * scale + scale / 2 and that pixel's surface distance (fog_preview_frag.glsl with
// PREVIEW_LOWRES: rgb = La, a = Dvp). A full-resolution pixel blends the rgb of its four
// surrounding low-res samples with bilinear weights times a depth similarity
// exp(-(r / PREVIEW_DEPTH_SIGMA)^2), r = |D_k - (D + slope . offset)| / D: the distance
// a sample would have on the plane through the pixel (slopes from one-sided differences
// of the full-resolution depth), so fog never leaks across a silhouette and grazing
// surfaces still interpolate smoothly. Its transmittance is exact: Tr = exp(-sigma_t
// (D - t0)) from its own distance. Where no sample shares the pixel's surface (best
// similarity below PREVIEW_DEPTH_ACCEPT: thin objects, the first pixels past an edge)
// the pixel's airlight is evaluated at full resolution.
//
// That evaluation is a separate draw of this file (PREVIEW_EXACT_PASS 1) that the depth
// test limits to those pixels: the blending draw (PREVIEW_EXACT_PASS 0, no airlight
// code) writes them into a full-resolution target and, with PREVIEW_MARK 1, marks them
// with depth 0 (others 1), and the exact draw, a quad at depth 0.5 tested GREATER, only
// runs there. Software rasterisers (llvmpipe) run both sides of a branch under a lane
// mask, and a discard does not end the shader early either, so an in-shader fallback
// cost one airlight evaluation for EVERY pixel (as much as the whole fog at full
// resolution with one light); a block of pixels that fails the early depth test is
// skipped. Without PREVIEW_MARK (modes 0 and 1) the blending draw composites straight
// into the region.
//
// mode: 0 = plain bilinear (for comparison; no exact pass), 1 = joint bilateral with
// nearest-depth fallback (no exact pass), 2 = joint bilateral with exact re-evaluation
// (the default).
//
//   fog_lo      reduced fog (RGBA32F: rgb = airlight, a = Dvp), lo_size texels
//   viewport    xy = lower-left corner of the region in the framebuffer, zw = its size
//   scale, mode (and the inputs of preview_common.glsl)

const float PREVIEW_DEPTH_SIGMA = 0.02;
const float PREVIEW_DEPTH_ACCEPT = 0.5;

// Surface distance at full-resolution pixel _px_ (its own view ray).
float preview_distance_at(ivec2 px)
{
  vec2 ndc;
  vec3 origin, dir;
  preview_ray(px, ndc, origin, dir);
  return preview_distance(px, ndc, origin, dir);
}

// One-sided screen-space derivative of the distance at _px_ along _axis_: the side
// that changes least, so it never reaches across an edge (0 next to background).
float preview_slope(ivec2 px, ivec2 axis, float D)
{
  ivec2 hi = min(px + axis, ivec2(viewport.zw) - 1), lo = max(px - axis, ivec2(0));
  float a = preview_distance_at(hi) - D, b = D - preview_distance_at(lo);
  a = isinf(a) || isnan(a) ? 0.0 : a;
  b = isinf(b) || isnan(b) ? 0.0 : b;
  return abs(a) < abs(b) ? a : b;
}

// Similarity of a sample's distance _Dk_ to the plane through the pixel (distance _D_,
// screen slopes _slope_) at the sample's offset _delta_ (1 = same surface); both inf =
// background.
float preview_similarity(float Dk, float D, vec2 slope, vec2 delta)
{
  if (isinf(D) || isinf(Dk)) {
    return (isinf(D) && isinf(Dk)) ? 1.0 : 0.0;
  }
  float predicted = D + dot(slope, delta);
  float r = abs(Dk - predicted) / max(min(Dk, D), 1e-6);
  return exp(-(r * r) / (PREVIEW_DEPTH_SIGMA * PREVIEW_DEPTH_SIGMA));
}

void main()
{
  ivec2 px = ivec2(gl_FragCoord.xy - viewport.xy);
  ivec2 lo_size = textureSize(fog_lo, 0);
  // Position in low-res texels of the samples' full-resolution pixels.
  vec2 f = (vec2(px) - float(pv_scale / 2)) / float(pv_scale);
  ivec2 i0 = ivec2(floor(f));
  vec2 t = f - vec2(i0);

  vec2 ndc;
  vec3 origin, dir;
  preview_ray(px, ndc, origin, dir);
  float D = preview_distance(px, ndc, origin, dir);
  vec2 slope = vec2(0.0);
  if (pv_mode != 0 && !isinf(D)) {
    slope = vec2(preview_slope(px, ivec2(1, 0), D), preview_slope(px, ivec2(0, 1), D));
  }

  vec3 sum = vec3(0.0);
  float wsum = 0.0, best = -1.0;
  vec3 nearest = vec3(0.0);
  for (int k = 0; k < 4; k++) {
    ivec2 o = ivec2(k & 1, k >> 1);
    ivec2 q = clamp(i0 + o, ivec2(0), lo_size - 1);
    float wb = (o.x == 1 ? t.x : 1.0 - t.x) * (o.y == 1 ? t.y : 1.0 - t.y);
    vec4 fog = texelFetch(fog_lo, q, 0);
    float s = 1.0;
    if (pv_mode != 0) {
      ivec2 qpx = min(q * pv_scale + pv_scale / 2, ivec2(viewport.zw) - 1);
      s = preview_similarity(fog.a, D, slope, vec2(qpx - px));
      if (s > best) {
        best = s;
        nearest = fog.rgb;
      }
      wb += 1e-3;
    }
    float w = wb * s;
    sum += w * fog.rgb;
    wsum += w;
  }
  bool exact = pv_mode == 2 && best < PREVIEW_DEPTH_ACCEPT;
#if PREVIEW_EXACT_PASS
  frag_color = preview_fog(origin, dir, D);
#  if PREVIEW_ENV
  preview_env(dir, D, frag_color);
#  endif
#else
#  if PREVIEW_MARK
  gl_FragDepth = exact ? 0.0 : 1.0;
#  endif
  vec3 La = (pv_mode == 0 || best >= PREVIEW_DEPTH_ACCEPT) ? sum / wsum : nearest;
  float Tr = exp(-pv_sigma_t * max(D - preview_near(dir), 0.0));
#  if PREVIEW_ENV
  Tr = isinf(D) ? pv_env_T : Tr;  // the World through the fog (its glow is in La)
#  endif
  frag_color = vec4(La, 1.0 - Tr);
#endif
}
