#!/usr/bin/python3
"""A/B of two `_native` builds on bench_rbf.py's Gaussian scenes, interleaved.

    /usr/bin/python3 benchmarks/ab_rbf.py --a DIR_A --b DIR_B [--scenes 3000,34,walls]
                                          [--rounds 3] [--warmup 3] [--bakes 9]
                                          [--resolution quarter] [--threads 2]
                                          [--width 1920 --height 1080]

DIR_A and DIR_B each hold a `_native*.so` (e.g. one built from an older commit with
`cmake -S <worktree> -B <build> -DAIRLIGHT_MODULE_DIR=DIR_A -DAIRLIGHT_BUILD_TESTS=OFF
-DCMAKE_BUILD_TYPE=Release`, and a copy of addon/airlight's). The development machine's
speed drifts by 10-15 % within minutes, so figures from separate runs do not compare: this
script alternates the two builds scene by scene for --rounds rounds, each measurement a
fresh process (AIRLIGHT_NATIVE_DIR) that bakes the scene --warmup times untimed, then
--bakes times at --width x --height (1920x1080 by default), and reports the median wall and CPU time of the timed bakes.
The warm-up matters: a process's first bakes build tables and fault in fresh pages (the
first always; the second too where a large buffer was freed and allocated again, until
glibc raises its mmap threshold), so medians over a process's first 3 bakes mix that in.
--warmup 0 --bakes 3 measures those early bakes instead.
Prints per scene and build the median over rounds, every round's wall time, and B / A.
"""

import argparse
import json
import os
import statistics
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))

# One measurement, run in a child process so that it imports the build AIRLIGHT_NATIVE_DIR
# names (bench_rbf.py imports `_native` from there).
CHILD = r"""
import json, sys
sys.path.insert(0, {here!r})
import bench_rbf as B
scene, warmup, bakes, resolution, threads = {scene!r}, {warmup}, {bakes}, {resolution!r}, {threads}
W, H = {width}, {height}
if scene == "34":
    gauss, lights, walls = B.cloud(34, (3.0, 10.0), (0.005, 0.02), 1), 3, False
else:
    gauss, lights, walls = B.cloud(3000, (1.0, 3.0), (0.01, 0.05), 2), 1, scene == "walls"
if warmup > 0:
    B.bake(W, H, lights, gauss, threads, warmup, resolution, walls)
wall, airlight, res, cpu, _ = B.bake(W, H, lights, gauss, threads, bakes, resolution, walls)
print(json.dumps({{"wall": wall, "cpu": cpu}}))
"""

SCENES = ("3000", "34", "walls")


def measure(native_dir, scene, warmup, bakes, resolution, threads, width, height):
    code = CHILD.format(here=HERE, scene=scene, warmup=warmup, bakes=bakes, resolution=resolution, threads=threads,
                        width=width, height=height)
    env = dict(os.environ, AIRLIGHT_NATIVE_DIR=native_dir)
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True)
    if out.returncode != 0:
        raise SystemExit(f"measurement failed ({native_dir}, scene {scene}):\n{out.stderr}")
    return json.loads(out.stdout.strip().splitlines()[-1])


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--a", required=True, help="folder with build A's _native*.so")
    ap.add_argument("--b", required=True, help="folder with build B's _native*.so")
    ap.add_argument("--scenes", default="3000,34,walls", help="comma-separated, of " + ", ".join(SCENES))
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--warmup", type=int, default=3, help="untimed bakes first in each process")
    ap.add_argument("--bakes", type=int, default=9, help="timed bakes per process (their median is one measurement)")
    ap.add_argument("--resolution", default="quarter", choices=("full", "half", "quarter"))
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--width", type=int, default=1920)
    ap.add_argument("--height", type=int, default=1080)
    args = ap.parse_args()
    scenes = args.scenes.split(",")
    for s in scenes:
        if s not in SCENES:
            raise SystemExit(f"unknown scene {s!r}: expected one of {', '.join(SCENES)}")
    builds = {"A": os.path.abspath(args.a), "B": os.path.abspath(args.b)}
    for name, d in builds.items():
        if not os.path.isdir(d) or not any(f.startswith("_native") for f in os.listdir(d)):
            raise SystemExit(f"build {name}: no _native module in {d}")
    print(f"A = {builds['A']}\nB = {builds['B']}\n{args.rounds} rounds x ({args.warmup} untimed + {args.bakes} timed) "
          f"bakes per process, {args.width}x{args.height}, {args.resolution}, {args.threads} threads")
    runs = {(b, s): [] for b in builds for s in scenes}
    for _ in range(args.rounds):
        for s in scenes:
            for b, d in builds.items():
                runs[(b, s)].append(measure(d, s, args.warmup, args.bakes, args.resolution, args.threads,
                                             args.width, args.height))
    for s in scenes:
        med = {}
        for b in builds:
            r = runs[(b, s)]
            med[b] = (statistics.median(x["wall"] for x in r), statistics.median(x["cpu"] for x in r))
            rounds = " ".join(f"{x['wall'] * 1e3:.0f}" for x in r)
            print(f"{s:>6} {b}: wall {med[b][0] * 1e3:7.1f} ms, CPU {med[b][1] * 1e3:7.1f} ms (rounds: {rounds})")
        print(f"{s:>6} B / A: wall {med['B'][0] / med['A'][0]:.3f}, CPU {med['B'][1] / med['A'][1]:.3f}")


if __name__ == "__main__":
    main()
