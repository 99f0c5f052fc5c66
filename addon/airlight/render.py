"""Render handlers: bake each frame's fog just before it renders.

With `scene.airlight.enabled`, `blender -b file.blend -f N`, `-a` and F12 render foggy:
`render_pre` runs once per frame (for -a after the frame has been set and the scene
evaluated there), bakes that frame into <cache_dir>/fog_####.exr and points the
compositor's Image node at it. Errors are printed and the frame renders without new fog
passes; they never abort the render.
"""

import threading

import bpy
from bpy.app.handlers import persistent

from . import bake, compositor, native


def _depsgraph(scene):
    """The scene's depsgraph evaluated at the frame about to render.

    At render_pre the render engine has not evaluated anything yet, and for `-a` the
    view layer's depsgraph still holds the previous frame (checked in Blender 3.4), so
    in the main thread (background renders) the frame is set again, which evaluates
    it. Interactive renders call render_pre from the render thread, where frame_set is
    unsafe: there the depsgraph the UI keeps up to date for the current frame is used.
    """
    if threading.current_thread() is threading.main_thread():
        scene.frame_set(scene.frame_current, subframe=scene.frame_subframe)
    view_layer = bpy.context.view_layer
    if view_layer is None or bpy.context.scene != scene:
        view_layer = scene.view_layers[0]
    return view_layer.depsgraph


@persistent
def on_render_pre(scene, *_):
    settings = getattr(scene, "airlight", None)
    if settings is None:
        return
    if not settings.enabled:
        if compositor.is_set_up(scene):
            compositor.sync(scene)  # mute: the render passes through unchanged
        return
    frame = scene.frame_current
    if not native.available():
        print(f"Airlight: frame {frame} rendered without fog: {native.error()}", flush=True)
        return
    try:
        depsgraph = _depsgraph(scene)
        filepath, stats, seconds = bake.bake_frame(scene, depsgraph, bake.cache_path(scene, frame))
    except Exception as ex:  # a handler must never take the render down
        reason = str(ex) if isinstance(ex, bake.BakeError) else f"{type(ex).__name__}: {ex}"
        print(f"Airlight: frame {frame} rendered without fog: {reason}", flush=True)
        if settings.auto_composite and compositor.is_set_up(scene):
            # Don't composite a stale bake of another frame.
            compositor.sync(scene, compositor.neutral_passes(scene))
        return
    print(f"Airlight: fog of frame {frame} baked in {seconds * 1000.0:.0f} ms -> {filepath}", flush=True)
    if settings.auto_composite:
        compositor.sync(scene, filepath)


@persistent
def on_load_post(*_):
    """Completes the fog nodes of loaded scenes before anything renders.

    A render composites with the node links as they were when it started (before
    render_pre), so the pass links must already exist then (checked in Blender 3.4).
    """
    for scene in bpy.data.scenes:
        settings = getattr(scene, "airlight", None)
        if settings is None or not (settings.enabled and settings.auto_composite):
            continue
        if not compositor.is_complete(scene):
            try:
                compositor.setup(scene)
            except Exception as ex:
                print(f"Airlight: cannot set up the compositor of scene '{scene.name}': {ex}", flush=True)


_HANDLERS = (
    (bpy.app.handlers.render_pre, on_render_pre),
    (bpy.app.handlers.load_post, on_load_post),
)


def register():
    for handlers, function in _HANDLERS:
        if function not in handlers:
            handlers.append(function)


def unregister():
    for handlers, function in _HANDLERS:
        while function in handlers:
            handlers.remove(function)
