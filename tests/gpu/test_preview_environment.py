"""The World's glow in the viewport preview (Environment Glow, Sun 2005 section 6) against
the bake: where rays meet no surface the preview adds the same native glow map (looked up
in GLSL exactly as the C++ environment_lookup) and lets the World through with
e^(-sigma_t distance), as addon/airlight/environment.apply does to the bake's passes."""

import math
import os

import bpy
import numpy as np
import pytest

from preview_scenes import build_scene, compare, render_preview, save_png


def _sky_world():
    h, w = 32, 64
    v = 1.0 - (np.arange(h) + 0.5) / h
    u = (np.arange(w) + 0.5) / w
    theta = (1.0 - v)[:, None] * math.pi
    phi = (0.5 - u)[None, :] * 2.0 * math.pi
    d = np.stack([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta) + 0 * phi], -1)
    sun = np.exp(6.0 * (d @ np.array([0.0, 0.8, 0.6]) - 1.0))
    sky = 0.3 + 0.2 * np.clip(d[..., 2], 0, 1) + 5.0 * sun
    px = np.ones((h, w, 4), dtype=np.float32)
    px[..., :3] = sky[..., None] * np.array([1.0, 0.9, 0.8])
    image = bpy.data.images.new("PreviewSky", w, h, float_buffer=True)
    image.pixels.foreach_set(px[::-1].ravel())
    world = bpy.data.worlds.new("PreviewSky")
    world.use_nodes = True
    tex = world.node_tree.nodes.new('ShaderNodeTexEnvironment')
    tex.image = image
    world.node_tree.links.new(tex.outputs['Color'], world.node_tree.nodes['Background'].inputs['Color'])
    return world


@pytest.mark.parametrize("scale", [1, 2])
def test01_preview_world_glow_matches_bake(addon, native, gs, artifacts, scale):
    from airlight import environment, scene_export
    scene = build_scene(0.03)
    scene.world = _sky_world()
    scene.airlight.environment_glow = True
    scene.airlight.environment_distance = 40.0
    try:
        desc = scene_export.export_scene(scene, bpy.context.evaluated_depsgraph_get())
        baked = native.bake(**desc, model="sun05", aa_samples=1, threads=0)
        plain = baked["airlight"].copy()
        environment.apply(native, environment.prepare(scene), desc, baked)
        ref = baked["airlight"].astype(np.float64)
        ref_T = baked["transmittance"].astype(np.float64)[..., 0]
        miss = ~np.isfinite(baked["depth"])
        assert 50 < miss.sum() < miss.size - 50, miss.sum()
        env = addon.scene_environment(scene)
        assert env is not None and abs(env["transmittance"] / math.exp(-0.03 * 40.0) - 1.0) < 1e-6
        got, got_T = render_preview(addon, gs, scene, desc, None, environment=env, scale=scale)
        rel, dT = compare(f"preview vs bake with the World's glow (scale {scale})", got, got_T, ref, ref_T)
        glow_share = float(((ref - plain)[miss]).mean() / ref[miss].mean())
        print(f"the glow is {glow_share:.3g} of the World pixels' airlight")
        sc = 1.0 / np.percentile(ref, 99)
        save_png(os.path.join(artifacts, f"preview_env_gpu_{scale}.png"), np.clip(got * sc, 0, 1))
        save_png(os.path.join(artifacts, f"preview_env_bake_{scale}.png"), np.clip(ref * sc, 0, 1))
        assert glow_share > 0.2
        np.testing.assert_allclose(got_T[miss], math.exp(-1.2), rtol=1e-5)
        if scale == 1:
            assert rel.mean() <= 2e-3 and dT.mean() <= 1e-4
        else:
            assert rel.mean() <= 2e-2 and dT.mean() <= 1e-3
        # Off: the World pixels are fully fogged again (T = 0), no glow.
        scene.airlight.environment_glow = False
        assert addon.scene_environment(scene) is None
    finally:
        scene.airlight.environment_glow = False
        scene.world = None
