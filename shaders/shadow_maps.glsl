// shadow_maps.glsl: whether a light reaches a world point, from the viewport preview's
// shadow maps (addon/airlight/preview_shadows.py draws them with the scene's shadow
// casters; the bake ray-casts the same casters with Embree instead).
//
// shadow_maps  R32F atlas, SHADOW_RES * 3 wide, SHADOW_RES * 2 high per shadowed light
//              (row r starts at y = 2 r SHADOW_RES). Each texel holds the distance to the
//              nearest caster, inf where there is none:
//              - point lights and spots: a cube of six SHADOW_RES^2 faces, face f at tile
//                (f % 3, f / 3), faces +X -X +Y -Y +Z -Z; face coordinates (u, v) =
//                (d_b, d_c) / |d_a| for the major axis a of d = p - light and (b, c) the
//                next two axes in cyclic order (X: (Y, Z), Y: (Z, X), Z: (X, Y)); the
//                stored distance is |p - light|;
//              - suns: one orthographic map over the whole 3 x 2 tile; the distance is
//                measured along the sun's direction from the plane in front of all casters.
// shadow_info  RGBA32F, one column per shadowed light, 4 texels:
//              0: point/spot (light position, 0); sun (texel size in m, 0, 0, 1)
//              1, 2: sun: (e, o) with map coordinate x (y) in [-1, 1] = dot(e, p) + o
//              3: sun: (w, o) with distance = dot(w, p) + o
//
// A point counts as lit when its distance is at most the stored one plus a bias of
// SHADOW_BIAS_TEXELS texels (the fog behind a caster's surface within that band is lit:
// the preview's error bound next to surfaces); 2 x 2 texels are compared and weighted
// bilinearly (percentage-closer filtering), so shadow edges are smooth at texel scale.

#ifndef SHADOW_RES
#  define SHADOW_RES 512
#endif
#ifndef SHADOW_BIAS_TEXELS
#  define SHADOW_BIAS_TEXELS 2.0
#endif

// Cube face of direction _d_ (0..5 = +X -X +Y -Y +Z -Z), its coordinates _uv_ in
// [-1, 1] and |d_a|.
int shadow_cube_face(vec3 d, out vec2 uv)
{
  vec3 a = abs(d);
  if (a.x >= a.y && a.x >= a.z) {
    uv = d.yz / max(a.x, 1e-30);
    return d.x >= 0.0 ? 0 : 1;
  }
  if (a.y >= a.z) {
    uv = d.zx / max(a.y, 1e-30);
    return d.y >= 0.0 ? 2 : 3;
  }
  uv = d.xy / max(a.z, 1e-30);
  return d.z >= 0.0 ? 4 : 5;
}

// Lit fraction at continuous texel position _xy_ of the tile [lo, lo + size): the four
// nearest texels' comparisons of _dist_ - _bias_ with their stored distance, weighted
// bilinearly (texels clamped to the tile).
float shadow_pcf(ivec2 lo, ivec2 size, vec2 xy, float dist, float bias)
{
  vec2 f = xy - 0.5;
  vec2 fl = floor(f);
  ivec2 i0 = ivec2(fl);
  vec2 a = f - fl;
  float lit = 0.0;
  for (int k = 0; k < 4; k++) {
    ivec2 o = ivec2(k & 1, k >> 1);
    ivec2 q = clamp(i0 + o, ivec2(0), size - 1);
    float stored = texelFetch(shadow_maps, lo + q, 0).r;
    vec2 w = mix(vec2(1.0) - a, a, vec2(o));
    lit += (dist - bias <= stored) ? w.x * w.y : 0.0;
  }
  return lit;
}

// Fraction of the light of shadow-map row _row_ that reaches world point _p_ (0..1).
float shadow_lit(int row, vec3 p)
{
  const int R = SHADOW_RES;
  ivec2 base = ivec2(0, row * 2 * R);
  vec4 t0 = texelFetch(shadow_info, ivec2(row, 0), 0);
  if (t0.w < 0.5) {
    vec3 d = p - t0.xyz;
    vec2 uv;
    int face = shadow_cube_face(d, uv);
    float dist = length(d);
    ivec2 lo = base + ivec2((face % 3) * R, (face / 3) * R);
    // A texel spans 2 |d_a| / R <= 2 dist / R on the face.
    float bias = SHADOW_BIAS_TEXELS * 2.0 * dist / float(R);
    return shadow_pcf(lo, ivec2(R), (uv * 0.5 + 0.5) * float(R), dist, bias);
  }
  vec4 ex = texelFetch(shadow_info, ivec2(row, 1), 0);
  vec4 ey = texelFetch(shadow_info, ivec2(row, 2), 0);
  vec4 ez = texelFetch(shadow_info, ivec2(row, 3), 0);
  vec2 m = vec2(dot(ex.xyz, p) + ex.w, dot(ey.xyz, p) + ey.w);
  if (abs(m.x) > 1.0 || abs(m.y) > 1.0) {
    return 1.0;  // outside the casters' footprint
  }
  ivec2 size = ivec2(3 * R, 2 * R);
  float dist = dot(ez.xyz, p) + ez.w;
  return shadow_pcf(base, size, (m * 0.5 + 0.5) * vec2(size), dist, SHADOW_BIAS_TEXELS * t0.x);
}
