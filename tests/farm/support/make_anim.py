"""Writes the farm tests' animated fog scene: tools/blender.sh -b --python make_anim.py -- OUT.blend

A floor, a cube and a point light that moves over frames 1-4 through homogeneous fog
(Volumetric Shadows on, so the cube's shadow moves too), a camera, Workbench at 128 x 72,
float EXR output. The fog is baked per frame when it renders (the add-on's render_pre)."""
import sys

import bpy
from mathutils import Vector

out = sys.argv[sys.argv.index("--") + 1]
bpy.ops.wm.read_factory_settings(use_empty=True)
scene = bpy.context.scene
bpy.ops.mesh.primitive_plane_add(size=30.0)
bpy.ops.mesh.primitive_cube_add(size=2.0, location=(0.0, 0.0, 1.0))
light = bpy.data.objects.new("Lamp", bpy.data.lights.new("Lamp", 'POINT'))
light.data.energy = 1500.0
light.data.shadow_soft_size = 0.0
scene.collection.objects.link(light)
for frame, x in ((1, -3.0), (4, 3.0)):
    light.location = (x, 2.5, 3.0)
    light.keyframe_insert("location", frame=frame)
cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
cam.location = (2.0, -10.0, 4.0)
cam.rotation_euler = (Vector((0.0, 0.0, 1.0)) - cam.location).to_track_quat('-Z', 'Y').to_euler()
scene.collection.objects.link(cam)
scene.camera = cam
scene.frame_start, scene.frame_end = 1, 4
r = scene.render
r.engine = 'BLENDER_WORKBENCH'
r.resolution_x, r.resolution_y, r.resolution_percentage = 128, 72, 100
r.image_settings.file_format = 'OPEN_EXR'
r.image_settings.color_depth = '32'
scene.airlight.enabled = True
scene.airlight.density = 0.06
scene.airlight.volumetric_shadows = True
bpy.ops.wm.save_as_mainfile(filepath=out)
