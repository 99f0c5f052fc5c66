"""Blender data -> the plain scene description that `_native.bake` takes.

`export_scene(scene, depsgraph)` returns a dict whose keys are exactly `_native.bake`'s
scene keyword arguments (width, height, cam_to_world, projection, clip_start, clip_end,
vertices, triangles, light_positions, light_intensities, sigma_t, albedo, phase, g, and
rbf_centres, rbf_scales, rbf_amplitudes when render-visible fog objects hold Gaussians),
all numpy arrays, numbers or strings, for the frame the depsgraph is evaluated at. Nothing here calls the native module.

Units: everything is in Blender units. `unit_settings.scale_length` is not applied, so
the density is per Blender unit (per metre with the default scale of 1).
"""

import math

import numpy as np

from . import fog_object, model_choice, visibility
from .properties import SUPPORTED_LIGHT_TYPES

# Object types that can be turned into a mesh for ray casting.
_GEOMETRY_TYPES = {'MESH', 'CURVE', 'SURFACE', 'FONT', 'META'}


class ExportError(ValueError):
    """The scene cannot be baked; the message says why and what to change."""


def render_size(scene):
    """Render resolution in pixels after the percentage scale, as Blender computes it."""
    render = scene.render
    width = render.resolution_x * render.resolution_percentage // 100
    height = render.resolution_y * render.resolution_percentage // 100
    return width, height


def render_region(scene):
    """The render region (Render > Format > Render Region) in pixels as Blender renders it:
    (x0, y0, x1, y1) within render_size(), y counted from the bottom, or None without one.
    Blender truncates border x render size in single precision (render pipeline,
    R_BORDER); a region of no pixels is left to the render to refuse ("Image too small")
    and is ignored here, as is one covering the whole frame."""
    render = scene.render
    if not render.use_border:
        return None
    width, height = render_size(scene)
    f32 = np.float32
    x0, x1 = (int(f32(v) * f32(width)) for v in (render.border_min_x, render.border_max_x))
    y0, y1 = (int(f32(v) * f32(height)) for v in (render.border_min_y, render.border_max_y))
    if x1 <= x0 or y1 <= y0 or (x0, y0, x1, y1) == (0, 0, width, height):
        return None
    return x0, y0, x1, y1


# Pixels baked around a render region on each side (within the frame) and dropped after:
# the bake's edge test looks two pixels away (a pixel is an edge when a neighbour's depth
# has a kink), so with this margin the region's pixels bake as in the whole frame's bake.
REGION_MARGIN = 2


def bake_window(scene):
    """The pixels the bake covers, (x0, y0, x1, y1) as render_region (y from the bottom):
    the render region grown by REGION_MARGIN within the frame, or None (the whole frame)."""
    region = render_region(scene)
    if region is None:
        return None
    width, height = render_size(scene)
    x0, y0, x1, y1 = region
    m = REGION_MARGIN
    return max(0, x0 - m), max(0, y0 - m), min(width, x1 + m), min(height, y1 + m)


def region_projection(projection, width, height, region):
    """The projection of the pixels of _region_ ((x0, y0, x1, y1) of a width x height
    frame, y from the bottom) as a frame of their own: the clip-space x, y of the whole
    frame's _projection_ scaled and shifted so that the region spans the new frame's
    [-1, 1] (pixel centres stay on the whole frame's; perspective and orthographic)."""
    x0, y0, x1, y1 = region
    sx, sy = width / (x1 - x0), height / (y1 - y0)
    cx, cy = (x0 + x1) / width - 1.0, (y0 + y1) / height - 1.0
    window = np.array([[sx, 0.0, 0.0, -sx * cx],
                       [0.0, sy, 0.0, -sy * cy],
                       [0.0, 0.0, 1.0, 0.0],
                       [0.0, 0.0, 0.0, 1.0]])
    return window @ projection


def render_views(scene):
    """[(view name, file suffix)] of the views a render of _scene_ makes: with Output >
    Stereoscopy on, its enabled views (Stereo 3D: "left" and "right"; Multi-View: every
    enabled view, each with its own camera), else [(None, "")] (one plain view)."""
    render = scene.render
    if not render.use_multiview:
        return [(None, "")]
    if render.views_format == 'STEREO_3D':
        views = [v for v in render.views if v.name in ("left", "right") and v.use]
    else:
        views = [v for v in render.views if v.use]
    return [(v.name, v.file_suffix) for v in views] or [(None, "")]


def view_camera(scene, view):
    """The camera object that renders _view_ (a name from render_views): the scene camera,
    or in Multi-View format the object named like it with the view's suffix in place of
    another view's suffix (Blender's rule: "Camera_L" -> "Camera_R")."""
    camera = scene.camera
    render = scene.render
    if view is None or camera is None or not render.use_multiview or render.views_format != 'MULTIVIEW':
        return camera
    suffix = render.views[view].file_suffix
    best = None
    for v in render.views:  # (every view, as Blender: the longest suffix the name ends with)
        if v.file_suffix and camera.name.endswith(v.file_suffix):
            if best is None or len(v.file_suffix) >= len(best):
                best = v.file_suffix
    if best is None:
        return camera
    other = scene.objects.get(camera.name[:len(camera.name) - len(best)] + suffix)
    return other if other is not None else camera


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


def _mesh_arrays(obj_eval):
    """Local-space vertices (N,3) float32 and triangles (M,3) uint32 of an evaluated object."""
    try:
        mesh = obj_eval.to_mesh()
    except RuntimeError:
        return None
    if mesh is None:
        return None
    try:
        mesh.calc_loop_triangles()
        n_verts = len(mesh.vertices)
        n_tris = len(mesh.loop_triangles)
        if n_verts == 0 or n_tris == 0:
            return None
        verts = np.empty(n_verts * 3, dtype=np.float32)
        mesh.vertices.foreach_get("co", verts)
        tris = np.empty(n_tris * 3, dtype=np.int32)
        mesh.loop_triangles.foreach_get("vertices", tris)
        return verts.reshape(-1, 3), tris.reshape(-1, 3)
    finally:
        obj_eval.to_mesh_clear()


def export_geometry_and_lights(scene, depsgraph, skip=frozenset()):
    """World-space triangle soup and point lights of all render-visible objects (lights
    named in _skip_ left out: model_choice.skipped_lights; instanced lights never are).

    Returns (vertices (N,3) float32, triangles (M,3) uint32, light_positions (L,3),
    light_intensities (L,3), skipped_lights [(name, type)]).
    """
    visible = visibility.RenderVisibility(depsgraph.view_layer)
    vertex_blocks, triangle_blocks = [], []
    n_vertices = 0
    positions, intensities, skipped = [], [], []
    for instance in depsgraph.object_instances:
        obj = instance.object
        # An instance is visible when whatever instances it renders (the instanced
        # object itself is often hidden, e.g. in a particle collection).
        source = instance.parent if instance.is_instance else obj
        if source is None or not visible(source):
            continue
        matrix = np.array(instance.matrix_world, dtype=np.float64)
        if obj.type == 'LIGHT':
            light = obj.data
            if light.type not in SUPPORTED_LIGHT_TYPES:
                skipped.append((obj.name, light.type))
                continue
            # Read from the original light: add-on properties do not tag the depsgraph,
            # so the evaluated copy can hold a stale value after the user toggles it.
            if not light.original.airlight.participate or light.type in {'SPOT', 'SUN'}:  # export_spot/sun_lights
                continue
            if not instance.is_instance and obj.name in skip:
                continue
            # Cycles point light: radiant intensity I0 = C * P / (4 pi) W/sr (NOTES.md).
            if not np.isfinite(matrix).all():
                raise ExportError(f"Light '{obj.name}' has a NaN or infinite location (a driver or constraint?).")
            positions.append(matrix[:3, 3])
            intensities.append(_emission(obj, light) / (4.0 * math.pi))
            continue
        # Geometry the camera cannot see does not stop view rays.
        if obj.type not in _GEOMETRY_TYPES or not getattr(obj, "visible_camera", True):
            continue
        arrays = _mesh_arrays(obj)
        if arrays is None:
            continue
        local, tris = arrays
        world = local.astype(np.float64) @ matrix[:3, :3].T + matrix[:3, 3]
        if not np.isfinite(world).all():
            raise ExportError(f"Object '{obj.name}' has NaN or infinite vertices or transform "
                              "(a driver, constraint or modifier?).")
        vertex_blocks.append(world.astype(np.float32))
        triangle_blocks.append(tris.astype(np.uint32) + np.uint32(n_vertices))
        n_vertices += len(local)

    vertices = np.concatenate(vertex_blocks) if vertex_blocks else np.zeros((0, 3), np.float32)
    triangles = np.concatenate(triangle_blocks) if triangle_blocks else np.zeros((0, 3), np.uint32)
    light_positions = np.array(positions, dtype=np.float64).reshape(-1, 3)
    light_intensities = np.array(intensities, dtype=np.float64).reshape(-1, 3)
    return vertices, triangles, light_positions, light_intensities, skipped


def _emission(obj, light):
    """Colour x power of a light (W, or W/m^2 for suns), RGB float64. Blender allows a
    negative power (Cycles then subtracts light); the fog bake takes none. ExportError,
    naming the light, for that (with how to keep it out of the fog) and for NaN or inf."""
    if light.energy < 0.0:
        raise ExportError(f"Light '{obj.name}' has a negative power ({light.energy:g}): the fog takes lights "
                          "of power >= 0 (untick its Scatter in Fog to keep it out of the fog).")
    emission = np.array(light.color, dtype=np.float64) * light.energy
    if not np.isfinite(emission).all():
        raise ExportError(f"Light '{obj.name}' has a NaN or infinite colour or power (a driver?).")
    return emission


def _directed_lights(depsgraph, light_type, skip):
    """(light data, its emission (_emission), world matrix (4, 4), unit -Z direction) of
    every render-visible, participating light instance of _light_type_ ('SPOT', 'SUN');
    lights named in _skip_ (Automatic's skipped lights) are left out unless instanced. A
    degenerate transform raises ExportError."""
    visible = visibility.RenderVisibility(depsgraph.view_layer)
    for instance in depsgraph.object_instances:
        obj = instance.object
        if obj.type != 'LIGHT' or obj.data.type != light_type:
            continue
        source = instance.parent if instance.is_instance else obj
        if source is None or not visible(source):
            continue
        light = obj.data
        if not light.original.airlight.participate or (not instance.is_instance and obj.name in skip):
            continue
        matrix = np.array(instance.matrix_world, dtype=np.float64)
        if not np.isfinite(matrix).all():
            raise ExportError(f"{light_type.title()} light '{obj.name}' has a NaN or infinite transform "
                              "(a driver or constraint?).")
        emission = _emission(obj, light)
        direction = -matrix[:3, 2]
        norm = float(np.linalg.norm(direction))
        if not (norm > 0.0 and math.isfinite(norm)):
            raise ExportError(f"{light_type.title()} light '{obj.name}' has a degenerate transform "
                              "(no direction).")
        yield light, emission, matrix, direction / norm


def export_spot_lights(depsgraph, skip=frozenset()):
    """Render-visible participating spot lights as `_native.bake`'s spot_* keyword arguments,
    or {} when there are none (then the bake is the point-light one, unchanged).

    Cycles' spot (NOTES.md): I(theta) = C P / (4 pi) cos(theta) smoothstep(...) with theta
    from the lamp's -Z; Blender gives a spot's power in W like a point light's, so the
    intensity is the point light's formula and the profile is applied by the bake.
    """
    positions, axes, intensities, sizes, blends = [], [], [], [], []
    for light, emission, matrix, axis in _directed_lights(depsgraph, 'SPOT', skip):
        positions.append(matrix[:3, 3])
        axes.append(axis)
        intensities.append(emission / (4.0 * math.pi))
        sizes.append(float(light.spot_size))
        blends.append(float(light.spot_blend))
    if not positions:
        return {}
    description = dict(spot_positions=np.array(positions, dtype=np.float64).reshape(-1, 3),
                       spot_axes=np.array(axes, dtype=np.float64).reshape(-1, 3),
                       spot_intensities=np.array(intensities, dtype=np.float64).reshape(-1, 3),
                       spot_size=np.array(sizes, dtype=np.float64),
                       spot_blend=np.array(blends, dtype=np.float64))
    for name, array in description.items():
        if not np.all(np.isfinite(array)):
            raise ExportError(f"The scene's {name.replace('_', ' ')} contain NaN or infinite values.")
    return description


def export_sun_lights(scene, depsgraph, skip=frozenset()):
    """Render-visible participating sun lamps as `_native.bake`'s sun_directions,
    sun_irradiances and fog_top keyword arguments, or {} when there are none.

    Cycles' sun: irradiance E = colour * strength in W/m^2 arriving along the lamp's -Z; its
    angle (soft shadows) is ignored. fog_top: the world Z of the fog layer's top when
    `scene.airlight.use_fog_top` is on (sunlight fades through the fog above each point),
    else +inf (Hoffman-Preetham: unattenuated sunlight), see native/kernels/sun_layer.h.
    """
    directions, irradiances = [], []
    for _light, emission, _matrix, direction in _directed_lights(depsgraph, 'SUN', skip):
        directions.append(direction)
        irradiances.append(emission)
    if not directions:
        return {}
    settings = scene.airlight
    fog_top = float(settings.fog_top) if settings.use_fog_top else math.inf
    if math.isnan(fog_top):
        raise ExportError("The fog top height is not a number.")
    description = dict(sun_directions=np.array(directions, dtype=np.float64).reshape(-1, 3),
                       sun_irradiances=np.array(irradiances, dtype=np.float64).reshape(-1, 3))
    for name, array in description.items():
        if not np.all(np.isfinite(array)):
            raise ExportError(f"The scene's {name.replace('_', ' ')} contain NaN or infinite values.")
    description["fog_top"] = fog_top
    return description


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
    if not (math.isfinite(g) and abs(g) < 1.0):
        raise ExportError(f"Fog anisotropy must be a finite number in (-1, 1) (got {g}).")
    return model_choice.native_phase(settings)


def export_fog_objects(depsgraph, mesh_overrides=None):
    """World-space Gaussians of the render-visible fog objects (`fog_object.gather`) as
    `_native.bake`'s rbf_* keyword arguments, or {} when there are none (then the bake is
    the homogeneous one, unchanged). Invalid fog objects raise ExportError. Per-Gaussian
    colours go to rbf_albedo when the gathered data has them: gather() returning a dict
    with key 'colors' ((n, 3) floats), or a 4-tuple (centres, scales, amplitudes, colors).
    _mesh_overrides_: see fog_object.gather."""
    try:
        gathered = fog_object.gather(depsgraph, mesh_overrides)
    except ValueError as ex:
        raise ExportError(str(ex)) from None
    colors = None
    if isinstance(gathered, dict):
        centres, scales, amplitudes = gathered["centres"], gathered["scales"], gathered["amplitudes"]
        colors = gathered.get("colors")
    elif len(gathered) == 4:
        centres, scales, amplitudes, colors = gathered
    else:
        centres, scales, amplitudes = gathered
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


def export_scene(scene, depsgraph, mesh_overrides=None, view=None):
    """The scene description for `_native.bake(**description, ...)` at the depsgraph's frame
    (_mesh_overrides_: see fog_object.gather), seen by _view_'s camera (render_views; None:
    the scene camera)."""
    sigma_t, albedo = export_medium(scene)
    phase, g = export_phase(scene)
    width, height, cam_to_world, projection = export_camera(scene, depsgraph, view)
    clip_start, clip_end = export_clip_range(scene, depsgraph, view)
    skip = model_choice.skipped_lights(scene, depsgraph)  # Automatic: lights below the target
    daylight = model_choice.choose(scene.airlight)[0] == "hoffman02"  # sun lamps only
    vertices, triangles, light_positions, light_intensities, _ = export_geometry_and_lights(scene, depsgraph, skip)
    if daylight:
        light_positions, light_intensities = np.zeros((0, 3)), np.zeros((0, 3))
    for name, array in (("camera matrix", cam_to_world), ("projection", projection),
                        ("vertices", vertices), ("light positions", light_positions),
                        ("light intensities", light_intensities)):
        if not np.all(np.isfinite(array)):
            raise ExportError(f"The scene's {name} contain NaN or infinite values.")
    gaussians = export_fog_objects(depsgraph, mesh_overrides)
    # (Fog objects take point, spot and sun lamps and any phase: rbf_splat.h RbfSplatLights.)
    spots = {} if daylight else export_spot_lights(depsgraph, skip)
    suns = export_sun_lights(scene, depsgraph, skip)
    return dict(
        width=width, height=height,
        cam_to_world=cam_to_world, projection=projection,
        clip_start=clip_start, clip_end=clip_end,
        vertices=vertices, triangles=triangles,
        light_positions=light_positions, light_intensities=light_intensities,
        sigma_t=sigma_t, albedo=albedo, phase=phase, g=g,
        **gaussians,
        **(export_noise(scene) if gaussians else {}),
        **spots,
        **suns,
    )


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
