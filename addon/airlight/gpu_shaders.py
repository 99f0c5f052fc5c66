"""GLSL loading and small GPU helpers shared by the viewport preview and the GPU tests.

Shaders live as files in `shaders/` (never inline strings), so the preview and the tests
compile exactly the same text. A shader is described by a vertex file, a fragment file,
and optional library files (e.g. `sun05_airlight.glsl`, the GLSL twin of the C++ kernel)
that are pasted in front of the fragment source. Everything here uses `gpu` APIs that
exist in Blender 3.4 and 4.x (GPUShaderCreateInfo, create_from_info, no bgl).

Nothing is created at import time: callers keep what they build (see preview.py) and
drop it on unregister or file load.
"""

import os

import gpu

# Full-screen quad: two triangles over clip space, attribute "pos".
_QUAD = ((-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0))
_QUAD_TRIS = ((0, 1, 2), (0, 2, 3))


def shader_dirs():
    """Folders searched for .glsl files: $AIRLIGHT_SHADER_PATH (os.pathsep-separated,
    for shader development), the packaged copy, then the repository's shaders/."""
    here = os.path.dirname(os.path.realpath(__file__))  # through the dev symlink
    extra = [d for d in os.environ.get("AIRLIGHT_SHADER_PATH", "").split(os.pathsep) if d]
    return extra + [os.path.join(here, "shaders"),
                    os.path.normpath(os.path.join(here, "..", "..", "shaders"))]


def shader_path(name):
    """Path of the GLSL file _name_; raises FileNotFoundError naming the folders tried."""
    for folder in shader_dirs():
        path = os.path.join(folder, name)
        if os.path.isfile(path):
            return path
    raise FileNotFoundError(f"GLSL file {name!r} not found in " + ", ".join(shader_dirs()))


def load_source(name):
    with open(shader_path(name), encoding="utf-8") as f:
        return f.read()


def create_fullscreen_shader(name, frag, *, libs=(), push_constants=(), samplers=(),
                             defines=()):
    """Compiles fullscreen_vert.glsl + _libs_ + _frag_ into a GPUShader.

    push_constants: (type, name) pairs, e.g. ('VEC4', 'color').
    samplers: sampler names (FLOAT_2D), bound to slots in order.
    defines: (name, value) pairs.
    The fragment shader writes `frag_color` (vec4) and reads `uv` (vec2, 0..1).
    Raises an Exception with the compiler log on GLSL errors.
    """
    iface = gpu.types.GPUStageInterfaceInfo(f"airlight_{name}_iface")
    iface.smooth('VEC2', "uv")
    info = gpu.types.GPUShaderCreateInfo()
    info.vertex_in(0, 'VEC2', "pos")
    info.vertex_out(iface)
    for ptype, pname in push_constants:
        info.push_constant(ptype, pname)
    for slot, sname in enumerate(samplers):
        info.sampler(slot, 'FLOAT_2D', sname)
    for dname, dvalue in defines:
        info.define(dname, str(dvalue))
    info.fragment_out(0, 'VEC4', "frag_color")
    info.vertex_source(load_source("fullscreen_vert.glsl"))
    fragment = "".join(load_source(lib) + "\n" for lib in libs) + load_source(frag)
    info.fragment_source(fragment)
    shader = gpu.shader.create_from_info(info)
    # Keep the interface alive as long as the shader (the create-info refers to it).
    return shader


def fullscreen_batch(shader):
    from gpu_extras.batch import batch_for_shader
    return batch_for_shader(shader, 'TRIS', {"pos": _QUAD}, indices=_QUAD_TRIS)


def builtin_uniform_color():
    """The built-in flat-colour shader under its 3.x or 4.x name."""
    for name in ('UNIFORM_COLOR', '3D_UNIFORM_COLOR', '2D_UNIFORM_COLOR'):
        try:
            return gpu.shader.from_builtin(name)
        except (ValueError, TypeError):
            continue
    raise RuntimeError("no built-in uniform colour shader found")


def float_texture(array):
    """GPUTexture from a float array of shape (H, W, C), C in {1, 2, 4}; row 0 is y = 0
    (the bottom row in gl_FragCoord terms). Values are copied exactly (32-bit float)."""
    import numpy as np
    a = np.ascontiguousarray(array, dtype=np.float32)
    if a.ndim == 2:
        a = a[:, :, None]
    h, w, c = a.shape
    fmt = {1: 'R32F', 2: 'RG32F', 4: 'RGBA32F'}.get(c)
    if fmt is None:
        raise ValueError(f"float_texture: {c} channels not supported (use 1, 2 or 4)")
    buf = gpu.types.Buffer('FLOAT', a.size, a.ravel())
    return gpu.types.GPUTexture((w, h), format=fmt, data=buf)


def f_table_texture(native):
    """Uploads `_native.special_F_table()` (the very data the C++ lookup uses) as an
    R32F texture of width nT and height nu (texel (iT, iu) = data[iu, iT]).
    Returns (texture, table dict)."""
    table = native.special_F_table()
    return float_texture(table["data"]), table


def read_offscreen(offscreen, channels=4):
    """Reads the colour of a bound-or-not GPUOffScreen into a float32 array (H, W, C),
    row 0 at the bottom."""
    import numpy as np
    w, h = offscreen.width, offscreen.height
    with offscreen.bind():
        fb = gpu.state.active_framebuffer_get()
        buf = fb.read_color(0, 0, w, h, channels, 0, 'FLOAT')
    return buffer_to_numpy(buf, (h, w, channels))


def buffer_to_numpy(buf, shape):
    """gpu.types.Buffer -> float32 array of _shape_, in the buffer's memory order.

    Blender 3.4 exports multi-dimensional Buffers with Fortran strides over C-ordered
    memory, so a plain np.array(buf) permutes the data; undo that, and fall back to
    to_list() where the buffer protocol is unavailable."""
    import numpy as np
    try:
        view = memoryview(buf)
        a = np.array(view, dtype=np.float32)
        if view.ndim > 1 and not view.c_contiguous:
            a = a.ravel(order='F')  # the real memory order
    except (TypeError, ValueError, BufferError):
        a = np.array(buf.to_list(), dtype=np.float32)
    return a.reshape(shape).copy()


def create_depth_shader():
    """Shader drawing world-space triangles (attribute "pos") through push constant
    `persp` (MAT4, projection * view); used to render scene depth."""
    info = gpu.types.GPUShaderCreateInfo()
    info.vertex_in(0, 'VEC3', "pos")
    info.push_constant('MAT4', "persp")
    info.fragment_out(0, 'VEC4', "frag_color")
    info.vertex_source(load_source("depth_only_vert.glsl"))
    info.fragment_source(load_source("depth_only_frag.glsl"))
    return gpu.shader.create_from_info(info)


def create_distance_shader():
    """Shader drawing object-space triangles (attribute "pos", VEC3) through push
    constants `model` (object to world) and `persp` (projection * view), writing the
    linear surface distance (preview_distance_*.glsl) into colour channel 0; `eye` and
    `axis` (VEC4) say how distance is measured (see the fragment file)."""
    iface = gpu.types.GPUStageInterfaceInfo("airlight_distance_iface")
    iface.smooth('VEC3', "wpos")
    info = gpu.types.GPUShaderCreateInfo()
    info.vertex_in(0, 'VEC3', "pos")
    info.vertex_out(iface)
    for name in ("model", "persp"):
        info.push_constant('MAT4', name)
    for name in ("eye", "axis"):
        info.push_constant('VEC4', name)
    info.fragment_out(0, 'VEC4', "frag_color")
    info.vertex_source(load_source("preview_distance_vert.glsl"))
    info.fragment_source(load_source("preview_distance_frag.glsl"))
    return gpu.shader.create_from_info(info)


def render_depth(vertices, triangles, persp, width, height):
    """Window-space depth (0..1, 1 = nothing) of a triangle soup seen through the 4x4
    matrix _persp_ (projection @ view, a mathutils.Matrix or nested sequence), as an
    R32F GPUTexture of width x height plus the gpu.types.Buffer it was read into
    (row 0 at the bottom)."""
    import numpy as np
    from gpu_extras.batch import batch_for_shader
    depth = gpu.types.GPUTexture((width, height), format='DEPTH_COMPONENT32F')
    colour = gpu.types.GPUTexture((width, height), format='RGBA8')
    fb = gpu.types.GPUFrameBuffer(depth_slot=depth, color_slots=(colour,))
    shader = create_depth_shader()
    batch = batch_for_shader(shader, 'TRIS',
                             {"pos": np.ascontiguousarray(vertices, np.float32)},
                             indices=np.ascontiguousarray(triangles, np.int32))
    with fb.bind():
        prev_viewport = gpu.state.viewport_get()
        gpu.state.viewport_set(0, 0, width, height)
        fb.clear(color=(0.0, 0.0, 0.0, 0.0), depth=1.0)
        prev_test, prev_mask = gpu.state.depth_test_get(), gpu.state.depth_mask_get()
        gpu.state.depth_test_set('LESS_EQUAL')
        gpu.state.depth_mask_set(True)
        try:
            shader.bind()
            shader.uniform_float("persp", persp)
            batch.draw(shader)
        finally:
            gpu.state.depth_test_set(prev_test)
            gpu.state.depth_mask_set(prev_mask)
        buf = fb.read_depth(0, 0, width, height)
        gpu.state.viewport_set(*prev_viewport)
    return depth_texture(buf, width, height), buf


def depth_texture(buf, width, height):
    """R32F texture from a read_depth() Buffer (no copy through Python lists)."""
    return gpu.types.GPUTexture((width, height), format='R32F', data=buf)
