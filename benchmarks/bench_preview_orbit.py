"""CPU cost of the Gaussian-fog viewport preview while the user orbits the view (issue 5).

    xvfb-run -a -s "-screen 0 1280x1024x24" tools/blender.sh --python benchmarks/bench_preview_orbit.py \
        [-- --gaussians 3000 --lights 1 3 4 --frames 12 --scale EIGHTH]

The scene of bench_preview.py (floor, cube, L point lights, a fog object of N Gaussians)
in a perspective 3D viewport. Per light count: one warm-up draw, then per frame the view
rotates about z by 2 degrees (an orbit: only the eye and the view change) and the region
is redrawn (wm.redraw_timer DRAW_SWAP); then as many frames without moving. Prints the
medians of the draw handler's time (preview._state["last_ms"]: the handler's own CPU
work plus the GPU submission, llvmpipe here), of the Gaussian factors' update
(GaussianFog.factor_ms: f1, C_sv and the texture uploads; only on orbit frames), of the
tile lists (GaussianFog.tiles_ms) and of the whole redraw, and how often the light rows
were computed (preview_gaussians.factor_stats, where the module has it).
"""

import argparse
import math
import os
import statistics
import sys
import time

import bpy
from mathutils import Quaternion

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import bench_preview as bp  # noqa: E402  (scene helpers)


def _args():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    p = argparse.ArgumentParser(prog="bench_preview_orbit")
    p.add_argument("--gaussians", type=int, default=3000)
    p.add_argument("--lights", type=int, nargs="+", default=[1, 3, 4])
    p.add_argument("--frames", type=int, default=12)
    p.add_argument("--scale", default="EIGHTH")
    return p.parse_args(argv)


def _frames(window, area, region, frames, orbit):
    from airlight import preview
    rv3d = area.spaces.active.region_3d
    step = Quaternion((0.0, 0.0, 1.0), math.radians(2.0))
    handler, factors, tiles, wall = [], [], [], []
    with bpy.context.temp_override(window=window, screen=window.screen, area=area, region=region):
        for _ in range(frames):
            if orbit:
                rv3d.view_rotation = step @ rv3d.view_rotation
            t0 = time.perf_counter()
            bpy.ops.wm.redraw_timer(type='DRAW_SWAP', iterations=1)
            wall.append((time.perf_counter() - t0) * 1e3)
            handler.append(preview._state["last_ms"])
            gf = preview._state["gpu"]["gaussian_fog"]
            factors.append(gf.factor_ms)
            tiles.append(gf.tiles_ms)
    med = statistics.median
    return med(handler), med(factors), med(tiles), med(wall)


def main():
    args = _args()
    import gpu
    from airlight import preview
    from airlight import preview_gaussians as pg
    print(f"GPU: {gpu.platform.renderer_get()} / {gpu.platform.version_get()}")
    window, area, region = bp._view3d_region()
    rv3d = area.spaces.active.region_3d
    wm = bpy.context.window_manager
    print(f"region {region.width} x {region.height} px, {args.gaussians} Gaussians, scale {args.scale}, "
          f"TILES, {args.frames} frames each (medians, ms)")
    for L in args.lights:
        bp._scene(L)
        bp._add_fog_object(args.gaussians)
        rv3d.view_perspective = 'PERSP'
        rv3d.view_location = (0.0, 0.0, 1.0)
        rv3d.view_distance = 14.0
        rv3d.view_rotation = Quaternion((1.0, 0.0, 0.0), math.radians(65.0))
        preview._state["error"] = None
        preview.GAUSS_PASS = 'TILES'
        wm.airlight_preview_scale = args.scale
        wm.airlight_preview_depth = 'DRAWN'
        wm.airlight_preview = True
        with bpy.context.temp_override(window=window, screen=window.screen, area=area, region=region):
            bpy.ops.wm.redraw_timer(type='DRAW_SWAP', iterations=2)  # warm-up: shaders, full factors
        if preview._state["error"]:
            print("preview error:", preview._state["error"])
            return 1
        stats = getattr(pg, "factor_stats", None)
        before = dict(stats) if stats is not None else None
        o_handler, o_factors, o_tiles, o_wall = _frames(window, area, region, args.frames, True)
        after = dict(stats) if stats is not None else None
        s_handler, _f, _t, s_wall = _frames(window, area, region, args.frames, False)
        wm.airlight_preview = False
        if preview._state["error"]:
            print("preview error:", preview._state["error"])
            return 1
        rows = "" if before is None else \
            (f"; light rows computed {after['full'] - before['full']}x, eye row only "
             f"{after['eye_only'] - before['eye_only']}x in {args.frames} orbit frames")
        print(f"{L} light(s): orbit frame: handler {o_handler:.1f} ms (factors + f1/gauss upload "
              f"{o_factors:.1f}, tile lists {o_tiles:.1f}), redraw {o_wall:.1f}; static frame: handler "
              f"{s_handler:.1f} ms, redraw {s_wall:.1f}{rows}", flush=True)
        for obj in [o for o in bpy.data.objects if o.name.startswith("BenchFog")]:
            bpy.data.objects.remove(obj)
    return 0


if __name__ == "__main__":
    try:
        code = main()
    except BaseException:
        import traceback
        traceback.print_exc()
        code = 1
    sys.stdout.flush()
    os._exit(code)
