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
    /usr/bin/python3 benchmarks/bench_gpu_preview.py bake-check IMAGES --size WxH [--step S]
            [--configs a,b]
        the reference: bakes the harness's scene with _native.bake (model sun05,
        aa_samples 1: one sample per pixel centre, as the preview) at WxH, with the
        Gaussians of IMAGES (its "gaussians" array) for the gauss_* and tiles_* images, and compares
        every image of IMAGES (every S-th pixel of a WxH image) with it: airlight against
        rgb, transmittance against 1 - alpha.
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
        files = sorted(glob.glob(os.path.join(path, "*.npy")))
        return {os.path.basename(f)[:-4]: np.load(f) for f in files}
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
        if x.ndim != 3:
            continue
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


def _scene(width, height):
    """The harness's scene (gpu_preview/preview.cpp make_view, Preview::build) as bake
    arguments."""
    import numpy as np
    eye, target = np.array([1.0, -12.0, 5.0]), np.array([0.0, 0.0, 1.0])
    up = np.array([0.0, 0.0, 1.0])
    f = (target - eye) / np.linalg.norm(target - eye)
    r = np.cross(f, up)
    r /= np.linalg.norm(r)
    u = np.cross(r, f)
    cam_to_world = np.eye(4)
    cam_to_world[:3, 0], cam_to_world[:3, 1] = r, u
    cam_to_world[:3, 2], cam_to_world[:3, 3] = -f, eye
    aspect = width / height
    tan_half_y = 0.36 / aspect if aspect >= 1.0 else 0.36
    near, far = 0.1, 100.0
    proj = np.zeros((4, 4))
    proj[0, 0], proj[1, 1] = 1.0 / (aspect * tan_half_y), 1.0 / tan_half_y
    proj[2, 2], proj[2, 3] = -(far + near) / (far - near), -2.0 * far * near / (far - near)
    proj[3, 2] = -1.0
    verts = [(-20, -20, 0), (20, -20, 0), (20, 20, 0), (-20, 20, 0)]
    tris = [(0, 1, 2), (0, 2, 3)]
    base = len(verts)
    verts += [(1 if i & 1 else -1, 1 if i & 2 else -1, 2 if i & 4 else 0) for i in range(8)]
    for q in ((0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5)):
        tris += [(base + q[0], base + q[1], base + q[2]), (base + q[0], base + q[2], base + q[3])]
    n = 4
    lights = [(-6.0 + 12.0 * i / (n - 1), 2.0 * (i % 3) - 2.0, 2.5) for i in range(n)]
    I0 = [(1000.0 / (4.0 * np.pi),) * 3] * n
    return dict(width=width, height=height, cam_to_world=cam_to_world, projection=proj,
                vertices=np.array(verts, np.float32), triangles=np.array(tris, np.int32),
                light_positions=np.array(lights), light_intensities=np.array(I0), sigma_t=0.08,
                clip_start=near, clip_end=far)


def cmd_bake_check(args):
    import numpy as np
    sys.path.insert(0, os.path.abspath(args.native_dir))
    import _native  # noqa: E402
    w, h = (int(v) for v in args.size.split("x"))
    images = _load(args.images)
    desc = _scene(w, h)
    refs = {}
    print(f"{'config':16s} {'airlight mean rel':>18s} {'Tr mean rel':>12s} {'px rel med':>11s} "
          f"{'r w/o 0.1%':>11s}")
    worst = 0.0
    only = set(args.configs.split(",")) if args.configs else None
    for name in sorted(images):
        img = images[name]
        if img.ndim != 3 or (only is not None and name not in only):
            continue
        gauss = name.startswith(("gauss", "tiles"))  # the splat and the tile pass
        if gauss and "gaussians" not in images:
            print(f"{name:16s} skipped: no gaussians array")
            continue
        if gauss not in refs:
            extra = {}
            if gauss:
                g = images["gaussians"].astype(np.float64)
                extra = dict(rbf_centres=g[:, :3], rbf_scales=g[:, 3], rbf_amplitudes=g[:, 4])
            baked = _native.bake(**desc, model="sun05", aa_samples=1, threads=0, **extra)
            refs[gauss] = (baked["airlight"][::-1].astype(np.float64),
                           baked["transmittance"][::-1].astype(np.float64))
        La, Tr = (x[::args.step, ::args.step] for x in refs[gauss])
        x = img.astype(np.float64)
        if x.shape[:2] != La.shape[:2]:
            print(f"{name:16s} shape {x.shape[:2]} vs bake {La.shape[:2]}: wrong --size/--step?")
            continue
        mr = (x[..., 0].mean() - La[..., 0].mean()) / La[..., 0].mean()
        mt = ((1.0 - x[..., 3]).mean() - Tr[..., 0].mean()) / Tr[..., 0].mean()
        rel = np.abs(x[..., 0] - La[..., 0]) / np.maximum(La[..., 0], 1e-6)
        keep = La[..., 0] <= np.quantile(La[..., 0], 0.999)
        mk = (x[..., 0][keep].mean() - La[..., 0][keep].mean()) / La[..., 0][keep].mean()
        worst = max(worst, abs(mk), abs(mt))
        print(f"{name:16s} {mr:18.2e} {mt:12.2e} {np.median(rel):11.2e} {mk:11.2e}")
    print(f"largest |mean rel| (without the brightest 0.1 %): {worst:.2e}")
    return 0


def main():
    p = argparse.ArgumentParser(description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("run")
    r.add_argument("--size", default="480x270")
    r.add_argument("--configs", default="homog_full,homog_half,homog_quarter,compute_full,"
                   "gauss_full,gauss_half,gauss_quarter,tiles_full,tiles_half,tiles_quarter")
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
    b = sub.add_parser("bake-check")
    b.add_argument("images")
    b.add_argument("--size", required=True, help="WxH of the run the images come from")
    b.add_argument("--step", type=int, default=1, help="its --npy-step")
    b.add_argument("--configs", help="comma-separated names to check (default: all)")
    b.add_argument("--native-dir", default=os.path.join(REPO, "addon", "airlight"))
    args = p.parse_args()
    return {"run": cmd_run, "stage": cmd_stage, "compare": cmd_compare,
            "bake-check": cmd_bake_check}[args.cmd](args)


if __name__ == "__main__":
    sys.exit(main())
