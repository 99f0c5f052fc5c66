#!/usr/bin/python3
"""Benchmark of the Sun 2005 bake on a fixed synthetic 1920x1080 street scene.

    /usr/bin/python3 benchmarks/bench_sun05.py [--runs 7] [--threads 2] [--json out.json]

No Blender needed: the scene (camera, ground, building boxes, street lamps) is built in
numpy and handed to `_native.bake` exactly as the add-on would (Blender camera matrices:
matrix_world and calc_matrix_camera). `_native` is imported from addon/airlight (build the
`_native` CMake target first) or from $AIRLIGHT_NATIVE_DIR. Prints medians over --runs runs of:
  - the airlight kernel cost in ns per pixel*light (bake stats) and per evaluation of the
    vectorised `_native.sun05_airlight` on random inputs;
  - bake wall time at 1920x1080 with 1 and 4 lights, split into raycast / airlight phases
    (the rest of the wall time, "overhead", is validation, the BVH build, output allocation
    and the numpy wrapping), from the eye (clip_start 0) and from Blender's default near
    plane (clip_start 0.1 m, clip_end 1000 m, as the add-on passes the camera's range);
  - models "sun05_exact" and "quadrature" on row bands spread over the image (timed on the
    bands, scaled to the full image: the output says so), their speed ratio vs the table
    model, and the table model's error against quadrature over those rows;
    (also from the near plane, against quadrature from the near plane);
  - PASS/FAIL lines against the targets (4 lights <= 50 ms, p99 error <= 0.5 %).
"""

import argparse
import json
import math
import os
import platform
import statistics
import sys
import time

import numpy as np

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
# AIRLIGHT_NATIVE_DIR: a directory holding another build of _native (e.g. one configured
# with -DAIRLIGHT_MODULE_DIR=...); default: the add-on's own copy.
sys.path.insert(0, os.environ.get("AIRLIGHT_NATIVE_DIR") or os.path.join(REPO, "addon", "airlight"))

WIDTH, HEIGHT = 1920, 1080
SIGMA_T = 0.05
TARGET_MS = 50.0
TARGET_P99 = 0.005
SIGNAL_FLOOR = 1e-6  # relative to the image's 99.9th percentile: "above a tiny floor"
CLIP = (0.1, 1000.0)  # Blender's default clip_start; clip_end as in the projection


# ---------------------------------------------------------------------------------
# The scene
# ---------------------------------------------------------------------------------

def camera_matrices(width, height, location=(0.0, -2.0, 1.7), pitch_deg=-3.0,
                    lens_mm=28.0, sensor_mm=36.0, clip=CLIP):
    """Blender-style camera: matrix_world (looks down -Z, +Y up) and the projection
    calc_matrix_camera returns for sensor_fit AUTO on a landscape image."""
    a = math.radians(90.0 + pitch_deg)  # rotate about X: -Z -> +Y, pitched
    R = np.array([[1, 0, 0], [0, math.cos(a), -math.sin(a)], [0, math.sin(a), math.cos(a)]])
    cam_to_world = np.eye(4)
    cam_to_world[:3, :3] = R
    cam_to_world[:3, 3] = location
    n, f = clip
    sx = 2.0 * lens_mm / sensor_mm
    P = np.zeros((4, 4))
    P[0, 0] = sx
    P[1, 1] = sx * width / height
    P[2, 2] = -(f + n) / (f - n)
    P[2, 3] = -2.0 * f * n / (f - n)
    P[3, 2] = -1.0
    return cam_to_world, P


def box(lo, hi):
    """8 vertices, 12 triangles of an axis-aligned box."""
    x0, y0, z0 = lo
    x1, y1, z1 = hi
    v = np.array([[x, y, z] for x in (x0, x1) for y in (y0, y1) for z in (z0, z1)], np.float32)
    # vertex index = 4 * ix + 2 * iy + iz
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    t = []
    for a, b, c, d in quads:
        t += [(a, b, c), (a, c, d)]
    return v, np.array(t, np.uint32)


def street_scene():
    """Ground (road and pavements), two rows of buildings, lamp posts; 4 street lamps."""
    rng = np.random.default_rng(12345)
    parts = [box((-60.0, -10.0, -0.2), (60.0, 400.0, 0.0))]  # ground slab
    for side in (-1.0, 1.0):
        y = 4.0
        while y < 220.0:
            depth = rng.uniform(8.0, 20.0)
            height = rng.uniform(6.0, 30.0)
            x_in = 7.0 + rng.uniform(0.0, 1.5)
            x0, x1 = sorted((side * x_in, side * (x_in + rng.uniform(8.0, 15.0))))
            parts.append(box((x0, y, 0.0), (x1, y + depth, height)))
            y += depth + rng.uniform(0.0, 6.0)
        for y in np.arange(8.0, 120.0, 20.0):  # lamp posts
            parts.append(box((side * 5.0 - 0.1, y - 0.1, 0.0), (side * 5.0 + 0.1, y + 0.1, 4.8)))
    verts, tris, base = [], [], 0
    for v, t in parts:
        verts.append(v)
        tris.append(t + base)
        base += len(v)
    lights = np.array([[-4.5, 8.0, 5.0], [4.5, 28.0, 5.0], [-4.5, 48.0, 5.0],
                       [4.5, 68.0, 5.0]], np.float64)
    # Warm 800 W lamps: I0 = C * P / (4 pi).
    colour = np.array([1.0, 0.85, 0.6])
    intens = np.tile(colour * 800.0 / (4.0 * math.pi), (4, 1))
    return np.concatenate(verts), np.concatenate(tris), lights, intens


def band_projection(P, height, row0, rows):
    """Projection whose image is rows [row0, row0 + rows) of the full one (same pixel
    centres): NDC y of the band mapped to [-1, 1], a linear map in clip space."""
    y_top = 1.0 - 2.0 * row0 / height
    y_bot = 1.0 - 2.0 * (row0 + rows) / height
    c, s = 0.5 * (y_top + y_bot), 0.5 * (y_top - y_bot)
    S = np.eye(4)
    S[1, 1] = 1.0 / s
    S[1, 3] = -c / s  # y' = (y - c w) / s
    return S @ P


# ---------------------------------------------------------------------------------
# Measurements
# ---------------------------------------------------------------------------------

def median(xs):
    return statistics.median(xs)


def run_bake(_native, base, lights, model, runs, threads, P=None, height=None, clip_start=0.0, **extra):
    kw = dict(base, **extra)
    if clip_start > 0.0:
        # As the add-on passes it: fog from the near plane on (Cycles' clip range).
        kw["clip_start"] = clip_start
        kw["clip_end"] = CLIP[1]
    if P is not None:
        kw["projection"] = P
        kw["height"] = height
    kw["light_positions"] = base["light_positions"][:lights]
    kw["light_intensities"] = base["light_intensities"][:lights]
    walls, rc, al, res = [], [], [], None
    for _ in range(runs):
        t0 = time.perf_counter()
        res = _native.bake(**kw, sigma_t=SIGMA_T, model=model, threads=threads)
        walls.append(time.perf_counter() - t0)
        rc.append(res["stats"]["seconds_raycast"])
        al.append(res["stats"]["seconds_airlight"])
    return dict(wall=median(walls), raycast=median(rc), airlight=median(al),
                samples=res["stats"]["samples"],
                supersampled=res["stats"]["supersampled_pixels"], result=res)


def rel_err(a, ref):
    a = np.asarray(a, np.float64).ravel()
    ref = np.asarray(ref, np.float64).ravel()
    finite = np.isfinite(ref)
    floor = SIGNAL_FLOOR * np.percentile(ref[finite], 99.9)
    m = finite & (ref > floor)
    r = np.abs(a[m] - ref[m]) / ref[m]
    return float(np.mean(r)), float(np.percentile(r, 99)), float(np.max(r)), int(m.sum())


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--runs", type=int, default=7)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--bands", type=int, default=8, help="row bands for slow models")
    ap.add_argument("--band-rows", type=int, default=8, help="rows per band")
    ap.add_argument("--json", help="also write the figures to this file")
    args = ap.parse_args()

    import _native

    cam_to_world, P = camera_matrices(WIDTH, HEIGHT)
    verts, tris, lights, intens = street_scene()
    base = dict(width=WIDTH, height=HEIGHT, cam_to_world=cam_to_world, projection=P,
                vertices=verts, triangles=tris, light_positions=lights,
                light_intensities=intens)
    out = {}
    print(f"Airlight bench_sun05: _native {_native.__version__}, {platform.processor() or platform.machine()}, "
          f"{os.cpu_count()} cores visible, threads={args.threads}, runs={args.runs} (medians)")
    print(f"scene: {WIDTH}x{HEIGHT}, {len(tris)} triangles, sigma_t={SIGMA_T}/m, "
          f"street with {len(lights)} lamps")

    # Warm-up: builds the F table, Embree BVH code paths, thread pool.
    run_bake(_native, base, 1, "sun05", 1, args.threads)

    # -- Table model, full image, 1 and 4 lights, from the eye and from Blender's default
    # near plane (clip_start 0.1 m, as the add-on passes it).
    print("\n== bake, model sun05 (table F), full image ==")
    table = {}
    for clip_start, L in ((0.0, 1), (0.0, 4), (CLIP[0], 1), (CLIP[0], 4)):
        r = run_bake(_native, base, L, "sun05", args.runs, args.threads, clip_start=clip_start)
        key = f"sun05_{L}light" + ("_clip" if clip_start > 0.0 else "")
        table[key] = r
        if clip_start > 0.0 and L == 1:
            print(f"-- clip_start {clip_start} m, clip_end {CLIP[1]:.0f} m (Blender's default near plane) --")
        px = WIDTH * HEIGHT
        ns_px = r["airlight"] / (px * L) * 1e9
        ns_smp = r["airlight"] / (r["samples"] * L) * 1e9 if r["samples"] else float("nan")
        print(f"{L} light(s): wall {r['wall'] * 1e3:8.1f} ms = raycast {r['raycast'] * 1e3:7.1f} ms"
              f" + airlight {r['airlight'] * 1e3:7.1f} ms (+ overhead "
              f"{(r['wall'] - r['raycast'] - r['airlight']) * 1e3:.1f} ms)")
        print(f"           airlight {ns_px:6.1f} ns per pixel*light, {ns_smp:6.1f} ns per "
              f"sample*light ({r['samples']} samples, {r['supersampled']} pixels supersampled)")
        out[key] = {k: v for k, v in r.items() if k != "result"}
        out[key]["ns_per_pixel_light"] = ns_px
    # The same 4-light bake with the homogeneous airlight on a lattice
    # (homogeneous_resolution, bake.cpp), and its error against the full bake above.
    print("-- homogeneous_resolution (lattice), 4 lights, from the eye --")
    full = table["sun05_4light"]
    for res_name in ("half", "quarter"):
        r = run_bake(_native, base, 4, "sun05", args.runs, args.threads, homogeneous_resolution=res_name)
        mean, p99, mx, n = rel_err(r["result"]["airlight"][..., 0], full["result"]["airlight"][..., 0])
        print(f"{res_name:>7}: wall {r['wall'] * 1e3:8.1f} ms = raycast {r['raycast'] * 1e3:7.1f} ms"
              f" + airlight {r['airlight'] * 1e3:7.1f} ms ({full['airlight'] / r['airlight']:.2f}x faster "
              f"airlight than full); vs full: mean {mean * 100:.4f} %, p99 {p99 * 100:.4f} %, "
              f"max {mx * 100:.3f} % over {n} px")
        table[f"sun05_4light_{res_name}"] = r
        out[f"sun05_4light_{res_name}"] = {k: v for k, v in r.items() if k != "result"}

    # -- Vectorised kernel on random inputs.
    print("\n== _native.sun05_airlight on random inputs (vectorised, one call) ==")
    rng = np.random.default_rng(7)
    N = 1_000_000
    Dsv = rng.uniform(0.5, 80.0, N)
    cos_g = rng.uniform(-1.0, 1.0, N)
    Dvp = np.where(rng.random(N) < 0.3, np.inf, rng.uniform(0.5, 200.0, N))
    for model in ("sun05", "sun05_exact"):
        ts = []
        for _ in range(max(3, args.runs // 2)):
            t0 = time.perf_counter()
            _native.sun05_airlight(SIGMA_T, Dsv, cos_g, Dvp, model=model)
            ts.append(time.perf_counter() - t0)
        ns = median(ts) / N * 1e9
        print(f"{model:12s}: {ns:7.1f} ns per evaluation ({N} points, incl. numpy "
              f"broadcasting and the output array)")
        out[f"vector_{model}_ns"] = ns
    # Accuracy of the table over a wider range than the street scene's (random optical
    # depths up to ~160), against the exact F.
    sig = np.exp(rng.uniform(math.log(1e-3), math.log(2.0), N))
    a = _native.sun05_airlight(sig, Dsv, cos_g, Dvp, model="sun05")
    b = _native.sun05_airlight(sig, Dsv, cos_g, Dvp, model="sun05_exact")
    mean, p99, mx, n = rel_err(a, b)
    print(f"sun05 vs sun05_exact, sigma_t log-uniform in [1e-3, 2]: mean {mean * 100:.4f} %, "
          f"p99 {p99 * 100:.4f} %, max {mx * 100:.4f} % over {n} points")
    out["vector_table_err"] = dict(mean=mean, p99=p99, max=mx)
    Nq = 20_000
    t0 = time.perf_counter()
    _native.sun05_airlight(SIGMA_T, Dsv[:Nq], cos_g[:Nq], Dvp[:Nq], model="quadrature")
    nsq = (time.perf_counter() - t0) / Nq * 1e9
    print(f"{'quadrature':12s}: {nsq:7.1f} ns per evaluation ({Nq} points, one run)")
    out["vector_quadrature_ns"] = nsq

    # -- Slow models on row bands, 4 lights.
    L = 4
    nb, br = args.bands, args.band_rows
    starts = [int(round((i + 0.5) * HEIGHT / nb - br / 2)) for i in range(nb)]
    rows = nb * br
    scale = HEIGHT / rows
    print(f"\n== models on {nb} bands of {br} rows ({rows} of {HEIGHT} rows, "
          f"times scaled x{scale:.1f} to the full image), {L} lights ==")
    # Entries "<model>" from the eye, "<model>@clip" from the near plane (clip_start 0.1 m:
    # the table model's one-evaluation sub-segment path against quadrature of the same).
    acc = {m: dict(wall=0.0, airlight=0.0, img=[]) for m in ("sun05", "sun05_exact",
                                                              "quadrature", "sun05@clip",
                                                              "quadrature@clip")}
    for r0 in starts:
        Pb = band_projection(P, HEIGHT, r0, br)
        for m, a in acc.items():
            model, _, clip = m.partition("@")
            runs = 1 if model == "quadrature" else 3
            r = run_bake(_native, base, L, model, runs, args.threads, P=Pb, height=br,
                         clip_start=CLIP[0] if clip else 0.0)
            a["wall"] += r["wall"]
            a["airlight"] += r["airlight"]
            a["img"].append(np.asarray(r["result"]["airlight"]))
    for m, a in acc.items():
        a["img"] = np.concatenate(a["img"], axis=0)
    # The bands' pixels are the full image's rows: check against the full table bake.
    full = np.asarray(table["sun05_4light"]["result"]["airlight"])
    same = np.concatenate([full[r0:r0 + br] for r0 in starts], axis=0)
    band_vs_full = rel_err(acc["sun05"]["img"], same)
    t_ref = acc["sun05"]["airlight"]
    for m, a in acc.items():
        ref = "quadrature@clip" if m.endswith("@clip") else "quadrature"
        mean, p99, mx, n = rel_err(a["img"], acc[ref]["img"])
        err = ("(the reference)" if m == ref else
               f"vs quadrature: mean {mean * 100:.4f} %, p99 {p99 * 100:.4f} %, "
               f"max {mx * 100:.4f} % over {n} px")
        print(f"{m:15s}: airlight {a['airlight'] * scale * 1e3:9.1f} ms full-image estimate "
              f"(wall {a['wall'] * scale * 1e3:9.1f} ms), {a['airlight'] / t_ref:7.1f}x the table"
              f" model; {err}")
        out[f"bands_{m}"] = dict(airlight_full_est=a["airlight"] * scale,
                                 wall_full_est=a["wall"] * scale,
                                 ratio_vs_table=a["airlight"] / t_ref,
                                 err_mean=mean, err_p99=p99, err_max=mx, pixels=n)
    print(f"(band bakes vs the same rows of the full bake: mean {band_vs_full[0] * 100:.2g} %,"
          f" max {band_vs_full[2] * 100:.2g} %; nonzero only where edge detection sees the"
          f" band border)")

    # -- Targets.
    print("\n== targets ==")
    t4 = table["sun05_4light"]
    t4c = table["sun05_4light_clip"]
    p99 = out["bands_sun05"]["err_p99"]
    p99c = out["bands_sun05@clip"]["err_p99"]
    checks = [
        (f"1920x1080, 4 lights, airlight phase {t4['airlight'] * 1e3:.1f} ms <= {TARGET_MS:.0f} ms",
         t4["airlight"] * 1e3 <= TARGET_MS),
        (f"1920x1080, 4 lights, total bake {t4['wall'] * 1e3:.1f} ms <= {TARGET_MS:.0f} ms",
         t4["wall"] * 1e3 <= TARGET_MS),
        (f"1920x1080, 4 lights, clip_start {CLIP[0]} m, total bake {t4c['wall'] * 1e3:.1f} ms"
         f" <= {TARGET_MS:.0f} ms", t4c["wall"] * 1e3 <= TARGET_MS),
        (f"1920x1080, 4 lights, homogeneous_resolution quarter, total bake "
         f"{table['sun05_4light_quarter']['wall'] * 1e3:.1f} ms <= {TARGET_MS:.0f} ms",
         table["sun05_4light_quarter"]["wall"] * 1e3 <= TARGET_MS),
        (f"table model p99 error vs quadrature {p99 * 100:.4f} % <= {TARGET_P99 * 100:.1f} %",
         p99 <= TARGET_P99),
        (f"table model p99 error vs quadrature, clip_start {CLIP[0]} m: {p99c * 100:.4f} % <= "
         f"{TARGET_P99 * 100:.1f} %", p99c <= TARGET_P99),
    ]
    for text, ok in checks:
        print(f"{'PASS' if ok else 'FAIL'}: {text}")
    out["targets"] = {text: ok for text, ok in checks}
    if args.json:
        with open(args.json, "w") as f:
            json.dump(out, f, indent=2)


if __name__ == "__main__":
    main()
