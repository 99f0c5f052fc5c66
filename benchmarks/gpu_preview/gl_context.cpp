// gl_context.cpp: EGL display, config and context for headless GL 4.5 core.
#include "gl_context.h"

#include <EGL/egl.h>
#include <EGL/eglext.h>
#define GL_GLEXT_PROTOTYPES 1
#include <GL/glcorearb.h>

#include <cstdio>
#include <cstring>
#include <stdexcept>
#include <vector>

namespace {

EGLDisplay g_display = EGL_NO_DISPLAY;
EGLContext g_context = EGL_NO_CONTEXT;

bool has_extension(const char *list, const char *name)
{
  if (list == nullptr) return false;
  const size_t n = std::strlen(name);
  for (const char *p = list; (p = std::strstr(p, name)) != nullptr; p += n) {
    if ((p == list || p[-1] == ' ') && (p[n] == ' ' || p[n] == '\0')) return true;
  }
  return false;
}

// One display of the _index_-th EGL device (the NVIDIA path), or EGL_NO_DISPLAY.
EGLDisplay device_display(int index)
{
  const char *client = eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS);
  if (!has_extension(client, "EGL_EXT_platform_device")) return EGL_NO_DISPLAY;
  auto query_devices = reinterpret_cast<PFNEGLQUERYDEVICESEXTPROC>(
      eglGetProcAddress("eglQueryDevicesEXT"));
  auto get_platform_display = reinterpret_cast<PFNEGLGETPLATFORMDISPLAYEXTPROC>(
      eglGetProcAddress("eglGetPlatformDisplayEXT"));
  if (query_devices == nullptr || get_platform_display == nullptr) return EGL_NO_DISPLAY;
  EGLint count = 0;
  if (!query_devices(0, nullptr, &count) || count <= 0) return EGL_NO_DISPLAY;
  std::vector<EGLDeviceEXT> devices(count);
  query_devices(count, devices.data(), &count);
  // Try the requested device first, then the others (Mesa lists a software device too).
  for (int k = 0; k < count; ++k) {
    int i = (index + k) % count;
    EGLDisplay d = get_platform_display(EGL_PLATFORM_DEVICE_EXT, devices[i], nullptr);
    EGLint major = 0, minor = 0;
    if (d != EGL_NO_DISPLAY && eglInitialize(d, &major, &minor)) return d;
  }
  return EGL_NO_DISPLAY;
}

EGLDisplay surfaceless_display()
{
  const char *client = eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS);
  if (!has_extension(client, "EGL_MESA_platform_surfaceless")) return EGL_NO_DISPLAY;
  auto get_platform_display = reinterpret_cast<PFNEGLGETPLATFORMDISPLAYEXTPROC>(
      eglGetProcAddress("eglGetPlatformDisplayEXT"));
  if (get_platform_display == nullptr) return EGL_NO_DISPLAY;
  EGLDisplay d = get_platform_display(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY,
                                      nullptr);
  EGLint major = 0, minor = 0;
  if (d != EGL_NO_DISPLAY && eglInitialize(d, &major, &minor)) return d;
  return EGL_NO_DISPLAY;
}

EGLDisplay default_display()
{
  EGLDisplay d = eglGetDisplay(EGL_DEFAULT_DISPLAY);
  EGLint major = 0, minor = 0;
  if (d != EGL_NO_DISPLAY && eglInitialize(d, &major, &minor)) return d;
  return EGL_NO_DISPLAY;
}

std::string hex(unsigned v)
{
  char buf[16];
  std::snprintf(buf, sizeof(buf), "0x%04x", v);
  return buf;
}

std::string gl_string(GLenum name)
{
  const GLubyte *s = glGetString(name);
  return s ? reinterpret_cast<const char *>(s) : "";
}

}  // namespace

GLContextInfo gl_context_create(const std::string &platform, int device_index)
{
  GLContextInfo info;
  if (platform == "device" || platform == "auto") {
    g_display = device_display(device_index);
    info.platform = "device";
  }
  if (g_display == EGL_NO_DISPLAY && (platform == "surfaceless" || platform == "auto")) {
    g_display = surfaceless_display();
    info.platform = "surfaceless";
  }
  if (g_display == EGL_NO_DISPLAY && (platform == "default" || platform == "auto")) {
    g_display = default_display();
    info.platform = "default";
  }
  if (g_display == EGL_NO_DISPLAY) {
    throw std::runtime_error("no EGL display for platform '" + platform +
                             "' (eglGetError " + hex(unsigned(eglGetError())) + ")");
  }
  if (!eglBindAPI(EGL_OPENGL_API)) throw std::runtime_error("eglBindAPI(EGL_OPENGL_API) failed");
  const EGLint config_attribs[] = {EGL_RENDERABLE_TYPE, EGL_OPENGL_BIT, EGL_NONE};
  EGLConfig config = nullptr;
  EGLint n = 0;
  if (!eglChooseConfig(g_display, config_attribs, &config, 1, &n) || n < 1) {
    // Surfaceless contexts need no config at all where EGL_KHR_no_config_context exists.
    config = nullptr;
  }
  const EGLint context_attribs[] = {EGL_CONTEXT_MAJOR_VERSION, 4, EGL_CONTEXT_MINOR_VERSION, 5,
                                    EGL_CONTEXT_OPENGL_PROFILE_MASK,
                                    EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT, EGL_NONE};
  g_context = eglCreateContext(g_display, config, EGL_NO_CONTEXT, context_attribs);
  if (g_context == EGL_NO_CONTEXT) {
    throw std::runtime_error("eglCreateContext(GL 4.5 core) failed: " +
                             hex(unsigned(eglGetError())));
  }
  if (!eglMakeCurrent(g_display, EGL_NO_SURFACE, EGL_NO_SURFACE, g_context)) {
    throw std::runtime_error("eglMakeCurrent without surface failed");
  }
  info.vendor = gl_string(GL_VENDOR);
  info.renderer = gl_string(GL_RENDERER);
  info.version = gl_string(GL_VERSION);
  info.glsl_version = gl_string(GL_SHADING_LANGUAGE_VERSION);
  return info;
}

void gl_context_destroy()
{
  if (g_display == EGL_NO_DISPLAY) return;
  eglMakeCurrent(g_display, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
  if (g_context != EGL_NO_CONTEXT) eglDestroyContext(g_display, g_context);
  eglTerminate(g_display);
  g_display = EGL_NO_DISPLAY;
  g_context = EGL_NO_CONTEXT;
}
