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
from preview_scenes import build_scene, compare, render_preview, save_png

N = 64
G = 0.6


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
        rel, dT = compare(f"preview vs bake, HG g = {G} (biri06)", got, got_T, ref, ref_T)
        iso = native.bake(**dict(desc, phase="isotropic", g=0.0), model="sun05", aa_samples=1,
                          threads=0)["airlight"]
        change = np.abs(iso - ref).mean() / ref.mean()
        print(f"g = {G} changes the bake's airlight by {change:.3g} (mean abs / mean)")
        scale = 1.0 / np.percentile(ref, 99)
        save_png(os.path.join(artifacts, "preview_hg_gpu.png"), np.clip(got * scale, 0, 1))
        save_png(os.path.join(artifacts, "preview_hg_bake.png"), np.clip(ref * scale, 0, 1))
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
        rel, dT = compare(f"preview vs bake, 2 spots only (g = {g})", got, got_T, ref, ref_T)
        lit = (ref > 1e-3 * ref.max()).mean()
        print(f"pixels with spot fog above 1e-3 of the max: {lit:.3g}")
        scale = 1.0 / np.percentile(ref, 99)
        save_png(os.path.join(artifacts, f"preview_spots_g{g}_gpu.png"), np.clip(got * scale, 0, 1))
        save_png(os.path.join(artifacts, f"preview_spots_g{g}_bake.png"), np.clip(ref * scale, 0, 1))
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


def test03b_preview_area_spread_matches_bake(addon, native, gs, artifacts):
    """Area lights with a Spread below 180 degrees (a 1 m disk at 40, a 2 x 0.5 m rectangle
    at 120): their samples' soft-box profile (spot_cone's constants in the spot texture's
    row 3) in the preview's fixed quadrature vs the bake's adaptive one."""
    import math
    from mathutils import Vector
    from airlight import scene_export
    scene = build_scene(0.08)
    lights = []
    for name, shape, size, size_y, spread, location, target in (
            ("Softbox", 'DISK', 1.0, 1.0, 40.0, (3.0, -2.0, 5.0), (0.0, 1.0, 0.0)),
            ("Panel", 'RECTANGLE', 2.0, 0.5, 120.0, (-3.0, 2.0, 4.0), (-1.0, 0.0, 0.0))):
        data = bpy.data.lights.new(name, 'AREA')
        data.shape, data.size, data.size_y, data.spread = shape, size, size_y, math.radians(spread)
        data.energy = 2000.0
        obj = bpy.data.objects.new(name, data)
        obj.location = location
        obj.rotation_euler = (Vector(target) - Vector(location)).to_track_quat('-Z', 'Y').to_euler()
        scene.collection.objects.link(obj)
        lights.append(obj)
    for obj in [o for o in scene.objects if o.type == 'LIGHT' and o.data.type == 'POINT']:
        bpy.data.objects.remove(obj)  # (build_scene makes them again for the next test)
    bpy.context.view_layer.update()
    try:
        desc = scene_export.export_scene(scene, bpy.context.evaluated_depsgraph_get())
        assert (desc["spot_spread"] < math.pi).all() and len(desc["spot_spread"]) <= 256   # (MAX_LIGHTS)
        baked = native.bake(**desc, aa_samples=1, threads=0)
        ref = baked["airlight"].astype(np.float64)
        ref_T = baked["transmittance"].astype(np.float64)[..., 0]
        spot_dict = addon.scene_spots(scene, bpy.context.view_layer)
        assert len(spot_dict["spreads"]) == len(desc["spot_spread"])
        got, got_T = render_preview(addon, gs, scene, desc, None, spots=spot_dict)
        rel, dT = compare("preview vs bake, 2 area lights with a Spread", got, got_T, ref, ref_T)
        lit = (ref > 1e-3 * ref.max()).mean()
        print(f"pixels with fog above 1e-3 of the max: {lit:.3g}")
        scale = 1.0 / np.percentile(ref, 99)
        save_png(os.path.join(artifacts, "preview_area_spread_gpu.png"), np.clip(got * scale, 0, 1))
        save_png(os.path.join(artifacts, "preview_area_spread_bake.png"), np.clip(ref * scale, 0, 1))
        assert lit > 0.1
        assert rel.mean() <= 2e-3
        assert np.percentile(rel, 99) <= 1e-2
        assert dT.mean() <= 1e-4
    finally:
        for obj in lights:
            bpy.data.objects.remove(obj)


# ---- sun lamps -----------------------------------------------------------------------------

def _sun_factor_quadrature(sigma, h_top, mu_s, o_z, d_z, t0, t1, n=20000):
    """G by Gauss-Legendre panels written from the geometry (view optical depth: sigma
    times the length of [t0, t] inside the fog z <= h_top; sun optical depth sigma (h_top -
    z) / mu_s), split where the ray crosses the top (the integrand's kink), finite t1."""
    cuts = [t0, t1]
    if d_z != 0.0:
        t_top = (h_top - o_z) / d_z
        if t0 < t_top < t1:
            cuts = [t0, t_top, t1]
    x, w = np.polynomial.legendre.leggauss(16)

    def view_depth(t):
        if d_z == 0.0:
            return sigma * (t - t0) * (o_z <= h_top)
        t_top = (h_top - o_z) / d_z
        lo = t0 if d_z > 0.0 else np.maximum(t0, t_top)
        hi = np.minimum(t, t_top) if d_z > 0.0 else t
        return sigma * np.maximum(0.0, hi - lo)

    total = 0.0
    for a, b in zip(cuts[:-1], cuts[1:]):
        edges = np.linspace(a, b, 65)
        for lo, hi in zip(edges[:-1], edges[1:]):
            t = 0.5 * (lo + hi) + 0.5 * (hi - lo) * x
            z = o_z + t * d_z
            f = np.where(z <= h_top, np.exp(-view_depth(t) - sigma * np.maximum(h_top - z, 0.0) / mu_s), 0.0)
            total += 0.5 * (hi - lo) * np.sum(w * f)
    return float(total)


def test04_sun_glsl_matches_references(gs, native):
    """sun_layer_factor (GLSL) vs Hoffman-Preetham (`_native.hoffman02`, h_top = inf) and
    vs a quadrature of the layered integrand (finite top)."""
    rng = np.random.default_rng(4)
    n = 32 * 32
    sigma = 10.0 ** rng.uniform(-3.0, 0.0, n)
    mu_s = rng.uniform(0.05, 1.0, n)
    o_z = rng.uniform(-5.0, 15.0, n)
    d_z = rng.uniform(-1.0, 1.0, n)
    t0 = rng.uniform(0.0, 1.0, n)
    t1 = t0 + 10.0 ** rng.uniform(-1.0, 2.0, n)
    h_top = np.where(np.arange(n) < n // 2, np.inf, 10.0)
    in0 = np.stack([sigma, h_top, mu_s, o_z], -1).astype(np.float32).reshape(32, 32, 4)
    in1 = np.stack([d_z, t0, t1, np.zeros(n)], -1).astype(np.float32).reshape(32, 32, 4)
    shader = gs.create_sun_test_shader()
    batch = gs.fullscreen_batch(shader)
    t_in0, t_in1 = gs.float_texture(in0), gs.float_texture(in1)
    off = gpu.types.GPUOffScreen(32, 32, format='RGBA32F')
    try:
        draw_fullscreen(off, shader, batch, samplers=[("in0", t_in0), ("in1", t_in1)])
        got = gs.read_offscreen(off).reshape(n, 4)[:, 0].astype(np.float64)
    finally:
        off.free()
    x0, x1 = in0.reshape(n, 4).astype(np.float64), in1.reshape(n, 4).astype(np.float64)
    ref = np.empty(n)
    for j in range(n):
        s, top, mu, oz = x0[j]
        dz, a, b = x1[j, :3]
        if np.isinf(top):
            # Hoffman-Preetham with beta_R = 0, beta_M = sigma, g = 0: L_in = E (1 - e^{-sigma L})
            # / (4 pi) per unit E, so G = 4 pi L_in / sigma.
            L_in = native.hoffman02(1.0, b - a, (0.0, 0.0, 0.0), (s, s, s), g=0.0)["L_in"][0]
            ref[j] = 4.0 * np.pi * L_in / s
        else:
            ref[j] = _sun_factor_quadrature(s, top, mu, oz, dz, a, b)
    hp = np.isinf(x0[:, 1])
    use = ref > 1e-6 * ref.max()
    rel = np.abs(got[use] - ref[use]) / ref[use]
    rel_hp = rel[hp[use]]
    rel_top = rel[~hp[use]]
    print(f"\nsun_layer_factor GLSL vs hoffman02 (no top): mean {rel_hp.mean():.3g} max {rel_hp.max():.3g}; "
          f"vs quadrature (top at 10 m): mean {rel_top.mean():.3g} max {rel_top.max():.3g}")
    assert np.isfinite(got).all()
    # float32 GLSL vs double: measured mean ~6e-6, max ~4e-4 (compensated expm1 in float).
    assert rel_hp.mean() < 1e-4 and rel_hp.max() < 2e-3
    assert rel_top.mean() < 1e-4 and rel_top.max() < 2e-3


@pytest.mark.parametrize("fog_top", [np.inf, 3.0])
def test05_preview_sun_matches_bake(addon, native, gs, artifacts, fog_top):
    """A sun lamp (point lights removed) vs `_native.bake(sun_directions=...)`; a bake
    without sun lamps (a TypeError on the keyword) fails the test."""
    from mathutils import Vector
    scene = build_scene(0.05)
    for obj in [o for o in scene.objects if o.type == 'LIGHT']:
        bpy.data.objects.remove(obj)
    data = bpy.data.lights.new("Sun", 'SUN')
    data.energy = 3.0
    data.color = (1.0, 0.9, 0.8)
    sun = bpy.data.objects.new("Sun", data)
    sun.rotation_euler = Vector((0.5, 1.0, -0.8)).to_track_quat('-Z', 'Y').to_euler()
    scene.collection.objects.link(sun)
    bpy.context.view_layer.update()
    from airlight import scene_export
    try:
        desc = scene_export.export_scene(scene, bpy.context.evaluated_depsgraph_get())
        suns = addon.scene_suns(scene, bpy.context.view_layer)
        suns["fog_top"] = float(fog_top)
        assert len(suns["directions"]) == 1
        w = np.array(suns["directions"])
        E = np.array([[c * data.energy for c in data.color]])
        kwargs = {k: v for k, v in desc.items() if not k.startswith("sun_") and k != "fog_top"}
        baked = native.bake(**kwargs, sun_directions=w, sun_irradiances=E, fog_top=float(fog_top),
                            model="sun05", aa_samples=1, threads=0)
        ref = baked["airlight"].astype(np.float64)
        ref_T = baked["transmittance"].astype(np.float64)[..., 0]
        got, got_T = render_preview(addon, gs, scene, desc, None, suns=suns)
        rel, dT = compare(f"preview vs bake, sun lamp (fog top {fog_top})", got, got_T, ref, ref_T)
        assert rel.mean() <= 1e-3
        assert dT.mean() <= 1e-4
    finally:
        bpy.data.objects.remove(sun)
