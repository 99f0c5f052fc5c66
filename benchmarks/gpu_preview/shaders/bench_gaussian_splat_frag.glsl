// bench_gaussian_splat_frag.glsl (harness-local stand-in, see ../README.md): airlight
// and optical depth of one Gaussian on one pixel's view ray (Fogshop eq. 10-13, 31; the
// approximation of native/gaussian/airlight.h), accumulated with additive blending:
//   rgb += sum_l albedo I0_l f0(b_i^r) f1(l, i) T_i(v, p),   a += T_i(v, p)
// T_i(p, q) = c_i sqrt(pi) / (2 a_i) exp(-a_i^2 h^2) [erf(a_i (L - t*)) - erf(-a_i t*)].
// f1 (the attenuation by everything else along s -> b_i -> v) comes per (light,
// Gaussian) from the CPU, as the preview's design has it.
//   gauss     RGBA32F N x 2 (see the vertex file); f1tab R32F N x light_count
//   (and the inputs of preview_common.glsl: depth_tex, lights, viewport, scale, ...)
const float kSqrtPi = 1.7724538509055159;

// erfc(x) for x >= 0 (Numerical Recipes erfcc, relative error < 1.2e-7).
float bench_erfc(float x)
{
  float t = 1.0 / (1.0 + 0.5 * x);
  return t * exp(-x * x - 1.26551223 + t * (1.00002368 + t * (0.37409196 + t * (0.09678418 +
         t * (-0.18628806 + t * (0.27886807 + t * (-1.13520398 + t * (1.48851587 +
         t * (-0.82215223 + t * 0.17087277)))))))));
}

// erf(x2) - erf(x1), x1 <= x2, through erfc where both have one sign.
float bench_erf_diff(float x1, float x2)
{
  if (x1 >= 0.0) return bench_erfc(x1) - bench_erfc(x2);
  if (x2 <= 0.0) return bench_erfc(-x2) - bench_erfc(-x1);
  return 2.0 - bench_erfc(x2) - bench_erfc(-x1);
}

// Line integral of Gaussian (b, a, c) along o + t r, t in [t0, t1].
float bench_gaussian_T(vec3 b, float a, float c, vec3 o, vec3 r, float t0, float t1)
{
  vec3 bo = b - o;
  float ts = dot(bo, r);
  float h2 = max(dot(bo, bo) - ts * ts, 0.0);
  return c * kSqrtPi / (2.0 * a) * exp(-a * a * h2) * bench_erf_diff(a * (t0 - ts), a * (t1 - ts));
}

// Segment p -> q.
float bench_gaussian_T_seg(vec3 b, float a, float c, vec3 p, vec3 q)
{
  float L = length(q - p);
  if (L <= 0.0) return 0.0;
  return bench_gaussian_T(b, a, c, p, (q - p) / L, 0.0, L);
}

void main()
{
  ivec2 px = min(ivec2(gl_FragCoord.xy - viewport.xy) * scale + scale / 2,
                 ivec2(viewport.zw) - 1);
  vec2 ndc;
  vec3 origin, dir;
  preview_ray(px, ndc, origin, dir);
  float Dvp = preview_distance(px, ndc, origin, dir);
  float t0 = preview_near(dir);
  vec4 ba = texelFetch(gauss, ivec2(gid, 0), 0);
  float c = texelFetch(gauss, ivec2(gid, 1), 0).x;
  vec3 b = ba.xyz;
  float a = ba.w;
  float t1 = min(Dvp, 1e30);
  float Ti = bench_gaussian_T(b, a, c, origin, dir, t0, t1);
  // b_i^r: the centre's projection on the ray, clamped to the fogged segment (eq. 10).
  vec3 br = origin + clamp(dot(b - origin, dir), t0, t1) * dir;
  vec3 p0 = origin + t0 * dir;
  float Tvb = bench_gaussian_T_seg(b, a, c, p0, b), Tvr = bench_gaussian_T_seg(b, a, c, p0, br);
  vec3 La = vec3(0.0);
  for (int l = 0; l < light_count; l++) {
    vec3 s = texelFetch(lights, ivec2(l, 0), 0).xyz;
    vec3 I0 = texelFetch(lights, ivec2(l, 1), 0).rgb;
    vec3 sr = br - s;
    float Tsb = bench_gaussian_T_seg(b, a, c, s, b), Tsr = bench_gaussian_T_seg(b, a, c, s, br);
    float f0 = exp(-Tsr - Tvr + Tsb + Tvb) / (4.0 * kPi * max(dot(sr, sr), 1e-12));
    float f1 = texelFetch(f1tab, ivec2(gid, l), 0).r;
    La += I0 * (f0 * f1 * Ti);
  }
  frag_color = vec4(La, Ti);
}
