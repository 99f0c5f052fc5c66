// create_info.cpp: GLSL assembly in the order Blender 3.4's GL backend uses:
//   patch (#version 430 + extensions + compat defines), stage define, standard defines
//   (GPU_SHADER, vendor, OS, backend), create-info defines, resources (samplers with
//   layout(binding = slot), push constants as uniforms), stage interface, sources.
// Blender also appends glsl_shader_defines.glsl (type aliases and helper functions the
// preview's GLSL never references), and in front of a typedef_source the macros of
// GPU_shader_shared_utils.h (float4 = vec4 and the like, which the preview's typedefs do
// not use); both are left out here.
#include "create_info.h"

#define GL_GLEXT_PROTOTYPES 1
#include <GL/glcorearb.h>

#include <fstream>
#include <sstream>
#include <stdexcept>

std::string read_text_file(const std::string &path)
{
  std::ifstream f(path, std::ios::binary);
  if (!f) throw std::runtime_error("cannot read " + path);
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

namespace {

std::string patch(const GLSLTarget &t)
{
  std::stringstream ss;
  ss << "#version 430\n";
  // What glsl_patch_default_get adds on a GL 4.3+ driver with these extensions.
  ss << "#extension GL_ARB_texture_gather: enable\n"
        "#ifdef GL_ARB_texture_gather\n#  define GPU_ARB_texture_gather\n#endif\n";
  ss << "#extension GL_ARB_shader_draw_parameters : enable\n"
        "#define GPU_ARB_shader_draw_parameters\n"
        "#define gpu_BaseInstance gl_BaseInstanceARB\n";
  ss << "#extension GL_ARB_gpu_shader5 : enable\n#define GPU_ARB_gpu_shader5\n";
  ss << "#extension GL_ARB_texture_cube_map_array : enable\n"
        "#define GPU_ARB_texture_cube_map_array\n";
  if (t.conservative_depth) ss << "#extension GL_ARB_conservative_depth : enable\n";
  ss << "#extension GL_ARB_shader_image_load_store: enable\n"
        "#extension GL_ARB_shading_language_420pack: enable\n";
  ss << "#define gpu_InstanceIndex (gl_InstanceID + gpu_BaseInstance)\n";
  ss << "#define gpu_Array(_type) _type[]\n";
  ss << "#define DFDX_SIGN 1.0\n#define DFDY_SIGN 1.0\n";
  return ss.str();
}

std::string standard_defines(const GLSLTarget &t)
{
  std::stringstream ss;
  ss << "#define GPU_SHADER\n";
  if (t.nvidia) ss << "#define GPU_NVIDIA\n";
  if (t.mesa) ss << "#define GPU_MESA\n";
  ss << "#define OS_UNIX\n#define GPU_OPENGL\n";
  return ss.str();
}

std::string defines_declare(const CreateInfo &info)
{
  std::stringstream ss;
  for (const auto &d : info.defines) ss << "#define " << d.first << " " << d.second << "\n";
  return ss.str();
}

std::string resources_declare(const CreateInfo &info)
{
  std::stringstream ss;
  ss << "\n/* Pass Resources. */\n";
  for (size_t slot = 0; slot < info.samplers.size(); ++slot) {
    ss << "layout(binding = " << slot << ") uniform sampler2D " << info.samplers[slot] << ";\n";
  }
  for (const auto &u : info.uniform_bufs) {
    ss << "layout(binding = " << u.slot << ", std140) uniform " << u.name << " { " << u.type_name
       << " _" << u.name << "; };\n";
  }
  for (const auto &u : info.uniform_bufs) ss << "#define " << u.name << " (_" << u.name << ")\n";
  ss << "\n/* Batch Resources. */\n";
  ss << "\n/* Push Constants. */\n";
  for (const auto &p : info.push_constants) ss << "uniform " << p.first << " " << p.second << ";\n";
  ss << "\n";
  return ss.str();
}

std::string interface_block(const CreateInfo &info, const char *prefix)
{
  if (info.iface.empty()) return "";
  std::stringstream ss;
  ss << prefix << " " << info.iface_name << "{\n";
  for (const auto &io : info.iface) ss << "  " << io.interp << " " << io.type << " " << io.name << ";\n";
  ss << "};\n";
  return ss.str();
}

std::string numbered(const std::string &src)
{
  std::stringstream in(src), out;
  std::string line;
  for (int n = 1; std::getline(in, line); ++n) out << n << ": " << line << "\n";
  return out.str();
}

const char *stage_name(GLenum stage)
{
  return stage == GL_VERTEX_SHADER ? " (vertex)" : stage == GL_FRAGMENT_SHADER ? " (fragment)" : " (compute)";
}

unsigned compile(GLenum stage, const std::string &src, const std::string &name)
{
  GLuint s = glCreateShader(stage);
  const char *p = src.c_str();
  glShaderSource(s, 1, &p, nullptr);
  glCompileShader(s);
  GLint ok = 0;
  glGetShaderiv(s, GL_COMPILE_STATUS, &ok);
  if (!ok) {
    char log[8192] = "";
    glGetShaderInfoLog(s, sizeof(log), nullptr, log);
    glDeleteShader(s);
    throw std::runtime_error("GLSL compile error in " + name + stage_name(stage) + ":\n" + log +
                             "\n" + numbered(src));
  }
  return s;
}

}  // namespace

std::string create_info_vertex_glsl(const CreateInfo &info, const GLSLTarget &t)
{
  std::stringstream ss;
  ss << patch(t) << standard_defines(t) << "#define GPU_VERTEX_SHADER\n" << defines_declare(info)
     << info.typedef_source << resources_declare(info);
  ss << "\n/* Inputs. */\n";
  for (size_t i = 0; i < info.vertex_in.size(); ++i) {
    ss << "layout(location = " << i << ") in " << info.vertex_in[i].first << " "
       << info.vertex_in[i].second << ";\n";
  }
  ss << "\n/* Interfaces. */\n" << interface_block(info, "out") << "\n";
  ss << info.vertex_source;
  return ss.str();
}

std::string create_info_fragment_glsl(const CreateInfo &info, const GLSLTarget &t)
{
  std::stringstream ss;
  ss << patch(t) << standard_defines(t) << "#define GPU_FRAGMENT_SHADER\n"
     << defines_declare(info) << info.typedef_source << resources_declare(info);
  ss << "\n/* Interfaces. */\n" << interface_block(info, "in");
  // The Python create-info leaves depth_write at its default (ANY).
  if (t.conservative_depth) ss << "layout(depth_any) out float gl_FragDepth;\n";
  ss << "\n/* Outputs. */\n";
  for (size_t i = 0; i < info.fragment_out.size(); ++i) {
    ss << "layout(location = " << i << ") out " << info.fragment_out[i].first << " "
       << info.fragment_out[i].second << ";\n";
  }
  ss << "\n" << info.fragment_source;
  return ss.str();
}

std::string create_info_compute_glsl(const CreateInfo &info, const GLSLTarget &t)
{
  std::string body = info.fragment_source;
  for (size_t pos = 0; (pos = body.find("gl_FragCoord", pos)) != std::string::npos;)
    body.replace(pos, 12, "bench_FragCoord");
  std::stringstream ss;
  ss << "#version 430\n" << standard_defines(t) << "#define GPU_COMPUTE_SHADER\n"
     << defines_declare(info) << info.typedef_source << resources_declare(info);
  ss << "layout(local_size_x = 8, local_size_y = 8) in;\n";
  // Fragment output i -> image unit i (bench_out, bench_out1, ...).
  for (size_t i = 0; i < info.fragment_out.size(); ++i)
    ss << "layout(binding = " << i << ", rgba32f) writeonly uniform image2D bench_out"
       << (i ? std::to_string(i) : std::string()) << ";\n";
  ss << "vec4 bench_FragCoord;\n";
  for (const auto &o : info.fragment_out) ss << o.first << " " << o.second << ";\n";
  ss << "#define main bench_fragment_main\n" << body << "\n#undef main\n";
  ss << "void main()\n{\n"
        "  ivec2 p = ivec2(gl_GlobalInvocationID.xy);\n"
        "  if (any(greaterThanEqual(p, imageSize(bench_out)))) return;\n"
        "  bench_FragCoord = vec4(vec2(p) + 0.5, 0.5, 1.0);\n"
        "  bench_fragment_main();\n";
  for (size_t i = 0; i < info.fragment_out.size(); ++i)
    ss << "  imageStore(bench_out" << (i ? std::to_string(i) : std::string()) << ", p, "
       << info.fragment_out[i].second << ");\n";
  ss << "}\n";
  return ss.str();
}

unsigned create_info_compute_program(const CreateInfo &info, const GLSLTarget &t)
{
  GLuint cs = compile(GL_COMPUTE_SHADER, create_info_compute_glsl(info, t), info.name);
  GLuint prog = glCreateProgram();
  glAttachShader(prog, cs);
  glLinkProgram(prog);
  glDeleteShader(cs);
  GLint ok = 0;
  glGetProgramiv(prog, GL_LINK_STATUS, &ok);
  if (!ok) {
    char log[8192] = "";
    glGetProgramInfoLog(prog, sizeof(log), nullptr, log);
    glDeleteProgram(prog);
    throw std::runtime_error("GLSL link error in " + info.name + " (compute):\n" + log);
  }
  return prog;
}

unsigned create_info_program(const CreateInfo &info, const GLSLTarget &t)
{
  GLuint vs = compile(GL_VERTEX_SHADER, create_info_vertex_glsl(info, t), info.name);
  GLuint fs = compile(GL_FRAGMENT_SHADER, create_info_fragment_glsl(info, t), info.name);
  GLuint prog = glCreateProgram();
  glAttachShader(prog, vs);
  glAttachShader(prog, fs);
  glLinkProgram(prog);
  glDeleteShader(vs);
  glDeleteShader(fs);
  GLint ok = 0;
  glGetProgramiv(prog, GL_LINK_STATUS, &ok);
  if (!ok) {
    char log[8192] = "";
    glGetProgramInfoLog(prog, sizeof(log), nullptr, log);
    glDeleteProgram(prog);
    throw std::runtime_error("GLSL link error in " + info.name + ":\n" + log);
  }
  return prog;
}
