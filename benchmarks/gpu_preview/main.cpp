// main.cpp: standalone GPU benchmark of the viewport fog preview (addon/airlight/preview.py).
//
// Compiles the preview's own GLSL files (shaders/) with the interface Blender 3.4
// generates from gpu_shaders.py's create-infos (create_info.cpp), and draws what
// preview._draw_callback draws per viewport redraw, headless through EGL:
//   1. the preview's distance pass (preview_distance_*.glsl) of the scene's triangles
//      into an R32F + depth target at full resolution ('DRAWN' depth source);
//   2. the fog (preview.draw_fog): at FULL scale fog_preview_frag.glsl straight onto
//      the viewport with premultiplied blending; at HALF / QUARTER the reduced fog
//      target (PREVIEW_LOWRES), the upsampling 'mark' draw into a full-resolution target,
//      the 'exact' draw tested GREATER, and the composite onto the viewport;
//   3. optionally the Gaussian fog splatting pass (gaussian_pass.cpp).
// Each configuration is timed with GL_TIME_ELAPSED around the whole frame and
// GL_TIMESTAMP between the passes (GPU time), and with the wall clock from frame start to
// glFinish; medians over --frames frames after --warmup frames. One more frame per
// configuration is drawn over a black RGBA32F viewport (the fog alone: rgb = airlight,
// a = 1 - Tr) and read back: its per-channel means are printed and, with --out, a
// decimated copy is written as .npy for comparison between drivers.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <stdexcept>
#include <string>
#include <vector>

#define GL_GLEXT_PROTOTYPES 1
#include <GL/glcorearb.h>

#include <glm/glm.hpp>
#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtc/type_ptr.hpp>

#include "create_info.h"
#include "gaussian_pass.h"
#include "gl_context.h"
#include "npy.h"

namespace {

struct Args {
  int width = 1920, height = 1080;
  int frames = 200, warmup = 30;
  double budget_s = 60.0;  // per configuration: stop timing after this (>= 10 frames)
  std::string shaders = "shaders";                             // the add-on's GLSL
  std::string bench_shaders = "benchmarks/gpu_preview/shaders";  // the stand-ins
  double cull_eps = 1e-7;  // RbfMedium::kDefaultCullEps
  std::string ftable;            // binary F table (make_ftable.py)
  std::string out;               // folder for .npy images and results (optional)
  std::string platform = "auto";
  int device = 0;
  int lights = 4;
  int gaussians = 3000;
  float sigma_t = 0.08f;
  int npy_step = 4;              // decimation of the written images
  bool full_npy = false;
  std::vector<std::string> configs = {"homog_full", "homog_half", "homog_quarter",
                                      "gauss_full", "gauss_half", "gauss_quarter"};
};

void usage()
{
  std::puts(
      "gpu_preview_bench --ftable FILE [--shaders DIR] [--bench-shaders DIR] [--cull-eps E] [--size WxH] [--frames N] [--warmup N]\n"
      "  [--budget-s S] [--configs a,b,...] [--lights N] [--gaussians N] [--sigma-t X] [--out DIR]\n"
      "  [--npy-step N] [--full-npy] [--platform auto|device|surfaceless|default] [--device I]\n"
      "configs: homog_full homog_half homog_quarter gauss_full gauss_half gauss_quarter");
}

std::vector<std::string> split(const std::string &s, char sep)
{
  std::vector<std::string> out;
  size_t start = 0;
  for (size_t i = 0; i <= s.size(); ++i) {
    if (i == s.size() || s[i] == sep) {
      if (i > start) out.push_back(s.substr(start, i - start));
      start = i + 1;
    }
  }
  return out;
}

Args parse(int argc, char **argv)
{
  Args a;
  for (int i = 1; i < argc; ++i) {
    std::string k = argv[i];
    auto next = [&]() -> std::string {
      if (i + 1 >= argc) throw std::invalid_argument("missing value after " + k);
      return argv[++i];
    };
    if (k == "--size") {
      auto wh = split(next(), 'x');
      if (wh.size() != 2) throw std::invalid_argument("--size WxH");
      a.width = std::stoi(wh[0]);
      a.height = std::stoi(wh[1]);
    }
    else if (k == "--frames") a.frames = std::stoi(next());
    else if (k == "--warmup") a.warmup = std::stoi(next());
    else if (k == "--budget-s") a.budget_s = std::stod(next());
    else if (k == "--shaders") a.shaders = next();
    else if (k == "--bench-shaders") a.bench_shaders = next();
    else if (k == "--cull-eps") a.cull_eps = std::stod(next());
    else if (k == "--ftable") a.ftable = next();
    else if (k == "--out") a.out = next();
    else if (k == "--platform") a.platform = next();
    else if (k == "--device") a.device = std::stoi(next());
    else if (k == "--lights") a.lights = std::stoi(next());
    else if (k == "--gaussians") a.gaussians = std::stoi(next());
    else if (k == "--sigma-t") a.sigma_t = std::stof(next());
    else if (k == "--configs") a.configs = split(next(), ',');
    else if (k == "--npy-step") a.npy_step = std::stoi(next());
    else if (k == "--full-npy") a.full_npy = true;
    else if (k == "-h" || k == "--help") {
      usage();
      std::exit(0);
    }
    else throw std::invalid_argument("unknown argument " + k);
  }
  if (a.ftable.empty()) throw std::invalid_argument("--ftable is required");
  if (a.width < 8 || a.height < 8 || a.frames < 1 || a.warmup < 0 || a.lights < 0 ||
      a.lights > 256 || a.gaussians < 0 || !(a.sigma_t >= 0.0f) || a.npy_step < 1 || !(a.cull_eps > 0.0))
    throw std::invalid_argument("bad size, frame, light, Gaussian or sigma_t value");
  return a;
}

// ---- GL objects ----------------------------------------------------------------------

struct Target {
  GLuint fbo = 0, colour = 0, depth = 0;
  int w = 0, h = 0;
};

GLuint texture(int w, int h, GLenum fmt, const void *data = nullptr, GLenum type = GL_FLOAT,
               GLenum format = GL_RGBA)
{
  GLuint t = 0;
  glCreateTextures(GL_TEXTURE_2D, 1, &t);
  glTextureStorage2D(t, 1, fmt, w, h);
  glTextureParameteri(t, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
  glTextureParameteri(t, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
  glTextureParameteri(t, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
  glTextureParameteri(t, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
  if (data != nullptr) glTextureSubImage2D(t, 0, 0, 0, w, h, format, type, data);
  return t;
}

Target make_target(int w, int h, GLenum colour_fmt, bool depth)
{
  Target t;
  t.w = w;
  t.h = h;
  t.colour = texture(w, h, colour_fmt);
  glCreateFramebuffers(1, &t.fbo);
  glNamedFramebufferTexture(t.fbo, GL_COLOR_ATTACHMENT0, t.colour, 0);
  if (depth) {
    t.depth = texture(w, h, GL_DEPTH_COMPONENT32F);
    glNamedFramebufferTexture(t.fbo, GL_DEPTH_ATTACHMENT, t.depth, 0);
  }
  if (glCheckNamedFramebufferStatus(t.fbo, GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE)
    throw std::runtime_error("incomplete framebuffer");
  return t;
}

void free_target(Target &t)
{
  glDeleteFramebuffers(1, &t.fbo);
  glDeleteTextures(1, &t.colour);
  if (t.depth) glDeleteTextures(1, &t.depth);
  t = Target();
}

// Indexed triangles with one vec attribute at location 0 (gpu_extras batch_for_shader).
struct Mesh {
  GLuint vao = 0, vbo = 0, ibo = 0;
  GLsizei count = 0;
};

Mesh make_mesh(const std::vector<float> &verts, int comps, const std::vector<unsigned> &tris)
{
  Mesh m;
  glCreateVertexArrays(1, &m.vao);
  glCreateBuffers(1, &m.vbo);
  glCreateBuffers(1, &m.ibo);
  glNamedBufferStorage(m.vbo, verts.size() * sizeof(float), verts.data(), 0);
  glNamedBufferStorage(m.ibo, tris.size() * sizeof(unsigned), tris.data(), 0);
  glVertexArrayVertexBuffer(m.vao, 0, m.vbo, 0, comps * sizeof(float));
  glVertexArrayElementBuffer(m.vao, m.ibo);
  glEnableVertexArrayAttrib(m.vao, 0);
  glVertexArrayAttribFormat(m.vao, 0, comps, GL_FLOAT, GL_FALSE, 0);
  glVertexArrayAttribBinding(m.vao, 0, 0);
  m.count = static_cast<GLsizei>(tris.size());
  return m;
}

void draw(const Mesh &m)
{
  glBindVertexArray(m.vao);
  glDrawElements(GL_TRIANGLES, m.count, GL_UNSIGNED_INT, nullptr);
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

void set(GLuint prog, const char *name, const glm::mat4 &m)
{
  GLint loc = glGetUniformLocation(prog, name);
  if (loc >= 0) glProgramUniformMatrix4fv(prog, loc, 1, GL_FALSE, glm::value_ptr(m));
}
void set(GLuint prog, const char *name, const glm::vec4 &v)
{
  GLint loc = glGetUniformLocation(prog, name);
  if (loc >= 0) glProgramUniform4fv(prog, loc, 1, glm::value_ptr(v));
}
void set(GLuint prog, const char *name, float f)
{
  GLint loc = glGetUniformLocation(prog, name);
  if (loc >= 0) glProgramUniform1f(prog, loc, f);
}
void set(GLuint prog, const char *name, int i)
{
  GLint loc = glGetUniformLocation(prog, name);
  if (loc >= 0) glProgramUniform1i(prog, loc, i);
}

// ---- the preview ---------------------------------------------------------------------

constexpr int kUpsampleBilateralExact = 2;  // preview.UPSAMPLE_BILATERAL_EXACT (default)

struct View {
  glm::mat4 persp, inv_persp;
  glm::vec3 eye, axis;
  glm::vec2 tan_half;  // tangents of the half field of view
  float clip_start;
};

// The scene of benchmarks/bench_preview.py: 40 m floor, 2 m cube, camera at (1, -12, 5)
// looking at (0, 0, 1) with Blender's default 50 mm lens on a 36 mm sensor (sensor fit
// AUTO: the wider side gets the sensor), clip 0.1 .. 100.
View make_view(int w, int h)
{
  View v;
  v.eye = glm::vec3(1.0f, -12.0f, 5.0f);
  glm::vec3 target(0.0f, 0.0f, 1.0f);
  float aspect = float(w) / float(h);
  float half_w = 18.0f / 50.0f;  // tan(fov_x / 2)
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

struct Preview {
  GLSLTarget target;
  std::string dir;
  GLuint distance = 0, fog = 0, fog_lo = 0, up_mark = 0, up_exact = 0, composite = 0;
  GLuint ftab = 0, lights = 0;
  int light_count = 0;
  std::vector<glm::vec3> light_positions;
  Mesh quad, scene;
  std::vector<GLsizei> object_offsets, object_counts;  // one draw per object, as the preview
  Target distance_target, lo_target, full_target;
  int lo_scale = 0;

  std::string src(const std::string &name) const { return read_text_file(dir + "/" + name); }

  // gpu_shaders.create_fullscreen_shader with preview._FOG_INPUTS and these defines.
  GLuint fullscreen(const std::string &name, const std::string &frag,
                    std::vector<std::pair<std::string, std::string>> defines)
  {
    CreateInfo ci;
    ci.name = name;
    ci.vertex_in = {{"vec2", "pos"}};
    ci.iface_name = "airlight_" + name + "_iface";
    ci.iface = {{"smooth", "vec2", "uv"}};
    ci.push_constants = {{"mat4", "inv_persp"}, {"vec4", "eye"},      {"vec4", "clip"},
                         {"vec4", "viewport"},  {"float", "sigma_t"}, {"int", "light_count"},
                         {"int", "scale"},      {"int", "mode"}};
    ci.samplers = {"Ftab", "depth_tex", "lights", "fog_lo"};
    ci.defines = std::move(defines);
    ci.vertex_source = src("fullscreen_vert.glsl");
    ci.fragment_source = src("sun05_airlight.glsl") + "\n" + src("preview_common.glsl") + "\n" +
                         src(frag);
    return create_info_program(ci, target);
  }

  void build(const Args &a)
  {
    // gpu_shaders.create_distance_shader
    CreateInfo d;
    d.name = "distance";
    d.vertex_in = {{"vec3", "pos"}};
    d.iface_name = "airlight_distance_iface";
    d.iface = {{"smooth", "vec3", "wpos"}};
    d.push_constants = {{"mat4", "model"}, {"mat4", "persp"}, {"vec4", "eye"}, {"vec4", "axis"}};
    d.vertex_source = src("preview_distance_vert.glsl");
    d.fragment_source = src("preview_distance_frag.glsl");
    distance = create_info_program(d, target);
    // preview._shader: PREVIEW_WINDOW_DEPTH 0 is the 'DRAWN' depth source.
    fog = fullscreen("preview_fog", "fog_preview_frag.glsl",
                     {{"PREVIEW_WINDOW_DEPTH", "0"}, {"PREVIEW_LOWRES", "0"}});
    fog_lo = fullscreen("preview_fog", "fog_preview_frag.glsl",
                        {{"PREVIEW_WINDOW_DEPTH", "0"}, {"PREVIEW_LOWRES", "1"}});
    up_mark = fullscreen("preview_upsample", "preview_upsample_frag.glsl",
                         {{"PREVIEW_WINDOW_DEPTH", "0"}, {"PREVIEW_EXACT_PASS", "0"},
                          {"PREVIEW_MARK", "1"}});
    up_exact = fullscreen("preview_upsample", "preview_upsample_frag.glsl",
                          {{"PREVIEW_WINDOW_DEPTH", "0"}, {"PREVIEW_EXACT_PASS", "1"},
                           {"PREVIEW_MARK", "0"}});
    composite = fullscreen("preview_composite", "preview_composite_frag.glsl",
                           {{"PREVIEW_WINDOW_DEPTH", "0"}});

    // gpu_shaders.fullscreen_batch
    quad = make_mesh({-1, -1, 1, -1, 1, 1, -1, 1}, 2, {0, 1, 2, 0, 2, 3});

    // Floor (plane of size 40) and the 2 m cube at (0, 0, 1), one batch each.
    std::vector<float> v = {-20, -20, 0, 20, -20, 0, 20, 20, 0, -20, 20, 0};
    std::vector<unsigned> t = {0, 1, 2, 0, 2, 3};
    object_offsets = {0};
    object_counts = {6};
    add_box(v, t, glm::vec3(0, 0, 1), glm::vec3(1, 1, 1));
    object_offsets.push_back(6);
    object_counts.push_back(36);
    scene = make_mesh(v, 3, t);

    // F table: int32 nu, int32 nT, float32 data[nu][nT] (make_ftable.py from
    // _native.special_F_table()); texture of width nT and height nu, as f_table_texture.
    FILE *f = std::fopen(a.ftable.c_str(), "rb");
    if (f == nullptr) throw std::runtime_error("cannot read F table " + a.ftable);
    int dims[2] = {0, 0};
    if (std::fread(dims, sizeof(int), 2, f) != 2 || dims[0] < 2 || dims[1] < 2 ||
        dims[0] > 65536 || dims[1] > 65536)
      throw std::runtime_error("bad F table header in " + a.ftable);
    std::vector<float> data(size_t(dims[0]) * dims[1]);
    if (std::fread(data.data(), sizeof(float), data.size(), f) != data.size())
      throw std::runtime_error("short F table " + a.ftable);
    std::fclose(f);
    ftab = texture(dims[1], dims[0], GL_R32F, data.data(), GL_FLOAT, GL_RED);

    // Point lights of bench_preview.py: 1000 W white, I0 = P / (4 pi), albedo 1.
    light_count = a.lights;
    int n = std::max(1, a.lights);
    std::vector<float> ltex(size_t(2) * n * 4, 0.0f);
    for (int i = 0; i < a.lights; ++i) {
      float x = -6.0f + 12.0f * i / float(std::max(1, a.lights - 1));
      float y = 2.0f * float(i % 3) - 2.0f;
      float *p = &ltex[size_t(i) * 4], *c = &ltex[(size_t(n) + i) * 4];
      p[0] = x, p[1] = y, p[2] = 2.5f;
      light_positions.emplace_back(x, y, 2.5f);
      c[0] = c[1] = c[2] = 1000.0f / (4.0f * float(M_PI));
    }
    lights = texture(n, 2, GL_RGBA32F, ltex.data());

    distance_target = make_target(a.width, a.height, GL_R32F, true);
  }

  void bind_inputs(GLuint prog, const View &v, glm::vec4 viewport, float sigma_t, int scale,
                   GLuint fog_lo_tex) const
  {
    glUseProgram(prog);
    set(prog, "inv_persp", v.inv_persp);
    set(prog, "eye", glm::vec4(v.eye, 1.0f));
    set(prog, "clip", glm::vec4(v.axis, v.clip_start));
    set(prog, "viewport", viewport);
    set(prog, "sigma_t", sigma_t);
    set(prog, "light_count", light_count);
    set(prog, "scale", scale);
    glBindTextureUnit(0, ftab);
    glBindTextureUnit(1, distance_target.colour);
    glBindTextureUnit(2, lights);
    if (fog_lo_tex != 0) {
      set(prog, "mode", kUpsampleBilateralExact);
      glBindTextureUnit(3, fog_lo_tex);
    }
  }

  // preview.draw_distance
  void draw_distance(const View &v)
  {
    glBindFramebuffer(GL_FRAMEBUFFER, distance_target.fbo);
    glViewport(0, 0, distance_target.w, distance_target.h);
    const float inf = INFINITY, zero[4] = {inf, 0, 0, 0};
    glClearNamedFramebufferfv(distance_target.fbo, GL_COLOR, 0, zero);
    glClearNamedFramebufferfi(distance_target.fbo, GL_DEPTH_STENCIL, 0, 1.0f, 0);
    glDisable(GL_BLEND);
    glEnable(GL_DEPTH_TEST);
    glDepthFunc(GL_LEQUAL);
    glDepthMask(GL_TRUE);
    glUseProgram(distance);
    set(distance, "persp", v.persp);
    set(distance, "eye", glm::vec4(v.eye, 1.0f));
    set(distance, "axis", glm::vec4(v.axis, -glm::dot(v.axis, v.eye)));
    glBindVertexArray(scene.vao);
    for (size_t i = 0; i < object_offsets.size(); ++i) {
      set(distance, "model", glm::mat4(1.0f));
      glDrawElements(GL_TRIANGLES, object_counts[i], GL_UNSIGNED_INT,
                     reinterpret_cast<void *>(size_t(object_offsets[i]) * sizeof(unsigned)));
    }
    glDisable(GL_DEPTH_TEST);
    glDepthMask(GL_FALSE);
  }

  // preview.draw_fog onto _viewport_ (bound by the caller), mode UPSAMPLE_BILATERAL_EXACT.
  void draw_fog(const View &v, const Target &viewport, float sigma_t, int scale)
  {
    const int w = viewport.w, h = viewport.h;
    const glm::vec4 region(0.0f, 0.0f, float(w), float(h));
    glDisable(GL_DEPTH_TEST);
    glDepthMask(GL_FALSE);
    glBlendFuncSeparate(GL_ONE, GL_ONE_MINUS_SRC_ALPHA, GL_ONE, GL_ONE_MINUS_SRC_ALPHA);
    if (scale == 1) {
      glEnable(GL_BLEND);
      bind_inputs(fog, v, region, sigma_t, scale, 0);
      draw(quad);
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
    bind_inputs(fog_lo, v, region, sigma_t, scale, 0);
    draw(quad);
    // Blend where the samples share the pixel's surface, mark the rest with depth 0,
    // evaluate those exactly (quad at depth 0.5 tested GREATER), composite.
    glBindFramebuffer(GL_FRAMEBUFFER, full_target.fbo);
    glViewport(0, 0, w, h);
    glEnable(GL_DEPTH_TEST);
    glDepthFunc(GL_ALWAYS);
    glDepthMask(GL_TRUE);
    bind_inputs(up_mark, v, region, sigma_t, scale, lo_target.colour);
    draw(quad);
    glDepthFunc(GL_GREATER);
    glDepthMask(GL_FALSE);
    bind_inputs(up_exact, v, region, sigma_t, scale, lo_target.colour);
    draw(quad);
    glDisable(GL_DEPTH_TEST);
    glBindFramebuffer(GL_FRAMEBUFFER, viewport.fbo);
    glViewport(0, 0, w, h);
    glEnable(GL_BLEND);
    bind_inputs(composite, v, region, sigma_t, scale, full_target.colour);
    draw(quad);
  }
};

struct Config {
  std::string name;
  int scale = 1;
  bool gaussians = false;
};

Config parse_config(const std::string &s)
{
  Config c;
  c.name = s;
  auto parts = split(s, '_');
  if (parts.size() != 2 || (parts[0] != "homog" && parts[0] != "gauss"))
    throw std::invalid_argument("bad config " + s);
  c.gaussians = parts[0] == "gauss";
  if (parts[1] == "full") c.scale = 1;
  else if (parts[1] == "half") c.scale = 2;
  else if (parts[1] == "quarter") c.scale = 4;
  else throw std::invalid_argument("bad config scale " + s);
  return c;
}

double median(std::vector<double> x)
{
  if (x.empty()) return NAN;
  std::sort(x.begin(), x.end());
  size_t n = x.size();
  return n % 2 ? x[n / 2] : 0.5 * (x[n / 2 - 1] + x[n / 2]);
}

double percentile(std::vector<double> x, double p)
{
  if (x.empty()) return NAN;
  std::sort(x.begin(), x.end());
  size_t i = std::min(x.size() - 1, size_t(p * (x.size() - 1) + 0.5));
  return x[i];
}

void check_gl(const char *where)
{
  GLenum e = glGetError();
  if (e != GL_NO_ERROR) {
    char buf[128];
    std::snprintf(buf, sizeof(buf), "GL error 0x%x after %s", e, where);
    throw std::runtime_error(buf);
  }
}

int run(const Args &a)
{
  GLContextInfo ctx = gl_context_create(a.platform, a.device);
  std::printf("EGL platform: %s\nGL_VENDOR: %s\nGL_RENDERER: %s\nGL_VERSION: %s\nGLSL: %s\n",
              ctx.platform.c_str(), ctx.vendor.c_str(), ctx.renderer.c_str(),
              ctx.version.c_str(), ctx.glsl_version.c_str());
  std::printf("size %dx%d, %d lights, sigma_t %g, %d frames after %d warm-up\n", a.width,
              a.height, a.lights, a.sigma_t, a.frames, a.warmup);
  std::fflush(stdout);

  Preview p;
  p.dir = a.shaders;
  p.target.nvidia = ctx.vendor.find("NVIDIA") != std::string::npos;
  p.target.mesa = ctx.vendor.find("Mesa") != std::string::npos;
  GLint n_ext = 0;
  glGetIntegerv(GL_NUM_EXTENSIONS, &n_ext);
  for (GLint i = 0; i < n_ext; ++i) {
    const char *e = reinterpret_cast<const char *>(glGetStringi(GL_EXTENSIONS, i));
    if (e && std::strcmp(e, "GL_ARB_conservative_depth") == 0) p.target.conservative_depth = true;
  }
  p.build(a);
  check_gl("build");
  const View view = make_view(a.width, a.height);

  GaussianPass gauss;
  bool gauss_built = false;

  // The viewport colour target: RGBA16F like Blender's viewport colour for timing;
  // RGBA32F cleared to 0 for the read-back (the fog alone).
  Target viewport = make_target(a.width, a.height, GL_RGBA16F, true);
  Target check = make_target(a.width, a.height, GL_RGBA32F, true);

  GLuint q_elapsed = 0, q_ts[4] = {0, 0, 0, 0};
  glGenQueries(1, &q_elapsed);
  glGenQueries(4, q_ts);

  FILE *results = nullptr;
  if (!a.out.empty()) {
    results = std::fopen((a.out + "/results.txt").c_str(), "w");
    if (results)
      std::fprintf(results, "renderer=%s\nversion=%s\nsize=%dx%d\n", ctx.renderer.c_str(),
                   ctx.version.c_str(), a.width, a.height);
  }

  for (const std::string &cs : a.configs) {
    const Config c = parse_config(cs);
    if (c.gaussians && !gauss_built) {
      auto t0 = std::chrono::steady_clock::now();
      gauss.build(a.shaders, a.bench_shaders, p.target, a.gaussians, view.eye, view.axis,
                  view.tan_half, p.light_positions,
                  a.sigma_t, a.cull_eps, p.ftab, p.lights);
      std::printf("Gaussian pass: %d Gaussians, cull eps %g, set up in %.1f s (CPU f1 factors)\n",
                  a.gaussians, a.cull_eps,
                  std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
      gauss_built = true;
      check_gl("gaussian build");
    }
    auto frame = [&](const Target &vp, const float clear[4], bool timed) {
      if (timed) {
        glBeginQuery(GL_TIME_ELAPSED, q_elapsed);
        glQueryCounter(q_ts[0], GL_TIMESTAMP);
      }
      p.draw_distance(view);
      if (timed) glQueryCounter(q_ts[1], GL_TIMESTAMP);
      // The viewport as the POST_VIEW handler finds it: the scene is drawn already.
      glBindFramebuffer(GL_FRAMEBUFFER, vp.fbo);
      glViewport(0, 0, vp.w, vp.h);
      glClearNamedFramebufferfv(vp.fbo, GL_COLOR, 0, clear);
      p.draw_fog(view, vp, a.sigma_t, c.scale);
      if (timed) glQueryCounter(q_ts[2], GL_TIMESTAMP);
      if (c.gaussians) {
        gauss.draw(vp.fbo, vp.w, vp.h, view.persp, view.inv_persp, glm::vec4(view.eye, 1.0f),
                   glm::vec4(view.axis, view.clip_start), p.distance_target.colour, a.sigma_t,
                   c.scale);
      }
      if (timed) {
        glQueryCounter(q_ts[3], GL_TIMESTAMP);
        glEndQuery(GL_TIME_ELAPSED);
      }
    };
    const float grey[4] = {0.2f, 0.2f, 0.2f, 1.0f}, black[4] = {0, 0, 0, 0};
    std::vector<double> gpu_ms, wall_ms, dist_ms, fog_ms, gauss_ms;
    const auto start = std::chrono::steady_clock::now();
    auto seconds = [&]() {
      return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    };
    // Warm-up: --warmup frames, fewer (at least one) when they take a quarter of the budget;
    // then --frames frames, fewer (at least 10) when the budget is spent.
    for (int f = 0; f < a.warmup && (f == 0 || seconds() < 0.25 * a.budget_s); ++f) {
      frame(viewport, grey, true);
      glFinish();
    }
    for (int f = 0; f < a.frames && (f < 10 || seconds() < a.budget_s); ++f) {
      auto t0 = std::chrono::steady_clock::now();
      frame(viewport, grey, true);
      glFinish();
      auto t1 = std::chrono::steady_clock::now();
      GLuint64 elapsed = 0, ts[4] = {0, 0, 0, 0};
      glGetQueryObjectui64v(q_elapsed, GL_QUERY_RESULT, &elapsed);
      for (int k = 0; k < 4; ++k) glGetQueryObjectui64v(q_ts[k], GL_QUERY_RESULT, &ts[k]);
      gpu_ms.push_back(elapsed * 1e-6);
      dist_ms.push_back((ts[1] - ts[0]) * 1e-6);
      fog_ms.push_back((ts[2] - ts[1]) * 1e-6);
      gauss_ms.push_back((ts[3] - ts[2]) * 1e-6);
      wall_ms.push_back(std::chrono::duration<double, std::milli>(t1 - t0).count());
    }
    check_gl(c.name.c_str());
    const double g = median(gpu_ms), w = median(wall_ms);
    char line[1024];
    std::snprintf(line, sizeof(line),
                  "%-14s scale=%d gaussians=%d lights=%d frames=%zu  gpu_ms median %.3f (p10 %.3f, p90 %.3f)"
                  " fps %.1f | wall_ms median %.3f fps %.1f | passes ms: distance %.3f fog %.3f"
                  " gaussians %.3f",
                  c.name.c_str(), c.scale, c.gaussians ? a.gaussians : 0, a.lights, gpu_ms.size(), g,
                  percentile(gpu_ms, 0.1), percentile(gpu_ms, 0.9), 1e3 / g, w, 1e3 / w,
                  median(dist_ms), median(fog_ms), median(gauss_ms));
    std::printf("%s\n", line);
    if (results) std::fprintf(results, "%s\n", line);

    // The fog alone over black, at float precision, read back.
    gauss.count_fragments = c.gaussians;
    frame(check, black, false);
    glFinish();
    std::vector<float> px(size_t(a.width) * a.height * 4);
    glBindFramebuffer(GL_READ_FRAMEBUFFER, check.fbo);
    glReadBuffer(GL_COLOR_ATTACHMENT0);
    glPixelStorei(GL_PACK_ALIGNMENT, 1);
    glReadPixels(0, 0, a.width, a.height, GL_RGBA, GL_FLOAT, px.data());
    check_gl("read-back");
    double sum[4] = {0, 0, 0, 0};
    size_t bad = 0;
    for (size_t i = 0; i < px.size(); ++i) {
      if (!std::isfinite(px[i])) {
        ++bad;
        continue;
      }
      sum[i % 4] += px[i];
    }
    const double npx = double(a.width) * a.height;
    std::snprintf(line, sizeof(line),
                  "%-14s fog image mean r %.7g g %.7g b %.7g a(1-Tr) %.7g  non-finite %zu",
                  c.name.c_str(), sum[0] / npx, sum[1] / npx, sum[2] / npx, sum[3] / npx, bad);
    std::printf("%s\n", line);
    if (results) std::fprintf(results, "%s\n", line);
    if (c.gaussians) {
      const int lw = (a.width + c.scale - 1) / c.scale, lh = (a.height + c.scale - 1) / c.scale;
      std::snprintf(line, sizeof(line),
                    "%-14s splat fragments %llu = %.1f per splat-target pixel (%dx%d)",
                    c.name.c_str(), gauss.fragments, double(gauss.fragments) / (double(lw) * lh),
                    lw, lh);
      std::printf("%s\n", line);
      if (results) std::fprintf(results, "%s\n", line);
    }
    std::fflush(stdout);
    if (!a.out.empty()) {
      const int s = a.npy_step;
      const size_t hh = (a.height + s - 1) / s, ww = (a.width + s - 1) / s;
      std::vector<float> dec(hh * ww * 4);
      for (size_t y = 0; y < hh; ++y)
        for (size_t x = 0; x < ww; ++x)
          for (int k = 0; k < 4; ++k)
            dec[(y * ww + x) * 4 + k] = px[((y * s) * a.width + x * s) * 4 + k];
      write_npy_f32(a.out + "/" + c.name + ".npy", dec.data(), {hh, ww, 4});
      if (a.full_npy)
        write_npy_f32(a.out + "/" + c.name + "_full.npy", px.data(),
                      {size_t(a.height), size_t(a.width), 4});
    }
  }
  if (results) std::fclose(results);
  gl_context_destroy();
  return 0;
}

}  // namespace

int main(int argc, char **argv)
{
  try {
    return run(parse(argc, argv));
  }
  catch (const std::invalid_argument &e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    usage();
    return 2;
  }
  catch (const std::exception &e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 1;
  }
}
