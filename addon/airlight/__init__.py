"""Airlight: analytic single-scattering fog (Sun et al. 2005) baked into compositing passes."""

bl_info = {
    "name": "Airlight Fog",
    "author": "Airlight developers",
    "version": (0, 1, 0),
    "blender": (3, 4, 0),
    "location": "Properties > Scene > Airlight Fog",
    "description": "Analytic single-scattering fog around point lights, baked per frame "
                   "and composited over Cycles/EEVEE renders",
    "category": "Render",
}

if "bpy" in locals():
    import importlib
    for _name in ("names", "views", "native", "visibility", "light_bounds", "fog_object", "scene_description",
                  "model_choice", "scene_export", "surface", "cache", "compositor", "properties", "bake",
                  "render", "ui", "preview"):
        if _name in locals():
            importlib.reload(locals()[_name])

import os as _os  # noqa: E402

import bpy  # noqa: E402

from . import native, properties, cache, scene_export, compositor, bake, render, ui  # noqa: E402

# Registration order: data first, then what uses it.
_modules = [properties, compositor, bake, render, ui]
from . import fog_object; _modules.append(fog_object)  # noqa: E402,E702  Gaussian fog objects
from . import brush_ops; _modules.append(brush_ops)  # noqa: E402,E702  fog paintbrush and eraser
from . import fog_clipboard; _modules.append(fog_clipboard)  # noqa: E402,E702  fog select/copy/paste/move
from . import airbrush; _modules.append(airbrush)  # noqa: E402,E702  airbrush and Fill Mesh with Fog
from . import emitter; _modules.append(emitter)  # noqa: E402,E702  particle emitter (smoke)
from . import tools_ui; _modules.append(tools_ui)  # noqa: E402,E702  N panel > Airlight > Fog Tools

# The viewport preview (preview.py, GPU) registers itself when it is part of the package.
if _os.path.exists(_os.path.join(__path__[0], "preview.py")):
    from . import preview  # noqa: E402
    if hasattr(preview, "register"):
        _modules.append(preview)


class AirlightPreferences(bpy.types.AddonPreferences):
    bl_idname = __package__

    def draw(self, context):
        layout = self.layout
        if native.available():
            layout.label(text=f"Native module {native.version()} loaded.", icon='CHECKMARK')
        else:
            col = layout.column()
            col.alert = True
            col.label(text="Native module not available:", icon='ERROR')
            for line in _wrap(native.error(), 90):
                col.label(text=line)


def _wrap(text, width):
    import textwrap
    return textwrap.wrap(text or "", width) or [""]


def register():
    native.load()  # import once; an error is kept and shown, never raised
    bpy.utils.register_class(AirlightPreferences)
    for module in _modules:
        module.register()


def unregister():
    for module in reversed(_modules):
        module.unregister()
    bpy.utils.unregister_class(AirlightPreferences)
