// gl_util.cpp: see gl_util.h.
#include "gl_util.h"

#include <glm/gtc/type_ptr.hpp>

#include <cstdio>
#include <stdexcept>

Stamps g_stamps;

GLuint gl_texture(int w, int h, GLenum internal_format, const void *data, GLenum format, GLenum type)
{
  GLuint t = 0;
  glCreateTextures(GL_TEXTURE_2D, 1, &t);
  glTextureStorage2D(t, 1, internal_format, w, h);
  glTextureParameteri(t, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
  glTextureParameteri(t, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
  glTextureParameteri(t, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
  glTextureParameteri(t, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
  if (data != nullptr) {
    glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
    glTextureSubImage2D(t, 0, 0, 0, w, h, format, type, data);
  }
  return t;
}

Target make_target(int w, int h, GLenum colour_format, bool depth, int colours)
{
  Target t;
  t.w = w;
  t.h = h;
  glCreateFramebuffers(1, &t.fbo);
  std::vector<GLenum> bufs;
  for (int k = 0; k < colours; ++k) {
    t.colour.push_back(gl_texture(w, h, colour_format));
    glNamedFramebufferTexture(t.fbo, GL_COLOR_ATTACHMENT0 + k, t.colour.back(), 0);
    bufs.push_back(GL_COLOR_ATTACHMENT0 + k);
  }
  glNamedFramebufferDrawBuffers(t.fbo, GLsizei(bufs.size()), bufs.data());
  if (depth) {
    t.depth = gl_texture(w, h, GL_DEPTH_COMPONENT32F);
    glNamedFramebufferTexture(t.fbo, GL_DEPTH_ATTACHMENT, t.depth, 0);
  }
  if (glCheckNamedFramebufferStatus(t.fbo, GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE)
    throw std::runtime_error("incomplete framebuffer");
  return t;
}

void free_target(Target &t)
{
  glDeleteFramebuffers(1, &t.fbo);
  for (GLuint c : t.colour) glDeleteTextures(1, &c);
  if (t.depth) glDeleteTextures(1, &t.depth);
  t = Target();
}

Mesh make_mesh(const std::vector<std::pair<int, std::vector<float>>> &attrs,
               const std::vector<unsigned> &tris)
{
  Mesh m;
  glCreateVertexArrays(1, &m.vao);
  for (size_t k = 0; k < attrs.size(); ++k) {
    GLuint b = 0;
    glCreateBuffers(1, &b);
    glNamedBufferStorage(b, attrs[k].second.size() * sizeof(float), attrs[k].second.data(), 0);
    glVertexArrayVertexBuffer(m.vao, GLuint(k), b, 0, attrs[k].first * sizeof(float));
    glEnableVertexArrayAttrib(m.vao, GLuint(k));
    glVertexArrayAttribFormat(m.vao, GLuint(k), attrs[k].first, GL_FLOAT, GL_FALSE, 0);
    glVertexArrayAttribBinding(m.vao, GLuint(k), GLuint(k));
    m.vbo.push_back(b);
  }
  glCreateBuffers(1, &m.ibo);
  glNamedBufferStorage(m.ibo, tris.size() * sizeof(unsigned), tris.data(), 0);
  glVertexArrayElementBuffer(m.vao, m.ibo);
  m.count = GLsizei(tris.size());
  return m;
}

void draw(const Mesh &m)
{
  glBindVertexArray(m.vao);
  glDrawElements(GL_TRIANGLES, m.count, GL_UNSIGNED_INT, nullptr);
}

void set_uniform(GLuint prog, const char *name, const glm::mat4 &m)
{
  GLint loc = glGetUniformLocation(prog, name);
  if (loc >= 0) glProgramUniformMatrix4fv(prog, loc, 1, GL_FALSE, glm::value_ptr(m));
}
void set_uniform(GLuint prog, const char *name, const glm::vec4 &v)
{
  GLint loc = glGetUniformLocation(prog, name);
  if (loc >= 0) glProgramUniform4fv(prog, loc, 1, glm::value_ptr(v));
}
void set_uniform(GLuint prog, const char *name, float f)
{
  GLint loc = glGetUniformLocation(prog, name);
  if (loc >= 0) glProgramUniform1f(prog, loc, f);
}
void set_uniform(GLuint prog, const char *name, int i)
{
  GLint loc = glGetUniformLocation(prog, name);
  if (loc >= 0) glProgramUniform1i(prog, loc, i);
}

void Stamps::begin()
{
  used = 0;
  names.clear();
  active = true;
  stamp("start");
}

void Stamps::stamp(const char *name)
{
  if (!active) return;
  if (used == queries.size()) {
    GLuint q = 0;
    glGenQueries(1, &q);
    queries.push_back(q);
  }
  glQueryCounter(queries[used++], GL_TIMESTAMP);
  names.push_back(name);
}

void Stamps::collect(std::vector<std::pair<std::string, std::vector<double>>> &out)
{
  active = false;
  std::vector<GLuint64> t(used, 0);
  for (size_t k = 0; k < used; ++k) glGetQueryObjectui64v(queries[k], GL_QUERY_RESULT, &t[k]);
  for (size_t k = 1; k < used; ++k) {
    const double ms = double(t[k] - t[k - 1]) * 1e-6;
    bool found = false;
    for (auto &e : out) {
      if (e.first == names[k]) {
        e.second.push_back(ms);
        found = true;
        break;
      }
    }
    if (!found) out.push_back({names[k], {ms}});
  }
}

void check_gl(const char *where)
{
  GLenum e = glGetError();
  if (e != GL_NO_ERROR) {
    char buf[160];
    std::snprintf(buf, sizeof(buf), "GL error 0x%x after %s", e, where);
    throw std::runtime_error(buf);
  }
}
