// gl_util.h: small OpenGL 4.5 (direct state access) helpers for the harness: textures,
// render targets, index-buffered meshes, uniforms by name, and GPU timestamps per pass.
#pragma once

#define GL_GLEXT_PROTOTYPES 1
#include <GL/glcorearb.h>

#include <glm/glm.hpp>

#include <string>
#include <utility>
#include <vector>

// 2D texture with nearest filtering and clamping (the preview reads with texelFetch).
GLuint gl_texture(int w, int h, GLenum internal_format, const void *data = nullptr,
                  GLenum format = GL_RGBA, GLenum type = GL_FLOAT);

// Framebuffer with _colours_ colour textures of one format and optionally a depth texture.
struct Target {
  GLuint fbo = 0, depth = 0;
  std::vector<GLuint> colour;
  int w = 0, h = 0;
};
Target make_target(int w, int h, GLenum colour_format, bool depth, int colours = 1);
void free_target(Target &t);

// Index-buffered triangles; attribute k of _attrs_ = (components, floats) at location k.
struct Mesh {
  GLuint vao = 0, ibo = 0;
  std::vector<GLuint> vbo;
  GLsizei count = 0;
};
Mesh make_mesh(const std::vector<std::pair<int, std::vector<float>>> &attrs,
               const std::vector<unsigned> &tris);
void draw(const Mesh &m);

// Uniforms by name; names the program lacks (optimised out) are skipped, as preview.py's
// bind() does.
void set_uniform(GLuint prog, const char *name, const glm::mat4 &m);
void set_uniform(GLuint prog, const char *name, const glm::vec4 &v);
void set_uniform(GLuint prog, const char *name, float f);
void set_uniform(GLuint prog, const char *name, int i);

// GL_TIMESTAMP queries at pass boundaries: stamp("name") ends the pass _name_. Per
// frame: begin(), stamps, then collect() after glFinish; medians per pass name.
struct Stamps {
  bool active = false;
  std::vector<GLuint> queries;
  std::vector<std::string> names;  // names[k] = pass ended by query k (k >= 1)
  size_t used = 0;
  void begin();
  void stamp(const char *name);
  // Appends this frame's pass durations (ms) to _out_ by name.
  void collect(std::vector<std::pair<std::string, std::vector<double>>> &out);
};
extern Stamps g_stamps;
inline void stamp(const char *name) { g_stamps.stamp(name); }

void check_gl(const char *where);
