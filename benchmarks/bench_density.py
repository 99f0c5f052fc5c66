#!/usr/bin/python3
"""The bake's cost from thin to opaque fog: thick fog must cost no more than thin fog.

    /usr/bin/python3 benchmarks/bench_density.py [--runs 3] [--threads 2] [--width 960 --height 540]

Scene: bench_sun05.py's street (ground, buildings, lamp posts, 4 lamps), clip range (0.1,
1000). For each density sigma_t from 1e-3 to 1e4 /m (the property's range), the median over
--runs bakes (after one untimed bake that builds any table it needs) of the whole bake, with
and without surface shading, for the isotropic phase (model sun05) and Henyey-Greenstein
g = 0.6 (model biri06, the phase-aware glow tables). The last column is each row's time over
the thinnest fog's, the figure that shows the cost is bounded. Also printed: the first bake's
extra time at each density (tables built on first use: the surface G table's large-T tail is
built when a surface first sees T > 64).
"""

import argparse
import os
import statistics
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import bench_sun05 as street  # noqa: E402  (also puts addon/airlight on sys.path)

DENSITIES = [1e-3, 1e-2, 0.1, 1.0, 5.0, 100.0, 1e4]


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--width", type=int, default=960)
    ap.add_argument("--height", type=int, default=540)
    args = ap.parse_args()
    import _native

    cam_to_world, P = street.camera_matrices(args.width, args.height)
    verts, tris, lights, intens = street.street_scene()
    base = dict(width=args.width, height=args.height, cam_to_world=cam_to_world, projection=P, vertices=verts,
                triangles=tris, light_positions=lights, light_intensities=intens, threads=args.threads,
                clip_start=street.CLIP[0], clip_end=street.CLIP[1])
    print(f"Airlight bench_density: {args.width}x{args.height}, {len(tris)} triangles, {len(lights)} lamps, "
          f"threads={args.threads}, runs={args.runs} (medians, ms)")
    for label, phase in (("isotropic, sun05", dict(model="sun05")),
                         ("HG g = 0.6, biri06", dict(model="biri06", phase="hg", g=0.6))):
        print(f"\n{label}")
        print(f"{'sigma_t /m':>10} | {'plain':>8} | {'surface':>8} | {'first surface bake':>18} | {'surface / thinnest':>18}")
        thinnest = None
        for sigma_t in DENSITIES:
            kw = dict(base, sigma_t=sigma_t, **phase)
            t0 = time.perf_counter()
            _native.bake(**kw, surface=True)
            first = time.perf_counter() - t0
            plain, surf = [], []
            for _ in range(args.runs):
                t0 = time.perf_counter()
                _native.bake(**kw)
                plain.append(time.perf_counter() - t0)
                t0 = time.perf_counter()
                _native.bake(**kw, surface=True)
                surf.append(time.perf_counter() - t0)
            p, s = 1000.0 * statistics.median(plain), 1000.0 * statistics.median(surf)
            thinnest = thinnest or s
            print(f"{sigma_t:>10g} | {p:8.1f} | {s:8.1f} | {1000.0 * first:18.1f} | {s / thinnest:18.2f}")


if __name__ == "__main__":
    main()
