"""Render handlers: bake each frame's fog just before it renders.

With `scene.airlight.enabled`, `blender -b file.blend -f N`, `-a`, F12 and Ctrl+F12 render
foggy: each frame is baked into <cache_dir>/fog_####.exr, and the compositor gets its
passes before it runs. Errors are printed (and shown in the Airlight Fog panel,
render_problem) and the frame renders without new fog passes; they never abort the render.

Where the bake happens (checked in Blender 3.4):
  - Background renders (-f, -a) call `render_pre` in the main thread: the frame is
    exported there, after frame_set evaluates the scene at the frame. One view's is baked
    in a thread (_BakeBeside), for the compositor to read from in-memory images: with
    Workbench and EEVEE beside the render engine until the compositor starts
    (render_stats), with other engines before the engine starts. Stereo renders bake
    there, before the engine, and the compositor reads the views' files.
  - Interactive renders (F12, Ctrl+F12) run in the render job's thread, where frame_set
    is unsafe and the UI's depsgraph stays at the frame shown in the UI. There
    `render_pre` only marks the frame; the render pipeline then evaluates its own
    depsgraph at the frame and calls `frame_change_post` with it (mode 'RENDER'), and the
    bake runs there, with that depsgraph. The scene's data is not written in that thread
    (the UI may be drawing it; only the compositor's Image node is pointed at the new
    file, as before): the emitters' smoke at the frame is computed for the bake
    (emitter.targets_at_frame) instead of being written into their fog objects.
"""

import os
import threading
import time

import bpy
from bpy.app.handlers import persistent

from . import bake, cache, compositor, emitter, mesh_read, native, surface


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
    _end_beside()  # (a render that ended without render_post)
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
    _end_beside()


@persistent
def on_render_post(*_):
    """The frame's pass files are whole before the next frame, or the process's end."""
    _end_beside()


def _bake_for_render(scene, get_depsgraph, get_mesh_overrides=lambda: None, evaluate_at=None):
    """Bakes the frame about to render with the depsgraph get_depsgraph() returns (and the
    fog objects' data get_mesh_overrides() returns, fog_object.gather) and hands it to the
    compositor: its passes copied into memory where the fog nodes read them from there
    (compositor.choose_source: baked beside the render, _BakeBeside, the EXR written after),
    else the EXR the Image node is pointed at. On failure prints why and composites neutral
    passes."""
    frame = scene.frame_current
    memory = scene.airlight.auto_composite and _in_main_thread() and compositor.in_memory(scene)
    try:
        jobs, export_seconds = bake.frame_jobs(scene, get_depsgraph(), bake.cache_path(scene, frame),
                                               mesh_overrides=get_mesh_overrides(), evaluate_at=evaluate_at)
        if memory:
            job = _beside["job"] = _BakeBeside(scene, frame, jobs, export_seconds, evaluate_at is not None)
            if not job.yields:
                job.composite()  # now: the render would only share the cores with it
            return
        baked = bake.frame_baked(scene, jobs, export_seconds, *bake.run_views(jobs))
    except Exception as ex:  # a handler must never take the render down
        _render_without_fog(scene, frame, ex, memory)
        return
    _composite(scene, frame, baked, evaluate_at is not None)


def _render_without_fog(scene, frame, ex, memory):
    """Says why frame _frame_ renders without fog, in the console and the panel, and gives
    the compositor neutral passes (never a stale bake of another frame)."""
    reason = str(ex) if isinstance(ex, bake.BakeError) else f"{type(ex).__name__}: {ex}"
    print(f"Airlight: frame {frame} rendered without fog: {reason}", flush=True)
    _failed[scene.name] = (frame, reason)
    if memory:
        compositor.fill_neutral(scene)
    elif scene.airlight.auto_composite and compositor.is_set_up(scene):
        compositor.sync(scene, compositor.neutral_passes(scene))


def _composite(scene, frame, baked, sampled, deferred=None, prepared_seconds=0.0):
    """Hands a successful bake (bake_frame's (filepath, stats, seconds)) to the compositor:
    _deferred_'s passes (cache.PassFile, their file written by _BakeBeside) copied into its
    in-memory images, or the EXR reloaded; prints the frame's lines. _sampled_: the bake
    sampled the shutter. _prepared_seconds_: making the images (compositor.make_images)."""
    filepath, stats, seconds = baked
    _failed.pop(scene.name, None)
    print(f"Airlight: fog of frame {frame} baked in {seconds * 1000.0:.0f} ms -> {filepath}", flush=True)
    for note in render_notes(scene):
        if note == MOTION_BLUR_INTERACTIVE and sampled:
            continue  # (this bake sampled the shutter)
        print(f"Airlight: frame {frame}: {note}", flush=True)
    composite = ""
    if deferred is not None:
        try:
            seconds = prepared_seconds + compositor.fill(scene, deferred[0].passes)
            composite = f", compositor {1000.0 * seconds:.0f} ms (passes in memory)"
        except Exception as ex:  # e.g. no memory for the images: say so, never a stale frame's fog
            reason = f"cannot hand the passes to the compositor: {type(ex).__name__}: {ex}"
            print(f"Airlight: frame {frame} rendered without fog: {reason}", flush=True)
            _failed[scene.name] = (frame, reason)
            compositor.fill_neutral(scene)
    elif scene.airlight.auto_composite:
        t0 = time.perf_counter()
        compositor.sync(scene, filepath)
        composite = f", compositor {1000.0 * (time.perf_counter() - t0):.0f} ms"
    for line in stats.get(bake.LIGHT_NOTES, ()):
        print(f"Airlight: frame {frame}: {line}", flush=True)
    print(f"Airlight: frame {frame}: {bake.parts_line(stats)}{bake.fog_objects_line(stats)}{composite}", flush=True)


# Render engines whose start leaves a core idle for a while (each process compiles the
# shaders on one core, ~1 s with Mesa's llvmpipe), where a background render's bake runs
# beside them until the compositor needs it (_BakeBeside). Measured on 2 cores: a 1080p
# Workbench frame of the street 1.26x the fog-off time when baked first, 1.17x beside (10
# alternating runs); Cycles keeps both cores busy from its start, and was 0.7 s slower with
# the bake beside it (docs/performance.md).
IDLE_START_ENGINES = ("BLENDER_WORKBENCH", "BLENDER_EEVEE")


class _BakeBeside:
    """A background render's bake (its passes composited from memory) in a thread beside the
    render engine, whose start leaves a core idle (Workbench and EEVEE compile their shaders
    on one), and the frame's EXR written in that thread after it. The compositor announces
    itself in the main thread before it reads an image (render_stats): composite() waits
    there for the bake, making the images meanwhile, and fills them, or at render_post and
    render_cancel where nothing composites; end() waits for the EXR and says how it went.
    _yields_: the scene's engine is one of IDLE_START_ENGINES, and the thread (and the bake's
    threads, core/parallel.h) runs at the lowest priority (_yield_to_the_engine). Beside
    Cycles, which keeps both cores busy from its start, an EXR written at that priority waited
    for the render's end."""

    def __init__(self, scene, frame, jobs, export_seconds, sampled):
        self.scene_name, self.frame, self.sampled = scene.name, frame, sampled
        self.yields = scene.render.engine in IDLE_START_ENGINES
        self.jobs, self.export_seconds = jobs, export_seconds
        self.deferred, self.result, self.error, self.written = [], None, None, None
        self.baked = threading.Event()
        self.composited = False
        self.thread = threading.Thread(target=self._run, name="Airlight bake")
        self.thread.start()

    def _run(self):
        if self.yields:
            _yield_to_the_engine()
        try:
            self.result = bake.run_views(self.jobs, None, self.deferred)
        except Exception as ex:  # reported by composite(), in the main thread
            self.error = ex
        finally:
            self.baked.set()
        if self.error is None:
            self.written = cache.write_files(self.deferred)

    def composite(self):
        """Main thread: waits for the bake and hands it to the compositor (once)."""
        if self.composited:
            return
        self.composited = True
        scene = bpy.data.scenes.get(self.scene_name)
        t0 = time.perf_counter()
        try:
            # Here, not in render_pre: the engine starts sooner, and the bake often still runs.
            if scene is not None:
                compositor.make_images(scene)
        except Exception:  # (e.g. no memory: fill says so)
            pass
        prepared_seconds = time.perf_counter() - t0
        self.baked.wait()
        if scene is None:
            return
        try:
            if self.error is not None:
                raise self.error
            baked = bake.frame_baked(scene, self.jobs, self.export_seconds, *self.result)
        except Exception as ex:  # a handler must never take the render down
            _render_without_fog(scene, self.frame, ex, True)
            return
        _composite(scene, self.frame, baked, self.sampled, self.deferred, prepared_seconds)

    def end(self):
        """Main thread: the frame's pass files are whole; prints how their writing went."""
        self.composite()
        self.thread.join()
        if self.written is None:
            return
        seconds, error = self.written
        if error is not None:
            print(f"Airlight: frame {self.frame}: the fog passes were composited but not saved: {error}",
                  flush=True)
        else:
            print(f"Airlight: frame {self.frame}: EXR {1000.0 * seconds:.0f} ms beside the render -> "
                  f"{self.deferred[0].filepath}", flush=True)


def _yield_to_the_engine():
    """Lowers the calling thread's priority (Linux: per thread; it ends with the thread): the
    bake's own thread, and the threads the native bake starts from it (they inherit it:
    core/parallel.h), then give way to the render engine's threads where they contend for a
    core, and run at full speed where they do not (the main thread waiting for them)."""
    try:
        os.setpriority(os.PRIO_PROCESS, threading.get_native_id(), 19)
    except (AttributeError, OSError):
        pass


# The bake running beside the render (_BakeBeside), until the frame's render ends.
_beside = {"job": None}


def _end_beside():
    job, _beside["job"] = _beside["job"], None
    if job is not None:
        job.end()


@persistent
def on_render_stats(*_):
    """Render statistics, printed in the background; in the main thread the first are the
    compositor's, before it reads the passes' images (checked in Blender 3.4)."""
    job = _beside["job"]
    if job is not None and _in_main_thread():
        job.composite()


@persistent
def on_load_post(*_):
    """Un-mutes the fog nodes of loaded scenes whose fog is on (files hold them muted, so
    that a machine without the add-on renders them unfogged: compositor.on_save_pre), and
    completes them before anything renders, and for the window's scene the surface
    shading's light groups (a file saved before a light was added, or without the add-on).

    A render composites with the node links as they were when it started (before
    render_pre), so the pass links must already exist then (checked in Blender 3.4).
    """
    mesh_read.reads.clear()  # the last file's meshes
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
    (bpy.app.handlers.render_stats, on_render_stats),
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
