"""A light's Radius in the fog (homogeneous/sphere_light.h): the native bake of the street at
1920x1080 with its lamps as points and with each lamp's Radius set to 0.1, 0.25 and 0.5 m,
alternating, three runs each, 2 threads.

    tools/blender.sh -b blend_examples/street.blend --python benchmarks/bench_light_radius.py

Prints each run's seconds and the medians, and each radius's median as a ratio to the points'.
The radius costs rays that pass within sphere_light_reach (27 radii in clear fog) of a lamp.
"""
import statistics
import time

import bpy
import numpy as np

from airlight import native, scene_export

RUNS = 3
RADII = (0.0, 0.1, 0.25, 0.5)


def main():
    scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y, scene.render.resolution_percentage = 1920, 1080, 100
    description = scene_export.export_scene(scene, bpy.context.evaluated_depsgraph_get())
    description.pop("light_radii", None)
    description.pop("spot_radii", None)
    module = native.get()
    n_points = len(description["light_positions"])
    n_spots = len(description.get("spot_positions", ()))
    print(f"street 1920x1080: {n_points} point lights, {n_spots} spots, sigma_t {description['sigma_t']:g} /m")
    times = {r: [] for r in RADII}
    for _ in range(RUNS):
        for r in RADII:
            extra = {}
            if r > 0.0:
                extra["light_radii"] = np.full(n_points, r)
                if n_spots:
                    extra["spot_radii"] = np.full(n_spots, r)
            t0 = time.perf_counter()
            module.bake(**description, **extra, threads=2)
            times[r].append(time.perf_counter() - t0)
            print(f"radius {r:.2f} m: {times[r][-1]:.3f} s")
    base = statistics.median(times[0.0])
    for r in RADII:
        med = statistics.median(times[r])
        print(f"median, radius {r:.2f} m: {med:.3f} s ({med / base:.2f}x the points)")


main()
