"""Child process of test_bake_extremes.py: bakes each case of a JSON file in turn and
appends one JSON line per case to the results file (flushed before the next case starts,
so a crash leaves the cases before it recorded and names the one that killed it).

    tools/blender.sh -b --python tests/blender/support/extremes_child.py -- CASES.json RESULTS.jsonl DIR

A case describes the camera, the render size, the scene's scale and the fog (see
test_bake_extremes.make_cases). The scene: a slab filling the middle of the view at a depth
inside the clip range (its thickness along the view at most a quarter of that depth), a ground plane under it, a point light beside the camera; with
"empty" no geometry at all. Cases with "cycles" also render Cycles' alpha (transparent film)
for the silhouette check.
"""
import json
import math
import os
import sys
import time
import traceback

import bpy
import numpy as np
from mathutils import Vector

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
from exr_files import read_exr  # noqa: E402


def build(case, directory):
    bpy.ops.wm.read_homefile(use_factory_startup=True, use_empty=True)
    scene = bpy.context.scene
    render = scene.render
    render.resolution_x, render.resolution_y = case["res"]
    render.resolution_percentage = case.get("percentage", 100)
    render.pixel_aspect_x, render.pixel_aspect_y = case["aspect"]
    cam_data = bpy.data.cameras.new("Cam")
    c = case["camera"]
    cam_data.type = c["type"]
    cam_data.lens = c["lens"]
    cam_data.sensor_fit = c["sensor_fit"]
    cam_data.shift_x, cam_data.shift_y = c["shift"]
    cam_data.ortho_scale = c["ortho_scale"]
    cam_data.clip_start, cam_data.clip_end = c["clip"]
    cam = bpy.data.objects.new("Cam", cam_data)
    scene.collection.objects.link(cam)
    scene.camera = cam
    origin = Vector(case["origin"])
    cam.location = origin
    cam.rotation_euler = (math.pi / 2, 0.0, 0.0)  # looking along +y
    bpy.context.view_layer.update()

    # The view's middle at depth d (inside the clip range): Blender's own frame corners.
    depth = case["depth"]
    frame = [Vector(v) for v in cam_data.view_frame(scene=scene)]
    centre = sum(frame, Vector()) / 4.0
    width = max((frame[0] - frame[2]).length, 1e-30)
    if c["type"] == 'PERSP':
        k = depth / -centre.z
        centre_local, size = centre * k, width * k / 3.0
    else:
        centre_local, size = Vector((centre.x, centre.y, -depth)), width / 3.0
    box_at = cam.matrix_world @ centre_local
    if not case.get("empty"):
        mesh = bpy.data.meshes.new("Box")
        # A slab a quarter of its depth thick at most, so that it lies inside the clip range.
        s, t = 0.5 * size, 0.5 * min(size, 0.25 * depth)
        verts = [(x, y, z) for x in (-s, s) for y in (-t, t) for z in (-s, s)]
        faces = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
        mesh.from_pydata(verts, [], faces)
        box = bpy.data.objects.new("Box", mesh)
        box.location = box_at
        scene.collection.objects.link(box)
        ground = bpy.data.meshes.new("Ground")
        g = 40.0 * size
        z = box_at.z - 2.0 * size
        ground.from_pydata([(-g, -g, 0), (g, -g, 0), (g, g, 0), (-g, g, 0)], [], [(0, 1, 2, 3)])
        floor = bpy.data.objects.new("Ground", ground)
        floor.location = (box_at.x, box_at.y, z)
        scene.collection.objects.link(floor)
    light_data = bpy.data.lights.new("Lamp", 'POINT')
    light_data.energy = 1000.0 * max(depth, 1e-3) ** 2
    light_data.shadow_soft_size = 0.0
    lamp = bpy.data.objects.new("Lamp", light_data)
    lamp.location = cam.matrix_world @ Vector((0.3 * depth, 0.2 * depth, -0.5 * depth))
    scene.collection.objects.link(lamp)
    if case.get("sun"):
        sun = bpy.data.lights.new("Sun", 'SUN')
        sun.energy = 3.0
        sun_obj = bpy.data.objects.new("Sun", sun)
        sun_obj.rotation_euler = (0.6, 0.2, 0.4)
        scene.collection.objects.link(sun_obj)

    if case.get("spot"):
        spot = bpy.data.lights.new("Spot", 'SPOT')
        spot.energy = light_data.energy
        spot.spot_size = 0.6
        spot.shadow_soft_size = 0.0
        spot_obj = bpy.data.objects.new("Spot", spot)
        spot_obj.location = cam.matrix_world @ Vector((-0.3 * depth, 0.0, -0.3 * depth))
        spot_obj.rotation_euler = (math.pi / 2 + 0.3, 0.0, 0.2)
        scene.collection.objects.link(spot_obj)
    fog = case["fog"]
    a = scene.airlight
    a.enabled = True
    a.model = fog["model"]
    a.density = fog["density"]
    a.phase = fog["phase"]
    a.anisotropy = fog["g"]
    a.surface_shading = fog["surface"]
    a.environment_glow = fog["environment"]
    a.cache_dir = directory
    world = bpy.data.worlds.new("World")
    world.color = (0.05, 0.05, 0.05)
    scene.world = world
    render.engine = 'CYCLES'
    scene.cycles.samples = 8
    scene.cycles.use_denoising = False
    scene.cycles.device = 'CPU'
    scene.view_settings.view_transform = 'Standard'
    return scene


def finite_range(pixels, names, prefix):
    index = [i for i, n in enumerate(names) if n.startswith(prefix)]
    values = pixels[..., index]
    return bool(np.isfinite(values).all()), float(np.min(values)), float(np.max(values))


def run_case(case, directory):
    scene = build(case, directory)
    out = {"id": case["id"]}
    path = os.path.join(directory, f"fog_{case['id']}.exr")
    start = time.perf_counter()
    try:
        bpy.ops.airlight.bake(filepath=path)
    except RuntimeError as ex:  # the operator's ERROR report
        out.update(status="refused", message=str(ex).strip(), seconds=time.perf_counter() - start)
        return out
    out["seconds"] = time.perf_counter() - start
    pixels, names = read_exr(path)
    out["status"] = "baked"
    out["airlight"] = finite_range(pixels, names, "Fog.Airlight.")
    out["transmittance"] = finite_range(pixels, names, "Fog.Transmittance.")
    surface = [n for n in names if n.startswith("Fog.Surface")]
    out["surface"] = finite_range(pixels, names, "Fog.Surface") if surface else None
    transmittance = pixels[..., names.index("Fog.Transmittance.R")]
    # Pixels the bake sees a surface through (T < 1 with fog, or the depth test below).
    from airlight import bake as bake_module
    if case.get("cycles"):
        description, settings = bake_module.prepare(scene, bpy.context.evaluated_depsgraph_get())[:2]
        from airlight import native
        result = native.get().bake(**description, model=settings["model"])
        hit = np.isfinite(result["depth"]).astype(np.float64)
        scene.render.film_transparent = True
        scene.airlight.enabled = False
        settings_img = scene.render.image_settings
        settings_img.file_format = 'OPEN_EXR'
        settings_img.color_depth = '32'
        scene.render.filepath = os.path.join(directory, f"cycles_{case['id']}.exr")
        bpy.ops.render.render(write_still=True)
        render_pixels, render_names = read_exr(scene.render.filepath)
        alpha = render_pixels[..., render_names.index("A")] if "A" in render_names else render_pixels[..., 3]
        np.save(os.path.join(directory, f"hit_{case['id']}.npy"), hit)
        np.save(os.path.join(directory, f"alpha_{case['id']}.npy"), alpha)
        out["cycles"] = True
    out["transmittance_shape"] = list(transmittance.shape)
    return out


def main():
    argv = sys.argv[sys.argv.index("--") + 1:]
    cases_path, results_path, directory = argv
    with open(cases_path) as f:
        cases = json.load(f)
    with open(results_path, "a") as results:
        for case in cases:
            results.write(json.dumps({"id": case["id"], "status": "started"}) + "\n")
            results.flush()
            try:
                out = run_case(case, directory)
            except Exception as ex:  # a Python error in the add-on is a finding, not a crash
                out = {"id": case["id"], "status": "error",
                       "message": f"{type(ex).__name__}: {ex}", "trace": traceback.format_exc()}
            results.write(json.dumps(out) + "\n")
            results.flush()


if __name__ == "__main__":
    code = 0
    try:
        main()
    except Exception:
        traceback.print_exc()
        code = 1
    finally:
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code)
