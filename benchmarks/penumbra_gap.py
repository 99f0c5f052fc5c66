"""What the missing penumbrae cost: the volumetric-shadow scenes of
tests/blender/test_cycles_shadows.py ("window", "panel") with the lamp's Radius at Blender's
default 0.25 m, Cycles (2 seeds, 1024 samples) against the bake, which takes the radius for
the glow and casts the shadows from 1 (the lamp's centre: hard shadow edges) to 32 points of
its sphere (shadow_samples).

    tools/blender.sh -b --python benchmarks/penumbra_gap.py

Prints per scene: the mean and p99 relative difference over the fog pixels (those above 5 %
of the p99, away from silhouettes and the light's image), the same over the shadow-edge
pixels alone (neighbours more than 15 % apart in Cycles), Cycles' noise there, and the
bake against the radius-0 Cycles render (the hard-shadow truth) for scale.
"""
import os
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(os.path.dirname(HERE), "tests", "blender"))
import cycles_scenes as cs  # noqa: E402
import test_cycles_shadows as ts  # noqa: E402

ARTIFACTS = os.path.join(os.path.dirname(HERE), "out", "penumbra_gap")
RADIUS = float(os.environ.get("PENUMBRA_RADIUS", "0.25"))  # m; Blender's default
SAMPLES = (1, 4, 8, 16, 32)  # shadow_samples: 1 is the hard shadows from the lamp's centre


def edges(C):
    up = np.zeros_like(C, bool)
    for axis in (0, 1):
        a = np.abs(np.diff(C, axis=axis)) > ts.EDGE_JUMP * np.maximum(
            np.minimum(np.take(C, range(C.shape[axis] - 1), axis), np.take(C, range(1, C.shape[axis]), axis)), 1e-30)
        pad = [(0, 0), (0, 0)]
        pad[axis] = (0, 1)
        up |= np.pad(a, pad)
        pad[axis] = (1, 0)
        up |= np.pad(a, pad)
    return up


def main():
    import bpy
    from airlight import native, scene_export
    for name, build, depth_fn in (("window", ts._build_window, ts.window_depth), ("panel", ts._build_panel,
                                                                                  ts.panel_depth)):
        desc, scene = build()
        lamp = next(o for o in scene.objects if o.type == 'LIGHT')
        st = scene.airlight
        st.density, st.color, st.anisotropy, st.model, st.volumetric_shadows = ts.SIGMA_T, (1, 1, 1), 0.0, 'AUTO', True
        scene.cycles.samples = 1024
        renders = {}
        for r in (0.0, RADIUS):
            lamp.data.shadow_soft_size = r
            bpy.context.view_layer.update()
            (c1, c2), _ = cs.render_seeds(scene, ARTIFACTS, f"{name}_r{r:g}", (1, 2))
            renders[r] = (0.5 * (c1 + c2)[..., 0], cs.seed_noise(c1, c2))
            description = scene_export.export_scene(scene, bpy.context.evaluated_depsgraph_get())
            renders[r] += ({k: native.get().bake(**description, threads=2, shadow_samples=k)["airlight"][..., 0]
                            .astype(np.float64) for k in SAMPLES},)
        inputs = cs.bake_inputs(scene)
        eye, d = cs.camera_rays(inputs["cam_to_world"], inputs["projection"], desc.width, desc.height, from_eye=True)
        depth = depth_fn(eye, d)
        C, noise, bakes = renders[RADIUS]
        near = cs.near_light(inputs, desc.width, desc.height, desc.light_location, ts.LIGHT_RADIUS_PX)
        mask = (C > ts.SIGNAL_FLOOR * np.percentile(C, 99)) & ~cs.silhouette_mask(depth, radius=2) & ~near
        edge = mask & edges(C)
        for label, m in (("fog", mask), ("shadow edges", edge)):
            if not m.any():
                print(f"{name}: no {label} pixels")
                continue
            hard_mean, _ = cs.rel_stats(renders[0.0][2][1], renders[0.0][0], m)
            for k, A in bakes.items():
                mean, p99 = cs.rel_stats(A, C, m)
                print(f"{name} r = {RADIUS} m, {label} ({int(m.sum())} px), {k} shadow sample(s): bake vs Cycles "
                      f"mean {100 * mean:.2f} % p99 {100 * p99:.1f} % (noise {100 * noise[m].mean():.2f} %); at "
                      f"r = 0 the bake vs Cycles mean {100 * hard_mean:.2f} %", flush=True)


main()
