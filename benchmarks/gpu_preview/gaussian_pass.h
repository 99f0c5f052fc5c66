// gaussian_pass.h: the Gaussian fog splatting pass of the preview (Fogshop section 5):
// one instanced quad per Gaussian over its cull sphere's screen bounds, additive
// accumulation of airlight and optical depth into an RGBA32F target at 1/scale
// resolution, then a composite onto the viewport with ALPHA_PREMULT blending.
// The shaders are the harness's own stand-ins (shaders/bench_gaussian_*.glsl here)
// until the add-on's own splatting shaders exist (see README.md).
#pragma once

#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "create_info.h"

struct GaussianPass {
  unsigned splat = 0, composite = 0;
  unsigned gauss_tex = 0, f1_tex = 0;
  unsigned quad_vao = 0, quad_vbo = 0, quad_ibo = 0;
  unsigned fs_vao = 0, fs_vbo = 0, fs_ibo = 0;
  unsigned acc_fbo = 0, acc_tex = 0;
  int acc_w = 0, acc_h = 0;
  int count = 0, light_count = 0;
  unsigned ftab = 0, lights = 0;
  // Set count_fragments and the next draw counts the splat's fragments (GL_SAMPLES_PASSED).
  bool count_fragments = false;
  unsigned long long fragments = 0;
  unsigned samples_query = 0;

  // Random Gaussians in the view of the benchmark scene (seeded: every run and driver
  // draws the same ones): centres uniform in the view frustum (ndc x, y in [-1, 1]) at
  // view depths 5 .. 30 m and heights 0 .. 4 m, scales a in [1, 2] / m (the brush's
  // default is 1), amplitudes c in [0.003, 0.015] / m (fainter than the brush's 0.2,
  // so that 3000 overlapping Gaussians stay translucent: mean added density ~0.1 / m); cull
  // radius for _cull_eps_; f1 per (light, Gaussian) on the CPU from the optical depths
  // through all Gaussians (culled at their cull spheres) and _beta0_.
  // _axis_: unit view direction, _tan_half_: tangents of the half field of view (x, y).
  void build(const std::string &repo_shader_dir, const std::string &bench_shader_dir,
             const GLSLTarget &target, int n, const glm::vec3 &eye, const glm::vec3 &axis,
             const glm::vec2 &tan_half,
             const std::vector<glm::vec3> &light_positions, float beta0, double cull_eps,
             unsigned ftab_tex, unsigned lights_tex);

  // Draws onto the bound viewport framebuffer of size w x h (restores nothing but
  // leaves blending off). depth_tex: the preview's distance target.
  void draw(unsigned viewport_fbo, int w, int h, const glm::mat4 &persp,
            const glm::mat4 &inv_persp, const glm::vec4 &eye, const glm::vec4 &clip,
            unsigned depth_tex, float sigma_t, int scale);
};
