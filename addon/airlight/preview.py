"""Viewport preview of the homogeneous fog: a SpaceView3D draw handler that composites
the analytic airlight (the GLSL twin of the C++ kernel, shaders/sun05_airlight.glsl)
over the 3D viewport.

Per draw (POST_VIEW):
1. Scene depth at full resolution, as the linear distance Dvp along each view ray.
   'DRAWN' (default): the evaluated mesh triangles of the visible objects are drawn into
   the preview's own R32F target (shaders/preview_distance_*.glsl) with the region's
   matrices; one batch per object, cached and dropped on depsgraph updates that touch
   geometry and on frame changes. 'READBACK' (fallback for what the own pass does not
   draw, e.g. curves' bevel-free wires, point clouds, volumes): the region's depth is read
   back from the bound framebuffer and uploaded as window depth.
2. The fog (shaders/fog_preview_frag.glsl): per pixel the view ray from the region's
   matrices, clipped like Cycles and the bake clip it (`view_clip_range`: the fog
   begins on the near plane, t0 = clip_start / cos(angle to the view axis), and
   surfaces beyond the far plane are already missing from the depth), the airlight of
   lights the bake takes (preview_lights: the same scene_description and plan) over
   [t0, Dvp] by sun05_airlight and Tr = exp(-sigma_t (Dvp - t0)),
   premultiplied (rgb = airlight, alpha = 1 - Tr). At FULL scale
   it is drawn straight into the viewport; at HALF / QUARTER into a float offscreen of
   1/2 or 1/4 the size (airlight and surface distance), then
3. composited by a depth-aware upsampling pass (shaders/preview_upsample_frag.glsl:
   joint bilateral weights from the full-resolution depth, exact Tr per pixel, and a
   second draw that re-evaluates the airlight exactly where no low-resolution sample
   lies on the pixel's surface), with ALPHA_PREMULT blending: L = La + Tr L_scene.

Lifetime: GPU resources (shaders, batches, targets, F table texture) are built on the
first draw, kept in `_state`, and dropped on unregister and on file load (load_pre).
The draw handler is added in register(), removed in unregister() and on load_pre, and
added back on load_post; the depsgraph and frame handlers live exactly as long as the
add-on, so no handler ever leaks. Any error while drawing is kept, shown in the
sidebar panel, and stops further drawing until a setting changes; it never raises into
Blender's draw loop. `draw_fog` (the view-independent part) is used by the GPU tests and
the benchmark with depth they render themselves.
"""

import math
import textwrap
import threading
import time

import bpy
import gpu
import numpy as np
from bpy.app.handlers import persistent
from bpy.props import BoolProperty, EnumProperty
from gpu_extras.batch import batch_for_shader
from mathutils import Vector

from . import environment, fog_object, ies, mesh_read, model_choice, native, scene_description
from . import scene_export, visibility
from . import gpu_shaders as gs
from . import preview_gaussians as pg
from . import preview_shadows as ps

# Module state: the draw handler, GPU resources built lazily, and diagnostics.
_state = {
    "handle": None,
    "gpu": None,        # dict(shaders, batch, ftab, targets) once built
    "meshes": {},       # (object name, data name) -> GPUBatch of its evaluated triangles
    "instances": None,  # [(mesh key, model matrix)] of the visible geometry, or None
    "casters": None,    # [(mesh key, model matrix)] of the shadow casters, or None
    "shadow_dropped": 0,  # shadowed lights past preview_shadows.MAX_SHADOW_MAPS (panel)
    "shadow_error": None,  # why the shadow maps could not be drawn (panel), or None
    "generation": 0,    # bumped on every depsgraph update and frame change
    "error": None,      # last draw error (str); drawing pauses while set
    "last_ms": None,    # duration of the last fog draw in milliseconds (CPU side)
    "last_depth_ms": None,  # of which the scene depth (own pass or read-back + upload)
    "draws": 0,         # number of fog passes drawn (tests read it)
    "capture": None,    # tests: set to {} and the next draw stores its inputs there
    "gaussians": None,  # fog objects' Gaussians (dict, see draw_fog) of one generation
    "environment": None,  # (key, scene_environment's value): the World's glow map
    "lights": None,     # (key, preview_lights' value) of one generation and fog settings
    "problem": None,    # why the bake (and so the preview) refuses the scene, or None
}

MAX_LIGHTS = 256

# Resolution scales of the fog pass: enum identifier -> full-resolution pixels per texel.
SCALES = {'FULL': 1, 'HALF': 2, 'QUARTER': 4, 'EIGHTH': 8}
# Volumetric shadows: steps per shadowed light along each view ray (enum identifier ->
# steps; tests/gpu/test_preview_shadows.py measures the error against the bake).
SHADOW_STEPS = {'FAST': 16, 'MEDIUM': 32, 'FINE': 64}
# Upsampling modes of preview_upsample_frag.glsl.
UPSAMPLE_BILINEAR, UPSAMPLE_BILATERAL, UPSAMPLE_BILATERAL_EXACT = 0, 1, 2
# Format of the reduced fog target: rgb = airlight (can exceed 1), a = surface distance
# (inf where nothing is hit), which the upsampling compares at full float precision.
LOWRES_FORMAT = 'RGBA32F'


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


def _phase_inputs(res, phase):
    """((kind, g, K, k), Gtab texture) for biri06_airlight.glsl: the bake's own Biri 2006
    table of _phase_ = (name, g), uploaded once per (name, g); the F table stands in as
    Gtab for the isotropic phase (the shader does not read it then)."""
    name, g = phase[0], float(phase[1])
    if name == "isotropic":
        return (0.0, 0.0, 1.0, 1.0), res["ftab"]
    kinds = {"hg": 1, "rayleigh": 2, "hazy_mie": 3, "murky_mie": 4}
    key = (name, g)
    cached = res.get("gtab")
    if cached is None or cached[0] != key:
        table = _native_for_preview().biri06_table(name, g)
        vec = (float(kinds[table["phase"]]), float(table["g"]), float(table["K"]), float(table["k"]))
        cached = res["gtab"] = (key, vec, gs.float_texture(table["data"]))
    return cached[1], cached[2]


def _gpu_resources():
    """Builds (once) the quad and the F table texture; shaders are built on first use."""
    res = _state["gpu"]
    if res is None:
        module = _native_for_preview()
        if module is None:
            raise RuntimeError(_missing_reason())
        ftab, _table = gs.f_table_texture(module)
        res = _state["gpu"] = dict(shaders={}, batch=None, ftab=ftab, targets={})
    return res


def _shader(kind, window_depth, variant=False, phase=False, spots=False, suns=False, env=False,
            shadows=False):
    """Fog ('fog'; variant: the reduced target's output, airlight + distance, or
    ('gauss', scale): with the Gaussian sums), upsampling ('upsample'; variant: 'mark' =
    blend and mark the pixels to re-evaluate in the depth buffer, 'exact' = the
    re-evaluation draw) or 'composite' shader, reading window depth or distance;
    phase: the homogeneous airlight through the Biri 2006 table of a non-isotropic phase
    function (biri06_airlight.glsl) instead of Sun 2005; spots: with the spot-light loop
    (spot_airlight.glsl); suns: with the sun-lamp loop (sun_airlight.glsl); env: with the
    World's glow where rays meet no surface (preview_common.glsl preview_env); shadows: 0, or
    the steps per ray (SHADOW_STEPS) of the shadowed lights' march through their shadow maps
    (shadow_maps.glsl; a spot takes steps / 8 panels of its quadrature)."""
    res = _gpu_resources()
    key = (kind, bool(window_depth), variant, bool(phase), bool(spots), bool(suns), bool(env),
           int(shadows))
    shader = res["shaders"].get(key)
    if shader is None:
        frag, defines = {
            'fog': ("fog_preview_frag.glsl", (("PREVIEW_LOWRES", int(variant is True)),
                                              ("PREVIEW_GAUSSIANS", int(isinstance(variant, tuple))),
                                              ("PREVIEW_GAUSS_SCALE",
                                               variant[1] if isinstance(variant, tuple) else 1))),
            'upsample': ("preview_upsample_frag.glsl",
                         (("PREVIEW_EXACT_PASS", int(variant == 'exact')),
                          ("PREVIEW_MARK", int(variant == 'mark')))),
            'composite': ("preview_composite_frag.glsl", ()),
        }[kind]
        shader = gs.create_preview_shader(
            f"preview_{kind}", frag,
            defines=(("PREVIEW_WINDOW_DEPTH", int(bool(window_depth))),
                     ("PREVIEW_PHASE", int(bool(phase))),
                     ("PREVIEW_SPOTS", int(bool(spots))),
                     ("PREVIEW_SUNS", int(bool(suns))),
                     ("PREVIEW_ENV", int(bool(env))),
                     ("PREVIEW_SHADOWS", int(bool(shadows))),
                     ("SHADOW_STEPS", max(8, int(shadows))),
                     ("SPOT_SHADOW_PANELS", max(1, int(shadows) // 8)),
                     ("SHADOW_RES", ps.SHADOW_RES)) + defines
            + ((("PREVIEW_GAUSSIANS", 0),) if kind != 'fog' else ()))
        res["shaders"][key] = shader
        if res["batch"] is None:
            res["batch"] = gs.fullscreen_batch(shader)
    return shader


def _target(name, width, height, fmt, depth=False):
    """Cached textures (one colour, optionally a depth one) of this size.

    Textures are shared between Blender's GPU contexts (one per window), framebuffers
    are not: a framebuffer made while drawing one window cannot be bound in another, so
    `_framebuffer` wraps the textures anew for each use (cheap)."""
    res = _gpu_resources()
    entry = res["targets"].get(name)
    if entry is None or entry["size"] != (width, height):
        colour = gpu.types.GPUTexture((width, height), format=fmt)
        depth_tex = gpu.types.GPUTexture((width, height), format='DEPTH_COMPONENT32F') if depth else None
        entry = res["targets"][name] = dict(size=(width, height), colour=colour,
                                            depth=depth_tex)
    return entry


def _framebuffer(target):
    return gpu.types.GPUFrameBuffer(depth_slot=target["depth"], color_slots=(target["colour"],))


def free_gpu_resources():
    _state["gpu"] = None
    _state["gaussians"] = _state["environment"] = _state["lights"] = None
    pg.clear_cache()
    _state["meshes"] = {}
    _state["instances"] = _state["casters"] = None


# ---- the preview's own scene depth ---------------------------------------------------

def _mesh_key(obj_eval):
    data = getattr(obj_eval, "data", None)
    return (obj_eval.name, data.name if data is not None else "")


def _visible_instances(depsgraph, view_layer):
    """[(key, object, matrix)] of the geometry the viewport shows (solid objects whose
    source is visible in the view layer), from the evaluated depsgraph's instances."""
    out = []
    for instance in depsgraph.object_instances:
        obj = instance.object
        if obj.type not in scene_description.GEOMETRY_TYPES:
            continue
        source = instance.parent if instance.is_instance else obj
        if source is None:
            continue
        try:
            if not source.original.visible_get(view_layer=view_layer):
                continue
        except (RuntimeError, TypeError):
            continue
        if obj.display_type in {'BOUNDS', 'WIRE'} or not getattr(instance, "show_self", True):
            continue
        out.append((_mesh_key(obj), obj, instance.matrix_world.copy()))
    return out


def _distance_shader():
    res = _gpu_resources()
    if res.get("distance_shader") is None:
        res["distance_shader"] = gs.create_distance_shader()
    return res["distance_shader"]


def _batches(items):
    """[(batch, model matrix)] of [(mesh key, evaluated object, matrix)]: each mesh's batch
    built on demand and kept until a depsgraph update touches its geometry (or the frame
    changes); objects without triangles are left out."""
    shader = _distance_shader()
    out = []
    for key, obj, matrix in items:
        batch = _state["meshes"].get(key)
        if batch is None:
            arrays = mesh_read.mesh_arrays(obj)
            if arrays is None:
                continue
            verts, tris = arrays
            batch = batch_for_shader(shader, 'TRIS', {"pos": verts}, indices=tris.astype("int32"))
            _state["meshes"][key] = batch
        out.append((batch, matrix))
    return out


def _scene_instances(context):
    """[(batch, model matrix)] of the visible geometry (`_batches`), listed once per
    depsgraph generation."""
    instances = _state["instances"]
    if instances is None:
        depsgraph = context.evaluated_depsgraph_get()
        instances = _state["instances"] = _batches(_visible_instances(depsgraph, context.view_layer))
    return instances


def _caster_instances(context):
    """[(batch, model matrix)] of the shadow casters the bake ray-casts: render-visible
    geometry with Ray Visibility > Shadow on, fog objects excepted
    (scene_description.export_instances), listed once per depsgraph generation."""
    casters = _state["casters"]
    if casters is None:
        depsgraph = context.evaluated_depsgraph_get()
        visible = visibility.RenderVisibility(depsgraph.view_layer)
        items = []
        for instance in depsgraph.object_instances:
            obj = instance.object
            source = instance.parent if instance.is_instance else obj
            if (obj.type not in scene_description.GEOMETRY_TYPES or source is None or not visible(source)
                    or not getattr(obj, "visible_shadow", True) or fog_object.is_fog_object(obj)):
                continue
            items.append((_mesh_key(obj), obj, instance.matrix_world.copy()))
        casters = _state["casters"] = _batches(items)
    return casters


def scene_shadows(lights, casters, generation):
    """draw_fog's _shadows_ for preview_lights' value _lights_ and the casters' [(batch,
    model matrix)] (or a callable returning them, called only when a light is shadowed:
    `_caster_instances`; tests pass their own), or None when the bake shadows none of its
    lights. The maps are drawn again only when _generation_ (any
    hashable: the depsgraph generation), the shadowed lights or the casters' box change.
    Shadowed lights past preview_shadows.MAX_SHADOW_MAPS stay unshadowed
    (_state["shadow_dropped"] counts them for the panel)."""
    requests, points, spots, suns, dropped = ps.requests_of(lights)
    _state["shadow_dropped"] = dropped
    box = lights["shadows"]["box"]
    if not requests or box is None:
        return None
    res = _gpu_resources()
    maps = res.get("shadow_maps")
    if maps is None:
        maps = res["shadow_maps"] = ps.ShadowMaps()
    key = (generation, tuple(requests), tuple(map(tuple, box)))
    maps.update(key, requests, box, casters, _distance_shader())
    return dict(maps=maps.maps, info=maps.info, points=points, spots=spots, suns=suns)


def _view_axis(perspective_matrix):
    """(dir, offset) with distance-from-near-plane = dot(p, dir) + offset (orthographic)."""
    inv = perspective_matrix.inverted()

    def unproject(z):
        p = inv @ Vector((0.0, 0.0, z, 1.0))
        return p.xyz / p.w
    near, far = unproject(-1.0), unproject(1.0)
    axis = (far - near).normalized()
    return axis, -axis.dot(near)


def draw_distance(context, *, perspective_matrix, view_origin, is_perspective, size):
    """Draws the visible geometry's linear distance (inf = nothing) into the preview's
    R32F distance target of _size_ and returns that texture. Restores the viewport and
    depth state; the caller's framebuffer is bound again afterwards."""
    w, h = size
    target = _target("distance", w, h, 'R32F', depth=True)
    instances = _scene_instances(context)
    shader = _distance_shader()
    axis, offset = _view_axis(perspective_matrix)
    with gs.preserved_state():
        fb = _framebuffer(target)
        with fb.bind():
            gpu.state.viewport_set(0, 0, w, h)
            gs.start_distances(fb, shader)
            gs.draw_distances(shader, perspective_matrix, (*view_origin, 1.0 if is_perspective else 0.0),
                              (*axis, offset), instances)
    return target["colour"]


@persistent
def _on_depsgraph_update(scene, depsgraph):
    """Drops the instance list on any update and the batches whose geometry changed."""
    _state["generation"] += 1
    _state["instances"] = _state["casters"] = None
    meshes = _state["meshes"]
    if not meshes:
        return
    for update in depsgraph.updates:
        if not update.is_updated_geometry:
            continue
        name = getattr(update.id, "name", None)
        for key in [k for k in meshes if k[0] == name or k[1] == name]:
            del meshes[key]


@persistent
def _on_frame_change(*_args):
    """Animated geometry (modifiers, shape keys) may differ on the new frame.

    Interactive renders call the frame handlers from the render thread for the render's
    own depsgraph: nothing of the viewport changed then, and the cached batches (GPU
    objects) must not be released from that thread. Blender sets the UI's frame again in
    the main thread when the render ends, which comes here."""
    if threading.current_thread() is not threading.main_thread():
        return
    _state["generation"] += 1
    _state["instances"] = _state["casters"] = None
    _state["meshes"] = {}


def scene_gaussians(context):
    """World-space Gaussians of the render-visible fog objects (what the bake gets) as
    draw_fog's _gaussians_ dict, gathered once per depsgraph generation (a depsgraph
    update or frame change starts a new one). Invalid fog objects raise ValueError."""
    cached = _state["gaussians"]
    if cached is None or cached["key"] != _state["generation"]:
        gathered = scene_description.fog_gaussians(context.evaluated_depsgraph_get())
        centres, scales, amplitudes = gathered
        colors = gathered.get("colors") if hasattr(gathered, "get") else None
        cached = _state["gaussians"] = dict(centres=centres, scales=scales,
                                            amplitudes=amplitudes, colors=colors,
                                            key=_state["generation"])
    return cached


def preview_lights(scene, depsgraph):
    """The lights the bake takes, as draw_fog's inputs: those of scene_export.light_arguments
    for the scene's scene_description and model_choice plan (lights inside collection
    instances included, Automatic's skipped lights left out, no points or spots in the
    daylight model), MAX_LIGHTS of each kind at most. dict: positions and intensities
    (albedo * I0) of the point lights and their bare I0 (lists of 3-tuples), their radii; spots
    (positions, axes, intensities = albedo * I0, sizes, blends); suns (directions,
    irradiances = albedo * E, fog_top: inf without Fog Top); shadows (points, spots, suns:
    whether the bake shadows each, scene_export.shadow_arguments; box: the shadow casters'
    union bounding box (lo, hi), None without casters). Cached per depsgraph
    generation and fog settings (read only: scene_lights and co. give copies); raises
    scene_description.ExportError where the bake does."""
    settings = scene.airlight
    key = (_state["generation"], scene.name, depsgraph.view_layer.name, scene.frame_current,
           getattr(scene.camera, "name", None), float(settings.density), tuple(settings.color),
           settings.model, float(settings.accuracy), settings.phase, float(settings.anisotropy),
           bool(settings.use_fog_top), float(settings.fog_top), settings.table_resolution,
           settings.table_interpolation, bool(settings.volumetric_shadows))
    cached = _state["lights"]
    if cached is not None and cached[0] == key:
        return cached[1]
    description = scene_description.describe(scene, depsgraph, bake=False)
    plan = model_choice.plan(settings, description.survey)
    lights = scene_export.light_arguments(description, plan)
    shadowed = scene_export.shadow_arguments(description, plan)
    _profiles_as_points(lights, shadowed)
    albedo = np.asarray(settings.color, dtype=np.float64)

    def rows(name, scale=1.0):
        return [tuple(row) for row in (scale * lights[name][:MAX_LIGHTS]).tolist()] if name in lights else []

    def flags(name):
        return [bool(v) for v in shadowed.get(name, ())[:MAX_LIGHTS]]
    n_points = len(lights["light_positions"])
    value = dict(positions=rows("light_positions"), intensities=rows("light_intensities", albedo),
                 I0=rows("light_intensities"),
                 radii=[float(r) for r in lights.get("light_radii", np.zeros(n_points))[:MAX_LIGHTS]],
                 spots=dict(positions=rows("spot_positions"), axes=rows("spot_axes"),
                            intensities=rows("spot_intensities", albedo),
                            sizes=[float(v) for v in lights.get("spot_size", ())[:MAX_LIGHTS]],
                            blends=[float(v) for v in lights.get("spot_blend", ())[:MAX_LIGHTS]],
                            spreads=[float(v) for v in lights.get("spot_spread", ())[:MAX_LIGHTS]],
                            radii=[float(v) for v in lights.get("spot_radii", ())[:MAX_LIGHTS]]),
                 suns=dict(directions=rows("sun_directions"), irradiances=rows("sun_irradiances", albedo),
                           fog_top=description.fog_top),
                 shadows=dict(points=flags("light_shadows"), spots=flags("spot_shadows"),
                              suns=flags("sun_shadows"), box=ps.union_box(description.survey.casters)))
    _state["lights"] = (key, value)
    return value


def _profiles_as_points(lights, shadowed):
    """The preview draws a point light with an IES profile (a spot row with spot_profiles) as
    a point light of the profile's mean intensity over the sphere, and a spot light with one
    (spot_profile_in_cone) as its spot scaled by the profile's mean over the cone, weighted by
    the cone's factor (the panel says so): moves the point lights' rows of _lights_ (and their
    shadow flags in _shadowed_) to the point lights, and scales the spots', in place."""
    profiles = lights.pop("spot_profiles", None)
    in_cone = np.asarray(lights.pop("spot_profile_in_cone", np.zeros(0)), dtype=bool)
    extent = np.asarray(lights.pop("spot_profile_extent", np.zeros(0)), dtype=np.float64)
    if profiles is None:
        return
    if len(in_cone) != len(profiles):
        in_cone = np.zeros(len(profiles), dtype=bool)
    if len(extent) != len(profiles):
        extent = np.full(len(profiles), math.pi)
    profiled = np.any(profiles != 0.0, axis=1) & ~in_cone
    mean = np.ones(len(profiles))   # the spots' scale, the points' mean intensity over the sphere
    for row in np.nonzero(in_cone | profiled)[0]:
        size = 2.0 * float(extent[row]) if profiled[row] else float(lights["spot_size"][row])
        c = np.linspace(max(-1.0, math.cos(0.5 * size)), 1.0, 513)
        lit = np.maximum(np.polynomial.polynomial.polyval(c, profiles[row]), 0.0)
        if profiled[row]:
            mean[row] = float(lit.mean() * (1.0 - c[0]) / 2.0)
        else:
            w = ies.cone_factor(c, size, float(lights["spot_blend"][row]))
            mean[row] = float((lit * w).sum() / max(w.sum(), 1e-300))
    lights["spot_intensities"] = np.asarray(lights["spot_intensities"]) * np.where(in_cone, mean, 1.0)[:, None]
    if "light_radii" in lights or "spot_radii" in lights:
        points = np.asarray(lights.get("light_radii", np.zeros(len(lights["light_positions"]))))
        spots = np.asarray(lights.get("spot_radii", np.zeros(len(profiles))))
        lights["light_radii"] = np.concatenate([points, spots[profiled]])
    lights["light_positions"] = np.concatenate([lights["light_positions"], lights["spot_positions"][profiled]])
    lights["light_intensities"] = np.concatenate([lights["light_intensities"],
                                                  lights["spot_intensities"][profiled] * mean[profiled, None]])
    if "spot_shadows" in shadowed:
        points = shadowed.get("light_shadows", np.zeros(len(lights["light_positions"]) - profiled.sum()))
        shadowed["light_shadows"] = np.concatenate([points, shadowed["spot_shadows"][profiled]])
        shadowed["spot_shadows"] = shadowed["spot_shadows"][~profiled]
    for key in [k for k in lights if k.startswith("spot_")]:
        lights[key] = np.asarray(lights[key])[~profiled]
    if not len(lights["spot_positions"]):
        for key in [k for k in lights if k.startswith("spot_")]:
            del lights[key]


def _depsgraph(view_layer):
    if view_layer is None or view_layer == bpy.context.view_layer:
        return bpy.context.evaluated_depsgraph_get()
    return view_layer.depsgraph


def scene_lights(scene, view_layer=None, with_albedo=True):
    """(positions, intensities) of preview_lights' point lights: intensity = albedo * I0 (the
    bake's I0 times the fog albedo; with_albedo=False: the bake's I0 alone, which Gaussians
    with their own colours multiply by theirs). _view_layer_: the context's by default."""
    lights = preview_lights(scene, _depsgraph(view_layer))
    return list(lights["positions"]), list(lights["intensities" if with_albedo else "I0"])


def scene_spots(scene, view_layer=None):
    """preview_lights' spot lights: draw_fog's _spots_ dict (the bake's spot_* values)."""
    return {k: list(v) for k, v in preview_lights(scene, _depsgraph(view_layer))["spots"].items()}


def scene_suns(scene, view_layer=None):
    """preview_lights' sun lamps: draw_fog's _suns_ dict (the bake's sun_* values)."""
    suns = preview_lights(scene, _depsgraph(view_layer))["suns"]
    return dict(suns, directions=list(suns["directions"]), irradiances=list(suns["irradiances"]))


def _rows_of(shadow_rows, n):
    """(n,) shadow-map rows (-1: unshadowed) from _shadow_rows_ (None: all -1)."""
    out = np.full(n, -1.0, np.float32)
    if shadow_rows is not None:
        out[:min(n, len(shadow_rows))] = shadow_rows[:n]
    return out


def _suns_texture(suns, shadow_rows=None):
    """RGBA32F, sun_count x 2 (sun_airlight.glsl via preview_common.glsl): row 0 =
    (direction, fog top), row 1 = (albedo E, shadow-map row or -1)."""
    n = 0 if suns is None else len(suns["directions"])
    data = np.zeros((2, max(1, n), 4), np.float32)
    data[1, :, 3] = _rows_of(shadow_rows, max(1, n))
    if n:
        w = np.asarray(suns["directions"], np.float64)
        data[0, :n, :3] = w / np.linalg.norm(w, axis=1, keepdims=True)
        data[0, :n, 3] = suns["fog_top"]
        data[1, :n, :3] = suns["irradiances"]
    return gs.float_texture(data)


def _spots_texture(spots, shadow_rows=None):
    """RGBA32F, spot_count x 4 (spot_airlight.glsl via preview_common.glsl): row 0 =
    (position, cos(size / 2)), row 1 = (axis, (1 - cos(size / 2)) blend), row 2 = (albedo
    I0, shadow-map row or -1), row 3 = (spread_a, spread_b, Radius, 0): an area light's Spread
    (the profile constants from `_native.spot_cone`) and the spot's Radius (_spots_' optional
    radii; 0: a point)."""
    n = 0 if spots is None else len(spots["positions"])
    data = np.zeros((4, max(1, n), 4), np.float32)
    data[2, :, 3] = _rows_of(shadow_rows, max(1, n))
    data[3, :, 0] = 1.0
    if n:
        data[0, :n, :3] = spots["positions"]
        axes = np.asarray(spots["axes"], np.float64)
        data[1, :n, :3] = axes / np.linalg.norm(axes, axis=1, keepdims=True)
        data[2, :n, :3] = spots["intensities"]
        spreads = list(spots.get("spreads", ())) + [math.pi] * n
        radii = list(spots.get("radii", ())) + [0.0] * n
        data[3, :n, 2] = radii[:n]
        module = native.get()
        for i in range(n):
            cos_half, smooth, a, b = module.spot_cone(spots["sizes"][i], spots["blends"][i], spreads[i])
            data[0, i, 3], data[1, i, 3], data[3, i, :2] = cos_half, smooth, (a, b)
    return gs.float_texture(data)


def _environment_texture(res, environment):
    """(GPU texture of the glow map, World transmittance); a 1x1 black texture when off
    (every preview shader declares the sampler)."""
    if environment is None:
        tex = res.get("env_off")
        if tex is None:
            tex = res["env_off"] = gs.float_texture(np.zeros((1, 1, 4), np.float32))
        return tex, 0.0
    glow = np.asarray(environment["glow"], dtype=np.float32)
    rgba = np.concatenate([glow, np.ones(glow.shape[:2] + (1,), np.float32)], axis=2)
    return gs.float_texture(rgba), float(environment["transmittance"])


def scene_environment(scene):
    """draw_fog's _environment_ for the scene: None when Environment Glow is off or the World
    emits nothing, else dict(glow, transmittance) from the same native convolution the bake
    uses (environment.py). Cached on the World's data and the fog settings it depends on
    (the convolution costs ~0.1-0.3 s); a World the glow cannot read raises WorldMapError."""
    settings = scene.airlight
    if not settings.environment_glow or scene.world is None:
        return None
    source = environment.world_source(scene)
    if source is None:
        return None
    key = (scene.world.name, repr(source[1]) if source[0] == 'COLOR' else
           (source[1].name, source[1].is_dirty, tuple(source[1].size), source[2]),
           float(settings.density), tuple(settings.color), float(settings.environment_distance),
           int(settings.environment_sh_order), _state["generation"] if source[0] == 'IMAGE' else 0)
    cached = _state.get("environment")
    if cached is not None and cached[0] == key:
        return cached[1]
    world = environment.world_map(scene)
    if world is None:
        value = None
    else:
        fog = native.get().environment_fog(
            world=world, sigma_t=float(settings.density), distance=float(settings.environment_distance),
            albedo=np.asarray(settings.color, dtype=np.float64), sh_order=int(settings.environment_sh_order),
            out_width=256, out_height=128, kind="exact")
        value = dict(glow=fog["glow"], transmittance=fog["transmittance"])
    _state["environment"] = (key, value)
    return value


def _lights_texture(positions, intensities, Csv=None, splat_I0=None, shadow_rows=None, radii=None):
    """Row 0: xyz = positions, w = the lights' Radius (_radii_; None: 0); row 1: rgb = albedo I0, a = C_sv (Gaussian fog transmittance
    light -> eye, 1 without fog objects); row 2: rgb = the I0 the Gaussian fog's splat
    multiplies by each Gaussian's albedo texel (rbf_splat_pixel.glsl): _splat_I0_ (the
    bare I0 when the Gaussians have their own colours), else albedo I0 again; a = the
    light's shadow-map row (-1: unshadowed)."""
    n = max(1, len(positions))
    data = np.zeros((3, n, 4), np.float32)
    data[1, :, 3] = 1.0
    data[2, :, 3] = _rows_of(shadow_rows, n)
    if positions:
        data[0, :len(positions), :3] = positions
        if radii is not None:
            data[0, :len(positions), 3] = radii
        data[1, :len(positions), :3] = intensities
        data[2, :len(positions), :3] = intensities if splat_I0 is None else splat_I0
        if Csv is not None:
            data[1, :len(positions), 3] = Csv
    return gs.float_texture(data)


# How the Gaussian fog's per-pixel sums are drawn: 'TILES' (one full-screen pass looping
# over per-tile Gaussian lists, rbf_tiles_frag.glsl) or 'SPLAT' (one blended quad per
# Gaussian, rbf_splat_*.glsl). Both give the same sums (tests/gpu/test_preview_gaussians.py).
GAUSS_PASSES = ('TILES', 'SPLAT')
GAUSS_PASS = 'TILES'
# Whether the Gaussian passes evaluate each Gaussian's fitted light factor per pixel
# (rbf_light_fit_frag.glsl, one GPU pass per draw before the sums) instead of the exact
# per-light terms: issue 5's speed-up; Gaussians with a light within
# gpu_shaders.RBF_FIT_NEAR cull radii or denser than RBF_FIT_MAX_T stay exact.
LIGHT_FIT = True


def _gaussian_fog(res, *, gaussians, window_depth, sigma_t, view_origin, light_positions,
                  gauss_pass, light_fit=False, noise=True, shadows=False):
    """The splat or tile shader and the current GaussianFog (textures, batch, factors)
    for these inputs (preview_gaussians.py; rebuilt only when one changes; _noise_:
    whether the draw uses the noise, see GaussianFog.update; _shadows_: the variants whose
    light terms take the lights' visibility from the shadow maps)."""
    key = (gauss_pass.lower(), bool(window_depth), bool(light_fit)) + (("shadows",) if shadows else ())
    shader = res["shaders"].get(key)
    if shader is None:
        create = gs.create_rbf_tiles_shader if gauss_pass == 'TILES' else gs.create_rbf_splat_shader
        shader = res["shaders"][key] = create(window_depth, light_fit=bool(light_fit), shadows=bool(shadows))
    fit_key = "rbf_light_fit_shadows" if shadows else "rbf_light_fit"
    if light_fit and res["shaders"].get(fit_key) is None:
        res["shaders"][fit_key] = gs.create_rbf_light_fit_shader(shadows=bool(shadows))
    fog = res.get("gaussian_fog")
    if fog is None:
        fog = res["gaussian_fog"] = pg.GaussianFog()
    fog.update(_native_for_preview(), shader if gauss_pass == 'SPLAT' else None, gaussians,
               sigma_t, view_origin, light_positions, noise=bool(noise))
    if gauss_pass == 'TILES' and fog.tiles_batch is None:
        fog.tiles_batch = gs.fullscreen_batch(shader)
    fit = res["shaders"].get(fit_key) if light_fit else None
    if fit is not None and fog.fit_batch is None:
        fog.fit_batch = gs.fullscreen_batch(fit)
    return shader, fog, gauss_pass, fit


def _fit_lights(fit, fog, size, bind):
    """The light-fit pass (rbf_light_fit_frag.glsl) into fog.light_tex: per Gaussian the
    fitted light factor the Gaussian passes read as gauss_light. Run every draw: it depends
    on f1 and the lights' intensities, and costs one fragment per (Gaussian, row)."""
    w, h = size
    if fog.light_tex is None or fog.light_tex_count != fog.count:
        fog.light_tex = gs.rbf_light_fit_texture(fog.count)
        fog.light_tex_count = fog.count
    fb = gpu.types.GPUFrameBuffer(color_slots=(fog.light_tex,))
    with fb.bind():
        gpu.state.viewport_set(0, 0, fog.light_tex.width, fog.light_tex.height)
        gpu.state.blend_set('NONE')
        bind(fit, (0, 0, w, h), None, pass_scale=1)
        fit.uniform_sampler("gauss", fog.gauss_tex)
        fit.uniform_sampler("gauss_f1", fog.f1_tex)
        fog.fit_batch.draw(fit)


def _draw_gaussians(shader, fog, gauss_pass, fit, size, scale, bind):
    """The Gaussian fog's sums into two RGBA32F targets of 1/_scale_ the region: 'SPLAT'
    clears them and adds one quad per Gaussian (ADDITIVE_PREMULT); 'TILES' writes every
    texel once from its tile's Gaussian list (no blending; the lists made current by
    fog.update_tiles). With _fit_ (the light-fit shader) its pass runs first and the
    passes read its output. Returns (acc, near) textures. The caller restores gpu.state."""
    w, h = size
    if fit is not None:
        _fit_lights(fit, fog, size, bind)
    lw, lh = -(-w // scale), -(-h // scale)
    acc = _target("gauss_acc", lw, lh, 'RGBA32F')
    near = _target("gauss_near", lw, lh, 'RGBA32F')
    fb = gpu.types.GPUFrameBuffer(color_slots=(acc["colour"], near["colour"]))
    with fb.bind():
        gpu.state.viewport_set(0, 0, lw, lh)
        bind(shader, (0, 0, w, h), None, pass_scale=scale)
        shader.uniform_sampler("gauss", fog.gauss_tex)
        shader.uniform_sampler("gauss_f1", fog.f1_tex)
        if fit is not None:
            shader.uniform_sampler("gauss_light", fog.light_tex)
        if gauss_pass == 'TILES':
            gpu.state.blend_set('NONE')
            shader.uniform_sampler("tile_index", fog.tile_tex[0])
            shader.uniform_sampler("tile_list", fog.tile_tex[1])
            fog.tiles_batch.draw(shader)
        else:
            fb.clear(color=(0.0, 0.0, 0.0, 0.0))
            gpu.state.blend_set('ADDITIVE_PREMULT')
            fog.batch.draw(shader)
    return acc["colour"], near["colour"]


def view_axis(perspective_matrix):
    """Unit view direction (world) of a perspective _perspective_matrix_ (projection @
    view): its last row is -(the view matrix's z row), i.e. the camera's -Z axis, for any
    lens shift. Orthographic matrices have no such row; their rays need none."""
    row = perspective_matrix.row[3].xyz
    return row.normalized() if row.length > 0.0 else Vector((0.0, 0.0, -1.0))


def view_clip_range(context):
    """(clip_start, clip_end) of what the 3D viewport of _context_ shows: the scene
    camera's in camera view (region_data.view_perspective == 'CAMERA'), else the
    viewport's own (space_data.clip_start / clip_end). The region's projection matrix
    is built from the same values, so its near plane is at view-axis depth clip_start in
    perspective views. Orthographic user views are centred on the view: Blender (and
    Cycles' viewport render) put their near plane at -clip_end / 2 and their far plane at
    +clip_end / 2, and the preview's orthographic rays start on that projected near plane
    anyway (tests/gpu/test_preview_clip_range.py checks both)."""
    rv3d, space = context.region_data, context.space_data
    camera = context.scene.camera
    if (rv3d is not None and rv3d.view_perspective == 'CAMERA' and camera is not None
            and camera.type == 'CAMERA'):
        data = camera.evaluated_get(context.evaluated_depsgraph_get()).data
        return float(data.clip_start), float(data.clip_end)
    if rv3d is not None and not rv3d.is_perspective:
        half = 0.5 * float(space.clip_end)
        return -half, half
    return float(space.clip_start), float(space.clip_end)


def draw_fog(*, depth_tex, perspective_matrix, view_origin, is_perspective, viewport,
             sigma_t, light_positions, light_intensities, clip_start=0.0, window_depth=True,
             scale=1, mode=UPSAMPLE_BILATERAL_EXACT, gaussians=None, phase=("isotropic", 0.0),
             spots=None, suns=None, environment=None, light_I0=None, noise=None, gauss_pass=None,
             light_fit=None, shadows=None, light_radii=None):
    """Draws the fog over the bound framebuffer with premultiplied blending.

    depth_tex: full-resolution R32F texture of the region (viewport[2] x viewport[3]):
    window depth in [0, 1] (window_depth=True) or linear distance Dvp, inf = nothing
    (window_depth=False); perspective_matrix: mathutils.Matrix, projection @ view;
    view_origin: 3 floats; viewport: (x, y, width, height) of the region in the
    framebuffer; clip_start: view-axis depth of the near clip plane (`view_clip_range`),
    where the fog begins as in Cycles and the bake (perspective only: orthographic rays
    start on the projection's near plane; surfaces beyond the far plane are already
    missing from the depth); scale: 1 draws the fog directly, 2 or 4 evaluate it in a
    float offscreen of 1/scale the size and upsample it (mode: UPSAMPLE_*).
    gaussians: None, or dict(centres (n, 3), scales (n,), amplitudes (n,), key, and
    optionally colors: None or (n, 3) per-Gaussian albedo) of the fog objects'
    world-space Gaussians (key: any hashable that changes with the arrays); with n > 0
    the Gaussian fog's sums are drawn first (preview_gaussians.py; _gauss_pass_ 'TILES'
    or 'SPLAT', default GAUSS_PASS; _light_fit_ None = LIGHT_FIT: per-Gaussian fitted
    light factors instead of the exact light terms per pixel) at 1/scale of the resolution
    (scale 1, 2, 4 or 8), and the fog pass runs
    at full resolution, upsampling the Gaussian sums depth-aware (fog_preview_frag.glsl
    preview_gauss_fetch).
    light_radii: None, or each point light's Radius (m, `preview_lights`' radii): the glow of
    Cycles' disk light near it, as the bake takes it (preview_common.glsl
    preview_light_size_excess); ignored with fog objects, whose bake takes lights as points.
    light_I0: the point lights' I0 without the fog's albedo (`scene_lights(...,
    with_albedo=False)`), required when the Gaussians have colours (their own albedo
    replaces the fog's, as in the bake).
    noise: None or (amplitude, scale, offset (3)) of the Gaussian fog's noise (Fogshop
    section 5.5, scene.airlight.noise_*; amplitude 0 = off), as the bake's.
    phase: (name, g) of the fog's phase function as `model_choice.native_phase` gives it
    for the bake; other than isotropic, the homogeneous airlight uses the Biri 2006 table
    of that phase (the bake's "biri06" model). The Gaussian terms stay isotropic (the
    bake refuses anisotropic Gaussian fog).
    spots: None or `scene_spots`' dict (positions, axes, intensities = albedo I0, sizes,
    blends, optional spreads and radii): spot lights by a fixed quadrature over the ray's part
    inside each cone (spot_airlight.glsl), a Radius as light_radii's.
    suns: None or `scene_suns`' dict (directions, irradiances = albedo E, fog_top): sun
    lamps by the closed form of the bake's sunlight_layer.h (sun_airlight.glsl).
    environment: None or `scene_environment`'s dict (glow = the World's airlight as an
    equirectangular (h, w, 3) map, albedo included; transmittance = e^(-sigma_t distance)):
    where a ray meets no surface, the glow is added and the World shows through with that
    transmittance, as the bake's environment.apply does.
    shadows: None, or dict(maps, info: the textures of a preview_shadows.ShadowMaps, points,
    spots, suns: the shadow-map row of each point light, spot and sun, -1 for unshadowed
    ones; `scene_shadows` builds it; optional steps: the march's steps per ray, default
    SHADOW_STEPS['MEDIUM']): volumetric shadows, the shadowed lights' airlight
    marched through their maps (shadow_maps.glsl); each Gaussian's light terms take the
    light's visibility where they are evaluated (b^r, or the light fit's nodes).
    Restores every gpu.state it changes.
    """
    res = _gpu_resources()
    flags = dict(phase=phase[0] != "isotropic", spots=bool(spots is not None and len(spots["positions"])),
                 suns=bool(suns is not None and len(suns["directions"])), env=environment is not None,
                 shadows=0 if shadows is None else int(shadows.get("steps", SHADOW_STEPS['MEDIUM'])))
    env_tex, env_T = _environment_texture(res, environment)
    shadow = shadows or {}
    if spots is not None and gaussians is not None and len(gaussians["scales"]) > 0:
        spots = dict(spots, radii=())  # (fog objects: the bake takes lights as points)
    spots_tex = _spots_texture(spots, shadow.get("spots"))
    suns_tex = _suns_texture(suns, shadow.get("suns"))
    if shadows is None:
        shadow_maps = shadow_info = _environment_texture(res, None)[0]  # 1x1, never read
    else:
        shadow_maps, shadow_info = shadows["maps"], shadows["info"]
    phase_vec, gtab = _phase_inputs(res, phase)
    x, y, w, h = (int(v) for v in viewport)
    splat = None
    Csv = None
    splat_I0 = None
    if noise is not None:
        amplitude, noise_scale = float(noise[0]), float(noise[1])
        offset = tuple(float(v) for v in noise[2])
        if not (math.isfinite(amplitude) and amplitude >= 0.0 and math.isfinite(noise_scale)
                and noise_scale > 0.0 and len(offset) == 3 and all(map(math.isfinite, offset))):
            raise ValueError(f"noise: amplitude must be finite and >= 0, scale finite and > 0, "
                             f"offset 3 finite numbers (got {noise!r})")
        noise = (amplitude, noise_scale, offset) if amplitude > 0.0 else None
    if gaussians is not None and len(gaussians["scales"]) > 0:
        gauss_pass = GAUSS_PASS if gauss_pass is None else gauss_pass
        if gauss_pass not in GAUSS_PASSES:
            raise ValueError(f"gauss_pass must be one of {GAUSS_PASSES}, got {gauss_pass!r}")
        if gaussians.get("colors") is not None:
            if light_I0 is None or len(light_I0) != len(light_positions):
                raise ValueError("Gaussians with colours need light_I0 (one I0 per light, "
                                 "without the fog's albedo)")
            splat_I0 = light_I0
        light_fit = LIGHT_FIT if light_fit is None else bool(light_fit)
        splat = _gaussian_fog(res, gaussians=gaussians, window_depth=window_depth,
                              sigma_t=sigma_t, view_origin=view_origin,
                              light_positions=light_positions, gauss_pass=gauss_pass,
                              light_fit=light_fit, noise=noise is not None, shadows=shadows is not None)
        gauss_scale, scale = int(scale), 1
        if gauss_pass == 'TILES' and not splat[1].update_tiles(
                _native_for_preview(), perspective_matrix, (w, h), gauss_scale):
            # More list entries than the shader's float indices hold: draw the splat.
            splat = _gaussian_fog(res, gaussians=gaussians, window_depth=window_depth,
                                  sigma_t=sigma_t, view_origin=view_origin,
                                  light_positions=light_positions, gauss_pass='SPLAT',
                                  light_fit=light_fit, noise=noise is not None, shadows=shadows is not None)
        Csv = splat[1].Csv
    _state["last_scale"] = scale
    _state["last_gauss_scale"] = gauss_scale if splat is not None else None
    if light_radii is not None:
        light_radii = [float(r) for r in light_radii]
        if len(light_radii) != len(light_positions) or not all(math.isfinite(r) and r >= 0.0 for r in light_radii):
            raise ValueError(f"light_radii: one finite radius >= 0 per light (got {light_radii!r})")
    lights = _lights_texture(light_positions, light_intensities, Csv, splat_I0, shadow.get("points"),
                             None if splat is not None else light_radii)
    fog = _shader('fog', window_depth, ('gauss', gauss_scale) if splat is not None else False,
                  **flags)
    clip = (*view_axis(perspective_matrix), float(clip_start) if is_perspective else 0.0)

    gauss_targets = None

    ubos = []

    def bind(shader, target_viewport, fog_lo, pass_scale=None):
        # The blending draw of the upsampling has no airlight code, so the compiler
        # drops the light inputs there: set what the shader has.
        def put(setter, name, value):
            try:
                setter(name, value)
            except ValueError:
                pass
        shader.bind()
        ubo = gs.preview_params_ubo(
            inv_persp=perspective_matrix.inverted(), persp=perspective_matrix,
            eye=(*view_origin, 1.0 if is_perspective else 0.0), clip=clip,
            viewport=tuple(float(v) for v in target_viewport), phase=phase_vec,
            sigma_t=float(sigma_t), light_count=len(light_positions),
            scale=int(pass_scale if pass_scale is not None else scale), mode=int(mode),
            env_T=env_T, noise=noise)
        ubos.append(ubo)  # alive until the draws are done
        shader.uniform_block("pv", ubo)
        put(shader.uniform_sampler, "Ftab", res["ftab"])
        put(shader.uniform_sampler, "Gtab", gtab)
        put(shader.uniform_sampler, "spots", spots_tex)
        put(shader.uniform_sampler, "suns", suns_tex)
        put(shader.uniform_sampler, "env_glow", env_tex)
        put(shader.uniform_sampler, "shadow_maps", shadow_maps)
        put(shader.uniform_sampler, "shadow_info", shadow_info)
        put(shader.uniform_sampler, "depth_tex", depth_tex)
        put(shader.uniform_sampler, "lights", lights)
        if fog_lo is not None:  # the upsampling pass (the fog pass has neither)
            put(shader.uniform_sampler, "fog_lo", fog_lo)
        if gauss_targets is not None:
            put(shader.uniform_sampler, "gauss_acc", gauss_targets[0])
            put(shader.uniform_sampler, "gauss_near", gauss_targets[1])

    prev_blend = gpu.state.blend_get()
    prev_depth = gpu.state.depth_test_get()
    prev_mask = gpu.state.depth_mask_get()
    prev_viewport = gpu.state.viewport_get()
    try:
        gpu.state.depth_test_set('NONE')
        gpu.state.depth_mask_set(False)
        if splat is not None:
            gauss_targets = _draw_gaussians(*splat, (w, h), gauss_scale, bind)
            gpu.state.viewport_set(*prev_viewport)
        if scale == 1:
            gpu.state.blend_set('ALPHA_PREMULT')
            bind(fog, (x, y, w, h), None)
            res["batch"].draw(fog)
        else:
            lw, lh = -(-w // scale), -(-h // scale)
            target = _target("fog_lo", lw, lh, LOWRES_FORMAT)
            gpu.state.blend_set('NONE')
            fog_lo = _shader('fog', window_depth, variant=True, **flags)
            with _framebuffer(target).bind():
                gpu.state.viewport_set(0, 0, lw, lh)
                bind(fog_lo, (0, 0, w, h), None)
                res["batch"].draw(fog_lo)
            gpu.state.viewport_set(*prev_viewport)
            if mode != UPSAMPLE_BILATERAL_EXACT:
                gpu.state.blend_set('ALPHA_PREMULT')
                up = _shader('upsample', window_depth, **flags)
                bind(up, (x, y, w, h), target["colour"])
                res["batch"].draw(up)
            else:
                # Blend where the samples share the pixel's surface into a full-res
                # target, marking the other pixels with depth 0; evaluate those exactly
                # (a quad at depth 0.5 tested GREATER: the rest is never shaded); then
                # composite. See preview_upsample_frag.glsl for why not one draw.
                full = _target("fog_full", w, h, 'RGBA32F', depth=True)
                gpu.state.blend_set('NONE')
                with _framebuffer(full).bind():
                    gpu.state.viewport_set(0, 0, w, h)
                    gpu.state.depth_test_set('ALWAYS')
                    gpu.state.depth_mask_set(True)
                    up = _shader('upsample', window_depth, 'mark', **flags)
                    bind(up, (0, 0, w, h), target["colour"])
                    res["batch"].draw(up)
                    gpu.state.depth_test_set('GREATER')
                    gpu.state.depth_mask_set(False)
                    exact = _shader('upsample', window_depth, 'exact', **flags)
                    bind(exact, (0, 0, w, h), target["colour"])
                    res["batch"].draw(exact)
                gpu.state.depth_test_set('NONE')
                gpu.state.viewport_set(*prev_viewport)
                gpu.state.blend_set('ALPHA_PREMULT')
                comp = _shader('composite', window_depth, **flags)
                bind(comp, (x, y, w, h), full["colour"])
                res["batch"].draw(comp)
    finally:
        gpu.state.blend_set(prev_blend)
        gpu.state.depth_test_set(prev_depth)
        gpu.state.depth_mask_set(prev_mask)
        gpu.state.viewport_set(*prev_viewport)
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


def auto_preview_scale(gaussians, perspective_matrix, size):
    """The scale of the preview's 'AUTO' resolution: with Gaussian fog, the coarsest whose
    texels stay within half the smallest visible Gaussian's projected sigma
    (preview_gaussians.auto_scale, up to EIGHTH); without, HALF."""
    if not len(gaussians["scales"]):
        return SCALES['HALF']
    radii = pg.cull_radii(gaussians["scales"], gaussians["amplitudes"])
    return pg.auto_scale(gaussians["centres"], gaussians["scales"], radii,
                         np.array(perspective_matrix), size)


def _draw_callback():
    """POST_VIEW handler: never raises; an error is kept and shown in the panel."""
    context = bpy.context
    try:
        if not _should_draw(context):
            return
        rv3d = context.region_data
        if rv3d is None:
            return
        wm = context.window_manager
        scale_name = getattr(wm, "airlight_preview_scale", 'AUTO')
        scale = SCALES.get(scale_name, 2)
        readback = getattr(wm, "airlight_preview_depth", 'DRAWN') == 'READBACK'
        t0 = time.perf_counter()
        scene = context.scene
        try:  # the bake's lights (scene_description + plan); a scene it refuses has no fog
            lights = preview_lights(scene, context.evaluated_depsgraph_get())
        except scene_description.ExportError as ex:
            _state["problem"] = str(ex)  # (shown in the panel; the next draw asks again)
            return
        _state["problem"] = None
        x, y, w, h = gpu.state.viewport_get()
        persp = rv3d.perspective_matrix.copy()
        view_origin = tuple(rv3d.view_matrix.inverted().translation)
        if readback:
            fb = gpu.state.active_framebuffer_get()
            depth_buf = fb.read_depth(x, y, w, h)
            depth_tex = gs.depth_texture(depth_buf, w, h)
        else:
            depth_tex = draw_distance(context, perspective_matrix=persp,
                                      view_origin=view_origin,
                                      is_perspective=rv3d.is_perspective, size=(w, h))
        _state["last_depth_ms"] = (time.perf_counter() - t0) * 1e3
        positions, intensities = lights["positions"], lights["intensities"]
        clip_start, clip_end = view_clip_range(context)
        gaussians = scene_gaussians(context)
        light_I0 = None
        if len(gaussians["scales"]) and gaussians.get("colors") is not None:
            light_I0 = lights["I0"]
        if scale_name == 'AUTO':
            scale = auto_preview_scale(gaussians, persp, (w, h))
        settings = scene.airlight
        noise = (float(settings.noise_amplitude), float(settings.noise_scale),
                 tuple(float(v) for v in settings.noise_offset))
        phase = model_choice.native_phase(scene.airlight)
        spots, suns = lights["spots"], lights["suns"]
        env = scene_environment(scene)
        try:  # a GPU that cannot hold the maps draws the fog unshadowed and says why
            shadows = scene_shadows(lights, lambda: _caster_instances(context), _state["generation"])
            if shadows is not None:
                shadows["steps"] = SHADOW_STEPS.get(getattr(wm, "airlight_preview_shadows", 'MEDIUM'), 32)
            _state["shadow_error"] = None
        except Exception as ex:  # (GPUTexture and framebuffer creation raise plain Exceptions)
            shadows = None
            _state["shadow_error"] = f"{type(ex).__name__}: {ex}"
        draw_fog(depth_tex=depth_tex, perspective_matrix=persp, view_origin=view_origin,
                 is_perspective=rv3d.is_perspective, viewport=(x, y, w, h),
                 sigma_t=scene.airlight.density, light_positions=positions,
                 light_intensities=intensities, clip_start=clip_start,
                 window_depth=readback, scale=scale, gaussians=gaussians, phase=phase,
                 spots=spots, suns=suns, environment=env, light_I0=light_I0, noise=noise,
                 shadows=shadows, light_radii=lights["radii"])
        _state["last_ms"] = (time.perf_counter() - t0) * 1e3
        if _state["capture"] is not None:
            if readback:
                depth = gs.buffer_to_numpy(depth_buf, (h, w))
            else:
                with _framebuffer(_state["gpu"]["targets"]["distance"]).bind():
                    buf = gpu.state.active_framebuffer_get().read_color(
                        0, 0, w, h, 1, 0, 'FLOAT')
                depth = gs.buffer_to_numpy(buf, (h, w))
                gpu.state.viewport_set(x, y, w, h)
            fog_lo = None
            scale = _state.get("last_scale", scale)  # FULL while Gaussians are drawn
            if scale > 1:
                target = _state["gpu"]["targets"]["fog_lo"]
                lw, lh = target["size"]
                with _framebuffer(target).bind():
                    buf = gpu.state.active_framebuffer_get().read_color(
                        0, 0, lw, lh, 4, 0, 'FLOAT')
                fog_lo = gs.buffer_to_numpy(buf, (lh, lw, 4))
                gpu.state.viewport_set(x, y, w, h)
            _state["capture"].update(
                depth=depth, fog_lo=fog_lo, window_depth=readback, viewport=(x, y, w, h), scale=scale,
                perspective_matrix=persp, view_origin=view_origin,
                sigma_t=scene.airlight.density, lights=(positions, intensities), spots=spots, suns=suns,
                clip=(clip_start, clip_end), gaussians=gaussians, phase=phase, noise=noise)
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
    _state["error"] = _state["problem"] = None


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
            for line in textwrap.wrap(_missing_reason(), 40):
                col.label(text=line)
            return
        if _state["error"] or _state["problem"]:
            col = layout.column()
            col.alert = True
            col.label(text="Preview stopped:" if _state["error"] else "No fog to preview:", icon='ERROR')
            col.label(text=(_state["error"] or _state["problem"])[:120])
        elif _state["last_ms"] is not None and context.window_manager.airlight_preview:
            layout.label(text=f"Last fog pass: {_state['last_ms']:.1f} ms")
        col = layout.column()
        col.enabled = context.window_manager.airlight_preview
        col.prop(context.window_manager, "airlight_preview_scale")
        col.prop(context.window_manager, "airlight_preview_depth")
        if settings.volumetric_shadows:
            col.prop(context.window_manager, "airlight_preview_shadows")
        layout.prop(settings, "density")
        layout.prop(settings, "color")
        if not (settings.phase == 'HENYEY_GREENSTEIN' and settings.anisotropy == 0.0):
            layout.label(text="Fog objects are previewed isotropic", icon='INFO')
        if settings.volumetric_shadows:
            if _state["shadow_dropped"]:
                layout.label(text=f"{_state['shadow_dropped']} shadowed lights past "
                             f"{ps.MAX_SHADOW_MAPS}: unshadowed here", icon='INFO')
            if _state["shadow_error"]:
                col = layout.column()
                col.label(text="Shadows unavailable here, fog drawn unshadowed:", icon='ERROR')
                col.label(text=_state["shadow_error"][:120])



def register():
    """Never raises: a failing preview must not break the add-on's registration."""
    try:
        bpy.types.WindowManager.airlight_preview = BoolProperty(
            name="Viewport Preview",
            description="Show the fog in the 3D viewport (analytic airlight of the point "
                        "lights composited over the viewport; not saved in the file)",
            default=False, update=_on_setting_changed)
        bpy.types.WindowManager.airlight_preview_scale = EnumProperty(
            name="Resolution",
            description="Resolution at which the fog is evaluated before a depth-aware "
                        "upsampling to the viewport; lower is faster, and silhouettes "
                        "stay sharp because pixels at depth edges are re-evaluated",
            items=(('FULL', "Full", "Evaluate the fog for every viewport pixel"),
                   ('HALF', "Half", "Evaluate the fog at half the viewport resolution"),
                   ('QUARTER', "Quarter",
                    "Evaluate the fog at a quarter of the viewport resolution"),
                   ('EIGHTH', "Eighth",
                    "Evaluate the fog at an eighth of the viewport resolution (Gaussian "
                    "fog is smooth: its sums lose little there)"),
                   ('AUTO', "Automatic",
                    "Fog objects: the coarsest scale (up to Eighth) whose texels stay within "
                    "half the smallest visible fog blob's projected width (sigma); "
                    "homogeneous fog alone: Half (default: 3000 fog blobs and 4 lights drew "
                    "at 89 fps at 1920x1080 on an H100 with Eighth, 20 fps with Quarter)")),
            default='AUTO', update=_on_setting_changed)
        bpy.types.WindowManager.airlight_preview_shadows = EnumProperty(
            name="Shadows",
            description="Steps along each view ray of the volumetric shadows' march through "
                        "the lights' shadow maps (Volumetric Shadows on): more are closer to "
                        "the bake and slower",
            items=(('FAST', "Fast", "16 steps per light (2-6 % from the bake on the test "
                    "scenes, mean)"),
                   ('MEDIUM', "Medium", "32 steps per light (1-3 % from the bake, mean)"),
                   ('FINE', "Fine", "64 steps per light (0.5-1.6 % from the bake, mean; "
                    "the shadow maps' resolution bounds the rest)")),
            default='MEDIUM', update=_on_setting_changed)
        bpy.types.WindowManager.airlight_preview_depth = EnumProperty(
            name="Depth",
            description="Where the fog gets each pixel's surface distance from: the "
                        "preview draws the scene's evaluated meshes itself (fast), or "
                        "reads the viewport's depth back (slower; also sees what only "
                        "the viewport draws, such as point clouds and volumes)",
            items=(('DRAWN', "Scene Meshes", "Draw the evaluated mesh triangles of the "
                    "visible objects into the preview's own distance buffer"),
                   ('READBACK', "Viewport Depth", "Read the viewport's depth buffer back "
                    "to the CPU and upload it every draw")),
            default='DRAWN', update=_on_setting_changed)
        bpy.utils.register_class(AIRLIGHT_PT_viewport_preview)
        add_draw_handler()
        if _on_depsgraph_update not in bpy.app.handlers.depsgraph_update_post:
            bpy.app.handlers.depsgraph_update_post.append(_on_depsgraph_update)
        if _on_frame_change not in bpy.app.handlers.frame_change_post:
            bpy.app.handlers.frame_change_post.append(_on_frame_change)
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
                         (bpy.app.handlers.load_post, _on_load_post),
                         (bpy.app.handlers.depsgraph_update_post, _on_depsgraph_update),
                         (bpy.app.handlers.frame_change_post, _on_frame_change)):
        while fn in handlers:
            handlers.remove(fn)
    try:
        bpy.utils.unregister_class(AIRLIGHT_PT_viewport_preview)
    except RuntimeError:
        pass  # never registered (register() failed early)
    for prop in ("airlight_preview", "airlight_preview_scale", "airlight_preview_depth",
                 "airlight_preview_shadows"):
        if hasattr(bpy.types.WindowManager, prop):
            delattr(bpy.types.WindowManager, prop)
    _state["error"] = _state["problem"] = None
    _state["last_ms"] = None
