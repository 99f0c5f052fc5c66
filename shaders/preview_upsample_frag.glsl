// preview_upsample_frag.glsl: composites the reduced-resolution fog over the full-
// resolution viewport with depth-aware (joint bilateral) upsampling.
//
// Low-res texel (i, j) holds the exact fog of full-resolution pixel
// (i, j) * scale + scale / 2 (fog_preview_frag.glsl), so its surface distance is read
// back from the full-resolution depth. A full-resolution pixel blends its four
// surrounding low-res samples with bilinear weights times a depth similarity
// exp(-(r / PREVIEW_DEPTH_SIGMA)^2), r = |D_k - (D + slope . offset)| / D: the distance
// a sample would have on the plane through the pixel (slopes from one-sided differences
// of the full-resolution depth), so fog never leaks across a silhouette and grazing
// surfaces still interpolate smoothly. Where no sample shares the pixel's surface (best similarity below
// PREVIEW_DEPTH_ACCEPT: thin objects, the first pixels past an edge) the pixel's fog is
// evaluated here at full resolution. mode: 0 = plain bilinear (for comparison),
// 1 = joint bilateral with nearest-depth fallback, 2 = joint bilateral with exact
// re-evaluation (the default).
//
//   fog_lo      reduced fog (RGBA, premultiplied), lo_size texels
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
  vec2 f = (vec2(px) - float(scale / 2)) / float(scale);
  ivec2 i0 = ivec2(floor(f));
  vec2 t = f - vec2(i0);

  float D = preview_distance_at(px);
  vec2 slope = vec2(0.0);
  if (mode != 0 && !isinf(D)) {
    slope = vec2(preview_slope(px, ivec2(1, 0), D), preview_slope(px, ivec2(0, 1), D));
  }

  vec4 sum = vec4(0.0);
  float wsum = 0.0, best = -1.0;
  vec4 nearest = vec4(0.0);
  for (int k = 0; k < 4; k++) {
    ivec2 o = ivec2(k & 1, k >> 1);
    ivec2 q = clamp(i0 + o, ivec2(0), lo_size - 1);
    float wb = (o.x == 1 ? t.x : 1.0 - t.x) * (o.y == 1 ? t.y : 1.0 - t.y);
    vec4 fog = texelFetch(fog_lo, q, 0);
    if (mode == 0) {
      sum += wb * fog;
      wsum += wb;
      continue;
    }
    ivec2 qpx = min(q * scale + scale / 2, ivec2(viewport.zw) - 1);
    float s = preview_similarity(preview_distance_at(qpx), D, slope, vec2(qpx - px));
    if (s > best) {
      best = s;
      nearest = fog;
    }
    float w = (wb + 1e-3) * s;
    sum += w * fog;
    wsum += w;
  }

  if (mode == 0) {
    frag_color = sum / wsum;
  }
  else if (best >= PREVIEW_DEPTH_ACCEPT) {
    frag_color = sum / wsum;
  }
  else if (mode == 1) {
    frag_color = nearest;
  }
  else {
    vec2 ndc;
    vec3 origin, dir;
    preview_ray(px, ndc, origin, dir);
    frag_color = preview_fog(origin, dir, D);
  }
}
