"""A light's Radius in the fog (homogeneous/sphere_light.h): the native bake of the street at
1920x1080 with its lamps as points and with each lamp's Radius set to 0.1, 0.25 and 0.5 m,
alternating, three runs each, 2 threads.

    tools/blender.sh -b blend_examples/street.blend --python benchmarks/bench_light_radius.py

Prints each run's seconds and the medians, and each radius's median as a ratio to the points'.
The radius costs rays that pass within sphere_light_reach (27 radii in clear fog at the
default light_size_tolerance 1e-3) of a lamp. Then, at Blender's default 0.25 m, the
tolerance Automatic passes at 5 %, 1 % and 0.1 % (a quarter of the target, at most 5e-3) against the
default: each one's median time (alternating, the same runs) and its airlight's relative
error against a bake at tolerance 1e-6 (mean, p99 and max over the pixels with fog).
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

    radii = dict(light_radii=np.full(n_points, 0.25))
    if n_spots:
        radii["spot_radii"] = np.full(n_spots, 0.25)
    ref = module.bake(**description, **radii, threads=2, light_size_tolerance=1e-6)["airlight"][..., 0]
    ref = np.asarray(ref, np.float64)
    fog = ref > 1e-6 * ref.max()
    tols = {"default": 1e-3, "auto 5 %": 0.005, "auto 1 %": 0.0025, "auto 0.1 %": 0.00025}
    spent = {k: [] for k in tols}
    errors = {}
    for _ in range(RUNS):
        for name, tol in tols.items():
            t0 = time.perf_counter()
            out = module.bake(**description, **radii, threads=2, light_size_tolerance=tol)
            spent[name].append(time.perf_counter() - t0)
            e = np.abs(np.asarray(out["airlight"][..., 0], np.float64) - ref)[fog] / ref[fog]
            errors[name] = (e.mean(), np.percentile(e, 99), e.max())
    for name, tol in tols.items():
        med = statistics.median(spent[name])
        mean, p99, worst = errors[name]
        print(f"radius 0.25 m, light_size_tolerance {tol:g} ({name}): {med:.3f} s ({med / base:.2f}x the points), "
              f"error mean {mean:.2e} p99 {p99:.2e} max {worst:.2e}")


main()
