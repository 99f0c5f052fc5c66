"""Light Passes' cost: Bake Fog's run() on the street at 1920x1080, off and on alternating.

    tools/blender.sh -b blend_examples/street.blend --python benchmarks/bench_light_passes.py

Prints per run the whole run(), the native bake, the per-light bakes and the EXR write, and
the medians. Where the total's bake splits the lights itself (homogeneous fog, bake.
_light_pass_index) the passes' cost is inside the native bake and the per-light bakes are 0.
"""
import os
import statistics
import tempfile

import bpy

from airlight import bake

RUNS = 3


def main():
    scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y, scene.render.resolution_percentage = 1920, 1080, 100
    depsgraph = bpy.context.evaluated_depsgraph_get()
    rows = {False: [], True: []}
    path = os.path.join(tempfile.mkdtemp(), "fog.exr")
    for _ in range(RUNS):
        for on in (False, True):
            scene.airlight.light_passes = on
            description, settings = bake.prepare(scene, depsgraph)
            stats, seconds = bake.run(description, settings, path)
            row = (seconds, stats.get("seconds_native", 0.0), stats.get("seconds_light_passes", 0.0),
                   stats["seconds_exr"])
            rows[on].append(row)
            print("light passes %-3s run %.3f s, native bake %.3f s, light passes %.3f s, EXR %.3f s"
                  % ((("on" if on else "off"),) + row))
    for on, label in ((False, "off"), (True, "on")):
        med = [statistics.median(r[k] for r in rows[on]) for k in range(4)]
        print("median, light passes %-3s: run %.3f s, native bake %.3f s, light passes %.3f s, EXR %.3f s"
              % ((label,) + tuple(med)))


main()
