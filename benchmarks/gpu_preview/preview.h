// preview.h: what addon/airlight/preview.py draws per viewport redraw, in plain GL 4.5,
// with the add-on's own GLSL files and the create-info interfaces of gpu_shaders.py.
//
// Two interface versions of the add-on's shaders are understood (chosen by the files in
// the shader folder):
//   v1  sun05_airlight.glsl + preview_common.glsl in front of each pass; push constants
//       inv_persp, eye, clip, viewport, sigma_t, light_count, scale, mode; samplers
//       Ftab, depth_tex, lights, fog_lo (preview._FOG_INPUTS before the Gaussian fog).
//   v2  (rbf_splat_vert.glsl present) gpu_shaders.create_preview_shader: libs
//       sun05_airlight + biri06_airlight + preview_common, push constants + phase,
//       samplers + gauss_acc, gauss_near, Gtab, defines PREVIEW_PHASE and
//       PREVIEW_GAUSSIANS / PREVIEW_GAUSS_SCALE; plus the Gaussian splat pass
//       (gpu_shaders.create_rbf_splat_shader, rbf_splat_batch, rbf_data_textures).
//       With spot_airlight.glsl / sun_airlight.glsl present (spot lights and sun lamps in
//       the preview), those libs and the samplers spots / suns follow, and the defines
//       PREVIEW_SPOTS / PREVIEW_SUNS are given as 0 (the benchmark has point lights only).
//       With preview_params.glsl present the passes read their parameters from uniform
//       buffers instead of push constants (gpu_shaders.PREVIEW_UBO "pv", DISTANCE_UBO
//       "dv"; filled per bind as preview_params_ubo / distance_params_ubo do).
//   v3  (rbf_splat_pixel.glsl present) per-Gaussian colours and noise: the splat's
//       fragment sources are gpu_shaders.RBF_SPLAT_SOURCES (+ rbf_noise.glsl,
//       rbf_splat_pixel.glsl), the gauss texture has 3 rows per block (albedo, the noise's
//       R_bake / |b - v|), the lights texture a third row (the splat's I0), the uniform
//       buffer 240 bytes (noise amplitude, offset, 1 / scale); and the tile pass
//       (gpu_shaders.create_rbf_tiles_shader: rbf_tiles_frag.glsl over per-tile lists
//       from native/bindings/preview_tiles.h, as _native.rbf_tile_lists builds them).
#pragma once

#include <map>
#include <string>
#include <vector>

#include "create_info.h"
#include "gaussians.h"
#include "gl_util.h"

struct View {
  glm::mat4 persp, inv_persp;
  glm::vec3 eye, axis;
  glm::vec2 tan_half;  // tangents of the half field of view (x, y)
  float clip_start;
};

// The scene of benchmarks/bench_preview.py: camera at (1, -12, 5) looking at (0, 0, 1),
// Blender's default 50 mm lens on a 36 mm sensor (sensor fit AUTO), clip 0.1 .. 100.
View make_view(int w, int h);

struct Preview {
  GLSLTarget target;
  std::string dir;
  bool v2 = false, spots = false, suns = false, ubo = false, v3 = false;
  // v4 (rbf_light_fit_frag.glsl): the light-fit pass; the splat and tile passes read its
  // output (RBF_LIGHT_FIT 1, as the add-on's default preview.LIGHT_FIT); tiles_exact the
  // tile pass with the exact per-pixel light terms (RBF_LIGHT_FIT 0).
  bool v4 = false;
  // RBF_FIT_NEAR of the v4 passes (a GLSL float): the add-on's gpu_shaders.RBF_FIT_NEAR
  // unless --fit-near says otherwise (to measure the fit's share).
  std::string fit_near = "2.0";
  // v3: the Gaussian fog's noise (amplitude 0 = off), scene.airlight.noise_*.
  float noise_amplitude = 0.0f, noise_scale = 1.0f;
  glm::vec3 noise_offset{0.0f};
  std::vector<GLuint> ubo_ring;  // one uniform buffer per bind (Blender makes a new one)
  size_t ubo_next = 0;
  GLuint distance = 0, fog = 0, fog_lo = 0, up_mark = 0, up_exact = 0, composite = 0;
  std::map<int, GLuint> fog_gauss;  // v2: fog pass with the Gaussian sums at scale S
  GLuint ftab = 0, lights = 0, lights_csv = 0;
  int light_count = 0;
  std::vector<glm::vec3> light_positions;
  Mesh quad, scene;
  std::vector<GLsizei> object_offsets, object_counts;
  Target distance_target, lo_target, full_target, gauss_target;
  int lo_scale = 0;
  // Experiment: the FULL fog pass as a compute shader (create_info_compute_glsl) into
  // compute_image, then preview_composite_frag.glsl onto the viewport.
  GLuint fog_compute = 0, compute_image = 0;
  // v2 Gaussian splat pass
  GLuint splat = 0, gauss_tex = 0, f1_tex = 0;
  Mesh splat_batch;
  int gauss_count = 0;
  const GaussianSet *gauss_set = nullptr;
  // v3 tile pass: program, lists for (scale), their textures and size.
  GLuint tiles = 0, tile_index_tex = 0, tile_list_tex = 0;
  // v4: tile pass without the fit, the light-fit pass and its target (gauss_light).
  GLuint tiles_exact = 0, light_fit = 0;
  GLuint tiles_compute = 0;  // experiment: the tile pass as a compute shader (tilescompute_*)
  Target light_target;
  int tiles_scale = 0;
  unsigned long long tile_entries = 0;
  double tiles_build_ms = 0.0;  // CPU time of the last list build + upload (not in the frame times)
  // Samples the last 'exact' draw shaded and the last splat drew (when counting).
  bool count_samples = false;
  unsigned long long exact_samples = 0, splat_samples = 0;
  // Fragment shader invocations of the last counted splat (ARB_pipeline_statistics_query;
  // 0 where the driver lacks it): every fragment the quads cover, before the cull test.
  bool has_pipeline_stats = false;
  unsigned long long splat_invocations = 0;

  // Compiles the passes, uploads the F table (ftable file), lights and the scene.
  void build(const std::string &shader_dir, const std::string &ftable_path, int lights,
             int width, int height);
  // v2: the Gaussians' textures, splat batch and the lights' C_sv.
  void build_gaussians(const GaussianSet &g);

  // preview.draw_distance: the scene's linear distance into distance_target.
  void draw_distance(const View &v);
  // preview.draw_fog onto _viewport_ (mode UPSAMPLE_BILATERAL_EXACT); with _gaussians_
  // (v2) the splat pass at 1/scale and the fog pass at full resolution.
  // _tiles_ (v3): the Gaussian sums by the tile pass instead of the splat.
  // _exact_ (v4): the tile pass with the exact light terms (no light-fit pass).
  // _compute_: the tile pass's GLSL as a compute shader (experiment).
  void draw_fog(const View &v, const Target &viewport, float sigma_t, int scale, bool gaussians,
                bool tiles = false, bool exact = false, bool compute = false);
  // v3: the tile lists for _scale_ (rebuilt when the scale changes; preview_gaussians.
  // GaussianFog.update_tiles).
  void build_tiles(const View &v, int w, int h, int scale);
  void draw_fog_compute(const View &v, const Target &viewport, float sigma_t);

 private:
  std::string src(const std::string &name) const;
  CreateInfo fullscreen_info(const std::string &name, const std::string &frag,
                             std::vector<std::pair<std::string, std::string>> defines);
  GLuint fullscreen(const std::string &name, const std::string &frag,
                    std::vector<std::pair<std::string, std::string>> defines);
  GLuint fog_gauss_program(int gauss_scale);
  std::vector<std::pair<std::string, std::string>> head_defines() const;
  void add_ubo(CreateInfo &ci, bool distance) const;
  void bind_ubo(const void *data, size_t bytes);
  void bind_inputs(GLuint prog, const View &v, glm::vec4 viewport, float sigma_t, int scale,
                   GLuint fog_lo_tex, GLuint lights_tex, const Target *gauss) const;
  void draw_splat(const View &v, int w, int h, float sigma_t, int gauss_scale);
  void draw_tiles(const View &v, int w, int h, float sigma_t, int gauss_scale, bool exact, bool compute);
  void draw_light_fit(const View &v, int w, int h, float sigma_t);
};
