"""Cost of the viewport fog preview under the current OpenGL driver (llvmpipe here).

    xvfb-run -a -s "-screen 0 1280x1024x24" tools/blender.sh --python benchmarks/bench_preview.py [-- --repeats 10]

Builds a small scene (floor, cube, N point lights), puts the 3D viewport in camera view
and redraws its region with wm.redraw_timer('DRAW_SWAP': the swap waits for the GPU, so queued fog work is not billed to the next draw),
with the preview off and on. Prints ms per viewport draw, the fog's extra cost and the
ratio, plus the handler's own timing split (depth read-back + upload vs fog pass).
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


def _view3d_region():
    window = bpy.context.window_manager.windows[0]
    for area in window.screen.areas:
        if area.type == 'VIEW_3D':
            area.spaces.active.region_3d.view_perspective = 'CAMERA'
            region = next(r for r in area.regions if r.type == 'WINDOW')
            return window, area, region
    raise RuntimeError("no 3D viewport")


def _time_draws(window, area, region, repeats, wm):
    """Median ms per region draw with the preview off and on, interleaved so that load
    from other processes hits both alike."""
    from airlight import preview
    off, on, depth, cpu_off, cpu_on = [], [], [], [], []
    with bpy.context.temp_override(window=window, screen=window.screen, area=area, region=region):
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


def main():
    args = _args()
    import gpu
    from airlight import preview
    print(f"GPU: {gpu.platform.renderer_get()} / {gpu.platform.version_get()}")
    window, area, region = _view3d_region()
    print(f"viewport region: {region.width} x {region.height} px, {args.repeats} draws each (median)")
    print(f"{'lights':>6} {'no fog ms':>10} {'fog ms':>8} {'extra ms':>9} {'ratio':>6} "
          f"{'depth ms':>9} {'CPU no fog':>11} {'CPU fog':>8} {'CPU ratio':>9}")
    print("(wall ms per region draw; CPU = process CPU time incl. llvmpipe threads, "
          "robust to other load; depth = read-back + upload in the handler)")
    wm = bpy.context.window_manager
    for n in args.lights:
        _scene(n)
        preview._state["error"] = None
        base, fog, depth, cbase, cfog = _time_draws(window, area, region, args.repeats, wm)
        if preview._state["error"]:
            print("preview error:", preview._state["error"])
            return 1
        print(f"{n:>6} {base:>10.1f} {fog:>8.1f} {fog - base:>9.1f} {fog / base:>6.2f} "
              f"{depth:>9.1f} {cbase:>11.1f} {cfog:>8.1f} {cfog / cbase:>9.2f}")
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
