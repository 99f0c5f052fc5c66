"""Fog paintbrush and eraser (Zhou et al. 2007, section 6) on the active fog object.

- Paintbrush (`airlight.fog_paint`): left-drag places Gaussians along the stroke, the
  stroke projected onto a plane (the view plane through the 3D cursor, the ground plane
  z = cursor z, or the surface under the mouse offset along its normal by 1/a). Adjacent
  Gaussians are `spacing`/a apart along the stroke (0.75/a by default) and each is moved
  by a random vector in the plane perpendicular to the stroke, shorter than 1/a.
- Eraser (`airlight.fog_erase`): lowers the amplitude of the Gaussians whose centres
  project inside the brush circle (smooth falloff) and deletes those that reach zero.

One operator run is one stroke and one undo step: the stroke is kept in numpy arrays
while dragging (drawn as points) and written to the mesh in bulk on release; Esc or
right-click cancels it and leaves the object untouched. F adjusts the size and Shift+F
the strength (move the mouse, click to confirm, Esc restores).

The stroke logic is in pure functions (`resample_stroke`, `paint_dabs`,
`project_points`, `erase`), tested headless; the operators only feed them events.
"""

import math

import bpy
import numpy as np
from bpy.props import EnumProperty, FloatProperty, IntProperty, PointerProperty

from . import fog_object

# ---- pure stroke logic ------------------------------------------------------------------


def resample_stroke(points, spacing, offset=0.0):
    """Positions every _spacing_ along the polyline _points_ (k, D), starting at arc length
    _offset_. Returns (positions (m, D), unit tangents (m, D), arc lengths (m,)).
    A single point (or a zero-length stroke) gives one position at the start."""
    points = np.asarray(points, dtype=np.float64)
    if points.ndim != 2 or len(points) == 0:
        raise ValueError("a stroke needs at least one point")
    if not spacing > 0.0:
        raise ValueError(f"spacing must be > 0, got {spacing}")
    seg = np.diff(points, axis=0)
    seg_len = np.linalg.norm(seg, axis=1)
    keep = seg_len > 0.0
    seg, seg_len = seg[keep], seg_len[keep]
    starts = points[:-1][keep]
    dim = points.shape[1]
    if len(seg) == 0:
        tangent = np.zeros((1, dim))
        tangent[0, 0] = 1.0
        return points[:1].copy(), tangent, np.zeros(1)
    cum = np.concatenate([[0.0], np.cumsum(seg_len)])
    total = cum[-1]
    s = offset + spacing * np.arange(int(math.floor((total - offset) / spacing + 1e-9)) + 1)
    s = s[(s >= 0.0) & (s <= total + 1e-12)]
    index = np.clip(np.searchsorted(cum, s, side='right') - 1, 0, len(seg) - 1)
    local = (s - cum[index]) / seg_len[index]
    positions = starts[index] + seg[index] * local[:, None]
    tangents = seg[index] / seg_len[index, None]
    return positions, tangents, s


def perpendicular_offsets(tangents, max_length, rng):
    """Random vectors in the planes perpendicular to _tangents_ (m, 3), uniform over the
    disc of radius _max_length_ (strictly shorter than it)."""
    tangents = np.asarray(tangents, dtype=np.float64).reshape(-1, 3)
    m = len(tangents)
    # An orthonormal basis (u, v) of each tangent's normal plane.
    helper = np.where(np.abs(tangents[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    u = np.cross(tangents, helper)
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    v = np.cross(tangents, u)
    r_phi = rng.random((m, 2))
    r = max_length * np.sqrt(r_phi[:, 0])  # random() < 1, so r < max_length
    phi = 2.0 * math.pi * r_phi[:, 1]
    return (r * np.cos(phi))[:, None] * u + (r * np.sin(phi))[:, None] * v


def paint_dabs(points, scale, spacing=0.75, jitter=1.0, seed=0):
    """Gaussian centres for a stroke through _points_ (k, 3) world space: one every
    spacing/scale along the stroke, each offset perpendicular to it by less than
    jitter/scale. Deterministic for a seed; a longer stroke repeats the shorter one's
    first centres (the random stream is consumed in stroke order)."""
    if not scale > 0.0:
        raise ValueError(f"scale a must be > 0, got {scale}")
    if not 0.0 <= jitter <= 1.0:
        raise ValueError(f"jitter must be in [0, 1], got {jitter}")
    positions, tangents, _ = resample_stroke(points, spacing / scale)
    rng = np.random.default_rng(seed)
    return positions + perpendicular_offsets(tangents, jitter / scale, rng)


def project_points(points, perspective_matrix, width, height):
    """Region pixel coordinates (n, 2) of world _points_ (n, 3) under a 4x4 view-projection
    matrix, and a mask of points in front of the viewer."""
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    m = np.asarray(perspective_matrix, dtype=np.float64)
    clip = points @ m[:3, :3].T + m[:3, 3]
    w = points @ m[3, :3] + m[3, 3]
    visible = w > 1e-9
    w_safe = np.where(visible, w, 1.0)
    xy = np.empty((len(points), 2))
    xy[:, 0] = (clip[:, 0] / w_safe + 1.0) * 0.5 * width
    xy[:, 1] = (clip[:, 1] / w_safe + 1.0) * 0.5 * height
    return xy, visible


def falloff(distance, radius):
    """Smooth brush falloff (1 - (d/R)^2)^2 inside the radius, 0 outside."""
    q = np.clip(np.asarray(distance, dtype=np.float64) / radius, 0.0, 1.0)
    return (1.0 - q * q) ** 2


def erase(xy, visible, amplitudes, centre, radius, strength):
    """One eraser dab at pixel _centre_: amplitudes lowered by strength * falloff; returns
    (new amplitudes, keep mask): Gaussians that reached zero are not kept."""
    amplitudes = np.asarray(amplitudes, dtype=np.float64)
    d = np.linalg.norm(np.asarray(xy, dtype=np.float64) - np.asarray(centre, dtype=np.float64), axis=1)
    amount = np.where(np.asarray(visible, dtype=bool), strength * falloff(d, radius), 0.0)
    new = np.maximum(amplitudes - amount, 0.0)
    return new, new > 0.0


# ---- settings ---------------------------------------------------------------------------


class AirlightBrushSettings(bpy.types.PropertyGroup):
    plane: EnumProperty(
        name="Plane",
        description="Where the paintbrush stroke is placed in 3D",
        items=(
            ('VIEW', "View Plane", "The plane facing the view through the 3D cursor"),
            ('GROUND', "Ground", "The horizontal plane at the 3D cursor's height"),
            ('SURFACE', "Surface", "The surface under the mouse, offset along its normal by 1/a"),
        ),
        default='VIEW',
    )
    scale: FloatProperty(
        name="Scale",
        description="Scale a of painted Gaussians, in 1/m: each blob's radius is about 1/a "
                    "(F in the brush adjusts it)",
        default=1.0, min=1e-3, max=1e4, soft_min=0.05, soft_max=50.0,
    )
    amplitude: FloatProperty(
        name="Amplitude",
        description="Peak density c of painted Gaussians, in 1/m (Shift+F in the brush adjusts it)",
        default=0.2, min=0.0, max=1e4, soft_max=5.0,
    )
    spacing: FloatProperty(
        name="Spacing",
        description="Distance between adjacent Gaussians along the stroke, in units of 1/a",
        default=0.75, min=0.05, max=10.0,
    )
    jitter: FloatProperty(
        name="Jitter",
        description="Largest random offset of each Gaussian perpendicular to the stroke, "
                    "as a fraction of 1/a",
        default=1.0, min=0.0, max=1.0,
    )
    seed: IntProperty(
        name="Seed",
        description="Seed of the random offsets (each stroke also mixes in the object's "
                    "Gaussian count, so strokes differ)",
        default=0, min=0,
    )
    radius: FloatProperty(
        name="Eraser Radius",
        description="Radius of the eraser circle in pixels (F in the eraser adjusts it)",
        default=50.0, min=1.0, max=2000.0, subtype='PIXEL',
    )
    strength: FloatProperty(
        name="Eraser Strength",
        description="Amplitude the eraser removes per dab at its centre, in 1/m "
                    "(Shift+F in the eraser adjusts it)",
        default=0.1, min=0.0, max=1e4, soft_max=2.0,
    )


# ---- drawing ----------------------------------------------------------------------------

# Live draw handlers (removed on every exit path and on unregister).
_draw_handles = set()
_draw_count = [0]


def _uniform_color_shader():
    import gpu
    for name in ('UNIFORM_COLOR', '2D_UNIFORM_COLOR'):  # 4.x name first, then 3.4's
        try:
            return gpu.shader.from_builtin(name)
        except (ValueError, SystemError):
            continue
    raise RuntimeError("no built-in uniform colour shader")


class _DrawState:
    """What the POST_PIXEL callback draws (a plain object, not the operator)."""

    def __init__(self, region_pointer):
        self.region_pointer = region_pointer
        self.mouse = (0.0, 0.0)
        self.radius = 10.0
        self.points = np.zeros((0, 3))  # world space, drawn projected
        self.colour = (1.0, 1.0, 1.0, 0.8)


def draw_overlay(state, outline, outline_colour, points_colour):
    """Draws a modal tool's screen-space outline (N x 2 pixels, a line strip) and its
    world-space `state.points` projected, in the tool's own region only, never during
    renders, restoring the gpu state it changes. Shared by every fog tool."""
    context = bpy.context
    region = context.region
    if region is None or region.as_pointer() != state.region_pointer:
        return False
    if getattr(bpy.app, "is_job_running", lambda kind: False)('RENDER'):
        return False
    import gpu
    from gpu_extras.batch import batch_for_shader
    shader = _uniform_color_shader()
    gpu.state.blend_set('ALPHA')
    gpu.state.line_width_set(1.5)
    try:
        shader.bind()
        if outline is not None:
            shader.uniform_float("color", outline_colour)
            batch_for_shader(shader, 'LINE_STRIP', {"pos": outline.astype(np.float32)}).draw(shader)
        if len(state.points):
            xy, visible = project_points(state.points, context.region_data.perspective_matrix,
                                         region.width, region.height)
            if visible.any():
                gpu.state.point_size_set(4.0)
                shader.uniform_float("color", points_colour)
                batch_for_shader(shader, 'POINTS', {"pos": xy[visible].astype(np.float32)}).draw(shader)
                gpu.state.point_size_set(1.0)
    finally:
        gpu.state.line_width_set(1.0)
        gpu.state.blend_set('NONE')
    return True


def remove_draw_handle(handles, handle):
    """Removes a SpaceView3D WINDOW draw handler once, forgetting it in `handles`."""
    if handle in handles:
        handles.discard(handle)
        bpy.types.SpaceView3D.draw_handler_remove(handle, 'WINDOW')


def _draw_callback(state):
    phi = np.linspace(0.0, 2.0 * math.pi, 49)
    circle = np.stack([state.mouse[0] + state.radius * np.cos(phi),
                       state.mouse[1] + state.radius * np.sin(phi)], axis=1)
    if draw_overlay(state, circle, state.colour, (1.0, 1.0, 1.0, 0.9)):
        _draw_count[0] += 1


# ---- operators --------------------------------------------------------------------------


def _window_region(area):
    for region in area.regions:
        if region.type == 'WINDOW':
            return region
    return None


class _FogBrush:
    """Shared modal machinery: the draw handler, header/status text, F / Shift+F."""
    bl_options = {'REGISTER', 'UNDO'}
    hint = ""

    @classmethod
    def poll(cls, context):
        if context.area is None or context.area.type != 'VIEW_3D':
            cls.poll_message_set("Run from a 3D viewport")
            return False
        if context.mode != 'OBJECT':
            cls.poll_message_set("Switch to Object Mode")
            return False
        if not fog_object.is_fog_object(context.active_object):
            cls.poll_message_set("Make a fog object active (Add > Airlight Fog Object)")
            return False
        if not fog_object.poll_editable(cls, context.active_object):
            return False
        return True

    # ---- hooks of the tools
    def adjust_targets(self):
        """(property for F, property for Shift+F), names in tool_settings()."""
        raise NotImplementedError

    def brush_radius_px(self, context):
        raise NotImplementedError

    def stroke_begin(self, context, xy):
        raise NotImplementedError

    def stroke_move(self, context, xy):
        raise NotImplementedError

    def stroke_end(self, context):
        """Writes the stroke; returns True when the object changed."""
        raise NotImplementedError

    # ---- common
    def _mouse(self, event):
        return (float(event.mouse_x - self._region.x), float(event.mouse_y - self._region.y))

    def invoke(self, context, event):
        self._area = context.area
        self._region = _window_region(context.area)
        if self._region is None or context.space_data.region_3d is None:
            self.report({'ERROR'}, "No 3D viewport region to paint in")
            return {'CANCELLED'}
        self._object = context.active_object
        self._stroking = False
        self._adjust = None  # (name, start value, start mouse x)
        self._state = _DrawState(self._region.as_pointer())
        self._state.mouse = self._mouse(event)
        self._handle = bpy.types.SpaceView3D.draw_handler_add(
            _draw_callback, (self._state,), 'WINDOW', 'POST_PIXEL')
        _draw_handles.add(self._handle)
        self._update_circle(context)
        self._set_text(context, self.hint)
        context.window_manager.modal_handler_add(self)
        if event.type == 'LEFTMOUSE' and event.value == 'PRESS':  # invoked by a drag
            self._begin(context, self._state.mouse)
        self._area.tag_redraw()
        return {'RUNNING_MODAL'}

    def _set_text(self, context, text):
        if self._area is not None:
            self._area.header_text_set(text)
        if context.workspace is not None:
            context.workspace.status_text_set(text)

    def _cleanup(self, context):
        remove_draw_handle(_draw_handles, self._handle)
        self._handle = None
        self._set_text(context, None)
        self._area.tag_redraw()

    def _update_circle(self, context):
        self._state.radius = self.brush_radius_px(context)

    def _begin(self, context, xy):
        self._stroking = True
        self.stroke_begin(context, xy)

    def modal(self, context, event):
        try:
            return self._modal(context, event)
        except Exception:
            self._cleanup(context)
            raise

    def scale_radius_px(self, context):
        """The tool's Gaussian radius 1/a (tool_settings().scale) in pixels, projected at the 3D
        cursor's depth: the brush circle of the tools that place Gaussians."""
        from bpy_extras import view3d_utils
        from mathutils import Vector
        rv3d = self._area.spaces.active.region_3d
        settings = self.tool_settings(context)
        cursor = context.scene.cursor.location
        right = rv3d.view_rotation @ Vector((1.0, 0.0, 0.0))
        a = view3d_utils.location_3d_to_region_2d(self._region, rv3d, cursor)
        b = view3d_utils.location_3d_to_region_2d(self._region, rv3d, cursor + right / settings.scale)
        if a is None or b is None:
            return 20.0
        return max(2.0, float((a - b).length))

    def tool_settings(self, context):
        """The property group that F / Shift+F adjust (adjust_targets names its properties)."""
        return context.scene.airlight_brush

    def other_event(self, context, event):
        """A subclass's own events (after F-adjusting and cancelling are handled, before
        strokes): a modal result to return, or None to go on."""
        return None

    def _modal(self, context, event):
        settings = self.tool_settings(context)
        if event.type in {'MOUSEMOVE', 'INBETWEEN_MOUSEMOVE', 'LEFTMOUSE', 'RIGHTMOUSE', 'ESC'}:
            self._state.mouse = self._mouse(event)
        self._area.tag_redraw()

        if self._adjust is not None:  # F / Shift+F: mouse x scales the value
            name, start, start_x = self._adjust
            if event.type == 'MOUSEMOVE':
                prop = settings.bl_rna.properties[name]
                value = start * 2.0 ** ((self._state.mouse[0] - start_x) / 100.0)
                setattr(settings, name, min(max(value, prop.hard_min), prop.hard_max))
                self._update_circle(context)
            elif event.type in {'LEFTMOUSE', 'RET', 'NUMPAD_ENTER'} and event.value == 'PRESS':
                self._adjust = None
                self._set_text(context, self.hint)
            elif event.type in {'ESC', 'RIGHTMOUSE'} and event.value == 'PRESS':
                setattr(settings, name, start)
                self._adjust = None
                self._update_circle(context)
                self._set_text(context, self.hint)
            return {'RUNNING_MODAL'}

        if event.type in {'ESC', 'RIGHTMOUSE'} and event.value == 'PRESS':
            self._cleanup(context)  # the stroke was never written: nothing to undo
            return {'CANCELLED'}
        result = self.other_event(context, event)
        if result is not None:
            return result
        if event.type == 'F' and event.value == 'PRESS' and not self._stroking:
            size_name, strength_name = self.adjust_targets()
            name = strength_name if event.shift else size_name
            self._adjust = (name, getattr(settings, name), self._state.mouse[0])
            self._set_text(context, f"Adjust {settings.bl_rna.properties[name].name}: move "
                                    "the mouse, click to confirm, Esc/right-click to restore")
            return {'RUNNING_MODAL'}
        if event.type == 'LEFTMOUSE' and event.value == 'PRESS' and not self._stroking:
            x, y = self._state.mouse
            if not (0 <= x < self._region.width and 0 <= y < self._region.height):
                return {'PASS_THROUGH'}  # a click on the sidebar, header or another editor
            self._begin(context, self._state.mouse)
            return {'RUNNING_MODAL'}
        if event.type in {'MOUSEMOVE', 'INBETWEEN_MOUSEMOVE'} and self._stroking:
            self.stroke_move(context, self._state.mouse)
            return {'RUNNING_MODAL'}
        if event.type == 'LEFTMOUSE' and event.value == 'RELEASE' and self._stroking:
            changed = self.stroke_end(context)
            self._cleanup(context)
            return {'FINISHED'} if changed else {'CANCELLED'}
        # Let the view be navigated between strokes (not during one).
        return {'RUNNING_MODAL'} if self._stroking else {'PASS_THROUGH'}


class AIRLIGHT_OT_fog_paint(_FogBrush, bpy.types.Operator):
    """Paint Gaussian fog along a stroke on the active fog object (left-drag; F size,
    Shift+F amplitude, Esc cancels)"""
    bl_idname = "airlight.fog_paint"
    bl_label = "Paint Fog"
    bl_options = {'REGISTER', 'UNDO'}
    hint = ("Fog Paint: left-drag paints, F size (1/a), Shift+F amplitude, "
            "Esc/right-click cancels")

    def adjust_targets(self):
        return "scale_radius", "amplitude"

    def brush_radius_px(self, context):
        return self.scale_radius_px(context)

    def _point_3d(self, context, xy):
        """The stroke point under pixel _xy_ on the chosen plane, or None."""
        from bpy_extras import view3d_utils
        from mathutils import Vector
        from mathutils.geometry import intersect_line_plane
        settings = context.scene.airlight_brush
        rv3d = self._area.spaces.active.region_3d
        origin = view3d_utils.region_2d_to_origin_3d(self._region, rv3d, xy)
        direction = view3d_utils.region_2d_to_vector_3d(self._region, rv3d, xy)
        cursor = context.scene.cursor.location
        if settings.plane == 'SURFACE':
            hit, location, normal, *_ = context.scene.ray_cast(
                context.evaluated_depsgraph_get(), origin, direction)
            if not hit:
                return None
            return np.array(location + normal.normalized() / settings.scale)
        if settings.plane == 'GROUND':
            normal = Vector((0.0, 0.0, 1.0))
        else:
            normal = rv3d.view_rotation @ Vector((0.0, 0.0, -1.0))
        if abs(direction.dot(normal)) < 1e-6:
            return None
        p = intersect_line_plane(origin, origin + direction, cursor, normal)
        return None if p is None else np.array(p)

    def stroke_begin(self, context, xy):
        self._points = []
        self.stroke_move(context, xy)

    def stroke_move(self, context, xy):
        p = self._point_3d(context, xy)
        if p is not None:
            self._points.append(p)
            self._state.points = self._dabs(context)

    def _dabs(self, context):
        if not self._points:
            return np.zeros((0, 3))
        settings = context.scene.airlight_brush
        seed = (settings.seed, len(self._object.data.vertices))
        return paint_dabs(np.array(self._points), settings.scale, settings.spacing,
                          settings.jitter, seed=seed)

    def stroke_end(self, context):
        dabs = self._dabs(context)
        if len(dabs) == 0:
            return False
        settings = context.scene.airlight_brush
        matrix = np.array(self._object.matrix_world, dtype=np.float64)
        s = fog_object.uniform_scale(matrix[:3, :3])
        local = (dabs - matrix[:3, 3]) @ np.linalg.inv(matrix[:3, :3]).T
        # gather() divides a by the object's scale: store a * s for the chosen world a.
        fog_object.append(self._object, local, settings.scale * s, settings.amplitude)
        return True


class AIRLIGHT_OT_fog_erase(_FogBrush, bpy.types.Operator):
    """Erase Gaussian fog under the brush on the active fog object (left-drag; F radius,
    Shift+F strength, Esc cancels)"""
    bl_idname = "airlight.fog_erase"
    bl_label = "Erase Fog"
    bl_options = {'REGISTER', 'UNDO'}
    hint = ("Fog Erase: left-drag lowers density (deleted at zero), F radius, "
            "Shift+F strength, Esc/right-click cancels")

    def adjust_targets(self):
        return "radius", "strength"

    def brush_radius_px(self, context):
        return context.scene.airlight_brush.radius

    def stroke_begin(self, context, xy):
        centres, self._scales, amplitudes = fog_object.read(self._object)
        matrix = np.array(self._object.matrix_world, dtype=np.float64)
        self._world = centres @ matrix[:3, :3].T + matrix[:3, 3]
        self._amplitudes = amplitudes
        self._original = amplitudes.copy()
        self._last = None
        self._state.colour = (1.0, 0.4, 0.3, 0.8)
        self._dab_along(context, xy)

    def _dab_along(self, context, xy):
        """Dabs every radius/4 pixels from the last dab to _xy_."""
        settings = context.scene.airlight_brush
        spacing = max(1.0, 0.25 * settings.radius)
        if self._last is None:
            dabs = [np.asarray(xy)]
        else:
            path = np.array([self._last, xy], dtype=np.float64)
            if np.linalg.norm(path[1] - path[0]) < spacing:
                return
            dabs, _, _ = resample_stroke(path, spacing, offset=spacing)
        rv3d = self._area.spaces.active.region_3d
        xy_all, visible = project_points(self._world, rv3d.perspective_matrix,
                                         self._region.width, self._region.height)
        for centre in dabs:
            self._amplitudes, _ = erase(xy_all, visible, self._amplitudes, centre,
                                        settings.radius, settings.strength)
            self._last = tuple(centre)
        self._state.points = self._world[self._amplitudes > 0.0]

    def stroke_move(self, context, xy):
        self._dab_along(context, xy)

    def stroke_end(self, context):
        if np.array_equal(self._amplitudes, self._original):
            return False
        keep = self._amplitudes > 0.0
        if not keep.any():
            self.report({'WARNING'}, f"All Gaussians of '{self._object.name}' erased: the bake "
                                     "refuses an empty fog object (paint some or delete it)")
        centres, scales, _ = fog_object.read(self._object)
        colors = fog_object.read_colors(self._object.data)  # per-Gaussian albedo, if any
        fog_object.write(self._object, centres[keep], scales[keep], self._amplitudes[keep],
                         None if colors is None else colors[keep])
        return True


def _scale_radius_get(self):
    return 1.0 / self.scale


def _scale_radius_set(self, value):
    self.scale = 1.0 / value


# F in the paintbrush changes the blob radius 1/a; exposed as a property of its own so the
# adjust mode treats both tools alike.
AirlightBrushSettings.__annotations__["scale_radius"] = FloatProperty(
    name="Radius",
    description="Radius 1/a of painted Gaussians, in m (the inverse of Scale)",
    get=_scale_radius_get, set=_scale_radius_set,
    min=1e-4, max=1e3, unit='LENGTH',
)

classes = (AirlightBrushSettings, AIRLIGHT_OT_fog_paint, AIRLIGHT_OT_fog_erase)


def register():
    for cls in classes:
        bpy.utils.register_class(cls)
    bpy.types.Scene.airlight_brush = PointerProperty(type=AirlightBrushSettings)


def unregister():
    for handle in list(_draw_handles):
        remove_draw_handle(_draw_handles, handle)
    del bpy.types.Scene.airlight_brush
    for cls in reversed(classes):
        bpy.utils.unregister_class(cls)
