#!/usr/bin/python3
"""Cost and accuracy of the bake's edge supersampling (bake.cpp pass 2, edge pixels).

    /usr/bin/python3 benchmarks/bench_edge.py [--runs 7] [--threads 2] [--width 1920 --height 1080]
                                              [--resolution quarter] [--scenes 34,3000,walls]

bench_rbf.py's Gaussian scenes (34 Gaussians / 3 lights, 3000 / 1, 3000 / 1 with walls) at
gaussian_resolution --resolution. Per scene, medians over --runs runs (interleaved) of the
whole bake's wall clock, its process CPU time and its airlight pass (stats seconds_airlight)
for: aa_samples=1 (no supersampling), the per-sample supersampling (edge_cluster_tol=0: every
sub-sample's fog evaluated) and the default (one fog evaluation per cluster of sub-samples).
The supersampling's cost is each one's excess over aa_samples=1 and, less noisy, the edge
pass's own time (stats seconds_edges: summed over the threads; median and least). Also the
fog evaluations on
edge pixels (stats samples beyond one per pixel) and the clustered bake's relative error
against the per-sample one on the edge pixels (pixels whose per-sample value differs from
aa_samples=1; Airlight: all channels of pixels above 1e-6 of the largest; Transmittance:
|dT| / max(T, 1e-3), and relative where T > 1e-3). A build without edge_cluster_tol (before
the clusters) times aa_samples=1 and its supersampling only. `_native` is imported from
$AIRLIGHT_NATIVE_DIR or addon/airlight.
"""

import argparse
import os
import statistics
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import bench_rbf as B  # noqa: E402  (imports _native)

_native = B._native


def kwargs(name, width, height, resolution, threads):
    cam, proj = B.camera(width, height)
    if name == "34":
        gauss, lights, walls = B.cloud(34, (3.0, 10.0), (0.005, 0.02), 1), 3, False
    else:
        gauss, lights, walls = B.cloud(3000, (1.0, 3.0), (0.01, 0.05), 2), 1, name == "walls"
    v, t = B.ground(walls)
    return dict(width=width, height=height, cam_to_world=cam, projection=proj, clip_start=B.CLIP[0],
                clip_end=B.CLIP[1], vertices=v, triangles=t, light_positions=B.LIGHTS[:lights],
                light_intensities=np.full((lights, 3), B.I0), sigma_t=B.BETA0, albedo=(0.9, 0.9, 0.9),
                model="sun05", threads=threads, rbf_centres=gauss[0], rbf_scales=gauss[1],
                rbf_amplitudes=gauss[2], gaussian_resolution=resolution)


def errors(got, ref, centre):
    edge = (np.any(ref["airlight"] != centre["airlight"], axis=-1) |
            np.any(ref["transmittance"] != centre["transmittance"], axis=-1))
    A, A0 = got["airlight"][edge].astype(np.float64), ref["airlight"][edge].astype(np.float64)
    m = A0 > 1e-6 * A0.max()
    ra = np.abs(A - A0)[m] / A0[m]
    T, T0 = got["transmittance"][edge].astype(np.float64), ref["transmittance"][edge].astype(np.float64)
    rt = np.abs(T - T0) / np.maximum(T0, 1e-3)
    big = T0 > 1e-3
    rtb = np.abs(T - T0)[big] / T0[big] if big.any() else np.zeros(1)
    return (f"Airlight mean {ra.mean():.1e} p99 {np.percentile(ra, 99):.1e} max {ra.max():.1e}; "
            f"Transmittance |dT|/max(T,1e-3) mean {rt.mean():.1e} p99 {np.percentile(rt, 99):.1e} "
            f"max {rt.max():.1e} (T > 1e-3: max {rtb.max():.1e})")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--runs", type=int, default=7)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--width", type=int, default=1920)
    ap.add_argument("--height", type=int, default=1080)
    ap.add_argument("--resolution", default="quarter")
    ap.add_argument("--scenes", default="34,3000,walls")
    args = ap.parse_args()
    try:
        _native.bake(**dict(kwargs("34", 64, 36, args.resolution, 1), edge_cluster_tol=0.0))
        clusters = True
    except TypeError:
        clusters = False
    configs = [("aa_samples=1", dict(aa_samples=1))]
    configs += [("per-sample", dict(edge_cluster_tol=0.0)), ("clusters", {})] if clusters else [("supersampled", {})]
    print(f"_native {_native.__version__}, bake {args.width}x{args.height}, gaussian_resolution {args.resolution}, "
          f"{args.threads} threads, median of {args.runs} runs")
    for name in args.scenes.split(","):
        kw = kwargs(name, args.width, args.height, args.resolution, args.threads)
        _native.bake(**kw)  # warm-up (tables, pages)
        wall = {c: [] for c, _ in configs}
        cpu = {c: [] for c, _ in configs}
        air = {c: [] for c, _ in configs}
        edges = {c: [] for c, _ in configs}
        out = {}
        for _ in range(args.runs):
            for c, extra in configs:
                t0, c0 = time.perf_counter(), time.process_time()
                out[c] = _native.bake(**kw, **extra)
                wall[c].append(time.perf_counter() - t0)
                cpu[c].append(time.process_time() - c0)
                air[c].append(out[c]["stats"]["seconds_airlight"])
                edges[c].append(out[c]["stats"].get("seconds_edges", float("nan")))
        med = {c: (statistics.median(wall[c]) * 1e3, statistics.median(cpu[c]) * 1e3,
                   statistics.median(air[c]) * 1e3) for c, _ in configs}
        base = out["aa_samples=1"]["stats"]["samples"]
        label = {"34": "34 Gaussians, 3 lights", "3000": "3000 Gaussians, 1 light",
                 "walls": "3000 Gaussians + walls, 1 light"}[name]
        print(f"[{label}] {out[configs[-1][0]]['stats']['supersampled_pixels']} edge pixels")
        for c, _ in configs:
            w, p, a = med[c]
            line = f"  {c:>13}: wall {w:6.1f} ms  CPU {p:6.1f} ms  airlight {a:6.1f} ms"
            if c != "aa_samples=1":
                w1, p1, a1 = med["aa_samples=1"]
                e = statistics.median(edges[c]) * 1e3
                line += (f"  | supersampling: wall +{w - w1:5.1f} ms, CPU +{p - p1:5.1f} ms, edge pass {e:5.1f} ms "
                         f"(threads' sum, min {min(edges[c]) * 1e3:5.1f}); "
                         f"{out[c]['stats']['samples'] - base} fog evaluations on edge pixels")
            print(line)
        if clusters:
            print("  clusters vs per-sample on edge pixels: " +
                  errors(out["clusters"], out["per-sample"], out["aa_samples=1"]))


if __name__ == "__main__":
    main()
