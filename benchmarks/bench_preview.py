"""Cost of the viewport fog preview under the current OpenGL driver (llvmpipe here).

    xvfb-run -a -s "-screen 0 1280x1024x24" tools/blender.sh --python benchmarks/bench_preview.py [-- --repeats 10]

Builds a small scene (floor, cube, N point lights), puts the 3D viewport in camera view
and redraws its region with wm.redraw_timer('DRAW_SWAP': the swap waits for the GPU, so queued fog work is not billed to the next draw),
with the preview off and on, for each depth source (DRAWN: the preview's own distance
pass; READBACK: viewport depth read back and uploaded) and fog resolution scale
(FULL / HALF / QUARTER). Prints ms per viewport draw, the fog's extra cost and the
ratio, plus the handler's own depth time (own pass, or read-back + upload).

Gaussian fog (--gaussians, default 300 and 3000; --gauss-lights, default 4): the same
scene with a fog object of N Gaussians (scale a = 2/m, i.e. paintbrush-sized 0.5 m blobs,
amplitude 0.3/m, centres uniform in a 16 x 10 x 3 m box around the cube), timed the
same way (preview on vs off, interleaved, medians), plus the native per-view factor
computation (f1, C_sv) the preview redoes when the view or the fog changes. Each way of
drawing the Gaussian sums (--gauss-passes, default TILES SPLAT: preview.GAUSS_PASS) is
timed against its own interleaved no-fog draws; TILES also prints its (tile, Gaussian)
list entries and the CPU time of building and uploading the lists (once per view change).
"""

import argparse
import os
import statistics
import sys
import time

import bpy
from mathutils import Vector


def _args():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    p = argparse.ArgumentParser(prog="bench_preview")
    p.add_argument("--repeats", type=int, default=8)
    p.add_argument("--lights", type=int, nargs="+", default=[1, 4, 16])
    p.add_argument("--scales", nargs="+", default=["FULL", "HALF", "QUARTER"])
    p.add_argument("--depth", nargs="+", default=["DRAWN", "READBACK"])
    p.add_argument("--gaussians", type=int, nargs="*", default=[300, 3000])
    p.add_argument("--gauss-lights", type=int, default=4)
    p.add_argument("--gauss-repeats", type=int, default=3)
    p.add_argument("--gauss-scales", nargs="+", default=["FULL", "HALF", "QUARTER"])
    p.add_argument("--gauss-passes", nargs="+", default=["TILES", "SPLAT"],
                   help="ways of drawing the Gaussian sums (preview.GAUSS_PASSES)")
    p.add_argument("--gauss-alone", action="store_true",
                   help="Gaussian section: time draw_fog alone offscreen (each pass and the fog "
                        "without Gaussians, interleaved) instead of whole viewport draws")
    p.add_argument("--factors-only", action="store_true",
                   help="Gaussian section: only time the native factor computation")
    p.add_argument("--skip-point-section", action="store_true",
                   help="only run the Gaussian section")
    p.add_argument("--passes-only", action="store_true",
                   help="only time the passes alone (offscreen), not whole viewport draws")
    return p.parse_args(argv)


def _scene(n_lights):
    scene = bpy.context.scene
    for obj in list(scene.objects):
        bpy.data.objects.remove(obj)
    bpy.ops.mesh.primitive_plane_add(size=40.0)
    bpy.ops.mesh.primitive_cube_add(size=2.0, location=(0.0, 0.0, 1.0))
    for i in range(n_lights):
        data = bpy.data.lights.new(f"L{i}", 'POINT')
        data.energy = 1000.0
        obj = bpy.data.objects.new(f"L{i}", data)
        obj.location = (-6.0 + 12.0 * i / max(1, n_lights - 1), 2.0 * (i % 3) - 2.0, 2.5)
        scene.collection.objects.link(obj)
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    cam.location = (1.0, -12.0, 5.0)
    cam.rotation_euler = (Vector((0, 0, 1)) - cam.location).to_track_quat('-Z', 'Y').to_euler()
    scene.collection.objects.link(cam)
    scene.camera = cam
    scene.airlight.enabled = True
    scene.airlight.density = 0.08
    # Workbench's progressive anti-aliasing makes each redraw cost depend on how many
    # samples are accumulated already; switch it off so every draw is a full draw.
    scene.display.viewport_aa = 'OFF'
    bpy.context.preferences.view.show_splash = False
    bpy.context.view_layer.update()


def _add_fog_object(n, seed=1):
    """A fog object of _n_ Gaussians (see the module docstring)."""
    import numpy as np
    from airlight import fog_object
    rng = np.random.default_rng(seed)
    centres = np.column_stack([rng.uniform(-8.0, 8.0, n), rng.uniform(-5.0, 5.0, n),
                               rng.uniform(0.0, 3.0, n)])
    obj = fog_object.new_fog_object("BenchFog", bpy.context.scene.collection, centres,
                                    np.full(n, 2.0), np.full(n, 0.3))
    bpy.context.view_layer.update()
    return obj


def _time_factors(count, n_lights, repeats):
    """Median ms of the native per-view factors (f1, C_sv) with nothing cached (new fog or
    lights) and after a view change only (the light side reused)."""
    from airlight import _native, preview, preview_gaussians as pg
    ctx = bpy.context
    g = preview.scene_gaussians(ctx)
    lights, _ = preview.scene_lights(ctx.scene, ctx.view_layer)
    full, view = [], []
    for k in range(repeats):
        pg.clear_cache()
        t0 = time.perf_counter()
        pg.fogshop_factors(_native, g["centres"], g["scales"], g["amplitudes"], 0.08, (1.0, -12.0, 5.0),
                           lights, data_key=("bench", k))
        full.append((time.perf_counter() - t0) * 1e3)
        t0 = time.perf_counter()
        pg.fogshop_factors(_native, g["centres"], g["scales"], g["amplitudes"], 0.08, (2.0, -11.0, 5.5),
                           lights, data_key=("bench", k))
        view.append((time.perf_counter() - t0) * 1e3)
    pg.clear_cache()
    print(f"factors ({count} Gaussians, {n_lights} lights): {statistics.median(full):.1f} ms from scratch, "
          f"{statistics.median(view):.1f} ms after a view change (median of {repeats})", flush=True)


def _view3d_region():
    window = bpy.context.window_manager.windows[0]
    for area in window.screen.areas:
        if area.type == 'VIEW_3D':
            area.spaces.active.region_3d.view_perspective = 'CAMERA'
            region = next(r for r in area.regions if r.type == 'WINDOW')
            return window, area, region
    raise RuntimeError("no 3D viewport")


def _time_draws(window, area, region, repeats, wm, scale, depth_mode):
    """Median ms per region draw with the preview off and on, interleaved so that load
    from other processes hits both alike."""
    from airlight import preview
    off, on, depth, cpu_off, cpu_on = [], [], [], [], []
    with bpy.context.temp_override(window=window, screen=window.screen, area=area, region=region):
        wm.airlight_preview_scale = scale
        wm.airlight_preview_depth = depth_mode
        wm.airlight_preview = True
        bpy.ops.wm.redraw_timer(type='DRAW_SWAP', iterations=1)  # warm-up (shader compile, table)
        for _ in range(repeats):
            for flag, times, cpu in ((False, off, cpu_off), (True, on, cpu_on)):
                wm.airlight_preview = flag
                t0, c0 = time.perf_counter(), time.process_time()
                bpy.ops.wm.redraw_timer(type='DRAW_SWAP', iterations=1)
                times.append((time.perf_counter() - t0) * 1e3)
                cpu.append((time.process_time() - c0) * 1e3)
            depth.append(preview._state["last_depth_ms"])
    wm.airlight_preview = False
    med = statistics.median
    return med(off), med(on), med(depth), med(cpu_off), med(cpu_on)


def _sync():
    """Waits for queued GPU work: reading one pixel back finishes everything before it."""
    import gpu
    gpu.state.active_framebuffer_get().read_color(0, 0, 1, 1, 4, 0, 'FLOAT')


def _time_passes(region, repeats):
    """Median wall / CPU ms of each preview pass alone at the region's size, offscreen,
    each finished by a 1-pixel read-back: the depth sources and the fog at each scale."""
    import gpu
    from airlight import preview
    from airlight import gpu_shaders as gs
    ctx = bpy.context
    w, h = region.width, region.height
    rv3d = next(a for a in ctx.window_manager.windows[0].screen.areas
                if a.type == 'VIEW_3D').spaces.active.region_3d
    persp = rv3d.perspective_matrix.copy()
    eye = tuple(rv3d.view_matrix.inverted().translation)
    scene = ctx.scene
    positions, intensities = preview.scene_lights(scene, ctx.view_layer)
    off = gpu.types.GPUOffScreen(w, h, format='RGBA8')
    rows = []
    try:
        with off.bind():
            def run(name, fn):
                fn()
                _sync()  # warm-up (compile, batches, targets)
                wall, cpu = [], []
                for _ in range(repeats):
                    t0, c0 = time.perf_counter(), time.process_time()
                    fn()
                    _sync()
                    wall.append((time.perf_counter() - t0) * 1e3)
                    cpu.append((time.process_time() - c0) * 1e3)
                rows.append((name, statistics.median(wall), statistics.median(cpu)))

            def readback():
                buf = gpu.state.active_framebuffer_get().read_depth(0, 0, w, h)
                return gs.depth_texture(buf, w, h)

            def drawn():
                return preview.draw_distance(ctx, perspective_matrix=persp, view_origin=eye,
                                             is_perspective=True, size=(w, h))
            run("depth: read-back + upload", readback)
            run("depth: own distance pass", drawn)
            dist = drawn()
            modes = (("bilinear", preview.UPSAMPLE_BILINEAR),
                     ("bilateral", preview.UPSAMPLE_BILATERAL),
                     ("bilateral+exact", preview.UPSAMPLE_BILATERAL_EXACT))
            for scale in (1, 2, 4):
                for mode_name, mode in (modes if scale > 1 else modes[-1:]):
                    run(f"fog at 1/{scale} + {mode_name}" if scale > 1 else "fog at full res",
                        lambda scale=scale, mode=mode: preview.draw_fog(
                            depth_tex=dist, perspective_matrix=persp, view_origin=eye,
                            is_perspective=True, viewport=(0, 0, w, h),
                            sigma_t=scene.airlight.density, light_positions=positions,
                            light_intensities=intensities, window_depth=False, scale=scale,
                            mode=mode))
    finally:
        off.free()
    return rows


def _time_gauss_alone(region, repeats, scales, passes):
    """Median wall / CPU ms of draw_fog alone offscreen at the region's size, interleaved:
    the fog without the Gaussians and with them through each pass, per scale; each draw
    is finished by a 1-pixel read-back. The factors and tile lists are built in the
    warm-up draw (they belong to the view, not to the draw)."""
    import gpu
    from airlight import preview
    ctx = bpy.context
    w, h = region.width, region.height
    rv3d = next(a for a in ctx.window_manager.windows[0].screen.areas
                if a.type == 'VIEW_3D').spaces.active.region_3d
    persp = rv3d.perspective_matrix.copy()
    eye = tuple(rv3d.view_matrix.inverted().translation)
    scene = ctx.scene
    positions, intensities = preview.scene_lights(scene, ctx.view_layer)
    gaussians = preview.scene_gaussians(ctx)
    off = gpu.types.GPUOffScreen(w, h, format='RGBA8')
    out = []
    try:
        with off.bind():
            dist = preview.draw_distance(ctx, perspective_matrix=persp, view_origin=eye,
                                         is_perspective=True, size=(w, h))
            for scale in scales:
                S = preview.SCALES[scale]
                configs = [("no Gaussians", None, None)] + [(p, gaussians, p) for p in passes]

                def draw(g, p):
                    preview.draw_fog(depth_tex=dist, perspective_matrix=persp, view_origin=eye,
                                     is_perspective=True, viewport=(0, 0, w, h),
                                     sigma_t=scene.airlight.density, light_positions=positions,
                                     light_intensities=intensities, window_depth=False, scale=S,
                                     gaussians=g, gauss_pass=p)
                    _sync()
                for _name, g, p in configs:
                    draw(g, p)  # warm-up: shaders, factors, tile lists
                wall = {c[0]: [] for c in configs}
                cpu = {c[0]: [] for c in configs}
                for _ in range(repeats):
                    for name, g, p in configs:
                        t0, c0 = time.perf_counter(), time.process_time()
                        draw(g, p)
                        wall[name].append((time.perf_counter() - t0) * 1e3)
                        cpu[name].append((time.process_time() - c0) * 1e3)
                med = statistics.median
                gf = preview._state["gpu"]["gaussian_fog"]
                for name, _g, _p in configs:
                    out.append((scale, name, med(wall[name]), med(cpu[name]),
                                gf.tile_pairs if name == "TILES" else None,
                                gf.tiles_ms if name == "TILES" else None))
    finally:
        off.free()
    return out


def main():
    args = _args()
    import gpu
    from airlight import preview
    print(f"GPU: {gpu.platform.renderer_get()} / {gpu.platform.version_get()}")
    window, area, region = _view3d_region()
    print(f"viewport region: {region.width} x {region.height} px, {args.repeats} draws each (median)")
    print(f"{'lights':>6} {'depth':>8} {'scale':>7} {'no fog ms':>10} {'fog ms':>8} {'extra ms':>9} {'ratio':>6} "
          f"{'depth ms':>9} {'CPU no fog':>11} {'CPU fog':>8} {'CPU ratio':>9}")
    print("(wall ms per region draw; CPU = process CPU time incl. llvmpipe threads, "
          "robust to other load; depth = read-back + upload in the handler)")
    wm = bpy.context.window_manager
    for n in ([] if args.skip_point_section else args.lights):
        _scene(n)
        for depth_mode in ([] if args.passes_only else args.depth):
            for scale in args.scales:
                preview._state["error"] = None
                base, fog, depth, cbase, cfog = _time_draws(window, area, region, args.repeats,
                                                            wm, scale, depth_mode)
                if preview._state["error"]:
                    print("preview error:", preview._state["error"])
                    return 1
                print(f"{n:>6} {depth_mode:>8} {scale:>7} {base:>10.1f} {fog:>8.1f} {fog - base:>9.1f} "
                      f"{fog / base:>6.2f} {depth:>9.1f} {cbase:>11.1f} {cfog:>8.1f} "
                      f"{cfog / cbase:>9.2f}", flush=True)
        print(f"  passes alone at {region.width}x{region.height}, {n} lights "
              f"(median of {args.repeats}, wall / CPU ms):")
        for name, wall, cpu in _time_passes(region, args.repeats):
            print(f"    {name:<32} {wall:>8.1f} {cpu:>8.1f}", flush=True)
    if args.gaussians:
        print(f"Gaussian fog: {args.gauss_lights} point lights, DRAWN depth, "
              f"{args.gauss_repeats} draws each (median)")
        print(f"{'gaussians':>9} {'scale':>7} {'pass':>6} {'no fog ms':>10} {'fog ms':>9} {'ratio':>7} "
              f"{'CPU no fog':>11} {'CPU fog':>9} {'CPU ratio':>9} {'factors ms':>10} {'tiles ms':>9} "
              f"{'entries':>9}")
    for count in args.gaussians:
        _scene(args.gauss_lights)
        _add_fog_object(count)
        _time_factors(count, args.gauss_lights, args.gauss_repeats)
        if args.gauss_alone and not args.factors_only:
            rows = _time_gauss_alone(region, args.gauss_repeats, args.gauss_scales, args.gauss_passes)
            print(f"  draw_fog alone at {region.width}x{region.height}, {count} Gaussians, "
                  f"{args.gauss_lights} lights (median of {args.gauss_repeats}; ratio = to the same "
                  f"draw without Gaussians):")
            base = {}
            for scale, name, wall, cpu, entries, tiles_ms in rows:
                if name == "no Gaussians":
                    base[scale] = (wall, cpu)
                extra = "" if entries is None else f"  tile entries {entries}, lists built in {tiles_ms:.1f} ms"
                print(f"    {scale:>7} {name:<13} wall {wall:>9.1f} ms ({wall / base[scale][0]:>6.2f}x)  "
                      f"CPU {cpu:>9.1f} ms ({cpu / base[scale][1]:>6.2f}x){extra}", flush=True)
            continue
        for scale in ([] if args.factors_only else args.gauss_scales):
            for gauss_pass in args.gauss_passes:
                preview.GAUSS_PASS = gauss_pass
                preview._state["error"] = None
                base, fog, _depth, cbase, cfog = _time_draws(window, area, region, args.gauss_repeats,
                                                             wm, scale, 'DRAWN')
                if preview._state["error"]:
                    print("preview error:", preview._state["error"])
                    return 1
                gf = (preview._state["gpu"] or {}).get("gaussian_fog")
                factor_ms = gf.factor_ms if gf is not None else float("nan")
                tiles_ms = gf.tiles_ms if gf is not None and gauss_pass == 'TILES' else float("nan")
                entries = gf.tile_pairs if gf is not None and gauss_pass == 'TILES' else 0
                print(f"{count:>9} {scale:>7} {gauss_pass:>6} {base:>10.1f} {fog:>9.1f} {fog / base:>7.2f} "
                      f"{cbase:>11.1f} {cfog:>9.1f} {cfog / cbase:>9.2f} {factor_ms:>10.1f} "
                      f"{tiles_ms:>9.1f} {entries:>9}", flush=True)
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
