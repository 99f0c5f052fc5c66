// gaussians.cpp: see gaussians.h.
#include "gaussians.h"

#include <algorithm>
#include <cmath>
#include <random>

namespace {

const double kSqrtPi = 1.7724538509055159;

double erf_diff(double x1, double x2)
{
  if (x1 >= 0.0) return std::erfc(x1) - std::erfc(x2);
  if (x2 <= 0.0) return std::erfc(-x2) - std::erfc(-x1);
  return std::erf(x2) - std::erf(x1);
}

double cull_radius(double a, double c, double eps)
{
  double lg = std::log(c * kSqrtPi / (a * eps));
  return lg > 0.0 ? std::sqrt(lg) / a : 0.0;
}

// Optical depth of Gaussian (b, a, c) on the segment p -> q (medium.h, eq. 31).
double segment_T(const glm::dvec3 &b, double a, double c, const glm::dvec3 &p, const glm::dvec3 &q)
{
  glm::dvec3 d = q - p;
  double L = glm::length(d);
  if (L <= 0.0) return 0.0;
  glm::dvec3 r = d / L, bo = b - p;
  double ts = glm::dot(bo, r);
  double h2 = std::max(glm::dot(bo, bo) - ts * ts, 0.0);
  return c * kSqrtPi / (2.0 * a) * std::exp(-a * a * h2) * erf_diff(-a * ts, a * (L - ts));
}

// Whether the segment p -> q comes within _R_ of _b_.
bool reaches(const glm::dvec3 &b, double R, const glm::dvec3 &p, const glm::dvec3 &q)
{
  glm::dvec3 d = q - p;
  double L2 = glm::dot(d, d);
  double t = L2 > 0.0 ? std::clamp(glm::dot(b - p, d) / L2, 0.0, 1.0) : 0.0;
  glm::dvec3 e = p + t * d - b;
  return glm::dot(e, e) <= R * R;
}

}  // namespace

GaussianSet make_gaussians(int n, const glm::vec3 &eye, const glm::vec3 &axis,
                           const glm::vec2 &tan_half, const std::vector<glm::vec3> &lights,
                           double beta0, double cull_eps)
{
  GaussianSet g;
  std::mt19937 rng(20071);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  const glm::dvec3 v(eye), fwd(axis), right = glm::normalize(glm::cross(fwd, glm::dvec3(0, 0, 1))),
                   up = glm::cross(right, fwd);
  while (int(g.size()) < n) {
    double x = 2.0 * u01(rng) - 1.0, y = 2.0 * u01(rng) - 1.0, d = 5.0 + 25.0 * u01(rng);
    glm::dvec3 p = v + d * (fwd + x * double(tan_half.x) * right + y * double(tan_half.y) * up);
    double a = 1.0 + u01(rng), c = 0.003 + 0.012 * u01(rng);
    if (p.z < 0.0 || p.z > 4.0) continue;
    g.b.push_back(p);
    g.a.push_back(a);
    g.c.push_back(c);
    g.R.push_back(cull_radius(a, c, cull_eps));
    g.R_bake.push_back(cull_radius(a, c, 1e-7));  // GaussianMedium::kDefaultCullEps
  }
  // Optical depths for the factors: culled at eps 1e-7 like RbfMedium's default.
  std::vector<double> R7(n);
  for (int i = 0; i < n; ++i) R7[i] = cull_radius(g.a[i], g.c[i], 1e-7);
  auto depth_without = [&](const glm::dvec3 &p, int i) {
    double T = beta0 * glm::length(g.b[i] - p);
    for (int j = 0; j < n; ++j)
      if (j != i && reaches(g.b[j], R7[j], p, g.b[i])) T += segment_T(g.b[j], g.a[j], g.c[j], p, g.b[i]);
    return T;
  };
  std::vector<double> Tv(n);
  for (int i = 0; i < n; ++i) Tv[i] = depth_without(v, i);
  const size_t L = lights.size();
  g.f1.assign(L * n, 0.0);
  g.Csv.assign(L, 1.0);
  for (size_t l = 0; l < L; ++l) {
    const glm::dvec3 s(lights[l]);
    for (int i = 0; i < n; ++i) g.f1[l * n + i] = std::exp(-(depth_without(s, i) + Tv[i]));
    double T = 0.0;
    for (int j = 0; j < n; ++j)
      if (reaches(g.b[j], R7[j], s, v)) T += segment_T(g.b[j], g.a[j], g.c[j], s, v);
    g.Csv[l] = std::exp(-T);
  }
  return g;
}
