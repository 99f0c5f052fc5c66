#!/usr/bin/python3
"""The fog passes' EXR: write time and file size per compression and precision, in one run.

    /usr/bin/python3 benchmarks/bench_exr.py [--runs 3] [--width 1920 --height 1080]

The passes of bench_sun05.py's street with 4 lamps and surface shading (Airlight,
Transmittance, Surface_<lamp> x 4, SurfaceGlow: 21 channels), written by `_native.write_exr`
to a temporary folder; medians over --runs writes, after one untimed write. Each line also
reads the file back (OpenImageIO) and prints the largest error against the float passes:
0 for the lossless compressions of floats, half's rounding (<= 2^-11 relative) for halves.
"""

import argparse
import os
import statistics
import sys
import tempfile
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import bench_sun05 as street  # noqa: E402  (also puts addon/airlight on sys.path)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--width", type=int, default=1920)
    ap.add_argument("--height", type=int, default=1080)
    args = ap.parse_args()
    import _native
    import OpenImageIO as oiio

    verts, tris, lights, intens = street.street_scene()
    cam, P = street.camera_matrices(args.width, args.height)
    r = _native.bake(width=args.width, height=args.height, cam_to_world=cam, projection=P, vertices=verts,
                     triangles=tris, sigma_t=street.SIGMA_T, model="sun05", threads=2, clip_start=street.CLIP[0],
                     clip_end=street.CLIP[1], light_positions=lights, light_intensities=intens, surface=True)
    passes = {"Airlight": r["airlight"], "Transmittance": r["transmittance"]}
    for k, a in enumerate(r["surface_attenuation"]):
        passes[f"Surface_fog_Lamp{k}"] = np.ascontiguousarray(a - 1.0, dtype=np.float32)
    passes["SurfaceGlow"] = r["surface_glow"]
    reference = np.concatenate(list(passes.values()), axis=2)
    print(f"Airlight bench_exr: {args.width}x{args.height}, {len(passes)} passes ({3 * len(passes)} channels), "
          f"runs={args.runs} (medians)")
    with tempfile.TemporaryDirectory() as tmp:
        for half in (False, True):
            for method in ("zip", "piz", "zips", "rle", "none", "dwaa", "auto"):
                # A file per line: OpenImageIO's cache would read an earlier one back.
                path = os.path.join(tmp, f"fog_{method}_{half}.exr")
                _native.write_exr(path, passes, layer_prefix="Fog.", half=half, compression=method)
                times = []
                for _ in range(args.runs):
                    t0 = time.perf_counter()
                    _native.write_exr(path, passes, layer_prefix="Fog.", half=half, compression=method)
                    times.append(time.perf_counter() - t0)
                size = os.path.getsize(path)
                inp = oiio.ImageInput.open(path)
                names = list(inp.spec().channelnames)   # OpenEXR keeps them sorted by name
                pixels = inp.read_image(oiio.FLOAT)
                inp.close()
                back = np.stack([pixels[..., names.index(f"Fog.{p}.{c}")] for p in passes for c in "RGB"], axis=2)
                err = np.max(np.abs(back - reference) / np.maximum(np.abs(reference), 1e-3))
                print(f"  {'half ' if half else 'float'} {method:5s}: {1000 * statistics.median(times):7.1f} ms "
                      f"{size / 1e6:7.2f} MB   max error {err:.2e} (relative, above 1e-3)")


if __name__ == "__main__":
    main()
