// noise.h: deterministic 3D gradient noise for the Fogshop noise perturbation
// (Zhou et al. 2007, section 5.5; gaussian/splat.h says how the bake uses it).
//
// Perlin-style gradient noise on the integer lattice, quintic fade, with the gradient of
// each lattice point taken from an integer hash of its coordinates (no permutation
// table), so the same function is a few lines of GLSL (uint arithmetic, GLSL 1.30+):
//   h = hash(ix, iy, iz): h = ix * 0x8da6b343u ^ iy * 0xd8163841u ^ iz * 0xcb1ab31fu;
//       h ^= h >> 16; h *= 0x7feb352du; h ^= h >> 15; h *= 0x846ca68bu; h ^= h >> 16;
//   g = (float(h & 1023u), float((h >> 10) & 1023u), float((h >> 20) & 1023u)) / 511.5 - 1
//   noise(p) = trilinear blend, with weights fade(f) = f^3 (f (6 f - 15) + 10), of
//              dot(g_corner, f - corner) over the 8 corners of the cell, f = p - floor(p).
// noise is 0 on every lattice point, continuous with continuous first and second
// derivatives, and |noise| <= sqrt(3) (in practice within about +-1).
// noise3 is a vector field: noise at p and at p shifted by two fixed offsets.
// Float throughout (world coordinates up to ~1e5 m keep ~1e-2 of a cell at scale 1).
#pragma once

#include <cmath>
#include <cstdint>

namespace airlight {

[[gnu::always_inline]] inline std::uint32_t noise_hash(std::int32_t x, std::int32_t y, std::int32_t z) {
    std::uint32_t h = static_cast<std::uint32_t>(x) * 0x8da6b343u ^ static_cast<std::uint32_t>(y) * 0xd8163841u ^
                      static_cast<std::uint32_t>(z) * 0xcb1ab31fu;
    h ^= h >> 16;
    h *= 0x7feb352du;
    h ^= h >> 15;
    h *= 0x846ca68bu;
    h ^= h >> 16;
    return h;
}

[[gnu::always_inline]] inline float noise_grad_dot(std::int32_t x, std::int32_t y, std::int32_t z, float fx, float fy, float fz) {
    const std::uint32_t h = noise_hash(x, y, z);
    const float gx = static_cast<float>(h & 1023u) * (1.0f / 511.5f) - 1.0f;
    const float gy = static_cast<float>((h >> 10) & 1023u) * (1.0f / 511.5f) - 1.0f;
    const float gz = static_cast<float>((h >> 20) & 1023u) * (1.0f / 511.5f) - 1.0f;
    return gx * fx + gy * fy + gz * fz;
}

[[gnu::always_inline]] inline float noise_floor(float x) { return std::floor(x); }

[[gnu::always_inline]] inline float noise_fade(float f) { return f * f * f * (f * (f * 6.0f - 15.0f) + 10.0f); }

// gradient_noise_inlined / gradient_noise3_inlined: the same, always inlined, so that a
// loop calling them can vectorise (gaussian/splat_reduced.cpp's path); the plain
// functions are the out-of-line form the full-resolution splat calls.
[[gnu::always_inline]] inline float gradient_noise_inlined(float px, float py, float pz) {
    const float flx = noise_floor(px), fly = noise_floor(py), flz = noise_floor(pz);
    const std::int32_t ix = static_cast<std::int32_t>(flx), iy = static_cast<std::int32_t>(fly),
                       iz = static_cast<std::int32_t>(flz);
    const float fx = px - flx, fy = py - fly, fz = pz - flz;
    const float ux = noise_fade(fx), uy = noise_fade(fy), uz = noise_fade(fz);
    const float n000 = noise_grad_dot(ix, iy, iz, fx, fy, fz);
    const float n100 = noise_grad_dot(ix + 1, iy, iz, fx - 1.0f, fy, fz);
    const float n010 = noise_grad_dot(ix, iy + 1, iz, fx, fy - 1.0f, fz);
    const float n110 = noise_grad_dot(ix + 1, iy + 1, iz, fx - 1.0f, fy - 1.0f, fz);
    const float n001 = noise_grad_dot(ix, iy, iz + 1, fx, fy, fz - 1.0f);
    const float n101 = noise_grad_dot(ix + 1, iy, iz + 1, fx - 1.0f, fy, fz - 1.0f);
    const float n011 = noise_grad_dot(ix, iy + 1, iz + 1, fx, fy - 1.0f, fz - 1.0f);
    const float n111 = noise_grad_dot(ix + 1, iy + 1, iz + 1, fx - 1.0f, fy - 1.0f, fz - 1.0f);
    const float x00 = n000 + ux * (n100 - n000), x10 = n010 + ux * (n110 - n010);
    const float x01 = n001 + ux * (n101 - n001), x11 = n011 + ux * (n111 - n011);
    const float y0 = x00 + uy * (x10 - x00), y1 = x01 + uy * (x11 - x01);
    return y0 + uz * (y1 - y0);
}

inline float gradient_noise(float px, float py, float pz) { return gradient_noise_inlined(px, py, pz); }

// Vector noise: three decorrelated components (the same field at shifted points).
[[gnu::always_inline]] inline void gradient_noise3_inlined(float px, float py, float pz, float& nx, float& ny,
                                                           float& nz) {
    nx = gradient_noise_inlined(px, py, pz);
    ny = gradient_noise_inlined(px + 31.416f, py - 47.853f, pz + 12.679f);
    nz = gradient_noise_inlined(px - 19.191f, py + 7.337f, pz - 57.931f);
}

inline void gradient_noise3(float px, float py, float pz, float& nx, float& ny, float& nz) {
    nx = gradient_noise(px, py, pz);
    ny = gradient_noise(px + 31.416f, py - 47.853f, pz + 12.679f);
    nz = gradient_noise(px - 19.191f, py + 7.337f, pz - 57.931f);
}

}  // namespace airlight
