"""Cost of the airbrush step and of the particle emitter's per-frame evaluation.

    tools/blender.sh -b --python benchmarks/bench_tools.py [-- --repeats 30]

Prints medians (ms) of:
- airbrush.step for 500 particles in a closed room with a solid box (BVHTree ray casts,
  about half the moves bounce) and without surfaces; the BVH build of that scene;
- emitter.evaluate for 1000 live particles (rate 500/s, lifetime 2 s), static and
  keyframed (cold: F-curves evaluated for every birth; playing forward: only the births
  since the last frame, the rest cached); update_emitter (evaluate + bulk write into the
  fog mesh) and scene.frame_set with the frame_change_post handler;
- Fill Mesh with Fog of a UV sphere at a = 8, spacing 0.75/a (about 5000 grid points).
"""

import argparse
import os
import sys

import bpy
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))  # Blender does not add it
from timing import median_ms  # noqa: E402


def _args():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    p = argparse.ArgumentParser(prog="bench_tools")
    p.add_argument("--repeats", type=int, default=30)
    return p.parse_args(argv)




def _box(name, lo, hi, flip=False):
    v = [(x, y, z) for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])]
    faces = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    if flip:
        faces = [tuple(reversed(f)) for f in faces]
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata(v, [], faces)
    obj = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(obj)
    return obj


def main():
    args = _args()
    from airlight import airbrush, emitter, fog_object
    bpy.ops.wm.read_homefile(use_factory_startup=True, use_empty=True)
    scene = bpy.context.scene
    _box("Room", (-2, -2, 0), (2, 2, 3), flip=True)
    _box("Solid", (-0.5, -0.5, 0), (0.5, 0.5, 1))
    depsgraph = bpy.context.evaluated_depsgraph_get()
    print(f"airbrush BVH build (2 boxes): {median_ms(lambda: airbrush.scene_bvh(depsgraph), args.repeats):.3f} ms")
    bvh = airbrush.scene_bvh(depsgraph)
    rng = np.random.default_rng(0)
    p, v = airbrush.spawn((1.2, 1.2, 1.5), None, 500, 4.0, rng)
    for _ in range(10):  # spread them out first
        p, v = airbrush.step(p, v, 1 / 30, 0.3, 2.0, bvh, rng)
    state = [p, v]

    def one_step(surfaces):
        state[0], state[1] = airbrush.step(state[0], state[1], 1 / 30, 0.3, 2.0,
                                           surfaces, rng)
    print(f"airbrush step, 500 particles, room + box: {median_ms(lambda: one_step(bvh), args.repeats):.2f} ms")
    print(f"airbrush step, 500 particles, no surfaces: {median_ms(lambda: one_step(None), args.repeats):.3f} ms")

    bpy.ops.wm.read_homefile(use_factory_startup=True, use_empty=True)
    scene = bpy.context.scene
    scene.frame_start, scene.frame_end = 1, 1000
    bpy.ops.airlight.add_emitter()
    obj = bpy.context.active_object
    s = obj.airlight_emitter
    s.rate, s.lifetime, s.frame_start, s.frame_end = 500.0, 2.0, 1, 1000
    scene.frame_set(100)
    n = len(emitter.evaluate(obj, scene)[0])
    print(f"emitter live particles at frame 100: {n}")
    print(f"emitter evaluate, {n} particles, static: {median_ms(lambda: emitter.evaluate(obj, scene), args.repeats):.3f} ms")
    print(f"emitter update_emitter (evaluate + write mesh), {n} particles: "
          f"{median_ms(lambda: emitter.update_emitter(obj, scene), args.repeats):.3f} ms")
    frames = iter(range(10 ** 6))
    print(f"scene.frame_set with the handler, {n} particles: "
          f"{median_ms(lambda: scene.frame_set(100 + next(frames) % 2), args.repeats):.3f} ms")
    obj.keyframe_insert("location", frame=1)
    obj.location = (3.0, 0.0, 1.0)
    obj.rotation_euler = (0.0, 0.0, 1.0)
    obj.keyframe_insert("location", frame=250)
    obj.keyframe_insert("rotation_euler", frame=250)

    def cold():
        emitter._track_cache.clear()
        emitter.evaluate(obj, scene)
    print(f"emitter evaluate, {n} particles, keyframed, cold (every birth's F-curves evaluated): "
          f"{median_ms(cold, args.repeats):.3f} ms")
    eval_frames = iter(range(101, 10 ** 6))
    print(f"emitter evaluate, {n} particles, keyframed, playing forward one frame per call: "
          f"{median_ms(lambda: emitter.evaluate(obj, scene, float(next(eval_frames))), args.repeats):.3f} ms")
    step_frames = iter(range(101, 10 ** 6))

    def forward():
        scene.frame_set(next(step_frames))  # runs the handler, which evaluates
    print(f"scene.frame_set with the handler, {n} particles, keyframed, playing forward: "
          f"{median_ms(forward, args.repeats):.3f} ms")

    bpy.ops.wm.read_homefile(use_factory_startup=True, use_empty=True)
    scene = bpy.context.scene
    bpy.ops.mesh.primitive_uv_sphere_add(radius=1.0, segments=48, ring_count=24)
    bvh = airbrush.scene_bvh(bpy.context.evaluated_depsgraph_get())
    h = 0.75 / 8.0
    counts = []
    ms = median_ms(lambda: counts.append(len(airbrush.fill_points(bvh, (-1, -1, -1), (1, 1, 1), h))),
                    max(3, args.repeats // 10))
    print(f"fill sphere r=1 at spacing {h:.4f} m: {counts[0]} Gaussians in {ms:.1f} ms "
          f"({int(np.floor(2 / h) + 1) ** 3} grid points tested)")


if __name__ == "__main__":
    main()
