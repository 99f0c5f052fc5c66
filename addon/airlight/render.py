"""Render handlers: bake each frame's fog just before it renders.

With `scene.airlight.enabled`, `blender -b file.blend -f N`, `-a`, F12 and Ctrl+F12 render
foggy: each frame is baked into <cache_dir>/fog_####.exr and the compositor's Image node
pointed at it, before the render engine starts on the frame. Errors are printed (and shown
in the Airlight Fog panel, render_problem) and the frame renders without new fog passes;
they never abort the render.

Where the bake happens (checked in Blender 3.4):
  - Background renders (-f, -a) call `render_pre` in the main thread: the bake runs
    there, after frame_set evaluates the scene at the frame.
  - Interactive renders (F12, Ctrl+F12) run in the render job's thread, where frame_set
    is unsafe and the UI's depsgraph stays at the frame shown in the UI. There
    `render_pre` only marks the frame; the render pipeline then evaluates its own
    depsgraph at the frame and calls `frame_change_post` with it (mode 'RENDER'), and the
    bake runs there, with that depsgraph. The scene's data is not written in that thread
    (the UI may be drawing it; only the compositor's Image node is pointed at the new
    file, as before): the emitters' smoke at the frame is computed for the bake
    (emitter.targets_at_frame) instead of being written into their fog objects.
"""

import threading

import time

import bpy
from bpy.app.handlers import persistent

from . import bake, cache, compositor, emitter, native, surface


def _in_main_thread():
    return threading.current_thread() is threading.main_thread()


def _main_thread_depsgraph(scene):
    """The scene's depsgraph evaluated at the frame about to render (main thread only).

    At render_pre the render engine has not evaluated anything yet, and for `-a` the
    view layer's depsgraph still holds the previous frame, so the frame is set again,
    which evaluates it.
    """
    scene.frame_set(scene.frame_current, subframe=scene.frame_subframe)
    view_layer = bpy.context.view_layer
    if view_layer is None or bpy.context.scene != scene:
        view_layer = scene.view_layers[0]
    return view_layer.depsgraph


# The fog reaches the image through the compositor, which a render skips with
# Output > Post Processing > Compositing off (the bake still writes its passes).
COMPOSITING_OFF = ("Compositing is off (Output > Post Processing): renders are saved without "
                   "the fog (its passes are still baked)")
# (Stereoscopy / multi-view renders bake every view from its own camera: bake.view_paths.)
# The bake traces pinhole cameras at the frame's instant: a render's motion blur, and its
# depth of field unless the lens is sampled (scene.airlight.lens_samples, perspective
# cameras), smear silhouettes that the fog passes keep sharp (a fringe at the edge).
DEPTH_OF_FIELD = ("Depth of field with one lens sample: the fog passes stay sharp, so out-of-focus "
                  "silhouettes get a fringe (raise Lens Samples, or defocus after the fog with the "
                  "Defocus node)")
MOTION_BLUR = ("Motion blur with one motion sample: the fog is baked at the frame's instant, sharp "
               "at moving silhouettes (raise Motion Samples)")
MOTION_BLUR_INTERACTIVE = ("Motion blur: interactive renders (F12) bake the fog at the frame's instant "
                           "(background renders and Bake Fog sample the shutter)")


def render_notes(scene):
    """What the fog composite of _scene_'s renders cannot do as the render asks (the
    messages above), for the panel and each render's console line."""
    notes = []
    if not scene.render.use_compositing:
        notes.append(COMPOSITING_OFF)
    camera = scene.camera
    if (camera is not None and camera.type == 'CAMERA' and camera.data.dof.use_dof
            and (scene.airlight.lens_samples <= 1 or camera.data.type != 'PERSP')):
        notes.append(DEPTH_OF_FIELD)
    if scene.render.use_motion_blur:
        notes.append(MOTION_BLUR if scene.airlight.motion_samples <= 1 else MOTION_BLUR_INTERACTIVE)
    return notes


# Interactive renders: the scene whose frame render_pre marked for baking in the render
# thread's frame_change_post (see the module's docstring); None when nothing is pending.
_pending = {"scene": None}
# Per scene name, (frame, reason) of the last render-time bake that failed, until one
# succeeds: the Airlight Fog panel shows it (an interactive render's messages go to a
# console the artist may not have open).
_failed = {}


def render_problem(scene):
    """(frame, reason) of the last render-time bake of _scene_ that failed, or None."""
    return _failed.get(scene.name)


@persistent
def on_render_pre(scene, *_):
    settings = getattr(scene, "airlight", None)
    if settings is None:
        return
    if not settings.enabled:
        if compositor.is_set_up(scene):
            compositor.sync(scene)  # mute: the render passes through unchanged
        return
    if not native.available():
        print(f"Airlight: frame {scene.frame_current} rendered without fog: {native.error()}", flush=True)
        return
    if _in_main_thread():
        _bake_for_render(scene, lambda: _main_thread_depsgraph(scene), evaluate_at=bake.frame_evaluator(scene))
    else:
        _pending["scene"] = scene.name


@persistent
def on_render_frame_evaluated(scene, depsgraph=None):
    """The render thread's bake (interactive renders), with the render's own depsgraph."""
    if _pending["scene"] != scene.name or depsgraph is None or depsgraph.mode != 'RENDER' or _in_main_thread():
        return
    _pending["scene"] = None
    _bake_for_render(scene, lambda: depsgraph, lambda: emitter.targets_at_frame(scene))


@persistent
def on_render_end(*_):
    _pending["scene"] = None
    _report_writes(cache.finish_writes())


def _report_writes(done):
    """Prints how the pass files written beside the render went (cache.finish_writes, each
    labelled with its frame)."""
    for frame, paths, seconds, error in done:
        if error is not None:
            print(f"Airlight: frame {frame}: the fog passes were composited but not saved: {error}", flush=True)
        else:
            print(f"Airlight: frame {frame}: EXR {1000.0 * seconds:.0f} ms beside the render -> {paths[0]}",
                  flush=True)


@persistent
def on_render_post(*_):
    """The frame's pass files are whole before the next frame, or the process's end."""
    _report_writes(cache.finish_writes())


def _bake_for_render(scene, get_depsgraph, get_mesh_overrides=lambda: None, evaluate_at=None):
    """Bakes the frame about to render with the depsgraph get_depsgraph() returns (and the
    fog objects' data get_mesh_overrides() returns, fog_object.gather) and hands it to the
    compositor: its passes copied into memory where the fog nodes read them from there
    (compositor.choose_source; the EXR then written beside the render), else the EXR the
    Image node is pointed at. On failure prints why and composites neutral passes."""
    settings = scene.airlight
    frame = scene.frame_current
    memory = settings.auto_composite and _in_main_thread() and compositor.in_memory(scene)
    deferred = [] if memory else None
    try:
        filepath, stats, seconds = bake.bake_frame(scene, get_depsgraph(), bake.cache_path(scene, frame),
                                                   mesh_overrides=get_mesh_overrides(), evaluate_at=evaluate_at,
                                                   deferred=deferred)
    except Exception as ex:  # a handler must never take the render down
        reason = str(ex) if isinstance(ex, bake.BakeError) else f"{type(ex).__name__}: {ex}"
        print(f"Airlight: frame {frame} rendered without fog: {reason}", flush=True)
        _failed[scene.name] = (frame, reason)
        if memory:
            compositor.fill_neutral(scene)
        elif settings.auto_composite and compositor.is_set_up(scene):
            # Don't composite a stale bake of another frame.
            compositor.sync(scene, compositor.neutral_passes(scene))
        return
    _failed.pop(scene.name, None)
    print(f"Airlight: fog of frame {frame} baked in {seconds * 1000.0:.0f} ms -> {filepath}", flush=True)
    for note in render_notes(scene):
        if note == MOTION_BLUR_INTERACTIVE and evaluate_at is not None:
            continue  # (this bake sampled the shutter)
        print(f"Airlight: frame {frame}: {note}", flush=True)
    composite = ""
    if memory:
        try:
            seconds = compositor.fill(scene, deferred[0].passes)
            composite = f", compositor {1000.0 * seconds:.0f} ms (passes in memory)"
        except Exception as ex:  # e.g. no memory for the images: say so, never a stale frame's fog
            reason = f"cannot hand the passes to the compositor: {type(ex).__name__}: {ex}"
            print(f"Airlight: frame {frame} rendered without fog: {reason}", flush=True)
            _failed[scene.name] = (frame, reason)
            compositor.fill_neutral(scene)
        _report_writes(cache.write_later(deferred, frame))
    elif settings.auto_composite:
        t0 = time.perf_counter()
        compositor.sync(scene, filepath)
        composite = f", compositor {1000.0 * (time.perf_counter() - t0):.0f} ms"
    for line in stats.get(bake.LIGHT_NOTES, ()):
        print(f"Airlight: frame {frame}: {line}", flush=True)
    print(f"Airlight: frame {frame}: {bake.parts_line(stats)}{bake.fog_objects_line(stats)}{composite}", flush=True)


@persistent
def on_load_post(*_):
    """Un-mutes the fog nodes of loaded scenes whose fog is on (files hold them muted, so
    that a machine without the add-on renders them unfogged: compositor.on_save_pre), and
    completes them before anything renders, and for the window's scene the surface
    shading's light groups (a file saved before a light was added, or without the add-on).

    A render composites with the node links as they were when it started (before
    render_pre), so the pass links must already exist then (checked in Blender 3.4).
    """
    for scene in bpy.data.scenes:
        settings = getattr(scene, "airlight", None)
        if settings is not None and compositor.is_set_up(scene):
            compositor.unmute_loaded(scene)  # saved muted (compositor.on_save_pre)
        if settings is None or not (settings.enabled and settings.auto_composite):
            continue
        try:
            if not compositor.is_complete(scene) or not compositor.views_ready(scene):
                compositor.setup(scene)
            compositor.choose_source(scene)
            if surface.active(scene) and scene == bpy.context.scene:
                compositor.complete_surface(scene, bpy.context.evaluated_depsgraph_get())
        except Exception as ex:
            print(f"Airlight: cannot set up the compositor of scene '{scene.name}': {ex}", flush=True)


@persistent
def on_render_init(scene, *_):
    """Before a render builds what it composites with: the fog nodes for its views
    (Stereoscopy switched on by a script after the file was loaded), and where they take
    the passes from (compositor.choose_source)."""
    settings = getattr(scene, "airlight", None)
    if settings is None or not (settings.enabled and settings.auto_composite) or not _in_main_thread():
        return
    try:
        compositor.ensure_views(scene)
        compositor.choose_source(scene)
    except Exception as ex:  # a handler must never take the render down
        print(f"Airlight: cannot set up the compositor's fog nodes: {ex}", flush=True)


_HANDLERS = (
    (bpy.app.handlers.render_init, on_render_init),
    (bpy.app.handlers.render_pre, on_render_pre),
    (bpy.app.handlers.frame_change_post, on_render_frame_evaluated),
    (bpy.app.handlers.render_post, on_render_post),
    (bpy.app.handlers.render_cancel, on_render_end),
    (bpy.app.handlers.render_complete, on_render_end),
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
