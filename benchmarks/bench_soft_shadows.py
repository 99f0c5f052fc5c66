#!/usr/bin/python3
"""Soft shadows: what the shadow samples cost and change, and what Automatic picks.

    /usr/bin/python3 benchmarks/bench_soft_shadows.py [--runs 3] [--threads 2] [--width 1920 --height 1080]
                                                       [--radii 0.25,1.0] [--samples 1,8,16]

Scene: bench_sun05.py's street (4 lamps in their housings, 492 triangles, sigma_t = 0.05 /m,
model sun05, volumetric shadows) with every lamp's Radius set to each of --radii. Per radius:
the median wall time of the bake with each shadow-sample count (after one untimed bake), its
mean / p99 relative difference from 64 samples over the lit fog (penumbra.mean_error's
pixels), and the count Soft Shadow Samples Automatic takes at 5 %, 1 % and 0.1 % with its
probe's time.
"""

import argparse
import importlib.util
import os
import statistics
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import bench_sun05 as street  # noqa: E402  (also puts addon/airlight on sys.path)

import _native  # noqa: E402

_spec = importlib.util.spec_from_file_location("penumbra", os.path.join(os.path.dirname(HERE), "addon", "airlight",
                                                                        "penumbra.py"))
penumbra = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(penumbra)


def differences(a, ref):
    """(mean, p99) relative difference of airlight _a_ from _ref_ over the lit fog."""
    s, r = a.sum(axis=-1, dtype=np.float64), ref.sum(axis=-1, dtype=np.float64)
    lit = r > penumbra.FLOOR * np.percentile(r, 99)
    e = np.abs(s[lit] - r[lit]) / r[lit]
    return float(e.mean()), float(np.percentile(e, 99))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--width", type=int, default=1920)
    ap.add_argument("--height", type=int, default=1080)
    ap.add_argument("--radii", default="0.25,1.0")
    ap.add_argument("--samples", default="1,8,16")
    args = ap.parse_args()
    verts, tris, lights, intens = street.street_scene()
    cam_to_world, P = street.camera_matrices(args.width, args.height)
    print(f"Airlight bench_soft_shadows: street {args.width}x{args.height}, {len(lights)} lamps, "
          f"threads={args.threads}, runs={args.runs} (medians)")
    for radius in (float(r) for r in args.radii.split(",")):
        scene = dict(width=args.width, height=args.height, cam_to_world=cam_to_world, projection=P, vertices=verts,
                     triangles=tris, sigma_t=street.SIGMA_T, clip_start=street.CLIP[0], clip_end=street.CLIP[1],
                     light_positions=lights, light_intensities=intens, shadows=True,
                     light_radii=np.full(len(lights), radius))
        settings = dict(model="sun05", threads=args.threads)
        reference = _native.bake(**scene, **settings, shadow_samples=64)["airlight"]
        print(f"\nRadius {radius:g} m (differences from 64 samples)")
        base = None
        for samples in (int(k) for k in args.samples.split(",")):
            _native.bake(**scene, **settings, shadow_samples=samples)
            times = []
            for _ in range(args.runs):
                t0 = time.perf_counter()
                result = _native.bake(**scene, **settings, shadow_samples=samples)
                times.append(time.perf_counter() - t0)
            t = statistics.median(times)
            base = base or t
            mean, p99 = differences(result["airlight"], reference)
            print(f"  {samples:2d} sample(s): {t:7.3f} s ({t / base:5.1f}x), mean {100 * mean:.3f} %, "
                  f"p99 {100 * p99:.2f} %")
        for target in (0.05, 0.01, 0.001):
            choice = penumbra.choose(_native, scene, settings, target)
            print(f"  Automatic at {100 * target:g} %: {choice.samples} sample(s), probe {choice.seconds:.3f} s"
                  f"{f' (target not met: {choice.limited})' if choice.limited else ''}")


if __name__ == "__main__":
    main()
