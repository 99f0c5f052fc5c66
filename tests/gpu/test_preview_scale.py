"""Reduced-resolution fog with depth-aware upsampling, the preview's own distance pass,
and cache invalidation (addon/airlight/preview.py).

- test01: the preview's own distance pass (mesh batches of the evaluated scene) against
  the bake's ray-traced depth of the same camera.
- test02: the fog at HALF, QUARTER and EIGHTH scale, upsampled by plain bilinear, joint
  bilateral with nearest-depth fallback, and joint bilateral with exact re-evaluation (the
  default), against the full-resolution preview and `_native.bake`: mean relative
  difference overall and at depth-discontinuity pixels. The default must stay within the
  issue's 2 % of the bake overall, add at most 2 % (EIGHTH: 3 %) to the full-resolution
  preview at silhouettes, and there beat plain bilinear by 2x (the depth-aware pass
  matters).
- test03: the draw handler follows edits: moving a light, changing the density, moving
  geometry and changing the frame (animated light) all change the next drawn preview.
"""

import bpy
import gpu
import numpy as np
import pytest
from mathutils import Matrix

from preview_scenes import redraw, save_png, view3d

W, H = 320, 240
MODES = {"bilinear": 0, "bilateral": 1, "bilateral+exact": 2}


def _camera_view(scene, native):
    from airlight import scene_export
    scene.render.resolution_x, scene.render.resolution_y = W, H
    bpy.context.view_layer.update()
    depsgraph = bpy.context.evaluated_depsgraph_get()
    desc = scene_export.export_scene(scene, depsgraph)
    baked = native.bake(**desc, model="sun05", aa_samples=1, threads=0)
    cam = scene.camera
    persp = Matrix(desc["projection"].tolist()) @ cam.matrix_world.inverted()
    return baked, persp, tuple(cam.matrix_world.translation), desc["clip_start"]


@pytest.fixture(scope="module")
def view(addon, native, fog_scene):
    baked, persp, eye, clip_start = _camera_view(fog_scene, native)
    addon.free_gpu_resources()
    # Distance pass through the camera (the handler's code, with the camera's matrices).
    off = gpu.types.GPUOffScreen(W, H, format='RGBA32F')
    try:
        with off.bind():
            tex = addon.draw_distance(bpy.context, perspective_matrix=persp, view_origin=eye,
                                      is_perspective=True, size=(W, H))
            target = addon._state["gpu"]["targets"]["distance"]
            with addon._framebuffer(target).bind():
                buf = gpu.state.active_framebuffer_get().read_color(0, 0, W, H, 1, 0, 'FLOAT')
    finally:
        off.free()
    from airlight import gpu_shaders as gs
    distance = gs.buffer_to_numpy(buf, (H, W))[::-1]  # top row first, like the bake
    return dict(baked=baked, persp=persp, eye=eye, clip_start=clip_start, distance=distance,
                distance_tex=tex)


def test01_own_distance_matches_bake_depth(view):
    ref = view["baked"]["depth"].astype(np.float64)
    got = view["distance"].astype(np.float64)
    both = np.isfinite(ref) & np.isfinite(got)
    rel = np.abs(got[both] - ref[both]) / ref[both]
    disagree = np.isfinite(ref) != np.isfinite(got)  # hit vs miss: only at silhouettes
    print(f"\nown distance pass vs bake depth ({W}x{H}): mean rel {rel.mean():.3g}, "
          f"max {rel.max():.3g}; hit/miss disagreement {disagree.mean():.3g} of pixels")
    assert both.mean() > 0.5
    assert rel.mean() < 1e-4
    assert np.median(rel) < 1e-5
    assert disagree.mean() < 2e-3


def _fog(addon, view, scene, scale, mode):
    positions, intensities = addon.scene_lights(scene, bpy.context.view_layer)
    off = gpu.types.GPUOffScreen(W, H, format='RGBA32F')
    try:
        with off.bind():
            gpu.state.active_framebuffer_get().clear(color=(0.0, 0.0, 0.0, 0.0))
            addon.draw_fog(depth_tex=view["distance_tex"], perspective_matrix=view["persp"],
                           view_origin=view["eye"], is_perspective=True,
                           viewport=(0, 0, W, H), sigma_t=scene.airlight.density,
                           light_positions=positions, light_intensities=intensities,
                           clip_start=view["clip_start"], window_depth=False, scale=scale, mode=mode)
        from airlight import gpu_shaders as gs
        return gs.read_offscreen(off)[::-1].astype(np.float64)
    finally:
        off.free()


def _silhouettes(depth):
    """Pixels whose 3x3 neighbourhood spans a depth discontinuity (relative jump > 5 %
    or hit next to background)."""
    d = np.where(np.isfinite(depth), depth, 1e30)
    pad = np.pad(d, 1, mode='edge')
    lo = np.full_like(d, np.inf)
    hi = np.zeros_like(d)
    for dy in range(3):
        for dx in range(3):
            n = pad[dy:dy + d.shape[0], dx:dx + d.shape[1]]
            lo, hi = np.minimum(lo, n), np.maximum(hi, n)
    return hi > lo * 1.05


def _rel(got, ref, mask):
    floor = 1e-6 * ref.max()
    use = (ref > floor) & mask[..., None]
    return np.abs(got - ref)[use] / ref[use]


def test02_reduced_scale_accuracy(addon, view, fog_scene, artifacts):
    ref = view["baked"]["airlight"].astype(np.float64)
    full = _fog(addon, view, fog_scene, 1, 2)[..., :3]
    sil = _silhouettes(view["baked"]["depth"].astype(np.float64))
    every = np.ones(sil.shape, bool)
    full_rel = _rel(full, ref, every)
    print(f"\nfog vs bake at {W}x{H}; silhouette pixels: {sil.sum()} ({sil.mean():.1%})")
    print(f"{'scale':>7} {'upsampling':>16} {'mean rel':>9} {'p99':>8} {'sil. mean':>10} "
          f"{'vs full':>9} {'sil. vs full':>12}")
    print(f"{'FULL':>7} {'-':>16} {full_rel.mean():>9.2e} {np.percentile(full_rel, 99):>8.2e} "
          f"{_rel(full, ref, sil).mean():>10.2e} {0.0:>9.2e} {0.0:>12.2e}")
    results = {}
    for scale_name, scale in (("HALF", 2), ("QUARTER", 4), ("EIGHTH", 8)):
        for mode_name, mode in MODES.items():
            got = _fog(addon, view, fog_scene, scale, mode)[..., :3]
            assert np.isfinite(got).all()
            rel, rel_sil = _rel(got, ref, every), _rel(got, ref, sil)
            results[scale_name, mode_name] = (rel.mean(), _rel(got, full, sil).mean())
            print(f"{scale_name:>7} {mode_name:>16} {rel.mean():>9.2e} "
                  f"{np.percentile(rel, 99):>8.2e} {rel_sil.mean():>10.2e} "
                  f"{_rel(got, full, every).mean():>9.2e} {_rel(got, full, sil).mean():>12.2e}")
            if mode == 2:
                scale_png = 1.0 / np.percentile(ref, 99)
                save_png(f"{artifacts}/preview_{scale_name.lower()}.png",
                         np.clip(got * scale_png, 0, 1))
    # FULL: the bake's clip range, float32 (measured 1.5e-5).
    assert full_rel.mean() <= 1e-4
    for scale_name in ("HALF", "QUARTER", "EIGHTH"):
        mean, sil_mean = results[scale_name, "bilateral+exact"]
        _, sil_bilinear = results[scale_name, "bilinear"]
        # The tolerance for homogeneous fog against the bake, overall; at
        # silhouettes the upsampling itself (against the full-resolution preview, so the
        # GLSL-vs-C++ difference is not counted twice) may add no more than that either:
        # exact re-evaluation leaves only interpolation along one surface there.
        assert mean <= 0.02
        # EIGHTH is 40 x 30 texels here: its silhouettes interpolate along a surface over
        # 8 pixels (measured 2.2e-2 at 320x240).
        assert sil_mean <= (0.03 if scale_name == "EIGHTH" else 0.02)
        # Depth-aware upsampling must matter: bilinear smears fog across edges.
        assert sil_mean < 0.5 * sil_bilinear


# ---- the draw handler follows edits -----------------------------------------------------

@pytest.fixture
def handler_view(addon, fog_scene):
    wm = bpy.context.window_manager
    addon._state["error"] = None
    wm.airlight_preview = True
    wm.airlight_preview_scale = 'HALF'
    wm.airlight_preview_depth = 'DRAWN'
    view3d().spaces.active.region_3d.view_perspective = 'CAMERA'
    yield addon
    wm.airlight_preview = False
    addon._state["capture"] = None


def _draw(addon):
    addon._state["capture"] = cap = {}
    n = addon._state["draws"]
    redraw()
    assert addon._state["error"] is None, addon._state["error"]
    assert addon._state["draws"] > n
    return cap


def _changed(a, b):
    a, b = a[..., :3], b[..., :3]  # airlight (the reduced target's alpha is the distance)
    return float(np.abs(a - b).max() / max(np.abs(a).max(), 1e-30))


def test03_preview_follows_lights_density_geometry_and_frame(handler_view):
    addon = handler_view
    scene = bpy.context.scene
    lamp, cube = scene.objects["LampA"], scene.objects["Cube"]
    base = _draw(addon)
    again = _draw(addon)
    assert _changed(base["fog_lo"][..., :3], again["fog_lo"][..., :3]) == 0.0  # nothing changed: same image

    lamp.location.x += 1.5
    moved = _draw(addon)
    assert _changed(base["fog_lo"], moved["fog_lo"]) > 1e-2
    lamp.location.x -= 1.5

    old_density = scene.airlight.density
    scene.airlight.density = old_density * 2.0
    denser = _draw(addon)
    assert denser["sigma_t"] == pytest.approx(old_density * 2.0)
    assert _changed(base["fog_lo"], denser["fog_lo"]) > 1e-2
    scene.airlight.density = old_density

    # Geometry: the own distance pass sees the moved cube (instance cache dropped).
    cube.location.x += 2.0
    bpy.context.view_layer.update()
    shifted = _draw(addon)
    finite = np.isfinite(base["depth"]) & np.isfinite(shifted["depth"])
    assert (np.abs(base["depth"][finite] - shifted["depth"][finite]) > 1e-3).mean() > 1e-3
    cube.location.x -= 2.0
    bpy.context.view_layer.update()

    # Timeline: an animated light follows frame changes.
    home = lamp.location.copy()
    lamp.keyframe_insert("location", frame=1)
    lamp.location.z += 2.0
    lamp.keyframe_insert("location", frame=10)
    try:
        scene.frame_set(1)
        f1 = _draw(addon)
        scene.frame_set(10)
        f10 = _draw(addon)
        assert f10["lights"][0] != f1["lights"][0]
        assert _changed(f1["fog_lo"], f10["fog_lo"]) > 1e-2
    finally:
        lamp.animation_data_clear()
        scene.frame_set(1)
        lamp.location = home
