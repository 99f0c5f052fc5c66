// standin_splat.h: the harness's own Gaussian splatting pass (shaders/bench_gaussian_*.glsl
// in this folder), written before the add-on had one and kept for comparison: one
// instanced quad per Gaussian over its cull sphere's screen bounds, per pixel the
// erf line integral and Fogshop's L_i per light, additive accumulation of airlight and
// optical depth into an RGBA32F target at 1/scale resolution, then a composite of that
// target over the viewport (L = La_g + exp(-T_g) L_behind: the Gaussian fog in front of
// the homogeneous fog, a simplification of the bake's combination).
#pragma once

#include <string>

#include "create_info.h"
#include "gaussians.h"
#include "gl_util.h"

struct StandinSplat {
  GLuint splat = 0, composite = 0, gauss_tex = 0, f1_tex = 0;
  Mesh quad, fullscreen;
  Target acc;
  int count = 0, light_count = 0;
  GLuint ftab = 0, lights = 0;

  void build(const std::string &repo_shader_dir, const std::string &bench_shader_dir,
             const GLSLTarget &target, const GaussianSet &g, int light_count, GLuint ftab_tex,
             GLuint lights_tex);

  // Draws onto _viewport_fbo_ (w x h); returns the number of fragments the splat drew
  // when _count_fragments_.
  unsigned long long draw(GLuint viewport_fbo, int w, int h, const glm::mat4 &persp,
                          const glm::mat4 &inv_persp, const glm::vec4 &eye,
                          const glm::vec4 &clip, GLuint depth_tex, float sigma_t, int scale,
                          bool count_fragments);
};
