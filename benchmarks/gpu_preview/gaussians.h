// gaussians.h: the benchmark's Gaussian fog (fog-object Gaussians as the preview gets
// them) and the per-(light, Gaussian) factors the preview computes natively per frame.
#pragma once

#include <vector>

#include <glm/glm.hpp>

struct GaussianSet {
  // Density of Gaussian i: c[i] exp(-a[i]^2 |x - b[i]|^2) (medium.h).
  std::vector<glm::dvec3> b;
  std::vector<double> a, c;
  std::vector<double> R;    // cull radii for the splat quads (cull_eps)
  std::vector<double> R_bake;  // cull radii at the bake's eps 1e-7 (they scale the noise)
  std::vector<double> f1;   // [l * n + i]: exp(-(T(s_l, b_i) + T(v, b_i)) without Gaussian i)
  std::vector<double> Csv;  // [l]: exp(-(T(s_l, v) - beta0 |s_l - v|)) (Fogshop eq. 15-17)
  size_t size() const { return a.size(); }
};

// _n_ Gaussians, seeded (every run and driver draws the same ones): centres uniform in the
// view frustum (ndc x, y in [-1, 1]) at view depths 5 .. 30 m and heights 0 .. 4 m, scales
// a in [1, 2] / m (the paint brush's default is 1), amplitudes c in [0.003, 0.015] / m
// (fainter than the brush's 0.2 so that 3000 overlapping Gaussians stay translucent: mean
// added density ~0.1 / m). R_i = sqrt(ln(c_i sqrt(pi) / (a_i cull_eps))) / a_i.
// f1 and Csv from optical depths over all Gaussians (each skipped where the segment stays
// outside its sphere for eps 1e-7, as RbfMedium does) plus beta0 on the segment.
// _axis_: unit view direction, _tan_half_: tangents of the half field of view (x, y).
GaussianSet make_gaussians(int n, const glm::vec3 &eye, const glm::vec3 &axis,
                           const glm::vec2 &tan_half, const std::vector<glm::vec3> &lights,
                           double beta0, double cull_eps);
