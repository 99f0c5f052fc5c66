"""Fog objects: inhomogeneous fog as a sum of isotropic Gaussians (Zhou et al. 2007, eq. 6)

    beta(x) = sum_i c_i exp(-a_i^2 |x - b_i|^2)

stored as Blender data. A fog object is a mesh object whose vertices are the Gaussian
centres b_i (object space) with two float point-domain attributes, "airlight_scale"
(a_i, 1/m) and "airlight_amplitude" (c_i, 1/m), and `obj.airlight_fog.is_fog = True`.
A mesh with only vertices renders nothing in Cycles or EEVEE; the object is drawn as
its bounding box in the viewport. An optional third point attribute "airlight_color"
(FLOAT_COLOR, RGB used, alpha ignored) is a per-Gaussian single-scattering albedo (the
particle emitter writes it); without it the scene fog's colour applies. Being plain mesh data, fog objects save with the
.blend, undo, duplicate (Shift+D copies the Gaussians, Alt+D shares them), link and
append like any mesh.

All access is in bulk (`foreach_get` / `foreach_set` with numpy): `read`, `write`,
`append`. `gather(depsgraph)` hands the bake every render-visible fog object's Gaussians
in world space.
"""

import bpy
import numpy as np
from bpy.props import BoolProperty, FloatProperty

from . import visibility

SCALE_ATTR = "airlight_scale"
AMPLITUDE_ATTR = "airlight_amplitude"
COLOR_ATTR = "airlight_color"


class FogObjectError(ValueError):
    """Invalid fog object data; `object_name` names the offending object."""

    def __init__(self, object_name, message):
        super().__init__(f"Fog object '{object_name}': {message}")
        self.object_name = object_name


class AirlightFogObjectSettings(bpy.types.PropertyGroup):
    is_fog: BoolProperty(
        name="Fog Object",
        description="This mesh's vertices are centres of Gaussian fog blobs (with the "
                    "airlight_scale and airlight_amplitude attributes); the Airlight bake "
                    "adds them to the fog",
        default=False,
    )


def is_fog_object(obj):
    """Whether _obj_ (original or evaluated) is marked as a fog object. The mark is read
    from the original: add-on properties do not tag the depsgraph, so an evaluated copy
    keeps the value it had when it was last evaluated (a script that sets is_fog after the
    depsgraph evaluated the mesh would bake without it)."""
    if obj is None or obj.type != 'MESH':
        return False
    return bool(getattr(getattr(obj.original, "airlight_fog", None), "is_fog", False))


def edit_problem(obj):
    """Why the fog tools cannot change _obj_'s own data (its Gaussians, or an emitter's
    stored frames), or None when they can. Blender saves no edit of data linked from a
    library, nor of a mesh a library override leaves in its library: a stroke there would
    vanish on save, so the tools refuse it (as Blender's own edit tools do) and say how to
    edit it. Baking and copying linked fog work as for any object."""
    data = obj.data if obj.type == 'MESH' else None
    for block in (obj, data):
        if block is not None and block.library is not None:
            return (f"'{obj.name}' is linked from {bpy.path.basename(block.library.filepath)}: edit it "
                    "there, or make it local (Object > Relations > Make Local) to edit it here")
    for block in (obj, data):
        if block is not None and block.override_library is not None:
            return (f"'{obj.name}' is a library override: its fog data stays in the library file "
                    "(edit it there, or make it local: Object > Relations > Make Local)")
    return None


def poll_editable(cls, obj):
    """An operator poll's check that _obj_'s data can be edited (edit_problem): False with
    the reason as the poll message when it cannot."""
    problem = edit_problem(obj)
    if problem:
        cls.poll_message_set(problem)
        return False
    return True


def _point_attribute(mesh, name):
    attr = mesh.attributes.get(name)
    if attr is not None and (attr.data_type != 'FLOAT' or attr.domain != 'POINT'):
        mesh.attributes.remove(attr)
        attr = None
    if attr is None:
        attr = mesh.attributes.new(name, 'FLOAT', 'POINT')
    return attr


def read_mesh(mesh, object_name=None):
    """(centres (n,3) float64 object space, scales (n,), amplitudes (n,)) of a fog mesh.
    A missing attribute raises FogObjectError."""
    n = len(mesh.vertices)
    co = np.empty(3 * n, dtype=np.float32)
    mesh.vertices.foreach_get("co", co)
    out = [co.reshape(n, 3).astype(np.float64)]
    for name in (SCALE_ATTR, AMPLITUDE_ATTR):
        attr = mesh.attributes.get(name)
        if attr is None or attr.domain != 'POINT' or attr.data_type != 'FLOAT':
            raise FogObjectError(object_name or mesh.name,
                                 f"missing the float point attribute '{name}'")
        values = np.empty(n, dtype=np.float32)
        attr.data.foreach_get("value", values)
        out.append(values.astype(np.float64))
    return tuple(out)


def read(obj):
    """Object-space Gaussians of a fog object (see read_mesh)."""
    return read_mesh(obj.data, obj.name)


def read_colors(mesh):
    """Per-Gaussian RGB albedo (n, 3) float32 from the "airlight_color" point attribute
    (FLOAT_COLOR, or FLOAT_VECTOR), or None when the mesh has no such attribute."""
    attr = mesh.attributes.get(COLOR_ATTR)
    if attr is None or attr.domain != 'POINT':
        return None
    n = len(mesh.vertices)
    if attr.data_type in {'FLOAT_COLOR', 'BYTE_COLOR'}:
        rgba = np.empty(4 * n, dtype=np.float32)
        attr.data.foreach_get("color", rgba)
        return np.ascontiguousarray(rgba.reshape(n, 4)[:, :3])
    if attr.data_type == 'FLOAT_VECTOR':
        rgb = np.empty(3 * n, dtype=np.float32)
        attr.data.foreach_get("vector", rgb)
        return rgb.reshape(n, 3)
    return None


def write_mesh(mesh, centres, scales, amplitudes, colors=None):
    """Replaces the mesh's geometry by the Gaussians (object space), in bulk. _colors_
    (n, 3) RGB albedo, or one RGB for all, writes the "airlight_color" attribute; None
    leaves the mesh without it."""
    centres = np.ascontiguousarray(centres, dtype=np.float32).reshape(-1, 3)
    n = len(centres)
    scales = np.ascontiguousarray(np.broadcast_to(scales, (n,)), dtype=np.float32)
    amplitudes = np.ascontiguousarray(np.broadcast_to(amplitudes, (n,)), dtype=np.float32)
    mesh.clear_geometry()  # also removes every attribute (checked in Blender 3.4)
    if n:
        mesh.vertices.add(n)
        mesh.vertices.foreach_set("co", centres.ravel())
    _point_attribute(mesh, SCALE_ATTR).data.foreach_set("value", scales)
    _point_attribute(mesh, AMPLITUDE_ATTR).data.foreach_set("value", amplitudes)
    if colors is not None:
        rgba = np.ones((n, 4), dtype=np.float32)
        rgba[:, :3] = np.broadcast_to(np.asarray(colors, dtype=np.float32), (n, 3))
        mesh.attributes.new(COLOR_ATTR, 'FLOAT_COLOR', 'POINT').data.foreach_set("color", rgba.ravel())
    mesh.update()


def write(obj, centres, scales, amplitudes, colors=None):
    write_mesh(obj.data, centres, scales, amplitudes, colors)


def _default_color():
    """The scene fog's colour (albedo), the colour of Gaussians that have none."""
    scene = getattr(bpy.context, "scene", None)
    settings = getattr(scene, "airlight", None)
    return np.array(settings.color if settings is not None else (1.0, 1.0, 1.0), dtype=np.float32)


def append(obj, centres, scales, amplitudes, colors=None):
    """Adds Gaussians (object space) to a fog object, in bulk. The object keeps its
    colour attribute: when only one side has colours, the other side's Gaussians get the
    scene fog's colour."""
    centres = np.asarray(centres, dtype=np.float64).reshape(-1, 3)
    n = len(centres)
    if n == 0:
        return
    old_c, old_s, old_a = read(obj)
    old_rgb = read_colors(obj.data)
    rgb = None
    if old_rgb is not None or colors is not None:
        fill = _default_color()
        old_rgb = np.broadcast_to(fill, (len(old_c), 3)) if old_rgb is None else old_rgb
        new_rgb = np.broadcast_to(fill if colors is None else np.asarray(colors, dtype=np.float32), (n, 3))
        rgb = np.concatenate([old_rgb, new_rgb])
    write(obj, np.concatenate([old_c, centres]),
          np.concatenate([old_s, np.broadcast_to(scales, (n,))]),
          np.concatenate([old_a, np.broadcast_to(amplitudes, (n,))]), rgb)


def new_fog_object(name, collection, centres=(), scales=1.0, amplitudes=0.1, location=(0, 0, 0),
                   colors=None):
    """Creates a fog object holding the given object-space Gaussians, linked to _collection_."""
    mesh = bpy.data.meshes.new(name)
    obj = bpy.data.objects.new(name, mesh)
    obj.airlight_fog.is_fog = True
    obj.location = location
    # Vertices alone are not drawn in object mode: show the extent as a box instead.
    obj.display_type = 'WIRE'
    obj.show_bounds = True
    obj.display_bounds_type = 'BOX'
    write_mesh(mesh, np.asarray(centres, dtype=np.float64).reshape(-1, 3), scales, amplitudes, colors)
    collection.objects.link(obj)
    return obj


def validate(name, centres, scales, amplitudes):
    """Raises FogObjectError for data the kernels cannot use."""
    if len(centres) == 0:
        raise FogObjectError(name, "has no Gaussians (an empty fog object); paint some or delete it")
    if not np.isfinite(centres).all():
        raise FogObjectError(name, f"{int((~np.isfinite(centres).all(1)).sum())} Gaussian "
                                   "centre(s) are NaN or infinite")
    if not np.isfinite(scales).all() or (scales <= 0).any():
        bad = int((~(np.isfinite(scales) & (scales > 0))).sum())
        raise FogObjectError(name, f"{bad} Gaussian(s) have a zero, negative or non-finite "
                                   f"'{SCALE_ATTR}' (a must be > 0, in 1/m)")
    if not np.isfinite(amplitudes).all() or (amplitudes < 0).any():
        bad = int((~(np.isfinite(amplitudes) & (amplitudes >= 0))).sum())
        raise FogObjectError(name, f"{bad} Gaussian(s) have a negative or non-finite "
                                   f"'{AMPLITUDE_ATTR}' (c must be >= 0, in 1/m)")


def uniform_scale(matrix3):
    """The isotropic scale factor of a 3x3 linear map: |det|^(1/3)."""
    return float(abs(np.linalg.det(np.asarray(matrix3, dtype=np.float64)))) ** (1.0 / 3.0)


class GatheredFog(tuple):
    """What gather() returns: unpacks as (centres, scales, amplitudes), as before, and is
    also read by key: g['centres'], g['scales'], g['amplitudes'], g['colors'] ((n, 3)
    float32 RGB albedo, or None when no gathered fog object has an "airlight_color"
    attribute), `'colors' in g` (True only when there are colours) and g.get(key)."""

    KEYS = ("centres", "scales", "amplitudes")

    def __new__(cls, centres, scales, amplitudes, colors=None):
        self = super().__new__(cls, (centres, scales, amplitudes))
        self.colors = colors
        return self

    def __getitem__(self, key):
        if isinstance(key, str):
            if key == "colors":
                return self.colors
            return tuple.__getitem__(self, self.KEYS.index(key))
        return tuple.__getitem__(self, key)

    def __contains__(self, key):
        if key == "colors":
            return self.colors is not None
        return key in self.KEYS

    def get(self, key, default=None):
        try:
            value = self[key]
        except ValueError:
            return default
        return default if value is None else value

    def keys(self):
        return self.KEYS + (("colors",) if self.colors is not None else ())


def gather(depsgraph, mesh_overrides=None):
    """World-space Gaussians of all render-visible fog objects (and their instances):
    (centres (n,3) float64, scales (n,) float64, amplitudes (n,) float64), a GatheredFog
    that also holds 'colors' (n,3) float32 when any of them has the "airlight_color"
    attribute (the others' Gaussians then get the scene fog's colour), else None.

    Centres are transformed by the instance's matrix_world. Gaussians stay isotropic:
    the scale a is divided by s = |det M|^(1/3), the object's uniform scale factor, so an
    object scaled by 2 has blobs twice as wide (a/2) with the same peak density c. Under
    a NON-uniform scale the centres spread anisotropically but each blob stays a sphere
    whose width follows the geometric mean of the three axis scales (s above), not an
    ellipsoid. Invalid data raises FogObjectError (a ValueError) naming the object.

    _mesh_overrides_ ({object name: (centres, scales, amplitudes, colors)} in object space)
    stands in for those objects' mesh data: the emitters' smoke at the frame a render
    thread bakes, which must not write the meshes (render.py).
    """
    visible = visibility.RenderVisibility(depsgraph.view_layer)
    blocks = []
    colors = []
    for instance in depsgraph.object_instances:
        obj = instance.object
        if not is_fog_object(obj):
            continue
        source = instance.parent if instance.is_instance else obj
        if source is None or not visible(source):
            continue
        name = obj.original.name
        override = (mesh_overrides or {}).get(name)
        if override is None:
            centres, scales, amplitudes = read_mesh(obj.data, name)
            rgb = read_colors(obj.data)
        else:
            centres, scales, amplitudes, rgb = override
        validate(name, centres, scales, amplitudes)
        matrix = np.array(instance.matrix_world, dtype=np.float64)
        s = uniform_scale(matrix[:3, :3])
        if not s > 0.0 or not np.isfinite(s):
            raise FogObjectError(name, "has a zero (degenerate) object scale")
        blocks.append((centres @ matrix[:3, :3].T + matrix[:3, 3], scales / s, amplitudes))
        if rgb is not None and (not np.isfinite(rgb).all() or (rgb < 0.0).any()):
            raise FogObjectError(name, f"'{COLOR_ATTR}' has negative or non-finite values")
        colors.append(rgb)
    if not blocks:
        return GatheredFog(np.zeros((0, 3)), np.zeros(0), np.zeros(0))
    rgb = None
    if any(c is not None for c in colors):
        scene_settings = getattr(depsgraph.scene, "airlight", None)
        fill = np.array(scene_settings.color if scene_settings is not None else (1.0, 1.0, 1.0),
                        dtype=np.float32)
        rgb = np.concatenate([np.broadcast_to(fill, (len(b[0]), 3)) if c is None else c
                              for b, c in zip(blocks, colors)]).astype(np.float32)
    return GatheredFog(*(np.concatenate([b[i] for b in blocks]) for i in range(3)), colors=rgb)


class AIRLIGHT_OT_add_fog_object(bpy.types.Operator):
    """Add a fog object: Gaussian fog blobs that the Airlight fog tools paint and erase"""
    bl_idname = "airlight.add_fog_object"
    bl_label = "Airlight Fog Object"
    bl_options = {'REGISTER', 'UNDO'}

    scale: FloatProperty(
        name="Scale",
        description="Scale a of the first Gaussian, in 1/m (its radius is about 1/a)",
        default=1.0, min=1e-4, soft_min=0.01, soft_max=100.0,
    )
    amplitude: FloatProperty(
        name="Amplitude",
        description="Peak density c of the first Gaussian, in 1/m",
        default=0.1, min=0.0, soft_max=10.0,
    )

    @classmethod
    def poll(cls, context):
        return context.scene is not None and context.mode == 'OBJECT'

    def execute(self, context):
        collection = context.collection or context.scene.collection
        location = tuple(context.scene.cursor.location)
        obj = new_fog_object("Fog", collection, centres=[(0.0, 0.0, 0.0)],
                             scales=self.scale, amplitudes=self.amplitude, location=location)
        for other in context.view_layer.objects:
            other.select_set(False)
        context.view_layer.objects.active = obj
        obj.select_set(True)
        return {'FINISHED'}


def _menu_add(self, context):
    self.layout.operator(AIRLIGHT_OT_add_fog_object.bl_idname, icon='OUTLINER_OB_VOLUME')


classes = (AirlightFogObjectSettings, AIRLIGHT_OT_add_fog_object)


def register():
    for cls in classes:
        bpy.utils.register_class(cls)
    bpy.types.Object.airlight_fog = bpy.props.PointerProperty(type=AirlightFogObjectSettings)
    bpy.types.VIEW3D_MT_add.append(_menu_add)


def unregister():
    bpy.types.VIEW3D_MT_add.remove(_menu_add)
    del bpy.types.Object.airlight_fog
    for cls in reversed(classes):
        bpy.utils.unregister_class(cls)
