"""Airbrush and Fill Mesh with Fog (Zhou et al. 2007, section 6) on the active fog object.

- Airbrush (`airlight.airbrush`): while the left button is held, particles are shot from
  the brush position (the first surface under the mouse, backed off along its normal by
  `offset`/a, or `distance` along the view ray when nothing is hit) in random directions
  (the hemisphere facing away from a hit surface) at `speed`. Every step (a timer, and
  every mouse move) each particle moves by velocity dt plus a diffusion random walk
  (sqrt(2 D dt) normal steps), its velocity decays by exp(-damping dt), and the move is
  ray cast against the scene's surfaces (a mathutils BVHTree built once when a stroke
  starts): a particle that would cross a surface stops a margin short of it and the rest
  of its move and its velocity are mirrored. So particles bounce and diffuse out but stay
  in the open region they were shot into. Each particle is drawn as a point during the
  stroke; on release they freeze into the fog object as Gaussians (scale a, amplitude c
  from the airbrush settings): one undo step. Esc or right-click cancels (nothing written).
  F adjusts the radius 1/a, Shift+F the amplitude, as in the paintbrush.
- Fill Mesh with Fog (`airlight.fill_mesh`): fills the interior of the selected closed
  meshes with Gaussians on a cubic grid of spacing `fill_spacing`/a; a grid point is
  inside when a ray from it crosses the surface an odd number of times.

The simulation is pure functions (`spawn`, `step`, `scene_bvh`, `inside_mask`,
`fill_points`), tested headless; the operator only feeds them events.
"""

import math
import time

import bpy
import numpy as np
from bpy.props import FloatProperty, IntProperty, PointerProperty

from . import brush_ops, fog_object

# ---- pure simulation --------------------------------------------------------------------


def scene_bvh(depsgraph, exclude=()):
    """A BVHTree of every evaluated mesh-like object's triangles in world space (fog
    objects, which are vertices only, and objects named in _exclude_ left out), or None
    when the scene has no surfaces."""
    from mathutils.bvhtree import BVHTree
    verts, tris, base = [], [], 0
    for instance in depsgraph.object_instances:
        obj = instance.object
        if obj.type not in {'MESH', 'CURVE', 'SURFACE', 'META', 'FONT'}:
            continue
        if fog_object.is_fog_object(obj) or obj.original.name in exclude:
            continue
        try:
            mesh = obj.to_mesh()
        except RuntimeError:
            continue
        if mesh is None:
            continue
        try:
            mesh.calc_loop_triangles()
            n_v, n_t = len(mesh.vertices), len(mesh.loop_triangles)
            if n_v and n_t:
                co = np.empty(3 * n_v, dtype=np.float64)
                mesh.vertices.foreach_get("co", co)
                tri = np.empty(3 * n_t, dtype=np.int64)
                mesh.loop_triangles.foreach_get("vertices", tri)
                m = np.array(instance.matrix_world, dtype=np.float64)
                verts.append(co.reshape(-1, 3) @ m[:3, :3].T + m[:3, 3])
                tris.append(tri.reshape(-1, 3) + base)
                base += n_v
        finally:
            obj.to_mesh_clear()
    if not verts:
        return None
    return BVHTree.FromPolygons(np.concatenate(verts).tolist(), np.concatenate(tris).tolist(),
                                all_triangles=True)


def spawn(origin, normal, count, speed, rng):
    """_count_ particles at _origin_ with velocities of length _speed_ in uniformly random
    directions, restricted to the hemisphere around _normal_ when it is given."""
    d = rng.normal(size=(count, 3))
    d /= np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-300)
    if normal is not None:
        n = np.asarray(normal, dtype=np.float64)
        n = n / np.linalg.norm(n)
        flip = d @ n < 0.0
        d[flip] -= 2.0 * np.outer(d[flip] @ n, n)
    positions = np.broadcast_to(np.asarray(origin, dtype=np.float64), (count, 3)).copy()
    return positions, d * speed


def step(positions, velocities, dt, diffusion, damping, bvh, rng, margin=1e-4, max_bounces=4):
    """Moves particles by v dt + a sqrt(2 D dt) normal random walk, bouncing off the
    BVHTree's triangles (mirror reflection of the remaining move and of the velocity),
    and damps the velocity by exp(-damping dt). Returns new (positions, velocities).
    A particle never crosses a surface: each straight piece of its move is ray cast and
    stops _margin_ short of the first hit; a move still blocked after _max_bounces_ ends
    there."""
    from mathutils import Vector
    positions = np.array(positions, dtype=np.float64).reshape(-1, 3)
    velocities = np.array(velocities, dtype=np.float64).reshape(-1, 3)
    n = len(positions)
    if n == 0 or dt <= 0.0:
        return positions, velocities
    moves = velocities * dt
    if diffusion > 0.0:
        moves += math.sqrt(2.0 * diffusion * dt) * rng.normal(size=(n, 3))
    if bvh is None:
        return positions + moves, velocities * math.exp(-damping * dt)
    # mathutils Vectors in the loop: numpy calls on 3-vectors cost microseconds each.
    pos_out, vel_out = [], []
    ray_cast = bvh.ray_cast
    for p, rem, v in zip(map(Vector, positions.tolist()), map(Vector, moves.tolist()),
                         map(Vector, velocities.tolist())):
        for _ in range(max_bounces):
            length = rem.length
            if length < 1e-12:
                break
            direction = rem / length
            loc, normal, _, dist = ray_cast(p, direction, length + margin)
            if loc is None:
                p = p + rem
                break
            if normal.dot(direction) > 0.0:
                normal = -normal
            travel = max(dist - margin, 0.0)
            p = p + direction * travel
            rem = direction.reflect(normal) * (length - travel)
            v = v.reflect(normal)
        pos_out.append(p)
        vel_out.append(v)
    positions = np.array(pos_out, dtype=np.float64).reshape(-1, 3)
    velocities = np.array(vel_out, dtype=np.float64).reshape(-1, 3)
    return positions, velocities * math.exp(-damping * dt)


def inside_mask(bvh, points, direction=(0.5773, 0.5779, 0.5768)):
    """True for points inside the closed surface in _bvh_ (an odd number of crossings
    along a ray; the direction is skewed off the axes so rays rarely graze edges)."""
    from mathutils import Vector
    d = Vector(direction).normalized()
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    inside = np.zeros(len(points), dtype=bool)
    for i, q in enumerate(points):
        p = Vector(q)
        count = 0
        for _ in range(10000):
            loc, _, _, _ = bvh.ray_cast(p, d)
            if loc is None:
                break
            count += 1
            p = loc + d * 1e-6
        inside[i] = count % 2 == 1
    return inside


def fill_points(bvh, lo, hi, spacing, max_points=2_000_000):
    """Grid points of _spacing_ inside the surface in _bvh_, over the box [lo, hi]; the
    grid is centred in the box."""
    lo, hi = np.asarray(lo, dtype=np.float64), np.asarray(hi, dtype=np.float64)
    counts = np.maximum(np.floor((hi - lo) / spacing).astype(np.int64) + 1, 1)
    if int(np.prod(counts)) > max_points:
        raise ValueError(f"Fill grid of {int(np.prod(counts))} points is too fine (at most "
                         f"{max_points}): raise the spacing or lower the scale")
    start = 0.5 * (lo + hi) - 0.5 * (counts - 1) * spacing
    axes = [start[i] + spacing * np.arange(counts[i]) for i in range(3)]
    grid = np.stack(np.meshgrid(*axes, indexing='ij'), axis=-1).reshape(-1, 3)
    return grid[inside_mask(bvh, grid)]


# ---- settings ---------------------------------------------------------------------------


class AirlightAirbrushSettings(bpy.types.PropertyGroup):
    scale: FloatProperty(
        name="Scale", default=4.0, min=1e-3, max=1e4, soft_min=0.05, soft_max=50.0,
        description="Scale a of the airbrush's Gaussians, in 1/m: each blob's radius is about "
                    "1/a (F in the airbrush adjusts it)")
    amplitude: FloatProperty(
        name="Amplitude", default=0.05, min=0.0, max=1e4, soft_max=5.0,
        description="Peak density c of each airbrush Gaussian, in 1/m (Shift+F in the airbrush "
                    "adjusts it)")
    rate: FloatProperty(
        name="Rate", default=300.0, min=1.0, max=1e5, soft_max=5000.0,
        description="Particles shot per second while the button is held")
    speed: FloatProperty(
        name="Speed", default=3.0, min=0.0, max=1e4, soft_max=50.0,
        description="Initial speed of the particles, m/s")
    diffusion: FloatProperty(
        name="Diffusion", default=0.3, min=0.0, max=1e4, soft_max=10.0,
        description="Diffusion coefficient D of the particles' random walk, m^2/s")
    damping: FloatProperty(
        name="Damping", default=2.0, min=0.0, max=1e3, soft_max=20.0,
        description="Velocity decay rate, 1/s (velocity falls by exp(-damping dt))")
    distance: FloatProperty(
        name="Distance", default=5.0, min=0.0, max=1e5, soft_max=100.0, unit='LENGTH',
        description="Where particles start when no surface is under the mouse: this far along "
                    "the view ray (perspective) or at the 3D cursor's depth (orthographic)")
    offset: FloatProperty(
        name="Offset", default=1.0, min=0.0, max=100.0,
        description="How far particles start from the surface under the mouse, in units of 1/a")
    max_particles: IntProperty(
        name="Max Particles", default=5000, min=1, max=1_000_000,
        description="The airbrush stops shooting when a stroke has this many particles")
    seed: IntProperty(
        name="Seed", default=0, min=0,
        description="Seed of the particles' directions and random walks (each stroke also mixes "
                    "in the object's Gaussian count)")
    fill_spacing: FloatProperty(
        name="Fill Spacing", default=0.75, min=0.05, max=10.0,
        description="Grid spacing of Fill Mesh with Fog, in units of 1/a")


def _scale_radius_get(self):
    return 1.0 / self.scale


def _scale_radius_set(self, value):
    self.scale = 1.0 / value


AirlightAirbrushSettings.__annotations__["scale_radius"] = FloatProperty(
    name="Radius",
    description="Radius 1/a of the airbrush's Gaussians, in m (the inverse of Scale)",
    get=_scale_radius_get, set=_scale_radius_set, min=1e-4, max=1e3, unit='LENGTH',
)


# ---- operators --------------------------------------------------------------------------


class AIRLIGHT_OT_airbrush(brush_ops._FogBrush, bpy.types.Operator):
    """Spray fog particles that bounce off surfaces and diffuse; on release they freeze into
    the active fog object (hold left button; F size, Shift+F amplitude, Esc cancels)"""
    bl_idname = "airlight.airbrush"
    bl_label = "Airbrush"
    bl_options = {'REGISTER', 'UNDO'}
    hint = ("Airbrush: hold left button to spray, F size (1/a), Shift+F amplitude, "
            "Esc/right-click cancels")
    timer_interval = 1.0 / 30.0

    def adjust_targets(self):
        return "scale_radius", "amplitude"

    def brush_radius_px(self, context):
        return self.scale_radius_px(context)

    def invoke(self, context, event):
        self._timer = None
        self._bvh = None
        self._state_colour = (0.6, 0.8, 1.0, 0.8)
        return super().invoke(context, event)

    def _source(self, context, xy):
        """(start point, surface normal or None) of new particles under pixel _xy_."""
        from bpy_extras import view3d_utils
        settings = context.scene.airlight_airbrush
        rv3d = self._area.spaces.active.region_3d
        origin = view3d_utils.region_2d_to_origin_3d(self._region, rv3d, xy)
        direction = view3d_utils.region_2d_to_vector_3d(self._region, rv3d, xy).normalized()
        if self._bvh is not None:
            loc, normal, _, _ = self._bvh.ray_cast(origin, direction)
            if loc is not None:
                n = normal.normalized()
                if n.dot(direction) > 0.0:
                    n = -n
                back = settings.offset / settings.scale
                blocked = self._bvh.ray_cast(loc + n * 1e-4, n, back)
                if blocked[0] is not None:  # another surface closer than the offset
                    back = 0.5 * blocked[3]
                return np.array(loc + n * back), np.array(n)
        if rv3d.is_perspective:
            return np.array(origin + direction * settings.distance), None
        p = view3d_utils.region_2d_to_location_3d(self._region, rv3d, xy, context.scene.cursor.location)
        return np.array(p), None

    def stroke_begin(self, context, xy):
        settings = context.scene.airlight_airbrush
        self._bvh = scene_bvh(context.evaluated_depsgraph_get())
        self._rng = np.random.default_rng((settings.seed, len(self._object.data.vertices)))
        self._pos = np.zeros((0, 3))
        self._vel = np.zeros((0, 3))
        self._owed = 1.0  # the press itself shoots one particle
        self._xy = xy
        self._last = time.perf_counter()
        self._timer = context.window_manager.event_timer_add(self.timer_interval, window=context.window)
        self._state.colour = self._state_colour
        self._advance(context, 0.0)

    def _advance(self, context, dt):
        """Shoots rate * dt new particles (fractions carried over) and steps them all."""
        settings = context.scene.airlight_airbrush
        self._owed += settings.rate * dt
        count = min(int(self._owed), settings.max_particles - len(self._pos))
        if count > 0:
            self._owed -= count
            origin, normal = self._source(context, self._xy)
            p, v = spawn(origin, normal, count, settings.speed, self._rng)
            self._pos = np.concatenate([self._pos, p])
            self._vel = np.concatenate([self._vel, v])
        self._pos, self._vel = step(self._pos, self._vel, dt, settings.diffusion, settings.damping,
                                    self._bvh, self._rng)
        self._state.points = self._pos

    def _tick(self, context):
        now = time.perf_counter()
        dt = min(now - self._last, 0.1)  # a stalled UI must not throw particles through walls
        self._last = now
        self._advance(context, dt)

    def stroke_move(self, context, xy):
        self._xy = xy
        self._tick(context)

    def stroke_end(self, context):
        self._tick(context)
        if len(self._pos) == 0:
            return False
        settings = context.scene.airlight_airbrush
        matrix = np.array(self._object.matrix_world, dtype=np.float64)
        s = fog_object.uniform_scale(matrix[:3, :3])
        local = (self._pos - matrix[:3, 3]) @ np.linalg.inv(matrix[:3, :3]).T
        fog_object.append(self._object, local, settings.scale * s, settings.amplitude)
        return True

    def _cleanup(self, context):
        if self._timer is not None:
            context.window_manager.event_timer_remove(self._timer)
            self._timer = None
        super()._cleanup(context)

    def tool_settings(self, context):
        return context.scene.airlight_airbrush

    def other_event(self, context, event):
        if event.type == 'TIMER':  # any timer (3.4 events don't say which): steps use real dt
            if self._stroking:
                self._tick(context)
                return {'RUNNING_MODAL'}
            return {'PASS_THROUGH'}
        return None


class AIRLIGHT_OT_fill_mesh(bpy.types.Operator):
    """Fill the inside of the selected closed meshes with Gaussians (a grid of spacing
    Fill Spacing/a) added to the active fog object"""
    bl_idname = "airlight.fill_mesh"
    bl_label = "Fill Mesh with Fog"
    bl_options = {'REGISTER', 'UNDO'}

    @classmethod
    def poll(cls, context):
        if context.mode != 'OBJECT':
            cls.poll_message_set("Switch to Object Mode")
            return False
        if not fog_object.is_fog_object(context.active_object):
            cls.poll_message_set("Make the fog object to fill active")
            return False
        if not fog_object.poll_editable(cls, context.active_object):
            return False
        if not _fill_sources(context):
            cls.poll_message_set("Select a closed mesh to fill (besides the active fog object)")
            return False
        return True

    def execute(self, context):
        settings = context.scene.airlight_airbrush
        target = context.active_object
        depsgraph = context.evaluated_depsgraph_get()
        spacing = settings.fill_spacing / settings.scale
        found = []
        wm = context.window_manager
        sources = _fill_sources(context)
        wm.progress_begin(0, len(sources))
        try:
            for i, obj in enumerate(sources):
                others = {o.name for o in context.scene.objects if o != obj}
                bvh = scene_bvh(depsgraph, exclude=others)
                if bvh is None:
                    continue
                corners = _world_bounds(obj.evaluated_get(depsgraph))
                found.append(fill_points(bvh, corners.min(0), corners.max(0), spacing))
                wm.progress_update(i + 1)
        except ValueError as ex:
            self.report({'ERROR'}, str(ex))
            return {'CANCELLED'}
        finally:
            wm.progress_end()
        points = np.concatenate(found) if found else np.zeros((0, 3))
        if len(points) == 0:
            self.report({'WARNING'}, "No grid point inside the selected meshes (not closed, or "
                                     "smaller than the spacing)")
            return {'CANCELLED'}
        matrix = np.array(target.matrix_world, dtype=np.float64)
        s = fog_object.uniform_scale(matrix[:3, :3])
        local = (points - matrix[:3, 3]) @ np.linalg.inv(matrix[:3, :3]).T
        fog_object.append(target, local, settings.scale * s, settings.amplitude)
        self.report({'INFO'}, f"Added {len(points)} Gaussians to '{target.name}'")
        return {'FINISHED'}


def _world_bounds(obj):
    m = np.array(obj.matrix_world, dtype=np.float64)
    corners = np.array([tuple(c) for c in obj.bound_box], dtype=np.float64)
    return corners @ m[:3, :3].T + m[:3, 3]


def _fill_sources(context):
    return [o for o in context.selected_objects
            if o.type == 'MESH' and not fog_object.is_fog_object(o) and o != context.active_object]


classes = (AirlightAirbrushSettings, AIRLIGHT_OT_airbrush, AIRLIGHT_OT_fill_mesh)


def register():
    for cls in classes:
        bpy.utils.register_class(cls)
    bpy.types.Scene.airlight_airbrush = PointerProperty(type=AirlightAirbrushSettings)


def unregister():
    del bpy.types.Scene.airlight_airbrush
    for cls in reversed(classes):
        bpy.utils.unregister_class(cls)
