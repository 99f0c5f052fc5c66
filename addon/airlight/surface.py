"""Surface shading through the fog (Sun 2005 eq. 13-19), composited over Cycles' own shading.

The bake (`_native.bake(surface=True)`, native/bake/surface_pass.h) writes per fogged
light l the attenuation e^{-T(light, p)} of the first hit p, and the Lambert glow (the light
the fog scatters onto p) per unit diffuse colour. The compositor then forms

    surface = Combined + sum_l Combined_<group l> (attenuation_l - 1) + DiffCol x glow

and the usual fog on top (x Transmittance + Airlight), so the user's materials stay Cycles'
own: only each light's contribution is attenuated by its own path through the fog.

Render passes this needs, enabled here automatically on every view layer of the scene:
one Cycles light group per fogged light (`view_layer.lightgroups`, `Object.lightgroup`,
Blender 3.2+; its pass Combined_<group>) and the Diffuse Color pass (DiffCol). Lights that
already belong to a light group of the user's, and light objects instanced more than once,
are left alone (no surface attenuation for them), as are lights of other types (area
lights). Sun lamps are attenuated by the fog layer above the surface (with Fog Top on;
without it their light reaches surfaces unattenuated, as Hoffman-Preetham assume), and
their glow is the sunlight the fog (layer) scatters onto the surface
(native/surface/sunlight_glow.h). Eevee and Workbench have no light groups: there the composite stays
render x Transmittance + Airlight; the Hoffman-Preetham model has no surface pass.

The glow's model depends on the phase function and the fog model (surface_pass.h;
`glow_model_text` says which for the panel): Sun 2005's G0/Gn for the isotropic phase; the
phase-aware G_p (Biri 2006 eq. 8-13 with the hemisphere clamped) for any other phase; with
model biri06 and an anisotropic phase, Biri's own Lambert model (eq. 10, the unclamped cosine,
clamped at 0). Spot lights glow as a point light times a cone factor (exact for surfaces facing
the light); with fog objects the glow takes the exact optical depth T(s, p) (Fogshop eq. 25).
"""

import math
import re

import numpy as np

from . import scene_description, visibility
# PASS_GLOSS: glossy glow per unit Glossy Color (scene.airlight.surface_gloss > 0).
from .names import GROUP_PREFIX, PASS_GLOSS, PASS_GLOW, PASS_PREFIX, WORLD_GROUP, area_cell, area_grid, is_isotropic

SURFACE_LIGHT_TYPES = ('POINT', 'SPOT', 'SUN', 'AREA')  # lights the bake's surface pass attenuates


def gloss_exponent(scene):
    """The Phong exponent of the glossy glow the bake adds (0: none)."""
    return float(scene.airlight.surface_gloss) if active(scene) else 0.0


def active(scene):
    """True when the bake and the compositor do surface shading for `scene` (Cycles; not
    with the Hoffman-Preetham daylight model, whose extinction differs per colour channel)."""
    settings = scene.airlight
    return (bool(settings.surface_shading) and scene.render.engine == 'CYCLES'
            and settings.model != 'HOFFMAN02')


# Measured errors of the glow models (native/surface/biri06_surface_test.cpp,
# spot_surface_test.cpp), for the panel.
GLOW_G_P_TABLE_ERROR = 0.011  # phase-aware G_p table, max over the tested phases (HG 0.9)
BIRI06_LAMBERT_ERROR = 0.86   # eq. 10 vs the clamped G_p facing the light, worst (HG -0.9)


def glow_model_text(settings, model_name):
    """One line for the Surface Shading panel: which glow model the bake uses for these fog
    settings and the resolved fog model _model_name_ (native name, e.g. "biri06")."""
    if getattr(settings, "surface_glow_model", 'EXACT') == 'BIRI06_EQ10':
        text = (f"Glow: Biri 2006 eq. 10 (coarse: up to {100 * BIRI06_LAMBERT_ERROR:.0f} % low, "
                "none facing away)")
    elif is_isotropic(settings):
        text = "Glow: Sun 2005 G0 (isotropic phase)"
    else:
        text = f"Glow: phase-aware G (Biri 2006 eq. 8-13), table ≤ {100 * GLOW_G_P_TABLE_ERROR:.2g} %"
    return text


def group_name(object_name):
    """Light group name of a fogged light: fog_<name> with only [A-Za-z0-9_] (Blender turns
    other characters into '_' anyway; this makes the name predictable)."""
    return GROUP_PREFIX + re.sub(r"[^A-Za-z0-9_]", "_", object_name)


def fogged_lights(depsgraph):
    """[(light object, group name or None)] in the bake's light order: the point lights, the
    spot lights, the area lights' samples, the point lights with an IES profile, then the sun
    lamps, as scene_export exports them (tests/blender/test_surface.py
    holds them to the same order). The group is None where surface shading cannot apply."""
    visible = visibility.RenderVisibility(depsgraph.view_layer)
    points, spots, areas, profiled, suns, counts = [], [], [], [], [], {}
    for instance in depsgraph.object_instances:
        obj = instance.object
        if obj.type != 'LIGHT':
            continue
        source = instance.parent if instance.is_instance else obj
        if source is None or not visible(source):
            continue
        light = obj.data
        # Point, spot and sun lights: the bake's surface pass covers no other type.
        if light.type not in SURFACE_LIGHT_TYPES or not light.original.airlight.participate:
            continue
        original = obj.original
        counts[original.name] = counts.get(original.name, 0) + 1
        if light.type == 'AREA':  # one row per sample spot (scene_export.area_samples)
            areas.extend([original] * area_sample_count(light, area_cell(depsgraph.scene.airlight)))
            continue
        if light.type == 'POINT' and scene_description.has_profile(light, depsgraph.scene):
            profiled.append(original)  # an IES light bakes as a spot row after the area samples
            continue
        {'SPOT': spots, 'SUN': suns}.get(light.type, points).append(original)
    rows = []
    for obj in points + spots + areas + profiled + suns:
        group = group_name(obj.name)
        usable = counts[obj.name] == 1 and obj.lightgroup in ("", group)
        rows.append((obj, group if usable else None))
    return rows


def world_group_wanted(scene):
    """True when the World's light on surfaces gets the environment fog (surface shading
    and Environment Glow both on, and a World to light the scene)."""
    return active(scene) and bool(scene.airlight.environment_glow) and scene.world is not None


def ensure_world_group(scene):
    """Puts the World in its light group on every view layer (main thread only); returns the
    group name, or None when not wanted or the World already has a group of the user's."""
    if not world_group_wanted(scene):
        return None
    world = scene.world
    if world.lightgroup not in ("", WORLD_GROUP):
        return None
    if world.lightgroup != WORLD_GROUP:
        world.lightgroup = WORLD_GROUP
    for view_layer in scene.view_layers:
        if WORLD_GROUP not in {lg.name for lg in view_layer.lightgroups}:
            view_layer.lightgroups.add(name=WORLD_GROUP)
            refresh_render_layer_sockets(view_layer)
    return WORLD_GROUP


def refresh_render_layer_sockets(view_layer):
    """Makes Render Layers nodes show new light-group passes: adding a light group does not
    update them (Blender 3.4), a pass toggle's update does, so set one to its own value."""
    view_layer.use_pass_diffuse_color = view_layer.use_pass_diffuse_color


def current_world_group(scene):
    """The World's group where already set up (render thread: writes nothing), else None."""
    if world_group_wanted(scene) and scene.world.lightgroup == WORLD_GROUP:
        return WORLD_GROUP
    return None


def current_groups(depsgraph):
    """The group name per bake light where it is already set up (else None), changing
    nothing: for the render thread, where bpy data must not be written."""
    return [group if group is not None and obj.lightgroup == group else None
            for obj, group in fogged_lights(depsgraph)]


def groups_in_place(scene, depsgraph):
    """(groups, ready): the light groups the surface passes use for the scene as it is now
    (ensure_passes' per light, then ensure_world_group's), and whether those two would
    change nothing. Reads only."""
    rows = fogged_lights(depsgraph)
    groups = [group for _, group in rows if group is not None]
    ready = all(obj.lightgroup == group for obj, group in rows if group is not None)
    if world_group_wanted(scene) and scene.world.lightgroup in ("", WORLD_GROUP):
        groups.append(WORLD_GROUP)
        ready = ready and scene.world.lightgroup == WORLD_GROUP
    for view_layer in scene.view_layers:
        ready = (ready and set(groups) <= {lg.name for lg in view_layer.lightgroups}
                 and view_layer.use_pass_diffuse_color
                 and (gloss_exponent(scene) <= 0.0 or view_layer.use_pass_glossy_color))
    return groups, ready


def ensure_passes(scene, depsgraph):
    """Enables the light groups and DiffCol pass the composite needs; returns the group name
    per bake light (None: no surface pass for that light). Writes bpy data: main thread only.
    (groups_in_place checks the same conditions without writing: keep the two in step.)"""
    rows = fogged_lights(depsgraph)
    groups = [group for _, group in rows]
    for obj, group in rows:
        if group is not None and obj.lightgroup != group:
            obj.lightgroup = group
    for view_layer in scene.view_layers:
        existing = {lg.name for lg in view_layer.lightgroups}
        added = False
        for group in groups:
            if group is not None and group not in existing:
                view_layer.lightgroups.add(name=group)
                existing.add(group)
                added = True
        if gloss_exponent(scene) > 0.0 and not view_layer.use_pass_glossy_color:
            view_layer.use_pass_glossy_color = True
            added = False  # that update refreshed the Render Layers sockets already
        if not view_layer.use_pass_diffuse_color:
            view_layer.use_pass_diffuse_color = True
        elif added:
            refresh_render_layer_sockets(view_layer)
    return groups


def area_sample_count(light, cell):
    """The number of spots an area light bakes as (scene_export.area_samples) for the sample
    cell _cell_ (names.area_cell)."""
    square = light.shape in ('SQUARE', 'DISK')
    kx, ky = area_grid(light.size, light.size if square else light.size_y, cell, getattr(light, "spread", math.pi))
    return kx * ky


def pass_arrays(result, groups):
    """{pass name: (H, W, 3) float32} of the surface passes from a bake result: attenuation
    - 1 per light with a group (so that Combined_<group> x pass is the correction to add),
    averaged over an area light's samples (its rows repeat the group), and the glow."""
    passes, sums = {}, {}
    attenuation = result["surface_attenuation"]
    for index, group in enumerate(groups or ()):
        if group is not None and index < len(attenuation):
            total, n = sums.get(group, (0.0, 0))
            sums[group] = (total + attenuation[index], n + 1)
    for group, (total, n) in sums.items():
        passes[PASS_PREFIX + group] = (total / n - 1.0).astype(np.float32)
    passes[PASS_GLOW] = result["surface_glow"]
    if "surface_gloss_glow" in result:
        passes[PASS_GLOSS] = result["surface_gloss_glow"]
    return passes
