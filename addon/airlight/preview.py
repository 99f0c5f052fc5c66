"""Viewport preview of the homogeneous fog: a SpaceView3D draw handler that composites
the analytic airlight (the GLSL twin of the C++ kernel, shaders/sun05_airlight.glsl)
over the 3D viewport.

Per draw: the region's scene depth is read back from the active framebuffer (POST_VIEW,
where the scene depth is still bound) into an R32F texture; one full-screen pass
(shaders/fog_preview_frag.glsl) reconstructs each pixel's view ray from the region's
matrices, sums sun05_airlight over the point lights and writes rgb = airlight,
alpha = 1 - transmittance with ALPHA_PREMULT blending: L = La + Tr L_scene.

Lifetime: GPU resources (shader, batch, F table texture) are built on the first draw,
kept in `_state`, and dropped on unregister and on file load (load_pre). The draw
handler is added in register(), removed in unregister() and on load_pre, and added back
on load_post, so no handler ever leaks. Any error while drawing is kept, shown in the
sidebar panel, and stops further drawing until a setting changes; it never raises into
Blender's draw loop. The view-independent part (`draw_fog`) is used by the GPU tests
and the benchmark with depth they render themselves.
"""

import math
import time

import bpy
from bpy.app.handlers import persistent
from bpy.props import BoolProperty

from . import native

# Module state: the draw handler, GPU resources built lazily, and diagnostics.
_state = {
    "handle": None,
    "gpu": None,        # dict(shader, batch, ftab) once built
    "error": None,      # last draw error (str); drawing pauses while set
    "last_ms": None,    # duration of the last fog draw in milliseconds (CPU side)
    "last_depth_ms": None,  # of which reading back and uploading the depth
    "draws": 0,         # number of fog passes drawn (tests read it)
    "capture": None,    # tests: set to {} and the next draw stores its inputs there
}

MAX_LIGHTS = 256


def _native_for_preview():
    """The native module if it offers the F table, else None (reason in _missing_reason)."""
    module = native.load()
    if module is None or not hasattr(module, "special_F_table"):
        return None
    return module


def _missing_reason():
    if native.load() is None:
        return native.error() or "The native module is not available."
    return "The native module lacks special_F_table(); rebuild it."


def _gpu_resources():
    """Builds (once) the fog shader, the quad and the F table texture."""
    res = _state["gpu"]
    if res is None:
        from . import gpu_shaders as gs
        module = _native_for_preview()
        if module is None:
            raise RuntimeError(_missing_reason())
        shader = gs.create_fullscreen_shader(
            "fog_preview", "fog_preview_frag.glsl", libs=("sun05_airlight.glsl",),
            push_constants=(('MAT4', "inv_persp"), ('VEC4', "eye"), ('VEC4', "viewport"),
                            ('FLOAT', "sigma_t"), ('INT', "light_count")),
            samplers=("Ftab", "depth_tex", "lights"))
        ftab, _table = gs.f_table_texture(module)
        res = _state["gpu"] = dict(shader=shader, batch=gs.fullscreen_batch(shader), ftab=ftab)
    return res


def free_gpu_resources():
    _state["gpu"] = None


def scene_lights(scene, view_layer=None):
    """(positions, intensities) of the visible point lights that scatter in the fog:
    lists of 3-tuples; intensity = albedo * colour * power / (4 pi) W/sr (the bake's
    I0 times the fog albedo)."""
    albedo = tuple(scene.airlight.color)
    positions, intensities = [], []
    objects = view_layer.objects if view_layer is not None else scene.objects
    for obj in objects:
        if obj.type != 'LIGHT' or obj.data.type != 'POINT':
            continue
        if not obj.data.airlight.participate:
            continue
        if view_layer is not None and not obj.visible_get(view_layer=view_layer):
            continue
        scale = obj.data.energy / (4.0 * math.pi)
        positions.append(tuple(obj.matrix_world.translation))
        intensities.append(tuple(a * c * scale for a, c in zip(albedo, obj.data.color)))
        if len(positions) == MAX_LIGHTS:
            break
    return positions, intensities


def _lights_texture(positions, intensities):
    import numpy as np
    from . import gpu_shaders as gs
    n = max(1, len(positions))
    data = np.zeros((2, n, 4), np.float32)
    if positions:
        data[0, :len(positions), :3] = positions
        data[1, :len(positions), :3] = intensities
    return gs.float_texture(data)


def draw_fog(*, depth_tex, perspective_matrix, view_origin, is_perspective, viewport,
             sigma_t, light_positions, light_intensities):
    """Draws the fog pass over the bound framebuffer with premultiplied blending.

    depth_tex: R32F texture of the window depth (viewport[2] x viewport[3]);
    perspective_matrix: mathutils.Matrix, projection @ view; view_origin: 3 floats;
    viewport: (x, y, width, height) of the target region in the framebuffer.
    Restores every gpu.state it changes.
    """
    import gpu
    res = _gpu_resources()
    shader = res["shader"]
    lights = _lights_texture(light_positions, light_intensities)
    prev_blend = gpu.state.blend_get()
    prev_depth = gpu.state.depth_test_get()
    prev_mask = gpu.state.depth_mask_get()
    try:
        gpu.state.blend_set('ALPHA_PREMULT')
        gpu.state.depth_test_set('NONE')
        gpu.state.depth_mask_set(False)
        shader.bind()
        shader.uniform_float("inv_persp", perspective_matrix.inverted())
        shader.uniform_float("eye", (*view_origin, 1.0 if is_perspective else 0.0))
        shader.uniform_float("viewport", tuple(float(v) for v in viewport))
        shader.uniform_float("sigma_t", float(sigma_t))
        shader.uniform_int("light_count", len(light_positions))
        shader.uniform_sampler("Ftab", res["ftab"])
        shader.uniform_sampler("depth_tex", depth_tex)
        shader.uniform_sampler("lights", lights)
        res["batch"].draw(shader)
    finally:
        gpu.state.blend_set(prev_blend)
        gpu.state.depth_test_set(prev_depth)
        gpu.state.depth_mask_set(prev_mask)
    _state["draws"] += 1


def _is_rendering():
    """A final render is running (F12 / animation): the viewport is not worth the CPU."""
    return bpy.app.is_job_running('RENDER')


def _should_draw(context):
    wm = context.window_manager
    if not getattr(wm, "airlight_preview", False) or _state["error"] is not None:
        return False
    scene = context.scene
    settings = getattr(scene, "airlight", None)
    if settings is None or not settings.enabled:
        return False
    if _is_rendering():
        return False
    return _native_for_preview() is not None


def _draw_callback():
    """POST_VIEW handler: never raises; an error is kept and shown in the panel."""
    context = bpy.context
    try:
        if not _should_draw(context):
            return
        import gpu
        from . import gpu_shaders as gs
        rv3d = context.region_data
        if rv3d is None:
            return
        t0 = time.perf_counter()
        x, y, w, h = gpu.state.viewport_get()
        fb = gpu.state.active_framebuffer_get()
        depth_buf = fb.read_depth(x, y, w, h)
        depth_tex = gs.depth_texture(depth_buf, w, h)
        _state["last_depth_ms"] = (time.perf_counter() - t0) * 1e3
        scene = context.scene
        positions, intensities = scene_lights(scene, context.view_layer)
        draw_fog(depth_tex=depth_tex, perspective_matrix=rv3d.perspective_matrix,
                 view_origin=tuple(rv3d.view_matrix.inverted().translation),
                 is_perspective=rv3d.is_perspective, viewport=(x, y, w, h),
                 sigma_t=scene.airlight.density, light_positions=positions,
                 light_intensities=intensities)
        _state["last_ms"] = (time.perf_counter() - t0) * 1e3
        if _state["capture"] is not None:
            _state["capture"].update(
                depth=gs.buffer_to_numpy(depth_buf, (h, w)), viewport=(x, y, w, h),
                perspective_matrix=rv3d.perspective_matrix.copy(),
                view_origin=tuple(rv3d.view_matrix.inverted().translation))
    except Exception as ex:  # never break Blender's draw loop
        _state["error"] = f"{type(ex).__name__}: {ex}"
        print(f"Airlight preview disabled: {_state['error']}")


def _on_setting_changed(self, context):
    """Toggling the preview retries after an error and redraws the viewports."""
    _state["error"] = None
    for window in getattr(context.window_manager, "windows", ()):
        for area in window.screen.areas:
            if area.type == 'VIEW_3D':
                area.tag_redraw()


def add_draw_handler():
    if _state["handle"] is None:
        _state["handle"] = bpy.types.SpaceView3D.draw_handler_add(
            _draw_callback, (), 'WINDOW', 'POST_VIEW')


def remove_draw_handler():
    if _state["handle"] is not None:
        bpy.types.SpaceView3D.draw_handler_remove(_state["handle"], 'WINDOW')
        _state["handle"] = None


def handler_count():
    """Number of draw handlers this module holds (0 or 1); for the tests."""
    return 0 if _state["handle"] is None else 1


@persistent
def _on_load_pre(*_args):
    remove_draw_handler()
    free_gpu_resources()  # the GPU context survives, but drop everything file-bound
    _state["error"] = None


@persistent
def _on_load_post(*_args):
    add_draw_handler()


class AIRLIGHT_PT_viewport_preview(bpy.types.Panel):
    bl_label = "Airlight Fog Preview"
    bl_idname = "AIRLIGHT_PT_viewport_preview"
    bl_space_type = 'VIEW_3D'
    bl_region_type = 'UI'
    bl_category = "Airlight"

    @classmethod
    def poll(cls, context):
        return getattr(context.scene, "airlight", None) is not None

    def draw(self, context):
        layout = self.layout
        settings = context.scene.airlight
        layout.prop(settings, "enabled")
        row = layout.row()
        row.enabled = settings.enabled
        row.prop(context.window_manager, "airlight_preview", toggle=True)
        if _native_for_preview() is None:
            col = layout.column()
            col.alert = True
            col.label(text="Preview unavailable:", icon='ERROR')
            import textwrap
            for line in textwrap.wrap(_missing_reason(), 40):
                col.label(text=line)
            return
        if _state["error"]:
            col = layout.column()
            col.alert = True
            col.label(text="Preview stopped:", icon='ERROR')
            col.label(text=_state["error"][:120])
        elif _state["last_ms"] is not None and context.window_manager.airlight_preview:
            layout.label(text=f"Last fog pass: {_state['last_ms']:.1f} ms")
        layout.prop(settings, "density")
        layout.prop(settings, "color")


def register():
    """Never raises: a failing preview must not break the add-on's registration."""
    try:
        bpy.types.WindowManager.airlight_preview = BoolProperty(
            name="Viewport Preview",
            description="Show the fog in the 3D viewport (analytic airlight of the point "
                        "lights composited over the viewport; not saved in the file)",
            default=False, update=_on_setting_changed)
        bpy.utils.register_class(AIRLIGHT_PT_viewport_preview)
        add_draw_handler()
        if _on_load_pre not in bpy.app.handlers.load_pre:
            bpy.app.handlers.load_pre.append(_on_load_pre)
        if _on_load_post not in bpy.app.handlers.load_post:
            bpy.app.handlers.load_post.append(_on_load_post)
    except Exception as ex:
        _state["error"] = f"registration failed: {type(ex).__name__}: {ex}"
        print(f"Airlight preview: {_state['error']}")


def unregister():
    remove_draw_handler()
    free_gpu_resources()
    for handlers, fn in ((bpy.app.handlers.load_pre, _on_load_pre),
                         (bpy.app.handlers.load_post, _on_load_post)):
        while fn in handlers:
            handlers.remove(fn)
    try:
        bpy.utils.unregister_class(AIRLIGHT_PT_viewport_preview)
    except RuntimeError:
        pass  # never registered (register() failed early)
    if hasattr(bpy.types.WindowManager, "airlight_preview"):
        del bpy.types.WindowManager.airlight_preview
    _state["error"] = None
    _state["last_ms"] = None
