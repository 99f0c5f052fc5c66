#!/usr/bin/python3
"""Benchmark of the Gaussian (RBF) medium: screen optical depth and Fogshop airlight.

    /usr/bin/python3 benchmarks/bench_rbf.py [--runs 3] [--threads 2] [--width 1920 --height 1080]

No Blender needed: a 1920x1080 pinhole camera at the origin looking down +z (60 degree
horizontal field of view) over a ground plane y = -2 (Dvp = the ground hit, inf above the
horizon), and synthetic clouds of Gaussians in front of it (seeded, so runs compare):
  - 34 broad Gaussians (1/a 3..10 m), 3 lights;
  - 3000 paint-brush-sized Gaussians (1/a 1..3 m), 1 light;
  - 1e5 small Gaussians (1/a 0.3..1 m), optical depth only.
`_native` is imported from $AIRLIGHT_NATIVE_DIR or addon/airlight. Prints medians over
--runs runs of the screen optical depth T(v, p) and of the airlight (model "fogshop"),
the per-ray cost, and PASS/FAIL against the issue's targets (3000 Gaussians, 1 light,
1080p <= 200 ms; 34 Gaussians, 3 lights <= 30 ms). Also the Fogshop error against the
quadrature reference on a sparse subset of the 34-Gaussian image.
"""

import argparse
import os
import statistics
import sys
import time

import numpy as np

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.environ.get("AIRLIGHT_NATIVE_DIR") or os.path.join(REPO, "addon", "airlight"))

import _native  # noqa: E402

TARGETS_MS = {("3000", 1): 200.0, ("34", 3): 30.0}


def camera_rays(w, h):
    """Unit directions (h*w, 3), top row first, and Dvp to the ground plane y = -2."""
    tan_half = np.tan(np.radians(30.0))
    xs = ((np.arange(w) + 0.5) / w * 2 - 1) * tan_half
    ys = (1 - (np.arange(h) + 0.5) / h * 2) * tan_half * h / w
    X, Y = np.meshgrid(xs, ys)
    d = np.stack([X, Y, np.ones_like(X)], axis=-1).reshape(-1, 3)
    d /= np.linalg.norm(d, axis=1)[:, None]
    with np.errstate(divide="ignore"):
        Dvp = np.where(d[:, 1] < -1e-9, -2.0 / d[:, 1], np.inf)
    return d, Dvp


def cloud(n, inv_a_range, c_range, seed):
    rng = np.random.default_rng(seed)
    b = np.column_stack([rng.uniform(-30, 30, n), rng.uniform(-2, 6, n), rng.uniform(10, 80, n)])
    a = 1.0 / rng.uniform(*inv_a_range, n)
    c = rng.uniform(*c_range, n)
    return b, a, c


def timed(fn, runs):
    times = []
    out = None
    for _ in range(runs):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times), out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--width", type=int, default=1920)
    ap.add_argument("--height", type=int, default=1080)
    ap.add_argument("--skip-1e5", action="store_true")
    ap.add_argument("--cull-eps", type=float, default=None,
                    help="per-Gaussian optical depth the culling may drop (default: the medium's 1e-7)")
    args = ap.parse_args()
    d, Dvp = camera_rays(args.width, args.height)
    m_rays = d.shape[0]
    v = np.zeros(3)
    origins = np.zeros_like(d)
    lights3 = np.array([[-8.0, 4.0, 30.0], [6.0, 3.0, 45.0], [0.0, 8.0, 60.0]])
    print(f"_native {_native.__version__}, {args.width}x{args.height} = {m_rays} rays, {args.threads} threads, "
          f"median of {args.runs}, cull_eps {args.cull_eps or 1e-7:g}")
    if m_rays != 1920 * 1080:
        print("(targets are for 1920x1080: times here are for fewer rays; scale by rays)")
    scenes = [("34", cloud(34, (3.0, 10.0), (0.005, 0.02), 1), 0.002, [3]),
              ("3000", cloud(3000, (1.0, 3.0), (0.01, 0.05), 2), 0.002, [1, 3])]
    if not args.skip_1e5:
        scenes.append(("100000", cloud(100000, (0.3, 1.0), (0.01, 0.05), 3), 0.002, []))
    for name, (b, a, c), beta0, light_counts in scenes:
        t0 = time.perf_counter()
        kw = {} if args.cull_eps is None else {"cull_eps": args.cull_eps}
        m = _native.RbfMedium(b, a, c, beta0=beta0, **kw)
        build = time.perf_counter() - t0
        t_od, T = timed(lambda: m.optical_depth_ray(origins, d, Dvp, threads=args.threads), args.runs)
        finite = np.isfinite(T)
        print(f"[{name:>6} Gaussians] build {build * 1e3:7.1f} ms | screen optical depth {t_od * 1e3:8.1f} ms "
              f"({t_od * args.threads / m_rays * 1e9:6.0f} ns/ray/thread), mean T {T[finite].mean():.3f}")
        for L in light_counts:
            lights = lights3[:L]
            t_air, La = timed(lambda: m.airlight(lights, v, d, Dvp, threads=args.threads), args.runs)
            ms = t_air * 1e3
            line = (f"[{name:>6} Gaussians] airlight, {L} light(s): {ms:8.1f} ms "
                    f"({t_air * args.threads / m_rays * 1e9:6.0f} ns/ray/thread), mean La {La.mean():.3e}")
            target = TARGETS_MS.get((name, L))
            if target is not None:
                ms_full = ms * (1920 * 1080) / m_rays  # scaled to 1080p when run smaller
                line += f" | at 1080p {ms_full:.0f} ms, target <= {target:.0f} ms: {'PASS' if ms_full <= target else 'FAIL'}"
            print(line)
        if name == "34":
            # Accuracy on a sparse subset (the quadrature reference is ~ms per ray).
            idx = np.arange(0, m_rays, max(1, m_rays // 600))
            fog = m.airlight(lights3, v, d[idx], Dvp[idx], threads=args.threads)
            ref = m.airlight(lights3, v, d[idx], Dvp[idx], model="quadrature", threads=args.threads)
            keep = ref > 1e-6 * ref.max()
            err = np.abs(fog[keep] - ref[keep]) / ref[keep]
            print(f"[    34 Gaussians] fogshop vs quadrature on {idx.size} rays x 3 lights: relative error "
                  f"mean {err.mean():.4f} p99 {np.percentile(err, 99):.4f} max {err.max():.4f}")


if __name__ == "__main__":
    main()
