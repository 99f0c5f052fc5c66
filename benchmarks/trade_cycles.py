"""Cycles half of benchmarks/bench_trade.py: renders its scenes with Cycles single scattering.

    tools/blender.sh -b --python benchmarks/trade_cycles.py -- <job.json>

Run by bench_trade.py (not by hand): job.json holds the scenes (bench_trade.Scene as
dicts), the resolution, the sample counts, the thread count and an output folder. For
each scene it builds the matched Cycles scene with tests/blender/cycles_scenes.py's
recipe (volume_bounces = 0, black world and black floor, radius-0 lights, Standard view,
no denoising, float EXR; see shared NOTES.md), with the medium's Henyey-Greenstein
anisotropy g and the scene's light (point, spot or sun), renders it once per sample
count, and writes <out>/<scene>_<spp>.exr (the fog only: everything else is black) and
<out>/cycles.json with the render times and the camera matrices Blender computed (which
bench_trade.py checks against its own).

The film filter is narrowed to 0.01 px (Blackman-Harris), so Cycles' pixels are point
samples at pixel centres like the bake's (aa_samples = 1): the comparison then measures
sampling noise, not the difference between a filtered and a point-sampled peak at the light.
"""

import json
import os
import sys

import bpy
import numpy as np
from mathutils import Vector

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(REPO, "tests", "blender"))
import cycles_scenes  # noqa: E402  (the shared Cycles recipe)


def _medium_box(scene, sc):
    """Homogeneous Volume Scatter box: x, y in +-box_half, z from -10 to fog_top (the sun
    scene: the sun's light enters through the top, as the bake's fog_top assumes)."""
    h, top = sc["box_half"], sc["fog_top"]
    verts = [(x, y, z) for x in (-h, h) for y in (-h, h) for z in (-10.0, top)]
    faces = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    mesh = bpy.data.meshes.new("TradeFogBox")
    mesh.from_pydata(verts, [], faces)
    mesh.validate()
    mesh.update()
    box = bpy.data.objects.new("TradeFogBox", mesh)
    mat = bpy.data.materials.new("TradeFog")
    mat.use_nodes = True
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    for n in list(nodes):
        nodes.remove(n)
    out = nodes.new("ShaderNodeOutputMaterial")
    vs = nodes.new("ShaderNodeVolumeScatter")
    _scatter(vs, sc)
    links.new(vs.outputs["Volume"], out.inputs["Volume"])
    mat.cycles.homogeneous_volume = True
    mesh.materials.append(mat)
    scene.collection.objects.link(box)


def _scatter(node, sc):
    node.inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)
    node.inputs["Density"].default_value = sc["sigma_t"]
    node.inputs["Anisotropy"].default_value = sc["g"]


def build(sc, width, height, threads):
    desc = cycles_scenes.FogScene(
        width=width, height=height, sigma_t=sc["sigma_t"], light_power=sc["power"],
        light_location=tuple(sc["light_location"]), camera_location=tuple(sc["camera_location"]),
        camera_pitch_deg=sc["camera_pitch_deg"], lens_mm=sc["lens_mm"],
        floor_x=tuple(sc["floor_x"]), floor_y=tuple(sc["floor_y"]), threads=threads,
        clip_start=sc["clip_start"], clip_end=sc["clip_end"], fog=False)
    scene = cycles_scenes.build(desc)
    scene.cycles.filter_width = 0.01
    if sc["light_type"] == 'SUN':
        _medium_box(scene, sc)
    else:
        world = scene.world
        nodes, links = world.node_tree.nodes, world.node_tree.links
        wout = next(n for n in nodes if n.bl_idname == "ShaderNodeOutputWorld")
        vs = nodes.new("ShaderNodeVolumeScatter")
        _scatter(vs, sc)
        links.new(vs.outputs["Volume"], wout.inputs["Volume"])
        world.cycles.homogeneous_volume = True
    light = scene.objects["RefLight"]
    if sc["light_type"] == 'SPOT':
        light.data.type = 'SPOT'
        light.data.spot_size = sc["spot_size"]
        light.data.spot_blend = sc["spot_blend"]
        light.data.shadow_soft_size = 0.0
        light.rotation_mode = 'QUATERNION'
        light.rotation_quaternion = Vector((0.0, 0.0, -1.0)).rotation_difference(Vector(sc["spot_axis"]))
    elif sc["light_type"] == 'SUN':
        light.data.type = 'SUN'
        light.data.energy = sc["sun_strength"]  # W/m^2
        light.data.angle = 0.0
        light.rotation_mode = 'QUATERNION'
        light.rotation_quaternion = Vector((0.0, 0.0, -1.0)).rotation_difference(Vector(sc["sun_direction"]))
    bpy.context.view_layer.update()
    return scene


def main():
    argv = sys.argv[sys.argv.index("--") + 1:]
    with open(argv[0]) as f:
        job = json.load(f)
    out_dir = job["out"]
    results = {}
    for sc in job["scenes"]:
        scene = build(sc, job["width"], job["height"], job["threads"])
        depsgraph = bpy.context.evaluated_depsgraph_get()
        cam = scene.camera
        proj = cam.calc_matrix_camera(depsgraph, x=job["width"], y=job["height"], scale_x=1.0, scale_y=1.0)
        times = {}
        for spp in job["samples"]:
            path = os.path.join(out_dir, f"{sc['name']}_{spp}.exr")
            scene.cycles.samples = spp
            times[str(spp)] = cycles_scenes.render(scene, path, seed=1)
            print(f"cycles {sc['name']} {spp} spp: {times[str(spp)]:.2f} s", flush=True)
        results[sc["name"]] = dict(times=times,
                                   cam_to_world=np.array(cam.matrix_world).tolist(),
                                   projection=np.array(proj).tolist())
    with open(os.path.join(out_dir, "cycles.json"), "w") as f:
        json.dump(results, f)


try:
    main()
except Exception:
    import traceback
    traceback.print_exc()
    sys.exit(1)
sys.exit(0)
