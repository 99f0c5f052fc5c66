"""Particle emitter (Zhou et al. 2007, section 6): smoke as Gaussians on parabolic paths.

An emitter is an Empty with `obj.airlight_emitter.is_emitter` (Add > Airlight Fog
Emitter). It spawns `rate` particles per second during its frame range; particle k is
born at t_k = k / rate (seconds after the range's first frame) at a seeded random point
of a ball of `radius` around the emitter, and moves on the constant-acceleration path

    p_k(t) = M_k (o_k) + R_k (v + spread n_k) tau + acceleration tau^2 / 2,  tau = t - t_k,

with M_k the emitter's world matrix at its birth frame (R_k its rotation), v the initial
velocity in the emitter's local frame, n_k a seeded standard normal 3-vector and the
acceleration in world space (buoyancy, wind). It lives `lifetime` seconds. A Gaussian
sits at each particle: its scale a and amplitude c go linearly from (scale, amplitude) at
birth to (scale * scale_end, amplitude * amplitude_end) at death, so older smoke is wider
(smaller a) and thinner (Fogshop: "the longer the particle lives, the smaller its scale
and amplitude"). Each particle's random numbers come from a counter-based hash of
(seed, k), so the state at a frame is a pure function of that frame: scrubbing, jumping
and rendering any frame give the same Gaussians in any order.

A frame_change_post handler writes each emitter's particles at the current frame into its
target fog object (bulk foreach_set), with the "airlight_color" attribute. The bake reads
the fog object after frame_set (render.py's render_pre calls frame_set, which runs this
handler first, then evaluates the depsgraph again), so `blender -b file -a` renders the
smoke. In the render thread of interactive renders (F12, Ctrl+F12) the handler writes
nothing, as the UI may be drawing the meshes: the bake there takes the smoke from
targets_at_frame instead. "Bake to Frames" stores every frame in hidden meshes that save with the .blend
(one per frame, fake user); the handler then copies the stored frame instead of
simulating. When no particle is alive the target holds one Gaussian of amplitude 0 (the
bake refuses an empty fog object).

The emitter's motion over time is read from its own F-curves (location, Euler rotation,
scale; cached per particle while the animation is unchanged) when it has no parent,
constraints, delta transform or F-curve modifier; otherwise the current world matrix is
used for every birth (an emitter moved by a parent or constraint emits from where it is
now, not from where it was: bake it with a static parent or keyframe the emitter itself).
"""

import math
import threading

import bpy
import numpy as np
from bpy.app.handlers import persistent
from bpy.props import (BoolProperty, CollectionProperty, FloatProperty, FloatVectorProperty,
                       IntProperty, PointerProperty)

from . import fog_object

MAX_LIVE_PARTICLES = 1_000_000


class EmitterError(ValueError):
    pass


# ---- pure simulation --------------------------------------------------------------------

_M1 = np.uint64(0x9E3779B97F4A7C15)
_M2 = np.uint64(0xBF58476D1CE4E5B9)
_M3 = np.uint64(0x94D049BB133111EB)
_M4 = np.uint64(0xD1B54A32D192ED69)


def hash_uniform(seed, k, stream):
    """Uniform numbers in [0, 1) from a splitmix64 hash of (seed, k, stream): the same
    for a particle index k whatever else is evaluated (k: int array)."""
    with np.errstate(over='ignore'):
        x = (np.asarray(k, dtype=np.uint64) * _M1
             + np.uint64(seed & 0xFFFFFFFF) * _M4 + np.uint64(stream + 1) * _M3)
        x ^= x >> np.uint64(30)
        x *= _M2
        x ^= x >> np.uint64(27)
        x *= _M3
        x ^= x >> np.uint64(31)
    return (x >> np.uint64(11)).astype(np.float64) * (1.0 / 9007199254740992.0)


def hash_normal3(seed, k, stream):
    """(len(k), 3) standard normal numbers (Box-Muller on hash_uniform streams)."""
    u = [hash_uniform(seed, k, stream + i) for i in range(4)]
    r1 = np.sqrt(-2.0 * np.log1p(-u[0]))
    r2 = np.sqrt(-2.0 * np.log1p(-u[2]))
    return np.stack([r1 * np.cos(2.0 * math.pi * u[1]), r1 * np.sin(2.0 * math.pi * u[1]),
                     r2 * np.cos(2.0 * math.pi * u[3])], axis=1)


def check_params(p):
    """Raises EmitterError for settings the simulation cannot use."""
    for name in ("rate", "lifetime", "scale"):
        if not (math.isfinite(p[name]) and p[name] > 0.0):
            raise EmitterError(f"Emitter {name} must be > 0 (got {p[name]})")
    for name in ("spread", "radius", "amplitude", "scale_end", "amplitude_end", "duration"):
        if not (math.isfinite(p[name]) and p[name] >= 0.0):
            raise EmitterError(f"Emitter {name} must be >= 0 (got {p[name]})")
    if p["scale_end"] <= 0.0:
        raise EmitterError("Emitter end scale factor must be > 0 (a Gaussian's scale a > 0)")
    for name in ("velocity", "acceleration"):
        if not np.all(np.isfinite(p[name])):
            raise EmitterError(f"Emitter {name} must be finite (got {tuple(p[name])})")
    if p["rate"] * min(p["lifetime"], p["duration"] + 1.0 / p["rate"]) > MAX_LIVE_PARTICLES:
        raise EmitterError(f"Emitter would have more than {MAX_LIVE_PARTICLES} live particles "
                           "(rate x lifetime): lower the rate or the lifetime")


def alive_indices(t, rate, lifetime, duration):
    """Indices k of the particles alive at time _t_ (s after the first frame): born
    (t_k = k / rate <= t, and t_k <= duration, the emission window) and younger than
    _lifetime_ (t - t_k < lifetime)."""
    if t < 0.0:
        return np.zeros(0, dtype=np.int64)
    k_hi = int(math.floor(min(t, duration) * rate + 1e-9))
    k_lo = max(0, int(math.floor((t - lifetime) * rate + 1e-9)) + 1)
    return np.arange(k_lo, k_hi + 1, dtype=np.int64) if k_hi >= k_lo else np.zeros(0, dtype=np.int64)


def simulate(t, p, matrix_at):
    """World-space Gaussians of the particles alive at time _t_ (s after the first frame).

    _p_: dict of rate, lifetime, duration (s of emission), velocity (3, local), spread
    (m/s), radius (m), acceleration (3, world), scale, amplitude, scale_end, amplitude_end
    (factors at death), seed. _matrix_at(times)_: (n, 4, 4) emitter world matrices at
    those birth times. Returns (centres (n,3), scales (n,), amplitudes (n,), k (n,))."""
    check_params(p)
    k = alive_indices(t, p["rate"], p["lifetime"], p["duration"])
    n = len(k)
    if n == 0:
        return np.zeros((0, 3)), np.zeros(0), np.zeros(0), k
    t_birth = k / p["rate"]
    tau = t - t_birth
    seed = int(p["seed"])
    # spawn point: uniform in the ball of _radius_ (emitter's local frame)
    direction = hash_normal3(seed, k, 0)
    direction /= np.maximum(np.linalg.norm(direction, axis=1, keepdims=True), 1e-300)
    offset = direction * (p["radius"] * np.cbrt(hash_uniform(seed, k, 4)))[:, None]
    velocity = np.asarray(p["velocity"], dtype=np.float64) + p["spread"] * hash_normal3(seed, k, 5)
    m = np.asarray(matrix_at(t_birth), dtype=np.float64).reshape(-1, 4, 4)
    m = np.broadcast_to(m, (n, 4, 4))
    linear = m[:, :3, :3]
    rotation = linear / np.maximum(np.linalg.norm(linear, axis=1, keepdims=True), 1e-300)
    p0 = np.einsum('nij,nj->ni', linear, offset) + m[:, :3, 3]
    v = np.einsum('nij,nj->ni', rotation, velocity)
    acc = np.asarray(p["acceleration"], dtype=np.float64)
    centres = p0 + v * tau[:, None] + 0.5 * acc * (tau * tau)[:, None]
    x = tau / p["lifetime"]
    scales = p["scale"] * (1.0 + (p["scale_end"] - 1.0) * x)
    amplitudes = p["amplitude"] * (1.0 + (p["amplitude_end"] - 1.0) * x)
    return centres, scales, np.maximum(amplitudes, 0.0), k


# ---- Blender side -----------------------------------------------------------------------

def _euler_matrices(angles, order):
    """(n, 3, 3) rotation matrices of Euler angles (n, 3) in Blender's _order_ ('XYZ':
    X first, so R = Rz Ry Rx)."""
    n = len(angles)
    mats = {}
    for axis, i in (("X", 0), ("Y", 1), ("Z", 2)):
        c, s = np.cos(angles[:, i]), np.sin(angles[:, i])
        r = np.zeros((n, 3, 3))
        j, l = [(1, 2), (2, 0), (0, 1)][i]
        r[:, i, i] = 1.0
        r[:, j, j] = c
        r[:, l, l] = c
        r[:, j, l] = -s
        r[:, l, j] = s
        mats[axis] = r
    out = np.broadcast_to(np.eye(3), (n, 3, 3))
    for axis in order:
        out = np.einsum('nij,njk->nik', mats[axis], out)
    return out


# Emitter matrices at birth times, per emitter: (fingerprint of its animation, {time: 4x4}).
# A particle's birth matrix never changes while the animation doesn't, so scrubbing only
# evaluates F-curves for the particles born since the last frame.
_track_cache = {}
_TRACK_CACHE_LIMIT = 200_000


def _is_identity_delta(obj):
    return (tuple(obj.delta_location) == (0.0, 0.0, 0.0)
            and tuple(obj.delta_rotation_euler) == (0.0, 0.0, 0.0)
            and tuple(obj.delta_rotation_quaternion) == (1.0, 0.0, 0.0, 0.0)
            and tuple(obj.delta_scale) == (1.0, 1.0, 1.0))


def _fingerprint(obj, curves, frame_start, fps):
    parts = [frame_start, fps, obj.rotation_mode]
    for path in ("location", "rotation_euler", "scale"):  # channels without F-curves
        values = getattr(obj, path)
        parts += [values[i] for i in range(3) if (path, i) not in curves]
    for key in sorted(curves):
        fc = curves[key]
        n = len(fc.keyframe_points)
        data = np.empty(6 * n, dtype=np.float64)
        for i, attr in enumerate(("co", "handle_left", "handle_right")):
            block = np.empty(2 * n, dtype=np.float64)
            fc.keyframe_points.foreach_get(attr, block)
            data[2 * n * i:2 * n * (i + 1)] = block
        parts += [key, data.tobytes(), fc.extrapolation, fc.mute,
                  tuple((k.interpolation, k.easing) for k in fc.keyframe_points)]
    return hash(tuple(parts))


def matrix_track(obj, scene):
    """matrix_at(times) for simulate(): the emitter's world matrices at birth times (s
    after its first frame), from its own F-curves when it is keyframed and has no parent,
    constraints, delta transforms, quaternion rotation or F-curve modifiers, else its
    current world matrix for every time."""
    current = np.array(obj.matrix_world, dtype=np.float64)
    settings = obj.airlight_emitter
    action = obj.animation_data.action if obj.animation_data is not None else None
    if (action is None or obj.parent is not None or len(obj.constraints)
            or obj.rotation_mode in {'QUATERNION', 'AXIS_ANGLE'} or not _is_identity_delta(obj)):
        return lambda times: current
    curves = {}
    for fc in action.fcurves:
        if fc.data_path in {"location", "rotation_euler", "scale"}:
            if len(fc.modifiers):
                return lambda times: current
            curves[(fc.data_path, fc.array_index)] = fc
    if not curves:
        return lambda times: current
    fps = scene.render.fps / scene.render.fps_base
    base = {"location": tuple(obj.location), "rotation_euler": tuple(obj.rotation_euler),
            "scale": tuple(obj.scale)}
    key = obj.as_pointer()
    fingerprint = _fingerprint(obj, curves, settings.frame_start, fps)
    entry = _track_cache.get(key)
    if entry is None or entry[0] != fingerprint or len(entry[1]) > _TRACK_CACHE_LIMIT:
        entry = (fingerprint, {})
        _track_cache[key] = entry
    cache = entry[1]

    def evaluate_frames(frames):
        values = {}
        for path in base:
            cols = []
            for i in range(3):
                fc = curves.get((path, i))
                cols.append(np.full(len(frames), base[path][i]) if fc is None
                            else np.fromiter((fc.evaluate(f) for f in frames), float, len(frames)))
            values[path] = np.stack(cols, axis=1)
        m = np.zeros((len(frames), 4, 4))
        m[:, :3, :3] = _euler_matrices(values["rotation_euler"], obj.rotation_mode) \
            * values["scale"][:, None, :]
        m[:, :3, 3] = values["location"]
        m[:, 3, 3] = 1.0
        return m

    def matrix_at(times):
        times = np.asarray(times, dtype=np.float64).ravel()
        missing = [t for t in times.tolist() if t not in cache]
        if missing:
            computed = evaluate_frames(settings.frame_start + np.array(missing) * fps)
            cache.update(zip(missing, computed))
        return np.stack([cache[t] for t in times.tolist()]) if len(times) else np.zeros((0, 4, 4))
    return matrix_at


def params(settings, scene):
    fps = scene.render.fps / scene.render.fps_base
    return dict(rate=settings.rate, lifetime=settings.lifetime,
                duration=max(0.0, (settings.frame_end - settings.frame_start) / fps),
                velocity=np.array(settings.velocity), spread=settings.spread,
                radius=settings.radius, acceleration=np.array(settings.acceleration),
                scale=settings.scale, amplitude=settings.amplitude,
                scale_end=settings.scale_end, amplitude_end=settings.amplitude_end,
                seed=settings.seed)


def evaluate(obj, scene, frame=None):
    """World-space Gaussians (centres, scales, amplitudes, colors (n,3)) of emitter _obj_
    at _frame_ (float; the scene's current frame and subframe by default)."""
    settings = obj.airlight_emitter
    if frame is None:
        frame = scene.frame_current + scene.frame_subframe
    fps = scene.render.fps / scene.render.fps_base
    t = (frame - settings.frame_start) / fps
    centres, scales, amplitudes, _ = simulate(t, params(settings, scene), matrix_track(obj, scene))
    colors = np.broadcast_to(np.array(settings.color, dtype=np.float32), (len(centres), 3))
    return centres, scales, amplitudes, colors


def to_local(target, centres, scales):
    """World Gaussians in _target_'s object space (gather() divides a by its scale)."""
    matrix = np.array(target.matrix_world, dtype=np.float64)
    s = fog_object.uniform_scale(matrix[:3, :3])
    local = (np.asarray(centres) - matrix[:3, 3]) @ np.linalg.inv(matrix[:3, :3]).T
    return local, np.asarray(scales) * s


def _local_frame(obj, scene, target):
    """Emitter _obj_'s Gaussians at the current frame in _target_'s object space:
    (centres, scales, amplitudes, colors), from its baked frame when it has one."""
    stored = baked_mesh(obj.airlight_emitter, scene.frame_current) if len(obj.airlight_emitter.baked) else None
    if stored is not None:
        centres, scales, amplitudes = fog_object.read_mesh(stored)
        colors = fog_object.read_colors(stored)
        if colors is None:
            colors = np.zeros((len(centres), 3), dtype=np.float32)
        return centres, scales, amplitudes, colors
    centres, scales, amplitudes, colors = evaluate(obj, scene)
    local, local_scales = to_local(target, centres, scales)
    return local, local_scales, amplitudes, colors


def baked_mesh(settings, frame):
    for item in settings.baked:
        if item.frame == frame:
            return item.mesh
    return None


def ensure_target(obj, context_collection=None):
    """The emitter's target fog object, created (at the world origin, linked where the
    emitter is) when missing."""
    settings = obj.airlight_emitter
    target = settings.target
    if target is not None and fog_object.is_fog_object(target):
        return target
    collection = context_collection or (obj.users_collection[0] if obj.users_collection
                                        else bpy.context.scene.collection)
    target = fog_object.new_fog_object(f"{obj.name} Smoke", collection, centres=np.zeros((1, 3)),
                                       scales=settings.scale, amplitudes=0.0, colors=settings.color)
    settings.target = target
    return target


def emitters(scene):
    return [o for o in scene.objects if getattr(o.airlight_emitter, "is_emitter", False)]


def _active(obj):
    settings = obj.airlight_emitter
    return (settings.is_emitter and settings.enabled and settings.target is not None
            and fog_object.is_fog_object(settings.target))


def target_frame(target, scene):
    """What fog object _target_ holds at the scene's current frame: the Gaussians of every
    enabled emitter of the scene that writes into it (several emitters can share one smoke
    object), in its object space, as (centres, scales, amplitudes, colors), or None when no
    emitter writes into it; one Gaussian of amplitude 0 when none is alive (the bake
    refuses an empty fog object). Also returns {emitter name: live particles}."""
    blocks, counts = [], {}
    for obj in emitters(scene):
        if _active(obj) and obj.airlight_emitter.target == target:
            block = _local_frame(obj, scene, target)
            counts[obj.name] = int((block[2] > 0.0).sum())
            blocks.append(block)
    if not blocks:
        return None, counts
    centres, scales, amplitudes, colors = (np.concatenate([b[i] for b in blocks]) for i in range(4))
    if len(centres) == 0:
        centres, scales, amplitudes = np.zeros((1, 3)), np.ones(1), np.zeros(1)
        colors = np.ones((1, 3), dtype=np.float32)
    return (centres, scales, amplitudes, colors), counts


def update_target(target, scene):
    """Rewrites fog object _target_ with target_frame(); returns {emitter name: live particles}."""
    frame, counts = target_frame(target, scene)
    if frame is not None:
        fog_object.write_mesh(target.data, *frame)
    return counts


def _targets(scene):
    """The fog objects the scene's enabled emitters write into, each once."""
    found = {}
    for obj in emitters(scene):
        if _active(obj):
            found.setdefault(obj.airlight_emitter.target.name, obj.airlight_emitter.target)
    return list(found.values())


def targets_at_frame(scene):
    """{fog object name: target_frame()} for the scene's current frame, written nowhere:
    what a render thread's bake reads instead of the meshes (fog_object.gather)."""
    return {target.name: target_frame(target, scene)[0] for target in _targets(scene)}


def update_emitter(obj, scene):
    """Writes emitter _obj_'s Gaussians at the scene's current frame (the baked frame when
    there is one) into its target, with those of the other emitters sharing it. Returns
    _obj_'s number of live particles, or None when it has no target or is disabled."""
    if not _active(obj):
        return None
    return update_target(obj.airlight_emitter.target, scene).get(obj.name, 0)


@persistent
def on_frame_change_post(scene, *_):
    # Interactive renders run the frame handlers in the render thread, while the UI may be
    # drawing these meshes: nothing is written there (the render's bake computes the smoke
    # itself, targets_at_frame; the render engines do not draw fog objects).
    if threading.current_thread() is not threading.main_thread():
        return
    for target in _targets(scene):
        try:
            update_target(target, scene)
        except Exception as ex:  # a handler must never break playback or a render
            print(f"Airlight: fog object '{target.name}' not updated by its emitters at frame "
                  f"{scene.frame_current}: {ex}", flush=True)


def _on_setting_changed(self, context):
    obj = self.id_data
    if context.scene is None or not self.is_emitter:
        return
    try:
        update_emitter(obj, context.scene)
    except EmitterError:
        pass  # the panel shows the error


# ---- settings ---------------------------------------------------------------------------


def _poll_fog(self, obj):
    return fog_object.is_fog_object(obj)


class AirlightEmitterFrame(bpy.types.PropertyGroup):
    frame: IntProperty(name="Frame", description="Scene frame this stored state belongs to")
    mesh: PointerProperty(name="Mesh", type=bpy.types.Mesh,
                          description="Hidden mesh holding the target's Gaussians at this frame")


class AirlightEmitterSettings(bpy.types.PropertyGroup):
    is_emitter: BoolProperty(
        name="Fog Emitter", default=False,
        description="This object emits smoke particles (Gaussians) into its target fog object")
    enabled: BoolProperty(
        name="Enabled", default=True, update=_on_setting_changed,
        description="Rewrite the target fog object on every frame change")
    target: PointerProperty(
        name="Target", type=bpy.types.Object, poll=_poll_fog, update=_on_setting_changed,
        description="Fog object the particles are written to (created when the emitter is added "
                    "or baked)")
    rate: FloatProperty(
        name="Rate", default=20.0, min=0.01, max=1e5, soft_max=500.0, update=_on_setting_changed,
        description="Particles spawned per second")
    velocity: FloatVectorProperty(
        name="Velocity", size=3, default=(0.0, 0.0, 1.0), subtype='VELOCITY',
        update=_on_setting_changed,
        description="Initial velocity of the particles in the emitter's local frame, m/s")
    spread: FloatProperty(
        name="Spread", default=0.2, min=0.0, soft_max=10.0,
        update=_on_setting_changed,
        description="Standard deviation of a random velocity added to each particle, m/s")
    radius: FloatProperty(
        name="Radius", default=0.1, min=0.0, soft_max=10.0, unit='LENGTH',
        update=_on_setting_changed,
        description="Particles are born at random points of a ball of this radius around the "
                    "emitter (scaled with the emitter)")
    acceleration: FloatVectorProperty(
        name="Acceleration", size=3, default=(0.0, 0.0, 0.3), subtype='ACCELERATION',
        update=_on_setting_changed,
        description="Constant acceleration in world space, m/s^2 (e.g. buoyancy up, wind sideways)")
    color: FloatVectorProperty(
        name="Color", size=3, subtype='COLOR', default=(0.8, 0.8, 0.8), min=0.0, max=1.0,
        update=_on_setting_changed,
        description="Single-scattering albedo of the smoke (the airlight_color attribute)")
    lifetime: FloatProperty(
        name="Lifetime", default=3.0, min=0.01, max=1e4, soft_max=60.0, unit='TIME_ABSOLUTE',
        update=_on_setting_changed,
        description="Seconds each particle lives")
    scale: FloatProperty(
        name="Start Scale", default=4.0, min=1e-3, max=1e4, soft_min=0.05, soft_max=50.0,
        update=_on_setting_changed,
        description="Scale a of a new particle's Gaussian, 1/m (its radius is about 1/a)")
    amplitude: FloatProperty(
        name="Start Amplitude", default=0.5, min=0.0, max=1e4, soft_max=10.0,
        update=_on_setting_changed,
        description="Peak density c of a new particle's Gaussian, 1/m")
    scale_end: FloatProperty(
        name="End Scale Factor", default=0.4, min=0.01, max=1.0, update=_on_setting_changed,
        description="Scale a at the end of the lifetime, as a fraction of the start scale "
                    "(linear in age; smaller a = wider blob)")
    amplitude_end: FloatProperty(
        name="End Amplitude Factor", default=0.0, min=0.0, max=1.0, update=_on_setting_changed,
        description="Amplitude c at the end of the lifetime, as a fraction of the start "
                    "amplitude (linear in age; 0 fades out)")
    seed: IntProperty(
        name="Seed", default=0, min=0, update=_on_setting_changed,
        description="Seed of the particles' random spawn points and velocities")
    frame_start: IntProperty(
        name="Start Frame", default=1, update=_on_setting_changed,
        description="First frame of emission (particle 0 is born here)")
    frame_end: IntProperty(
        name="End Frame", default=250, update=_on_setting_changed,
        description="Last frame of emission (particles born before it live on)")
    baked: CollectionProperty(
        type=AirlightEmitterFrame,
        description="Stored frames written by Bake to Frames")


# ---- operators --------------------------------------------------------------------------


class AIRLIGHT_OT_add_emitter(bpy.types.Operator):
    """Add a fog emitter: an Empty that spawns smoke particles (Gaussians) into a new fog object"""
    bl_idname = "airlight.add_emitter"
    bl_label = "Airlight Fog Emitter"
    bl_options = {'REGISTER', 'UNDO'}

    @classmethod
    def poll(cls, context):
        return context.scene is not None and context.mode == 'OBJECT'

    def execute(self, context):
        collection = context.collection or context.scene.collection
        obj = bpy.data.objects.new("Fog Emitter", None)
        obj.empty_display_type = 'SPHERE'
        obj.empty_display_size = 0.25
        obj.location = context.scene.cursor.location
        collection.objects.link(obj)
        settings = obj.airlight_emitter
        settings.is_emitter = True
        settings.frame_start = context.scene.frame_start
        settings.frame_end = context.scene.frame_end
        ensure_target(obj, collection)
        update_emitter(obj, context.scene)
        # The frame handler rewrites a mesh: renders from the UI run it in the render
        # thread, which is only safe with the interface locked (Blender's advice for
        # handlers that change data).
        context.scene.render.use_lock_interface = True
        for other in context.view_layer.objects:
            other.select_set(False)
        context.view_layer.objects.active = obj
        obj.select_set(True)
        return {'FINISHED'}


def _active_emitter(context):
    obj = context.active_object
    return obj if obj is not None and obj.airlight_emitter.is_emitter else None


def free_bake(obj):
    settings = obj.airlight_emitter
    for item in settings.baked:
        if item.mesh is not None:
            bpy.data.meshes.remove(item.mesh)
    settings.baked.clear()


def bake_frames(obj, scene, frame_start, frame_end, progress=None):
    """Stores the emitter's state of every frame in [frame_start, frame_end] in hidden
    meshes (fake user, so they save with the .blend), replacing an older bake."""
    free_bake(obj)
    settings = obj.airlight_emitter
    target = ensure_target(obj)
    for i, frame in enumerate(range(frame_start, frame_end + 1)):
        centres, scales, amplitudes, colors = evaluate(obj, scene, float(frame))
        mesh = bpy.data.meshes.new(f".{obj.name}.airlight.{frame:05d}")
        mesh.use_fake_user = True
        local, local_scales = to_local(target, centres, scales)
        fog_object.write_mesh(mesh, local, local_scales, amplitudes, colors)
        item = settings.baked.add()
        item.frame = frame
        item.mesh = mesh
        if progress is not None:
            progress(i)
    update_emitter(obj, scene)


class AIRLIGHT_OT_emitter_bake(bpy.types.Operator):
    """Store the emitter's Gaussians of every frame of the scene's range in the .blend (renders
    and playback then read them instead of simulating)"""
    bl_idname = "airlight.emitter_bake"
    bl_label = "Bake to Frames"
    bl_options = {'REGISTER', 'UNDO'}

    @classmethod
    def poll(cls, context):
        if _active_emitter(context) is None:
            cls.poll_message_set("Make a fog emitter active")
            return False
        if not fog_object.poll_editable(cls, context.active_object):
            return False
        return True

    def execute(self, context):
        obj = _active_emitter(context)
        scene = context.scene
        wm = context.window_manager
        wm.progress_begin(0, max(1, scene.frame_end - scene.frame_start + 1))
        try:
            bake_frames(obj, scene, scene.frame_start, scene.frame_end, progress=wm.progress_update)
        except EmitterError as ex:
            free_bake(obj)
            self.report({'ERROR'}, str(ex))
            return {'CANCELLED'}
        finally:
            wm.progress_end()
        n = len(obj.airlight_emitter.baked)
        self.report({'INFO'}, f"Baked {n} frames of '{obj.name}'")
        return {'FINISHED'}


class AIRLIGHT_OT_emitter_free_bake(bpy.types.Operator):
    """Delete the emitter's stored frames (it simulates live again)"""
    bl_idname = "airlight.emitter_free_bake"
    bl_label = "Free Bake"
    bl_options = {'REGISTER', 'UNDO'}

    @classmethod
    def poll(cls, context):
        obj = _active_emitter(context)
        return (obj is not None and len(obj.airlight_emitter.baked) > 0
                and fog_object.edit_problem(obj) is None)

    def execute(self, context):
        obj = _active_emitter(context)
        free_bake(obj)
        update_emitter(obj, context.scene)
        return {'FINISHED'}


class AIRLIGHT_OT_emitter_update(bpy.types.Operator):
    """Write the emitter's particles at the current frame into its target fog object
    (creating the target if it is missing)"""
    bl_idname = "airlight.emitter_update"
    bl_label = "Update Emitter"
    bl_options = {'REGISTER', 'UNDO'}

    @classmethod
    def poll(cls, context):
        return _active_emitter(context) is not None

    def execute(self, context):
        obj = _active_emitter(context)
        try:
            ensure_target(obj)
            n = update_emitter(obj, context.scene)
        except EmitterError as ex:
            self.report({'ERROR'}, str(ex))
            return {'CANCELLED'}
        self.report({'INFO'}, f"{n or 0} live particles")
        return {'FINISHED'}


class AIRLIGHT_PT_emitter(bpy.types.Panel):
    bl_label = "Airlight Fog Emitter"
    bl_idname = "AIRLIGHT_PT_emitter"
    bl_space_type = 'PROPERTIES'
    bl_region_type = 'WINDOW'
    bl_context = "object"

    @classmethod
    def poll(cls, context):
        obj = context.object
        return obj is not None and obj.airlight_emitter.is_emitter

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        settings = context.object.airlight_emitter
        layout.prop(settings, "enabled")
        layout.prop(settings, "target")
        try:
            check_params(params(settings, context.scene))
        except EmitterError as ex:
            layout.label(text=str(ex), icon='ERROR')
        col = layout.column(align=True)
        col.prop(settings, "rate")
        col.prop(settings, "lifetime")
        col.prop(settings, "frame_start")
        col.prop(settings, "frame_end")
        col.prop(settings, "seed")
        col = layout.column()
        col.prop(settings, "radius")
        col.prop(settings, "velocity")
        col.prop(settings, "spread")
        col.prop(settings, "acceleration")
        col = layout.column(align=True)
        col.prop(settings, "scale")
        col.prop(settings, "amplitude")
        col.prop(settings, "scale_end")
        col.prop(settings, "amplitude_end")
        layout.prop(settings, "color")
        row = layout.row(align=True)
        row.operator("airlight.emitter_update", icon='FILE_REFRESH')
        row.operator("airlight.emitter_bake", icon='REC')
        row.operator("airlight.emitter_free_bake", icon='TRASH')
        if len(settings.baked):
            frames = [item.frame for item in settings.baked]
            layout.label(text=f"Baked frames {min(frames)}-{max(frames)} (stored in the .blend)",
                         icon='CHECKMARK')


def _menu_add(self, context):
    self.layout.operator(AIRLIGHT_OT_add_emitter.bl_idname, icon='OUTLINER_OB_FORCE_FIELD')


classes = (AirlightEmitterFrame, AirlightEmitterSettings, AIRLIGHT_OT_add_emitter,
           AIRLIGHT_OT_emitter_bake, AIRLIGHT_OT_emitter_free_bake, AIRLIGHT_OT_emitter_update,
           AIRLIGHT_PT_emitter)


def register():
    for cls in classes:
        bpy.utils.register_class(cls)
    bpy.types.Object.airlight_emitter = PointerProperty(type=AirlightEmitterSettings)
    bpy.types.VIEW3D_MT_add.append(_menu_add)
    if on_frame_change_post not in bpy.app.handlers.frame_change_post:
        bpy.app.handlers.frame_change_post.append(on_frame_change_post)


def unregister():
    while on_frame_change_post in bpy.app.handlers.frame_change_post:
        bpy.app.handlers.frame_change_post.remove(on_frame_change_post)
    bpy.types.VIEW3D_MT_add.remove(_menu_add)
    del bpy.types.Object.airlight_emitter
    for cls in reversed(classes):
        bpy.utils.unregister_class(cls)
