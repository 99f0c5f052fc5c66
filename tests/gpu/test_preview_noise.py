"""Fog-object noise (Fogshop section 5.5) and per-Gaussian colours in the viewport preview.

- test01: shaders/rbf_noise.glsl vs native/core/noise.h (`_native.gradient_noise3`) on
  the same float32 points (negative, large, on and next to lattice points): the noise
  function itself, value by value.
- test02: the preview (`preview.draw_fog` with noise on) vs `_native.bake` with the same
  noise at full resolution, both Gaussian passes (TILES, SPLAT): mean relative
  difference of the airlight <= 5 %, and the noise changes the image (so the test sees it).
- test03: Gaussians with their own colours AND noise vs the bake (rbf_albedo).
- test04: keyframed noise_offset reaches the draw handler on every frame (scrubbing), and
  a changed offset changes the preview's image.
Images are saved under out/test_artifacts/ (or $AIRLIGHT_TEST_ARTIFACTS).
"""

import os

import bpy
import gpu
import numpy as np
import pytest

from conftest import draw_fullscreen
from preview_scenes import GAUSS_SIGMA_T as SIGMA_T, build_scene, compare, random_gaussians, redraw, render_preview, save_png

NOISE = (0.6, 1.5, (0.3, -1.2, 2.5))  # amplitude, scale (m), offset (cells)


@pytest.fixture(scope="module")
def noise_scene(addon, native):
    return build_scene(SIGMA_T)


def test01_glsl_noise_matches_cpp(gs, native):
    rng = np.random.default_rng(12)
    N = 64
    n = N * N
    p = np.concatenate([
        rng.uniform(-8.0, 8.0, (n // 2, 3)),                       # both signs
        rng.uniform(-300.0, 300.0, (n // 4, 3)),                   # far from the origin
        np.round(rng.uniform(-5.0, 5.0, (n // 8, 3))),             # lattice points (0)
        np.round(rng.uniform(-5.0, 5.0, (n - n // 2 - n // 4 - n // 8, 3)))
        + rng.choice([-1.0, 1.0], (n - n // 2 - n // 4 - n // 8, 3)) * 1e-4,  # next to them
    ]).astype(np.float32)
    ref = native.gradient_noise3(p).astype(np.float64)
    q = np.zeros((N, N, 4), np.float32)
    q[..., :3] = p.reshape(N, N, 3)
    shader = gs.create_noise_test_shader()
    batch = gs.fullscreen_batch(shader)
    tex = gs.float_texture(q)
    off = gpu.types.GPUOffScreen(N, N, format='RGBA32F')
    try:
        draw_fullscreen(off, shader, batch, samplers=[("in0", tex)])
        got = gs.read_offscreen(off).reshape(n, 4)[:, :3].astype(np.float64)
    finally:
        off.free()
    d = np.abs(got - ref)
    lattice = slice(n // 2 + n // 4, n // 2 + n // 4 + n // 8)
    print(f"\nrbf_gradient_noise3 vs noise.h: {n} points, abs diff mean {d.mean():.3g} "
          f"p99 {np.percentile(d, 99):.3g} max {d.max():.3g}; |noise| max {np.abs(ref).max():.3g}, "
          f"std {ref.std():.3g}")
    assert np.isfinite(got).all()
    assert ref.std() > 0.1                      # a real field, not zeros
    assert np.abs(ref[lattice, 0]).max() == 0.0  # noise is 0 on the lattice (component x)
    # Same float operations in the same order: only rounding (FMA contraction) differs.
    assert d.max() < 1e-5
    with pytest.raises(ValueError):
        native.gradient_noise3(np.array([[0.0, np.nan, 1.0]]))


def _bake(native, desc, centres, scales, amplitudes, noise=None, colors=None):
    extra = {}
    if noise is not None:
        extra.update(noise_amplitude=noise[0], noise_scale=noise[1], noise_offset=noise[2])
    if colors is not None:
        extra["rbf_albedo"] = np.asarray(colors, np.float64)
    baked = native.bake(**desc, rbf_centres=centres, rbf_scales=scales, rbf_amplitudes=amplitudes,
                        model="sun05", aa_samples=1, threads=0, **extra)
    return baked["airlight"].astype(np.float64), baked["transmittance"].astype(np.float64)[..., 0]


def _save(artifacts, name, got, ref, got_T, ref_T, native):
    scale = 1.0 / np.percentile(ref, 99)
    save_png(os.path.join(artifacts, f"{name}_gpu.png"), np.clip(got * scale, 0, 1))
    save_png(os.path.join(artifacts, f"{name}_bake.png"), np.clip(ref * scale, 0, 1))
    native.write_exr(os.path.join(artifacts, f"{name}_vs_bake.exr"),
                     {"preview": got.astype(np.float32), "bake": ref.astype(np.float32),
                      "preview_T": np.repeat(got_T[..., None], 3, -1).astype(np.float32),
                      "bake_T": np.repeat(ref_T[..., None], 3, -1).astype(np.float32)})


@pytest.mark.parametrize("gauss_pass", ["TILES", "SPLAT"])
def test02_noise_preview_matches_bake(addon, native, gs, noise_scene, artifacts, gauss_pass):
    from airlight import scene_export
    scene = noise_scene
    desc = scene_export.export_scene(scene, bpy.context.evaluated_depsgraph_get())
    centres, scales, amplitudes = random_gaussians(tuple(scene.camera.matrix_world.translation))
    ref, ref_T = _bake(native, desc, centres, scales, amplitudes, noise=NOISE)
    plain, _ = _bake(native, desc, centres, scales, amplitudes)
    gaussians = dict(centres=centres, scales=scales, amplitudes=amplitudes, key="test12")
    got, got_T = render_preview(addon, gs, scene, desc, gaussians, noise=NOISE,
                                gauss_pass=gauss_pass)
    rel, dT = compare(f"noisy Gaussian preview ({gauss_pass}) vs bake", got, got_T, ref, ref_T)
    change = np.abs(plain - ref).mean() / ref.mean()
    print(f"noise changes the bake's airlight by {change:.3g} (mean abs / mean)")
    _save(artifacts, f"preview_noise_{gauss_pass.lower()}", got, ref, got_T, ref_T, native)
    assert np.isfinite(got).all() and np.isfinite(got_T).all()
    assert change > 0.02
    assert rel.mean() <= 0.05
    assert dT.mean() <= 5e-3
    # Off (amplitude 0) is the plain preview.
    off, _ = render_preview(addon, gs, scene, desc, gaussians, noise=(0.0, 1.0, (0, 0, 0)),
                            gauss_pass=gauss_pass)
    rel_off, _ = compare("noise amplitude 0 vs the plain bake", off, got_T, plain, ref_T)
    assert rel_off.mean() <= 1e-3


@pytest.mark.parametrize("gauss_pass", ["TILES", "SPLAT"])
def test03_colours_and_noise_match_bake(addon, native, gs, noise_scene, artifacts, gauss_pass):
    from airlight import scene_export
    scene = noise_scene
    desc = scene_export.export_scene(scene, bpy.context.evaluated_depsgraph_get())
    centres, scales, amplitudes = random_gaussians(tuple(scene.camera.matrix_world.translation))
    rng = np.random.default_rng(3)
    colors = rng.uniform(0.0, 1.0, (len(scales), 3))
    colors[::3] = (1.0, 0.1, 0.05)
    ref, ref_T = _bake(native, desc, centres, scales, amplitudes, noise=NOISE, colors=colors)
    gaussians = dict(centres=centres, scales=scales, amplitudes=amplitudes, colors=colors,
                     key="test12c")
    I0 = addon.scene_lights(scene, bpy.context.view_layer, with_albedo=False)[1]
    got, got_T = render_preview(addon, gs, scene, desc, gaussians, noise=NOISE, light_I0=I0,
                                gauss_pass=gauss_pass)
    rel, dT = compare(f"coloured noisy Gaussians ({gauss_pass}) vs bake", got, got_T, ref, ref_T)
    _save(artifacts, f"preview_noise_colour_{gauss_pass.lower()}", got, ref, got_T, ref_T, native)
    assert rel.mean() <= 0.05
    with pytest.raises(ValueError):
        render_preview(addon, gs, scene, desc, gaussians, noise=NOISE, gauss_pass=gauss_pass)
    with pytest.raises(ValueError):
        render_preview(addon, gs, scene, desc, dict(gaussians, colors=None, key="bad"),
                       noise=(-1.0, 1.0, (0, 0, 0)), gauss_pass=gauss_pass)


def test04_keyframed_offset_follows_the_frame(addon, native, gs, noise_scene):
    """Scrubbing: each draw reads the noise at the current frame (keyframes evaluated),
    and the offsets of two frames give different images."""
    from airlight import fog_object, scene_export
    scene = noise_scene
    centres, scales, amplitudes = random_gaussians(tuple(scene.camera.matrix_world.translation))
    obj = fog_object.new_fog_object("NoiseFog", scene.collection, centres, scales, amplitudes)
    s = scene.airlight
    s.noise_amplitude = NOISE[0]
    s.noise_scale = NOISE[1]
    s.noise_offset = (0.0, 0.0, 0.0)
    s.keyframe_insert("noise_offset", frame=1)
    s.noise_offset = (4.0, -2.0, 1.0)
    s.keyframe_insert("noise_offset", frame=11)
    wm = bpy.context.window_manager
    addon._state["error"] = None
    wm.airlight_preview = True
    for area in wm.windows[0].screen.areas:
        if area.type == 'VIEW_3D':
            area.spaces.active.region_3d.view_perspective = 'CAMERA'
    seen = {}
    try:
        for frame in (1, 6, 11):
            scene.frame_set(frame)
            addon._state["capture"] = cap = {}
            redraw()
            assert addon._state["error"] is None, addon._state["error"]
            expected = tuple(scene.airlight.noise_offset)
            print(f"\nframe {frame}: offset {expected}, drawn with {cap['noise']}")
            assert cap["noise"][0] == pytest.approx(NOISE[0])
            np.testing.assert_allclose(cap["noise"][2], expected, rtol=0, atol=1e-6)
            seen[frame] = expected
        assert seen[1] != seen[6] != seen[11]
        np.testing.assert_allclose(seen[11], (4.0, -2.0, 1.0), atol=1e-6)
        # Two of those offsets give different previews.
        desc = scene_export.export_scene(scene, bpy.context.evaluated_depsgraph_get())
        gaussians = dict(centres=centres, scales=scales, amplitudes=amplitudes, key="test12k")
        a, _ = render_preview(addon, gs, scene, desc, gaussians, noise=(NOISE[0], NOISE[1], seen[1]))
        b, _ = render_preview(addon, gs, scene, desc, gaussians, noise=(NOISE[0], NOISE[1], seen[6]))
        change = np.abs(a - b).mean() / a.mean()
        print(f"offset {seen[1]} -> {seen[6]} changes the preview by {change:.3g}")
        assert change > 1e-3
    finally:
        wm.airlight_preview = False
        addon._state["capture"] = None
        scene.animation_data_clear()
        s.noise_amplitude = 0.0
        scene.frame_set(1)
        bpy.data.objects.remove(obj)
