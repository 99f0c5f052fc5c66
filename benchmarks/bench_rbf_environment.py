#!/usr/bin/python3
"""Environment lighting in Gaussian fog (Fogshop section 4.2): T(u) accuracy, the cost of the
average optical depth Tbar(p) at 1080p, and the far field's error, printed as tables.

    /usr/bin/python3 benchmarks/bench_rbf_environment.py [--runs 3] [--threads 2]

No Blender needed. `_native` from addon/airlight (or $AIRLIGHT_NATIVE_DIR). The scene is
bench_rbf.py's: a camera at the origin looking down +z (60 degree horizontal field of view),
a ground plane y = -2 and, here, a back wall z = 100 so that every one of the 1920 x 1080
pixel-centre rays hits a surface; its 34 (1/a 3..10 m) and 3000 (1/a 1..3 m) Gaussian clouds
with the same seeds; beta0 = 0.002 / m and the environment 50 m away. Prints:
  - T(u) of the kernel's table and of its Dawson closed form against scipy.special.dawsn;
  - the median wall and CPU time of rbf_average_depth on the 2,073,600 hit points per
    far-field tolerance, the terms it evaluated per point, and brute force (every Gaussian
    through Dawson's function) timed on every 64th (34) / 1024th (3000) point and scaled;
  - the far field's largest relative error against brute force on those points (the bound
    is the tolerance) and the largest error of the Gaussians' part alone.
"""
import argparse
import math
import os
import statistics
import sys
import time

import numpy as np

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.environ.get("AIRLIGHT_NATIVE_DIR") or os.path.join(REPO, "addon", "airlight"))
import _native  # noqa: E402

BETA0 = 0.002
DISTANCE = 50.0


def hit_points(width, height):
    t = math.tan(math.radians(30.0))
    xs = -((np.arange(width) + 0.5) / width * 2 - 1) * t
    ys = (1 - (np.arange(height) + 0.5) / height * 2) * t * height / width
    X, Y = np.meshgrid(xs, ys)
    d = np.stack([X, Y, np.ones_like(X)], axis=-1).reshape(-1, 3)
    d /= np.linalg.norm(d, axis=1)[:, None]
    with np.errstate(divide="ignore"):
        ground = np.where(d[:, 1] < -1e-9, -2.0 / d[:, 1], np.inf)
    wall = 100.0 / d[:, 2]
    return d * np.minimum(ground, wall)[:, None]


def cloud(n, inv_a_range, c_range, seed):
    rng = np.random.default_rng(seed)
    b = np.column_stack([rng.uniform(-30, 30, n), rng.uniform(-2, 6, n), rng.uniform(10, 80, n)])
    a = 1.0 / rng.uniform(*inv_a_range, n)
    c = rng.uniform(*c_range, n)
    return b, a, c


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--threads", type=int, default=2)
    args = parser.parse_args()

    from scipy.special import dawsn
    u = np.concatenate([np.linspace(0.0, 12.0, 200001), np.geomspace(12.0, 1e4, 2000)])
    ref = np.where(u > 0, 0.5 * np.sqrt(np.pi) * dawsn(np.maximum(u, 1e-300)) / np.maximum(u, 1e-300),
                   0.5 * np.sqrt(np.pi))
    print("## T(u) = (sqrt(pi)/2) F(u)/u against scipy.special.dawsn (u in [0, 1e4], 202001 points)\n")
    for exact in (False, True):
        err = np.abs(_native.average_depth_unit(u, exact=exact) / ref - 1.0)
        print(f"- {'Dawson closed form' if exact else 'table (step 1/128 on [0, 32], asymptotic beyond)'}: "
              f"max relative error {err.max():.2e}")

    p = hit_points(1920, 1080)
    print(f"\n## Tbar(p) on {len(p)} hit points (1920x1080), {args.threads} threads, median of {args.runs}\n")
    print("| Gaussians | method | wall ms | CPU ms (all threads) | terms / point (far nodes; linearised nodes, "
          "Gaussians) | "
          "max rel. error vs brute force | max error of the Gaussians' part |")
    print("|---|---|---|---|---|---|---|")
    for name, (b, a, c), step in (("34", cloud(34, (3.0, 10.0), (0.005, 0.02), 1), 64),
                                  ("3000", cloud(3000, (1.0, 3.0), (0.01, 0.05), 2), 1024)):
        sub = p[::step]
        kw = dict(centres=b, scales=a, amplitudes=c, beta0=BETA0, distance=DISTANCE, threads=args.threads)
        t0, c0 = time.perf_counter(), time.process_time()
        exact = _native.rbf_average_depth(points=sub, exact=True, **kw)["average_depth"]
        scale = len(p) / len(sub)
        t_brute, c_brute = (time.perf_counter() - t0) * scale, (time.process_time() - c0) * scale
        gauss = exact - BETA0 * DISTANCE
        print(f"| {name} | brute force (Dawson), every {step}th point, scaled | {t_brute * 1e3:.0f} | "
              f"{c_brute * 1e3:.0f} | {len(b)} | ref | ref |")
        for tol in (0.0, 1e-3, 1e-2):
            full = not (tol == 0.0 and len(b) > 100)  # every Gaussian at 3000: subsample, scaled
            pts = p if full else sub
            times, cpus = [], []
            for _ in range(args.runs if full else 1):
                t0, c0 = time.perf_counter(), time.process_time()
                out = _native.rbf_average_depth(points=pts, tolerance=tol, **kw)
                times.append(time.perf_counter() - t0)
                cpus.append(time.process_time() - c0)
            k = 1.0 if full else scale
            st = out["stats"]
            terms = (st["near_terms"] + st["far_terms"]) / st["points"]
            approx = out["average_depth"][::step] if full else out["average_depth"]  # the same run's values
            rel = np.max(np.abs(approx / exact - 1.0))
            part = np.max(np.abs(approx - exact) / np.maximum(gauss, 1e-300))
            label = "table, every Gaussian" if tol == 0 else f"tree, tolerance {tol:g}"
            if not full:
                label += f" (every {step}th point, scaled)"
            lin = st["linear_terms"] / st["points"]
            far_lin = st["far_linear_terms"] / st["points"]
            print(f"| {name} | {label} | {statistics.median(times) * k * 1e3:.0f} | "
                  f"{statistics.median(cpus) * k * 1e3:.0f} | {terms:.1f} ({st['far_terms'] / st['points']:.1f} far; "
                  f"{far_lin:.0f}, {lin:.0f} linear) | "
                  f"{rel:.2e} | {part:.2e} |")

    print("\n## Per-pixel irradiance (environment_irradiance_varying) at 1080p\n")
    rng = np.random.default_rng(0)
    normals = rng.normal(size=(len(p), 3))
    T = rng.uniform(0.0, 5.0, len(p))
    sh = rng.uniform(0.0, 1.0, (9, 3))
    sh[0] += 3.0
    times = []
    for _ in range(args.runs):
        t0 = time.perf_counter()
        _native.environment_irradiance_varying(sh, np.ones(3), normals, T, threads=args.threads)
        times.append(time.perf_counter() - t0)
    print(f"- {len(p)} normals: {statistics.median(times) * 1e3:.0f} ms (median of {args.runs})")


if __name__ == "__main__":
    main()
