"""Builds blend_examples/street.blend: a small street at night with four warm lamps in fog.

    tools/blender.sh -b --python blend_examples/make_street.py

Needs the Airlight add-on enabled (tools/blender.sh does that) to set scene.airlight.
Render it with `tools/blender.sh -b blend_examples/street.blend -o //render_#### -f 1`.
"""
import math
import os

import bpy

HERE = os.path.dirname(os.path.abspath(__file__))
OUT = os.path.join(HERE, "street.blend")


def material(name, color, roughness=0.8, emission=None):
    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    bsdf = mat.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Base Color"].default_value = (*color, 1.0)
    bsdf.inputs["Roughness"].default_value = roughness
    if emission is not None:
        bsdf.inputs["Emission"].default_value = (*emission, 1.0)
        if "Emission Strength" in bsdf.inputs:
            bsdf.inputs["Emission Strength"].default_value = 20.0
    return mat


def box(name, location, size, mat):
    bpy.ops.mesh.primitive_cube_add(size=1.0, location=location)
    obj = bpy.context.object
    obj.name = name
    obj.scale = size
    bpy.ops.object.transform_apply(location=False, rotation=False, scale=True)
    obj.data.materials.append(mat)
    return obj


def main():
    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    scene.name = "Street"

    asphalt = material("Asphalt", (0.05, 0.05, 0.055), 0.6)
    pavement = material("Pavement", (0.25, 0.24, 0.22))
    walls = [material("Brick", (0.35, 0.15, 0.1)), material("Plaster", (0.5, 0.45, 0.38)),
             material("Concrete", (0.3, 0.3, 0.32))]
    metal = material("Post", (0.03, 0.03, 0.03), 0.4)
    glass = material("LampGlass", (1.0, 0.8, 0.5), 0.3, emission=(1.0, 0.75, 0.45))

    # Road along +Y, pavements on both sides.
    box("Road", (0, 30, -0.05), (8, 80, 0.1), asphalt)
    box("PavementL", (-5.5, 30, 0.0), (3, 80, 0.2), pavement)
    box("PavementR", (5.5, 30, 0.0), (3, 80, 0.2), pavement)

    # Building blocks on both sides, varied heights.
    heights = [9, 14, 7, 11, 16, 8, 12]
    y = 0.0
    for i, h in enumerate(heights):
        depth = 8.0 + (i % 3) * 2.0
        for side in (-1, 1):
            hh = h if side < 0 else heights[(i + 3) % len(heights)]
            box(f"Building{'L' if side < 0 else 'R'}{i}", (side * 11.0, y + depth / 2, hh / 2),
                (8, depth - 0.6, hh), walls[(i + (side > 0)) % len(walls)])
        y += depth

    # Lamp posts with warm point lamps, alternating sides.
    lamp_colors = [(1.0, 0.72, 0.42), (1.0, 0.78, 0.5), (1.0, 0.7, 0.4), (1.0, 0.75, 0.45)]
    powers = [300.0, 250.0, 400.0, 300.0]
    for i, (color, power) in enumerate(zip(lamp_colors, powers)):
        side = -1 if i % 2 == 0 else 1
        x, yy = side * 4.3, 8.0 + i * 12.0
        bpy.ops.mesh.primitive_cylinder_add(radius=0.08, depth=4.5, location=(x, yy, 2.25), vertices=12)
        post = bpy.context.object
        post.name = f"Post{i}"
        post.data.materials.append(metal)
        bpy.ops.mesh.primitive_uv_sphere_add(radius=0.12, location=(x - side * 0.6, yy, 4.6),
                                             segments=12, ring_count=6)
        globe = bpy.context.object
        globe.name = f"Globe{i}"
        globe.data.materials.append(glass)
        globe.visible_shadow = False
        light = bpy.data.lights.new(f"Lamp{i}", 'POINT')
        light.energy = power
        light.color = color
        light.shadow_soft_size = 0.05
        lamp = bpy.data.objects.new(f"Lamp{i}", light)
        lamp.location = (x - side * 0.6, yy, 4.35)
        scene.collection.objects.link(lamp)

    # Eye-level camera looking down the street.
    cam_data = bpy.data.cameras.new("Camera")
    cam_data.lens = 28.0
    cam = bpy.data.objects.new("Camera", cam_data)
    cam.location = (1.2, -6.0, 1.7)
    cam.rotation_euler = (math.radians(88.0), 0.0, math.radians(-3.0))
    scene.collection.objects.link(cam)
    scene.camera = cam

    # Dark night sky.
    world = bpy.data.worlds.new("Night")
    world.use_nodes = True
    background = world.node_tree.nodes["Background"]
    background.inputs["Color"].default_value = (0.004, 0.006, 0.012, 1.0)
    background.inputs["Strength"].default_value = 1.0
    scene.world = world

    # Modest Cycles settings: ~1 minute on 2 cores.
    scene.render.engine = 'CYCLES'
    scene.cycles.device = 'CPU'
    scene.cycles.samples = 32
    scene.cycles.use_denoising = False  # Debian's Blender has no OpenImageDenoise
    # Without a denoiser, diffuse bounces that hit the small bright lamp globes leave white
    # fireflies across the walls and road at 32 samples: clamp indirect light (default 10).
    scene.cycles.sample_clamp_indirect = 1.0
    scene.cycles.max_bounces = 4
    scene.cycles.diffuse_bounces = 2
    scene.cycles.glossy_bounces = 2
    scene.cycles.transmission_bounces = 2
    scene.cycles.volume_bounces = 0
    scene.render.resolution_x, scene.render.resolution_y = 960, 540
    scene.render.resolution_percentage = 100
    scene.render.image_settings.file_format = 'PNG'
    scene.view_settings.view_transform = 'Filmic'
    scene.frame_start = scene.frame_end = scene.frame_current = 1

    # Fog: visible halos around the lamps.
    fog = scene.airlight
    fog.density = 0.05
    fog.color = (0.9, 0.92, 0.95)
    fog.cache_dir = "//airlight_cache/"
    bpy.ops.wm.save_as_mainfile(filepath=OUT, compress=True)  # '//' resolves next to the file
    fog.enabled = True
    bpy.ops.airlight.setup_compositor()
    bpy.ops.wm.save_as_mainfile(filepath=OUT, compress=True)
    print(f"make_street: wrote {OUT}")


main()
