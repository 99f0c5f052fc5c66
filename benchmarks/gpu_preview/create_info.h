// create_info.h: the part of Blender 3.4's GPUShaderCreateInfo -> GLSL translation
// (source/blender/gpu/opengl/gl_shader.cc: glsl_patch_default_get, resources_declare,
// vertex_interface_declare, fragment_interface_declare; gpu_shader.cc: standard_defines,
// defines_declare) that the preview's shaders use, so the harness compiles the very
// text Blender compiles from addon/airlight/gpu_shaders.py's create-infos.
#pragma once

#include <string>
#include <utility>
#include <vector>

struct CreateInfo {
  std::string name;
  // vertex_in(index, type, name): GLSL type names ("vec2", "vec3", ...).
  std::vector<std::pair<std::string, std::string>> vertex_in;
  // One GPUStageInterfaceInfo (no instance name): (interpolation, type, name).
  std::string iface_name;
  struct InOut {
    std::string interp, type, name;
  };
  std::vector<InOut> iface;
  // push_constant(type, name): plain uniforms in the GL backend.
  std::vector<std::pair<std::string, std::string>> push_constants;
  // sampler(slot, 'FLOAT_2D', name): slot = position in this list.
  std::vector<std::string> samplers;
  // define(name, value)
  std::vector<std::pair<std::string, std::string>> defines;
  // typedef_source(text) and uniform_buf(slot, type_name, name): a std140 block at
  // binding _slot_ whose one member _name_ (a struct of the typedef) the GLSL reads.
  std::string typedef_source;
  struct UniformBuf {
    int slot;
    std::string type_name, name;
  };
  std::vector<UniformBuf> uniform_bufs;
  // fragment_out(0, 'VEC4', "frag_color") and the like: (type, name).
  std::vector<std::pair<std::string, std::string>> fragment_out = {{"vec4", "frag_color"}};
  std::string vertex_source, fragment_source;
};

struct GLSLTarget {
  bool nvidia = false, mesa = false;  // GPU_NVIDIA / GPU_MESA-style vendor define
  bool conservative_depth = false;     // GL_ARB_conservative_depth present
};

// The full GLSL text of one stage as Blender 3.4 assembles it.
std::string create_info_vertex_glsl(const CreateInfo &info, const GLSLTarget &target);
std::string create_info_fragment_glsl(const CreateInfo &info, const GLSLTarget &target);

// The fragment stage's main() run as a compute shader (8 x 8 groups, one invocation per
// pixel; an experiment, not what Blender compiles): gl_FragCoord becomes the invocation's
// pixel centre and frag_color is stored into image unit 0 (RGBA32F, "bench_out").
std::string create_info_compute_glsl(const CreateInfo &info, const GLSLTarget &target);
unsigned create_info_compute_program(const CreateInfo &info, const GLSLTarget &target);

// Compiles and links; throws std::runtime_error with the log and the numbered source.
unsigned create_info_program(const CreateInfo &info, const GLSLTarget &target);

std::string read_text_file(const std::string &path);
