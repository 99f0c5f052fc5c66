"""Gaussian fog (fog objects) in the viewport preview (preview_gaussians.py,
shaders/rbf_*.glsl).

- test01: GLSL vs C++ on the same float32 inputs: rbf_erf_diff vs `_native.erf_diff`,
  rbf_erf vs math.erf, the Gaussian line integral vs `RbfMedium.optical_depth(culled=False)`
  and Fogshop's per-Gaussian L_i (eq. 11) vs `RbfMedium.airlight(model="fogshop")` of a
  one-Gaussian medium with beta0 = 0 (so f1 = 1 and the homogeneous term is 0).
- test02: the preview (`preview.draw_fog` with Gaussians: splat pass + composite) vs
  `_native.bake` of the same view, Gaussians, lights and clip range at full resolution
  (model "sun05": the same Fogshop approximation): mean relative difference of the
  airlight <= 5 % (the figure is printed), transmittance likewise. One broad Gaussian
  holds the camera (the full-screen splat path). Both ways of drawing the Gaussian sums
  (preview.GAUSS_PASSES: TILES, the full-screen loop over per-tile lists, and SPLAT, one
  blended quad per Gaussian). Images are saved under out/test_artifacts/ (or
  $AIRLIGHT_TEST_ARTIFACTS).
- test04: the same at HALF / QUARTER / EIGHTH (splat targets at 1/2, 1/4, 1/8).
- test06: Gaussians with their own colours (fog objects' "airlight_color", the bake's
  rbf_albedo) vs the bake at FULL, both passes; the colours change the image.
- test07: the tile lists hold every Gaussian whose cull sphere a texel's ray meets
  (brute force over texels x Gaussians), and TILES equals SPLAT image for image.
- test08: the draw handler with a coloured fog object.
"""

import math
import os

import bpy
import gpu
import numpy as np
import pytest
from mathutils import Matrix

from conftest import draw_fullscreen
from preview_scenes import GAUSS_SIGMA_T as SIGMA_T, H, W, build_scene, compare, random_gaussians, render_preview, save_png

N = 48  # N x N input points in the agreement test


def _texture(gs, q):
    return gs.float_texture(np.ascontiguousarray(q, np.float32))


def test01_glsl_matches_cpp(gs, native):
    rng = np.random.default_rng(9)
    n = N * N
    # erf_diff arguments: both signs, straddling, short intervals, far tails, +inf.
    x1 = rng.uniform(-6.0, 6.0, n)
    x2 = x1 + 10.0 ** rng.uniform(-4.0, 1.0, n)
    x2[rng.uniform(0, 1, n) < 0.05] = np.inf
    # Gaussians and rays: centre near the ray, distance and scale over a few decades.
    a = 10.0 ** rng.uniform(-1.0, 0.7, n)
    c = 10.0 ** rng.uniform(-2.0, 0.5, n)
    o = rng.uniform(-5.0, 5.0, (n, 3))
    r = rng.normal(size=(n, 3))
    r /= np.linalg.norm(r, axis=1, keepdims=True)
    t_centre = rng.uniform(-2.0, 20.0, n)
    perp = rng.normal(size=(n, 3))
    perp -= (perp * r).sum(1, keepdims=True) * r
    perp /= np.linalg.norm(perp, axis=1, keepdims=True)
    b = o + t_centre[:, None] * r + (rng.uniform(0.0, 2.0, n) / a)[:, None] * perp
    D = 10.0 ** rng.uniform(-0.5, 1.6, n)
    s = b + rng.normal(size=(n, 3)) * rng.uniform(0.5, 6.0, n)[:, None]
    inputs = [np.stack([x1, x2, D, np.ones(n)], -1), np.concatenate([b, a[:, None]], -1),
              np.concatenate([o, c[:, None]], -1), np.concatenate([r, np.zeros((n, 1))], -1),
              np.concatenate([s, np.zeros((n, 1))], -1)]
    inputs = [q.astype(np.float32).reshape(N, N, 4) for q in inputs]
    # The C++ runs on the float32-rounded inputs (directions renormalised in double).
    q0, q1, q2, q3, q4 = (q.reshape(n, 4).astype(np.float64) for q in inputs)
    x1, x2, D = q0[:, 0], q0[:, 1], q0[:, 2]
    b, a, o, c, s = q1[:, :3], q1[:, 3], q2[:, :3], q2[:, 3], q4[:, :3]
    r = q3[:, :3] / np.linalg.norm(q3[:, :3], axis=1, keepdims=True)

    shader = gs.create_rbf_test_shader()
    batch = gs.fullscreen_batch(shader)
    textures = [_texture(gs, q) for q in inputs]
    off = gpu.types.GPUOffScreen(N, N, format='RGBA32F')
    try:
        draw_fullscreen(off, shader, batch,
                        samplers=[(f"in{k}", t) for k, t in enumerate(textures)])
        got = gs.read_offscreen(off).reshape(n, 4).astype(np.float64)
    finally:
        off.free()

    ref_diff = native.erf_diff(x1, x2)
    ref_erf = np.array([math.erf(v) for v in x1])
    ref_T = np.empty(n)
    ref_L = np.empty(n)
    for j in range(n):
        medium = native.RbfMedium(b[j:j + 1], a[j:j + 1], c[j:j + 1], beta0=0.0)
        ref_T[j] = medium.optical_depth(o[j:j + 1], (o[j] + D[j] * r[j])[None], culled=False)[0]
        ref_L[j] = medium.airlight(s[j], o[j], r[j:j + 1], D[j:j + 1], model="fogshop")[0]

    def stats(name, got_v, ref_v, floor_fraction):
        floor = floor_fraction * np.max(np.abs(ref_v))
        use = np.abs(ref_v) > floor
        rel = np.abs(got_v[use] - ref_v[use]) / np.abs(ref_v[use])
        absd = np.abs(got_v - ref_v)
        print(f"\n{name}: {use.sum()} points, rel mean {rel.mean():.3g} p99 "
              f"{np.percentile(rel, 99):.3g} max {rel.max():.3g}; abs max {absd.max():.3g}")
        return rel, absd

    rel_d, abs_d = stats("rbf_erf_diff vs erf_diff", got[:, 0], ref_diff, 1e-30)
    rel_e, abs_e = stats("rbf_erf vs math.erf", got[:, 1], ref_erf, 1e-30)
    rel_T, _ = stats("line integral vs RbfMedium.optical_depth", got[:, 2], ref_T, 1e-6)
    # L_i: the C++ culls Gaussians whose line integral is below 1e-7; compare above a floor.
    rel_L, _ = stats("Fogshop L_i vs RbfMedium.airlight", got[:, 3], ref_L, 1e-5)
    assert np.isfinite(got).all()
    assert abs_e.max() < 3e-7            # erf: absolute error (float32 + the fit)
    # Measured: p99 5e-6 / max 8e-6 (erf_diff), 3e-6 / 9e-6 (T_i and L_i).
    assert np.percentile(rel_d, 99) < 2e-5 and rel_d.max() < 1e-4
    assert np.percentile(rel_T, 99) < 2e-5 and rel_T.max() < 1e-4
    assert np.percentile(rel_L, 99) < 2e-5 and rel_L.max() < 1e-4


def test09_fast_erf_diff_within_the_bakes_bound(gs, native):
    """rbf_fast_erf_diff (what rbf_splat_pixel.glsl evaluates, the bake's fast_erf_diff)
    vs the double erf_diff, within fast_erf.h's stated bound:
    |fast - exact| <= 1e-5 exact + (4e-6 + 2.4e-7 m^2) max(erfc|x1|, erfc|x2|) + 1e-37."""
    rng = np.random.default_rng(19)
    n = N * N
    x1 = rng.uniform(-9.0, 9.0, n)
    x2 = x1 + 10.0 ** rng.uniform(-4.0, 1.2, n)
    x2[rng.uniform(0, 1, n) < 0.05] = np.inf
    q = np.zeros((n, 4), np.float32)
    q[:, 0], q[:, 1] = x1, x2
    x1, x2 = q[:, 0].astype(np.float64), q[:, 1].astype(np.float64)
    shader = gs.create_rbf_fast_test_shader()
    batch = gs.fullscreen_batch(shader)
    tex = gs.float_texture(q.reshape(N, N, 4))
    off = gpu.types.GPUOffScreen(N, N, format='RGBA32F')
    try:
        draw_fullscreen(off, shader, batch, samplers=[("in0", tex)])
        got = gs.read_offscreen(off).reshape(n, 4)[:, 0].astype(np.float64)
    finally:
        off.free()
    exact = native.erf_diff(x1, x2)
    m = np.where(np.isinf(x2), np.abs(x1), np.maximum(np.abs(x1), np.abs(x2)))
    erfc_max = np.maximum([math.erfc(abs(v)) for v in x1], [math.erfc(abs(v)) for v in x2])
    bound = 1e-5 * np.abs(exact) + (4e-6 + 2.4e-7 * m ** 2) * erfc_max + 1e-37
    ratio = np.abs(got - exact) / bound
    print(f"\nrbf_fast_erf_diff vs erf_diff: {n} points, error / fast_erf.h's bound: "
          f"median {np.median(ratio):.3g}, max {ratio.max():.3g}")
    assert np.isfinite(got).all()
    assert ratio.max() <= 1.0


# ---- preview vs bake -------------------------------------------------------------------

@pytest.fixture(scope="module")
def gauss_scene(addon, native):
    return build_scene(SIGMA_T)


@pytest.mark.parametrize("gauss_pass", ["TILES", "SPLAT"])
def test02_preview_matches_bake(addon, native, gs, gauss_scene, artifacts, gauss_pass):
    from airlight import scene_export
    scene = gauss_scene
    depsgraph = bpy.context.evaluated_depsgraph_get()
    desc = scene_export.export_scene(scene, depsgraph)
    centres, scales, amplitudes = random_gaussians(tuple(scene.camera.matrix_world.translation))
    baked = native.bake(**desc, rbf_centres=centres, rbf_scales=scales,
                        rbf_amplitudes=amplitudes, model="sun05", aa_samples=1, threads=0)
    ref = baked["airlight"].astype(np.float64)
    ref_T = baked["transmittance"].astype(np.float64)[..., 0]
    gaussians = dict(centres=centres, scales=scales, amplitudes=amplitudes, key="test09")
    got, got_T = render_preview(addon, gs, scene, desc, gaussians, gauss_pass=gauss_pass)
    rel, dT = compare(f"Gaussian preview ({gauss_pass}) vs bake ({W}x{H}, {len(scales)} Gaussians, "
                       "2 lights)", got, got_T, ref, ref_T)
    # Without the Gaussians the same scene is much darker / clearer: the test sees them.
    plain = native.bake(**desc, model="sun05", aa_samples=1, threads=0)
    change = np.abs(plain["airlight"] - ref).mean() / ref.mean()
    print(f"Gaussians change the bake's airlight by {change:.3g} (mean abs / mean)")

    scale = 1.0 / np.percentile(ref, 99)
    tag = "" if gauss_pass == "TILES" else "_splat"
    save_png(os.path.join(artifacts, f"preview_gauss_gpu{tag}.png"), np.clip(got * scale, 0, 1))
    save_png(os.path.join(artifacts, "preview_gauss_bake.png"), np.clip(ref * scale, 0, 1))
    native.write_exr(os.path.join(artifacts, f"preview_gauss_vs_bake{tag}.exr"),
                     {"preview": got.astype(np.float32), "bake": ref.astype(np.float32),
                      "preview_T": np.repeat(got_T[..., None], 3, -1).astype(np.float32),
                      "bake_T": np.repeat(ref_T[..., None], 3, -1).astype(np.float32)})
    assert np.isfinite(got).all() and np.isfinite(got_T).all()
    assert change > 0.2
    # The issue asks for <= 5 % mean; the same approximation in float32 gives ~2e-5 (a
    # few silhouette pixels differ by hit/miss), so hold it much tighter.
    assert rel.mean() <= 1e-3
    assert np.percentile(rel, 99) <= 1e-2
    assert dT.mean() <= 1e-4


@pytest.mark.parametrize("gauss_pass", ["TILES", "SPLAT"])
@pytest.mark.parametrize("scale", [2, 4, 8])
def test04_reduced_scale_splat(addon, native, gs, gauss_scene, scale, gauss_pass):
    """HALF / QUARTER / EIGHTH: the Gaussians are splatted at 1/scale and upsampled
    depth-aware in the full-resolution fog pass; vs the bake (figures printed)."""
    from airlight import scene_export
    scene = gauss_scene
    desc = scene_export.export_scene(scene, bpy.context.evaluated_depsgraph_get())
    centres, scales, amplitudes = random_gaussians(tuple(scene.camera.matrix_world.translation))
    baked = native.bake(**desc, rbf_centres=centres, rbf_scales=scales,
                        rbf_amplitudes=amplitudes, model="sun05", aa_samples=1, threads=0)
    ref = baked["airlight"].astype(np.float64)
    ref_T = baked["transmittance"].astype(np.float64)[..., 0]
    gaussians = dict(centres=centres, scales=scales, amplitudes=amplitudes, key="test09")
    got, got_T = render_preview(addon, gs, scene, desc, gaussians, scale=scale, gauss_pass=gauss_pass)
    rel, dT = compare(f"Gaussian preview ({gauss_pass}) at 1/{scale} vs bake", got, got_T, ref, ref_T)
    assert np.isfinite(got).all()
    # EIGHTH is 20 x 15 texels here (measured 3.9e-2, 5.7e-3): held to the 5 %.
    assert rel.mean() <= (0.05 if scale == 8 else 0.02)
    assert dT.mean() <= (1e-2 if scale == 8 else 2e-3)


# ---- the draw handler with a fog object ----------------------------------------------------

def _redraw():
    window = bpy.context.window_manager.windows[0]
    with bpy.context.temp_override(window=window, screen=window.screen):
        bpy.ops.wm.redraw_timer(type='DRAW_WIN_SWAP', iterations=1)


def test03_handler_draws_fog_objects_and_follows_edits(addon, gauss_scene):
    """A fog object in the scene reaches the handler's draw (the same gather as the
    bake), the draw succeeds, and removing the object reaches the next draw (the
    cached Gaussians belong to one depsgraph generation)."""
    from airlight import fog_object
    scene = gauss_scene
    centres, scales, amplitudes = random_gaussians(tuple(scene.camera.matrix_world.translation))
    obj = fog_object.new_fog_object("PreviewFog", scene.collection, centres, scales, amplitudes)
    bpy.context.view_layer.update()
    wm = bpy.context.window_manager
    addon._state["error"] = None
    wm.airlight_preview = True
    for area in wm.windows[0].screen.areas:
        if area.type == 'VIEW_3D':
            area.spaces.active.region_3d.view_perspective = 'CAMERA'
    try:
        addon._state["capture"] = cap = {}
        _redraw()
        assert addon._state["error"] is None, addon._state["error"]
        assert len(cap["gaussians"]["scales"]) == len(scales)
        np.testing.assert_allclose(cap["gaussians"]["centres"], centres, rtol=0, atol=1e-5)
        fog = addon._state["gpu"]["gaussian_fog"]
        print(f"\nhandler with {len(scales)} Gaussians: fog pass {addon._state['last_ms']:.1f} ms "
              f"at {cap['viewport'][2]}x{cap['viewport'][3]}, scale {addon._state['last_scale']} "
              f"(factors {fog.factor_ms:.1f} ms when rebuilt)")
        bpy.data.objects.remove(obj)
        bpy.context.view_layer.update()
        addon._state["capture"] = cap = {}
        _redraw()
        assert addon._state["error"] is None, addon._state["error"]
        assert len(cap["gaussians"]["scales"]) == 0
    finally:
        wm.airlight_preview = False
        addon._state["capture"] = None
        if "PreviewFog" in bpy.data.objects:
            bpy.data.objects.remove(bpy.data.objects["PreviewFog"])


def test05_factor_cache_matches_fresh(native):
    """Moving the view reuses the light-side optical depths: the factors equal a fresh
    computation at the new viewpoint (and differ from the old one's)."""
    from airlight import preview_gaussians as pg
    centres, scales, amplitudes = random_gaussians((1.0, -12.0, 5.0))
    lights = [(2.0, -1.0, 3.0), (-4.0, 3.0, 2.0)]
    pg.clear_cache()
    f1_a, _ = pg.fogshop_factors(native, centres, scales, amplitudes, SIGMA_T, (1.0, -12.0, 5.0),
                                 lights, data_key="k")
    f1_b, Csv_b = pg.fogshop_factors(native, centres, scales, amplitudes, SIGMA_T, (3.0, -9.0, 4.0),
                                     lights, data_key="k")
    f1_c, Csv_c = pg.fogshop_factors(native, centres, scales, amplitudes, SIGMA_T, (3.0, -9.0, 4.0),
                                     lights)
    pg.clear_cache()
    np.testing.assert_allclose(f1_b, f1_c, rtol=1e-12)
    np.testing.assert_allclose(Csv_b, Csv_c, rtol=1e-12)
    assert np.abs(f1_a - f1_b).max() > 1e-3


# ---- per-Gaussian colours, tile lists ------------------------------------------------------

def _colors(n):
    rng = np.random.default_rng(6)
    colors = rng.uniform(0.0, 1.0, (n, 3))
    colors[::4] = (0.1, 0.3, 1.0)   # saturated blues and reds next to the fog's warm albedo
    colors[1::4] = (1.0, 0.05, 0.0)
    return colors


@pytest.mark.parametrize("gauss_pass", ["TILES", "SPLAT"])
def test06_coloured_gaussians_match_bake(addon, native, gs, gauss_scene, artifacts, gauss_pass):
    from airlight import scene_export
    scene = gauss_scene
    desc = scene_export.export_scene(scene, bpy.context.evaluated_depsgraph_get())
    centres, scales, amplitudes = random_gaussians(tuple(scene.camera.matrix_world.translation))
    colors = _colors(len(scales))
    baked = native.bake(**desc, rbf_centres=centres, rbf_scales=scales, rbf_amplitudes=amplitudes,
                        rbf_albedo=colors, model="sun05", aa_samples=1, threads=0)
    ref = baked["airlight"].astype(np.float64)
    ref_T = baked["transmittance"].astype(np.float64)[..., 0]
    white = native.bake(**desc, rbf_centres=centres, rbf_scales=scales, rbf_amplitudes=amplitudes,
                        model="sun05", aa_samples=1, threads=0)["airlight"].astype(np.float64)
    gaussians = dict(centres=centres, scales=scales, amplitudes=amplitudes, colors=colors,
                     key="test09c")
    I0 = addon.scene_lights(scene, bpy.context.view_layer, with_albedo=False)[1]
    got, got_T = render_preview(addon, gs, scene, desc, gaussians, light_I0=I0, gauss_pass=gauss_pass)
    rel, dT = compare(f"coloured Gaussians ({gauss_pass}) vs bake", got, got_T, ref, ref_T)
    change = np.abs(white - ref).mean() / ref.mean()
    print(f"the colours change the bake's airlight by {change:.3g} (mean abs / mean)")
    scale = 1.0 / np.percentile(ref, 99)
    tag = gauss_pass.lower()
    save_png(os.path.join(artifacts, f"preview_gauss_colour_{tag}_gpu.png"), np.clip(got * scale, 0, 1))
    save_png(os.path.join(artifacts, "preview_gauss_colour_bake.png"), np.clip(ref * scale, 0, 1))
    native.write_exr(os.path.join(artifacts, f"preview_gauss_colour_{tag}_vs_bake.exr"),
                     {"preview": got.astype(np.float32), "bake": ref.astype(np.float32)})
    assert np.isfinite(got).all()
    assert change > 0.1
    # The bound is 5 %; measured like the white Gaussians (~5e-5).
    assert rel.mean() <= 0.05
    assert rel.mean() <= 1e-3
    assert dT.mean() <= 1e-4


def test07_tile_lists_cover_and_tiles_equal_splat(addon, native, gs, gauss_scene):
    from airlight import preview_gaussians as pg
    from airlight import scene_export
    scene = gauss_scene
    desc = scene_export.export_scene(scene, bpy.context.evaluated_depsgraph_get())
    cam = scene.camera
    eye = np.array(cam.matrix_world.translation)
    centres, scales, amplitudes = random_gaussians(tuple(eye))
    # More and smaller Gaussians than test02, some behind the camera and off screen.
    rng = np.random.default_rng(11)
    extra = eye + rng.normal(size=(300, 3)) * 8.0
    centres = np.vstack([centres, extra])
    scales = np.append(scales, rng.uniform(0.5, 3.0, 300))
    amplitudes = np.append(amplitudes, rng.uniform(0.01, 0.3, 300))
    radii = pg.cull_radii(scales, amplitudes)
    persp = np.array(Matrix(desc["projection"].tolist()) @ cam.matrix_world.inverted())
    inv = np.linalg.inv(persp)
    for S in (1, 2, 4):
        first, count, entries = pg.tile_lists(centres, radii, persp, (W, H), S, gs.RBF_TILE)
        # The native lists (what the preview uses) are the same lists.
        n_first, n_count, n_entries = native.rbf_tile_lists(centres, radii, persp, W, H, S, gs.RBF_TILE)
        np.testing.assert_array_equal(n_first, first)
        np.testing.assert_array_equal(n_count, count)
        np.testing.assert_array_equal(n_entries, entries)
        lw, lh = -(-W // S), -(-H // S)
        qx, qy = np.meshgrid(np.arange(lw), np.arange(lh))
        px = np.minimum(qx * S + S // 2, W - 1) + 0.5
        py = np.minimum(qy * S + S // 2, H - 1) + 0.5
        ndc = np.stack([px / W * 2 - 1, py / H * 2 - 1], -1).reshape(-1, 2)
        far = np.column_stack([ndc, np.ones(len(ndc)), np.ones(len(ndc))]) @ inv.T
        d = far[:, :3] / far[:, 3:] - eye
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        rel = centres - eye                                   # (n, 3)
        ts = np.maximum(d @ rel.T, 0.0)                       # (texels, n), ray [0, inf)
        dist2 = (rel ** 2).sum(1)[None] - 2 * ts * (d @ rel.T) + ts ** 2
        hit = dist2 < radii[None] ** 2
        tiles = (qy // gs.RBF_TILE * count.shape[1] + qx // gs.RBF_TILE).reshape(-1)
        lists = [set(entries[f:f + c].tolist()) for f, c in zip(first.ravel(), count.ravel())]
        missing = sum(len(set(np.nonzero(hit[k])[0].tolist()) - lists[tiles[k]]) for k in range(len(tiles)))
        needed = int(hit.sum())
        pairs = int(count.sum()) * gs.RBF_TILE ** 2
        print(f"\nscale {S}: {needed} (texel, Gaussian) pairs hit, tile lists hold {len(entries)} "
              f"entries ({pairs} texel evaluations, {pairs / max(needed, 1):.2f}x the hits), missing {missing}")
        assert missing == 0
        assert needed > 1000
    # Orthographic view (parallel rays from the near plane; no cone test): the lists
    # still hold every Gaussian whose sphere a texel's ray line meets.
    view = np.array(cam.matrix_world.inverted())
    ortho = np.diag([1.0 / 8.0, 1.0 / 6.0, -2.0 / 100.0, 1.0])
    ortho[2, 3] = -1.0
    P = ortho @ view
    inv = np.linalg.inv(P)
    for S in (1, 4):
        first, count, entries = native.rbf_tile_lists(centres, radii, P, W, H, S, gs.RBF_TILE)
        lw, lh = -(-W // S), -(-H // S)
        qx, qy = np.meshgrid(np.arange(lw), np.arange(lh))
        px = np.minimum(qx * S + S // 2, W - 1) + 0.5
        py = np.minimum(qy * S + S // 2, H - 1) + 0.5
        ndc = np.stack([px / W * 2 - 1, py / H * 2 - 1], -1).reshape(-1, 2)
        near = np.column_stack([ndc, -np.ones(len(ndc)), np.ones(len(ndc))]) @ inv.T
        o = near[:, :3] / near[:, 3:]
        d = (inv @ np.array([0.0, 0.0, 1.0, 0.0]))[:3]
        d /= np.linalg.norm(d)
        rel = centres[None] - o[:, None]                      # (texels, n, 3)
        ts = np.maximum(rel @ d, 0.0)
        dist2 = (rel ** 2).sum(-1) - 2 * ts * (rel @ d) + ts ** 2
        hit = dist2 < radii[None] ** 2
        tiles = (qy // gs.RBF_TILE * count.shape[1] + qx // gs.RBF_TILE).reshape(-1)
        lists = [set(entries[f:f + c].tolist()) for f, c in zip(first.ravel(), count.ravel())]
        missing = sum(len(set(np.nonzero(hit[k])[0].tolist()) - lists[tiles[k]]) for k in range(len(tiles)))
        print(f"orthographic, scale {S}: {int(hit.sum())} pairs hit, {len(entries)} entries, missing {missing}")
        assert missing == 0 and hit.sum() > 100
    gaussians = dict(centres=centres, scales=scales, amplitudes=amplitudes, key="test09t")
    a, a_T = render_preview(addon, gs, scene, desc, gaussians, gauss_pass="TILES")
    b, b_T = render_preview(addon, gs, scene, desc, gaussians, gauss_pass="SPLAT")
    d = np.abs(a - b) / np.maximum(np.abs(b), 1e-6 * b.max())
    print(f"TILES vs SPLAT: airlight max rel {d.max():.3g}, transmittance max abs {np.abs(a_T - b_T).max():.3g}")
    assert d.max() < 1e-4
    assert np.abs(a_T - b_T).max() < 1e-5
    with pytest.raises(ValueError):
        render_preview(addon, gs, scene, desc, gaussians, gauss_pass="BOGUS")
    # Lists too long for the shader's float indices: the splat is drawn instead.
    limit = pg.MAX_TILE_ENTRIES
    pg.MAX_TILE_ENTRIES = 10
    try:
        c, c_T = render_preview(addon, gs, scene, desc, dict(gaussians, key="test09t2"),
                                gauss_pass="TILES")
    finally:
        pg.MAX_TILE_ENTRIES = limit
    assert addon._state["gpu"]["gaussian_fog"].tile_tex is None
    np.testing.assert_array_equal(c, b)
    np.testing.assert_array_equal(c_T, b_T)
    with pytest.raises(ValueError):
        native.rbf_tile_lists(centres, radii[:-1], persp, W, H, 1, gs.RBF_TILE)
    with pytest.raises(ValueError):
        native.rbf_tile_lists(centres, -radii, persp, W, H, 1, gs.RBF_TILE)


def test08_handler_draws_coloured_fog_objects(addon, gauss_scene):
    from airlight import fog_object
    scene = gauss_scene
    centres, scales, amplitudes = random_gaussians(tuple(scene.camera.matrix_world.translation))
    obj = fog_object.new_fog_object("ColourFog", scene.collection, centres, scales, amplitudes,
                                    colors=_colors(len(scales)))
    bpy.context.view_layer.update()
    wm = bpy.context.window_manager
    addon._state["error"] = None
    wm.airlight_preview = True
    try:
        addon._state["capture"] = cap = {}
        _redraw()
        assert addon._state["error"] is None, addon._state["error"]
        np.testing.assert_allclose(cap["gaussians"]["colors"], _colors(len(scales)), atol=1e-6)
    finally:
        wm.airlight_preview = False
        addon._state["capture"] = None
        bpy.data.objects.remove(obj)


# ---- orbiting: a view change recomputes only the eye side -----------------------------------

@pytest.mark.parametrize("noise", [None, (0.5, 2.0, (0.1, 0.2, 0.3))])
def test10_orbit_reuses_light_rows_and_equals_a_fresh_cache(addon, native, gs, gauss_scene, noise):
    """The view orbits around the scene (the camera rotated about z through the origin):
    each new view computes the factors' eye row only (preview_gaussians.factor_stats: no
    new light rows), keeps the gauss texture while the noise is off (it holds the eye only
    through the noise radii; with the noise on it follows the eye), and draws the same
    image as a fresh cache (new GaussianFog, light side dropped) at that view, which
    differs from the previous view's image."""
    from airlight import preview_gaussians as pg
    from airlight import scene_export
    scene = gauss_scene
    cam = scene.camera
    saved = cam.matrix_world.copy()
    centres, scales, amplitudes = random_gaussians(tuple(saved.translation))
    gaussians = dict(centres=centres, scales=scales, amplitudes=amplitudes, key=f"test10-{noise is not None}")

    def draw():
        bpy.context.view_layer.update()
        desc = scene_export.export_scene(scene, bpy.context.evaluated_depsgraph_get())
        return render_preview(addon, gs, scene, desc, gaussians, noise=noise)

    def fresh():
        if addon._state["gpu"] is not None:
            addon._state["gpu"].pop("gaussian_fog", None)
        pg.clear_cache()

    try:
        fresh()
        prev, _ = draw()
        for angle in (0.08, 0.2, 0.35):
            cam.matrix_world = Matrix.Rotation(angle, 4, 'Z') @ saved
            fog = addon._state["gpu"]["gaussian_fog"]
            stats, uploads, updates = dict(pg.factor_stats), fog.gauss_uploads, fog.factor_updates
            got, got_T = draw()
            assert addon._state["gpu"]["gaussian_fog"] is fog
            assert pg.factor_stats["full"] == stats["full"], "a view change recomputed the light rows"
            assert pg.factor_stats["eye_only"] == stats["eye_only"] + 1
            assert fog.factor_updates == updates + 1
            assert fog.gauss_uploads == uploads + (1 if noise is not None else 0)
            fresh()
            ref, ref_T = draw()
            assert pg.factor_stats["full"] == stats["full"] + 1
            diff = np.abs(got - ref).max()
            print(f"\norbit {angle:.2f} rad, noise {noise is not None}: cached vs fresh max |diff| {diff:.3g}, "
                  f"vs previous view {np.abs(got - prev).max():.3g} (of max {ref.max():.3g})")
            np.testing.assert_allclose(got, ref, rtol=1e-6, atol=1e-7 * ref.max())
            np.testing.assert_allclose(got_T, ref_T, rtol=0, atol=1e-6)
            assert np.abs(got - prev).max() > 1e-2 * ref.max()  # the view really changed
            prev = got
    finally:
        cam.matrix_world = saved
        bpy.context.view_layer.update()
        fresh()
