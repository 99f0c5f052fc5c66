"""Embree's BVH shared between bakes of the same geometry (image/raycast.h, RayCaster::shared).

    /usr/bin/python3 benchmarks/bench_geometry_cache.py [--triangles 2000000] [--runs 3]

A wavy plane of N triangles in fog, one point light, 64x36 pixels (so the geometry's cost
shows): the first bake of the mesh (BVH built), then bakes of equal copies (shared), then,
with volumetric shadows, the same pair. Prints each bake's wall time and the medians.
"""
import argparse
import math
import os
import statistics
import sys
import time

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "addon", "airlight"))
import _native  # noqa: E402


def wavy_plane(triangles):
    n = max(1, int(math.sqrt(triangles / 2)))
    u = np.linspace(-50.0, 50.0, n + 1)
    X, Y = np.meshgrid(u, u)
    V = np.column_stack([X.ravel(), Y.ravel() + 60.0, (0.3 * np.sin(X) * np.cos(Y)).ravel() - 2.0]).astype(np.float32)
    i = (np.arange(n)[:, None] * (n + 1) + np.arange(n)[None, :]).ravel()
    T = np.concatenate([np.column_stack([i, i + 1, i + n + 2]), np.column_stack([i, i + n + 2, i + n + 1])])
    return V, T.astype(np.uint32)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--triangles", type=int, default=2_000_000)
    ap.add_argument("--runs", type=int, default=3)
    args = ap.parse_args()
    V, T = wavy_plane(args.triangles)
    cam = np.eye(4)
    cam[:3, :3] = [[1, 0, 0], [0, 0, -1], [0, 1, 0]]
    f = 1.0 / math.tan(0.4)
    proj = np.array([[f, 0, 0, 0], [0, f * 16 / 9, 0, 0], [0, 0, -1.0002, -0.2], [0, 0, -1, 0]])
    kw = dict(width=64, height=36, cam_to_world=cam, projection=proj, light_positions=np.array([[0.0, 20.0, 3.0]]),
              light_intensities=np.full((1, 3), 100.0), sigma_t=0.05, threads=2)
    print(f"{len(T)} triangles, 64x36")
    for label, extra in (("no shadows", {}), ("volumetric shadows", dict(shadows=True, light_shadows=np.array([True])))):
        first, shared = [], []
        for _ in range(args.runs):
            _native.clear_geometry_cache()
            for times in (first, shared, shared):
                t0 = time.perf_counter()
                _native.bake(vertices=V.copy(), triangles=T.copy(), **kw, **extra)
                times.append(time.perf_counter() - t0)
        print(f"{label}: first bake of the mesh {statistics.median(first):.3f} s, "
              f"same mesh again {statistics.median(shared):.3f} s (medians)")


main()
