// gl_context.h: a headless OpenGL 4.5 core context through EGL (no window, no X):
// EGL_EXT_platform_device (the NVIDIA driver, one display per GPU) or
// EGL_MESA_platform_surfaceless (Mesa llvmpipe), else the default display.
#pragma once

#include <string>

struct GLContextInfo {
  std::string platform;  // which EGL platform gave the display
  std::string vendor, renderer, version, glsl_version;
};

// Creates the context and makes it current (no surface: rendering goes to framebuffer
// objects). _platform_: "auto", "device", "surfaceless" or "default".
// Throws std::runtime_error saying what failed.
GLContextInfo gl_context_create(const std::string &platform, int device_index);

void gl_context_destroy();
