// preview.cpp: see preview.h. Comments name the preview.py / gpu_shaders.py code each
// step mirrors.
#include "preview.h"

#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtc/type_ptr.hpp>

#include <chrono>
#include <cmath>
#include <cstring>
#include <cstdio>
#include <fstream>
#include <stdexcept>

#include "bindings/preview_tiles.h"

namespace {

constexpr int kUpsampleBilateralExact = 2;  // preview.UPSAMPLE_BILATERAL_EXACT (default)
constexpr int kRbfTexWidth = 1024;          // gpu_shaders.RBF_TEX_WIDTH
constexpr int kRbfTile = 8;                 // gpu_shaders.RBF_TILE (v3)
constexpr int kRbfListWidth = 4096;         // gpu_shaders.RBF_LIST_WIDTH (v3)
constexpr int kRbfFitRows = 9;              // gpu_shaders.RBF_FIT_ROWS (v4)
const char *const kRbfFitMaxT = "0.1";      // repr(gpu_shaders.RBF_FIT_MAX_T) (v4)

bool file_exists(const std::string &path)
{
  std::ifstream f(path);
  return bool(f);
}

// Axis-aligned box of half-size _h_ centred at _c_, appended to _v_ / _t_.
void add_box(std::vector<float> &v, std::vector<unsigned> &t, glm::vec3 c, glm::vec3 h)
{
  unsigned base = static_cast<unsigned>(v.size() / 3);
  for (int i = 0; i < 8; ++i) {
    v.push_back(c.x + ((i & 1) ? h.x : -h.x));
    v.push_back(c.y + ((i & 2) ? h.y : -h.y));
    v.push_back(c.z + ((i & 4) ? h.z : -h.z));
  }
  const unsigned q[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4},
                            {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
  for (const auto &f : q) {
    unsigned a[6] = {f[0], f[1], f[2], f[0], f[2], f[3]};
    for (unsigned k : a) t.push_back(base + k);
  }
}

// ALPHA_PREMULT of gpu.state.blend_set.
void blend_alpha_premult()
{
  glEnable(GL_BLEND);
  glBlendFuncSeparate(GL_ONE, GL_ONE_MINUS_SRC_ALPHA, GL_ONE, GL_ONE_MINUS_SRC_ALPHA);
}

}  // namespace

View make_view(int w, int h)
{
  View v;
  v.eye = glm::vec3(1.0f, -12.0f, 5.0f);
  glm::vec3 target(0.0f, 0.0f, 1.0f);
  float aspect = float(w) / float(h);
  float half_w = 18.0f / 50.0f;  // tan(fov_x / 2) with the sensor on the wider side
  float tan_half_y = (aspect >= 1.0f) ? half_w / aspect : half_w;
  v.clip_start = 0.1f;
  v.tan_half = glm::vec2(tan_half_y * aspect, tan_half_y);
  glm::mat4 proj = glm::perspective(2.0f * std::atan(tan_half_y), aspect, v.clip_start, 100.0f);
  glm::mat4 view = glm::lookAt(v.eye, target, glm::vec3(0.0f, 0.0f, 1.0f));
  v.persp = proj * view;
  v.inv_persp = glm::inverse(v.persp);
  v.axis = glm::normalize(target - v.eye);
  return v;
}

std::string Preview::src(const std::string &name) const { return read_text_file(dir + "/" + name); }

// gpu_shaders.create_fullscreen_shader with the preview's inputs (v1: preview._FOG_INPUTS,
// v2: create_preview_shader).
CreateInfo Preview::fullscreen_info(const std::string &name, const std::string &frag,
                                   std::vector<std::pair<std::string, std::string>> defines)
{
  CreateInfo ci;
  ci.name = name;
  ci.vertex_in = {{"vec2", "pos"}};
  ci.iface_name = "airlight_" + name + "_iface";
  ci.iface = {{"smooth", "vec2", "uv"}};
  if (!ubo)
    ci.push_constants = {{"mat4", "inv_persp"}, {"vec4", "eye"},      {"vec4", "clip"},
                         {"vec4", "viewport"},  {"float", "sigma_t"}, {"int", "light_count"},
                         {"int", "scale"},      {"int", "mode"}};
  ci.samplers = {"Ftab", "depth_tex", "lights", "fog_lo"};
  std::string libs = src("sun05_airlight.glsl") + "\n";
  if (v2) {
    if (!ubo) ci.push_constants.push_back({"vec4", "phase"});
    ci.samplers.insert(ci.samplers.end(), {"gauss_acc", "gauss_near", "Gtab"});
    libs += src("biri06_airlight.glsl") + "\n";
  }
  if (spots) {
    ci.samplers.push_back("spots");
    libs += src("spot_airlight.glsl") + "\n";
  }
  if (suns) {
    ci.samplers.push_back("suns");
    libs += src("sun_airlight.glsl") + "\n";
  }
  libs += src("preview_common.glsl") + "\n";
  ci.defines = std::move(defines);
  if (ubo) add_ubo(ci, false);
  ci.vertex_source = src("fullscreen_vert.glsl");
  ci.fragment_source = libs + src(frag);
  return ci;
}

GLuint Preview::fullscreen(const std::string &name, const std::string &frag,
                           std::vector<std::pair<std::string, std::string>> defines)
{
  return create_info_program(fullscreen_info(name, frag, std::move(defines)), target);
}

// gpu_shaders._add_ubo with PREVIEW_UBO (or DISTANCE_UBO): typedef, block at slot 0,
// and a define per member alias.
void Preview::add_ubo(CreateInfo &ci, bool dist) const
{
  if (dist) {
    ci.typedef_source = src("preview_distance_params.glsl");
    ci.uniform_bufs.push_back({0, "AirlightDistanceParams", "dv"});
    ci.defines.insert(ci.defines.end(), {{"eye", "dv.u_eye"}, {"axis", "dv.u_axis"}});
    return;
  }
  ci.typedef_source = src("preview_params.glsl");
  ci.uniform_bufs.push_back({0, "AirlightPreviewParams", "pv"});
  ci.defines.insert(ci.defines.end(),
                    {{"inv_persp", "pv.u_inv_persp"}, {"persp", "pv.u_persp"},
                     {"eye", "pv.u_eye"}, {"clip", "pv.u_clip"}, {"viewport", "pv.u_viewport"},
                     {"pv_phase", "pv.u_phase"}, {"pv_sigma_t", "pv.u_fparams.x"},
                     {"light_count", "pv.u_iparams.x"}, {"pv_scale", "pv.u_iparams.y"},
                     {"pv_mode", "pv.u_iparams.z"}});
  if (v3)
    ci.defines.insert(ci.defines.end(), {{"pv_env_T", "pv.u_fparams.y"},
                                         {"pv_noise_amp", "pv.u_fparams.z"},
                                         {"pv_noise", "pv.u_noise"}});
}

// A fresh std140 block at binding 0 for the next draw (Blender's GPUUniformBuf per bind).
void Preview::bind_ubo(const void *data, size_t bytes)
{
  if (ubo_ring.empty()) {
    ubo_ring.resize(32);
    glCreateBuffers(GLsizei(ubo_ring.size()), ubo_ring.data());
    for (GLuint b : ubo_ring) glNamedBufferData(b, 256, nullptr, GL_DYNAMIC_DRAW);
  }
  GLuint b = ubo_ring[ubo_next++ % ubo_ring.size()];
  glNamedBufferSubData(b, 0, GLsizeiptr(bytes), data);
  glBindBufferBase(GL_UNIFORM_BUFFER, 0, b);
}

// preview._shader's leading defines: the 'DRAWN' depth source, isotropic, no spots/suns.
std::vector<std::pair<std::string, std::string>> Preview::head_defines() const
{
  std::vector<std::pair<std::string, std::string>> d = {{"PREVIEW_WINDOW_DEPTH", "0"}};
  if (v2) d.push_back({"PREVIEW_PHASE", "0"});
  if (spots) d.push_back({"PREVIEW_SPOTS", "0"});
  if (suns) d.push_back({"PREVIEW_SUNS", "0"});
  return d;
}

GLuint Preview::fog_gauss_program(int S)
{
  auto it = fog_gauss.find(S);
  if (it != fog_gauss.end()) return it->second;
  // preview._shader('fog', False, ('gauss', S))
  std::vector<std::pair<std::string, std::string>> defs = head_defines();
  defs.insert(defs.end(), {{"PREVIEW_LOWRES", "0"}, {"PREVIEW_GAUSSIANS", "1"},
                           {"PREVIEW_GAUSS_SCALE", std::to_string(S)}});
  GLuint p = fullscreen("preview_fog", "fog_preview_frag.glsl", defs);
  fog_gauss[S] = p;
  return p;
}

void Preview::build(const std::string &shader_dir, const std::string &ftable_path, int n_lights,
                    int width, int height)
{
  dir = shader_dir;
  v2 = file_exists(dir + "/rbf_splat_vert.glsl");
  ubo = v2 && file_exists(dir + "/preview_params.glsl");
  v3 = ubo && file_exists(dir + "/rbf_splat_pixel.glsl");
  v4 = v3 && file_exists(dir + "/rbf_light_fit_frag.glsl");
  spots = v2 && file_exists(dir + "/spot_airlight.glsl");
  suns = v2 && file_exists(dir + "/sun_airlight.glsl");
  // gpu_shaders.create_distance_shader
  CreateInfo d;
  d.name = "distance";
  d.vertex_in = {{"vec3", "pos"}};
  d.iface_name = "airlight_distance_iface";
  d.iface = {{"smooth", "vec3", "wpos"}};
  d.push_constants = {{"mat4", "model"}, {"mat4", "persp"}};
  if (ubo) add_ubo(d, true);
  else d.push_constants.insert(d.push_constants.end(), {{"vec4", "eye"}, {"vec4", "axis"}});
  d.vertex_source = src("preview_distance_vert.glsl");
  d.fragment_source = src("preview_distance_frag.glsl");
  distance = create_info_program(d, target);
  // preview._shader for the 'DRAWN' depth source (PREVIEW_WINDOW_DEPTH 0), isotropic.
  using Defs = std::vector<std::pair<std::string, std::string>>;
  const Defs head = head_defines();
  auto with = [&](Defs extra, bool gauss_off) {
    Defs all = head;
    all.insert(all.end(), extra.begin(), extra.end());
    if (v2 && gauss_off) all.push_back({"PREVIEW_GAUSSIANS", "0"});
    return all;
  };
  if (v2) {
    fog = fullscreen("preview_fog", "fog_preview_frag.glsl",
                     with({{"PREVIEW_LOWRES", "0"}, {"PREVIEW_GAUSSIANS", "0"},
                           {"PREVIEW_GAUSS_SCALE", "1"}}, false));
    fog_lo = fullscreen("preview_fog", "fog_preview_frag.glsl",
                        with({{"PREVIEW_LOWRES", "1"}, {"PREVIEW_GAUSSIANS", "0"},
                              {"PREVIEW_GAUSS_SCALE", "1"}}, false));
  }
  else {
    fog = fullscreen("preview_fog", "fog_preview_frag.glsl", with({{"PREVIEW_LOWRES", "0"}}, false));
    fog_lo = fullscreen("preview_fog", "fog_preview_frag.glsl", with({{"PREVIEW_LOWRES", "1"}}, false));
  }
  up_mark = fullscreen("preview_upsample", "preview_upsample_frag.glsl",
                       with({{"PREVIEW_EXACT_PASS", "0"}, {"PREVIEW_MARK", "1"}}, true));
  up_exact = fullscreen("preview_upsample", "preview_upsample_frag.glsl",
                        with({{"PREVIEW_EXACT_PASS", "1"}, {"PREVIEW_MARK", "0"}}, true));
  composite = fullscreen("preview_composite", "preview_composite_frag.glsl", with({}, true));

  // gpu_shaders.fullscreen_batch
  quad = make_mesh({{2, {-1, -1, 1, -1, 1, 1, -1, 1}}}, {0, 1, 2, 0, 2, 3});

  // Floor (plane of size 40) and the 2 m cube at (0, 0, 1), one batch each (one draw
  // per object, as preview._scene_instances).
  std::vector<float> verts = {-20, -20, 0, 20, -20, 0, 20, 20, 0, -20, 20, 0};
  std::vector<unsigned> tris = {0, 1, 2, 0, 2, 3};
  object_offsets = {0};
  object_counts = {6};
  add_box(verts, tris, glm::vec3(0, 0, 1), glm::vec3(1, 1, 1));
  object_offsets.push_back(6);
  object_counts.push_back(36);
  scene = make_mesh({{3, verts}}, tris);

  // F table: int32 nu, int32 nT, float32 data[nu][nT] (make_ftable.py from
  // _native.special_F_table()); width nT, height nu, as gpu_shaders.f_table_texture.
  FILE *f = std::fopen(ftable_path.c_str(), "rb");
  if (f == nullptr) throw std::runtime_error("cannot read F table " + ftable_path);
  int dims[2] = {0, 0};
  if (std::fread(dims, sizeof(int), 2, f) != 2 || dims[0] < 2 || dims[1] < 2 ||
      dims[0] > 65536 || dims[1] > 65536) {
    std::fclose(f);
    throw std::runtime_error("bad F table header in " + ftable_path);
  }
  std::vector<float> data(size_t(dims[0]) * dims[1]);
  const size_t got = std::fread(data.data(), sizeof(float), data.size(), f);
  std::fclose(f);
  if (got != data.size()) throw std::runtime_error("short F table " + ftable_path);
  ftab = gl_texture(dims[1], dims[0], GL_R32F, data.data(), GL_RED);

  // Point lights of bench_preview.py: 1000 W white, I0 = P / (4 pi), albedo 1; row 1
  // alpha = C_sv = 1 (preview._lights_texture without fog objects); v3: row 2 = the
  // splat's I0 (albedo I0 again: the benchmark's Gaussians have no colours).
  light_count = n_lights;
  const int n = std::max(1, n_lights);
  const int rows = v3 ? 3 : 2;
  std::vector<float> ltex(size_t(rows) * n * 4, 0.0f);
  for (int i = 0; i < n; ++i) ltex[(size_t(n) + i) * 4 + 3] = 1.0f;
  for (int i = 0; i < n_lights; ++i) {
    float x = -6.0f + 12.0f * i / float(std::max(1, n_lights - 1));
    float y = 2.0f * float(i % 3) - 2.0f;
    float *p = &ltex[size_t(i) * 4], *c = &ltex[(size_t(n) + i) * 4];
    p[0] = x, p[1] = y, p[2] = 2.5f;
    light_positions.emplace_back(x, y, 2.5f);
    c[0] = c[1] = c[2] = 1000.0f / (4.0f * float(M_PI));
    if (v3) {
      float *c2 = &ltex[(size_t(2 * n) + i) * 4];
      c2[0] = c2[1] = c2[2] = c[0];
    }
  }
  lights = gl_texture(n, rows, GL_RGBA32F, ltex.data());
  distance_target = make_target(width, height, GL_R32F, true);
}

void Preview::build_gaussians(const GaussianSet &g)
{
  if (!v2) throw std::runtime_error("the shader folder has no Gaussian splat pass (v1 shaders)");
  // gpu_shaders.create_rbf_splat_shader(window_depth=False)
  CreateInfo s;
  s.name = "rbf_splat";
  s.vertex_in = {{"vec2", "corner"}, {"float", "gid"}};
  s.iface_name = "airlight_rbf_splat_iface";
  s.iface = {{"flat", "int", "gi"}};
  if (ubo) add_ubo(s, false);
  else
    s.push_constants = {{"mat4", "persp"},      {"mat4", "inv_persp"}, {"vec4", "eye"},
                        {"vec4", "clip"},       {"vec4", "viewport"},  {"float", "sigma_t"},
                        {"int", "light_count"}, {"int", "scale"},      {"int", "mode"},
                        {"vec4", "phase"}};
  s.samplers = {"Ftab", "depth_tex", "lights", "gauss", "gauss_f1"};
  s.defines.insert(s.defines.end(), {{"RBF_TEX_WIDTH", std::to_string(kRbfTexWidth)},
                                     {"PREVIEW_WINDOW_DEPTH", "0"},
                                     {"PREVIEW_PHASE", "0"}});
  if (spots) s.defines.push_back({"PREVIEW_SPOTS", "0"});
  if (suns) s.defines.push_back({"PREVIEW_SUNS", "0"});
  // v4: gpu_shaders._rbf_create_info(..., light_fit): the fit's defines, gauss_light last.
  CreateInfo s_exact;
  if (v4) {
    s.defines.insert(s.defines.end(), {{"RBF_LIGHT_FIT", "0"}, {"RBF_FIT_NEAR", fit_near},
                                       {"RBF_FIT_MAX_T", kRbfFitMaxT}});
    s_exact = s;
    for (auto &d : s.defines)
      if (d.first == "RBF_LIGHT_FIT") d.second = "1";
    s.samplers.push_back("gauss_light");
  }
  s.fragment_out = {{"vec4", "frag_color"}, {"vec4", "frag_near"}};
  s_exact.fragment_out = s.fragment_out;
  s.vertex_source = src("rbf_splat_vert.glsl");
  // gpu_shaders.RBF_SPLAT_SOURCES (v3 adds rbf_noise.glsl and rbf_splat_pixel.glsl).
  std::string libs = src("sun05_airlight.glsl") + "\n" + src("preview_common.glsl") + "\n" +
                     src("rbf_gaussian.glsl") + "\n";
  if (v3) libs += src("rbf_noise.glsl") + "\n" + src("rbf_splat_pixel.glsl") + "\n";
  s.fragment_source = libs + src("rbf_splat_frag.glsl") + "\n";
  splat = create_info_program(s, target);
  gauss_set = &g;
  if (v3) {
    // gpu_shaders.create_rbf_tiles_shader: the fullscreen quad's interface, the splat's
    // defines and outputs, two more samplers.
    auto tiles_info = [&](CreateInfo t, bool fit) {
      t.name = "rbf_tiles";
      t.vertex_in = {{"vec2", "pos"}};
      t.iface_name = "airlight_rbf_tiles_iface";
      t.iface = {{"smooth", "vec2", "uv"}};
      if (fit) t.samplers.pop_back();  // gauss_light goes after the tile samplers
      t.samplers.insert(t.samplers.end(), {"tile_index", "tile_list"});
      if (fit) t.samplers.push_back("gauss_light");
      t.defines.insert(t.defines.end(), {{"RBF_TILE", std::to_string(kRbfTile)},
                                         {"RBF_LIST_WIDTH", std::to_string(kRbfListWidth)}});
      t.vertex_source = src("fullscreen_vert.glsl");
      t.fragment_source = libs + src("rbf_tiles_frag.glsl") + "\n";
      return t;
    };
    tiles = create_info_program(tiles_info(s, v4), target);
    // Experiment (tilescompute_*): the same GLSL as a compute shader (create_info_compute_glsl:
    // outputs -> image units 0, 1), as compute_full does for the fog pass. Not what Blender
    // 3.4 can run (no compute from Python before 4.1).
    tiles_compute = create_info_compute_program(tiles_info(s, v4), target);
    if (v4) {
      tiles_exact = create_info_program(tiles_info(s_exact, false), target);
      // gpu_shaders.create_rbf_light_fit_shader
      CreateInfo f = s_exact;
      f.name = "rbf_light_fit";
      f.vertex_in = {{"vec2", "pos"}};
      f.iface_name = "airlight_rbf_light_fit_iface";
      f.iface = {{"smooth", "vec2", "uv"}};
      f.vertex_source = src("fullscreen_vert.glsl");
      f.fragment_source = libs + src("rbf_light_fit_frag.glsl") + "\n";
      light_fit = create_info_program(f, target);
    }
  }

  // gpu_shaders.rbf_splat_batch: 4 vertices and 2 triangles per Gaussian.
  const int n = int(g.size());
  gauss_count = n;
  std::vector<float> corner, gid;
  std::vector<unsigned> tris;
  const float qc[8] = {-1, -1, 1, -1, 1, 1, -1, 1};
  const unsigned qt[6] = {0, 1, 2, 0, 2, 3};
  for (int i = 0; i < n; ++i) {
    corner.insert(corner.end(), qc, qc + 8);
    for (int k = 0; k < 4; ++k) gid.push_back(float(i));
    for (unsigned k : qt) tris.push_back(unsigned(i) * 4 + k);
  }
  splat_batch = make_mesh({{2, corner}, {1, gid}}, tris);

  // gpu_shaders.rbf_data_textures (v3: 3 rows per block, no colours: albedo 1)
  const int W = kRbfTexWidth, blocks = std::max(1, (n + W - 1) / W);
  const int L = std::max(1, light_count);
  const int rows = v3 ? 3 : 2;
  const glm::dvec3 eye(make_view(16, 16).eye);  // the view's eye (independent of the size)
  // v4: gauss_f1 RGBA32F, light l in component l % 4 of row l / 4 of each block.
  const int f1_rows = v4 ? (L + 3) / 4 : L, f1_comp = v4 ? 4 : 1;
  std::vector<float> gauss(size_t(blocks) * rows * W * 4, 0.0f),
      f1(size_t(blocks) * f1_rows * W * f1_comp, 0.0f);
  for (int i = 0; i < n; ++i) {
    const int blk = i / W, col = i % W;
    float *r0 = &gauss[(size_t(blk * rows) * W + col) * 4];
    float *r1 = &gauss[(size_t(blk * rows + 1) * W + col) * 4];
    r0[0] = float(g.b[i].x), r0[1] = float(g.b[i].y), r0[2] = float(g.b[i].z), r0[3] = float(g.a[i]);
    r1[0] = float(g.c[i]), r1[1] = float(g.R[i]);
    if (v3) {
      const double dist = glm::length(g.b[i] - eye);
      r1[2] = dist > 0.0 ? float(g.R_bake[i] / dist) : 0.0f;
      float *r2 = &gauss[(size_t(blk * rows + 2) * W + col) * 4];
      r2[0] = r2[1] = r2[2] = 1.0f;
    }
    for (int l = 0; l < light_count; ++l) {
      if (v4)
        f1[(size_t(blk * f1_rows + l / 4) * W + col) * 4 + l % 4] = float(g.f1[size_t(l) * n + i]);
      else
        f1[size_t(blk * L + l) * W + col] = float(g.f1[size_t(l) * n + i]);
    }
  }
  gauss_tex = gl_texture(W, blocks * rows, GL_RGBA32F, gauss.data());
  // gpu_shaders.rbf_light_fit_texture (v4)
  if (v4) light_target = make_target(W, blocks * kRbfFitRows, GL_RGBA32F, false);
  f1_tex = v4 ? gl_texture(W, blocks * f1_rows, GL_RGBA32F, f1.data())
              : gl_texture(W, blocks * L, GL_R32F, f1.data(), GL_RED);

  // preview._lights_texture(..., Csv)
  const int nl = std::max(1, light_count);
  std::vector<float> ltex(size_t(rows) * nl * 4, 0.0f);
  glGetTextureImage(lights, 0, GL_RGBA, GL_FLOAT, GLsizei(ltex.size() * sizeof(float)), ltex.data());
  for (int l = 0; l < light_count; ++l) ltex[(size_t(nl) + l) * 4 + 3] = float(g.Csv[l]);
  lights_csv = gl_texture(nl, rows, GL_RGBA32F, ltex.data());
}

// preview_gaussians.GaussianFog.update_tiles + gpu_shaders.rbf_tile_textures (v3).
void Preview::build_tiles(const View &v, int w, int h, int S)
{
  if (tiles_scale == S) return;
  const auto t0 = std::chrono::steady_clock::now();
  const GaussianSet &g = *gauss_set;
  std::vector<double> centres, radii(g.R.begin(), g.R.end());
  for (const glm::dvec3 &b : g.b) centres.insert(centres.end(), {b.x, b.y, b.z});
  const airlight::preview::TileLists lists = airlight::preview::tile_lists(
      centres.data(), radii.data(), g.size(), glm::dmat4(v.persp), w, h, S, kRbfTile, true);
  const int lw = (w + S - 1) / S, lh = (h + S - 1) / S;
  const int tx_n = (lw + kRbfTile - 1) / kRbfTile, ty_n = (lh + kRbfTile - 1) / kRbfTile;
  std::vector<float> index(size_t(tx_n) * ty_n * 2);
  for (size_t t = 0; t < lists.first.size(); ++t) {
    index[2 * t] = float(lists.first[t]);
    index[2 * t + 1] = float(lists.count[t]);
  }
  const size_t m = lists.entries.size();
  const int list_rows = int(std::max<size_t>(1, (m + kRbfListWidth - 1) / kRbfListWidth));
  std::vector<float> list(size_t(list_rows) * kRbfListWidth, 0.0f);
  for (size_t e = 0; e < m; ++e) list[e] = float(lists.entries[e]);
  if (tile_index_tex) glDeleteTextures(1, &tile_index_tex);
  if (tile_list_tex) glDeleteTextures(1, &tile_list_tex);
  tile_index_tex = gl_texture(tx_n, ty_n, GL_RG32F, index.data(), GL_RG);
  tile_list_tex = gl_texture(kRbfListWidth, list_rows, GL_R32F, list.data(), GL_RED);
  glFinish();
  tiles_scale = S;
  tile_entries = m;
  tiles_build_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

void Preview::bind_inputs(GLuint prog, const View &v, glm::vec4 viewport, float sigma_t, int scale,
                          GLuint fog_lo_tex, GLuint lights_tex, const Target *gauss) const
{
  glUseProgram(prog);
  if (ubo) {
    // gpu_shaders.preview_params_ubo: 224 bytes std140.
    float f[56] = {};
    std::memcpy(f, glm::value_ptr(v.inv_persp), 64);
    std::memcpy(f + 16, glm::value_ptr(v.persp), 64);
    const glm::vec4 eye4(v.eye, 1.0f), clip4(v.axis, v.clip_start), phase4(0, 0, 1, 1);
    std::memcpy(f + 32, glm::value_ptr(eye4), 16);
    std::memcpy(f + 36, glm::value_ptr(clip4), 16);
    std::memcpy(f + 40, glm::value_ptr(viewport), 16);
    std::memcpy(f + 44, glm::value_ptr(phase4), 16);
    f[48] = sigma_t;
    const int ip[4] = {light_count, scale, kUpsampleBilateralExact, 0};
    std::memcpy(f + 52, ip, 16);
    if (!v3) {
      const_cast<Preview *>(this)->bind_ubo(f, sizeof(f));
    }
    else {
      // v3: 240 bytes, u_fparams.z = noise amplitude, u_noise = (offset, 1 / scale).
      float f3[60] = {};
      std::memcpy(f3, f, sizeof(f));
      if (noise_amplitude > 0.0f) {
        f3[50] = noise_amplitude;
        f3[56] = noise_offset.x, f3[57] = noise_offset.y, f3[58] = noise_offset.z;
        f3[59] = 1.0f / noise_scale;
      }
      const_cast<Preview *>(this)->bind_ubo(f3, sizeof(f3));
    }
  }
  set_uniform(prog, "persp", v.persp);
  set_uniform(prog, "inv_persp", v.inv_persp);
  set_uniform(prog, "eye", glm::vec4(v.eye, 1.0f));
  set_uniform(prog, "clip", glm::vec4(v.axis, v.clip_start));
  set_uniform(prog, "viewport", viewport);
  set_uniform(prog, "sigma_t", sigma_t);
  set_uniform(prog, "light_count", light_count);
  set_uniform(prog, "scale", scale);
  set_uniform(prog, "phase", glm::vec4(0.0f, 0.0f, 1.0f, 1.0f));  // isotropic
  glBindTextureUnit(0, ftab);
  glBindTextureUnit(1, distance_target.colour[0]);
  glBindTextureUnit(2, lights_tex);
  if (fog_lo_tex != 0) {
    set_uniform(prog, "mode", kUpsampleBilateralExact);
    glBindTextureUnit(3, fog_lo_tex);
  }
  if (v2) {
    if (gauss != nullptr) {
      glBindTextureUnit(4, gauss->colour[0]);
      glBindTextureUnit(5, gauss->colour[1]);
    }
    glBindTextureUnit(6, ftab);  // Gtab: the F table stands in for the isotropic phase
    if (spots) glBindTextureUnit(7, ftab);  // unread with PREVIEW_SPOTS 0
    if (suns) glBindTextureUnit(spots ? 8 : 7, ftab);
  }
}

void Preview::draw_distance(const View &v)
{
  glBindFramebuffer(GL_FRAMEBUFFER, distance_target.fbo);
  glViewport(0, 0, distance_target.w, distance_target.h);
  const float clear[4] = {INFINITY, 0, 0, 0};
  glClearNamedFramebufferfv(distance_target.fbo, GL_COLOR, 0, clear);
  glClearNamedFramebufferfi(distance_target.fbo, GL_DEPTH_STENCIL, 0, 1.0f, 0);
  glDisable(GL_BLEND);
  glEnable(GL_DEPTH_TEST);
  glDepthFunc(GL_LEQUAL);
  glDepthMask(GL_TRUE);
  glUseProgram(distance);
  set_uniform(distance, "persp", v.persp);
  const glm::vec4 eye4(v.eye, 1.0f), axis4(v.axis, -glm::dot(v.axis, v.eye));
  if (ubo) {
    float f[8];
    std::memcpy(f, glm::value_ptr(eye4), 16);
    std::memcpy(f + 4, glm::value_ptr(axis4), 16);
    bind_ubo(f, sizeof(f));
  }
  set_uniform(distance, "eye", eye4);
  set_uniform(distance, "axis", axis4);
  glBindVertexArray(scene.vao);
  for (size_t i = 0; i < object_offsets.size(); ++i) {
    set_uniform(distance, "model", glm::mat4(1.0f));
    glDrawElements(GL_TRIANGLES, object_counts[i], GL_UNSIGNED_INT,
                   reinterpret_cast<void *>(size_t(object_offsets[i]) * sizeof(unsigned)));
  }
  glDisable(GL_DEPTH_TEST);
  glDepthMask(GL_FALSE);
  stamp("distance");
}

// preview._draw_gaussians
void Preview::draw_splat(const View &v, int w, int h, float sigma_t, int S)
{
  if (v4) draw_light_fit(v, w, h, sigma_t);  // RBF_LIGHT_FIT 1 (preview.LIGHT_FIT)
  const int lw = (w + S - 1) / S, lh = (h + S - 1) / S;
  if (gauss_target.w != lw || gauss_target.h != lh) {
    if (gauss_target.fbo) free_target(gauss_target);
    gauss_target = make_target(lw, lh, GL_RGBA32F, false, 2);
  }
  glBindFramebuffer(GL_FRAMEBUFFER, gauss_target.fbo);
  glViewport(0, 0, lw, lh);
  const float zero[4] = {0, 0, 0, 0};
  glClearNamedFramebufferfv(gauss_target.fbo, GL_COLOR, 0, zero);
  glClearNamedFramebufferfv(gauss_target.fbo, GL_COLOR, 1, zero);
  glEnable(GL_BLEND);
  glBlendFunc(GL_ONE, GL_ONE);  // ADDITIVE_PREMULT
  bind_inputs(splat, v, glm::vec4(0, 0, float(w), float(h)), sigma_t, S, 0, lights_csv, nullptr);
  glBindTextureUnit(3, gauss_tex);
  glBindTextureUnit(4, f1_tex);
  // No stale binding of the target being drawn; v4: gauss_light.
  glBindTextureUnit(5, v4 ? light_target.colour[0] : 0);
  GLuint q[2] = {0, 0};
  if (count_samples) {
    glGenQueries(2, q);
    glBeginQuery(GL_SAMPLES_PASSED, q[0]);
    if (has_pipeline_stats) glBeginQuery(GL_FRAGMENT_SHADER_INVOCATIONS_ARB, q[1]);
  }
  ::draw(splat_batch);
  if (count_samples) {
    glEndQuery(GL_SAMPLES_PASSED);
    if (has_pipeline_stats) glEndQuery(GL_FRAGMENT_SHADER_INVOCATIONS_ARB);
    GLuint64 n = 0, m = 0;
    glGetQueryObjectui64v(q[0], GL_QUERY_RESULT, &n);
    if (has_pipeline_stats) glGetQueryObjectui64v(q[1], GL_QUERY_RESULT, &m);
    splat_samples = n;
    splat_invocations = m;
    glDeleteQueries(2, q);
  }
  stamp("splat");
}

// preview._fit_lights (v4): the light-fit pass into light_target, every draw.
void Preview::draw_light_fit(const View &v, int w, int h, float sigma_t)
{
  glBindFramebuffer(GL_FRAMEBUFFER, light_target.fbo);
  glViewport(0, 0, light_target.w, light_target.h);
  glDisable(GL_BLEND);
  bind_inputs(light_fit, v, glm::vec4(0, 0, float(w), float(h)), sigma_t, 1, 0, lights_csv, nullptr);
  glBindTextureUnit(3, gauss_tex);
  glBindTextureUnit(4, f1_tex);
  glBindTextureUnit(5, 0);
  ::draw(quad);
  stamp("light_fit");
}

// preview._draw_gaussians with gauss_pass 'TILES' (v3): every splat-target texel once.
void Preview::draw_tiles(const View &v, int w, int h, float sigma_t, int S, bool exact, bool compute)
{
  const bool fit = v4 && !exact;
  if (fit) draw_light_fit(v, w, h, sigma_t);
  if (compute) {
    const int lw = (w + S - 1) / S, lh = (h + S - 1) / S;
    if (gauss_target.w != lw || gauss_target.h != lh) {
      if (gauss_target.fbo) free_target(gauss_target);
      gauss_target = make_target(lw, lh, GL_RGBA32F, false, 2);
    }
    bind_inputs(tiles_compute, v, glm::vec4(0, 0, float(w), float(h)), sigma_t, S, 0, lights_csv, nullptr);
    glBindTextureUnit(3, gauss_tex);
    glBindTextureUnit(4, f1_tex);
    glBindTextureUnit(5, tile_index_tex);
    glBindTextureUnit(6, tile_list_tex);
    if (fit) glBindTextureUnit(7, light_target.colour[0]);
    glBindImageTexture(0, gauss_target.colour[0], 0, GL_FALSE, 0, GL_WRITE_ONLY, GL_RGBA32F);
    glBindImageTexture(1, gauss_target.colour[1], 0, GL_FALSE, 0, GL_WRITE_ONLY, GL_RGBA32F);
    glDispatchCompute(GLuint((lw + 7) / 8), GLuint((lh + 7) / 8), 1);
    glMemoryBarrier(GL_TEXTURE_FETCH_BARRIER_BIT);
    stamp("tiles_compute");
    return;
  }
  const int lw = (w + S - 1) / S, lh = (h + S - 1) / S;
  if (gauss_target.w != lw || gauss_target.h != lh) {
    if (gauss_target.fbo) free_target(gauss_target);
    gauss_target = make_target(lw, lh, GL_RGBA32F, false, 2);
  }
  glBindFramebuffer(GL_FRAMEBUFFER, gauss_target.fbo);
  glViewport(0, 0, lw, lh);
  glDisable(GL_BLEND);
  const GLuint prog = (v4 && exact) ? tiles_exact : tiles;
  bind_inputs(prog, v, glm::vec4(0, 0, float(w), float(h)), sigma_t, S, 0, lights_csv, nullptr);
  glBindTextureUnit(3, gauss_tex);
  glBindTextureUnit(4, f1_tex);
  glBindTextureUnit(5, tile_index_tex);
  glBindTextureUnit(6, tile_list_tex);
  if (fit) glBindTextureUnit(7, light_target.colour[0]);
  ::draw(quad);
  stamp("tiles");
}

void Preview::draw_fog(const View &v, const Target &viewport, float sigma_t, int scale, bool gaussians,
                       bool tile_pass, bool exact, bool compute)
{
  const int w = viewport.w, h = viewport.h;
  const glm::vec4 region(0.0f, 0.0f, float(w), float(h));
  glDisable(GL_DEPTH_TEST);
  glDepthMask(GL_FALSE);
  if (gaussians) {
    // Splat (or the tile pass) at 1/scale, then the fog pass at full resolution with the sums.
    if (tile_pass) draw_tiles(v, w, h, sigma_t, scale, exact, compute);
    else draw_splat(v, w, h, sigma_t, scale);
    GLuint prog = fog_gauss_program(scale);
    glBindFramebuffer(GL_FRAMEBUFFER, viewport.fbo);
    glViewport(0, 0, w, h);
    blend_alpha_premult();
    bind_inputs(prog, v, region, sigma_t, 1, 0, lights_csv, &gauss_target);
    ::draw(quad);
    stamp("fog");
    return;
  }
  if (scale == 1) {
    blend_alpha_premult();
    bind_inputs(fog, v, region, sigma_t, scale, 0, lights, nullptr);
    ::draw(quad);
    stamp("fog");
    return;
  }
  const int lw = (w + scale - 1) / scale, lh = (h + scale - 1) / scale;
  if (lo_scale != scale || lo_target.w != lw || lo_target.h != lh) {
    if (lo_target.fbo) free_target(lo_target);
    lo_target = make_target(lw, lh, GL_RGBA32F, false);
    lo_scale = scale;
  }
  if (full_target.w != w || full_target.h != h) {
    if (full_target.fbo) free_target(full_target);
    full_target = make_target(w, h, GL_RGBA32F, true);
  }
  glDisable(GL_BLEND);
  glBindFramebuffer(GL_FRAMEBUFFER, lo_target.fbo);
  glViewport(0, 0, lw, lh);
  bind_inputs(fog_lo, v, region, sigma_t, scale, 0, lights, nullptr);
  ::draw(quad);
  stamp("fog_lo");
  // Blend where the samples share the pixel's surface, mark the rest with depth 0,
  // evaluate those exactly (quad at depth 0.5 tested GREATER), composite.
  glBindFramebuffer(GL_FRAMEBUFFER, full_target.fbo);
  glViewport(0, 0, w, h);
  glEnable(GL_DEPTH_TEST);
  glDepthFunc(GL_ALWAYS);
  glDepthMask(GL_TRUE);
  bind_inputs(up_mark, v, region, sigma_t, scale, lo_target.colour[0], lights, nullptr);
  ::draw(quad);
  stamp("mark");
  glDepthFunc(GL_GREATER);
  glDepthMask(GL_FALSE);
  bind_inputs(up_exact, v, region, sigma_t, scale, lo_target.colour[0], lights, nullptr);
  GLuint q = 0;
  if (count_samples) {
    glGenQueries(1, &q);
    glBeginQuery(GL_SAMPLES_PASSED, q);
  }
  ::draw(quad);
  if (count_samples) {
    glEndQuery(GL_SAMPLES_PASSED);
    GLuint64 n = 0;
    glGetQueryObjectui64v(q, GL_QUERY_RESULT, &n);
    exact_samples = n;
    glDeleteQueries(1, &q);
  }
  stamp("exact");
  glDisable(GL_DEPTH_TEST);
  glBindFramebuffer(GL_FRAMEBUFFER, viewport.fbo);
  glViewport(0, 0, w, h);
  blend_alpha_premult();
  bind_inputs(composite, v, region, sigma_t, scale, full_target.colour[0], lights, nullptr);
  ::draw(quad);
  stamp("composite");
}

void Preview::draw_fog_compute(const View &v, const Target &viewport, float sigma_t)
{
  const int w = viewport.w, h = viewport.h;
  if (fog_compute == 0) {
    std::vector<std::pair<std::string, std::string>> defs = head_defines();
    defs.push_back({"PREVIEW_LOWRES", "0"});
    if (v2) defs.insert(defs.end(), {{"PREVIEW_GAUSSIANS", "0"}, {"PREVIEW_GAUSS_SCALE", "1"}});
    fog_compute = create_info_compute_program(
        fullscreen_info("preview_fog_compute", "fog_preview_frag.glsl", defs), target);
    compute_image = gl_texture(w, h, GL_RGBA32F);
  }
  const glm::vec4 region(0.0f, 0.0f, float(w), float(h));
  bind_inputs(fog_compute, v, region, sigma_t, 1, 0, lights, nullptr);
  glBindImageTexture(0, compute_image, 0, GL_FALSE, 0, GL_WRITE_ONLY, GL_RGBA32F);
  glDispatchCompute(GLuint((w + 7) / 8), GLuint((h + 7) / 8), 1);
  glMemoryBarrier(GL_TEXTURE_FETCH_BARRIER_BIT);
  stamp("fog_compute");
  glBindFramebuffer(GL_FRAMEBUFFER, viewport.fbo);
  glViewport(0, 0, w, h);
  blend_alpha_premult();
  bind_inputs(composite, v, region, sigma_t, 1, compute_image, lights, nullptr);
  ::draw(quad);
  stamp("composite");
}
