"""GLSL loading and small GPU helpers shared by the viewport preview and the GPU tests.

Shaders live as files in `shaders/` (never inline strings), so the preview and the tests
compile exactly the same text. A shader is described by a vertex file, a fragment file,
and optional library files (e.g. `sun05_airlight.glsl`, the GLSL twin of the C++ kernel)
that are pasted in front of the fragment source. Everything here uses `gpu` APIs that
exist in Blender 3.4 and 4.x (GPUShaderCreateInfo, create_from_info, no bgl).

Nothing is created at import time: callers keep what they build (see preview.py) and
drop it on unregister or file load.
"""

import contextlib
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
                             defines=(), ubo=None):
    """Compiles fullscreen_vert.glsl + _libs_ + _frag_ into a GPUShader.

    push_constants: (type, name) pairs, e.g. ('VEC4', 'color').
    samplers: sampler names (FLOAT_2D), bound to slots in order.
    defines: (name, value) pairs.
    ubo: None or (typedef file, struct name, variable name, {alias: member}): a uniform
    buffer at slot 0 whose members the GLSL reads as `alias` (a define).
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
    if ubo is not None:
        _add_ubo(info, *ubo)
    info.fragment_out(0, 'VEC4', "frag_color")
    info.vertex_source(load_source("fullscreen_vert.glsl"))
    fragment = "".join(load_source(lib) + "\n" for lib in libs) + load_source(frag)
    info.fragment_source(fragment)
    shader = gpu.shader.create_from_info(info)
    # Keep the interface alive as long as the shader (the create-info refers to it).
    return shader


def _add_ubo(info, typedef_file, struct, var, aliases):
    info.typedef_source(load_source(typedef_file))
    info.uniform_buf(0, struct, var)
    for alias, member in aliases.items():
        info.define(alias, f"{var}.{member}")


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


DISTANCE_UBO = ("preview_distance_params.glsl", "AirlightDistanceParams", "dv",
                {"eye": "u_eye", "axis": "u_axis"})


def distance_params_ubo(eye, axis):
    """GPUUniformBuf of AirlightDistanceParams (bind with shader.uniform_block("dv", ubo))."""
    import numpy as np
    return gpu.types.GPUUniformBuf(np.array([*eye, *axis], np.float32).tobytes())


def draw_distances(shader, persp, eye, axis, instances):
    """Draws [(batch, model matrix)] with the bound distance shader (create_distance_shader)
    through _persp_, distance measured as _eye_ and _axis_ say (distance_params_ubo)."""
    shader.uniform_float("persp", persp)
    ubo = distance_params_ubo(eye, axis)
    shader.uniform_block("dv", ubo)
    for batch, model in instances:
        shader.uniform_float("model", model)
        batch.draw(shader)


def start_distances(fb, shader):
    """Clears the bound framebuffer _fb_ (an R32F colour and a depth target) to no surface
    (inf, far depth), sets the nearest-wins depth test without blending, binds _shader_."""
    import math
    fb.clear(color=(math.inf, 0.0, 0.0, 0.0), depth=1.0)
    gpu.state.blend_set('NONE')
    gpu.state.depth_test_set('LESS_EQUAL')
    gpu.state.depth_mask_set(True)
    shader.bind()


@contextlib.contextmanager
def preserved_state():
    """Restores the viewport, depth test, depth mask and blending on exit."""
    viewport = gpu.state.viewport_get()
    test, mask, blend = gpu.state.depth_test_get(), gpu.state.depth_mask_get(), gpu.state.blend_get()
    try:
        yield
    finally:
        gpu.state.depth_test_set(test)
        gpu.state.depth_mask_set(mask)
        gpu.state.blend_set(blend)
        gpu.state.viewport_set(*viewport)


def create_distance_shader():
    """Shader drawing object-space triangles (attribute "pos", VEC3) through push
    constants `model` (object to world) and `persp` (projection * view; 128 bytes in
    all), writing the linear surface distance (preview_distance_*.glsl) into colour
    channel 0; `eye` and `axis` (VEC4, uniform buffer DISTANCE_UBO at slot 0, "dv") say
    how distance is measured (see the fragment file)."""
    iface = gpu.types.GPUStageInterfaceInfo("airlight_distance_iface")
    iface.smooth('VEC3', "wpos")
    info = gpu.types.GPUShaderCreateInfo()
    info.vertex_in(0, 'VEC3', "pos")
    info.vertex_out(iface)
    for name in ("model", "persp"):
        info.push_constant('MAT4', name)
    _add_ubo(info, *DISTANCE_UBO)
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


# ---- Gaussian fog (fog objects) in the preview -----------------------------------------
# Each shader's full interface is in one function below, so a standalone GL harness can
# mirror it (vertex inputs, interface blocks, push constants, samplers, fragment outputs,
# defines, and the order in which files are concatenated).

# Width of the per-Gaussian data textures (texel (i % W, ...) for Gaussian i).
RBF_TEX_WIDTH = 1024

# Inputs shared by the fog passes and the splat pass (preview_common.glsl): one uniform
# buffer (shaders/preview_params.glsl, 224 bytes, std140) instead of push constants; the
# GLSL reads its members under these names (pv_*: names the kernels use for parameters).
PREVIEW_UBO = ("preview_params.glsl", "AirlightPreviewParams", "pv", {
    "inv_persp": "u_inv_persp", "persp": "u_persp", "eye": "u_eye", "clip": "u_clip",
    "viewport": "u_viewport", "pv_phase": "u_phase", "pv_sigma_t": "u_fparams.x",
    "light_count": "u_iparams.x", "pv_scale": "u_iparams.y", "pv_mode": "u_iparams.z",
    "pv_env_T": "u_fparams.y", "pv_noise_amp": "u_fparams.z", "pv_noise": "u_noise"})


def preview_params_ubo(*, inv_persp, persp, eye, clip, viewport, phase, sigma_t, light_count,
                       scale, mode, env_T=0.0, noise=None):
    """GPUUniformBuf of AirlightPreviewParams (shaders/preview_params.glsl, 240 bytes):
    matrices as mathutils.Matrix or 4x4 nested sequences (row-major; stored column-major),
    vec4s as 4 numbers; _noise_ None (off) or (amplitude, scale, offset (3)) of the
    Gaussian fog's noise. Bind with shader.uniform_block("pv", ubo)."""
    import numpy as np
    f = np.zeros(60, np.float32)
    f[0:16] = np.asarray(inv_persp, np.float64).T.ravel()
    f[16:32] = np.asarray(persp, np.float64).T.ravel()
    f[32:36], f[36:40], f[40:44], f[44:48] = eye, clip, viewport, phase
    f[48] = sigma_t
    f[49] = env_T  # the World's transmittance e^(-sigma_t distance) (PREVIEW_ENV)
    if noise is not None and noise[0] > 0.0:
        f[50] = noise[0]
        f[56:59] = noise[2]
        f[59] = 1.0 / noise[1]
    i = f.view(np.int32)
    i[52:56] = (int(light_count), int(scale), int(mode), 0)
    return gpu.types.GPUUniformBuf(f.tobytes())
# Texels per side of a shadow-map face (shadow_maps.glsl; preview_shadows.py draws them).
SHADOW_RES = 512
PREVIEW_FOG_SAMPLERS = ("Ftab", "depth_tex", "lights", "fog_lo", "gauss_acc", "gauss_near", "Gtab",
                        "spots", "suns", "env_glow", "shadow_maps", "shadow_info")
PREVIEW_LIBS = ("sun05_airlight.glsl", "biri06_airlight.glsl", "shadow_maps.glsl", "spot_airlight.glsl",
                "sun_airlight.glsl", "preview_common.glsl")


def create_preview_shader(name, frag, defines=()):
    """A full-screen pass of the preview (fog_preview_frag.glsl, preview_upsample_frag.glsl,
    preview_composite_frag.glsl).

    Sources: vertex = fullscreen_vert.glsl (vertex input 0 VEC2 "pos", interface
    "airlight_<name>_iface" with smooth VEC2 "uv"); fragment = PREVIEW_LIBS + _frag_,
    concatenated in that order.
    Uniform buffer: slot 0, struct AirlightPreviewParams (typedef preview_params.glsl) as
    variable "pv"; the GLSL names of PREVIEW_UBO are defines for its members (no push
    constants). Samplers (FLOAT_2D, slots in order): PREVIEW_FOG_SAMPLERS.
    Defines (all must be given): PREVIEW_WINDOW_DEPTH, PREVIEW_PHASE, PREVIEW_SPOTS, PREVIEW_SUNS,
    PREVIEW_GAUSSIANS, PREVIEW_ENV (the World's glow: sampler env_glow, an equirectangular
    RGBA map with row 0 at the top, and pv_env_T), PREVIEW_SHADOWS (volumetric shadows:
    samplers shadow_maps and shadow_info of preview_shadows.py, SHADOW_RES),
    and per file: PREVIEW_LOWRES and PREVIEW_GAUSS_SCALE (fog), PREVIEW_EXACT_PASS and
    PREVIEW_MARK (upsample). Output: 0 VEC4 "frag_color".
    """
    return create_fullscreen_shader(name, frag, libs=PREVIEW_LIBS, samplers=PREVIEW_FOG_SAMPLERS,
                                    defines=defines, ubo=PREVIEW_UBO)


RBF_SPLAT_SOURCES = ("sun05_airlight.glsl", "preview_common.glsl", "rbf_gaussian.glsl",
                     "rbf_noise.glsl", "rbf_splat_pixel.glsl")
# Tile pass (rbf_tiles_frag.glsl): tile size in splat-target texels and the width of the
# list texture.
RBF_TILE = 8
RBF_LIST_WIDTH = 4096
# Light fit (rbf_light_fit_frag.glsl): rows of gauss_light per block of RBF_TEX_WIDTH
# Gaussians, and when a Gaussian keeps the exact per-pixel light terms: a light closer
# than RBF_FIT_NEAR cull radii, or a peak optical depth c sqrt(pi) / a above
# RBF_FIT_MAX_T (tests/gpu/test_preview_gaussians.py measures the fit's error against the bake).
RBF_FIT_ROWS = 9
RBF_FIT_NEAR = 2.0
RBF_FIT_MAX_T = 0.1


def _rbf_create_info(window_depth, samplers, light_fit=False, shadows=False):
    """Create-info parts the splat and tile passes share (see create_rbf_splat_shader);
    _light_fit_ adds the sampler gauss_light after _samplers_ and RBF_LIGHT_FIT 1; _shadows_
    the samplers shadow_maps and shadow_info after those, PREVIEW_SHADOWS 1 and SHADOW_RES
    (each Gaussian's light terms times the light's visibility where they are evaluated)."""
    info = gpu.types.GPUShaderCreateInfo()
    _add_ubo(info, *PREVIEW_UBO)
    if light_fit:
        samplers = tuple(samplers) + ("gauss_light",)
    if shadows:
        samplers = tuple(samplers) + ("shadow_maps", "shadow_info")
        info.define("SHADOW_RES", str(SHADOW_RES))
    info.define("PREVIEW_SHADOWS", "1" if shadows else "0")
    for slot, sname in enumerate(samplers):
        info.sampler(slot, 'FLOAT_2D', sname)
    info.define("RBF_TEX_WIDTH", str(RBF_TEX_WIDTH))
    info.define("RBF_LIGHT_FIT", "1" if light_fit else "0")
    info.define("RBF_FIT_NEAR", repr(float(RBF_FIT_NEAR)))
    info.define("RBF_FIT_MAX_T", repr(float(RBF_FIT_MAX_T)))
    info.define("PREVIEW_WINDOW_DEPTH", str(int(bool(window_depth))))
    info.define("PREVIEW_PHASE", "0")
    info.define("PREVIEW_SPOTS", "0")
    info.define("PREVIEW_SUNS", "0")
    info.fragment_out(0, 'VEC4', "frag_color")
    info.fragment_out(1, 'VEC4', "frag_near")
    return info


def _rbf_sources(shadows, last):
    """RBF_SPLAT_SOURCES (after shadow_maps.glsl with _shadows_) and then _last_."""
    return "".join(load_source(name) + "\n" for name in
                   (("shadow_maps.glsl",) if shadows else ()) + RBF_SPLAT_SOURCES + (last,))


def create_rbf_splat_shader(window_depth=False, light_fit=False, shadows=False):
    """The Gaussian splat pass (Fogshop section 5).

    Sources: vertex = rbf_splat_vert.glsl; fragment = RBF_SPLAT_SOURCES (sun05_airlight.glsl,
    preview_common.glsl, rbf_gaussian.glsl, rbf_noise.glsl, rbf_splat_pixel.glsl) +
    rbf_splat_frag.glsl, concatenated in this order (the create-info adds the
    declarations below in front of each).
    Defines: RBF_TEX_WIDTH (int), PREVIEW_WINDOW_DEPTH (0: depth_tex holds linear
    distance, 1: window depth), PREVIEW_PHASE 0, PREVIEW_SPOTS 0, PREVIEW_SUNS 0.
    Vertex inputs: 0 VEC2 "corner" (quad corner in {-1, 1}^2), 1 FLOAT "gid" (Gaussian
    index); 4 vertices per Gaussian, drawn as TRIS with 6 indices per Gaussian
    (`rbf_splat_batch`).
    Vertex -> fragment: interface "airlight_rbf_splat_iface", flat INT "gi".
    Uniform buffer: as create_preview_shader (PREVIEW_UBO, "pv"): persp, inv_persp, eye,
    clip, viewport, sigma_t, light_count, scale (the splat target's reduction), noise
    (pv_noise_amp, pv_noise); no push constants.
    Samplers (FLOAT_2D, slots in order): 0 Ftab, 1 depth_tex, 2 lights, 3 gauss, 4 gauss_f1
    (Ftab is declared because preview_common.glsl refers to it; unused here).
    Fragment outputs: 0 VEC4 "frag_color" (rgb airlight, a optical depth [t0, Dvp]),
    1 VEC4 "frag_near" (r = optical depth [0, t0]); blend ADDITIVE_PREMULT into two
    RGBA32F targets cleared to 0.
    Light fit (_light_fit_ True): defines RBF_LIGHT_FIT 1, RBF_FIT_NEAR, RBF_FIT_MAX_T
    (floats; also given, unused, with RBF_LIGHT_FIT 0) and one more sampler after the
    others, "gauss_light" (the output of create_rbf_light_fit_shader's pass): the pixels
    evaluate each Gaussian's fitted light factor instead of the exact light terms.
    """
    iface = gpu.types.GPUStageInterfaceInfo("airlight_rbf_splat_iface")
    iface.flat('INT', "gi")
    info = _rbf_create_info(window_depth, ("Ftab", "depth_tex", "lights", "gauss", "gauss_f1"),
                            light_fit, shadows)
    info.vertex_in(0, 'VEC2', "corner")
    info.vertex_in(1, 'FLOAT', "gid")
    info.vertex_out(iface)
    info.vertex_source(load_source("rbf_splat_vert.glsl"))
    info.fragment_source(_rbf_sources(shadows, "rbf_splat_frag.glsl"))
    return gpu.shader.create_from_info(info)


def create_rbf_tiles_shader(window_depth=False, light_fit=False, shadows=False):
    """The Gaussian tile pass: the splat pass's sums in one full-screen draw per target
    (rbf_tiles_frag.glsl), no blending.

    Sources: vertex = fullscreen_vert.glsl (vertex input 0 VEC2 "pos", interface
    "airlight_rbf_tiles_iface" with smooth VEC2 "uv"); fragment = RBF_SPLAT_SOURCES +
    rbf_tiles_frag.glsl. Defines: those of create_rbf_splat_shader plus RBF_TILE and
    RBF_LIST_WIDTH. Uniform buffer: as create_rbf_splat_shader. Samplers (FLOAT_2D, slots
    in order): 0 Ftab, 1 depth_tex, 2 lights, 3 gauss, 4 gauss_f1, 5 tile_index, 6
    tile_list (then 7 gauss_light with _light_fit_, as create_rbf_splat_shader). Fragment
    outputs as create_rbf_splat_shader; drawn with blending NONE over the two RGBA32F
    targets (no clear needed)."""
    iface = gpu.types.GPUStageInterfaceInfo("airlight_rbf_tiles_iface")
    iface.smooth('VEC2', "uv")
    info = _rbf_create_info(window_depth, ("Ftab", "depth_tex", "lights", "gauss", "gauss_f1",
                                           "tile_index", "tile_list"), light_fit, shadows)
    info.define("RBF_TILE", str(RBF_TILE))
    info.define("RBF_LIST_WIDTH", str(RBF_LIST_WIDTH))
    info.vertex_in(0, 'VEC2', "pos")
    info.vertex_out(iface)
    info.vertex_source(load_source("fullscreen_vert.glsl"))
    info.fragment_source(_rbf_sources(shadows, "rbf_tiles_frag.glsl"))
    return gpu.shader.create_from_info(info)


def create_rbf_light_fit_shader(shadows=False):
    """The light-fit pass (rbf_light_fit_frag.glsl): one texel of gauss_light per
    (Gaussian, row), drawn as a full-screen quad over an RGBA32F texture of RBF_TEX_WIDTH x
    RBF_FIT_ROWS * blocks texels (`rbf_light_fit_texture`), no blending.

    Sources: vertex = fullscreen_vert.glsl (interface "airlight_rbf_light_fit_iface",
    smooth VEC2 "uv"); fragment = RBF_SPLAT_SOURCES + rbf_light_fit_frag.glsl. Defines,
    uniform buffer and samplers (0 Ftab, 1 depth_tex, 2 lights, 3 gauss, 4 gauss_f1) as
    create_rbf_splat_shader with RBF_LIGHT_FIT 0; outputs 0 "frag_color" (the texture),
    1 "frag_near" (unused: 0)."""
    iface = gpu.types.GPUStageInterfaceInfo("airlight_rbf_light_fit_iface")
    iface.smooth('VEC2', "uv")
    info = _rbf_create_info(False, ("Ftab", "depth_tex", "lights", "gauss", "gauss_f1"), shadows=shadows)
    info.vertex_in(0, 'VEC2', "pos")
    info.vertex_out(iface)
    info.vertex_source(load_source("fullscreen_vert.glsl"))
    info.fragment_source(_rbf_sources(shadows, "rbf_light_fit_frag.glsl"))
    return gpu.shader.create_from_info(info)


def rbf_light_fit_texture(count):
    """The (uninitialised) RGBA32F target of the light-fit pass for _count_ Gaussians."""
    blocks = max(1, -(-int(count) // RBF_TEX_WIDTH))
    return gpu.types.GPUTexture((RBF_TEX_WIDTH, RBF_FIT_ROWS * blocks), format='RGBA32F')


def rbf_tile_textures(first, count, entries):
    """(tile_index, tile_list) textures of rbf_tiles_frag.glsl from per-tile first entry
    and count ((tiles_y, tiles_x) each) and the concatenated Gaussian indices."""
    import numpy as np
    index = np.stack([np.asarray(first, np.float32), np.asarray(count, np.float32)], -1)
    entries = np.asarray(entries, np.float32).ravel()
    rows = max(1, -(-len(entries) // RBF_LIST_WIDTH))
    flat = np.zeros(rows * RBF_LIST_WIDTH, np.float32)
    flat[:len(entries)] = entries
    return float_texture(index), float_texture(flat.reshape(rows, RBF_LIST_WIDTH))


def rbf_splat_batch(shader, count):
    """4 vertices and 2 triangles per Gaussian for `create_rbf_splat_shader` (attribute
    "corner" in {-1, 1}^2, "gid" = Gaussian index). Depends on _count_ only: the data
    come from textures, so the batch is rebuilt only when the number of Gaussians changes."""
    import numpy as np
    from gpu_extras.batch import batch_for_shader
    n = int(count)
    corner = np.tile(np.array(_QUAD, np.float32), (n, 1))
    gid = np.repeat(np.arange(n, dtype=np.float32), 4)
    base = (np.arange(n, dtype=np.int32) * 4)[:, None, None]
    tris = (np.array(_QUAD_TRIS, np.int32)[None] + base).reshape(-1, 3)
    return batch_for_shader(shader, 'TRIS', {"corner": corner, "gid": gid}, indices=tris)


def rbf_data_textures(centres, scales, amplitudes, radii, f1, albedo=None, noise_radii=None):
    """The splat pass's per-Gaussian textures (layout in rbf_splat_pixel.glsl): gauss
    (RGBA32F, RBF_TEX_WIDTH x 3 rows per block of W Gaussians) and gauss_f1 (RGBA32F,
    RBF_TEX_WIDTH x ceil(L / 4) rows per block, light l in component l % 4 of row l // 4),
    f1 of shape (L, n); _albedo_ (n, 3) per-Gaussian
    colours (None: 1, the lights' intensities then carry the fog's albedo); _noise_radii_
    (n,) R_bake / |b - eye| for the noise (None: 0). (`rbf_gauss_texture`, `rbf_f1_texture`.)"""
    return (rbf_gauss_texture(centres, scales, amplitudes, radii, albedo, noise_radii),
            rbf_f1_texture(f1, len(scales)))


def rbf_gauss_texture(centres, scales, amplitudes, radii, albedo=None, noise_radii=None):
    """The gauss texture of `rbf_data_textures` alone (it depends on the eye only through
    _noise_radii_: the preview keeps it across view changes while the noise is off)."""
    import numpy as np
    n = len(scales)
    W = RBF_TEX_WIDTH
    blocks = max(1, -(-n // W))
    flat = np.zeros((blocks, 3, W, 4), np.float32)
    idx = np.arange(n)
    blk, col = idx // W, idx % W
    flat[blk, 0, col, :3] = np.asarray(centres, np.float64).reshape(-1, 3)
    flat[blk, 0, col, 3] = scales
    flat[blk, 1, col, 0] = amplitudes
    flat[blk, 1, col, 1] = radii
    if noise_radii is not None:
        flat[blk, 1, col, 2] = noise_radii
    flat[blk, 2, col, :3] = 1.0 if albedo is None else np.asarray(albedo, np.float64).reshape(-1, 3)
    return float_texture(flat.reshape(blocks * 3, W, 4))


def rbf_f1_texture(f1, n):
    """The gauss_f1 texture of `rbf_data_textures` alone, f1 of shape (L, n)."""
    import numpy as np
    W = RBF_TEX_WIDTH
    blocks = max(1, -(-n // W))
    idx = np.arange(n)
    blk, col = idx // W, idx % W
    f1 = np.asarray(f1, np.float64).reshape(-1, n)
    rows = max(1, -(-f1.shape[0] // 4))
    f1_tex = np.zeros((blocks, rows, W, 4), np.float32)
    for l in range(f1.shape[0]):
        f1_tex[blk, l // 4, col, l % 4] = f1[l]
    return float_texture(f1_tex.reshape(blocks * rows, W, 4))


def create_rbf_test_shader():
    """GLSL-vs-C++ agreement shader for rbf_gaussian.glsl (test_preview_gaussians.py):
    fullscreen_vert.glsl + rbf_gaussian.glsl + test_rbf_frag.glsl; samplers 0..4 "in0".."in4" (RGBA32F, one
    input point per pixel; layout in test_rbf_frag.glsl); output frag_color."""
    return create_fullscreen_shader("test_rbf", "test_rbf_frag.glsl", libs=("rbf_gaussian.glsl",),
                                    samplers=("in0", "in1", "in2", "in3", "in4"))


def create_biri_test_shader():
    """GLSL-vs-C++ agreement shader for biri06_airlight.glsl (test_preview_phase_spot_sun.py):
    fullscreen_vert.glsl + sun05_airlight.glsl + biri06_airlight.glsl + test_biri_frag.glsl; samplers 0 "in0"
    (RGBA32F inputs), 1 "Gtab" (the Biri table); push constant VEC4 "phase"."""
    return create_fullscreen_shader("test_biri", "test_biri_frag.glsl",
                                    libs=("sun05_airlight.glsl", "biri06_airlight.glsl"),
                                    push_constants=(('VEC4', "phase"),), samplers=("in0", "Gtab"))


def create_sun_test_shader():
    """GLSL-vs-reference shader for sun_airlight.glsl (test_preview_phase_spot_sun.py):
    fullscreen_vert.glsl + sun05_airlight.glsl + sun_airlight.glsl + test_sun_frag.glsl; samplers 0 "in0", 1 "in1"."""
    return create_fullscreen_shader("test_sun", "test_sun_frag.glsl",
                                    libs=("sun05_airlight.glsl", "sun_airlight.glsl"),
                                    samplers=("in0", "in1"))


def create_noise_test_shader():
    """GLSL-vs-C++ agreement shader for rbf_noise.glsl (test_preview_noise.py):
    fullscreen_vert.glsl + rbf_noise.glsl + test_noise_frag.glsl; sampler 0 "in0" (RGBA32F points)."""
    return create_fullscreen_shader("test_noise", "test_noise_frag.glsl", libs=("rbf_noise.glsl",),
                                    samplers=("in0",))


def create_rbf_fast_test_shader():
    """Agreement shader for rbf_gaussian.glsl's rbf_fast_erf_diff (test_preview_gaussians.py):
    fullscreen_vert.glsl + rbf_gaussian.glsl + test_rbf_fast_frag.glsl; sampler 0 "in0"."""
    return create_fullscreen_shader("test_rbf_fast", "test_rbf_fast_frag.glsl",
                                    libs=("rbf_gaussian.glsl",), samplers=("in0",))


def create_shadow_test_shader(shadow_res):
    """GLSL-vs-C++ agreement shader for shadow_maps.glsl (test_preview_shadows.py):
    fullscreen_vert.glsl + shadow_maps.glsl + test_shadow_frag.glsl, SHADOW_RES _shadow_res_;
    samplers 0 "in0" (RGBA32F: point, row), 1 "shadow_maps", 2 "shadow_info"."""
    return create_fullscreen_shader("test_shadow", "test_shadow_frag.glsl", libs=("shadow_maps.glsl",),
                                    samplers=("in0", "shadow_maps", "shadow_info"),
                                    defines=(("SHADOW_RES", int(shadow_res)),))
