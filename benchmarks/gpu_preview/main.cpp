// main.cpp: standalone GPU benchmark of the viewport fog preview (addon/airlight/preview.py).
//
// Compiles the preview's own GLSL files (shaders/) with the interfaces Blender 3.4
// generates from gpu_shaders.py's create-infos (create_info.cpp) and draws, headless
// through EGL, what preview._draw_callback draws per viewport redraw (preview.cpp):
//   1. the distance pass (preview_distance_*.glsl) of the scene into an R32F + depth
//      target at full resolution (the 'DRAWN' depth source);
//   2. the fog (preview.draw_fog): at FULL scale fog_preview_frag.glsl onto the viewport
//      with premultiplied blending; at HALF / QUARTER the reduced fog target, the
//      upsampling 'mark' draw, the 'exact' draw tested GREATER and the composite;
//      with Gaussian fog (configurations gauss_*): the add-on's splat pass at 1/scale,
//      then the fog pass at full resolution with the Gaussian sums; (tiles_*, shaders
//      with rbf_splat_pixel.glsl) the add-on's tile pass instead of the splat, its lists
//      built on the CPU once per configuration (native/bindings/preview_tiles.h; not in
//      the frame times, printed); with shaders that have rbf_light_fit_frag.glsl (v4)
//      tiles_* and gauss_* run the light-fit pass first and read its output (the add-on's
//      default preview.LIGHT_FIT), tilesexact_* is the tile pass without it,
//      tilescompute_* (an experiment) the tile pass's GLSL as a compute shader; scales
//      full, half, quarter, eighth; or (standin_*) the
//      harness's own splat pass (standin_splat.cpp) after the homogeneous fog;
//      compute_full: the FULL fog pass's GLSL run as a compute shader (an experiment:
//      how much of the cost is the fragment pipeline's on this GPU).
// Per configuration: GL_TIME_ELAPSED around the frame and GL_TIMESTAMP between passes
// (GPU time), and the wall clock from frame start to glFinish; medians over --frames
// frames after --warmup. Then one frame over a black RGBA32F viewport (the fog alone:
// rgb = airlight, a = 1 - Tr) is read back: its per-channel means are printed, and with
// --out a copy (every --npy-step-th pixel) is written as .npy (row 0 = bottom).
#include <algorithm>
#include <cstdarg>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <stdexcept>
#include <string>
#include <vector>

#include "create_info.h"
#include "gaussians.h"
#include "gl_context.h"
#include "gl_util.h"
#include "npy.h"
#include "preview.h"
#include "standin_splat.h"

namespace {

struct Args {
  int width = 1920, height = 1080;
  int frames = 200, warmup = 30;
  double budget_s = 60.0;  // per configuration: stop timing after this (>= 10 frames)
  std::string shaders = "shaders";                             // the add-on's GLSL
  std::string bench_shaders = "benchmarks/gpu_preview/shaders";  // the stand-in's GLSL
  std::string ftable;
  std::string out;
  std::string platform = "auto";
  int device = 0;
  int lights = 4;
  int gaussians = 3000;
  double cull_eps = 1e-4;  // preview_gaussians.CULL_EPS
  float noise_amplitude = 0.0f, noise_scale = 1.0f;  // scene.airlight.noise_* (tiles/gauss, v3)
  std::string fit_near = "2.0";  // gpu_shaders.RBF_FIT_NEAR (v4), --fit-near
  float sigma_t = 0.08f;
  int npy_step = 4;
  std::vector<std::string> configs = {"homog_full", "homog_half", "homog_quarter",
                                      "gauss_full", "gauss_half", "gauss_quarter"};
};

void usage()
{
  std::puts(
      "gpu_preview_bench --ftable FILE [--shaders DIR] [--bench-shaders DIR] [--size WxH]\n"
      "  [--frames N] [--warmup N] [--budget-s S] [--configs a,b,...] [--lights N]\n"
      "  [--gaussians N] [--cull-eps E] [--sigma-t X] [--out DIR] [--npy-step N]\n"
      "  [--noise-amplitude A] [--noise-scale S] [--fit-near K.K]\n"
      "  [--platform auto|device|surfaceless|default] [--device I]\n"
      "configs: {homog,gauss,tiles,tilesexact,tilescompute,standin}_{full,half,quarter,eighth},\n"
      "  compute_full (tiles, gauss: with the light fit where the shaders have it; tilesexact:\n"
      "  without; tilescompute: the tile pass's GLSL as a compute shader, an experiment)");
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
    else if (k == "--ftable") a.ftable = next();
    else if (k == "--out") a.out = next();
    else if (k == "--platform") a.platform = next();
    else if (k == "--device") a.device = std::stoi(next());
    else if (k == "--lights") a.lights = std::stoi(next());
    else if (k == "--gaussians") a.gaussians = std::stoi(next());
    else if (k == "--cull-eps") a.cull_eps = std::stod(next());
    else if (k == "--noise-amplitude") a.noise_amplitude = std::stof(next());
    else if (k == "--noise-scale") a.noise_scale = std::stof(next());
    else if (k == "--fit-near") {
      a.fit_near = next();
      if (!(std::stof(a.fit_near) >= 0.0f) || a.fit_near.find('.') == std::string::npos)
        throw std::invalid_argument("--fit-near: a float >= 0 with a decimal point (a GLSL float)");
    }
    else if (k == "--sigma-t") a.sigma_t = std::stof(next());
    else if (k == "--configs") a.configs = split(next(), ',');
    else if (k == "--npy-step") a.npy_step = std::stoi(next());
    else if (k == "-h" || k == "--help") {
      usage();
      std::exit(0);
    }
    else throw std::invalid_argument("unknown argument " + k);
  }
  if (a.ftable.empty()) throw std::invalid_argument("--ftable is required");
  if (a.width < 8 || a.height < 8 || a.width > 16384 || a.height > 16384 || a.frames < 1 ||
      a.warmup < 0 || a.lights < 0 || a.lights > 256 || a.gaussians < 1 ||
      !(a.sigma_t >= 0.0f) || a.npy_step < 1 || !(a.cull_eps > 0.0) || !(a.budget_s > 0.0) ||
      !(a.noise_amplitude >= 0.0f) || !(a.noise_scale > 0.0f))
    throw std::invalid_argument("bad size, frame, light, Gaussian, eps or sigma_t value");
  return a;
}

struct Config {
  std::string name, kind;  // kind: homog, gauss (the add-on's splat), tiles (its tile pass), tilesexact (v4: without the light fit), standin
  int scale = 1;
};

Config parse_config(const std::string &s)
{
  Config c;
  c.name = s;
  auto parts = split(s, '_');
  if (parts.size() != 2 || (parts[0] != "homog" && parts[0] != "gauss" && parts[0] != "standin" &&
                            parts[0] != "compute" && parts[0] != "tiles" && parts[0] != "tilesexact" &&
                            parts[0] != "tilescompute"))
    throw std::invalid_argument("bad config " + s);
  c.kind = parts[0];
  if (c.kind == "compute" && parts[1] != "full")
    throw std::invalid_argument("compute_full is the only compute configuration");
  if (parts[1] == "full") c.scale = 1;
  else if (parts[1] == "half") c.scale = 2;
  else if (parts[1] == "quarter") c.scale = 4;
  else if (parts[1] == "eighth") c.scale = 8;
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
  return x[std::min(x.size() - 1, size_t(p * double(x.size() - 1) + 0.5))];
}

struct Report {
  FILE *file = nullptr;
  void line(const std::string &s)
  {
    std::printf("%s\n", s.c_str());
    std::fflush(stdout);
    if (file) std::fprintf(file, "%s\n", s.c_str());
  }
};

std::string fmt(const char *f, ...) __attribute__((format(printf, 1, 2)));
std::string fmt(const char *f, ...)
{
  char buf[2048];
  va_list ap;
  va_start(ap, f);
  std::vsnprintf(buf, sizeof(buf), f, ap);
  va_end(ap);
  return buf;
}

int run(const Args &a)
{
  GLContextInfo ctx = gl_context_create(a.platform, a.device);
  Report rep;
  if (!a.out.empty()) rep.file = std::fopen((a.out + "/results.txt").c_str(), "w");
  rep.line("EGL platform: " + ctx.platform);
  rep.line("GL_VENDOR: " + ctx.vendor);
  rep.line("GL_RENDERER: " + ctx.renderer);
  rep.line("GL_VERSION: " + ctx.version + " (GLSL " + ctx.glsl_version + ")");

  Preview p;
  p.target.nvidia = ctx.vendor.find("NVIDIA") != std::string::npos;
  p.target.mesa = ctx.vendor.find("Mesa") != std::string::npos;
  GLint n_ext = 0;
  glGetIntegerv(GL_NUM_EXTENSIONS, &n_ext);
  for (GLint i = 0; i < n_ext; ++i) {
    const char *e = reinterpret_cast<const char *>(glGetStringi(GL_EXTENSIONS, i));
    if (e && std::strcmp(e, "GL_ARB_conservative_depth") == 0) p.target.conservative_depth = true;
    if (e && std::strcmp(e, "GL_ARB_pipeline_statistics_query") == 0) p.has_pipeline_stats = true;
  }
  p.build(a.shaders, a.ftable, a.lights, a.width, a.height);
  check_gl("build");
  rep.line(fmt("size %dx%d, %d lights, sigma_t %g, shaders %s (interface %s), %d frames after "
               "%d warm-up, budget %g s per configuration",
               a.width, a.height, a.lights, a.sigma_t, a.shaders.c_str(),
               (std::string(p.v2 ? "v2" : "v1") + (p.spots ? " +spots" : "") + (p.suns ? " +suns" : "") +
                (p.ubo ? " +UBO" : " push constants") + (p.v3 ? " +v3 (colours, noise, tile pass)" : "") +
                (p.v4 ? " +v4 (light fit, f1 4 lights per texel)" : "")).c_str(),
               a.frames, a.warmup, a.budget_s));
  const View view = make_view(a.width, a.height);

  GaussianSet gset;
  StandinSplat standin;
  bool have_set = false, have_addon = false, have_standin = false;

  // Viewport colour: RGBA16F like Blender's viewport colour for timing; RGBA32F cleared
  // to 0 for the read-back (the fog alone).
  Target viewport = make_target(a.width, a.height, GL_RGBA16F, true);
  Target check = make_target(a.width, a.height, GL_RGBA32F, true);
  GLuint q_elapsed = 0;
  glGenQueries(1, &q_elapsed);

  for (const std::string &cs : a.configs) {
    const Config c = parse_config(cs);
    const bool tile_kind = c.kind == "tiles" || c.kind == "tilesexact" || c.kind == "tilescompute";
    const bool addon_gauss = c.kind == "gauss" || tile_kind;
    if (addon_gauss && !p.v2) {
      rep.line(fmt("%-15s skipped: these shaders have no Gaussian splat pass (interface v1)",
                   c.name.c_str()));
      continue;
    }
    if (c.kind == "tilesexact" && !p.v4) {
      rep.line(fmt("%-15s skipped: these shaders have no light fit (before rbf_light_fit_frag.glsl)",
                   c.name.c_str()));
      continue;
    }
    if (tile_kind && !p.v3) {
      rep.line(fmt("%-15s skipped: these shaders have no tile pass (before rbf_splat_pixel.glsl)",
                   c.name.c_str()));
      continue;
    }
    if ((addon_gauss || c.kind == "standin") && !have_set) {
      auto t0 = std::chrono::steady_clock::now();
      gset = make_gaussians(a.gaussians, view.eye, view.axis, view.tan_half, p.light_positions,
                            a.sigma_t, a.cull_eps);
      have_set = true;
      if (!a.out.empty()) {
        // What the GPU draws (float32): b.xyz, a, c per row, for a bake of the same fog.
        std::vector<float> rows;
        for (size_t i = 0; i < gset.size(); ++i)
          rows.insert(rows.end(), {float(gset.b[i].x), float(gset.b[i].y), float(gset.b[i].z),
                                   float(gset.a[i]), float(gset.c[i])});
        write_npy_f32(a.out + "/gaussians.npy", rows.data(), {gset.size(), 5});
      }
      double R = 0.0;
      for (double r : gset.R) R += r;
      rep.line(fmt("Gaussians: %d, cull eps %g (mean cull radius %.3f m), CPU factors f1 and "
                   "C_sv in %.2f s (not timed below: the add-on computes them per view change)",
                   a.gaussians, a.cull_eps, R / double(gset.size()),
                   std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count()));
    }
    if (addon_gauss && !have_addon) {
      p.noise_amplitude = a.noise_amplitude;
      p.noise_scale = a.noise_scale;
      p.fit_near = a.fit_near;
      p.build_gaussians(gset);
      have_addon = true;
      check_gl("Gaussian build");
    }
    if (tile_kind) {
      p.build_tiles(view, a.width, a.height, c.scale);
      check_gl("tile lists");
      const int lw = (a.width + c.scale - 1) / c.scale, lh = (a.height + c.scale - 1) / c.scale;
      rep.line(fmt("%-15s tile lists: %llu entries (%.1f per %dx%d tile of the %dx%d target), built and "
                   "uploaded in %.1f ms (CPU, once per view change; not in the frame times)",
                   c.name.c_str(), p.tile_entries,
                   double(p.tile_entries) / (double((lw + 7) / 8) * double((lh + 7) / 8)), 8, 8, lw, lh,
                   p.tiles_build_ms));
    }
    if (c.kind == "standin" && !have_standin) {
      standin.build(a.shaders, a.bench_shaders, p.target, gset, a.lights, p.ftab, p.lights);
      have_standin = true;
      check_gl("stand-in build");
    }
    unsigned long long standin_fragments = 0;
    auto frame = [&](const Target &vp, const float clear[4], bool count) {
      p.draw_distance(view);
      // The viewport as the POST_VIEW handler finds it: the scene is drawn already.
      glBindFramebuffer(GL_FRAMEBUFFER, vp.fbo);
      glViewport(0, 0, vp.w, vp.h);
      glClearNamedFramebufferfv(vp.fbo, GL_COLOR, 0, clear);
      p.count_samples = count;
      if (c.kind == "compute") p.draw_fog_compute(view, vp, a.sigma_t);
      else p.draw_fog(view, vp, a.sigma_t, c.kind == "standin" ? 1 : c.scale, addon_gauss,
                      tile_kind, c.kind == "tilesexact", c.kind == "tilescompute");
      p.count_samples = false;
      if (c.kind == "standin") {
        standin_fragments = standin.draw(vp.fbo, vp.w, vp.h, view.persp, view.inv_persp,
                                         glm::vec4(view.eye, 1.0f),
                                         glm::vec4(view.axis, view.clip_start),
                                         p.distance_target.colour[0], a.sigma_t, c.scale, count);
      }
    };
    const float grey[4] = {0.2f, 0.2f, 0.2f, 1.0f}, black[4] = {0, 0, 0, 0};
    std::vector<double> gpu_ms, wall_ms;
    std::vector<std::pair<std::string, std::vector<double>>> passes;
    const auto start = std::chrono::steady_clock::now();
    auto seconds = [&]() {
      return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    };
    // Warm-up: --warmup frames (at least one: drivers compile shaders lazily on the first
    // draw, and llvmpipe's first timer query reads garbage), fewer once they took a
    // quarter of the budget; then --frames frames, fewer (at least 10) once the budget
    // is spent.
    for (int f = 0; f < std::max(1, a.warmup) && (f == 0 || seconds() < 0.25 * a.budget_s); ++f) {
      frame(viewport, grey, false);
      glFinish();
    }
    for (int f = 0; f < a.frames && (f < 10 || seconds() < a.budget_s); ++f) {
      auto t0 = std::chrono::steady_clock::now();
      glBeginQuery(GL_TIME_ELAPSED, q_elapsed);
      g_stamps.begin();
      frame(viewport, grey, false);
      glEndQuery(GL_TIME_ELAPSED);
      glFinish();
      auto t1 = std::chrono::steady_clock::now();
      GLuint64 elapsed = 0;
      glGetQueryObjectui64v(q_elapsed, GL_QUERY_RESULT, &elapsed);
      g_stamps.collect(passes);
      gpu_ms.push_back(double(elapsed) * 1e-6);
      wall_ms.push_back(std::chrono::duration<double, std::milli>(t1 - t0).count());
    }
    check_gl(c.name.c_str());
    const double g = median(gpu_ms), w = median(wall_ms);
    std::string pass_text;
    for (const auto &e : passes) pass_text += fmt(" %s %.3f", e.first.c_str(), median(e.second));
    rep.line(fmt("%-15s scale=%d gaussians=%d lights=%d frames=%zu  GPU ms median %.3f (p10 %.3f, "
                 "p90 %.3f) = %.1f fps | wall ms median %.3f = %.1f fps | passes (ms):%s",
                 c.name.c_str(), c.scale,
                 addon_gauss || c.kind == "standin" ? a.gaussians : 0, a.lights,
                 gpu_ms.size(), g, percentile(gpu_ms, 0.1), percentile(gpu_ms, 0.9), 1e3 / g, w,
                 1e3 / w, pass_text.c_str()));

    // The fog alone over black, at float precision, read back.
    frame(check, black, true);
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
    rep.line(fmt("%-15s fog image mean r %.7g g %.7g b %.7g a(1-Tr) %.7g  non-finite %zu",
                 c.name.c_str(), sum[0] / npx, sum[1] / npx, sum[2] / npx, sum[3] / npx, bad));
    if (c.scale > 1 && !addon_gauss && c.kind != "standin")
      rep.line(fmt("%-15s exact re-evaluation: %llu pixels (%.2f %% of the region)", c.name.c_str(),
                   p.exact_samples, 100.0 * double(p.exact_samples) / npx));
    if (c.kind == "gauss" || c.kind == "standin") {
      const int lw = (a.width + c.scale - 1) / c.scale, lh = (a.height + c.scale - 1) / c.scale;
      const unsigned long long n = c.kind == "gauss" ? p.splat_samples : standin_fragments;
      rep.line(fmt("%-15s splat fragments %llu = %.1f per splat-target pixel (%dx%d)",
                   c.name.c_str(), n, double(n) / (double(lw) * lh), lw, lh));
      if (c.kind == "gauss" && p.splat_invocations > 0)
        rep.line(fmt("%-15s splat fragment shader invocations %llu = %.1f per splat-target pixel "
                     "(before the cull test's discard)",
                     c.name.c_str(), p.splat_invocations,
                     double(p.splat_invocations) / (double(lw) * lh)));
    }
    if (!a.out.empty()) {
      const int s = a.npy_step;
      const size_t hh = (a.height + s - 1) / s, ww = (a.width + s - 1) / s;
      std::vector<float> dec(hh * ww * 4);
      for (size_t y = 0; y < hh; ++y)
        for (size_t x = 0; x < ww; ++x)
          for (int k = 0; k < 4; ++k)
            dec[(y * ww + x) * 4 + k] = px[((y * s) * a.width + x * s) * 4 + k];
      write_npy_f32(a.out + "/" + c.name + ".npy", dec.data(), {hh, ww, 4});
    }
  }
  if (rep.file) std::fclose(rep.file);
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
