"""Cost of volumetric shadows in the viewport preview under the current OpenGL driver
(llvmpipe here; the GPU harness in gpu_preview/ times the shaders on a real GPU).

    xvfb-run -a -s "-screen 0 1280x1024x24" tools/blender.sh --python benchmarks/bench_preview_shadows.py [-- --repeats 5]

Scene: a floor, a wall with a window and a row of slats, and N lights (points, spots, a sun,
cycled) that all cast shadows. draw_fog alone, offscreen at --size (default 1920 x 1080) and
at each --scales (default QUARTER, HALF), interleaved: shadows off (the unshadowed shaders)
against shadows on (each shadowed light marched through its shadow map). Each draw is
finished by a 1-pixel read-back. Also the shadow maps' own cost: drawing the atlas again
(what a depsgraph update or a light's move costs, once; view changes do not redraw it).
Prints medians and the on/off ratio per light count; --clutter adds random caster
triangles (the maps' cost against 10^3..10^6 casters).
"""

import argparse
import math
import os
import statistics
import sys
import time

import bpy
import gpu
import numpy as np
from gpu_extras.batch import batch_for_shader
from mathutils import Matrix, Vector

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))


def _args():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    p = argparse.ArgumentParser(prog="bench_preview_shadows")
    p.add_argument("--repeats", type=int, default=5)
    p.add_argument("--lights", type=int, nargs="+", default=[1, 4])
    p.add_argument("--scales", nargs="+", default=["QUARTER", "HALF"])
    p.add_argument("--size", type=int, nargs=2, default=[1920, 1080])
    p.add_argument("--clutter", type=int, nargs="+", default=[0],
                   help="extra random caster triangles (one mesh) to time the maps' growth")
    return p.parse_args(argv)


def _mesh(scene, name, verts, faces):
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata(verts, [], faces)
    obj = bpy.data.objects.new(name, mesh)
    scene.collection.objects.link(obj)


def _scene(n_lights, size, clutter=0):
    scene = bpy.context.scene
    for obj in list(scene.objects):
        bpy.data.objects.remove(obj)
    _mesh(scene, "Floor", [(-30, -30, 0), (30, -30, 0), (30, 30, 0), (-30, 30, 0)], [(0, 1, 2, 3)])
    wall = [(-6, 0, 0), (-1, 0, 0), (-1, 0, 5), (-6, 0, 5), (1, 0, 0), (6, 0, 0), (6, 0, 5), (1, 0, 5),
            (-1, 0, 0), (1, 0, 0), (1, 0, 1.5), (-1, 0, 1.5), (-1, 0, 3.5), (1, 0, 3.5), (1, 0, 5), (-1, 0, 5)]
    _mesh(scene, "Wall", wall, [(0, 1, 2, 3), (4, 5, 6, 7), (8, 9, 10, 11), (12, 13, 14, 15)])
    slats, faces = [], []
    for k, z in enumerate(np.arange(0.5, 3.5, 0.4)):
        b = len(slats)
        slats += [(-8, -4, z), (-3, -4, z), (-3, -4, z + 0.2), (-8, -4, z + 0.2)]
        faces.append((b, b + 1, b + 2, b + 3))
    _mesh(scene, "Slats", slats, faces)
    if clutter:
        rng = np.random.default_rng(1)
        c = rng.uniform((-10, -10, 0.2), (10, 10, 4.0), (clutter, 3))
        v = (c[:, None, :] + rng.normal(scale=0.03, size=(clutter, 3, 3))).reshape(-1, 3)
        _mesh(scene, "Clutter", [tuple(p) for p in v], [tuple(range(3 * i, 3 * i + 3)) for i in range(clutter)])
    kinds = ('POINT', 'SPOT', 'SUN')
    for i in range(n_lights):
        kind = kinds[i % 3] if n_lights > 1 else 'POINT'
        data = bpy.data.lights.new(f"L{i}", kind)
        data.energy = 3.0 if kind == 'SUN' else 2000.0
        data.shadow_soft_size = 0.0
        obj = bpy.data.objects.new(f"L{i}", data)
        obj.location = (-4.0 + 3.0 * i, 3.0 + 0.5 * i, 2.5)
        if kind != 'POINT':
            target = Vector((0.0, -4.0, 1.0))
            obj.rotation_euler = (target - obj.location).to_track_quat('-Z', 'Y').to_euler()
        scene.collection.objects.link(obj)
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    cam.location = (9.0, -12.0, 3.0)
    cam.rotation_euler = (Vector((0.0, 0.0, 1.5)) - cam.location).to_track_quat('-Z', 'Y').to_euler()
    scene.collection.objects.link(cam)
    scene.camera = cam
    scene.render.resolution_x, scene.render.resolution_y = size
    scene.render.resolution_percentage = 100
    scene.airlight.enabled = True
    scene.airlight.density = 0.08
    scene.airlight.volumetric_shadows = True
    scene.airlight.model = 'AUTO'
    bpy.context.view_layer.update()
    return scene


def main():
    args = _args()
    import airlight
    if not hasattr(bpy.types.Scene, "airlight"):
        airlight.register()
    from airlight import gpu_shaders as gs
    from airlight import preview, preview_shadows, scene_export
    w, h = args.size
    print(f"GPU: {gpu.platform.renderer_get()}; {w}x{h}, median of {args.repeats}; shadow maps "
          f"{preview_shadows.SHADOW_RES}^2 per face")
    print(f"{'lights':>6} {'scale':>8} {'off ms':>9} {'on ms':>9} {'ratio':>6} {'maps ms':>8}")
    for n, clutter in [(n, c) for c in args.clutter for n in args.lights]:
        scene = _scene(n, (w, h), clutter)
        depsgraph = bpy.context.evaluated_depsgraph_get()
        desc = scene_export.export_scene(scene, depsgraph)
        preview._state["lights"] = None
        lights = preview.preview_lights(scene, depsgraph)
        cam = scene.camera
        persp = Matrix(desc["projection"].tolist()) @ cam.matrix_world.inverted()
        depth_tex, _ = gs.render_depth(desc["vertices"], desc["triangles"], persp, w, h)
        verts = np.asarray(desc.get("occluder_vertices", desc["vertices"]), np.float32)
        tris = np.asarray(desc.get("occluder_triangles", desc["triangles"]), np.int32)
        off = gpu.types.GPUOffScreen(w, h, format='RGBA16F')
        try:
            with off.bind():
                batch = batch_for_shader(preview._distance_shader(), 'TRIS', {"pos": verts}, indices=tris)
                casters = [(batch, Matrix.Identity(4))]
                shadows = preview.scene_shadows(lights, casters, ("bench", n))
                shadowed = sum(r >= 0 for k in ("points", "spots", "suns") for r in shadows[k])

                def finish():
                    gpu.state.active_framebuffer_get().read_color(0, 0, 1, 1, 4, 0, 'FLOAT')

                def draw(S, sh):
                    preview.draw_fog(depth_tex=depth_tex, perspective_matrix=persp,
                                     view_origin=tuple(cam.matrix_world.translation), is_perspective=True,
                                     viewport=(0, 0, w, h), sigma_t=scene.airlight.density,
                                     light_positions=lights["positions"],
                                     light_intensities=lights["intensities"],
                                     clip_start=desc["clip_start"], window_depth=True, scale=S,
                                     spots=lights["spots"], suns=lights["suns"], shadows=sh)
                    finish()

                def maps(k):
                    preview.scene_shadows(lights, casters, ("bench", n, k))
                    finish()
                maps(-1)
                maps_ms = statistics.median(_timed(lambda k=k: maps(k)) for k in range(args.repeats))
                for scale in args.scales:
                    S = preview.SCALES[scale]
                    draw(S, None)
                    draw(S, shadows)  # compile both
                    t_off, t_on = [], []
                    for _ in range(args.repeats):
                        t_off.append(_timed(lambda: draw(S, None)))
                        t_on.append(_timed(lambda: draw(S, shadows)))
                    a, b = statistics.median(t_off), statistics.median(t_on)
                    print(f"{n:>6} {scale:>8} {a:>9.1f} {b:>9.1f} {b / a:>6.2f} {maps_ms:>8.1f}"
                          f"   ({shadowed} shadowed, {len(tris)} caster triangles)", flush=True)
        finally:
            off.free()
    return 0


def _timed(fn):
    t0 = time.perf_counter()
    fn()
    return (time.perf_counter() - t0) * 1e3


if __name__ == "__main__":
    code = 1
    try:
        code = main()
    finally:
        sys.stdout.flush()
        os._exit(code)
