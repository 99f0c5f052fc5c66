#!/usr/bin/python3
"""Cost of the surface-shading pass of the bake (native/bake/surface_pass.cpp).

    /usr/bin/python3 benchmarks/bench_surface.py [--runs 5] [--threads 2]

Scene: bench_sun05.py's 1920x1080 street (ground, buildings, lamp posts, 4 lamps), sigma_t
0.05 /m, model sun05, clip range (0.1, 1000). Prints medians over --runs runs of the bake's
`seconds_surface` (pixel-centre ray cast with normals + per-light attenuation + Lambert glow
table lookups) with 1 and 4 lights, the whole bake's wall time with and without the pass,
and the one-off build time of the Lambert G table (128 x 128; once per process).
"""

import argparse
import os
import statistics
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import bench_sun05 as street  # noqa: E402  (also puts addon/airlight on sys.path)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--threads", type=int, default=2)
    args = ap.parse_args()
    import _native

    cam_to_world, P = street.camera_matrices(street.WIDTH, street.HEIGHT)
    verts, tris, lights, intens = street.street_scene()
    base = dict(width=street.WIDTH, height=street.HEIGHT, cam_to_world=cam_to_world, projection=P,
                vertices=verts, triangles=tris, sigma_t=street.SIGMA_T, model="sun05",
                threads=args.threads, clip_start=street.CLIP[0], clip_end=street.CLIP[1])
    print(f"Airlight bench_surface: {street.WIDTH}x{street.HEIGHT}, {len(tris)} triangles, "
          f"threads={args.threads}, runs={args.runs} (medians)")

    # First bake with surface=True builds the Lambert G table: time it once.
    t0 = time.perf_counter()
    _native.bake(**base, light_positions=lights[:1], light_intensities=intens[:1], surface=True)
    first = time.perf_counter() - t0
    t0 = time.perf_counter()
    _native.bake(**base, light_positions=lights[:1], light_intensities=intens[:1], surface=True)
    second = time.perf_counter() - t0
    print(f"G table build (first surface bake minus the second): {1000.0 * (first - second):.0f} ms")

    for n in (1, 4):
        kw = dict(base, light_positions=lights[:n], light_intensities=intens[:n])
        walls, surf, plain = [], [], []
        for _ in range(args.runs):
            t0 = time.perf_counter()
            res = _native.bake(**kw, surface=True)
            walls.append(time.perf_counter() - t0)
            surf.append(res["stats"]["seconds_surface"])
            t0 = time.perf_counter()
            _native.bake(**kw)
            plain.append(time.perf_counter() - t0)
        ms = lambda xs: 1000.0 * statistics.median(xs)
        print(f"{n} light(s): surface pass {ms(surf):.1f} ms "
              f"({1e9 * statistics.median(surf) / (street.WIDTH * street.HEIGHT * n):.1f} ns per pixel*light); "
              f"bake wall {ms(walls):.1f} ms with / {ms(plain):.1f} ms without")


if __name__ == "__main__":
    main()
