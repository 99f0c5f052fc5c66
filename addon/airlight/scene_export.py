"""A scene's description and its plan -> the keyword arguments of `_native.bake`.

`export_scene(scene, depsgraph)` returns a dict whose keys are exactly `_native.bake`'s
scene keyword arguments (width, height, cam_to_world, projection, clip_start, clip_end,
vertices, triangles, light_positions, light_intensities (light_radii when a light has a
Radius), sigma_t, albedo, phase, g, and
rbf_centres, rbf_scales, rbf_amplitudes when render-visible fog objects hold Gaussians,
spot_* and sun_* with spot lights and sun lamps), all numpy arrays, numbers or strings, for
the frame the depsgraph is evaluated at: scene_description.describe() reads the scene,
model_choice.plan() says which lights the bake takes, and `light_arguments` (the lights,
which the viewport preview draws too) and `bake_arguments` (everything) put them in the
bake's form. Nothing here reads Blender data or calls the native module.
"""

import math

import numpy as np

from . import ies, model_choice, scene_description
from .names import AREA_INTENSITY, SUPPORTED_LIGHT_TYPES, area_grid
from .scene_description import ExportError


def _baked(light, plan):
    """Whether the bake takes _light_ (a LightInstance): a supported type, Scatter in Fog
    on, not skipped by Automatic (model_choice.plan; instanced lights never are)."""
    return (light.type in SUPPORTED_LIGHT_TYPES and light.participates
            and (light.instanced or light.name not in plan.skipped))


# An area light (names.AREA_INTENSITY) bakes as spots of 180 degrees without blend (profile
# cos(theta), spot_light.h) spread over its surface (names.area_grid), each carrying 1 / n of
# the intensity; a Spread below 180 degrees gives each sample Cycles' soft-box profile
# (spot_spread, SpotCone in spot_light.h).
# Blender's smallest Spread (1 degree, the property's hard minimum).
AREA_MIN_SPREAD = math.radians(1.0)


def area_samples(light, cell):
    """The sample points (n, 3) of an area light (a LightInstance) in world space: the
    centres of kx x ky equal cells of about _cell_ m (names.area_grid, narrowed by a Spread
    below 180 degrees) over the rectangle, or
    those cells mapped to the ellipse
    by the concentric map (Shirley-Chiu, equal areas) for disks and ellipses."""
    sx, sy = (abs(float(s)) for s in light.area_size)
    kx, ky = area_grid(sx, sy, cell, light.spread)
    u = (np.arange(kx) + 0.5) / kx * 2.0 - 1.0
    v = (np.arange(ky) + 0.5) / ky * 2.0 - 1.0
    U, V = (a.ravel() for a in np.meshgrid(u, v))
    if light.area_shape in ('DISK', 'ELLIPSE'):
        r = np.where(np.abs(U) > np.abs(V), U, V)
        with np.errstate(divide="ignore", invalid="ignore"):
            phi = np.where(np.abs(U) > np.abs(V), math.pi / 4 * V / U, math.pi / 2 - math.pi / 4 * U / V)
        phi = np.where((U == 0) & (V == 0), 0.0, phi)
        U, V = r * np.cos(phi), r * np.sin(phi)
    local = np.column_stack([0.5 * sx * U, 0.5 * sy * V, np.zeros_like(U), np.ones_like(U)])
    return (local @ light.matrix.T)[:, :3]


def _emission(light):
    """Colour x power of a light (W, or W/m^2 for suns), RGB float64. Blender allows a
    negative power (Cycles then subtracts light); the fog bake takes none. ExportError,
    naming the light, for that (with how to keep it out of the fog) and for NaN or inf."""
    if light.energy < 0.0:
        raise ExportError(f"Light '{light.name}' has a negative power ({light.energy:g}): the fog takes lights "
                          "of power >= 0 (untick its Scatter in Fog to keep it out of the fog).")
    emission = light.color * light.energy
    if not np.isfinite(emission).all():
        raise ExportError(f"Light '{light.name}' has a NaN or infinite colour or power (a driver?).")
    return emission


def ies_fit(light, plan):
    """The ies.Fit of a point or spot light's IES profile at the plan's accuracy (a spot's in
    its cone), or None (no profile, or one that cannot be read: the light then bakes without
    it; ies_notes says so)."""
    if light.type not in ('POINT', 'SPOT') or not light.ies_text:
        return None
    return ies.fit_light(light.ies_text, plan.accuracy, light)[0]


def ies_notes(lights, plan):
    """One line per fogged point or spot light with an IES Texture: its fit, or why it bakes
    without it."""
    notes = []
    for light in lights:
        if light.type not in ('POINT', 'SPOT') or not _baked(light, plan) or not (light.ies_text or light.ies_problem):
            continue
        problem = light.ies_problem
        if not problem:
            fit, why = ies.fit_light(light.ies_text, plan.accuracy, light)
            if fit is not None:
                notes.append(f"Light '{light.name}': " + ies.describe(fit))
                continue
            problem = f"its IES profile cannot be read: {why}"
        without = "its spot cone alone" if light.type == 'SPOT' else "an even light of its power"
        notes.append(f"Light '{light.name}': WARNING {problem}: the fog takes it without its profile ({without})")
    return notes


def _point_rows(lights, plan):
    """The point lights that bake as points (those with an IES profile bake as spot rows)."""
    return [l for l in lights if l.type == 'POINT' and _baked(l, plan) and ies_fit(l, plan) is None]


def _ies_rows(lights, plan):
    """(light, fit) of the point lights with an IES profile, after the spots and area samples."""
    return [(l, f) for l in lights if l.type == 'POINT' and _baked(l, plan) for f in (ies_fit(l, plan),)
            if f is not None]


def point_lights(lights, plan, names=None, radii=None):
    """(light_positions (L, 3), light_intensities (L, 3)) of the point lights the bake takes.
    Cycles point light: radiant intensity I0 = C * P / (4 pi) W/sr (NOTES.md). _names_ (a
    list): each row's light name is appended (spot_lights and sun_lights alike); _radii_ (a
    list): each row's Radius (checked by _radius)."""
    positions, intensities = [], []
    for light in _point_rows(lights, plan):
        if names is not None:
            names.append(light.name)
        if radii is not None:
            radii.append(_radius(light))
        if not np.isfinite(light.matrix).all():
            raise ExportError(f"Light '{light.name}' has a NaN or infinite location (a driver or constraint?).")
        positions.append(light.matrix[:3, 3])
        intensities.append(_emission(light) / (4.0 * math.pi))
    return (np.array(positions, dtype=np.float64).reshape(-1, 3),
            np.array(intensities, dtype=np.float64).reshape(-1, 3))


def _radius(light):
    """A point or spot light's Radius in m: Cycles' disk facing each point, which the bake
    takes in homogeneous fog (native/homogeneous/sphere_light.h)."""
    radius = float(light.radius)
    if not (math.isfinite(radius) and radius >= 0.0):
        raise ExportError(f"Light '{light.name}' has a NaN, infinite or negative Radius ({radius:g}).")
    return radius


def _directed_lights(lights, light_type, plan, keep=None):
    """(light, its emission (_emission), unit -Z direction) of every light of _light_type_
    ('SPOT', 'SUN', 'AREA'; 'POINT' for an IES profile's axis) the bake takes, and _keep_
    (a predicate) keeps. A degenerate transform raises ExportError."""
    for light in lights:
        if light.type != light_type or not _baked(light, plan) or (keep is not None and not keep(light)):
            continue
        matrix = light.matrix
        if not np.isfinite(matrix).all():
            raise ExportError(f"{light_type.title()} light '{light.name}' has a NaN or infinite transform "
                              "(a driver or constraint?).")
        emission = _emission(light)
        direction = -matrix[:3, 2]
        norm = float(np.linalg.norm(direction))
        if not (norm > 0.0 and math.isfinite(norm)):
            raise ExportError(f"{light_type.title()} light '{light.name}' has a degenerate transform "
                              "(no direction).")
        yield light, emission, direction / norm


def _check_finite(description):
    for name, array in description.items():
        if not np.all(np.isfinite(array)):
            raise ExportError(f"The scene's {name.replace('_', ' ')} contain NaN or infinite values.")
    return description


def spot_lights(lights, plan, names=None):
    """The spot lights the bake takes as `_native.bake`'s spot_* keyword arguments, or {}
    when there are none (then the bake is the point-light one, unchanged).

    Cycles' spot (NOTES.md): I(theta) = C P / (4 pi) cos(theta) smoothstep(...) with theta
    from the lamp's -Z; Blender gives a spot's power in W like a point light's, so the
    intensity is the point light's formula and the profile is applied by the bake.
    """
    positions, axes, intensities, sizes, blends, spreads, radii = [], [], [], [], [], [], []
    # Per row its IES fit's coefficients (None: none), whether in a cone, and its extent (points).
    profiles, in_cone, extents = [], [], []
    for light, emission, axis in _directed_lights(lights, 'SPOT', plan):
        if names is not None:
            names.append(light.name)
        fit = ies_fit(light, plan)
        profiles.append(None if fit is None else fit.coefficients)
        in_cone.append(fit is not None)
        extents.append(math.pi)
        radii.append(_radius(light))
        positions.append(light.matrix[:3, 3])
        axes.append(axis)
        intensities.append(emission / (4.0 * math.pi))
        sizes.append(light.spot_size)
        blends.append(light.spot_blend)
        spreads.append(math.pi)
    # Area lights after the spots, as their samples (AREA_INTENSITY).
    for light, emission, axis in _directed_lights(lights, 'AREA', plan):
        samples = area_samples(light, plan.area_cell)
        for p in samples:
            if names is not None:
                names.append(light.name)
            positions.append(p)
            axes.append(axis)
            intensities.append(emission * (AREA_INTENSITY / len(samples)))
            sizes.append(math.pi)
            blends.append(0.0)
            spreads.append(min(math.pi, max(AREA_MIN_SPREAD, float(light.spread))))
            radii.append(0.0)
            profiles.append(None)
            in_cone.append(False)
            extents.append(math.pi)
    # Point lights with an IES profile last, as spots whose profile replaces the cone (dark
    # beyond its extent).
    fits = {id(light): fit for light, fit in _ies_rows(lights, plan)}
    for light, emission, axis in _directed_lights(lights, 'POINT', plan, keep=lambda l: id(l) in fits):
        fit = fits[id(light)]
        if names is not None:
            names.append(light.name)
        positions.append(light.matrix[:3, 3])
        axes.append(axis)
        intensities.append(emission / (4.0 * math.pi))
        sizes.append(math.pi)
        blends.append(0.0)
        spreads.append(math.pi)
        radii.append(_radius(light))
        profiles.append(fit.coefficients)
        in_cone.append(False)
        extents.append(fit.extent)
    if not positions:
        return {}
    spots = dict(spot_radii=np.array(radii, dtype=np.float64)) if any(radii) else {}
    if any(p is not None for p in profiles):
        width = max(len(p) for p in profiles if p is not None)
        table = np.zeros((len(profiles), width))
        for k, p in enumerate(profiles):
            if p is not None:
                table[k, :len(p)] = p
        spots["spot_profiles"] = table
        if any(in_cone):
            spots["spot_profile_in_cone"] = np.array(in_cone, dtype=np.float64)
        if any(e < math.pi for e in extents):
            spots["spot_profile_extent"] = np.array(extents, dtype=np.float64)
    return spots | _check_finite(dict(spot_positions=np.array(positions, dtype=np.float64).reshape(-1, 3),
                              spot_axes=np.array(axes, dtype=np.float64).reshape(-1, 3),
                              spot_intensities=np.array(intensities, dtype=np.float64).reshape(-1, 3),
                              spot_size=np.array(sizes, dtype=np.float64),
                              spot_blend=np.array(blends, dtype=np.float64),
                              spot_spread=np.array(spreads, dtype=np.float64)))


def sun_lights(lights, plan, fog_top, names=None):
    """The sun lamps the bake takes as `_native.bake`'s sun_directions, sun_irradiances and
    fog_top keyword arguments, or {} when there are none.

    Cycles' sun: irradiance E = colour * strength in W/m^2 arriving along the lamp's -Z; its
    Angle (sun_angles, when a sun has one) softens its volumetric shadows. fog_top: the world Z of the fog layer's top when
    `scene.airlight.use_fog_top` is on (sunlight fades through the fog above each point),
    else +inf (Hoffman-Preetham: unattenuated sunlight), see native/homogeneous/sunlight_layer.h.
    """
    directions, irradiances, angles = [], [], []
    for light, emission, direction in _directed_lights(lights, 'SUN', plan):
        if names is not None:
            names.append(light.name)
        directions.append(direction)
        irradiances.append(emission)
        angles.append(light.angle)
    if not directions:
        return {}
    if math.isnan(fog_top):
        raise ExportError("The fog top height is not a number.")
    description = _check_finite(dict(sun_directions=np.array(directions, dtype=np.float64).reshape(-1, 3),
                                      sun_irradiances=np.array(irradiances, dtype=np.float64).reshape(-1, 3)))
    description["fog_top"] = fog_top
    if any(angles):
        description["sun_angles"] = np.array(angles, dtype=np.float64)
    return description


def light_arguments(description, plan, names=None):
    """The lights the bake takes (and the preview draws) as `_native.bake` keyword
    arguments: light_positions and light_intensities (no point lights in the daylight
    model), spot_* (none in daylight either) and sun_* as spot_lights and sun_lights give
    them. Lights named in plan.skipped (Automatic) are left out unless instanced. _names_
    (a dict): its "points", "spots" and "suns" get each row's light name (an area light's
    samples and a collection's instances share their light's name; the per-light passes)."""
    rows = None if names is None else {"points": [], "spots": [], "suns": []}
    radii = []
    positions, intensities = point_lights(description.lights, plan, None if rows is None else rows["points"], radii)
    if plan.daylight:  # Hoffman-Preetham: sun lamps only
        positions, intensities, radii = np.zeros((0, 3)), np.zeros((0, 3)), []
        if rows is not None:
            rows["points"].clear()
    for name, array in (("light positions", positions), ("light intensities", intensities)):
        if not np.all(np.isfinite(array)):
            raise ExportError(f"The scene's {name} contain NaN or infinite values.")
    # (Fog objects take point, spot and sun lamps and any phase: splat.h GaussianSplatLights.)
    spots = {} if plan.daylight else spot_lights(description.lights, plan, None if rows is None else rows["spots"])
    suns = sun_lights(description.lights, plan, description.fog_top, None if rows is None else rows["suns"])
    if rows is not None:
        names.update(rows)
    # A light's Radius only where one has it (the arguments stay those of point lights).
    sized = dict(light_radii=np.array(radii, dtype=np.float64)) if any(radii) else {}
    return dict(light_positions=positions, light_intensities=intensities, **sized, **spots, **suns)


def _shadowed(light, plan):
    """Whether a baked light casts volumetric shadows: Volumetric Shadows on with casters in
    the scene (plan.shadows), its Cast Shadow on, and not left clear by Automatic
    (plan.unshadowed; instanced lights never are)."""
    return plan.shadows and light.casts_shadow and (light.instanced or light.name not in plan.unshadowed)


def shadow_arguments(description, plan):
    """The volumetric-shadow keyword arguments of `_native.bake` ({} when no baked light is
    shadowed): shadows=True, one flag per baked point light, spot and sun in the order
    point_lights, spot_lights and sun_lights give them, and the shadow casters when they are
    not the camera's geometry (occluder_vertices, occluder_triangles, and how many of them lead
    that the camera sees too: occluder_seen_triangles)."""
    if not plan.shadows:
        return {}
    flags = {}
    kinds = (('POINT', "light_shadows"), ('SPOT', "spot_shadows"), ('SUN', "sun_shadows"))
    for light_type, key in kinds:
        if plan.daylight and light_type != 'SUN':
            continue
        if light_type == 'POINT':
            chosen = _point_rows(description.lights, plan)
        else:
            chosen = [l for l in description.lights if l.type == light_type and _baked(l, plan)]
        if light_type == 'SPOT' and not plan.daylight:  # each area light's samples follow the spots
            chosen += [l for l in description.lights if l.type == 'AREA' and _baked(l, plan)
                       for _ in range(len(area_samples(l, plan.area_cell)))]
            chosen += [l for l, _ in _ies_rows(description.lights, plan)]  # then the IES lights
        if chosen:
            flags[key] = np.array([_shadowed(l, plan) for l in chosen], dtype=np.float64)
    if not any(np.any(f) for f in flags.values()):
        return {}
    out = dict(shadows=True, **flags)
    if description.occluders is not None:
        (out["occluder_vertices"], out["occluder_triangles"],
         out["occluder_seen_triangles"]) = description.occluders
    return out


def bake_arguments(description, plan, light_names=None):
    """`_native.bake`'s scene keyword arguments (the module docstring) of a SceneDescription
    described for the bake, with the lights its plan takes."""
    width, height, cam_to_world, projection = description.camera
    clip_start, clip_end = description.clip
    for name, array in (("camera matrix", cam_to_world), ("projection", projection),
                        ("vertices", description.vertices)):
        if not np.all(np.isfinite(array)):
            raise ExportError(f"The scene's {name} contain NaN or infinite values.")
    lights = light_arguments(description, plan, light_names)
    spots = {k: v for k, v in lights.items() if k.startswith("spot_")}
    suns = {k: v for k, v in lights.items() if k.startswith("sun_") or k == "fog_top"}
    return dict(
        width=width, height=height,
        cam_to_world=cam_to_world, projection=projection,
        clip_start=clip_start, clip_end=clip_end,
        vertices=description.vertices, triangles=description.triangles,
        light_positions=lights["light_positions"], light_intensities=lights["light_intensities"],
        **({"light_radii": lights["light_radii"]} if "light_radii" in lights else {}),
        sigma_t=description.sigma_t, albedo=description.albedo, phase=description.phase, g=description.g,
        **description.gaussians,
        **(description.noise or {}),
        **spots,
        **suns,
        **shadow_arguments(description, plan),
    )


def export(scene, depsgraph, mesh_overrides=None, view=None, light_names=None, notes=None):
    """(bake_arguments, plan) of _scene_ at the depsgraph's frame (_mesh_overrides_: see
    fog_object.gather), seen by _view_'s camera (views.render_views; None: the scene
    camera); _light_names_ (a dict) gets the light arrays' row names (light_arguments);
    _notes_ (a list) what the user should know about its lights (ies_notes)."""
    description = scene_description.describe(scene, depsgraph, mesh_overrides, view)
    plan = model_choice.plan(scene.airlight, description.survey)
    if notes is not None:
        notes.extend(ies_notes(description.lights, plan))
    return bake_arguments(description, plan, light_names), plan


def export_scene(scene, depsgraph, mesh_overrides=None, view=None):
    """The scene description for `_native.bake(**description, ...)` (export's first half)."""
    return export(scene, depsgraph, mesh_overrides, view)[0]
