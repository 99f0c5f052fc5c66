"""Viewport fog preview on a GPU: builds and runs the standalone harness
benchmarks/gpu_preview/ (EGL + OpenGL 4.5, the add-on's own GLSL files), and compares the
fog images of two runs (e.g. an NVIDIA GPU's against Mesa llvmpipe's).

    /usr/bin/python3 benchmarks/bench_gpu_preview.py run [--size 480x270] [--configs ...]
        builds the harness, writes the F table of the built _native module, runs it here
        (EGL surfaceless: Mesa llvmpipe without a GPU) and prints its figures: GPU ms and
        fps per configuration (medians), per-pass times, fog image means.
    /usr/bin/python3 benchmarks/bench_gpu_preview.py stage DEST [--shaders DIR] [NAME=DIR ...]
        puts binary, F table, shaders and the glvnd .debs into DEST for a machine without
        Blender or GL loader (then run DEST/run_device.sh there; see gpu_preview/README.md).
    /usr/bin/python3 benchmarks/bench_gpu_preview.py compare A B
        A, B: a folder of .npy images (a run's --out) or an images_*.npz of run_device.sh;
        per configuration both have: mean relative difference of the image means, the
        median / 99th percentile of per-pixel relative differences, and the mean again
        without the 0.1 % brightest pixels (the pixels whose view ray passes within a
        fraction of a pixel of a light, where the airlight diverges and float rounding of
        the ray direction alone changes it by tens of percent).
"""

import argparse
import os
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
HARNESS = os.path.join(HERE, "gpu_preview")
REPO = os.path.dirname(HERE)


def _build():
    out = subprocess.run([os.path.join(HARNESS, "build.sh")], check=True, capture_output=True,
                         text=True).stdout.strip().splitlines()
    return out[-1]


def cmd_run(args):
    import tempfile
    binary = _build()
    out = args.out or tempfile.mkdtemp(prefix="gpu_preview_")
    os.makedirs(out, exist_ok=True)
    ftable = os.path.join(out, "ftable.bin")
    subprocess.run([sys.executable, os.path.join(HARNESS, "make_ftable.py"), ftable,
                    "--native-dir", args.native_dir], check=True)
    cmd = [binary, "--ftable", ftable, "--shaders", args.shaders,
           "--bench-shaders", os.path.join(HARNESS, "shaders"), "--platform", args.platform,
           "--size", args.size, "--frames", str(args.frames), "--warmup", str(args.warmup),
           "--budget-s", str(args.budget_s), "--gaussians", str(args.gaussians),
           "--configs", args.configs, "--out", out, "--npy-step", str(args.npy_step)]
    print(" ".join(cmd), flush=True)
    rc = subprocess.run(cmd).returncode
    print(f"images and results.txt in {out}")
    return rc


def cmd_stage(args):
    cmd = [os.path.join(HARNESS, "stage.sh"), args.dest, "--native-dir", args.native_dir]
    if args.shaders:
        cmd += ["--shaders", args.shaders]
    return subprocess.run(cmd + list(args.extra)).returncode


def _load(path):
    import glob
    import numpy as np
    if os.path.isdir(path):
        return {os.path.basename(f)[:-4]: np.load(f) for f in sorted(glob.glob(os.path.join(path, "*.npy")))}
    data = np.load(path)
    return {k: data[k] for k in data.files}


def cmd_compare(args):
    import numpy as np
    a, b = _load(args.a), _load(args.b)
    common = sorted(set(a) & set(b))
    if not common:
        print("no common configuration")
        return 1
    print(f"A = {args.a}\nB = {args.b}")
    print(f"{'config':16s} {'shape':>14s} {'mean rel r':>11s} {'mean rel a':>11s} "
          f"{'px rel med':>11s} {'px rel p99':>11s} {'r w/o 0.1%':>11s} {'bright px':>9s}")
    worst = 0.0
    for name in common:
        x, y = a[name].astype(np.float64), b[name].astype(np.float64)
        if x.shape != y.shape:
            print(f"{name:16s} shapes differ: {x.shape} vs {y.shape}")
            continue
        mr = (x[..., 0].mean() - y[..., 0].mean()) / y[..., 0].mean()
        ma = (x[..., 3].mean() - y[..., 3].mean()) / y[..., 3].mean()
        scale = np.maximum(np.abs(y[..., :3]).max(-1), 1e-6)
        rel = np.abs(x[..., :3] - y[..., :3]).max(-1) / scale
        bright = y[..., 0] > np.quantile(y[..., 0], 0.999)
        keep = ~bright
        mk = (x[..., 0][keep].mean() - y[..., 0][keep].mean()) / y[..., 0][keep].mean()
        worst = max(worst, abs(mk), abs(ma))
        print(f"{name:16s} {str(x.shape[:2]):>14s} {mr:11.2e} {ma:11.2e} {np.median(rel):11.2e} "
              f"{np.quantile(rel, 0.99):11.2e} {mk:11.2e} {int(bright.sum()):9d}")
    print(f"largest |mean rel| without the brightest 0.1 %: {worst:.2e}")
    return 0


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("run")
    r.add_argument("--size", default="480x270")
    r.add_argument("--configs", default="homog_full,homog_half,homog_quarter,compute_full,"
                   "gauss_full,gauss_half,gauss_quarter")
    r.add_argument("--frames", type=int, default=20)
    r.add_argument("--warmup", type=int, default=3)
    r.add_argument("--budget-s", type=float, default=20.0)
    r.add_argument("--gaussians", type=int, default=300)
    r.add_argument("--npy-step", type=int, default=1)
    r.add_argument("--platform", default="auto")
    r.add_argument("--shaders", default=os.path.join(REPO, "shaders"))
    r.add_argument("--native-dir", default=os.path.join(REPO, "addon", "airlight"))
    r.add_argument("--out")
    s = sub.add_parser("stage")
    s.add_argument("dest")
    s.add_argument("--shaders")
    s.add_argument("--native-dir", default=os.path.join(REPO, "addon", "airlight"))
    s.add_argument("extra", nargs="*", help="NAME=DIR: further shader folders to measure")
    c = sub.add_parser("compare")
    c.add_argument("a")
    c.add_argument("b")
    args = p.parse_args()
    return {"run": cmd_run, "stage": cmd_stage, "compare": cmd_compare}[args.cmd](args)


if __name__ == "__main__":
    sys.exit(main())
