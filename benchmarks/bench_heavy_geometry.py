"""What a frame's geometry costs as it grows: the street with a mesh of N triangles added.

    tools/blender.sh -b blend_examples/street.blend --python benchmarks/bench_heavy_geometry.py \
        [-- --triangles 100000,1000000,10000000 --width 480 --height 270]

Per N, in one Blender process: a grid of N triangles over the street (it casts shadows and
the camera sees it), then bakes of the frame as `-a` makes them (bake.bake_frame, volumetric
shadows on, the soft-shadow probe remembered after the first): the first (geometry BVH and
shadow volumes built), the same frame again (both shared: image/raycast.h,
shadow/shadow_volumes.h), one after a lamp post moved (its object's BVH built again:
image/embree_blocks.h; the volumes built again), one after it moved back (its BVH built
again, the volumes of before shared), and one after the camera moved half a metre (both
shared). Printed per bake, in ms: the Python export (bake.prepare: foreach_get of every
mesh, world transform, the soup), the native bake with its BVH and shadow volumes
(stats seconds_geometry, seconds_shadow_volumes), and the whole bake_frame.
"""

import argparse
import os
import sys
import time

import bpy

from airlight import bake

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))  # Blender does not add it


def _args():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    p = argparse.ArgumentParser(prog="bench_heavy_geometry")
    p.add_argument("--triangles", default="100000,1000000,10000000")
    p.add_argument("--width", type=int, default=480)
    p.add_argument("--height", type=int, default=270)
    return p.parse_args(argv)


def _frame(scene, what):
    depsgraph = bpy.context.evaluated_depsgraph_get()
    t0 = time.perf_counter()
    _, stats, _ = bake.bake_frame(scene, depsgraph, os.path.join(bpy.app.tempdir, "heavy.exr"))
    total = time.perf_counter() - t0
    print(f"  {what:32s} export {1e3 * stats['seconds_export']:7.0f}  native {1e3 * stats['seconds_native']:7.0f}  "
          f"(BVH {1e3 * stats['seconds_geometry']:6.0f}  volumes {1e3 * stats['seconds_shadow_volumes']:6.0f})  "
          f"bake_frame {1e3 * total:7.0f}", flush=True)


def main():
    args = _args()
    scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y = args.width, args.height
    scene.render.resolution_percentage = 100
    scene.airlight.enabled = scene.airlight.volumetric_shadows = True
    post = next(o for o in scene.objects if o.type == 'MESH' and o.name != "Ground" and o.name != "Road")
    print(f"Airlight bench_heavy_geometry: street.blend at {args.width}x{args.height}, volumetric shadows; "
          f"ms per bake (the moved object: '{post.name}')")
    for n in (int(k) for k in args.triangles.split(",")):
        side = max(1, int((n / 2) ** 0.5))
        bpy.ops.mesh.primitive_grid_add(x_subdivisions=side, y_subdivisions=side, size=30.0, location=(0.0, 25.0, 6.0))
        grid = bpy.context.active_object
        print(f"\n{2 * side * side} triangles added", flush=True)
        _frame(scene, "first bake")
        _frame(scene, "the same frame again")
        post.location.x += 0.01
        _frame(scene, "after an object moved")
        post.location.x -= 0.01
        _frame(scene, "the object moved back")
        scene.camera.location.x += 0.5
        _frame(scene, "after the camera moved")
        scene.camera.location.x -= 0.5
        bpy.data.objects.remove(grid)


main()
