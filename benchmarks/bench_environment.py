#!/usr/bin/python3
"""Environment glow (Sun 2005 section 6: PSF, spherical-harmonic convolution of the World):
cost and error against the exact reference, printed as tables.

    /usr/bin/python3 benchmarks/bench_environment.py [--runs 5]

No Blender needed. `_native` from addon/airlight (or $AIRLIGHT_NATIVE_DIR). Prints medians of:
  - the PSF factorisation (eq. 22) against the exact PSF (eq. 20): lambda_0 (the glow's total
    energy) and lambda_8 ratios for optical distances Tsv = 0.1 .. 20;
  - the cost of environment_fog (SH projection, eigenvalues, reconstruction to 256x128) per SH
    order, with the exact and the factorised eigenvalues, and of environment_view at 1920x1080;
  - the error of the SH glow against the direct convolution with the exact PSF (the reference)
    on a sky with a small bright sun, per SH order (mean and p99 relative over the map).
"""
import argparse
import os
import sys
import time

import numpy as np

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.environ.get("AIRLIGHT_NATIVE_DIR") or os.path.join(REPO, "addon", "airlight"))
import _native  # noqa: E402
from timing import median_seconds  # noqa: E402




def sky(width, height, sun_width):
    v = 1.0 - (np.arange(height) + 0.5) / height
    u = (np.arange(width) + 0.5) / width
    theta = (1.0 - v)[:, None] * np.pi
    phi = (0.5 - u)[None, :] * 2.0 * np.pi
    d = np.stack([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta) + 0 * phi], -1)
    sun_dir = np.array([0.3, 0.5, 0.81])
    sun_dir /= np.linalg.norm(sun_dir)
    sun = np.exp((d @ sun_dir - 1.0) / sun_width ** 2)
    value = 0.3 + 0.2 * np.clip(d[..., 2], 0, 1) + 20.0 * sun
    return np.ascontiguousarray(np.repeat(value[..., None], 3, axis=2), dtype=np.float32)


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--runs", type=int, default=5)
    args = parser.parse_args()

    print("## PSF factorisation (eq. 22) vs exact PSF (eq. 20)\n")
    print("| Tsv | lambda_0 factorised / exact | lambda_8 factorised / exact |")
    print("|---|---|---|")
    for Tsv in (0.1, 0.5, 1.0, 2.0, 5.0, 20.0):
        ex = _native.psf_eigenvalues(Tsv, 8, "exact")
        fa = _native.psf_eigenvalues(Tsv, 8, "factorised")
        print(f"| {Tsv:g} | {fa[0] / ex[0]:.4f} | {fa[8] / ex[8]:.4f} |")

    world = sky(256, 128, 0.08)
    print(f"\n## Cost (medians of {args.runs}; World 256x128, glow map 256x128)\n")
    print("| SH order | environment_fog exact (ms) | factorised (ms) |")
    print("|---|---|---|")
    for L in (8, 16, 24, 48):
        t_ex = median_seconds(lambda: _native.environment_fog(world=world, sigma_t=0.02, distance=60.0,
                                                           albedo=[1, 1, 1], sh_order=L, kind="exact"), args.runs)
        t_fa = median_seconds(lambda: _native.environment_fog(world=world, sigma_t=0.02, distance=60.0,
                                                           albedo=[1, 1, 1], sh_order=L, kind="factorised"),
                           args.runs)
        print(f"| {L} | {1e3 * t_ex:.1f} | {1e3 * t_fa:.1f} |")
    glow = _native.environment_fog(world=world, sigma_t=0.02, distance=60.0, albedo=[1, 1, 1], sh_order=24)["glow"]
    cam = np.eye(4)
    proj = np.array([[1.0, 0, 0, 0], [0, 16 / 9, 0, 0], [0, 0, -1.0002, -0.2], [0, 0, -1, 0]])
    t_view = median_seconds(lambda: _native.environment_view(cam_to_world=cam, projection=proj, width=1920,
                                                          height=1080, glow=glow), args.runs)
    print(f"\nenvironment_view (glow along every camera ray) at 1920x1080: {1e3 * t_view:.1f} ms")

    print("\n## SH glow vs direct convolution with the exact PSF (World 48x24, Tsv = 1.2)\n")
    small = sky(48, 24, 0.15)
    t = time.perf_counter()
    ref = _native.environment_fog(world=small, sigma_t=0.02, distance=60.0, albedo=[1, 1, 1], sh_order=-1,
                                  out_width=48, out_height=24)["glow"][..., 0]
    t_ref = time.perf_counter() - t
    print(f"(reference: direct convolution, {t_ref:.1f} s)\n")
    print("| SH order | eigenvalues | mean rel err | p99 rel err | max rel err |")
    print("|---|---|---|---|---|")
    for L in (4, 8, 16, 24, 48):
        for kind in ("exact", "factorised"):
            g = _native.environment_fog(world=small, sigma_t=0.02, distance=60.0, albedo=[1, 1, 1], sh_order=L,
                                        out_width=48, out_height=24, kind=kind)["glow"][..., 0]
            rel = np.abs(g - ref) / ref
            print(f"| {L} | {kind} | {100 * rel.mean():.2f} % | {100 * np.percentile(rel, 99):.2f} % | "
                  f"{100 * rel.max():.2f} % |")


if __name__ == "__main__":
    main()
