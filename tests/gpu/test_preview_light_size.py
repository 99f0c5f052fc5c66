"""A point light's Radius in the viewport preview: the glow of Cycles' disk light near the
lamp (preview_common.glsl preview_light_size_excess) against the bake's (light_size_airlight,
itself held to Cycles by tests/blender/test_cycles_light_radius.py).

The fog scene's two lamps get Radii of 0.6 and 0.3 m. Over the pixels where the Radius
changes the bake's airlight by more than 1 % the preview is within 1 % mean and 5 % p99 of
the bake (float32 GLSL, 16-node quadrature of the disk against the bake's tables; measured
0.09 % mean), where drawing the lamps as points is several times further off (8.4 %);
elsewhere it stays within 1e-3 mean. test02: radii that are not one finite value >= 0 per
light are refused. test03: a spot's Radius (its cone's profile on the disk's glow, 4 x 8 nodes
a side for the cone's edge): 0.05 % mean where the radius matters (the spot as a point:
16 %)."""

import os

import bpy
import numpy as np

from preview_scenes import compare, render_preview, save_png

RADII = {"LampA": 0.6, "LampB": 0.3}


def _scene_with_radii(scene):
    for name, r in RADII.items():
        scene.objects[name].data.shadow_soft_size = r
    bpy.context.view_layer.update()
    return scene


def test01_preview_takes_the_lamps_radius(addon, native, fog_scene, gs, artifacts):
    from airlight import scene_export
    scene = _scene_with_radii(fog_scene)
    try:
        desc = scene_export.export_scene(scene, bpy.context.evaluated_depsgraph_get())
        assert "light_radii" in desc
        lights = addon.preview_lights(scene, bpy.context.evaluated_depsgraph_get())
        np.testing.assert_allclose(sorted(lights["radii"]), sorted(RADII.values()), rtol=1e-6)
        baked = native.bake(**desc, model="sun05", aa_samples=1, threads=0)
        ref, ref_T = baked["airlight"].astype(np.float64), baked["transmittance"][..., 0].astype(np.float64)
        points = native.bake(**{k: v for k, v in desc.items() if k != "light_radii"}, model="sun05", aa_samples=1,
                             threads=0)["airlight"].astype(np.float64)
        got, got_T = render_preview(addon, gs, scene, desc, None, light_radii=lights["radii"])
        plain, _ = render_preview(addon, gs, scene, desc, None)
    finally:
        for name in RADII:
            scene.objects[name].data.shadow_soft_size = 0.0
    floor = 1e-4 * np.percentile(ref, 99)
    near = (np.abs(ref - points) > 0.01 * ref) & (ref > floor)
    far = ~near & (ref > floor)
    assert near.sum() > 50, near.sum()
    rel = np.abs(got - ref)[near] / ref[near]
    rel_plain = np.abs(plain - ref)[near] / ref[near]
    rel_far = np.abs(got - ref)[far] / ref[far]
    print(f"\npreview with Radius vs bake near the lamps ({int(near.sum())} values): mean {rel.mean():.4g}, "
          f"p99 {np.percentile(rel, 99):.4g}; lamps as points there {rel_plain.mean():.4g}; elsewhere mean "
          f"{rel_far.mean():.4g}")
    scale = 1.0 / np.percentile(ref, 99)
    save_png(os.path.join(artifacts, "preview_light_size.png"), np.clip(got * scale, 0, 1))
    save_png(os.path.join(artifacts, "preview_light_size_bake.png"), np.clip(ref * scale, 0, 1))
    assert np.isfinite(got).all()
    assert rel.mean() <= 0.01 and np.percentile(rel, 99) <= 0.05
    assert rel_plain.mean() > 3.0 * rel.mean()
    assert rel_far.mean() <= 1e-3
    compare("preview with Radius", got, got_T, ref, ref_T)
    assert np.abs(got_T - ref_T).mean() <= 1e-4


def test02_bad_radii_are_refused(addon, fog_scene, gs):
    import pytest
    from airlight import scene_export
    desc = scene_export.export_scene(fog_scene, bpy.context.evaluated_depsgraph_get())
    for radii in ([0.5], [float("nan"), 0.1], [-0.1, 0.1]):
        with pytest.raises(ValueError, match="light_radii"):
            render_preview(addon, gs, fog_scene, desc, None, light_radii=radii)


def test03_spot_radius(addon, native, fog_scene, gs):
    """A spot's Radius: its cone's profile weighs the disk's glow (the bake's spot_radii)."""
    from airlight import scene_export
    scene = fog_scene
    data = bpy.data.lights.new("SizedSpot", 'SPOT')
    data.energy, data.spot_size, data.spot_blend, data.shadow_soft_size = 3000.0, 1.2, 0.3, 0.5
    spot = bpy.data.objects.new("SizedSpot", data)
    spot.location, spot.rotation_euler = (-1.0, 1.0, 3.5), (0.4, -0.3, 0.0)
    scene.collection.objects.link(spot)
    bpy.context.view_layer.update()
    try:
        depsgraph = bpy.context.evaluated_depsgraph_get()
        desc = scene_export.export_scene(scene, depsgraph)
        assert "spot_radii" in desc
        spots = addon.scene_spots(scene, bpy.context.view_layer)
        assert spots["radii"] == [0.5]
        ref = native.bake(**desc, model="sun05", aa_samples=1, threads=0)["airlight"].astype(np.float64)
        points = native.bake(**{k: v for k, v in desc.items() if k != "spot_radii"}, model="sun05", aa_samples=1,
                             threads=0)["airlight"].astype(np.float64)
        got, _ = render_preview(addon, gs, scene, desc, None, spots=spots)
        plain, _ = render_preview(addon, gs, scene, desc, None, spots=dict(spots, radii=[0.0]))
    finally:
        bpy.data.objects.remove(spot)
    floor = 1e-4 * np.percentile(ref, 99)
    near = (np.abs(ref - points) > 0.01 * ref) & (ref > floor)
    assert near.sum() > 20, near.sum()
    rel = np.abs(got - ref)[near] / ref[near]
    rel_plain = np.abs(plain - ref)[near] / ref[near]
    print(f"\nspot with Radius, preview vs bake where the radius matters ({int(near.sum())} values): mean "
          f"{rel.mean():.4g}, p99 {np.percentile(rel, 99):.4g}; the spot as a point there {rel_plain.mean():.4g}")
    assert rel.mean() <= 0.005 and rel_plain.mean() > 4.0 * rel.mean()
