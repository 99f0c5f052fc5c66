// standin_splat.cpp: see standin_splat.h.
#include "standin_splat.h"

#include <algorithm>

void StandinSplat::build(const std::string &repo_dir, const std::string &bench_dir,
                         const GLSLTarget &target, const GaussianSet &g, int nl, GLuint ftab_tex,
                         GLuint lights_tex)
{
  const int n = int(g.size());
  count = n;
  light_count = nl;
  ftab = ftab_tex;
  lights = lights_tex;
  const std::string libs = read_text_file(repo_dir + "/sun05_airlight.glsl") + "\n" +
                           read_text_file(repo_dir + "/preview_common.glsl") + "\n";
  CreateInfo s;
  s.name = "bench_gaussian_splat";
  s.vertex_in = {{"vec2", "pos"}};
  s.iface_name = "bench_gaussian_splat_iface";
  s.iface = {{"flat", "int", "gid"}};
  s.push_constants = {{"mat4", "persp"},     {"mat4", "inv_persp"}, {"vec4", "eye"},
                      {"vec4", "clip"},      {"vec4", "viewport"},  {"float", "sigma_t"},
                      {"int", "light_count"}, {"int", "scale"},      {"vec4", "phase"}};
  s.samplers = {"Ftab", "depth_tex", "lights", "gauss", "f1tab"};
  // preview_common.glsl reads pv_* names once the preview has uniform buffers: point
  // them at this pass's push constants (harmless where they are unused).
  s.defines = {{"PREVIEW_WINDOW_DEPTH", "0"}, {"PREVIEW_PHASE", "0"}, {"pv_sigma_t", "sigma_t"},
               {"pv_phase", "phase"}, {"pv_scale", "scale"}};
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

  quad = make_mesh({{2, {0, 0, 1, 0, 1, 1, 0, 1}}}, {0, 1, 2, 0, 2, 3});
  fullscreen = make_mesh({{2, {-1, -1, 1, -1, 1, 1, -1, 1}}}, {0, 1, 2, 0, 2, 3});

  std::vector<float> data(size_t(n) * 8, 0.0f);
  for (int i = 0; i < n; ++i) {
    float *row0 = &data[size_t(i) * 4], *row1 = &data[(size_t(n) + i) * 4];
    row0[0] = float(g.b[i].x), row0[1] = float(g.b[i].y), row0[2] = float(g.b[i].z);
    row0[3] = float(g.a[i]);
    row1[0] = float(g.c[i]), row1[1] = float(g.R[i]);
  }
  gauss_tex = gl_texture(n, 2, GL_RGBA32F, data.data());
  const int rows = std::max(1, nl);
  std::vector<float> f1(size_t(n) * rows, 0.0f);
  for (size_t k = 0; k < g.f1.size(); ++k) f1[k] = float(g.f1[k]);
  f1_tex = gl_texture(n, rows, GL_R32F, f1.data(), GL_RED);
}

unsigned long long StandinSplat::draw(GLuint viewport_fbo, int w, int h, const glm::mat4 &persp,
                                      const glm::mat4 &inv_persp, const glm::vec4 &eye,
                                      const glm::vec4 &clip, GLuint depth_tex, float sigma_t,
                                      int scale, bool count_fragments)
{
  const int lw = (w + scale - 1) / scale, lh = (h + scale - 1) / scale;
  if (acc.w != lw || acc.h != lh) {
    if (acc.fbo) free_target(acc);
    acc = make_target(lw, lh, GL_RGBA32F, false);
  }
  const glm::vec4 region(0.0f, 0.0f, float(w), float(h));
  glBindFramebuffer(GL_FRAMEBUFFER, acc.fbo);
  glViewport(0, 0, lw, lh);
  const float zero[4] = {0, 0, 0, 0};
  glClearNamedFramebufferfv(acc.fbo, GL_COLOR, 0, zero);
  glDisable(GL_DEPTH_TEST);
  glDepthMask(GL_FALSE);
  glEnable(GL_BLEND);
  glBlendFunc(GL_ONE, GL_ONE);
  glUseProgram(splat);
  set_uniform(splat, "persp", persp);
  set_uniform(splat, "inv_persp", inv_persp);
  set_uniform(splat, "eye", eye);
  set_uniform(splat, "clip", clip);
  set_uniform(splat, "viewport", region);
  set_uniform(splat, "sigma_t", sigma_t);
  set_uniform(splat, "light_count", light_count);
  set_uniform(splat, "scale", scale);
  glBindTextureUnit(0, ftab);
  glBindTextureUnit(1, depth_tex);
  glBindTextureUnit(2, lights);
  glBindTextureUnit(3, gauss_tex);
  glBindTextureUnit(4, f1_tex);
  GLuint q = 0;
  if (count_fragments) {
    glGenQueries(1, &q);
    glBeginQuery(GL_SAMPLES_PASSED, q);
  }
  glBindVertexArray(quad.vao);
  glDrawElementsInstanced(GL_TRIANGLES, 6, GL_UNSIGNED_INT, nullptr, count);
  GLuint64 fragments = 0;
  if (count_fragments) {
    glEndQuery(GL_SAMPLES_PASSED);
    glGetQueryObjectui64v(q, GL_QUERY_RESULT, &fragments);
    glDeleteQueries(1, &q);
  }
  stamp("splat");
  glBindFramebuffer(GL_FRAMEBUFFER, viewport_fbo);
  glViewport(0, 0, w, h);
  glBlendFuncSeparate(GL_ONE, GL_ONE_MINUS_SRC_ALPHA, GL_ONE, GL_ONE_MINUS_SRC_ALPHA);
  glUseProgram(composite);
  set_uniform(composite, "viewport", region);
  set_uniform(composite, "scale", scale);
  glBindTextureUnit(0, acc.colour[0]);
  ::draw(fullscreen);
  glDisable(GL_BLEND);
  stamp("gauss_composite");
  return fragments;
}
