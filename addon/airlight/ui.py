"""Properties-editor panels: Scene > Airlight Fog and Light > Airlight Fog."""

import bpy

from . import compositor, model_choice, native, scene_export


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

        col = layout.column()
        col.active = settings.enabled
        col.prop(settings, "density")
        col.prop(settings, "color")
        col.prop(settings, "phase")
        sub = col.column()
        sub.active = settings.phase == 'HENYEY_GREENSTEIN'
        sub.prop(settings, "anisotropy")
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
            col.label(text=f"Uses {label}, error \u2264 {100.0 * error:.2g} %", icon='INFO')
        col.prop(settings, "aa_samples")
        col.prop(settings, "threads")
        col.prop(settings, "cache_dir")
        col.prop(settings, "auto_composite")
        col.prop(settings, "surface_shading")
        if settings.surface_shading and context.scene.render.engine != 'CYCLES':
            col.label(text="Surface shading needs Cycles (light groups): "
                           "plain fog composite here", icon='INFO')

        row = layout.row(align=True)
        row.operator("airlight.bake", icon='RENDER_STILL')
        row.operator("airlight.setup_compositor", icon='NODETREE')
        if settings.enabled and not compositor.is_set_up(context.scene) and not settings.auto_composite:
            layout.label(text="Compositor fog nodes are missing.", icon='INFO')

        lights = scene_export.fog_lights(context.scene)
        box = layout.box()
        box.label(text="Lights in the Fog")
        if not lights:
            box.label(text="No render-visible lights.", icon='INFO')
        for name, light_type, supported, participates in lights:
            row = box.row()
            if not supported:
                row.label(text=f"{name}: {light_type.lower()} light, not yet in fog", icon='LIGHT')
            elif participates:
                row.label(text=f"{name}: in fog", icon='LIGHT_POINT')
            else:
                row.label(text=f"{name}: excluded (Scatter in Fog is off)", icon='LIGHT_POINT')


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
        row = layout.row()
        row.active = light.type == 'POINT'
        row.prop(light.airlight, "participate")
        if light.type != 'POINT':
            layout.label(text=f"{light.type.title()} lights are not yet in fog.", icon='INFO')


classes = (AIRLIGHT_PT_scene, AIRLIGHT_PT_light)


def register():
    for cls in classes:
        bpy.utils.register_class(cls)


def unregister():
    for cls in reversed(classes):
        bpy.utils.unregister_class(cls)
