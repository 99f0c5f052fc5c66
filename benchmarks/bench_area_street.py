"""Area lights at the cost of a frame: the street at 1920x1080 with its lamps as point lights
and as 0.5 x 0.5 m square area lights facing down (same power), Automatic at 1 %, the native
bake of the add-on's export, alternating, three runs each, 2 threads.

    tools/blender.sh -b blend_examples/street.blend --python benchmarks/bench_area_street.py

Prints each run, the medians, the area lights' sample count and the ratio (target <= 3x).
"""
import statistics
import time

import bpy

from airlight import bake, native

RUNS = 3


def _lamps(scene):
    return [o for o in scene.objects if o.type == 'LIGHT' and o.data.type == 'POINT']


def _as(scene, lamps, kind):
    for obj in lamps:
        obj.data.type = kind
        if kind == 'AREA':
            obj.data.shape, obj.data.size = 'SQUARE', 0.5
            obj.rotation_euler = (0.0, 0.0, 0.0)  # -Z: down
    bpy.context.view_layer.update()


def main():
    scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y, scene.render.resolution_percentage = 1920, 1080, 100
    scene.airlight.model, scene.airlight.accuracy = 'AUTO', 1.0
    lamps = _lamps(scene)
    module = native.get()
    times = {'POINT': [], 'AREA': []}
    rows = {}
    for _ in range(RUNS):
        for kind in ('POINT', 'AREA'):
            _as(scene, lamps, kind)
            description, settings = bake.prepare(scene, bpy.context.evaluated_depsgraph_get())
            rows[kind] = len(description.get("spot_positions", ())) + len(description["light_positions"])
            t0 = time.perf_counter()
            module.bake(**description, **dict(bake.native_settings(settings), threads=2))
            times[kind].append(time.perf_counter() - t0)
            print(f"{kind.lower():5s} lamps ({rows[kind]} light rows): {times[kind][-1]:.3f} s")
    point, area = statistics.median(times['POINT']), statistics.median(times['AREA'])
    print(f"median: {len(lamps)} lamps as points {point:.3f} s, as 0.5 m area lights {area:.3f} s "
          f"({rows['AREA']} samples), {area / point:.2f}x")


main()
