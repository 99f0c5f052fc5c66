"""Viewport fog preview (addon/airlight/preview.py).

- test01: the fog pass (`preview.draw_fog`, the very code the draw handler runs), fed
  scene depth rendered on the GPU for the scene camera, against `_native.bake` of the
  same view with the same clip range (fog from the near plane, as Cycles): mean relative
  difference of the airlight <= 1e-4 (float32 GLSL vs the double C++ on the same F
  table: measured 2e-5; without the near clip it was 6e-3). Images are saved under
  out/test_artifacts/.
- test02..: the draw handler in a real 3D viewport (redrawn with wm.redraw_timer): it
  draws, the depth it reads in POST_VIEW gives the right distances (checked against the
  analytic distance to the floor plane), it returns early when off / rendering / without
  the native module, and register/unregister cycles and file loads leave no handlers.
"""

import os
import tempfile

import bpy
import gpu
import numpy as np
import pytest
from mathutils import Matrix

from preview_scenes import FOG_SIGMA_T, H, W, redraw, save_png, view3d


def test01_preview_matches_bake(addon, native, fog_scene, gs, artifacts):
    from airlight import scene_export
    scene = fog_scene
    depsgraph = bpy.context.evaluated_depsgraph_get()
    desc = scene_export.export_scene(scene, depsgraph)
    baked = native.bake(**desc, model="sun05", aa_samples=1, threads=0)
    ref = baked["airlight"].astype(np.float64)          # (H, W, 3), top row first
    ref_T = baked["transmittance"].astype(np.float64)

    cam = scene.camera
    proj = Matrix(desc["projection"].tolist())
    persp = proj @ cam.matrix_world.inverted()
    depth_tex, _ = gs.render_depth(desc["vertices"], desc["triangles"], persp, W, H)
    positions, intensities = addon.scene_lights(scene, bpy.context.view_layer)
    assert len(positions) == 2

    off = gpu.types.GPUOffScreen(W, H, format='RGBA32F')
    try:
        with off.bind():
            fb = gpu.state.active_framebuffer_get()
            fb.clear(color=(0.0, 0.0, 0.0, 0.0))
            addon.draw_fog(depth_tex=depth_tex, perspective_matrix=persp,
                           view_origin=tuple(cam.matrix_world.translation),
                           is_perspective=True, viewport=(0, 0, W, H), sigma_t=FOG_SIGMA_T,
                           light_positions=positions, light_intensities=intensities,
                           clip_start=desc["clip_start"])
        out = gs.read_offscreen(off)[::-1].astype(np.float64)  # to top row first
    finally:
        off.free()
    got, got_T = out[..., :3], 1.0 - out[..., 3]

    floor = 1e-6 * ref.max()
    use = ref > floor
    rel = np.abs(got - ref)[use] / ref[use]
    rel_T = np.abs(got_T - ref_T[..., 0])
    print(f"\npreview vs bake ({W}x{H}, sun05): airlight mean rel {rel.mean():.4g}, "
          f"p99 {np.percentile(rel, 99):.4g}, max {rel.max():.4g}; "
          f"transmittance mean abs {rel_T.mean():.3g}, max {rel_T.max():.3g}")
    scale = 1.0 / np.percentile(ref, 99)
    save_png(os.path.join(artifacts, "preview_gpu.png"), np.clip(got * scale, 0, 1))
    save_png(os.path.join(artifacts, "preview_bake.png"), np.clip(ref * scale, 0, 1))
    diff = np.zeros_like(ref)
    diff[use] = np.abs(got - ref)[use] / ref[use]
    save_png(os.path.join(artifacts, "preview_reldiff_x10.png"), np.clip(diff * 10.0, 0, 1))
    native.write_exr(os.path.join(artifacts, "preview_vs_bake.exr"),
                     {"preview": got.astype(np.float32), "bake": ref.astype(np.float32)})
    assert np.isfinite(got).all()
    # Float32 evaluation of the same formulas and F table: ~1e-5 per pixel; a few
    # silhouette pixels differ by hit/miss (rasterised vs ray-cast edges).
    assert rel.mean() <= 1e-4
    assert np.percentile(rel, 99) <= 1e-3
    assert rel_T.mean() <= 1e-4


# ---- the real draw handler in the window's 3D viewport ---------------------------------

@pytest.fixture
def preview_on(addon, fog_scene):
    addon._state["error"] = None
    bpy.context.window_manager.airlight_preview = True
    yield addon
    bpy.context.window_manager.airlight_preview = False  # wm may be new after a load
    addon._state["capture"] = None


@pytest.mark.parametrize("depth_mode", ["DRAWN", "READBACK"])
def test02_handler_draws_with_scene_depth(preview_on, depth_mode):
    """Looking through the camera at the floor: the depth the handler uses (its own
    distance pass, or the viewport depth read in POST_VIEW) gives the analytic distance
    to the plane z = 0 (checked where the floor is visible)."""
    addon = preview_on
    wm = bpy.context.window_manager
    wm.airlight_preview_depth = depth_mode
    area = view3d()
    area.spaces.active.region_3d.view_perspective = 'CAMERA'
    addon._state["capture"] = cap = {}
    before = addon._state["draws"]
    try:
        redraw()
    finally:
        wm.airlight_preview_depth = 'DRAWN'
    assert addon._state["error"] is None, addon._state["error"]
    assert addon._state["draws"] > before
    assert cap["window_depth"] == (depth_mode == 'READBACK')
    print(f"\nviewport fog pass ({depth_mode}): {addon._state['last_ms']:.1f} ms at "
          f"{cap['viewport'][2]}x{cap['viewport'][3]}, depth {addon._state['last_depth_ms']:.1f} ms")
    depth = cap["depth"].astype(np.float64)
    x0, y0, w, h = cap["viewport"]
    inv = np.array(cap["perspective_matrix"].inverted())
    eye = np.array(cap["view_origin"])
    ys, xs = np.mgrid[0:h, 0:w]
    ones = np.ones_like(depth)
    ndc_xy = [(xs + 0.5) / w * 2 - 1, (ys + 0.5) / h * 2 - 1]
    far = np.stack(ndc_xy + [ones, ones], -1) @ inv.T
    d = far[..., :3] / far[..., 3:] - eye
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    if cap["window_depth"]:
        hit = depth < 1.0
        p = np.stack(ndc_xy + [depth * 2 - 1, ones], axis=-1) @ inv.T
        p = p[..., :3] / p[..., 3:]
        Dvp = np.linalg.norm(p - eye, axis=-1)
    else:
        hit = np.isfinite(depth)
        assert (depth[~hit] == np.inf).all()  # background is +inf, never NaN
        Dvp = np.where(hit, depth, 0.0)
        p = eye + d * Dvp[..., None]
    t_plane = -eye[2] / d[..., 2]  # analytic distance to z = 0
    # floor pixels: depth hit, the hit point lies on z = 0 outside the cube's footprint
    floor = hit & (np.abs(p[..., 2]) < 0.05) & (np.max(np.abs(p[..., :2]), -1) > 1.2)
    assert floor.mean() > 0.05
    rel = np.abs(Dvp[floor] - t_plane[floor]) / t_plane[floor]
    print(f"{depth_mode} depth -> Dvp vs analytic floor distance: mean rel {rel.mean():.3g}, "
          f"max {rel.max():.3g} over {floor.sum()} pixels")
    assert rel.mean() < 1e-3


def test03_no_draw_when_off_rendering_or_without_native(preview_on, monkeypatch):
    addon = preview_on
    wm = bpy.context.window_manager
    n = addon._state["draws"]
    wm.airlight_preview = False
    redraw()
    assert addon._state["draws"] == n
    wm.airlight_preview = True
    monkeypatch.setattr(addon, "_is_rendering", lambda: True)
    redraw()
    assert addon._state["draws"] == n
    monkeypatch.undo()
    monkeypatch.setattr(addon, "_native_for_preview", lambda: None)
    redraw()
    assert addon._state["draws"] == n and addon._state["error"] is None
    monkeypatch.undo()
    bpy.context.scene.airlight.enabled = False
    redraw()
    assert addon._state["draws"] == n
    bpy.context.scene.airlight.enabled = True
    redraw()
    assert addon._state["draws"] > n


def test04_gpu_state_restored(preview_on, gs):
    addon = preview_on
    gpu.state.blend_set('NONE')
    before = (gpu.state.blend_get(), gpu.state.depth_test_get(), gpu.state.depth_mask_get())
    off = gpu.types.GPUOffScreen(8, 8, format='RGBA32F')
    try:
        depth_tex = gs.float_texture(np.ones((8, 8), np.float32))
        with off.bind():
            addon.draw_fog(depth_tex=depth_tex, perspective_matrix=Matrix.Identity(4),
                           view_origin=(0, 0, 0), is_perspective=True, viewport=(0, 0, 8, 8),
                           sigma_t=0.1, light_positions=[(0, 0, -1)],
                           light_intensities=[(1, 1, 1)])
    finally:
        off.free()
    after = (gpu.state.blend_get(), gpu.state.depth_test_get(), gpu.state.depth_mask_get())
    assert before == after


def _load_handlers(addon):
    return (sum(1 for f in bpy.app.handlers.load_pre if f is addon._on_load_pre),
            sum(1 for f in bpy.app.handlers.load_post if f is addon._on_load_post))


def _update_handlers(addon):
    return (sum(1 for f in bpy.app.handlers.depsgraph_update_post if f is addon._on_depsgraph_update),
            sum(1 for f in bpy.app.handlers.frame_change_post if f is addon._on_frame_change))


def test05_register_cycles_leave_no_handlers(addon):
    for _ in range(3):
        addon.unregister()
        assert addon.handler_count() == 0 and _load_handlers(addon) == (0, 0)
        assert not hasattr(bpy.types.WindowManager, "airlight_preview")
        assert not hasattr(bpy.types.WindowManager, "airlight_preview_scale")
        assert _update_handlers(addon) == (0, 0)
        addon.register()
        assert addon.handler_count() == 1 and _load_handlers(addon) == (1, 1)
        assert _update_handlers(addon) == (1, 1)
    assert addon._state["error"] is None


def test06_file_load_keeps_one_handler_and_redraws(preview_on):
    addon = preview_on
    path = os.path.join(tempfile.mkdtemp(prefix="airlight_gpu_"), "fog.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    bpy.ops.wm.open_mainfile(filepath=path)
    assert addon.handler_count() == 1 and _load_handlers(addon) == (1, 1)
    assert _update_handlers(addon) == (1, 1)
    assert addon._state["gpu"] is None  # dropped on load_pre, rebuilt on the next draw
    assert addon._state["meshes"] == {} and addon._state["instances"] is None
    bpy.context.window_manager.airlight_preview = True  # a session setting
    assert bpy.context.scene.airlight.enabled
    n = addon._state["draws"]
    redraw()
    assert addon._state["error"] is None, addon._state["error"]
    assert addon._state["draws"] > n


def test07_disable_addon_while_drawing(preview_on):
    """Disabling the add-on between draws (and from inside a draw) leaves no handler and
    no error; re-enabling works."""
    import addon_utils
    addon = preview_on
    installed = "airlight" in {m.__name__ for m in addon_utils.modules()}
    disable = (lambda: addon_utils.disable("airlight")) if installed else addon.unregister

    def disable_from_draw():
        bpy.types.SpaceView3D.draw_handler_remove(handle[0], 'WINDOW')
        disable()
    handle = [bpy.types.SpaceView3D.draw_handler_add(disable_from_draw, (), 'WINDOW', 'POST_VIEW')]
    redraw()
    assert addon.handler_count() == 0
    assert _update_handlers(addon) == (0, 0)
    redraw()  # nothing left to draw, nothing raises
    if installed:
        addon_utils.enable("airlight")
        from airlight import preview as fresh
        assert fresh.handler_count() == 1
    else:
        addon.register()
        assert addon.handler_count() == 1
