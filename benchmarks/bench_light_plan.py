"""Cost of the Airlight panel's per-light list (model_choice.light_plan: the model each
light gets, its error, and the Automatic model's skipping bounds), which the panel
recomputes on every redraw, and of the sun lamps in the bake.

    tools/blender.sh -b --python benchmarks/bench_light_plan.py [-- --repeats 20]

Scene: a camera and N point lights scattered on a 200 m square around it (some in frame,
most not; a quarter of them faint), one sun lamp. Prints the median time of light_plan per
N, and the bake's airlight pass (default 1920x1080, 2 threads) with 0 and 1 sun lamps
(no point lights).
"""

import argparse
import math
import random
import statistics
import sys
import time

import bpy
import numpy as np


def _args():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    p = argparse.ArgumentParser(prog="bench_light_plan")
    p.add_argument("--repeats", type=int, default=20)
    p.add_argument("--lights", type=int, nargs="+", default=[1, 10, 100, 1000])
    p.add_argument("--size", type=int, nargs=2, default=[1920, 1080], help="bake resolution")
    return p.parse_args(argv)


def _scene(n, size=(480, 270)):
    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    cam.location = (0.0, 0.0, 1.5)
    cam.rotation_euler = (math.radians(90.0), 0.0, 0.0)
    scene.collection.objects.link(cam)
    scene.camera = cam
    scene.render.resolution_x, scene.render.resolution_y = size
    rng = random.Random(1)
    for i in range(n):
        data = bpy.data.lights.new(f"L{i}", 'POINT')
        data.energy = 1.0 if i % 4 == 0 else 1000.0
        obj = bpy.data.objects.new(f"L{i}", data)
        obj.location = (rng.uniform(-100, 100), rng.uniform(-100, 100), rng.uniform(0.5, 10))
        scene.collection.objects.link(obj)
    sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", 'SUN'))
    sun.rotation_euler = (math.radians(40.0), 0.0, math.radians(20.0))
    scene.collection.objects.link(sun)
    scene.airlight.density = 0.05
    bpy.context.view_layer.update()
    return scene


def main():
    args = _args()
    from airlight import bake, model_choice, native
    for n in args.lights:
        scene = _scene(n)
        times = []
        for _ in range(args.repeats):
            t0 = time.perf_counter()
            rows = model_choice.light_plan(scene)
            times.append(time.perf_counter() - t0)
        skipped = sum(r.status == 'skipped' for r in rows)
        print(f"light_plan: {n:5d} point lights + 1 sun: median {1e3 * statistics.median(times):8.2f} ms "
              f"({skipped} skipped)")
    if not native.available():
        return
    scene = _scene(0, args.size)
    description, settings = bake.prepare(scene, bpy.context.evaluated_depsgraph_get())
    settings = dict(bake.native_settings(settings), threads=2, aa_samples=1)
    for label, extra in (("no sun", dict(sun_directions=np.zeros((0, 3)), sun_irradiances=np.zeros((0, 3)))),
                         ("1 sun", {})):
        d = dict(description, **extra)
        times = [native.get().bake(**d, **settings)["stats"]["seconds_airlight"] for _ in range(args.repeats)]
        print(f"bake airlight pass {args.size[0]}x{args.size[1]}, 2 threads, {label}: "
              f"median {1e3 * statistics.median(times):.2f} ms")


main()
