"""Cost of the bake's Blender side (Python, before the native bake) in a scene of many objects.

    tools/blender.sh -b --python benchmarks/bench_export.py [-- --objects 3000 --lights 50 --repeats 5]

Builds a scene of --objects one-triangle meshes spread over 20 collections, --lights point
lights in the master collection, a camera and fog with surface shading (Cycles, so the
light groups are in play), and prints medians (ms) of:
- scene_export.export_scene (camera, geometry, lights, fog objects: what the bake gets);
- surface.fogged_lights (the surface shading's lights and their groups);
- bake.prepare (everything the bake needs, as F12 and -a run it per frame);
- a light's energy edit followed by view_layer.update() (the depsgraph update the main loop
  runs after each edit, with the compositor's surface-pass handler), and the same update
  with the handler removed.
Each object is asked whether it renders (visibility.RenderVisibility).
"""

import argparse
import os
import sys

import bpy

from airlight import bake, compositor, scene_export, surface

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))  # Blender does not add it
from timing import median_ms  # noqa: E402


def _args():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    p = argparse.ArgumentParser(prog="bench_export")
    p.add_argument("--objects", type=int, default=3000)
    p.add_argument("--lights", type=int, default=50)
    p.add_argument("--repeats", type=int, default=5)
    return p.parse_args(argv)


def _scene(n_objects, n_lights):
    bpy.ops.wm.read_homefile(use_factory_startup=True, use_empty=True)
    scene = bpy.context.scene
    scene.render.engine = 'CYCLES'
    scene.render.resolution_x, scene.render.resolution_y = 64, 48
    mesh = bpy.data.meshes.new("Tri")
    mesh.from_pydata([(0, 0, 0), (1, 0, 0), (0, 1, 0)], [], [(0, 1, 2)])
    collections = [bpy.data.collections.new(f"C{k}") for k in range(20)]
    for collection in collections:
        scene.collection.children.link(collection)
    for k in range(n_objects):
        obj = bpy.data.objects.new(f"M{k}", mesh)
        obj.location = (k % 50, k // 50, -1.0)
        collections[k % 20].objects.link(obj)
    lights = []
    for k in range(n_lights):
        obj = bpy.data.objects.new(f"L{k}", bpy.data.lights.new(f"L{k}", 'POINT'))
        obj.location = (k, 0.0, 3.0)
        scene.collection.objects.link(obj)
        lights.append(obj)
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    cam.location = (0.0, 0.0, 10.0)
    scene.collection.objects.link(cam)
    scene.camera = cam
    scene.airlight.enabled = True
    scene.airlight.surface_shading = True
    bpy.ops.airlight.setup_compositor()
    bpy.context.view_layer.update()
    return scene, lights




def main():
    args = _args()
    scene, lights = _scene(args.objects, args.lights)
    view_layer = bpy.context.view_layer
    depsgraph = bpy.context.evaluated_depsgraph_get()
    print(f"bench_export: {args.objects} meshes in 20 collections, {args.lights} point lights, "
          f"median of {args.repeats}")
    for label, fn in (("scene_export.export_scene", lambda: scene_export.export_scene(scene, depsgraph)),
                      ("surface.fogged_lights", lambda: surface.fogged_lights(depsgraph)),
                      ("bake.prepare", lambda: bake.prepare(scene, depsgraph))):
        print(f"  {label:28s} {median_ms(fn, args.repeats):8.1f} ms")
    energy = iter(range(10**6))

    def edit():
        lights[0].data.energy = 100.0 + next(energy)
        view_layer.update()

    with_handler = median_ms(edit, args.repeats)
    bpy.app.handlers.depsgraph_update_post.remove(compositor.on_depsgraph_update_post)
    try:
        without = median_ms(edit, args.repeats)
    finally:
        bpy.app.handlers.depsgraph_update_post.append(compositor.on_depsgraph_update_post)
    print(f"  {'light edit + update':28s} {with_handler:8.1f} ms (without the surface-pass handler "
          f"{without:.1f} ms)")


main()
