#!/usr/bin/python3
"""The speed/accuracy trade of every fog model in the built `_native`, and of Cycles.

    /usr/bin/python3 benchmarks/bench_trade.py [--quick] [--out out/trade] [--threads 2]
                                               [--no-cycles] [--scenes a,b,...]

A fixed set of scenes (below: thin to thick fog, T_sv = sigma_t * D_sv from 0.1 to 20;
isotropic, forward g = 0.6 and backward g = -0.4 Henyey-Greenstein scattering; point,
spot and sun lights; a light 0.25 m above a surface). Camera, black floor and lights are
those of tests/blender/cycles_scenes.py (camera at (0, -8, 1.5) looking along +Y, 50 mm
lens, floor z = 0 ending at y = 2), built here in numpy as the add-on hands them to
`_native.bake` (Blender's matrix_world and calc_matrix_camera; trade_cycles.py checks
them against Blender's own).

For every model of `_native.models()` (sun05 also at table sizes 64/128/256/512, bilinear
and nearest), on every scene it takes (a model that refuses a scene, e.g. the isotropic-only
Sun 2005 models with g != 0, is skipped with the reason printed):
  - error against the "quadrature" model's bake of the same scene at ERR_SIZE: mean and
    p99 of the per-pixel relative error over the pixels with fog (reference airlight above
    1e-3 of its 99.9th percentile, i.e. visible fog; all three channels);
  - time per 1920x1080 frame per light: median wall time of `_native.bake` over --runs
    runs (threads = --threads; raycast included, every scene has one light). Models slower
    than SLOW_S at ERR_SIZE are timed at ERR_SIZE only and scaled by the pixel count
    (marked "scaled" in the table).
In the same run Cycles single scattering (volume_bounces = 0) renders each scene at
CYCLES_SIZE with several sample counts, through Blender as a subprocess
(tools/blender.sh -b --python benchmarks/trade_cycles.py); its error is taken against
the quadrature bake of the same scene at CYCLES_SIZE (both point-sampled at pixel
centres: Cycles' filter width 0.01 px, the bake's aa_samples 1), and its time is scaled
to 1920x1080: the render times t(spp) are fitted by a + b spp (a: scene sync, BVH,
kernel load), and a + b spp (1920 x 1080) / (W H) is reported (marked "scaled").

Prints a markdown table and writes <out>/trade.png (p99 error against time per frame,
log-log, one panel per scene, one point per model and per Cycles sample count),
<out>/trade.json (all figures) and the Cycles EXRs. Nothing is written in the repo
unless --out points there (out/ is ignored by git). --quick: fewer scenes, sizes,
sample counts and runs (about 2 minutes); the full run takes about 4.5 minutes on the
2-core development machine.

Spot lights are integrated by adaptive quadrature for every model (the bake's spot path),
so all models agree on the spot scene: its row measures the spot path's cost only.
"""

import argparse
import json
import math
import os
import statistics
import subprocess
import sys
import time
from dataclasses import asdict, dataclass

import numpy as np

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.environ.get("AIRLIGHT_NATIVE_DIR") or os.path.join(REPO, "addon", "airlight"))

FULL_HD = (1920, 1080)
SIGNAL_FLOOR = 1e-3      # pixels with fog: reference above this fraction of its 99.9th pct
SLOW_S = 1.0             # models slower than this at ERR_SIZE are not timed at 1920x1080
TABLE_SIZES = (64, 128, 256, 512)
TABLE_SIZES_ALL = TABLE_SIZES
CAMERA = dict(camera_location=(0.0, -8.0, 1.5), camera_pitch_deg=-5.0, lens_mm=50.0,
              sensor_mm=36.0, clip_start=0.1, clip_end=1000.0)
FLOOR = dict(floor_x=(-20.0, 20.0), floor_y=(-15.0, 2.0))


@dataclass
class Scene:
    name: str
    family: str                    # for the table: what the scene exercises
    sigma_t: float
    g: float = 0.0                 # Henyey-Greenstein g (Cycles' sign), 0: isotropic
    light_type: str = 'POINT'      # 'POINT', 'SPOT', 'SUN'
    light_location: tuple = (0.5, 6.0, 2.5)
    power: float = 1000.0          # W (point/spot: I0 = P / (4 pi))
    spot_axis: tuple = (0.0, 0.0, -1.0)
    spot_size: float = math.radians(60.0)
    spot_blend: float = 0.3
    sun_direction: tuple = (0.3, 0.5, -0.8)   # direction the light travels (lamp's -Z)
    sun_strength: float = 2.0      # W/m^2
    fog_top: float = 30.0          # sun scene: top of the fog layer (world z)
    box_half: float = 400.0        # sun scene: half size in x, y of Cycles' fog box
    camera_location: tuple = CAMERA["camera_location"]
    camera_pitch_deg: float = CAMERA["camera_pitch_deg"]
    lens_mm: float = CAMERA["lens_mm"]
    clip_start: float = CAMERA["clip_start"]
    clip_end: float = CAMERA["clip_end"]
    floor_x: tuple = FLOOR["floor_x"]
    floor_y: tuple = FLOOR["floor_y"]

    @property
    def T_sv(self):
        if self.light_type == 'SUN':
            return float("nan")
        return self.sigma_t * float(np.linalg.norm(np.subtract(self.light_location, self.camera_location)))


def _unit(v):
    v = np.asarray(v, float)
    return tuple(v / np.linalg.norm(v))


# D_sv = |light - camera| = 14.3 m for the default light (0.5, 6, 2.5).
D_SV = float(np.linalg.norm(np.subtract((0.5, 6.0, 2.5), CAMERA["camera_location"])))
NEAR_LIGHT = (0.5, -1.0, 0.25)     # 0.25 m above the floor, 7 m in front of the camera
# A floor to the horizon: with the light near the floor (or the sun above it), view rays
# past the default floor's far edge would go on below z = 0 through fog that the floor
# shadows in Cycles, which the analytic models (no shadows) do not; here every ray below
# the horizon ends on the floor.
WIDE_FLOOR = dict(floor_x=(-2000.0, 2000.0), floor_y=(-15.0, 2000.0))
THICK_LIGHT = (0.3, -3.0, 1.2)     # 5 m from the camera
SCENES = [
    Scene("point_thin", "point, thin fog T_sv=0.1, isotropic", 0.1 / D_SV),
    Scene("point_mid", "point, T_sv=1, isotropic", 1.0 / D_SV),
    Scene("point_thick", "point, thick fog T_sv=20, isotropic", 20.0 / float(np.linalg.norm(
        np.subtract(THICK_LIGHT, CAMERA["camera_location"]))), light_location=THICK_LIGHT),
    Scene("point_forward", "point, T_sv=1, forward g=0.6", 1.0 / D_SV, g=0.6),
    Scene("point_backward", "point, T_sv=1, backward g=-0.4", 1.0 / D_SV, g=-0.4),
    Scene("near_surface", "point 0.25 m above the floor, T_sv=1", 1.0 / float(np.linalg.norm(
        np.subtract(NEAR_LIGHT, CAMERA["camera_location"]))), light_location=NEAR_LIGHT, **WIDE_FLOOR),
    Scene("spot", "spot 60 deg, blend 0.3, sigma_t of point_mid (T_sv=0.74), isotropic", 1.0 / D_SV,
          light_type='SPOT',
          light_location=(0.5, 2.0, 4.0), spot_axis=_unit((0.0, 0.5, -1.0))),
    Scene("sun", "sun, sigma_t=0.1, fog top 30 m, isotropic", 0.1, light_type='SUN', **WIDE_FLOOR),
]
QUICK_SCENES = ("point_mid", "point_forward", "spot", "sun")


# ---------------------------------------------------------------------------------
# Scene -> _native.bake arguments
# ---------------------------------------------------------------------------------

def camera_matrices(sc, width, height, sensor_mm=CAMERA["sensor_mm"]):
    """Blender's camera.matrix_world (rotation X by 90 deg + pitch: looks along +Y) and
    calc_matrix_camera for sensor_fit AUTO on a landscape image."""
    a = math.radians(90.0 + sc.camera_pitch_deg)
    R = np.array([[1, 0, 0], [0, math.cos(a), -math.sin(a)], [0, math.sin(a), math.cos(a)]])
    cam_to_world = np.eye(4)
    cam_to_world[:3, :3] = R
    cam_to_world[:3, 3] = sc.camera_location
    n, f = sc.clip_start, sc.clip_end
    sx = 2.0 * sc.lens_mm / sensor_mm
    P = np.zeros((4, 4))
    P[0, 0] = sx
    P[1, 1] = sx * width / height
    P[2, 2] = -(f + n) / (f - n)
    P[2, 3] = -2.0 * f * n / (f - n)
    P[3, 2] = -1.0
    return cam_to_world, P


def bake_args(sc, width, height, threads):
    x0, x1 = sc.floor_x
    y0, y1 = sc.floor_y
    vertices = np.array([(x0, y0, 0), (x1, y0, 0), (x1, y1, 0), (x0, y1, 0)], np.float32)
    triangles = np.array([(0, 1, 2), (0, 2, 3)], np.uint32)
    cam_to_world, P = camera_matrices(sc, width, height)
    I0 = sc.power / (4.0 * math.pi)
    args = dict(width=width, height=height, cam_to_world=cam_to_world, projection=P,
                vertices=vertices, triangles=triangles, sigma_t=sc.sigma_t,
                clip_start=sc.clip_start, clip_end=sc.clip_end, threads=threads,
                light_positions=np.zeros((0, 3)), light_intensities=np.zeros((0, 3)))
    if sc.g != 0.0:
        args.update(phase="hg", g=sc.g)
    if sc.light_type == 'POINT':
        args.update(light_positions=np.array([sc.light_location], float),
                    light_intensities=np.full((1, 3), I0))
    elif sc.light_type == 'SPOT':
        args.update(spot_positions=np.array([sc.light_location], float),
                    spot_axes=np.array([sc.spot_axis], float), spot_intensities=np.full((1, 3), I0),
                    spot_size=np.array([sc.spot_size]), spot_blend=np.array([sc.spot_blend]))
    elif sc.light_type == 'SUN':
        args.update(sun_directions=np.array([sc.sun_direction], float),
                    sun_irradiances=np.full((1, 3), sc.sun_strength), fog_top=sc.fog_top)
    return args


# ---------------------------------------------------------------------------------
# Measurements
# ---------------------------------------------------------------------------------

def variants(native):
    """(label, bake keywords) of every model to measure, in table order."""
    names = [name for name, _ in native.models()]
    out = []
    for name in names:
        if name == "sun05":
            for interp in ("bilinear", "nearest"):
                for size in TABLE_SIZES:
                    out.append((f"sun05 {size} {interp}",
                                dict(model="sun05", table_size=size, table_interpolation=interp)))
        else:
            out.append((name, dict(model=name)))
    return out


def rel_errors(a, ref):
    """Mean and p99 of |a - ref| / ref over the pixels (and channels) with fog."""
    floor = SIGNAL_FLOOR * np.percentile(ref, 99.9)
    mask = ref > max(floor, 1e-30)
    if not mask.any():
        return float("nan"), float("nan")
    r = np.abs(a[mask].astype(np.float64) - ref[mask]) / ref[mask]
    return float(np.mean(r)), float(np.percentile(r, 99))


def why(ex):
    """One line for a skipped model or scene."""
    if isinstance(ex, TypeError):  # pybind11: an argument this build of bake() lacks
        wanted = [k for k in ("sun_directions", "table_size") if k in str(ex).split("Invoked with")[-1]
                  and f"{k}:" not in str(ex).split("Invoked with")[0]]
        return f"this build of _native.bake() has no argument {', '.join(wanted) or '(see TypeError)'}"
    return str(ex).splitlines()[0]


def timed_bake(native, args, runs):
    """(median wall seconds, last result) of `runs` bakes."""
    times, out = [], None
    for _ in range(runs):
        t0 = time.perf_counter()
        out = native.bake(**args)
        times.append(time.perf_counter() - t0)
    return statistics.median(times), out


def measure_models(native, sc, err_size, runs, threads, log):
    """Rows for every model variant on scene _sc_ (error vs quadrature at err_size)."""
    rows = []
    small = bake_args(sc, *err_size, threads)
    try:
        t_ref, ref = timed_bake(native, dict(small, model="quadrature"), 1)
    except (ValueError, TypeError) as ex:
        log(f"  {sc.name}: skipped, the built _native cannot bake it: {why(ex)}")
        return rows, None
    ref_airlight = ref["airlight"]
    scale = FULL_HD[0] * FULL_HD[1] / (err_size[0] * err_size[1])
    for label, kw in variants(native):
        try:
            # Warm-up at 16x9: builds the model's table (a one-off per process) untimed.
            native.bake(**dict(bake_args(sc, 16, 9, threads), **kw))
            t_small, out = timed_bake(native, dict(small, **kw), 1)
        except (ValueError, TypeError) as ex:
            log(f"  {sc.name}: {label} skipped: {why(ex)}")
            continue
        mean, p99 = rel_errors(out["airlight"], ref_airlight)
        if t_small > SLOW_S:
            seconds, scaled = t_small * scale, True
        else:
            # A bake expected to take seconds is timed once (the spot path, thick scenes).
            n = runs if t_small * scale < 2.0 else 1
            seconds, _ = timed_bake(native, dict(bake_args(sc, *FULL_HD, threads), **kw), n)
            scaled = False
        rows.append(dict(scene=sc.name, model=label, mean=mean, p99=p99, seconds=seconds, scaled=scaled))
        log(f"  {sc.name}: {label}: mean {mean:.3g} p99 {p99:.3g}, {seconds:.3g} s/frame"
            f"{' (scaled)' if scaled else ''}")
    return rows, ref_airlight


def run_cycles(scenes, size, samples, threads, out_dir, log):
    """Renders every scene with Cycles via Blender; returns cycles.json's dict (or None)."""
    job = dict(scenes=[dict(asdict(sc), name=sc.name) for sc in scenes], width=size[0],
               height=size[1], samples=list(samples), threads=threads, out=os.path.abspath(out_dir))
    job_path = os.path.join(out_dir, "cycles_job.json")
    with open(job_path, "w") as f:
        json.dump(job, f)
    cmd = [os.path.join(REPO, "tools", "blender.sh"), "-b", "--python",
           os.path.join(REPO, "benchmarks", "trade_cycles.py"), "--", job_path]
    log(f"Cycles: {' '.join(cmd)}")
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True)
    for line in proc.stdout.splitlines():
        if line.startswith("cycles "):
            log("  " + line)
    if proc.returncode != 0:
        log(f"Cycles run failed (exit {proc.returncode}); no Cycles rows.\n"
            f"{proc.stdout[-2000:]}\n{proc.stderr[-2000:]}")
        return None
    log(f"Cycles: {time.perf_counter() - t0:.0f} s in Blender")
    with open(os.path.join(out_dir, "cycles.json")) as f:
        return json.load(f)


def read_exr_rgb(path):
    sys.path.insert(0, os.path.join(REPO, "tests", "blender"))
    import cycles_scenes
    return cycles_scenes.read_exr_rgb(path)


def cycles_rows(native, sc, result, size, samples, threads, out_dir, log):
    """Rows for Cycles at each sample count on scene _sc_ (error vs quadrature at size)."""
    args = bake_args(sc, *size, threads)
    for key in ("cam_to_world", "projection"):  # our matrices are Blender's
        if not np.allclose(args[key], np.array(result[key]), atol=1e-5):
            log(f"  {sc.name}: WARNING {key} differs from Blender's:\n{np.array(result[key])}\n{args[key]}")
    try:
        ref = native.bake(**dict(args, model="quadrature", aa_samples=1))["airlight"]
    except (ValueError, TypeError) as ex:
        log(f"  {sc.name}: Cycles rows skipped, the built _native cannot bake the reference: {why(ex)}")
        return []
    spp = np.array(samples, float)
    t = np.array([result["times"][str(s)] for s in samples])
    b, a = np.polyfit(spp, t, 1) if len(spp) > 1 else (t[0] / spp[0], 0.0)
    a, b = max(a, 0.0), max(b, 0.0)
    scale = FULL_HD[0] * FULL_HD[1] / (size[0] * size[1])
    rows = []
    for s, ts in zip(samples, t):
        img = read_exr_rgb(os.path.join(out_dir, f"{sc.name}_{s}.exr"))
        mean, p99 = rel_errors(img, ref)
        seconds = a + b * s * scale
        rows.append(dict(scene=sc.name, model=f"Cycles {s} spp", mean=mean, p99=p99, seconds=seconds,
                         scaled=True, cycles_raw_seconds=float(ts)))
        log(f"  {sc.name}: Cycles {s} spp: mean {mean:.3g} p99 {p99:.3g}, {ts:.2f} s at "
            f"{size[0]}x{size[1]} -> {seconds:.3g} s/frame (fit a={a:.2f} s, b={b * 1e3:.2f} ms/spp)")
    return rows


# ---------------------------------------------------------------------------------
# Output
# ---------------------------------------------------------------------------------

def fmt_err(x):
    if x != x:
        return "n/a"
    return "0" if x == 0.0 else f"{100.0 * x:.2g} %"


def markdown(rows, scenes):
    by_scene = {sc.name: sc for sc in scenes}
    lines = ["| scene | model | mean err | p99 err | s / 1920x1080 frame / light |",
             "|---|---|---|---|---|"]
    for r in rows:
        sc = by_scene[r["scene"]]
        t = f"{r['seconds']:.3g}" + (" (scaled)" if r["scaled"] else "")
        err = ("reference" if r["model"] == "quadrature" else fmt_err(r["mean"])), \
              ("reference" if r["model"] == "quadrature" else fmt_err(r["p99"]))
        lines.append(f"| {sc.name} | {r['model']} | {err[0]} | {err[1]} | {t} |")
    return "\n".join(lines)


def plot(rows, scenes, path, log):
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        log("matplotlib missing (tools/install_deps.sh installs python3-matplotlib): no plot")
        return
    names = [sc.name for sc in scenes if any(r["scene"] == sc.name for r in rows)]
    if not names:
        return
    cols = min(4, len(names))
    nrows = (len(names) + cols - 1) // cols
    fig, axes = plt.subplots(nrows, cols, figsize=(4.2 * cols, 3.6 * nrows), squeeze=False)
    floor = 1e-6  # errors of exactly 0 (the spot path, the reference) drawn at this floor
    markers = {"sun05": "o", "sun05_exact": "s", "biri06": "^", "baseline": "x",
               "pegoraro10": "D", "hoffman02": "v"}
    colours = {"sun05_exact": "tab:purple", "biri06": "tab:orange", "baseline": "black",
               "pegoraro10": "tab:brown", "hoffman02": "tab:olive"}
    for ax, name in zip(axes.ravel(), names):
        mine = [r for r in rows if r["scene"] == name and r["model"] != "quadrature"]
        cyc = [r for r in mine if r["model"].startswith("Cycles")]
        for r in mine:
            if r in cyc:
                continue
            base = r["model"].split()[0]
            colour = colours.get(base, "tab:grey")
            if base == "sun05" and len(r["model"].split()) == 3:  # "sun05 <size> <interp>"
                _, size, interp = r["model"].split()
                shade = 0.35 + 0.65 * TABLE_SIZES_ALL.index(int(size)) / (len(TABLE_SIZES_ALL) - 1)
                colour = plt.get_cmap("Blues" if interp == "bilinear" else "Greens")(shade)
            ax.scatter(r["seconds"], max(r["p99"], floor), marker=markers.get(base, "*"), color=colour,
                       label=r["model"], s=22)
        if cyc:
            ax.plot([r["seconds"] for r in cyc], [max(r["p99"], floor) for r in cyc], "-o", color="tab:red",
                    label="Cycles (spp)", ms=4)
            for r in cyc:
                ax.annotate(r["model"].split()[1], (r["seconds"], max(r["p99"], floor)), fontsize=7,
                            xytext=(3, 3), textcoords="offset points")
        ref = [r for r in rows if r["scene"] == name and r["model"] == "quadrature"]
        for r in ref:
            ax.axvline(r["seconds"], color="grey", ls=":", lw=1)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_title(name, fontsize=9)
        ax.set_xlabel("s per 1920x1080 frame per light")
        ax.set_ylabel("p99 relative error")
        ax.grid(True, which="both", lw=0.3)
    for ax in axes.ravel()[len(names):]:
        ax.axis("off")
    handles = {}
    for ax in axes.ravel():
        for h, l in zip(*ax.get_legend_handles_labels()):
            handles.setdefault(l, h)
    fig.legend(list(handles.values()), list(handles.keys()), loc="lower center", ncol=6, fontsize=7)
    fig.suptitle("Fog models and Cycles single scattering: p99 relative error against time\n"
                 "(dotted: the quadrature reference's time; errors of 0 drawn at 1e-6)", fontsize=10)
    fig.tight_layout(rect=(0, 0.08 + 0.03 * (len(handles) // 6), 1, 0.93))
    fig.savefig(path, dpi=110)
    log(f"plot: {path}")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="the 2-minute version")
    ap.add_argument("--out", default=os.path.join(REPO, "out", "trade"), help="output folder")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--runs", type=int, default=None, help="timing runs per model (median)")
    ap.add_argument("--no-cycles", action="store_true", help="skip the Cycles renders")
    ap.add_argument("--scenes", default=None, help="comma-separated scene names")
    opts = ap.parse_args()

    import _native as native

    os.makedirs(opts.out, exist_ok=True)
    scenes = SCENES
    if opts.scenes:
        scenes = [sc for sc in SCENES if sc.name in opts.scenes.split(",")]
    elif opts.quick:
        scenes = [sc for sc in SCENES if sc.name in QUICK_SCENES]
    err_size = (240, 135) if opts.quick else (480, 270)
    cycles_size = (96, 54) if opts.quick else (160, 90)
    samples = (1, 4, 16, 64) if opts.quick else (1, 4, 16, 64, 256)
    runs = opts.runs or (1 if opts.quick else 5)
    global TABLE_SIZES
    if opts.quick:
        TABLE_SIZES = (64, 256)

    def log(msg):
        print(msg, flush=True)

    log(f"models in _native: {', '.join(n for n, _ in native.models())}")
    log(f"error at {err_size[0]}x{err_size[1]} against model 'quadrature'; time at 1920x1080, "
        f"threads={opts.threads}, median of {runs}; Cycles at {cycles_size[0]}x{cycles_size[1]}, "
        f"spp {samples}")
    for sc in scenes:
        log(f"scene {sc.name}: {sc.family}; sigma_t={sc.sigma_t:.4g}/m, T_sv={sc.T_sv:.3g}")
    # Timings depend on what else runs on the machine: say how busy it was.
    log(f"load average at start: {os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs")
    t_start = time.perf_counter()
    rows = []
    for sc in scenes:
        r, _ = measure_models(native, sc, err_size, runs, opts.threads, log)
        rows += r
    if not opts.no_cycles:
        todo = [sc for sc in scenes if any(r["scene"] == sc.name for r in rows)]
        result = run_cycles(todo, cycles_size, samples, opts.threads, opts.out, log) if todo else None
        if result:
            for sc in todo:
                rows += cycles_rows(native, sc, result[sc.name], cycles_size, samples, opts.threads,
                                    opts.out, log)
    order = {sc.name: i for i, sc in enumerate(scenes)}
    rows.sort(key=lambda r: (order[r["scene"]], r["model"].startswith("Cycles"),
                             r["seconds"] if r["model"].startswith("Cycles") else 0))
    log("")
    log(markdown(rows, scenes))
    with open(os.path.join(opts.out, "trade.json"), "w") as f:
        json.dump(dict(rows=rows, scenes=[dict(asdict(sc), T_sv=sc.T_sv) for sc in scenes],
                       err_size=err_size, cycles_size=cycles_size, samples=samples, runs=runs,
                       threads=opts.threads), f, indent=1)
    plot(rows, scenes, os.path.join(opts.out, "trade.png"), log)
    log(f"load average at end: {os.getloadavg()[0]:.1f}; total {time.perf_counter() - t_start:.0f} s")


if __name__ == "__main__":
    main()
