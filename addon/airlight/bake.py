"""Bake operators: scene description -> `_native.bake` -> one multilayer EXR per frame.

`airlight.bake` bakes synchronously for EXEC_DEFAULT and in background mode (printing
progress lines), and as a cancellable modal operator with a worker thread when invoked
from the UI (the native bake releases the GIL, a timer polls its progress).
"""

import math
import os
import threading
import time

import bpy
import numpy as np
from bpy.props import IntProperty, StringProperty

from . import cache, compositor, environment, model_choice, native, penumbra, scene_description, scene_export, surface
from .names import PASS_AIRLIGHT_WORLD, light_pass
from .views import bake_window, render_region, render_size, render_views


class BakeError(RuntimeError):
    """A bake failed for a reason the user can fix; the message says which."""


cache_path = cache.cache_path
# Key of the settings dict (not a `_native.bake` argument; run() takes it out): the light
# group name per bake light when surface shading is on (surface.ensure_passes).
SURFACE_GROUPS = "surface_groups"
# Another such key, with a render region (views.render_region): the bake covers
# the region and a margin around it (views.bake_window); ((left, top, width,
# height) of the region in the baked image, rows top first; (left, top, width, height) of
# the region in the whole frame when the render is not cropped to the region, else None).
# run() cuts the region out of the passes and, uncropped, puts it back into a whole frame
# of neutral passes (outside the region the render is empty).
REGION = "render_region"
# And: write the passes as 16-bit floats (scene.airlight.pass_precision 'HALF').
HALF_PASSES = "half_passes"
# And, with the camera's depth of field (scene_description.export_lens): [(cam_to_world,
# projection)] of the lens samples, one bake each, averaged by run().
LENS = "lens_samples"
# And, with motion blur (prepare_views with evaluate_at): the scene descriptions of the
# shutter samples (each lens sample of each), one bake each, averaged by run().
SAMPLES = "samples_to_average"
# Settings key (popped by run) of the per-light passes: the light arrays' row names
# (scene_export.light_arguments), or absent when Light Passes is off.
LIGHT_PASSES = "light_passes"
# (fogged lights, Light Pass Limit) when Light Passes is on but the scene has more lights
# than the limit: no per-light pass is written, and the console line says so.
LIGHT_PASSES_OVER = "light_passes_over"
# prepare()'s notes on the lights (scene_export.ies_notes), which run() puts in its stats.
LIGHT_NOTES = "light_notes"
# Soft Shadow Samples Automatic: the accuracy target its probe meets (penumbra.choose), run()
# sets shadow_samples from it.
SOFT_SHADOW_TARGET = "soft_shadow_target"


# Outputs that keep more than 8 bits per channel (the passes' half-float rounding would show).
FLOAT_OUTPUTS = ('OPEN_EXR', 'OPEN_EXR_MULTILAYER', 'HDR')


def half_passes(scene):
    """Whether the cache EXR holds 16-bit floats: Pass Precision Half, or Automatic with an
    8-bit output (Output > Format), where half's rounding (<= 4.9e-4 relative) is below the
    output's step (1/255) and the EXR writes ~4x faster (docs/performance.md)."""
    precision = getattr(scene.airlight, "pass_precision", 'AUTO')
    if precision != 'AUTO':
        return precision == 'HALF'
    image = scene.render.image_settings
    return image.file_format not in FLOAT_OUTPUTS and image.color_depth == '8'


def film_filter_width(scene):
    """The render's pixel filter width in pixels, which the bake's edge sub-samples follow
    (Blackman-Harris, importance-sampled): Cycles' Film > Pixel Filter width, else
    Render > Film > Filter Size (EEVEE, Workbench). Cycles' Box and Gaussian filters get
    the Blackman-Harris one of their width."""
    cycles = getattr(scene, "cycles", None) if scene.render.engine == 'CYCLES' else None
    return float(cycles.filter_width) if cycles is not None else float(scene.render.filter_size)


def bake_settings(scene, description=None):
    """Keyword arguments of `_native.bake` that are not part of the scene description
    (_description_, scene_export's, gives Automatic the render's pixel size for the fog
    objects' resolution; without it the 1080p reference is assumed)."""
    settings = scene.airlight
    model = model_choice.choose(settings)[0]
    extra = dict(rayleigh_density=float(settings.rayleigh_density)) if model == "hoffman02" else {}
    pixel = (model_choice.pixel_angle(description["projection"], description["width"])
             if description is not None else None)
    return dict(model=model, threads=settings.threads, aa_samples=settings.aa_samples,
                filter_width=film_filter_width(scene),
                gaussian_resolution=model_choice.gaussian_resolution(settings, pixel),
                gaussian_accuracy=model_choice.gaussian_accuracy(settings),
                light_size_tolerance=model_choice.light_size_tolerance(settings),
                shadow_samples=max(1, int(getattr(settings, "shadow_samples", 1))),
                homogeneous_resolution=getattr(settings, "homogeneous_resolution", 'FULL').lower(),
                **model_choice.table_settings(settings), **extra)


def prepare(scene, depsgraph, mesh_overrides=None, view=None):
    """Everything the bake needs, gathered in the main thread (touches bpy); in a render
    thread nothing is written (_mesh_overrides_: see fog_object.gather). _view_: the
    render view whose camera sees it (views.render_views; None: the scene camera).

    The World for the environment glow travels in the settings under "environment"
    (environment.prepare(); absent when off), which `run` takes out before the native bake."""
    try:
        names = {} if getattr(scene.airlight, "light_passes", False) else None
        notes = []
        description, plan = scene_export.export(scene, depsgraph, mesh_overrides, view, names, notes)
        over = None
        if names is not None:
            count, limit = len(light_pass_names(names)), int(getattr(scene.airlight, "light_pass_limit", 8))
            if count > limit:
                over, names = (count, limit), None
        settings = bake_settings(scene, description)
        world = environment.prepare(scene)
        if world is not None:
            settings["environment"] = world
    except (scene_description.ExportError, environment.WorldMapError) as ex:
        raise BakeError(str(ex)) from None
    if half_passes(scene):
        settings[HALF_PASSES] = True
    if names is not None:
        settings[LIGHT_PASSES] = names
    if notes:
        settings[LIGHT_NOTES] = notes
    target = model_choice.soft_shadow_target(scene.airlight)
    if target is not None and penumbra.needed(description):
        settings[SOFT_SHADOW_TARGET] = target
    if over is not None:
        settings[LIGHT_PASSES_OVER] = over
    lens = scene_description.export_lens(scene, depsgraph, view, description["cam_to_world"],
                                         description["projection"])
    if lens is not None:
        settings[LENS] = lens
    region, window = render_region(scene), bake_window(scene)
    if region is not None:
        width, height = render_size(scene)
        x0, y0, x1, y1 = region
        cut = (x0 - window[0], window[3] - y1, x1 - x0, y1 - y0)
        whole = None if scene.render.use_crop_to_border else (x0, height - y1, width, height)
        settings[REGION] = (cut, whole)
    if surface.active(scene):
        # Surface shading: the light groups and DiffCol pass the composite reads (surface.py).
        settings["surface"] = True
        if surface.gloss_exponent(scene) > 0.0:
            settings["surface_phong_exponent"] = max(1.0, surface.gloss_exponent(scene))
        if scene.airlight.surface_glow_model == 'BIRI06_EQ10':
            settings["surface_glow_model"] = "biri06_eq10"
        # (Interactive renders call this from the render thread: there nothing is written.)
        main = threading.current_thread() is threading.main_thread()
        groups = (surface.ensure_passes(scene, depsgraph) if main
                  else surface.current_groups(depsgraph))
        # One entry per light the bake gets: Automatic's skipped lights are not exported
        # (scene_export), so drop their groups or the attenuation images would shift.
        rows = surface.fogged_lights(depsgraph)
        settings[SURFACE_GROUPS] = [group for (obj, _), group in zip(rows, groups)
                                    if obj.name not in plan.skipped]
        if world is not None:
            world["group"] = (surface.ensure_world_group(scene) if main
                              else surface.current_world_group(scene))
    return description, settings


# The keys of prepare()'s settings that run() takes out before the native bake.
RUN_ONLY = (SURFACE_GROUPS, REGION, HALF_PASSES, "environment", LENS, SAMPLES, LIGHT_PASSES, LIGHT_PASSES_OVER,
            LIGHT_NOTES, SOFT_SHADOW_TARGET)


def native_settings(settings):
    """prepare()'s _settings_ as `_native.bake` keyword arguments: without run()'s own keys
    (the surface groups, region, precision, World, lens and shutter samples, light passes)."""
    return {k: v for k, v in settings.items() if k not in RUN_ONLY}


def run(description, settings, filepath, progress=None, deferred=None):
    """Bakes and writes the EXR; safe to call from a worker thread (no bpy access).

    Returns (stats dict, seconds). Raises `_native.BakeCancelled` when `progress`
    returns False, BakeError for invalid input or I/O failure. With _deferred_ (a list) the
    EXR is not written: a cache.PassFile is appended to it instead (the compositor takes its
    passes from memory and render._BakeBeside writes the file after the bake, beside the render).
    """
    module = native.get()
    try:
        cache.ensure_parent_dir(filepath)
    except cache.CacheError as ex:
        raise BakeError(str(ex)) from None
    start = time.perf_counter()
    own = {key: settings.get(key) for key in RUN_ONLY}
    settings = native_settings(settings)
    groups, region, half, world = own[SURFACE_GROUPS], own[REGION], bool(own[HALF_PASSES]), own["environment"]
    lens, rows, over = own[LENS], own[LIGHT_PASSES], own[LIGHT_PASSES_OVER]
    samples = own[SAMPLES] or (_variants(description, {LENS: lens}) if lens else None)

    counts = module.table_cache_counts() if hasattr(module, "table_cache_counts") else None
    soft = None
    if own[SOFT_SHADOW_TARGET] is not None:
        try:
            soft = penumbra.choose(module, description, settings, own[SOFT_SHADOW_TARGET])
        except ValueError as ex:
            raise BakeError(f"Invalid fog scene: {ex}") from None
        settings["shadow_samples"] = soft.samples

    def bake_once(description, progress):
        """(airlight, transmittance, extra passes or None, depth, stats) of one bake."""
        try:
            t0 = time.perf_counter()
            index = _light_pass_index(module, description, settings, rows) if rows else None
            after = bool(rows) and index is None  # the light passes baked after the total
            result = module.bake(**description, **settings, **({LIGHT_PASS_INDEX: index[1]} if index else {}),
                                 progress=_sub_progress(progress, 0, 1 + after))
            stats = dict(result["stats"])
            stats["seconds_native"] = time.perf_counter() - t0
            unlit = result["airlight"].copy() if rows and world is not None else None
            if world is not None:
                stats["seconds_environment"] = environment.apply(module, world, description, result)
            refined = settings.get("gaussian_accuracy", 0.0) > 0.0 and len(description.get("rbf_centres", ())) > 0
            lit = unlit if unlit is not None else result["airlight"]
            if index is not None:
                keys = index[0]
                lights = ({keys[0]: lit} if len(keys) == 1 else
                          {key: result["light_airlight"][g] for g, key in enumerate(keys)})
                light_seconds = None
            else:
                lights, light_seconds = (_light_passes(module, description, settings, rows,
                                                       _sub_progress(progress, 1, 2), total=None if refined else lit)
                                         if rows else (None, 0.0))
            if lights is not None and refined:
                _split_like(lights, lit)
        except ValueError as ex:
            raise BakeError(f"Invalid fog scene: {ex}") from None
        extra = surface.pass_arrays(result, groups) if settings.get("surface") else None
        if extra is not None and "environment_surface" in result:
            name, ratio = result["environment_surface"]
            extra[surface.PASS_PREFIX + name] = ratio
        if lights is not None:
            extra = dict(extra or {}, **lights)
            if unlit is not None:
                extra[PASS_AIRLIGHT_WORLD] = result["airlight"] - unlit
            if light_seconds is not None:
                stats["seconds_light_passes"] = light_seconds
        return result["airlight"], result["transmittance"], extra, result["depth"], stats

    if samples is None:
        airlight, transmittance, extra, _, stats = bake_once(description, progress)
    else:
        airlight, transmittance, extra, stats = _average(bake_once, samples, progress)
    if region is not None:
        airlight = _fit_region(airlight, region, 0.0)
        transmittance = _fit_region(transmittance, region, 1.0)
        extra = {name: _fit_region(p, region, 0.0) for name, p in (extra or {}).items()} or None
    if deferred is not None:
        deferred.append(cache.PassFile(filepath, cache.pass_dict(airlight, transmittance, extra), half))
        stats["exr_deferred"] = True
    else:
        t0 = time.perf_counter()
        try:
            cache.write_passes(filepath, airlight, transmittance, extra, half=half)
        except cache.CacheError as ex:
            raise BakeError(str(ex)) from None
        stats["seconds_exr"] = time.perf_counter() - t0
    if own[LIGHT_NOTES]:
        stats[LIGHT_NOTES] = list(own[LIGHT_NOTES])
    if soft is not None:
        stats["soft_shadows"] = soft
    if over is not None:
        stats["light_passes_over_limit"] = over
    if counts is not None:
        stats["tables_built"] = module.table_cache_counts()["built"] - counts["built"]
    return stats, time.perf_counter() - start


# The light arrays of `_native.bake` per kind of row names, and the per-light flags.
# (The per-light shadow flags last: _light_cost reads them.)
_LIGHT_ARRAYS = {
    "points": ("light_positions", "light_intensities", "light_radii", "light_shadows"),
    "spots": ("spot_positions", "spot_axes", "spot_intensities", "spot_size", "spot_blend", "spot_spread",
              "spot_radii", "spot_profiles", "spot_profile_in_cone",
              "spot_profile_extent", "spot_shadows"),
    "suns": ("sun_directions", "sun_irradiances", "sun_angles", "sun_shadows"),
}


# `_native.bake`'s argument of the per-light passes baked with the total.
LIGHT_PASS_INDEX = "light_pass_index"


def _light_pass_index(module, description, settings, rows):
    """(pass names, per light row its pass) for the light passes in the total's own bake,
    every light evaluated once (`_native.bake`'s light_pass_index: points, spots, suns); None
    where that bake cannot split them (fog objects, a whole-image model, the homogeneous
    lattice) or the rows do not match the light arrays: then _light_passes bakes them apart.
    One pass needs no index (it is the total)."""
    if (len(description.get("rbf_centres", ())) > 0 or settings.get("model") in module.whole_image_models()
            or settings.get("homogeneous_resolution", "full") != "full"):
        return None
    keys = list(dict.fromkeys(light_pass(n) for n in light_pass_names(rows)))
    index = []
    for kind, array_keys in _LIGHT_ARRAYS.items():
        names = rows.get(kind, ())
        if len(names) != len(description.get(array_keys[0], ())):
            return None
        index += [keys.index(light_pass(n)) for n in names]
    return (keys, np.array(index, dtype=np.int32)) if len(keys) > 1 else (keys, None)


def _one_light(description, rows, name):
    """_description_ with the rows of light _name_ only (every kind; the others' arrays emptied)."""
    out = dict(description)
    for kind, keys in _LIGHT_ARRAYS.items():
        keep = np.array([n == name for n in rows.get(kind, ())], dtype=bool)
        for key in keys:
            if key in out:
                out[key] = np.asarray(out[key])[keep] if len(keep) == len(out[key]) else out[key]
        if kind != "points" and not keep.any():
            for key in keys:
                out.pop(key, None)
    return out


def light_pass_names(rows):
    """The fogged lights of _rows_ (scene_export.light_arguments' names), in their order."""
    return list(dict.fromkeys(n for kind in ("points", "spots", "suns") for n in rows.get(kind, ())))


def _light_cost(description, rows, name):
    """A light's share of a bake, to choose the one left to the remainder: its rows (an
    area light's samples), the shadowed ones counted four times (their lit intervals)."""
    cost = 0
    for kind, keys in _LIGHT_ARRAYS.items():
        names = rows.get(kind, ())
        shadows = description.get(keys[-1])
        shadows = np.asarray(shadows, dtype=bool) if shadows is not None and len(shadows) == len(names) else None
        cost += sum((4 if shadows is not None and shadows[k] else 1) for k, n in enumerate(names) if n == name)
    return cost


def _light_passes(module, description, settings, rows, progress, total=None):
    """({pass name: airlight (H, W, 3)} of each light alone, seconds): the bake is linear in
    the lights, so they sum to the total but for float rounding; the same model and settings,
    without the surface passes. With _total_ (the whole bake's airlight of the lights, without
    the World's glow) the costliest light is not baked again: its pass is the total less the
    others' (clipped at 0 against rounding), so one light costs no bake at all and n lights
    n - 1. Without it (the fog objects' refinement, which is not linear in the lights) every
    light is baked."""
    names = light_pass_names(rows)
    left = max(names, key=lambda n: _light_cost(description, rows, n)) if total is not None and names else None
    one = dict(settings, surface=False)
    passes, t0 = {}, time.perf_counter()
    baked = [n for n in names if n != left]
    for k, name in enumerate(baked):
        result = module.bake(**_one_light(description, rows, name), **one, progress=_sub_progress(progress, k, len(baked)))
        key = light_pass(name)
        passes[key] = passes[key] + result["airlight"] if key in passes else result["airlight"]
    if left is not None:
        rest = np.maximum(total - sum(passes.values(), np.zeros_like(total)), 0.0).astype(np.float32)
        key = light_pass(left)
        passes[key] = passes[key] + rest if key in passes else rest
    return passes, time.perf_counter() - t0


def _split_like(passes, total):
    """Scales the per-light passes in place so that they sum to _total_ per pixel and channel:
    the fog objects' refinement (gaussian_accuracy) chooses its exact terms per ray from the
    whole ray's airlight, so bakes of one light at a time need not add up to the refined
    total; this keeps the total's accuracy and each light's share of it."""
    passes_sum = sum(passes.values())
    scale = np.divide(total, passes_sum, out=np.ones_like(total), where=passes_sum > 0.0)
    for name in passes:
        passes[name] = passes[name] * scale


def _average(bake_once, descriptions, progress):
    """The passes averaged over the bakes of _descriptions_ (lens samples,
    scene_description.export_lens; shutter samples, prepare_views), as a render averages its
    camera rays over the aperture and the shutter: airlight and the surface passes the mean
    of all; transmittance the mean of the samples whose rays hit a surface (where some do),
    as the edge samples take it (a miss looks into the world through fog out to infinity,
    T = 0, and the render's mix of surface and world at such a pixel is already its own).
    Returns (airlight, transmittance, extra, stats of the first with "averaged_bakes")."""
    n = len(descriptions)
    airlight = transmittance = extra = stats = None
    hit_T = hits = None
    for k, description in enumerate(descriptions):
        A, T, E, depth, S = bake_once(description, _sub_progress(progress, k, n))
        hit = np.isfinite(depth)[..., None].astype(np.float32)
        if airlight is None:
            airlight, transmittance, stats = A.astype(np.float32), T.astype(np.float32), S
            hit_T, hits = T * hit, hit.copy()
            extra = {name: p.astype(np.float32) for name, p in E.items()} if E else E
        else:
            airlight += A
            transmittance += T
            hit_T += T * hit
            hits += hit
            for name, p in (E or {}).items():
                extra[name] += p
    airlight /= n
    transmittance = np.where(hits > 0, hit_T / np.maximum(hits, 1.0), transmittance / n).astype(np.float32)
    for p in (extra or {}).values():
        p /= n
    stats = dict(stats, averaged_bakes=n)
    return airlight, transmittance, extra, stats


def _fit_region(baked, region, fill):
    """A pass of the baked window made the size the render gives (see REGION): the render
    region cut out, and uncropped placed into a whole frame filled with _fill_ (0: no
    airlight or correction, 1: transmittance)."""
    (left, top, w, h), whole = region
    cut = baked[top:top + h, left:left + w]
    if whole is None:
        return np.ascontiguousarray(cut)
    left, top, width, height = whole
    frame = np.full((height, width) + baked.shape[2:], fill, dtype=np.float32)
    frame[top:top + h, left:left + w] = cut
    return frame


def view_paths(scene, filepath):
    """[(view, path)]: the passes' file of each view a render makes (render_views): with
    Stereoscopy on, _filepath_ with the view's suffix before the extension (fog_0001_L.exr,
    fog_0001_R.exr; the compositor hands each view its own, compositor._setup_views), else
    [(None, filepath)]."""
    views = render_views(scene)
    if views[0][0] is None:
        return [(None, filepath)]
    root, ext = os.path.splitext(filepath)
    return [(name, root + suffix + ext) for name, suffix in views]


def shutter_offsets(scene):
    """Frame offsets of the shutter samples (scene.airlight.motion_samples) with Motion Blur
    on: evenly spaced over the shutter (Output > Motion Blur > Shutter, in frames) placed as
    the engine's Position says (Cycles or Eevee: start, centre or end on the frame); [] for
    one sample or no motion blur."""
    render = scene.render
    count = int(getattr(scene.airlight, "motion_samples", 1))
    if not render.use_motion_blur or count <= 1:
        return []
    shutter = max(0.0, float(render.motion_blur_shutter))
    engine = scene.cycles if render.engine == 'CYCLES' and hasattr(scene, "cycles") else scene.eevee
    position = getattr(engine, "motion_blur_position", 'CENTER')
    start = {'START': 0.0, 'END': -shutter}.get(position, -0.5 * shutter)
    return [start + shutter * (k + 0.5) / count for k in range(count)]


def frame_evaluator(scene):
    """evaluate_at for prepare_views, main thread only: sets _scene_'s frame to the current
    one (with its subframe) plus an offset and returns the depsgraph it evaluated."""
    frame, subframe = scene.frame_current, scene.frame_subframe

    def evaluate_at(offset):
        t = frame + subframe + offset
        whole = math.floor(t)
        scene.frame_set(int(whole), subframe=t - whole)
        if bpy.context.scene == scene and bpy.context.view_layer is not None:
            return bpy.context.evaluated_depsgraph_get()
        return scene.view_layers[0].depsgraph
    return evaluate_at


def _variants(description, settings):
    """The scene descriptions one prepare()d bake stands for: one per lens sample."""
    lens = settings.get(LENS)
    if not lens:
        return [description]
    return [dict(description, cam_to_world=c, projection=p) for c, p in lens]


def prepare_views(scene, depsgraph, filepath, mesh_overrides=None, evaluate_at=None):
    """[(description, settings, path)] per view (view_paths): prepare() with each view's
    camera. The first path is the one the compositor is pointed at.

    _evaluate_at_ (main thread only; None elsewhere): a callable taking a frame offset that
    evaluates the scene there and returns its depsgraph, then back at 0.0. With Motion Blur
    (shutter_offsets) every view's settings then carry the descriptions of its shutter
    samples (and of their lens samples) under SAMPLES, which run() bakes and averages."""
    paths = view_paths(scene, filepath)
    offsets = shutter_offsets(scene) if evaluate_at is not None else []
    if not offsets:
        return [prepare(scene, depsgraph, mesh_overrides, view) + (path,) for view, path in paths]
    # (the frame's own instant is not a shutter sample: each view's job is its first sample's
    # description and settings, which run() does not bake itself when SAMPLES is there)
    jobs = [None] * len(paths)
    samples = [[] for _ in paths]
    try:
        for offset in offsets:
            at = evaluate_at(offset)
            for k, (view, path) in enumerate(paths):
                description, settings = prepare(scene, at, None, view)
                jobs[k] = jobs[k] or (description, settings, path)
                samples[k].extend(_variants(description, settings))
    finally:
        evaluate_at(0.0)
    for (_, settings, _), own in zip(jobs, samples):
        settings.pop(LENS, None)
        settings[SAMPLES] = own
    return jobs


def _sub_progress(progress, k, n):
    """The progress callback for part _k_ of _n_ equal parts of a bake (None: none)."""
    if progress is None:
        return None
    return lambda fraction: progress((k + fraction) / n)


def run_views(jobs, progress=None, deferred=None):
    """run() for each of prepare_views' jobs, _progress_ spread over them; returns (the
    first view's stats, seconds for all). _deferred_: as run's."""
    first, total = None, 0.0
    for k, (description, settings, path) in enumerate(jobs):
        stats, seconds = run(description, settings, path, _sub_progress(progress, k, len(jobs)), deferred)
        first = stats if first is None else first
        total += seconds
    return first, total


def bake_frame(scene, depsgraph, filepath=None, progress=None, mesh_overrides=None, evaluate_at=None,
               deferred=None):
    """Synchronous bake of the depsgraph's current frame (every view of a stereo render,
    view_paths; the shutter's instants with _evaluate_at_, prepare_views); returns
    (filepath, stats, seconds), filepath the first view's. _deferred_: as run's."""
    jobs, export_seconds = frame_jobs(scene, depsgraph, filepath, mesh_overrides, evaluate_at)
    return frame_baked(scene, jobs, export_seconds, *run_views(jobs, progress, deferred))


def frame_jobs(scene, depsgraph, filepath=None, mesh_overrides=None, evaluate_at=None):
    """bake_frame's first half, in the main thread: (prepare_views' jobs, the seconds their
    export took). run_views bakes them, in any thread."""
    if filepath is None:
        filepath = cache_path(scene, scene.frame_current)
    t0 = time.perf_counter()
    jobs = prepare_views(scene, depsgraph, filepath, mesh_overrides, evaluate_at)
    return jobs, time.perf_counter() - t0


def frame_baked(scene, jobs, export_seconds, stats, seconds):
    """bake_frame's last half, in the main thread, once run_views(jobs) returned (_stats_,
    _seconds_): what the panel remembers of the bake; returns bake_frame's result."""
    stats = dict(stats, seconds_export=export_seconds)
    remember_fog_objects(scene, stats)
    remember_soft_shadows(scene, stats)
    return jobs[0][2], stats, seconds + export_seconds


# Per scene name: Soft Shadow Samples Automatic's last penumbra.Choice (the scene panel shows it).
LAST_SOFT_SHADOWS = {}


def soft_shadows_text(soft):
    """A penumbra.Choice for the console, the report and the panel."""
    what = (f"{soft.samples} sample(s) (probe {1000.0 * soft.seconds:.0f} ms"
            + (", remembered from an earlier bake of this frame" if soft.remembered else ""))
    if soft.limited == "budget":
        return (f"{what}, stopped at its {penumbra.PROBE_BUDGET:g} s budget: the casters make each sample dear; "
                f"set Soft Shadow Samples to choose)")
    if soft.limited == "ladder":
        return (f"{what}, the most it takes: {soft.samples // 2} still differed from it by {100.0 * soft.error:.2g} %, "
                f"more than half the target)")
    return f"{what}, measured {100.0 * soft.error:.2g} % from a finer count)"


def remember_soft_shadows(scene, stats):
    """Keeps the count Soft Shadow Samples Automatic took in a bake for the panel."""
    if stats.get("soft_shadows"):
        soft = stats["soft_shadows"]
        LAST_SOFT_SHADOWS[scene.name] = soft
    else:
        LAST_SOFT_SHADOWS.pop(scene.name, None)


# Per scene name: what the last bake did with the fog objects (the Fog Objects panel shows it).
LAST_FOG_OBJECTS = {}


def remember_fog_objects(scene, stats):
    """Keeps the refinement's figures of a bake with fog objects for the panel."""
    if stats.get("gaussian_pairs", 0) > 0:
        LAST_FOG_OBJECTS[scene.name] = dict(
            accuracy=model_choice.gaussian_accuracy(scene.airlight),
            error_bound=float(stats.get("gaussian_error_bound", 0.0)),
            pairs=int(stats["gaussian_pairs"]),
            marched=int(stats.get("gaussian_marched_lights", 0)),
            background_rays=int(stats.get("gaussian_background_rays", 0)),
            abandoned=bool(stats.get("gaussian_refine_abandoned", False)))
    else:
        LAST_FOG_OBJECTS.pop(scene.name, None)


def fog_objects_line(stats):
    """The refinement of fog objects in a bake's stats, for the console ('' without it)."""
    pairs = stats.get("gaussian_pairs", 0)
    if not pairs:
        return ""
    if stats.get("gaussian_refine_abandoned"):
        return (f"; fog objects: WARNING the refinement to the accuracy target would take more than its budget "
                f"(~{stats.get('gaussian_refine_work', 0.0):.0f} s of CPU counted before it stopped): this frame has "
                f"Fogshop's approximation alone (up to ~29 % off on thick fog near a light); raise the Accuracy "
                f"percentage or choose Quadrature")
    marched = stats.get("gaussian_marched_lights", 0)
    return (f"; fog objects: {marched} light{'s' if marched != 1 else ''} marched exactly "
            f"({stats.get('gaussian_marched_rays', 0)} rays), "
            f"{stats.get('gaussian_background_rays', 0)} ray-lights of uniform fog corrected, "
            f"error bound {100.0 * float(stats.get('gaussian_error_bound', 0.0)):.2g} %, "
            f"{1000.0 * float(stats.get('seconds_refine', 0.0)):.0f} ms refining")


def parts_line(stats):
    """Where a frame's fog time went, for the console: the scene's export, the native bake
    (its tables' first build, ray casting, fog, surfaces) and the EXR."""
    ms = lambda key: 1000.0 * float(stats.get(key, 0.0))  # noqa: E731
    native_ms = ms("seconds_native")
    volumes = f" of which shadow volumes {ms('seconds_shadow_volumes'):.0f}" if ms("seconds_shadow_volumes") >= 1 else ""
    parts = [f"export {ms('seconds_export'):.0f} ms", f"native bake {native_ms:.0f} ms (BVH "
             f"{ms('seconds_geometry'):.0f}, setup and tables {ms('seconds_fog_setup'):.0f}{volumes}, rays "
             f"{ms('seconds_raycast'):.0f}, fog {ms('seconds_airlight'):.0f}, surfaces {ms('seconds_surface'):.0f})",
             "EXR written beside the render" if stats.get("exr_deferred") else f"EXR {ms('seconds_exr'):.0f} ms"]
    if "seconds_light_passes" in stats:
        parts.append(f"light passes {ms('seconds_light_passes'):.0f} ms")
    if stats.get("light_passes_over_limit"):
        count, limit = stats["light_passes_over_limit"]
        parts.append(f"no light passes ({count} fogged lights, over the Light Pass Limit of {limit})")
    if stats.get("soft_shadows"):
        parts.append(f"soft shadows {soft_shadows_text(stats['soft_shadows'])}")
    if stats.get("tables_built"):
        parts.append(f"{stats['tables_built']} table(s) built")
    return ", ".join(parts)


def _printing_progress(label):
    """A progress callback for background mode: one line per 10 %."""
    last = [-1]

    def progress(fraction):
        step = int(fraction * 10)
        if step > last[0]:
            last[0] = step
            print(f"Airlight: {label} {int(fraction * 100):3d}%", flush=True)
        return True
    return progress


class AIRLIGHT_OT_bake(bpy.types.Operator):
    """Bake the fog passes (airlight and transmittance) of one frame to a multilayer EXR"""
    bl_idname = "airlight.bake"
    bl_label = "Bake Fog"
    bl_options = {'REGISTER'}

    filepath: StringProperty(
        name="File Path",
        description="Multilayer EXR to write (default: the cache folder's fog_####.exr for the frame; "
                    "with Stereoscopy one file per view, the view's suffix before the extension)",
        subtype='FILE_PATH', options={'SKIP_SAVE'},
    )
    frame: IntProperty(
        name="Frame",
        description="Frame to bake (default: the current frame)",
        options={'SKIP_SAVE'},
    )

    _running = set()  # modal instances, so unregister() can cancel them

    @classmethod
    def poll(cls, context):
        if context.scene is None:
            cls.poll_message_set("No scene to bake.")
            return False
        if not native.available():
            cls.poll_message_set(native.error())
            return False
        if cls._running:
            cls.poll_message_set("A fog bake is already running.")
            return False
        return True

    # Frame handling: bake another frame by evaluating the scene there, then go back.
    def _target(self, context):
        scene = context.scene
        frame = self.frame if self.properties.is_property_set("frame") else scene.frame_current
        filepath = bpy.path.abspath(self.filepath) if self.filepath else cache_path(scene, frame)
        return scene, frame, filepath

    def _prepare_at(self, context, scene, frame):
        # frame_set even for the current frame: it re-applies the animation, so the
        # bake sees exactly what a render of that frame sees.
        original = scene.frame_current, scene.frame_subframe
        scene.frame_set(frame)
        try:
            return prepare_views(scene, context.evaluated_depsgraph_get(), self._target(context)[2],
                                 evaluate_at=frame_evaluator(scene))
        finally:
            if frame != original[0]:
                scene.frame_set(original[0], subframe=original[1])

    def _finish(self, context, scene, filepath, stats, seconds):
        if scene.airlight.auto_composite:
            compositor.sync(scene, filepath)
        skipped = sorted(model_choice.skipped_lights(scene))
        note = f"; skipped below the accuracy target: {', '.join(skipped)}" if skipped else ""
        for line in stats.get(LIGHT_NOTES, ()):
            print(f"Airlight: {line}", flush=True)
        warnings = [line for line in stats.get(LIGHT_NOTES, ()) if "WARNING" in line]
        if warnings:
            self.report({'WARNING'}, warnings[0])
        remember_soft_shadows(scene, stats)
        if stats.get("soft_shadows"):
            note += f"; soft shadows {soft_shadows_text(stats['soft_shadows'])}"
        self.report({'INFO'}, f"Fog baked in {seconds * 1000.0:.0f} ms ({os.path.basename(filepath)}){note}")
        return {'FINISHED'}

    def execute(self, context):
        scene, frame, filepath = self._target(context)
        try:
            jobs = self._prepare_at(context, scene, frame)
            filepath = jobs[0][2]
            progress = _printing_progress(f"baking frame {frame}") if bpy.app.background else None
            stats, seconds = run_views(jobs, progress)
        except BakeError as ex:
            self.report({'ERROR'}, str(ex))
            return {'CANCELLED'}
        except native.get().BakeCancelled:
            self.report({'INFO'}, "Fog bake cancelled")
            return {'CANCELLED'}
        return self._finish(context, scene, filepath, stats, seconds)

    # Modal bake: worker thread + timer.
    def invoke(self, context, event):
        if bpy.app.background:
            return self.execute(context)
        scene, frame, filepath = self._target(context)
        try:
            jobs = self._prepare_at(context, scene, frame)
        except BakeError as ex:
            self.report({'ERROR'}, str(ex))
            return {'CANCELLED'}
        self._scene_name = scene.name
        self._filepath = jobs[0][2]
        self._fraction = 0.0
        self._cancel = False
        self._outcome = None  # ('ok', stats, seconds) | ('cancelled',) | ('error', message)

        def progress(fraction):
            self._fraction = float(fraction)
            return not self._cancel

        def work():
            try:
                stats, seconds = run_views(jobs, progress)
                self._outcome = ('ok', stats, seconds)
            except BakeError as ex:
                self._outcome = ('error', str(ex))
            except Exception as ex:
                if type(ex).__name__ == "BakeCancelled":
                    self._outcome = ('cancelled',)
                else:
                    self._outcome = ('error', f"Fog bake failed: {type(ex).__name__}: {ex}")

        wm = context.window_manager
        self._timer = wm.event_timer_add(0.1, window=context.window)
        wm.progress_begin(0, 100)
        self._thread = threading.Thread(target=work, name="airlight-bake", daemon=True)
        AIRLIGHT_OT_bake._running.add(self)
        self._thread.start()
        wm.modal_handler_add(self)
        return {'RUNNING_MODAL'}

    def _cleanup(self, context):
        wm = context.window_manager
        if self._timer is not None:
            wm.event_timer_remove(self._timer)
            self._timer = None
        wm.progress_end()
        if context.workspace is not None:
            context.workspace.status_text_set(None)
        AIRLIGHT_OT_bake._running.discard(self)

    def modal(self, context, event):
        if event.type in {'ESC', 'RIGHTMOUSE'} and event.value == 'PRESS':
            self._cancel = True
        if event.type != 'TIMER':
            return {'PASS_THROUGH'}
        if self._thread.is_alive():
            percent = int(self._fraction * 100)
            context.window_manager.progress_update(percent)
            if context.workspace is not None:
                state = "cancelling" if self._cancel else f"{percent}%"
                context.workspace.status_text_set(f"Baking fog: {state} (Esc to cancel)")
            return {'RUNNING_MODAL'}
        self._thread.join()
        self._cleanup(context)
        outcome = self._outcome or ('error', "Fog bake ended without a result.")
        if outcome[0] == 'ok':
            scene = bpy.data.scenes.get(self._scene_name) or context.scene
            return self._finish(context, scene, self._filepath, outcome[1], outcome[2])
        if outcome[0] == 'cancelled':
            self.report({'INFO'}, "Fog bake cancelled")
        else:
            self.report({'ERROR'}, outcome[1])
        return {'CANCELLED'}

    def cancel(self, context):
        # Blender ends the modal handler (file load, window closed): stop the worker.
        self._cancel = True
        self._thread.join()
        self._cleanup(context)


class AIRLIGHT_OT_setup_compositor(bpy.types.Operator):
    """Add the Airlight fog nodes to the compositor (keeps existing nodes)"""
    bl_idname = "airlight.setup_compositor"
    bl_label = "Set Up Compositor"
    bl_options = {'REGISTER', 'UNDO'}

    @classmethod
    def poll(cls, context):
        if context.scene is None:
            cls.poll_message_set("No scene.")
            return False
        return True

    def execute(self, context):
        scene = context.scene
        path = view_paths(scene, cache_path(scene, scene.frame_current))[0][1]
        compositor.setup(scene, path if os.path.exists(path) else None)
        self.report({'INFO'}, "Compositor fog nodes set up")
        return {'FINISHED'}


classes = (AIRLIGHT_OT_bake, AIRLIGHT_OT_setup_compositor)


def cancel_running():
    """Asks running modal bakes to stop and waits for their threads (for unregister)."""
    for op in list(AIRLIGHT_OT_bake._running):
        op._cancel = True
        op._thread.join()
    AIRLIGHT_OT_bake._running.clear()


def register():
    for cls in classes:
        bpy.utils.register_class(cls)


def unregister():
    cancel_running()
    for cls in reversed(classes):
        bpy.utils.unregister_class(cls)
