#!/usr/bin/python3
"""Volumetric shadows: what they cost against unshadowed fog, in one run.

    /usr/bin/python3 benchmarks/bench_shadows.py [--runs 5] [--threads 2] [--width 1920 --height 1080]
                                                 [--skip-growth]

Scene: bench_sun05.py's street (ground, buildings, lamp posts, 4 street lamps, 492
triangles), sigma_t = 0.05 /m, model sun05, clip (0.1, 1000). Printed, as medians over --runs
bakes alternating shadows off / on / on with shadow_crossings='traced' after one untimed bake
of each:
  - the whole bake's wall time with 1, 2 and 4 lamps, shadows off and on, and the ratio
    (target: 4 lamps at 1920x1080, shadowed <= 4x unshadowed), and the same with every
    camera ray's crossings traced through Embree instead of rasterized on the film;
  - the cost growth with the number of occluder triangles: the street plus a field of small
    random triangles (10^3 .. 10^6) around the lamps, 4 lamps, at --width/4 x --height/4;
  - the shadows' effect on the image (the airlight removed, relative);
  - the surface pass with 4 lamps, the glow unshadowed and shadowed (its lit share).
"""

import argparse
import math
import os
import statistics
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import bench_sun05 as street  # noqa: E402  (also puts addon/airlight on sys.path)


def timed(fn, runs):
    times = []
    for _ in range(runs):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times), out


def clutter(n, rng):
    """_n_ small random triangles (0.2-0.6 m) in the street's lamp region."""
    c = np.column_stack([rng.uniform(-6, 6, n), rng.uniform(0, 80, n), rng.uniform(0.3, 4.5, n)])
    v = (c[:, None, :] + rng.uniform(-0.3, 0.3, (n, 3, 3))).reshape(-1, 3).astype(np.float32)
    t = np.arange(3 * n, dtype=np.uint32).reshape(-1, 3)
    return v, t


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--width", type=int, default=1920)
    ap.add_argument("--height", type=int, default=1080)
    ap.add_argument("--skip-growth", action="store_true")
    args = ap.parse_args()
    import _native

    verts, tris, lights, intens = street.street_scene()

    def base(width, height):
        cam_to_world, P = street.camera_matrices(width, height)
        return dict(width=width, height=height, cam_to_world=cam_to_world, projection=P, vertices=verts,
                    triangles=tris, sigma_t=street.SIGMA_T, model="sun05", threads=args.threads,
                    clip_start=street.CLIP[0], clip_end=street.CLIP[1])

    print(f"Airlight bench_shadows: street, {len(tris)} triangles, threads={args.threads}, runs={args.runs} (medians)")
    kw = base(args.width, args.height)
    print(f"\n{args.width}x{args.height}, model sun05")
    for n in (1, 2, 4):
        k = dict(kw, light_positions=lights[:n], light_intensities=intens[:n])
        _native.bake(**k)
        _native.bake(**k, shadows=True)
        _native.bake(**k, shadows=True, shadow_crossings="traced")
        off, on, traced = [], [], []
        for _ in range(args.runs):
            t0 = time.perf_counter()
            a = _native.bake(**k)
            off.append(time.perf_counter() - t0)
            t0 = time.perf_counter()
            b = _native.bake(**k, shadows=True)
            on.append(time.perf_counter() - t0)
            t0 = time.perf_counter()
            _native.bake(**k, shadows=True, shadow_crossings="traced")
            traced.append(time.perf_counter() - t0)
        t_off, t_on = 1000 * statistics.median(off), 1000 * statistics.median(on)
        t_traced = 1000 * statistics.median(traced)
        removed = 1.0 - b["airlight"].sum() / a["airlight"].sum()
        print(f"  {n} lamp(s): unshadowed {t_off:7.1f} ms, shadowed {t_on:7.1f} ms, ratio {t_on / t_off:5.2f} "
              f"(crossings traced by Embree instead: {t_traced:7.1f} ms, {t_traced / t_off:5.2f}; "
              f"shadows remove {100 * removed:.1f} % of the airlight)")
        if n == 4:
            print(f"  target 4 lamps: shadowed <= 4x unshadowed: {'PASS' if t_on <= 4 * t_off else 'FAIL'}")
    # The surface pass: each lamp's glow times its lit share (glow_shadow.h), 4 lamps.
    k = dict(kw, light_positions=lights, light_intensities=intens, surface=True)
    _native.bake(**k)
    _native.bake(**k, shadows=True)
    off, on = [], []
    for _ in range(args.runs):
        off.append(_native.bake(**k)["stats"]["seconds_surface"])
        on.append(_native.bake(**k, shadows=True)["stats"]["seconds_surface"])
    s_off, s_on = 1000 * statistics.median(off), 1000 * statistics.median(on)
    print(f"  surface pass, 4 lamps: unshadowed glow {s_off:7.1f} ms, shadowed glow {s_on:7.1f} ms "
          f"(+{s_on - s_off:.1f} ms)")
    if args.skip_growth:
        return
    w, h = args.width // 4, args.height // 4
    print(f"\ncost growth with occluder triangles, 4 lamps, {w}x{h}")
    rng = np.random.default_rng(7)
    kb = base(w, h)
    kb.update(light_positions=lights, light_intensities=intens)
    _native.bake(**kb)
    t_off, _ = timed(lambda: _native.bake(**kb), args.runs)
    for n in (10**3, 10**4, 10**5, 10**6):
        cv, ct = clutter(n, rng)
        occ_v = np.concatenate([verts, cv])
        occ_t = np.concatenate([tris, ct + len(verts)])
        k = dict(kb, shadows=True, occluder_vertices=occ_v, occluder_triangles=occ_t)
        t0 = time.perf_counter()
        _native.bake(**k)
        first = time.perf_counter() - t0
        t_on, _ = timed(lambda: _native.bake(**k), max(1, args.runs // 2))
        print(f"  {n + len(tris):8d} occluder triangles: shadowed {1000 * t_on:8.1f} ms "
              f"({t_on / t_off:6.1f}x unshadowed {1000 * t_off:.1f} ms)")


if __name__ == "__main__":
    main()
