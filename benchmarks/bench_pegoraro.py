#!/usr/bin/python3
"""Pegoraro et al. 2010 closed form: cost and error vs polynomial order, the spot-profile
fit, and the 1080p spot bake (closed form vs quadrature) in one run.

    /usr/bin/python3 benchmarks/bench_pegoraro.py [--runs 5] [--threads 2] [--quick]

Prints (medians over --runs):
  1. ns per evaluation of `_native.pegoraro10_airlight` (point light, HG truncated at order
     N, 20000 random rays: sigma_t 0.01-3, Dsv 0.1-30 m, all gamma, 30 % Dvp = inf) for
     N = 0..32, split into H = sigma_t h <= 1.5 (forward recurrence) and > 1.5 (Olver).
  2. airlight error vs order for HG g = 0.3 / 0.6 / 0.9 against the phase-aware quadrature
     of the true HG (not the polynomial): the truncation error (mean / p99 / max relative),
     and the order the bake picks (Legendre tail below 1e-6 of the lobe everywhere, at most 96;
     none for g = 0.9: the bake refuses pegoraro10 there).
  3. the single-polynomial least-squares fit of the Cycles spot profile over the cone
     (cos theta in [cos(size/2), 1], Chebyshev basis, 2000 points), max error relative to
     the profile's maximum, vs order, for size 30/45/90/150 deg and blend 0/0.15/1. The bake
     does not fit: the profile is exactly c (inner cone) and c * smoothstep (blend annulus),
     polynomials of degree 1 and 4 on analytic cone-crossing pieces (fit error 0).
  4. 1920x1080 bake, one 45 deg spot (blend 0.15), no point light, camera of
     tests/native/test12: the airlight pass with the closed form (model sun05 / biri06: spots
     use Pegoraro) vs quadrature (model quadrature), minus the same bake without the spot,
     and their mean / p99 / max relative difference over pixels with spot fog above 1e-3 of
     the maximum (--bake-only runs just this).
"""

import argparse
import math
import os
import statistics
import sys

import numpy as np

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.environ.get("AIRLIGHT_NATIVE_DIR") or os.path.join(REPO, "addon", "airlight"))
sys.path.insert(0, os.path.join(REPO, "tests", "native"))

import _native  # noqa: E402
from scene_util import camera_matrix, perspective, quad, rotation_x  # noqa: E402
from timing import median_seconds  # noqa: E402




def random_rays(n, seed=1):
    rng = np.random.default_rng(seed)
    s = 10 ** rng.uniform(-2, 0.5, n)
    D = 10 ** rng.uniform(-1, 1.5, n)
    c = rng.uniform(-1, 1, n)
    V = np.where(rng.uniform(size=n) < 0.3, np.inf, 10 ** rng.uniform(-1, 2, n))
    return s, D, c, V


def cost_vs_order(runs):
    print("## 1. Cost per evaluation vs order (point light, HG g = 0.6 truncated at N)\n")
    s, D, c, V = random_rays(20000)
    H = s * D * np.sqrt(1 - c * c)
    low = H <= 1.5
    print(f"rays: {len(s)}, H <= 1.5 (forward recurrence): {low.sum()}, H > 1.5 (Olver): {(~low).sum()}\n")
    print("| order N | ns/eval all | ns/eval H<=1.5 | ns/eval H>1.5 |")
    print("|---:|---:|---:|---:|")
    for N in [0, 1, 2, 4, 8, 12, 16, 24, 32]:
        row = [N]
        for m in (slice(None), low, ~low):
            args = (s[m], D[m], c[m], V[m])
            t = median_seconds(lambda: _native.pegoraro10_airlight(*args, "hg", 0.6, N), runs)
            row.append(1e9 * t / len(args[0]))
        print(f"| {row[0]} | {row[1]:.0f} | {row[2]:.0f} | {row[3]:.0f} |")
    t = median_seconds(lambda: _native.sun05_airlight(s, D, c, V), runs)
    print(f"\nsame rays, sun05 (table) through its binding: {1e9 * t / len(s):.0f} ns/eval")
    t = median_seconds(lambda: _native.sun05_airlight(s, D, c, V, "sun05_exact"), runs)
    print(f"same rays, sun05_exact: {1e9 * t / len(s):.0f} ns/eval")
    t = median_seconds(lambda: _native.pegoraro10_airlight(s, D, c, V, "isotropic", 0.0), runs)
    print(f"same rays, pegoraro10 isotropic (order 0): {1e9 * t / len(s):.0f} ns/eval")
    t = median_seconds(lambda: _native.pegoraro10_airlight(s, D, c, V, "murky_mie", 0.0), runs)
    print(f"same rays, pegoraro10 murky Mie (exact order 32): {1e9 * t / len(s):.0f} ns/eval")
    sub = slice(0, 2000)
    t = median_seconds(lambda: _native.airlight_quadrature(s[sub], D[sub], c[sub], V[sub], "hg", 0.6), 1)
    print(f"same rays (first 2000), phase-aware quadrature HG 0.6: {1e9 * t / 2000:.0f} ns/eval\n")


def error_vs_order(n):
    print("## 2. Airlight error vs order, HG truncated at N, vs quadrature of the true HG\n")
    s, D, c, V = random_rays(n, seed=2)
    print("| g | N | mean rel | p99 rel | max rel |")
    print("|---:|---:|---:|---:|---:|")
    for g in (0.3, 0.6, 0.75, 0.9):
        q = _native.airlight_quadrature(s, D, c, V, "hg", g)
        try:
            auto = len(_native.pegoraro_legendre("hg", g, -1, 1e-6)) - 1
        except ValueError:  # no order <= 96 meets the bake's tolerance: the bake refuses this g
            auto = None
            print(f"| {g} | none <= 96 meets the tolerance: the bake refuses pegoraro10 | | | |")
        for N in sorted({1, 2, 4, 8, 16, 32, 48, 64, 96} | ({auto} if auto is not None else set())):
            a = _native.pegoraro10_airlight(s, D, c, V, "hg", g, N)
            rel = np.abs(a - q) / q
            tag = " (bake's choice)" if N == auto else ""
            print(f"| {g} | {N}{tag} | {rel.mean():.2e} | {np.percentile(rel, 99):.2e} | {rel.max():.2e} |")
    for name in ("isotropic", "rayleigh", "hazy_mie", "murky_mie"):
        q = _native.airlight_quadrature(s, D, c, V, name, 0.0)
        a = _native.pegoraro10_airlight(s, D, c, V, name, 0.0)
        rel = np.abs(a - q) / q
        print(f"| {name} (exact polynomial) | {len(_native.pegoraro_legendre(name)) - 1} | {rel.mean():.2e} | "
              f"{np.percentile(rel, 99):.2e} | {rel.max():.2e} |")
    print()


def spot_profile(c, size, blend):
    ch = math.cos(size / 2)
    e1 = (1 - ch) * blend
    t = np.clip((c - ch) / e1, 0, 1) if e1 > 0 else np.ones_like(c)
    return np.where(c > ch, c * t * t * (3 - 2 * t), 0.0)


def fit_table():
    print("## 3. Spot profile: one least-squares polynomial in cos(theta) over the cone\n")
    print("max |fit - profile| / max profile over the cone (2000 points); the bake's piecewise")
    print("form is exact (degree 1 inside the blend cone, degree 4 in the annulus).\n")
    orders = [1, 2, 4, 6, 8, 12, 16]
    print("| size | blend | " + " | ".join(f"N={n}" for n in orders) + " |")
    print("|---:|---:|" + "---:|" * len(orders))
    for size_deg in (30, 45, 90, 150):
        for blend in (0.0, 0.15, 1.0):
            size = math.radians(size_deg)
            ch = math.cos(size / 2)
            c = np.linspace(ch, 1.0, 2000)[1:]
            y = spot_profile(c, size, blend)
            errs = []
            for n in orders:
                fit = np.polynomial.chebyshev.Chebyshev.fit(c, y, n, domain=[ch, 1.0])
                errs.append(np.abs(fit(c) - y).max() / y.max())
            print(f"| {size_deg} | {blend} | " + " | ".join(f"{e:.1e}" for e in errs) + " |")
    print()


def spot_bake(runs, threads, width, height):
    print(f"## 4. Spot bake {width}x{height}, {threads} threads: closed form vs quadrature\n")
    print("One 45 deg spot (blend 0.15), no point lights, floor at 10 m: the airlight pass with the")
    print("spot minus the same bake without it (medians). Isotropic: model sun05 (spot by the closed")
    print("form) vs quadrature; HG g = 0.5: pegoraro10 (closed form, order 30) vs quadrature (the")
    print("other models bake spots of phase order > 8 by quadrature).\n")
    fov = math.radians(60.0)
    tilt = math.radians(-10.0)
    big = 1000.0
    vertices, triangles = quad([[-big, -big, -10.0], [big, -big, -10.0], [big, big, -10.0], [-big, big, -10.0]])
    base = dict(width=width, height=height, cam_to_world=camera_matrix(rotation_x(tilt), np.array([0.0, 0.5, 1.0])),
                projection=perspective(fov, width, height), vertices=vertices, triangles=triangles,
                light_positions=np.zeros((0, 3)), light_intensities=np.zeros((0, 3)),
                sigma_t=0.15, albedo=(0.9, 0.8, 0.6), threads=threads, aa_samples=1)
    spot = dict(spot_positions=np.array([[0.5, 3.0, -5.0]]), spot_axes=np.array([[0.1, -1.0, -0.2]]),
                spot_intensities=np.array([[30.0, 20.0, 10.0]]), spot_size=np.array([math.radians(45.0)]),
                spot_blend=np.array([0.15]))
    for phase, g, fast in (("isotropic", 0.0, "sun05"), ("hg", 0.5, "pegoraro10")):
        out = {}
        for model in (fast, "quadrature"):
            times = {}
            for key, kw in (("without", {}), ("with", spot)):
                ts = []
                for _ in range(runs):
                    r = _native.bake(model=model, phase=phase, g=g, **base, **kw)
                    ts.append(1e3 * r["stats"]["seconds_airlight"])
                out[(model, key)] = r
                times[key] = statistics.median(ts)
            spot_ms = times["with"] - times["without"]
            path = "Pegoraro closed form" if model != "quadrature" else "adaptive quadrature (1e-5)"
            print(f"{phase} g={g} model {model:10s} (spot by {path}): spot costs {spot_ms:.1f} ms "
                  f"({1e9 * spot_ms / 1e3 / (width * height):.0f} ns per pixel)")
        a = out[(fast, "with")]["airlight"]
        b = out[("quadrature", "with")]["airlight"]
        m = b > 1e-3 * b.max()
        rel = np.abs(a - b)[m] / b[m]
        print(f"  closed form vs quadrature ({m.sum()} pixel-channels above 1e-3 of max): "
              f"mean {rel.mean():.2e}, p99 {np.percentile(rel, 99):.2e}, max {rel.max():.2e}\n")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--quick", action="store_true", help="smaller error sample and a 480x270 bake")
    ap.add_argument("--bake-only", action="store_true", help="only section 4 (the spot bake)")
    args = ap.parse_args()
    print(f"# bench_pegoraro ({os.cpu_count()} CPUs, threads {args.threads}, runs {args.runs})\n")
    if not args.bake_only:
        cost_vs_order(args.runs)
        error_vs_order(300 if args.quick else 2000)
        fit_table()
    spot_bake(args.runs, args.threads, *((480, 270) if args.quick else (1920, 1080)))


if __name__ == "__main__":
    main()
