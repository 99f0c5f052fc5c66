#!/usr/bin/python3
"""Surface glow for any phase function, spots and Biri's Lambert model (biri06_surface.h,
spot_surface.h, surface_pass.cpp): prints

  1. the one-off build time of each G table (per phase; once per process and (phase, g, m));
  2. the surface pass's cost per pixel*light on the street scene for Sun's isotropic path, the
     phase-aware G_p path, Biri's eq. 10 path and spot lights (SpotGlowModel), medians;
  3. the error of Biri's Lambert model (eq. 10, the unclamped cosine, clamped at 0 as the bake
     does) against the clamped exact G_p over a T x theta_s grid, per phase (median / mean / max);
  4. the error of the bake's spot glow (SpotGlowModel x point glow) and of the naive profile
     toward p against the brute-force spot integral, for a 45 deg spot 3 m above a floor.

    /usr/bin/python3 benchmarks/bench_surface_phase.py [--runs 3] [--threads 2] [--scale 0.5]
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

PHASES = [("isotropic", 0.0), ("hg", 0.6), ("hg", -0.6), ("hg", 0.9), ("hg", -0.9), ("rayleigh", 0.0),
          ("hazy_mie", 0.0), ("murky_mie", 0.0)]


def label(name, g):
    return f"{name} g={g:+.1f}" if name == "hg" else name


def table_builds(nat):
    print("1. G table build (first lookup; 128x128 Lambert, 64x64 Phong n=20, 256-row Gamma_L):")
    for name, g in PHASES:
        row = []
        for what, call in (("G0/G_p", lambda: nat.surface_G(1.0, 0.5, phase=name, g=g, exact=False)),
                           ("Gn n=20", lambda: nat.surface_G(1.0, 0.5, m=20.0, phase=name, g=g, exact=False,
                                                             nT=64, ntheta=64)),
                           ("Gamma_L", lambda: nat.biri06_gamma_L(1.0, phase=name, g=g, exact=False))):
            t0 = time.perf_counter()
            call()
            row.append(f"{what} {time.perf_counter() - t0:.2f} s")
        print(f"   {label(name, g):14s} " + ", ".join(row))


def pass_cost(nat, args):
    w, h = int(street.WIDTH * args.scale), int(street.HEIGHT * args.scale)
    cam_to_world, P = street.camera_matrices(w, h)
    verts, tris, lights, intens = street.street_scene()
    base = dict(width=w, height=h, cam_to_world=cam_to_world, projection=P, vertices=verts, triangles=tris,
                sigma_t=street.SIGMA_T, threads=args.threads, clip_start=street.CLIP[0], clip_end=street.CLIP[1],
                surface=True, aa_samples=1)
    pts = dict(light_positions=lights[:4], light_intensities=intens[:4])
    spots = dict(light_positions=np.zeros((0, 3)), light_intensities=np.zeros((0, 3)), spot_positions=lights[:4],
                 spot_axes=np.tile([0.0, 0.0, -1.0], (4, 1)), spot_intensities=intens[:4],
                 spot_size=np.full(4, math.radians(45.0)), spot_blend=np.full(4, 0.15))
    cases = [("4 points, isotropic (Sun G0)", dict(pts, model="biri06")),
             ("4 points, HG 0.6, phase-aware G_p", dict(pts, model="pegoraro10", phase="hg", g=0.6)),
             ("4 points, HG 0.6, biri06: eq. 10", dict(pts, model="biri06", phase="hg", g=0.6)),
             ("4 spots 45 deg, isotropic", dict(spots, model="biri06"))]
    print(f"2. surface pass at {w}x{h}, {args.threads} threads, medians of {args.runs} (after a warm-up bake; "
          "tables cached per process):")
    ref = None
    for text, kw in cases:
        nat.bake(**base, **kw)  # warm-up: builds the tables
        secs = [nat.bake(**base, **kw)["stats"]["seconds_surface"] for _ in range(args.runs)]
        med = statistics.median(secs)
        ref = ref or med
        print(f"   {text:36s} {1000 * med:7.1f} ms  {1e9 * med / (w * h * 4):6.1f} ns per pixel*light  "
              f"({med / ref:.2f}x Sun's)")


def biri_error(nat):
    print("3. Biri eq. 10 (clamped at 0) vs the clamped exact G_p, T in {0.1, 0.5, 1, 2, 5, 10}:")
    Ts = np.array([0.1, 0.5, 1.0, 2.0, 5.0, 10.0])
    for thetas, what in ((np.radians([0, 15, 30, 45, 60, 75]), "theta_s < 90 deg (facing the light)"),
                         (np.radians([0, 15, 30, 45, 60, 75, 105, 120, 150, 180]), "theta_s 0..180 deg")):
        print(f"   {what}:")
        for name, g in PHASES:
            T, th = np.meshgrid(Ts, thetas)
            exact = nat.surface_G(T, th, phase=name, g=g)
            gl = nat.biri06_gamma_L(T, phase=name, g=g)
            biri = np.maximum(0.0, 4 * math.pi ** 2 * np.cos(th) * gl)
            err = np.abs(biri / exact - 1.0)
            print(f"     {label(name, g):14s} median {np.median(err):.3f}  mean {err.mean():.3f}  max {err.max():.3f}")


def one(a):
    return float(np.asarray(a).ravel()[0])


def spot_error(nat):
    print("4. spot glow, 45 deg spot (blend 0.15) 3 m above a floor, sigma_t 0.3 (relative error vs brute force):")
    s, axis = np.array([0.0, 0.0, 3.0]), np.array([0.0, 0.0, -1.0])
    size, blend, sigma = math.radians(45.0), 0.15, 0.3
    for name, g in (("isotropic", 0.0), ("hg", 0.6)):
        errs_model, errs_naive = [], []
        for x in (0.0, 0.4, 0.8, 1.2, 1.6, 2.0, 3.0):
            p = np.array([x, 0.0, 0.0])
            for facing in (False, True):
                n = (s - p) / np.linalg.norm(s - p) if facing else np.array([0.0, 0.0, 1.0])
                v = s - p
                D = float(np.linalg.norm(v))
                theta = math.acos(min(1.0, float(n @ v) / D))
                point = sigma * one(nat.surface_G(sigma * D, theta, phase=name, g=g)) / (2 * math.pi * D)
                ref = nat.spot_surface_glow_reference(s, axis, size, blend, p, n, sigma, phase=name, g=g, rel_tol=1e-4)
                cos_psi = float(axis @ (p - s)) / D
                model = one(nat.spot_glow_factor(sigma * D, cos_psi, size, blend, phase=name, g=g)) * point
                cone = math.cos(size / 2)
                profile = 0.0
                if cos_psi > cone:
                    t = min(1.0, (cos_psi - cone) / ((1 - cone) * blend))
                    profile = cos_psi * t * t * (3 - 2 * t)
                naive = profile * point
                print(f"   {label(name, g):10s} x={x:.1f} m {'facing' if facing else 'floor '}: model {model / ref - 1:+.3f}"
                      f"  profile-at-p {naive / ref - 1:+.3f}")
                errs_model.append(abs(model / ref - 1))
                errs_naive.append(abs(naive / ref - 1))
        print(f"   {label(name, g)}: |error| median model {np.median(errs_model):.3f} (max {max(errs_model):.3f}), "
              f"profile-at-p {np.median(errs_naive):.3f} (max {max(errs_naive):.3f})")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--scale", type=float, default=0.5, help="fraction of 1920x1080 for the pass cost")
    args = ap.parse_args()
    import _native
    table_builds(_native)
    pass_cost(_native, args)
    biri_error(_native)
    spot_error(_native)


if __name__ == "__main__":
    main()
