"""Soft shadows against Cycles: the volumetric-shadow scenes of
tests/blender/test_cycles_shadows.py ("window", "panel": a lamp of Radius PENUMBRA_RADIUS,
default Blender's 0.25 m; "roof": a sun of Angle PENUMBRA_SUN_ANGLE degrees, default 5),
Cycles (2 seeds, 1024 samples) against the bake with its shadows cast from 1 (the light's
centre: hard shadow edges) to 64 points of its sphere or directions over the sun's disk
(shadow_samples), and the count Soft Shadow Samples Automatic picks at 1 %.

    [PENUMBRA_RADIUS=1] [PENUMBRA_SUN_ANGLE=5] [PENUMBRA_SCENES=window,panel,roof] tools/blender.sh -b --python benchmarks/penumbra_gap.py

Prints per scene: the mean and p99 relative difference over the fog pixels (those above 5 %
of the p99, away from silhouettes and the light's image), the same over the shadow-edge
pixels alone (neighbours more than 15 % apart in Cycles), Cycles' noise there, and the
bake against the size-0 Cycles render (the hard-shadow truth) for scale.
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
SUN_ANGLE = float(os.environ.get("PENUMBRA_SUN_ANGLE", "5"))  # degrees
SCENES = os.environ.get("PENUMBRA_SCENES", "window,panel,roof").split(",")
SAMPLES = (1, 4, 8, 16, 32, 64)  # shadow_samples: 1 is the hard shadows from the light's centre


def set_size(lamp, on):
    """The lamp's Radius (a sun's Angle) on, or 0."""
    import math
    if lamp.data.type == 'SUN':
        lamp.data.angle = math.radians(SUN_ANGLE) if on else 0.0
    else:
        lamp.data.shadow_soft_size = RADIUS if on else 0.0


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
    from airlight import native, penumbra
    for name, build, depth_fn in (("window", ts._build_window, ts.window_depth),
                                  ("panel", ts._build_panel, ts.panel_depth),
                                  ("roof", ts._build_roof, ts.roof_depth)):
        if name not in SCENES:
            continue
        desc, scene = build()
        lamp = next(o for o in scene.objects if o.type == 'LIGHT')
        st = scene.airlight
        st.density, st.color, st.anisotropy, st.model, st.volumetric_shadows = ts.SIGMA_T, (1, 1, 1), 0.0, 'AUTO', True
        scene.cycles.samples = 1024
        size = f"Angle {SUN_ANGLE:g} deg" if lamp.data.type == 'SUN' else f"r = {RADIUS:g} m"
        renders = {}
        for on in (False, True):
            set_size(lamp, on)
            bpy.context.view_layer.update()
            (c1, c2), _ = cs.render_seeds(scene, ARTIFACTS, f"{name}_{'soft' if on else 'hard'}", (1, 2))
            renders[on] = (0.5 * (c1 + c2)[..., 0], cs.seed_noise(c1, c2))
            description = ts._bake_description({"scene": scene, "name": name})  # (the roof: its fog slab)
            renders[on] += ({k: native.get().bake(**description, threads=2, shadow_samples=k)["airlight"][..., 0]
                             .astype(np.float64) for k in SAMPLES},)
        auto = penumbra.choose(native.get(), description, dict(threads=2, model="sun05"), 0.01)
        print(f"{name} {size}: Automatic at 1 % takes {auto.samples} sample(s) (probe {1000 * auto.seconds:.0f} ms)")
        inputs = cs.bake_inputs(scene)
        eye, d = cs.camera_rays(inputs["cam_to_world"], inputs["projection"], desc.width, desc.height, from_eye=True)
        depth = depth_fn(eye, d)
        C, noise, bakes = renders[True]
        mask = (C > ts.SIGNAL_FLOOR * np.percentile(C, 99)) & ~cs.silhouette_mask(depth, radius=2)
        if lamp.data.type != 'SUN':
            mask &= ~cs.near_light(inputs, desc.width, desc.height, desc.light_location, ts.LIGHT_RADIUS_PX)
        edge = mask & edges(C)
        for label, m in (("fog", mask), ("shadow edges", edge)):
            if not m.any():
                print(f"{name}: no {label} pixels")
                continue
            hard_mean, _ = cs.rel_stats(renders[False][2][1], renders[False][0], m)
            for k, A in bakes.items():
                mean, p99 = cs.rel_stats(A, C, m)
                print(f"{name} {size}, {label} ({int(m.sum())} px), {k} shadow sample(s): bake vs Cycles "
                      f"mean {100 * mean:.2f} % p99 {100 * p99:.1f} % (noise {100 * noise[m].mean():.2f} %); at "
                      f"size 0 the bake vs Cycles mean {100 * hard_mean:.2f} %", flush=True)


main()
