"""Area lights' sampling error and cost against their sample count, with and without Spread.

    tools/blender.sh -b --python benchmarks/bench_area_spread.py [-- --spreads 50,180]

tests/blender/test_cycles_area.py's scene (96 x 72, sigma_t 0.15 /m) with its light as a
2 m disk of each Spread (degrees); the reference is that test's quadrature of the area
integral with Cycles' soft-box profile written out. For accuracies that give 16 ... 1600
samples (names.area_grid's cap lifted, its Spread narrowing off: the same grids at every
Spread), prints the samples, the mean and p99 relative error of the bake against the
reference over the test's pixels, and the bake's airlight seconds; then the row of the rule
itself at Automatic 1 %. The rule in names.py (cell narrowed by Spread / 180 degrees) comes
from these rows.
"""
import argparse
import math
import os
import sys

import numpy as np

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(REPO, "tests", "blender"))
import bpy  # noqa: E402
import cycles_scenes as cs  # noqa: E402
import test_cycles_area as T  # noqa: E402
from airlight import names, native, scene_export  # noqa: E402


def main():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    ap = argparse.ArgumentParser()
    ap.add_argument("--spreads", default="50,180")
    args = ap.parse_args(argv)
    names.AREA_MAX_PER_AXIS = 64
    share = names._spread_share
    for spread_deg in (float(a) for a in args.spreads.split(",")):
        desc = cs.FogScene(width=96, height=72, samples=16)
        scene = cs.build(desc)
        light = T._make_area(scene, desc, 'DISK', 2.0, 2.0, spread_deg)
        rays = cs.reference_rays(scene, desc, T.LIGHT_RADIUS_PX)
        o, d, depth, Dvp, near_light = (rays[k] for k in ("o", "d", "depth", "Dvp", "near_light"))
        points, weights = T._area_points(light, 'DISK', 2.0, 2.0)
        La = T.area_reference(o, d, Dvp, points, weights, T.AXIS, desc.light_power, desc.sigma_t,
                              math.radians(spread_deg))
        finite = np.isfinite(La)
        mask = finite & (np.where(finite, La, 0.0) > T.SIGNAL_FLOOR * np.nanpercentile(La, 99))
        mask &= ~cs.silhouette_mask(depth, radius=2) & ~near_light
        st = scene.airlight
        st.density = desc.sigma_t
        for accuracy in (1.6, 0.4, 0.1, 0.025, 0.00625, "rule"):
            names._spread_share = share if accuracy == "rule" else (lambda spread: 1.0)
            names.AREA_MAX_PER_AXIS_SPREAD = 16 if accuracy == "rule" else 64
            st.accuracy = 1.0 if accuracy == "rule" else accuracy
            description = scene_export.export_scene(scene, bpy.context.evaluated_depsgraph_get())
            result = native.get().bake(**description, threads=2)
            A = result["airlight"].astype(np.float64)[..., 0]
            mean, p99 = cs.rel_stats(A, La, mask)
            print(f"spread {spread_deg:5.1f} deg  samples {len(description['spot_positions']):5d}  "
                  f"mean {100 * mean:6.3f} %  p99 {100 * p99:6.3f} %  "
                  f"airlight {result['stats']['seconds_airlight']:.3f} s  ({mask.sum()} pixels)"
                  + ("  <- names.area_grid at 1 %" if accuracy == "rule" else ""))


main()
