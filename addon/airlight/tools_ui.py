"""3D viewport sidebar (N panel) > Airlight > Fog Tools: brush settings and the buttons
that start the paintbrush, the eraser, the airbrush and Fill Mesh with Fog on the active
fog object, and adding a particle emitter."""

import bpy

from . import fog_object
from . import fog_clipboard


class AIRLIGHT_PT_fog_tools(bpy.types.Panel):
    bl_label = "Fog Tools"
    bl_idname = "AIRLIGHT_PT_fog_tools"
    bl_space_type = 'VIEW_3D'
    bl_region_type = 'UI'
    bl_category = "Airlight"

    @classmethod
    def poll(cls, context):
        return context.scene is not None and hasattr(context.scene, "airlight_brush")

    def draw(self, context):
        layout = self.layout
        settings = context.scene.airlight_brush
        obj = context.active_object

        row = layout.row(align=True)
        row.operator("airlight.add_fog_object", icon='ADD')
        row.operator("airlight.add_emitter", text="Emitter", icon='OUTLINER_OB_FORCE_FIELD')
        if context.mode != 'OBJECT':
            layout.label(text="Fog tools work in Object Mode.", icon='INFO')
        elif not fog_object.is_fog_object(obj):
            layout.label(text="Select a fog object to paint or erase.", icon='INFO')
        else:
            box = layout.box()
            box.label(text=f"{obj.name}: {len(obj.data.vertices)} Gaussians",
                      icon='OUTLINER_OB_VOLUME')
        row = layout.row(align=True)
        row.scale_y = 1.4
        row.operator("airlight.fog_paint", icon='BRUSH_DATA')
        row.operator("airlight.fog_erase", icon='X')
        row = layout.row(align=True)
        row.operator("airlight.airbrush", icon='MOD_FLUIDSIM')
        row.operator("airlight.fill_mesh", icon='MESH_ICOSPHERE')
        col = layout.column(align=True)
        col.operator("airlight.fog_select_rect", icon='SELECT_SET')
        row = col.row(align=True)
        row.operator("airlight.fog_copy", icon='COPYDOWN')
        row.operator("airlight.fog_paste", icon='PASTEDOWN')
        col.operator("airlight.fog_move", icon='VIEW_PAN')
        if fog_object.is_fog_object(obj):
            clip = fog_clipboard.clipboard()
            n_sel = int(fog_clipboard.read_selection(obj).sum())
            n_clip = 0 if clip is None else len(clip["centres"])
            col.label(text=f"{n_sel} selected, {n_clip} in clipboard (not saved)")

        layout.use_property_split = True
        layout.use_property_decorate = False
        col = layout.column(heading="Paintbrush")
        col.prop(settings, "plane")
        col.prop(settings, "scale")
        col.prop(settings, "scale_radius")
        col.prop(settings, "amplitude")
        col.prop(settings, "spacing")
        col.prop(settings, "jitter")
        col.prop(settings, "seed")
        col = layout.column(heading="Eraser")
        col.prop(settings, "radius")
        col.prop(settings, "strength")
        air = getattr(context.scene, "airlight_airbrush", None)
        if air is not None:
            col = layout.column(heading="Airbrush")
            col.prop(air, "scale_radius")
            col.prop(air, "amplitude")
            col.prop(air, "rate")
            col.prop(air, "speed")
            col.prop(air, "diffusion")
            col.prop(air, "damping")
            col.prop(air, "offset")
            col.prop(air, "distance")
            col.prop(air, "max_particles")
            col.prop(air, "seed")
            col.prop(air, "fill_spacing")


classes = (AIRLIGHT_PT_fog_tools,)


def register():
    for cls in classes:
        bpy.utils.register_class(cls)


def unregister():
    for cls in reversed(classes):
        bpy.utils.unregister_class(cls)
