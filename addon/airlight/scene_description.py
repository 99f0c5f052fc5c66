"""Blender data -> the plain description of a scene that the bake and the viewport preview
share: the one place that reads the scene for the fog.

`describe(scene, depsgraph)` returns a SceneDescription for the frame the depsgraph is
evaluated at, all numpy arrays, numbers, strings and named tuples (no bpy data):
- the fog: density sigma_t, albedo, phase and g, fog top, fog-object noise;
- the light instances (LightInstance, in the depsgraph's order): every render-visible light
  the depsgraph instances, lights inside collection instances and particles included, with
  its transform, colour, power and cone;
- the survey (Survey) the Automatic model's light skipping bounds: the render-visible lights
  of the scene's own objects and the scene camera's frame (light_bounds.Frame);
- for the bake (`bake=True`): the camera of a render view, its clip range, and the
  world-space triangles of the render-visible geometry; and the fog objects' Gaussians.

Then model_choice makes the plan from it (the model, the lights Automatic skips),
scene_export turns description + plan into `_native.bake`'s keyword arguments, and the
preview (preview.py) takes its lights from the same two. Nothing here calls the native
module or chooses a model.

Units: everything is in Blender units. `unit_settings.scale_length` is not applied, so
the density is per Blender unit (per metre with the default scale of 1).
"""

import math
from typing import NamedTuple

import numpy as np

from . import fog_object, ies, light_bounds, light_nodes, mesh_read, visibility
from .names import SUPPORTED_LIGHT_TYPES, native_phase
from .views import bake_window, region_projection, render_size, view_camera

# Object types that can be turned into a mesh for ray casting.
GEOMETRY_TYPES = {'MESH', 'CURVE', 'SURFACE', 'FONT', 'META'}


class ExportError(ValueError):
    """The scene cannot be baked; the message says why and what to change."""


def _eye_factors(stereo, is_left):
    """(fac, fac_signed) of a Stereo 3D eye as Blender's camera_stereo3d_* functions take
    them (half the interocular distance each side of a centre pivot, all of it from a
    side pivot; positive for the left eye), or None for the pivot eye itself (the camera)."""
    pivot = stereo.pivot
    if (pivot == 'LEFT' and is_left) or (pivot == 'RIGHT' and not is_left):
        return None
    fac = 0.5 if pivot == 'CENTER' else 1.0
    return fac, (fac if is_left else -fac)


def _stereo_model_matrix(world, stereo, is_left):
    """The camera-to-world matrix of the left or right eye in Stereo 3D (Blender's
    camera_stereo3d_model_matrix): the eyes sit interocular_distance apart along the
    camera's x axis around the pivot; Toe-in turns each towards the convergence plane."""
    iod, conv = float(stereo.interocular_distance), float(stereo.convergence_distance)
    mode, pivot = stereo.convergence_mode, stereo.pivot
    factors = _eye_factors(stereo, is_left)
    if factors is None:
        return world.copy()
    fac, fac_signed = factors
    size = np.linalg.norm(world[:3, :3], axis=0)
    size_mat = np.diag([size[0], size[1], size[2], 1.0])
    normalized = world.copy()
    normalized[:3, :3] = world[:3, :3] / size

    def translation(x):
        m = np.eye(4)
        m[0, 3] = x
        return m

    if mode == 'TOE':
        if pivot == 'CENTER':
            fac, fac_signed = -fac, -fac_signed
        angle = math.atan(iod * 0.5 / conv) / fac * fac_signed
        c, s = math.cos(angle), math.sin(angle)
        rot = np.eye(4)
        rot[0, 0], rot[0, 2], rot[2, 0], rot[2, 2] = c, -s, s, c  # about the camera's y axis
        if pivot == 'CENTER':
            toe_in = rot.copy()
            toe_in[0, 3] = iod * fac_signed
            return normalized @ toe_in @ size_mat
        return normalized @ rot @ translation(-iod * fac_signed) @ rot @ size_mat
    return normalized @ translation(-iod * fac_signed) @ size_mat


def _stereo_shift_x(data, is_left):
    """The extra horizontal lens shift of an Off-Axis stereo eye (Blender's
    camera_stereo3d_shift_x), in units of the sensor-fit dimension like Shift X."""
    stereo = data.stereo
    factors = _eye_factors(stereo, is_left)
    if stereo.convergence_mode != 'OFFAXIS' or factors is None:
        return 0.0
    fac_signed = factors[1]
    return (float(stereo.interocular_distance) / float(data.sensor_width)) * \
        (float(data.lens) / float(stereo.convergence_distance)) * fac_signed


def _shifted_projection(projection, data, shift, width, height, render):
    """_projection_ with the lens shifted by _shift_ more along x (Blender's view plane:
    dx = shift * viewfac, viewfac the width in pixels for a horizontal sensor fit, the
    height times the pixel aspect for a vertical one)."""
    aspx, aspy = float(render.pixel_aspect_x), float(render.pixel_aspect_y)
    fit = data.sensor_fit
    if fit == 'AUTO':
        fit = 'HORIZONTAL' if aspx * width >= aspy * height else 'VERTICAL'
    viewfac = width if fit == 'HORIZONTAL' else (aspy / aspx) * height
    out = projection.copy()
    out[0, 2] += 2.0 * shift * viewfac / width
    return out


def export_camera(scene, depsgraph, view=None):
    """Returns (width, height, cam_to_world (4,4), projection (4,4)) of the scene camera,
    for the pixels of bake_window() only when a render region is set (width and height are
    then the window's; bake.run cuts the region out and, when the render is not cropped to
    it, puts it back into the whole frame). Its clip range is `export_clip_range`.
    _view_ (a name from render_views): that view's camera (view_camera), in Stereo 3D the
    eye's position, toe-in and off-axis shift."""
    camera = view_camera(scene, view)
    if camera is None:
        raise ExportError(f"Scene '{scene.name}' has no active camera: set one in the Scene properties.")
    if camera.type != 'CAMERA':
        raise ExportError(f"The active object '{camera.name}' of scene '{scene.name}' is not a camera.")
    if camera.data.type == 'PANO':
        raise ExportError(f"Camera '{camera.name}' is panoramic; the fog bake supports "
                          "perspective and orthographic cameras only.")
    width, height = render_size(scene)
    if width < 1 or height < 1:
        raise ExportError(f"The render resolution {width}x{height} is empty.")
    camera_eval = camera.evaluated_get(depsgraph)
    world = np.array(camera_eval.matrix_world, dtype=np.float64)
    if not np.isfinite(world).all():
        raise ExportError(f"Camera '{camera.name}' has a NaN or infinite transform (a driver or constraint?).")
    if not abs(float(np.linalg.det(world[:3, :3]))) > 1e-30:
        raise ExportError(f"Camera '{camera.name}' has a zero scale: it sees nothing (set its Scale "
                          "to 1 in the Object properties).")
    render = scene.render
    projection = camera_eval.calc_matrix_camera(
        depsgraph, x=width, y=height,
        scale_x=render.pixel_aspect_x, scale_y=render.pixel_aspect_y)
    cam_to_world = world
    projection = np.array(projection, dtype=np.float64)
    if view is not None and render.use_multiview and render.views_format == 'STEREO_3D':
        is_left = view != "right"  # (Blender: any view but "right" is a left eye)
        cam_to_world = _stereo_model_matrix(world, camera_eval.data.stereo, is_left)
        shift = _stereo_shift_x(camera_eval.data, is_left)
        if shift != 0.0:
            projection = _shifted_projection(projection, camera_eval.data, shift, width, height, render)
    window = bake_window(scene)
    if window is not None:
        projection = region_projection(projection, width, height, window)
        width, height = window[2] - window[0], window[3] - window[1]
    return width, height, cam_to_world, projection


def lens_points(count):
    """_count_ points spread evenly over the unit disk (a Fibonacci spiral: equal areas per
    point); the centre alone for one."""
    if count <= 1:
        return [(0.0, 0.0)]
    golden = math.pi * (3.0 - math.sqrt(5.0))
    return [(math.sqrt((k + 0.5) / count) * math.cos(k * golden),
             math.sqrt((k + 0.5) / count) * math.sin(k * golden)) for k in range(count)]


def export_lens(scene, depsgraph, view, cam_to_world, projection):
    """The cameras of the lens samples (scene.airlight.lens_samples) when _view_'s camera has
    Depth of Field on: [(cam_to_world, projection)], each a pinhole at a point of the
    aperture looking through the same focus plane, as Cycles samples its thin lens (radius
    lens / (2 F-stop), lens in mm and the radius in metres; focus distance along the view
    axis, or to the focus object). None for one sample, no depth of field or an
    orthographic camera. The aperture is a disk (Blades and Ratio are not followed)."""
    camera = view_camera(scene, view)
    samples = int(getattr(scene.airlight, "lens_samples", 1))
    data = camera.evaluated_get(depsgraph).data
    dof = data.dof
    if samples <= 1 or not dof.use_dof or data.type != 'PERSP':
        return None
    radius = float(data.lens) * 1e-3 / (2.0 * max(float(dof.aperture_fstop), 1e-5))
    axes = cam_to_world[:3, :3] / np.linalg.norm(cam_to_world[:3, :3], axis=0)
    eye = cam_to_world[:3, 3]
    if dof.focus_object is not None:
        target = np.array(dof.focus_object.evaluated_get(depsgraph).matrix_world.translation, dtype=np.float64)
        focus = abs(float(np.dot(axes[:, 2], eye - target)))
    else:
        focus = float(dof.focus_distance)
    if not (radius > 0.0 and focus > 0.0 and math.isfinite(radius) and math.isfinite(focus)):
        return None
    cameras = []
    for u, v in lens_points(samples):
        dx, dy = radius * u, radius * v
        moved = cam_to_world.copy()
        moved[:3, 3] = eye + dx * axes[:, 0] + dy * axes[:, 1]
        # Points of the focus plane (view depth _focus_) keep their pixels.
        shifted = projection.copy()
        shifted[0, 2] -= projection[0, 0] * dx / focus
        shifted[1, 2] -= projection[1, 1] * dy / focus
        cameras.append((moved, shifted))
    return cameras


def export_clip_range(scene, depsgraph, view=None):
    """(clip_start, clip_end) of the scene camera (of _view_'s, view_camera): Cycles starts
    camera rays on the near plane (the fog begins there) and does not see surfaces beyond
    the far plane."""
    camera = view_camera(scene, view)
    data = camera.evaluated_get(depsgraph).data
    start, end = float(data.clip_start), float(data.clip_end)
    if not start < end:
        raise ExportError(f"Camera '{camera.name}': Clip Start ({start:g}) must be less than "
                          f"Clip End ({end:g}).")
    return start, end


def bounds_frame(scene, depsgraph=None):
    """light_bounds.Frame of the scene camera (evaluated in _depsgraph_ when given), or None
    when there is none to bound (no camera, not a camera, panoramic)."""
    camera = scene.camera
    if camera is None or camera.type != 'CAMERA' or camera.data.type == 'PANO':
        return None
    cam = camera.evaluated_get(depsgraph) if depsgraph is not None else camera
    corners = [tuple(v) for v in cam.data.view_frame(scene=scene)]
    return light_bounds.Frame(np.array(cam.matrix_world), corners, cam.data.type == 'ORTHO',
                              float(cam.data.clip_start))


class LightInstance(NamedTuple):
    """One render-visible light instance of the depsgraph, as Blender has it (unchecked:
    scene_export validates the ones the bake takes)."""
    name: str             # the light object's name (an instance's: the instanced object's)
    type: str             # Blender's light type ('POINT', 'SPOT', 'SUN', 'AREA')
    participates: bool    # Scatter in Fog, read from the original light
    instanced: bool       # an instance of a collection instance, particles, ...
    matrix: np.ndarray    # (4, 4) float64 world matrix of the instance
    color: np.ndarray     # (3,) float64 RGB
    energy: float         # power in W (spots, points) or strength in W/m^2 (suns)
    spot_size: float      # cone angle in rad (spots; 0 for the others)
    spot_blend: float     # cone edge softness (spots; 0 for the others)
    casts_shadow: bool = True  # Cast Shadow (volumetric shadows)
    area_shape: str = ""       # area lights: 'SQUARE', 'RECTANGLE', 'DISK' or 'ELLIPSE'
    area_size: tuple = (0.0, 0.0)  # area lights: the size along the light's X and Y, m
    spread: float = math.pi    # area lights: Cycles' Spread, rad (pi: the full cosine lobe)
    radius: float = 0.0        # points and spots: Radius (shadow_soft_size), m
    angle: float = 0.0         # suns: Angle, the disk's angular diameter (soft shadows), rad
    ies_text: str = None       # points, spots: the IES profile's text (Cycles, an IES Texture on Strength)
    ies_problem: str = ""      # why an IES Texture's profile could not be read (baked without it)


def _light_instance(instance, obj, engine):
    light = obj.data
    spot = light.type == 'SPOT'
    participates = bool(light.original.airlight.participate)
    try:
        # Light > Use Nodes (Cycles): the constant factor of its Emission shader (a light kept
        # out of the fog is not asked).
        factor = light_nodes.emission_factor(obj.name, light, engine) if participates else np.ones(3)
    except light_nodes.LightNodeError as ex:
        raise ExportError(str(ex)) from None
    ies = _ies(obj.name, light, engine) if participates else {}
    # Read from the original light: add-on properties do not tag the depsgraph, so the
    # evaluated copy can hold a stale value after the user toggles it.
    return LightInstance(
        name=obj.name, type=light.type, participates=participates,
        instanced=bool(instance.is_instance), matrix=np.array(instance.matrix_world, dtype=np.float64),
        color=np.array(light.color, dtype=np.float64) * factor, energy=light.energy,
        spot_size=float(light.spot_size) if spot else 0.0, spot_blend=float(light.spot_blend) if spot else 0.0,
        casts_shadow=bool(getattr(light, "use_shadow", True)),
        radius=float(light.shadow_soft_size) if light.type in ('POINT', 'SPOT') else 0.0,
        angle=float(light.angle) if light.type == 'SUN' else 0.0, **ies,
        **_area_fields(light))


def _ies(name, light, engine):
    """LightInstance's ies_* of a light whose Emission Strength is an IES Texture ({} without);
    ExportError for an IES Texture on a light type the fog takes no profile for."""
    node = light_nodes.ies_node(light, engine)
    if node is None:
        return {}
    if light.type not in ('POINT', 'SPOT'):
        kind = {'AREA': "an area", 'SUN': "a sun"}.get(light.type, f"a {light.type.lower()}")
        raise ExportError(f"Light '{name}': an IES Texture on {kind} light is not in the fog "
                          "(point and spot lights only): remove it, or untick the light's Scatter in Fog")
    text, problem = light_nodes.ies_text(node)
    return dict(ies_text=text, ies_problem=problem or "")


def has_profile(light, scene):
    """Whether the bake takes a point light's IES profile (readable, at the scene's accuracy):
    such a point light bakes as a spot row, and the light's row order (surface.fogged_lights)
    follows scene_export's. A spot's IES keeps its spot row."""
    node = light_nodes.ies_node(light, scene.render.engine)
    if node is None:
        return False
    text, _ = light_nodes.ies_text(node)
    return bool(text) and ies.fit_light(text, scene.airlight.accuracy / 100.0, light)[0] is not None


def _area_fields(light):
    """LightInstance's area_* and spread of an area light ({} for the other types)."""
    if light.type != 'AREA':
        return {}
    square = light.shape in ('SQUARE', 'DISK')
    size_y = light.size if square else light.size_y
    return dict(area_shape=str(light.shape), area_size=(float(light.size), float(size_y)),
                spread=float(getattr(light, "spread", math.pi)))


def export_instances(depsgraph, geometry=True):
    """(lights, vertices, triangles, occluders) of every render-visible object instance: the
    lights as LightInstances in the depsgraph's order, and with _geometry_ the world-space
    triangle soup the camera sees (vertices (N, 3) float32, triangles (M, 3) uint32) and the
    one that casts shadows (Ray Visibility > Shadow), as (vertices, triangles, seen): the
    casters the camera sees first, _seen_ triangles of them, then the shadow-only ones; None
    when it is the same soup (else all three None). An instance is visible when whatever
    instances it renders (the instanced object itself is often hidden, e.g. in a particle
    collection)."""
    if not geometry:
        return _instances(depsgraph, None)[0], None, None, None
    with mesh_read.reads.pass_() as reads:
        lights, seen, casting, casting_only = _instances(depsgraph, reads)
        vertices, triangles = reads.soup("seen", seen)
        occluders = None
        if casting_only or len(casting) != len(seen):  # (casting: the seen blocks that cast)
            occluders = reads.soup("casters", casting + casting_only) + (sum(len(t) for _, t in casting),)
    return lights, vertices, triangles, occluders


def _instances(depsgraph, reads):
    """(lights, seen, casting, casting_only) of export_instances: the LightInstances, and with
    _reads_ (mesh_read.MeshReads in a pass) the world-space blocks the camera sees, those that
    cast shadows and that it sees, and those that only cast shadows."""
    visible = visibility.RenderVisibility(depsgraph.view_layer)
    lights, seen, casting, casting_only = [], [], [], []
    for instance in depsgraph.object_instances:
        obj = instance.object
        if obj.type != 'LIGHT' and reads is None:
            continue
        source = instance.parent if instance.is_instance else obj
        if source is None or not visible(source):
            continue
        if obj.type == 'LIGHT':
            lights.append(_light_instance(instance, obj, depsgraph.scene.render.engine))
            continue
        if obj.type not in GEOMETRY_TYPES:
            continue
        # Geometry the camera cannot see does not stop view rays; geometry that casts no
        # shadow does not stop the light.
        camera, shadow = getattr(obj, "visible_camera", True), getattr(obj, "visible_shadow", True)
        if not (camera or shadow):
            continue
        try:
            block = reads.world_triangles(obj, np.array(instance.matrix_world, dtype=np.float64))
        except mesh_read.NotFinite as ex:
            raise ExportError(f"{ex} (a driver, constraint or modifier?)") from None
        if block is None:
            continue
        if camera:
            seen.append(block)
        if shadow:
            (casting if camera else casting_only).append(block)
    return tuple(lights), seen, casting, casting_only


class SurveyLight(NamedTuple):
    """A render-visible light of the scene's own objects, for the Automatic model's bounds."""
    name: str
    type: str
    participates: bool
    emission: np.ndarray    # colour x power (3,) float64 (None unless participating and supported)
    position: tuple         # world location (None unless participating and supported)
    casts_shadow: bool = True
    supported: bool = True  # its type and settings are in the bake (area lights: full Spread)
    profiled: bool = False  # an IES Texture shapes it (no point light's bound: never skipped)


class Survey(NamedTuple):
    """What model_choice.light_plan bounds: the scene's render-visible lights (not instanced
    ones), the scene camera's frame (None: none to bound), whether a render-visible fog
    object is in the scene, and the world-space bounding boxes ((2, 3) lo, hi) of the
    render-visible objects that cast shadows (instances included)."""
    lights: tuple
    frame: object
    fog_objects: bool
    casters: tuple = ()


def survey(scene, depsgraph=None, view_layer=None):
    """The Survey of _scene_: its render-visible lights in _view_layer_ (default: the
    depsgraph's, else the scene's first), placed as _depsgraph_ evaluates them (None: as the
    objects are, for the panel)."""
    if view_layer is None:
        view_layer = depsgraph.view_layer if depsgraph is not None else scene.view_layers[0]
    visible = visibility.RenderVisibility(view_layer)
    frame = bounds_frame(scene, depsgraph)
    lights = []
    for obj in scene.objects:
        if obj.type != 'LIGHT' or not visible(obj):
            continue
        light = obj.data
        participates = bool(light.airlight.participate)
        emission = position = None
        supported = light.type in SUPPORTED_LIGHT_TYPES
        if supported and participates:
            emission = (np.array(light.color, dtype=np.float64) * light.energy
                        * light_nodes.safe_emission_factor(obj.name, light, scene.render.engine))
            src = obj.evaluated_get(depsgraph) if depsgraph is not None else obj
            position = tuple(src.matrix_world.translation)
        profiled = light_nodes.ies_node(light, scene.render.engine) is not None
        lights.append(SurveyLight(obj.name, light.type, participates, emission, position,
                                  bool(getattr(light, "use_shadow", True)), supported, profiled))
    fog_objects = any(getattr(getattr(obj, "airlight_fog", None), "is_fog", False)
                      and visible(obj) for obj in scene.objects)
    return Survey(tuple(lights), frame, fog_objects, caster_boxes(scene, depsgraph, visible))


def caster_boxes(scene, depsgraph, visible):
    """World-space bounding boxes ((2, 3) float64: lo, hi) of the render-visible objects that
    cast shadows: the depsgraph's instances when given, else the scene's objects as they are
    (the panel). Fog objects hold Gaussians, not surfaces: they cast none."""
    boxes = []
    if depsgraph is not None:
        items = ((inst.object, inst.parent if inst.is_instance else inst.object, inst.matrix_world)
                 for inst in depsgraph.object_instances)
    else:
        items = ((obj, obj, obj.matrix_world) for obj in scene.objects)
    for obj, source, matrix in items:
        if obj.type not in GEOMETRY_TYPES or source is None or not visible(source):
            continue
        if not getattr(obj, "visible_shadow", True) or fog_object.is_fog_object(obj):
            continue
        corners = np.array([tuple(c) for c in obj.bound_box], dtype=np.float64)
        m = np.array(matrix, dtype=np.float64)
        world = corners @ m[:3, :3].T + m[:3, 3]
        if np.isfinite(world).all():
            boxes.append(np.array([world.min(axis=0), world.max(axis=0)]))
    return tuple(boxes)


def fog_lights(scene):
    """For the UI: [(object name, light type, supported, participates)] of the scene's lights."""
    rows = []
    for obj in scene.objects:
        if obj.type != 'LIGHT' or obj.hide_render:
            continue
        light = obj.data
        rows.append((obj.name, light.type, light.type in SUPPORTED_LIGHT_TYPES,
                     light.airlight.participate))
    return rows


def export_medium(scene):
    """(sigma_t, albedo) of the scene fog, validated (the phase: `export_phase`)."""
    settings = scene.airlight
    sigma_t = float(settings.density)
    if not math.isfinite(sigma_t) or sigma_t < 0.0:
        raise ExportError(f"Fog density must be a finite number >= 0 (got {sigma_t}).")
    albedo = tuple(float(c) for c in settings.color)
    if not all(math.isfinite(c) and 0.0 <= c for c in albedo):
        raise ExportError(f"Fog colour must be finite and non-negative (got {albedo}).")
    return sigma_t, albedo


def export_phase(scene):
    """(phase, g) of the scene fog for `_native.bake`: "isotropic" for Henyey-Greenstein
    with Anisotropy 0, else the phase name and HG's g (Blender's sign, > 0 forward)."""
    settings = scene.airlight
    g = float(settings.anisotropy)
    # The Anisotropy property's own range (a script can go past it through the raw ID
    # property, scene.airlight["anisotropy"]): the range the models are measured over.
    rna = settings.bl_rna.properties["anisotropy"]
    if not (math.isfinite(g) and rna.hard_min <= g <= rna.hard_max):
        raise ExportError(f"Fog anisotropy must be a finite number in [{rna.hard_min:g}, {rna.hard_max:g}] "
                          f"(got {g:g}).")
    return native_phase(settings)


def export_fog_objects(depsgraph, mesh_overrides=None):
    """World-space Gaussians of the render-visible fog objects (`fog_object.gather`) as
    `_native.bake`'s rbf_* keyword arguments, or {} when there are none (then the bake is
    the homogeneous one, unchanged). Invalid fog objects raise ExportError. Per-Gaussian
    colours go to rbf_albedo when the gathered data has them: gather()'s GatheredFog with
    its colors ((n, 3) floats: some fog object has an "airlight_color" attribute), a dict
    with key 'colors', or a 4-tuple (centres, scales, amplitudes, colors).
    _mesh_overrides_: see fog_object.gather."""
    gathered = fog_gaussians(depsgraph, mesh_overrides)
    colors = None
    if isinstance(gathered, dict):
        centres, scales, amplitudes = gathered["centres"], gathered["scales"], gathered["amplitudes"]
        colors = gathered.get("colors")
    elif len(gathered) == 4:
        centres, scales, amplitudes, colors = gathered
    else:  # fog_object.GatheredFog: unpacks as three arrays and holds the colours beside them
        centres, scales, amplitudes = gathered
        colors = getattr(gathered, "colors", None)
    if len(scales) == 0:
        return {}
    out = dict(rbf_centres=np.ascontiguousarray(centres, dtype=np.float64),
               rbf_scales=np.ascontiguousarray(scales, dtype=np.float64),
               rbf_amplitudes=np.ascontiguousarray(amplitudes, dtype=np.float64))
    if colors is not None:
        colors = np.ascontiguousarray(colors, dtype=np.float64).reshape(-1, 3)
        if colors.shape[0] != len(scales):
            raise ExportError(f"Fog objects have {colors.shape[0]} colours for {len(scales)} blobs.")
        if not np.all(np.isfinite(colors)) or np.any(colors < 0.0):
            raise ExportError("Fog object colours must be finite and not negative.")
        out["rbf_albedo"] = colors
    return out


def export_noise(scene):
    """Fog-object noise settings (Fogshop section 5.5) as `_native.bake` keyword arguments,
    read at the scene's current frame (so keyframed values animate)."""
    settings = scene.airlight
    amplitude = float(settings.noise_amplitude)
    scale = float(settings.noise_scale)
    offset = tuple(float(x) for x in settings.noise_offset)
    if not (math.isfinite(amplitude) and amplitude >= 0.0):
        raise ExportError(f"Noise Amplitude must be a finite number >= 0 (got {amplitude}).")
    if not (math.isfinite(scale) and scale > 0.0):
        raise ExportError(f"Noise Scale must be a finite number > 0 (got {scale}).")
    if not all(math.isfinite(x) for x in offset):
        raise ExportError("Noise Offset must be finite.")
    return dict(noise_amplitude=amplitude, noise_scale=scale, noise_offset=offset)


def fog_gaussians(depsgraph, mesh_overrides=None):
    """fog_object.gather's Gaussians of the render-visible fog objects (what the bake and the
    preview get); an invalid fog object raises ExportError. _mesh_overrides_: see gather."""
    try:
        return fog_object.gather(depsgraph, mesh_overrides)
    except ValueError as ex:
        raise ExportError(str(ex)) from None


class SceneDescription(NamedTuple):
    """What the fog knows of a scene at one frame (see the module docstring); camera, clip,
    vertices, triangles and gaussians are None unless described for the bake, noise unless
    fog objects hold Gaussians."""
    sigma_t: float
    albedo: tuple
    phase: str
    g: float
    fog_top: float          # world Z of the fog layer's top for sun lamps (inf: Fog Top off)
    lights: tuple           # LightInstance, the depsgraph's order
    survey: Survey
    gaussians: dict         # export_fog_objects: rbf_* arrays, {} without fog objects; None
    noise: dict             # export_noise, or None
    camera: tuple           # export_camera: (width, height, cam_to_world, projection), or None
    clip: tuple             # export_clip_range: (clip_start, clip_end), or None
    vertices: np.ndarray    # (N, 3) float32 world-space, or None
    triangles: np.ndarray   # (M, 3) uint32, or None
    # (vertices, triangles, seen) of the shadow casters when not the above: the first _seen_
    # triangles are the camera's too
    occluders: tuple = None


def describe(scene, depsgraph, mesh_overrides=None, view=None, bake=True):
    """The SceneDescription of _scene_ at _depsgraph_'s frame. With _bake_, also what only
    the bake reads at once: _view_'s camera (views.render_views; None: the scene camera),
    its clip range, the geometry and the fog objects (_mesh_overrides_: see
    fog_object.gather); without, what the viewport preview reads per draw, the fog and its
    lights (it has its own view and depth, and gathers the fog objects once per depsgraph
    update with fog_gaussians). Invalid data raises ExportError."""
    sigma_t, albedo = export_medium(scene)
    phase, g = export_phase(scene)
    camera = clip = None
    if bake:
        camera = export_camera(scene, depsgraph, view)
        clip = export_clip_range(scene, depsgraph, view)
    surveyed = survey(scene, depsgraph)
    lights, vertices, triangles, occluders = export_instances(depsgraph, geometry=bake)
    gaussians = export_fog_objects(depsgraph, mesh_overrides) if bake else None
    settings = scene.airlight
    fog_top = float(settings.fog_top) if settings.use_fog_top else math.inf
    return SceneDescription(sigma_t=sigma_t, albedo=albedo, phase=phase, g=g, fog_top=fog_top,
                            lights=lights, survey=surveyed, gaussians=gaussians,
                            noise=export_noise(scene) if gaussians else None,
                            camera=camera, clip=clip, vertices=vertices, triangles=triangles,
                            occluders=occluders)
