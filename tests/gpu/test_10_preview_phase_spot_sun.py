"""Anisotropic phase, spot lights and sun lamps in the viewport preview.

- test01: biri06_airlight.glsl (the Biri 2006 table of `_native.biri06_table`, the very
  table the bake uses) vs `_native.biri06_airlight` on the same float32 inputs, g = 0.6.
- test02: the preview with Henyey-Greenstein g = 0.6 vs `_native.bake(model="biri06")` of
  the same view (figures printed; images under out/test_artifacts/).
- test03: spot lights (spot_airlight.glsl: fixed Gauss-Legendre panels over the analytic
  cone interval) vs the bake's adaptive quadrature, isotropic and g = 0.6.
"""

import os

import bpy
import gpu
import numpy as np
import pytest

from conftest import draw_fullscreen
from test_09_preview_gaussians import (ALBEDO, H, W, _compare, _save_png, build_scene,
                                       render_preview)

N = 64
G = 0.6


@pytest.fixture(scope="module")
def addon():
    import airlight
    if not hasattr(bpy.types.Scene, "airlight"):
        airlight.register()
    from airlight import preview
    return preview


@pytest.mark.parametrize("phase,g", [("hg", G), ("hg", -0.5), ("rayleigh", 0.0), ("murky_mie", 0.0)])
def test01_biri_glsl_matches_cpp(gs, native, phase, g):
    rng = np.random.default_rng(10)
    n = N * N
    sigma_t = 10.0 ** rng.uniform(-3.0, 0.3, n)
    Dsv = 10.0 ** rng.uniform(-1.0, 1.7, n)
    cos_gamma = rng.uniform(-1.0, 1.0, n)
    Dvp = 10.0 ** rng.uniform(-1.0, 2.0, n)
    Dvp[rng.uniform(0, 1, n) < 0.1] = np.inf
    q = np.stack([sigma_t, Dsv, cos_gamma, Dvp], -1).astype(np.float32)
    x = q.astype(np.float64)
    ref = native.biri06_airlight(x[:, 0], x[:, 1], x[:, 2], x[:, 3], phase=phase, g=g)
    exact = native.biri06_airlight(x[:, 0], x[:, 1], x[:, 2], x[:, 3], phase=phase, g=g, exact=True)
    table = native.biri06_table(phase, g)
    kinds = {"isotropic": 0, "hg": 1, "rayleigh": 2, "hazy_mie": 3, "murky_mie": 4}
    shader = gs.create_biri_test_shader()
    batch = gs.fullscreen_batch(shader)
    in0 = gs.float_texture(q.reshape(N, N, 4))
    gtab = gs.float_texture(table["data"])
    phase_vec = (float(kinds[table["phase"]]), float(table["g"]), float(table["K"]), float(table["k"]))
    off = gpu.types.GPUOffScreen(N, N, format='RGBA32F')
    try:
        with off.bind():
            fb = gpu.state.active_framebuffer_get()
            fb.clear(color=(0.0, 0.0, 0.0, 0.0))
            shader.bind()
            shader.uniform_sampler("in0", in0)
            shader.uniform_sampler("Gtab", gtab)
            shader.uniform_float("phase", phase_vec)
            batch.draw(shader)
        got = gs.read_offscreen(off).reshape(n, 4)[:, 0].astype(np.float64)
    finally:
        off.free()
    floor = 1e-6 * np.max(ref)
    use = ref > floor
    rel = np.abs(got[use] - ref[use]) / ref[use]
    rel_x = np.abs(got[use] - exact[use]) / exact[use]
    print(f"\nbiri06 GLSL vs C++ table path ({phase}, g={g}): mean {rel.mean():.3g} "
          f"p99 {np.percentile(rel, 99):.3g} max {rel.max():.3g}; vs exact: mean "
          f"{rel_x.mean():.3g} p99 {np.percentile(rel_x, 99):.3g} max {rel_x.max():.3g}")
    assert np.isfinite(got).all()
    # Measured: mean <= 5e-5, p99 <= 1.1e-3, max <= 3e-3 (the fallback's fixed panels
    # vs the C++'s adaptive quadrature where the table difference would cancel).
    assert rel.mean() < 2e-4
    assert np.percentile(rel, 99) < 3e-3
    assert rel.max() < 1e-2


def test02_preview_hg_matches_bake(addon, native, gs, artifacts):
    from airlight import scene_export
    scene = build_scene(0.08)
    scene.airlight.phase = 'HENYEY_GREENSTEIN'
    scene.airlight.anisotropy = G
    try:
        desc = scene_export.export_scene(scene, bpy.context.evaluated_depsgraph_get())
        assert desc["phase"] == "hg" and abs(desc["g"] - G) < 1e-6
        baked = native.bake(**desc, model="biri06", aa_samples=1, threads=0)
        ref = baked["airlight"].astype(np.float64)
        ref_T = baked["transmittance"].astype(np.float64)[..., 0]
        got, got_T = render_preview(addon, gs, scene, desc, None, phase=(desc["phase"], desc["g"]))
        rel, dT = _compare(f"preview vs bake, HG g = {G} (biri06)", got, got_T, ref, ref_T)
        iso = native.bake(**dict(desc, phase="isotropic", g=0.0), model="sun05", aa_samples=1,
                          threads=0)["airlight"]
        change = np.abs(iso - ref).mean() / ref.mean()
        print(f"g = {G} changes the bake's airlight by {change:.3g} (mean abs / mean)")
        scale = 1.0 / np.percentile(ref, 99)
        _save_png(os.path.join(artifacts, "preview_hg_gpu.png"), np.clip(got * scale, 0, 1))
        _save_png(os.path.join(artifacts, "preview_hg_bake.png"), np.clip(ref * scale, 0, 1))
        assert change > 0.1
        assert rel.mean() <= 2e-3
        assert np.percentile(rel, 99) <= 2e-2
        assert dT.mean() <= 1e-4
    finally:
        scene.airlight.anisotropy = 0.0


def _add_spot(scene, name, location, target, size, blend, energy, colour):
    from mathutils import Vector
    data = bpy.data.lights.new(name, 'SPOT')
    data.energy = energy
    data.color = colour
    data.spot_size = size
    data.spot_blend = blend
    data.shadow_soft_size = 0.0
    obj = bpy.data.objects.new(name, data)
    obj.location = location
    direction = Vector(target) - Vector(location)
    obj.rotation_euler = direction.to_track_quat('-Z', 'Y').to_euler()
    scene.collection.objects.link(obj)
    return obj


@pytest.mark.parametrize("g", [0.0, G])
def test03_preview_spots_match_bake(addon, native, gs, artifacts, g):
    """Two spots (soft 60 deg, hard 100 deg), the point lights left out of the fog: the
    preview's fixed quadrature over the cone interval vs the bake's adaptive quadrature
    (<= 2 % mean asked; figures printed)."""
    import math
    from airlight import scene_export
    scene = build_scene(0.08)
    scene.airlight.phase = 'HENYEY_GREENSTEIN'
    scene.airlight.anisotropy = g
    spots = [_add_spot(scene, "SpotSoft", (3.0, -2.0, 5.0), (0.0, 1.0, 0.0), math.radians(60), 0.3,
                       3000.0, (1.0, 0.9, 0.7)),
             _add_spot(scene, "SpotHard", (-3.0, 2.0, 4.0), (-1.0, 0.0, 0.0), math.radians(100), 0.0,
                       1500.0, (0.6, 0.8, 1.0))]
    for obj in [o for o in scene.objects if o.type == 'LIGHT' and o.data.type == 'POINT']:
        bpy.data.objects.remove(obj)  # (build_scene makes them again for the next test)
    bpy.context.view_layer.update()
    try:
        desc = scene_export.export_scene(scene, bpy.context.evaluated_depsgraph_get())
        assert len(desc["spot_positions"]) == 2
        model = "sun05" if g == 0.0 else "biri06"
        baked = native.bake(**desc, model=model, aa_samples=1, threads=0)
        ref = baked["airlight"].astype(np.float64)
        ref_T = baked["transmittance"].astype(np.float64)[..., 0]
        spot_dict = addon.scene_spots(scene, bpy.context.view_layer)
        got, got_T = render_preview(addon, gs, scene, desc, None, phase=(desc["phase"], desc["g"]),
                                    spots=spot_dict)
        rel, dT = _compare(f"preview vs bake, 2 spots only (g = {g})", got, got_T, ref, ref_T)
        lit = (ref > 1e-3 * ref.max()).mean()
        print(f"pixels with spot fog above 1e-3 of the max: {lit:.3g}")
        scale = 1.0 / np.percentile(ref, 99)
        _save_png(os.path.join(artifacts, f"preview_spots_g{g}_gpu.png"), np.clip(got * scale, 0, 1))
        _save_png(os.path.join(artifacts, f"preview_spots_g{g}_bake.png"), np.clip(ref * scale, 0, 1))
        assert len(desc["light_positions"]) == 0
        assert lit > 0.2
        # Asked: <= 2 %; measured 1e-4 mean, 4e-4 p99 (max: hit/miss pixels on a cone edge).
        assert rel.mean() <= 2e-3
        assert np.percentile(rel, 99) <= 1e-2
        assert dT.mean() <= 1e-4
    finally:
        for obj in spots:
            bpy.data.objects.remove(obj)
        scene.airlight.anisotropy = 0.0
