// gaussian_pass.cpp: see gaussian_pass.h.
#include "gaussian_pass.h"

#define GL_GLEXT_PROTOTYPES 1
#include <GL/glcorearb.h>

#include <glm/gtc/type_ptr.hpp>

#include <algorithm>
#include <cmath>
#include <random>
#include <stdexcept>

namespace {

const double kSqrtPi = 1.7724538509055159;

double erf_diff(double x1, double x2)
{
  if (x1 >= 0.0) return std::erfc(x1) - std::erfc(x2);
  if (x2 <= 0.0) return std::erfc(-x2) - std::erfc(-x1);
  return std::erf(x2) - std::erf(x1);
}

// Optical depth of Gaussian (b, a, c) on the segment p -> q (rbf_medium.h, eq. 31).
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

// Whether the segment p -> q comes within _R_ of _b_ (else its T is below the cull eps).
bool reaches(const glm::dvec3 &b, double R, const glm::dvec3 &p, const glm::dvec3 &q)
{
  glm::dvec3 d = q - p;
  double L2 = glm::dot(d, d);
  double t = L2 > 0.0 ? std::clamp(glm::dot(b - p, d) / L2, 0.0, 1.0) : 0.0;
  glm::dvec3 e = p + t * d - b;
  return glm::dot(e, e) <= R * R;
}

void uniform(unsigned prog, const char *name, const glm::mat4 &m)
{
  GLint loc = glGetUniformLocation(prog, name);
  if (loc >= 0) glProgramUniformMatrix4fv(prog, loc, 1, GL_FALSE, glm::value_ptr(m));
}
void uniform(unsigned prog, const char *name, const glm::vec4 &v)
{
  GLint loc = glGetUniformLocation(prog, name);
  if (loc >= 0) glProgramUniform4fv(prog, loc, 1, glm::value_ptr(v));
}
void uniform(unsigned prog, const char *name, float f)
{
  GLint loc = glGetUniformLocation(prog, name);
  if (loc >= 0) glProgramUniform1f(prog, loc, f);
}
void uniform(unsigned prog, const char *name, int i)
{
  GLint loc = glGetUniformLocation(prog, name);
  if (loc >= 0) glProgramUniform1i(prog, loc, i);
}

unsigned float_texture(int w, int h, GLenum fmt, GLenum format, const float *data)
{
  GLuint t = 0;
  glCreateTextures(GL_TEXTURE_2D, 1, &t);
  glTextureStorage2D(t, 1, fmt, w, h);
  glTextureParameteri(t, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
  glTextureParameteri(t, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
  glTextureSubImage2D(t, 0, 0, 0, w, h, format, GL_FLOAT, data);
  return t;
}

void quad_mesh(const float *v, unsigned &vao, unsigned &vbo, unsigned &ibo)
{
  const unsigned idx[6] = {0, 1, 2, 0, 2, 3};
  glCreateVertexArrays(1, &vao);
  glCreateBuffers(1, &vbo);
  glCreateBuffers(1, &ibo);
  glNamedBufferStorage(vbo, 8 * sizeof(float), v, 0);
  glNamedBufferStorage(ibo, sizeof(idx), idx, 0);
  glVertexArrayVertexBuffer(vao, 0, vbo, 0, 2 * sizeof(float));
  glVertexArrayElementBuffer(vao, ibo);
  glEnableVertexArrayAttrib(vao, 0);
  glVertexArrayAttribFormat(vao, 0, 2, GL_FLOAT, GL_FALSE, 0);
  glVertexArrayAttribBinding(vao, 0, 0);
}

}  // namespace

void GaussianPass::build(const std::string &repo_dir, const std::string &bench_dir,
                         const GLSLTarget &target, int n, const glm::vec3 &eye,
                         const glm::vec3 &axis, const glm::vec2 &tan_half,
                         const std::vector<glm::vec3> &light_positions, float beta0,
                         double cull_eps, unsigned ftab_tex, unsigned lights_tex)
{
  count = n;
  light_count = static_cast<int>(light_positions.size());
  ftab = ftab_tex;
  lights = lights_tex;
  const std::string libs = read_text_file(repo_dir + "/sun05_airlight.glsl") + "\n" +
                           read_text_file(repo_dir + "/preview_common.glsl") + "\n";
  std::vector<std::pair<std::string, std::string>> push = {
      {"mat4", "persp"},     {"mat4", "inv_persp"}, {"vec4", "eye"},
      {"vec4", "clip"},      {"vec4", "viewport"},  {"float", "sigma_t"},
      {"int", "light_count"}, {"int", "scale"}};
  CreateInfo s;
  s.name = "bench_gaussian_splat";
  s.vertex_in = {{"vec2", "pos"}};
  s.iface_name = "bench_gaussian_splat_iface";
  s.iface = {{"flat", "int", "gid"}};
  s.push_constants = push;
  s.samplers = {"Ftab", "depth_tex", "lights", "gauss", "f1tab"};
  s.defines = {{"PREVIEW_WINDOW_DEPTH", "0"}};
  s.vertex_source = read_text_file(bench_dir + "/bench_gaussian_splat_vert.glsl");
  s.fragment_source = libs + read_text_file(bench_dir + "/bench_gaussian_splat_frag.glsl");
  splat = create_info_program(s, target);

  CreateInfo c;
  c.name = "bench_gaussian_composite";
  c.vertex_in = {{"vec2", "pos"}};
  c.iface_name = "bench_gaussian_composite_iface";
  c.iface = {{"smooth", "vec2", "uv"}};
  c.push_constants = {{"vec4", "viewport"}, {"int", "scale"}};
  c.samplers = {"fog_lo"};
  c.vertex_source = read_text_file(repo_dir + "/fullscreen_vert.glsl");
  c.fragment_source = read_text_file(bench_dir + "/bench_gaussian_composite_frag.glsl");
  composite = create_info_program(c, target);

  const float unit[8] = {0, 0, 1, 0, 1, 1, 0, 1};
  quad_mesh(unit, quad_vao, quad_vbo, quad_ibo);
  const float full[8] = {-1, -1, 1, -1, 1, 1, -1, 1};
  quad_mesh(full, fs_vao, fs_vbo, fs_ibo);

  // Gaussians in the view frustum (see the header).
  std::mt19937 rng(20071);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  const glm::dvec3 fwd(axis), right = glm::normalize(glm::cross(fwd, glm::dvec3(0, 0, 1))),
                   up = glm::cross(right, fwd);
  std::vector<glm::dvec3> b;
  std::vector<double> a, amp, R;
  while (int(b.size()) < n) {
    double x = 2.0 * u01(rng) - 1.0, y = 2.0 * u01(rng) - 1.0, d = 5.0 + 25.0 * u01(rng);
    glm::dvec3 p = glm::dvec3(eye) + d * (fwd + x * tan_half.x * right + y * tan_half.y * up);
    double ai = 1.0 + u01(rng), ci = 0.003 + 0.012 * u01(rng);
    if (p.z < 0.0 || p.z > 4.0) continue;
    b.push_back(p);
    a.push_back(ai);
    amp.push_back(ci);
    double lg = std::log(ci * kSqrtPi / (ai * cull_eps));
    R.push_back(lg > 0.0 ? std::sqrt(lg) / ai : 0.0);
  }
  std::vector<float> g(size_t(n) * 8, 0.0f);
  for (int i = 0; i < n; ++i) {
    float *row0 = &g[size_t(i) * 4], *row1 = &g[(size_t(n) + i) * 4];
    row0[0] = float(b[i].x), row0[1] = float(b[i].y), row0[2] = float(b[i].z), row0[3] = float(a[i]);
    row1[0] = float(amp[i]), row1[1] = float(R[i]);
  }
  gauss_tex = float_texture(n, 2, GL_RGBA32F, GL_RGBA, g.data());

  // f1(l, i) = exp(-(T(s, b_i) + T(v, b_i)) without Gaussian i) (Fogshop eq. 12, 13).
  const glm::dvec3 v(eye);
  std::vector<double> Tv(n, 0.0);
  for (int i = 0; i < n; ++i) {
    double T = beta0 * glm::length(b[i] - v);
    for (int j = 0; j < n; ++j)
      if (j != i && reaches(b[j], R[j], v, b[i])) T += segment_T(b[j], a[j], amp[j], v, b[i]);
    Tv[i] = T;
  }
  const int nl = std::max(1, light_count);
  std::vector<float> f1(size_t(n) * nl, 0.0f);
  for (int l = 0; l < light_count; ++l) {
    const glm::dvec3 sl(light_positions[l]);
    for (int i = 0; i < n; ++i) {
      double T = beta0 * glm::length(b[i] - sl);
      for (int j = 0; j < n; ++j)
        if (j != i && reaches(b[j], R[j], sl, b[i])) T += segment_T(b[j], a[j], amp[j], sl, b[i]);
      f1[size_t(l) * n + i] = float(std::exp(-(T + Tv[i])));
    }
  }
  f1_tex = float_texture(n, nl, GL_R32F, GL_RED, f1.data());
}

void GaussianPass::draw(unsigned viewport_fbo, int w, int h, const glm::mat4 &persp,
                        const glm::mat4 &inv_persp, const glm::vec4 &eye, const glm::vec4 &clip,
                        unsigned depth_tex, float sigma_t, int scale)
{
  const int lw = (w + scale - 1) / scale, lh = (h + scale - 1) / scale;
  if (acc_w != lw || acc_h != lh) {
    if (acc_fbo) {
      glDeleteFramebuffers(1, &acc_fbo);
      glDeleteTextures(1, &acc_tex);
    }
    glCreateTextures(GL_TEXTURE_2D, 1, &acc_tex);
    glTextureStorage2D(acc_tex, 1, GL_RGBA32F, lw, lh);
    glCreateFramebuffers(1, &acc_fbo);
    glNamedFramebufferTexture(acc_fbo, GL_COLOR_ATTACHMENT0, acc_tex, 0);
    if (glCheckNamedFramebufferStatus(acc_fbo, GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE)
      throw std::runtime_error("incomplete Gaussian accumulation framebuffer");
    acc_w = lw;
    acc_h = lh;
  }
  const glm::vec4 region(0.0f, 0.0f, float(w), float(h));
  // Splat: additive accumulation at 1/scale resolution.
  glBindFramebuffer(GL_FRAMEBUFFER, acc_fbo);
  glViewport(0, 0, lw, lh);
  const float zero[4] = {0, 0, 0, 0};
  glClearNamedFramebufferfv(acc_fbo, GL_COLOR, 0, zero);
  glDisable(GL_DEPTH_TEST);
  glDepthMask(GL_FALSE);
  glEnable(GL_BLEND);
  glBlendFunc(GL_ONE, GL_ONE);
  glUseProgram(splat);
  uniform(splat, "persp", persp);
  uniform(splat, "inv_persp", inv_persp);
  uniform(splat, "eye", eye);
  uniform(splat, "clip", clip);
  uniform(splat, "viewport", region);
  uniform(splat, "sigma_t", sigma_t);
  uniform(splat, "light_count", light_count);
  uniform(splat, "scale", scale);
  glBindTextureUnit(0, ftab);
  glBindTextureUnit(1, depth_tex);
  glBindTextureUnit(2, lights);
  glBindTextureUnit(3, gauss_tex);
  glBindTextureUnit(4, f1_tex);
  glBindVertexArray(quad_vao);
  if (count_fragments) {
    if (samples_query == 0) glGenQueries(1, &samples_query);
    glBeginQuery(GL_SAMPLES_PASSED, samples_query);
  }
  glDrawElementsInstanced(GL_TRIANGLES, 6, GL_UNSIGNED_INT, nullptr, count);
  if (count_fragments) {
    glEndQuery(GL_SAMPLES_PASSED);
    GLuint64 n = 0;
    glGetQueryObjectui64v(samples_query, GL_QUERY_RESULT, &n);
    fragments = n;
    count_fragments = false;
  }
  // Composite onto the viewport: L = La_g + exp(-T_g) L_behind.
  glBindFramebuffer(GL_FRAMEBUFFER, viewport_fbo);
  glViewport(0, 0, w, h);
  glBlendFuncSeparate(GL_ONE, GL_ONE_MINUS_SRC_ALPHA, GL_ONE, GL_ONE_MINUS_SRC_ALPHA);
  glUseProgram(composite);
  uniform(composite, "viewport", region);
  uniform(composite, "scale", scale);
  glBindTextureUnit(0, acc_tex);
  glBindVertexArray(fs_vao);
  glDrawElements(GL_TRIANGLES, 6, GL_UNSIGNED_INT, nullptr);
  glDisable(GL_BLEND);
}
