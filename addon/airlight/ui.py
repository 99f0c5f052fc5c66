"""Properties-editor panels: Scene > Airlight Fog and Light > Airlight Fog."""

import math

import bpy

from . import (bake, compositor, environment, fog_object, ies, model_choice, native, render, scene_description,
               surface)
from . import light_nodes, names
from .names import SUPPORTED_LIGHT_TYPES


class AIRLIGHT_PT_scene(bpy.types.Panel):
    bl_label = "Airlight Fog"
    bl_idname = "AIRLIGHT_PT_scene"
    bl_space_type = 'PROPERTIES'
    bl_region_type = 'WINDOW'
    bl_context = "scene"

    @classmethod
    def poll(cls, context):
        return context.scene is not None and hasattr(context.scene, "airlight")

    def draw_header(self, context):
        self.layout.prop(context.scene.airlight, "enabled", text="")

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        settings = context.scene.airlight

        if not native.available():
            box = layout.box()
            box.alert = True
            box.label(text="Native module not available", icon='ERROR')
            box.label(text=native.error()[:120])
        failed = render.render_problem(context.scene)
        if failed is not None:
            box = layout.box()
            box.alert = True
            box.label(text=f"Frame {failed[0]} rendered without fog:", icon='ERROR')
            box.label(text=failed[1][:120])

        col = layout.column()
        col.active = settings.enabled
        col.prop(settings, "density")
        col.prop(settings, "color")
        col.prop(settings, "phase")
        sub = col.column()
        sub.active = settings.phase == 'HENYEY_GREENSTEIN'
        sub.prop(settings, "anisotropy")
        if settings.model == 'HOFFMAN02':
            col.prop(settings, "rayleigh_density")
        col.prop(settings, "use_fog_top")
        sub = col.column()
        sub.active = settings.use_fog_top
        sub.prop(settings, "fog_top")
        col.prop(settings, "model")
        sub = col.column()
        sub.active = settings.model == 'AUTO'
        sub.prop(settings, "accuracy")
        problem = model_choice.phase_problem(settings)
        if problem:
            box = col.box()
            box.alert = True
            box.label(text=problem, icon='ERROR')
        else:
            name, label, error = model_choice.choose(settings)
            bound = "unbounded" if math.isinf(error) else f"\u2264 {100.0 * error:.2g} %"
            col.label(text=f"Uses {label}, error {bound}", icon='INFO')
            if name == "sun05":
                row = col.row(align=True)
                row.prop(settings, "table_resolution", text="Table")
                row.prop(settings, "table_interpolation", text="")
                col.prop(settings, "homogeneous_resolution", text="Resolution")
        col.prop(settings, "aa_samples")
        col.prop(settings, "threads")
        col.prop(settings, "cache_dir")
        col.prop(settings, "pass_precision")
        col.prop(settings, "light_passes")
        if settings.light_passes:
            sub = col.row()
            sub.prop(settings, "light_pass_limit")
            note = light_pass_note(context.scene)
            if note:
                col.label(text=note, icon='INFO')
        camera = context.scene.camera
        if camera is not None and camera.type == 'CAMERA' and camera.data.dof.use_dof:
            col.prop(settings, "lens_samples")
        if context.scene.render.use_motion_blur:
            col.prop(settings, "motion_samples")
        col.prop(settings, "auto_composite")
        col.prop(settings, "volumetric_shadows")
        if settings.volumetric_shadows:
            col.prop(settings, "shadow_samples")
            if settings.shadow_samples == 0:
                col.label(text=soft_shadow_note(context.scene), icon='INFO')
        note = shadow_note(context.scene)
        if note:
            col.label(text=note, icon='INFO')
        col.prop(settings, "surface_shading")
        sub = col.column()
        sub.active = settings.surface_shading
        sub.prop(settings, "surface_gloss")
        sub.prop(settings, "surface_glow_model")
        if settings.surface_shading and not problem and settings.model != 'HOFFMAN02':
            sub.label(text=surface.glow_model_text(settings, model_choice.choose(settings)[0]), icon='LIGHT')
        if settings.surface_shading and context.scene.render.engine != 'CYCLES':
            col.label(text="Surface shading needs Cycles (light groups): "
                           "plain fog composite here", icon='INFO')

        row = layout.row(align=True)
        row.operator("airlight.bake", icon='RENDER_STILL')
        row.operator("airlight.setup_compositor", icon='NODETREE')
        if settings.enabled and not compositor.is_set_up(context.scene) and not settings.auto_composite:
            layout.label(text="Compositor fog nodes are missing.", icon='INFO')
        for note in render.render_notes(context.scene) if settings.enabled else ():
            layout.label(text=note, icon='ERROR' if note == render.COMPOSITING_OFF else 'INFO')

        box = layout.box()
        box.label(text="Lights in the Fog")
        lines = light_lines(context.scene, context.view_layer)
        if not lines:
            box.label(text="No render-visible lights.", icon='INFO')
        for text, icon in lines:
            box.row().label(text=text, icon=icon)


_LIGHT_ICONS = {'POINT': 'LIGHT_POINT', 'SPOT': 'LIGHT_SPOT', 'SUN': 'LIGHT_SUN', 'AREA': 'LIGHT_AREA'}


def _area_error(settings, light):
    """An area light's expected mean error (a fraction) for its sample grid (names.area_error)."""
    square = light.shape in ('SQUARE', 'DISK')
    return names.area_error(light.size, light.size if square else light.size_y, names.area_cell(settings),
                            getattr(light, "spread", math.pi))


def _percent(fraction):
    return f"{100.0 * fraction:.2g} %"


def light_lines(scene, view_layer=None):
    """(text, icon) per render-visible light for the panel: the model each fogged light
    gets and its expected error, or why it is not in the fog (model_choice.light_plan;
    no bake, so it follows the settings as they change)."""
    try:
        rows = model_choice.light_plan(scene, view_layer=view_layer)
    except ValueError as ex:   # e.g. a degenerate camera: say so instead of failing the panel
        return [(f"Cannot plan the lights: {ex}", 'ERROR')]
    # With fog objects the row's error is that of the uniform fog's model; the Gaussians'
    # error (Fogshop's approximation) is on the Fog Objects panel (fog_object_note).
    where = " in the uniform fog" if any(fog_object.is_fog_object(obj) for obj in scene.objects) else ""
    lines = []
    for row in rows:
        icon = _LIGHT_ICONS.get(row.type, 'LIGHT')
        daylight = scene.airlight.model == 'HOFFMAN02'
        if row.status == 'unsupported' and (row.type in ('POINT', 'SPOT') or (row.type == 'AREA' and daylight)):
            text = f"{row.name}: not in Hoffman-Preetham's daylight fog (sun lamps only)"
        elif row.status == 'unsupported':
            text = f"{row.name}: {row.type.lower()} light, not yet in fog"
        elif row.status == 'off':
            text = f"{row.name}: excluded (Scatter in Fog is off)"
        elif row.status == 'skipped':
            text = f"{row.name}: skipped: below {_percent(row.share)} of the fog"
        elif row.type == 'AREA':
            obj = scene.objects.get(row.name)
            n = surface.area_sample_count(obj.data, names.area_cell(scene.airlight)) if obj is not None else 0
            text = (f"{row.name}: area light as {n} spot{'s' if n != 1 else ''} ({row.label}), sampled for "
                    f"{_percent(_area_error(scene.airlight, obj.data)) if obj is not None else '?'} beyond its image"
                    f"{where}{_SHADOW_TEXT.get(row.shadow, '')}")
        else:
            error = "unbounded" if math.isinf(row.error) else f"\u2264 {_percent(row.error)}"
            text = f"{row.name}: {row.label}, error {error}{where}{_SHADOW_TEXT.get(row.shadow, '')}"
        lines.append((text, icon))
    return lines


_SHADOW_TEXT = {'shadowed': ", shadowed", 'clear': ", unshadowed (no caster near enough to matter)",
                'no shadow': ", unshadowed (Cast Shadow off)"}


def light_pass_note(scene):
    """A line for the panel when Light Passes is on but the scene has more fogged lights than
    its limit (the bake writes none then), or None."""
    settings = scene.airlight
    count = sum(1 for _, kind, supported, participates in scene_description.fog_lights(scene)
                if supported and participates)
    if settings.light_passes and count > settings.light_pass_limit:
        return f"{count} fogged lights, over the limit: no light passes"
    return None


def soft_shadow_note(scene):
    """What Soft Shadow Samples Automatic (0) does, and what it took in the last bake."""
    last = bake.LAST_SOFT_SHADOWS.get(scene.name)
    if last is None:
        return "Automatic: measured per frame for lamps with a Radius and suns with an Angle"
    return f"Automatic, last bake: {bake.soft_shadows_text(last)}"


def shadow_note(scene):
    """A line for the panel when Volumetric Shadows is on but bakes none, or None."""
    settings = scene.airlight
    if not settings.volumetric_shadows:
        return None
    if not any(obj.type in ('MESH', 'CURVE', 'SURFACE', 'FONT', 'META') and not obj.hide_render
               and getattr(obj, "visible_shadow", True) and not fog_object.is_fog_object(obj)
               for obj in scene.objects):
        return "No object casts shadows (Ray Visibility > Shadow)"
    return None


class AIRLIGHT_PT_light(bpy.types.Panel):
    bl_label = "Airlight Fog"
    bl_idname = "AIRLIGHT_PT_light"
    bl_space_type = 'PROPERTIES'
    bl_region_type = 'WINDOW'
    bl_context = "data"

    @classmethod
    def poll(cls, context):
        return context.light is not None and hasattr(context.light, "airlight")

    def draw(self, context):
        layout = self.layout
        light = context.light
        supported = light.type in SUPPORTED_LIGHT_TYPES
        row = layout.row()
        row.active = supported
        row.prop(light.airlight, "participate")
        if not supported:
            layout.label(text=f"{light.type.title()} lights are not yet in fog.", icon='INFO')
        problem = light_node_problem(light, context.scene) if light.airlight.participate else None
        if problem:
            box = layout.box()
            box.alert = True
            for line in problem:
                box.label(text=line, icon='ERROR' if line is problem[0] else 'BLANK1')
        note = light_ies_note(light, context.scene) if light.airlight.participate and not problem else None
        if note:
            warn, lines = note
            box = layout.box()
            box.alert = warn
            for line in lines:
                box.label(text=line, icon=('ERROR' if warn else 'LIGHT') if line is lines[0] else 'BLANK1')


def light_ies_note(light, scene):
    """(warning, lines) on a light's IES Texture as the fog takes it (its fit, or why it bakes
    without it), or None without one."""
    node = light_nodes.ies_node(light, scene.render.engine)
    if node is None:
        return None
    if light.type not in ('POINT', 'SPOT'):
        return True, [f"IES profiles on {light.type.lower()} lights are not in the fog", "(point and spot lights only)"]
    text, problem = light_nodes.ies_text(node)
    if text is not None:
        fit, why = ies.fit_light(text, scene.airlight.accuracy / 100.0, light)
        if fit is not None:
            drawn = "a spot of its mean in the cone" if light.type == 'SPOT' else "an even light"
            return False, [f"IES profile in the fog: degree {fit.degree} fit",
                           f"{100.0 * fit.mean_error:.2g} % mean error, {100.0 * fit.max_error:.2g} % of peak at most",
                           f"averaged about the axis; the viewport preview draws it as {drawn}"]
        problem = f"IES profile unreadable: {why}"
    return True, [problem, "The fog takes this light without its profile"]


def light_node_problem(light, scene):
    """The panel's lines when _light_'s node tree is one the fog refuses (light_nodes), or None."""
    try:
        light_nodes.emission_factor(light.name, light, scene.render.engine)
    except light_nodes.LightNodeError as ex:
        text = str(ex)
        first, _, rest = text.partition(". ")
        return [first, rest] if rest else [first]
    return None


def fog_object_note(model_name, settings=None, last=None):
    """One line saying how the chosen model treats fog objects (Gaussian fog) and its
    error (docs/models.md: airlight_test.cpp, tests/native/test_gaussian_refine.py). With the
    Automatic model (_settings_) the bake refines Fogshop to the accuracy target; _last_ (the
    scene's bake.LAST_FOG_OBJECTS entry) gives the last bake's expected error."""
    if model_name in ("sun05", "sun05_exact", "biri06", "pegoraro10", "baseline"):
        target = model_choice.gaussian_accuracy(settings) if settings is not None else 0.0
        if target > 0.0:
            if last and abs(last["accuracy"] - target) < 1e-12 and last.get("abandoned"):
                return (f"Fogshop 2007 alone: refining to {100.0 * target:g} % was over its budget in the last "
                        "bake (up to ~29 % off near lights); raise the Accuracy or choose Quadrature")
            if last and abs(last["accuracy"] - target) < 1e-12:
                marched = last.get("marched", 0)
                lights = f"{marched} light{'s' if marched != 1 else ''} marched, " if marched else ""
                return (f"Fogshop 2007, refined: last bake {lights}expected error <= "
                        f"{100.0 * last['error_bound']:.2g} % (target {100.0 * target:g} %)")
            return (f"Fogshop 2007, refined to the {100.0 * target:g} % target: lights whose fog it misses "
                    "are marched exactly (bake to see the mix)")
        return ("Fogshop 2007 approximation (point, spot and sun lamps, any phase): ~1 % on thin fog, "
                "up to ~15 % at hard spot cone edges, 12-29 % on thick fog near a light; "
                "Automatic refines it to the accuracy, Quadrature is exact (slow)")
    if model_name == "quadrature":
        return "Exact single scattering (quadrature with exact optical depths)"
    return "This model does not take fog objects: the bake refuses them"


class AIRLIGHT_PT_fog_objects(bpy.types.Panel):
    bl_label = "Fog Objects"
    bl_idname = "AIRLIGHT_PT_fog_objects"
    bl_space_type = 'PROPERTIES'
    bl_region_type = 'WINDOW'
    bl_context = "scene"
    bl_parent_id = "AIRLIGHT_PT_scene"
    bl_options = {'DEFAULT_CLOSED'}

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        settings = context.scene.airlight
        count = sum(1 for obj in context.scene.objects
                    if getattr(getattr(obj, "airlight_fog", None), "is_fog", False))
        col = layout.column()
        col.active = settings.enabled
        if count == 0:
            col.label(text="No fog objects (Add > Airlight Fog Object, or paint one)", icon='INFO')
        else:
            col.label(text=f"{count} fog object{'s' if count != 1 else ''}", icon='OUTLINER_OB_POINTCLOUD')
            last = bake.LAST_FOG_OBJECTS.get(context.scene.name)
            col.label(text=fog_object_note(model_choice.choose(settings)[0], settings, last), icon='INFO')
            if model_choice.gaussian_accuracy(settings) > 0.0:
                col.label(text="Viewport preview: Fogshop's approximation (the render refines it)", icon='INFO')
        col.prop(settings, "gaussian_resolution", text="Resolution")
        chosen = resolution_note(context) if count else None
        if chosen:
            col.label(text=chosen, icon='INFO')
        col.prop(settings, "noise_amplitude")
        sub = col.column()
        sub.active = settings.noise_amplitude > 0.0
        sub.prop(settings, "noise_scale")
        sub.prop(settings, "noise_offset")


def resolution_note(context):
    """What Automatic bakes fog objects at for this render when that is finer than the
    Resolution setting (the error grows as the square of a pixel's angle: model_choice),
    else None."""
    scene = context.scene
    settings = scene.airlight
    if settings.model != 'AUTO':
        return None
    try:
        width, _height, _to_world, projection = scene_description.export_camera(
            scene, context.evaluated_depsgraph_get())
    except scene_description.ExportError:
        return None
    angle = model_choice.pixel_angle(projection, width)
    chosen = model_choice.gaussian_resolution(settings, angle)
    if chosen == settings.gaussian_resolution.lower():
        return None
    factor = (angle / model_choice.REFERENCE_PIXEL_ANGLE) ** 2
    return (f"Automatic bakes {chosen.title()} here: at this render size the error is {factor:.1f}x "
            f"the 1080p figure, above the {settings.accuracy:g} % target")


class AIRLIGHT_PT_environment(bpy.types.Panel):
    bl_label = "Environment Glow"
    bl_idname = "AIRLIGHT_PT_environment"
    bl_space_type = 'PROPERTIES'
    bl_region_type = 'WINDOW'
    bl_context = "scene"
    bl_parent_id = "AIRLIGHT_PT_scene"
    bl_options = {'DEFAULT_CLOSED'}

    def draw_header(self, context):
        self.layout.prop(context.scene.airlight, "environment_glow", text="")

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        settings = context.scene.airlight
        col = layout.column()
        col.active = settings.enabled and settings.environment_glow
        col.prop(settings, "environment_distance")
        col.prop(settings, "environment_sh_order")
        if settings.environment_glow:
            try:
                source = environment.world_source(context.scene)
            except environment.WorldMapError as ex:
                box = col.box()
                box.alert = True
                box.label(text=str(ex)[:120], icon='ERROR')
            else:
                if source is None or (source[0] == 'COLOR' and not any(source[1])):
                    col.label(text="The World emits no light: nothing glows.", icon='INFO')
                elif source[0] == 'IMAGE':
                    col.label(text=f"Glow from '{source[1].name}'", icon='WORLD')


classes = (AIRLIGHT_PT_scene, AIRLIGHT_PT_light, AIRLIGHT_PT_fog_objects, AIRLIGHT_PT_environment)


def register():
    for cls in classes:
        bpy.utils.register_class(cls)


def unregister():
    for cls in reversed(classes):
        bpy.utils.unregister_class(cls)
