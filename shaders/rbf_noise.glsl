// rbf_noise.glsl: the world-space vector gradient noise of Fogshop section 5.5, the GLSL
// twin of native/core/noise.h (same hash, gradients, fade and corner order, float
// throughout); tests/gpu/test_preview_noise.py holds the two together on the same
// inputs (`_native.gradient_noise3`). Pure functions, no inputs, GLSL 330.
//   hash(ix, iy, iz) -> gradient in [-1, 1]^3 (10 bits per component),
//   noise(p) = trilinear blend with the quintic fade of dot(g_corner, f - corner),
//   noise3(p) = noise at p and at p shifted by two fixed offsets.

uint rbf_noise_hash(int x, int y, int z)
{
  uint h = uint(x) * 0x8da6b343u ^ uint(y) * 0xd8163841u ^ uint(z) * 0xcb1ab31fu;
  h ^= h >> 16u;
  h *= 0x7feb352du;
  h ^= h >> 15u;
  h *= 0x846ca68bu;
  h ^= h >> 16u;
  return h;
}

float rbf_noise_grad_dot(ivec3 i, vec3 f)
{
  uint h = rbf_noise_hash(i.x, i.y, i.z);
  vec3 g = vec3(float(h & 1023u), float((h >> 10u) & 1023u), float((h >> 20u) & 1023u)) *
               (1.0 / 511.5) - 1.0;
  return g.x * f.x + g.y * f.y + g.z * f.z;
}

float rbf_noise_fade(float f)
{
  return f * f * f * (f * (f * 6.0 - 15.0) + 10.0);
}

float rbf_gradient_noise(vec3 p)
{
  vec3 fl = floor(p);
  ivec3 i = ivec3(fl);
  vec3 f = p - fl;
  vec3 u = vec3(rbf_noise_fade(f.x), rbf_noise_fade(f.y), rbf_noise_fade(f.z));
  float n000 = rbf_noise_grad_dot(i, f);
  float n100 = rbf_noise_grad_dot(i + ivec3(1, 0, 0), f - vec3(1.0, 0.0, 0.0));
  float n010 = rbf_noise_grad_dot(i + ivec3(0, 1, 0), f - vec3(0.0, 1.0, 0.0));
  float n110 = rbf_noise_grad_dot(i + ivec3(1, 1, 0), f - vec3(1.0, 1.0, 0.0));
  float n001 = rbf_noise_grad_dot(i + ivec3(0, 0, 1), f - vec3(0.0, 0.0, 1.0));
  float n101 = rbf_noise_grad_dot(i + ivec3(1, 0, 1), f - vec3(1.0, 0.0, 1.0));
  float n011 = rbf_noise_grad_dot(i + ivec3(0, 1, 1), f - vec3(0.0, 1.0, 1.0));
  float n111 = rbf_noise_grad_dot(i + ivec3(1, 1, 1), f - vec3(1.0, 1.0, 1.0));
  float x00 = n000 + u.x * (n100 - n000), x10 = n010 + u.x * (n110 - n010);
  float x01 = n001 + u.x * (n101 - n001), x11 = n011 + u.x * (n111 - n011);
  float y0 = x00 + u.y * (x10 - x00), y1 = x01 + u.y * (x11 - x01);
  return y0 + u.z * (y1 - y0);
}

// Vector noise: three decorrelated components (the same field at shifted points).
vec3 rbf_gradient_noise3(vec3 p)
{
  return vec3(rbf_gradient_noise(p),
              rbf_gradient_noise(p + vec3(31.416, -47.853, 12.679)),
              rbf_gradient_noise(p + vec3(-19.191, 7.337, -57.931)));
}
