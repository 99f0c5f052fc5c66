"""The preview's camera clip range (addon/airlight/preview.py, preview_common.glsl).

Cycles, and the bake after it, start camera rays on the near clip plane (the fog begins
there) and do not see surfaces beyond the far plane.

- test01: `view_clip_range` against the region's own projection, in camera view,
  perspective user view and orthographic user view: the view-axis depths of the near and
  far planes unprojected from the matrix Blender drew with are the clip range the preview
  uses (for orthographic user views Blender centres the range on the view: -clip_end / 2
  to +clip_end / 2).
- test02: `draw_fog` against `_native.bake` with a near plane far out (3 m: without the
  clip the fog differs by ~30 %) and a far plane that cuts the floor (those pixels miss:
  fog to infinity, T = 0), for a perspective and an orthographic camera.
- test03: the draw handler in camera view hands the camera's clip_start to the fog, and
  moving it changes the drawn fog.
"""

import bpy
import gpu
import numpy as np
import pytest
from mathutils import Matrix, Vector

from preview_scenes import redraw, view3d

W, H = 160, 120


def _plane_depths(persp, eye, is_perspective, axis):
    """View-axis depths (from _eye_) of the near and far planes of _persp_ at the centre."""
    inv = persp.inverted()

    def unproject(z):
        p = inv @ Vector((0.0, 0.0, z, 1.0))
        return p.xyz / p.w
    return tuple((unproject(z) - Vector(eye)).dot(axis) for z in (-1.0, 1.0))


@pytest.mark.parametrize("perspective", ["CAMERA", "PERSP", "ORTHO"])
def test01_clip_range_is_the_region_projection(addon, fog_scene, perspective):
    area = view3d()
    space = area.spaces.active
    rv3d = space.region_3d
    cam = fog_scene.camera.data
    old = (cam.clip_start, cam.clip_end, space.clip_start, space.clip_end)
    cam.clip_start, cam.clip_end = 0.7, 300.0
    space.clip_start, space.clip_end = 0.05, 500.0
    rv3d.view_perspective = perspective
    try:
        redraw()  # updates the region's matrices
        region = next(r for r in area.regions if r.type == 'WINDOW')
        with bpy.context.temp_override(window=bpy.context.window_manager.windows[0],
                                       area=area, region=region, space_data=space,
                                       region_data=rv3d):
            start, end = addon.view_clip_range(bpy.context)
        persp = rv3d.perspective_matrix.copy()
        eye = rv3d.view_matrix.inverted().translation
        if rv3d.is_perspective:
            axis = addon.view_axis(persp)
        else:
            axis = -rv3d.view_matrix.inverted().col[2].xyz.normalized()
        near, far = _plane_depths(persp, eye, rv3d.is_perspective, axis)
    finally:
        cam.clip_start, cam.clip_end, space.clip_start, space.clip_end = old
        rv3d.view_perspective = 'CAMERA'
    print(f"\n{perspective}: view_clip_range ({start:.6g}, {end:.6g}), "
          f"region projection ({near:.6g}, {far:.6g})")
    expected = {"CAMERA": (0.7, 300.0), "PERSP": (0.05, 500.0), "ORTHO": (-250.0, 250.0)}
    assert (start, end) == pytest.approx(expected[perspective], rel=1e-6)
    assert near == pytest.approx(start, rel=1e-4, abs=1e-4)
    assert far == pytest.approx(end, rel=1e-3)


def _preview_vs_bake(addon, native, gs, scene):
    from airlight import scene_export
    desc = scene_export.export_scene(scene, bpy.context.evaluated_depsgraph_get())
    baked = native.bake(**desc, model="sun05", aa_samples=1, threads=0)
    cam = scene.camera
    persp = Matrix(desc["projection"].tolist()) @ cam.matrix_world.inverted()
    depth_tex, _ = gs.render_depth(desc["vertices"], desc["triangles"], persp, W, H)
    positions, intensities = addon.scene_lights(scene, bpy.context.view_layer)
    is_persp = cam.data.type == 'PERSP'
    off = gpu.types.GPUOffScreen(W, H, format='RGBA32F')

    def draw(clip_start):
        with off.bind():
            gpu.state.active_framebuffer_get().clear(color=(0.0, 0.0, 0.0, 0.0))
            addon.draw_fog(depth_tex=depth_tex, perspective_matrix=persp,
                           view_origin=tuple(cam.matrix_world.translation),
                           is_perspective=is_persp, viewport=(0, 0, W, H),
                           sigma_t=scene.airlight.density, light_positions=positions,
                           light_intensities=intensities, clip_start=clip_start)
        return gs.read_offscreen(off)[::-1].astype(np.float64)
    try:
        got, unclipped = draw(desc["clip_start"]), draw(0.0)
    finally:
        off.free()
    ref = baked["airlight"].astype(np.float64)
    use = ref > 1e-6 * ref.max()
    rel = lambda img: np.abs(img[..., :3] - ref)[use] / ref[use]  # noqa: E731
    T_err = np.abs(1.0 - got[..., 3] - baked["transmittance"][..., 0])
    return rel(got), rel(unclipped), T_err, baked


@pytest.mark.parametrize("camera_type", ["PERSP", "ORTHO"])
def test02_near_and_far_plane_match_bake(addon, native, gs, fog_scene, camera_type):
    scene = fog_scene
    cam = scene.camera.data
    old = (cam.type, cam.clip_start, cam.clip_end, cam.ortho_scale,
           scene.render.resolution_x, scene.render.resolution_y)
    cam.type = camera_type
    cam.ortho_scale = 16.0
    cam.clip_start, cam.clip_end = 3.0, 15.0  # the far floor lies beyond 15 m
    scene.render.resolution_x, scene.render.resolution_y = W, H
    bpy.context.view_layer.update()
    try:
        rel, rel_unclipped, T_err, baked = _preview_vs_bake(addon, native, gs, scene)
    finally:
        (cam.type, cam.clip_start, cam.clip_end, cam.ortho_scale,
         scene.render.resolution_x, scene.render.resolution_y) = old
        bpy.context.view_layer.update()
    beyond = np.isinf(baked["depth"]).mean()
    print(f"\n{camera_type} camera, clip 3..15 m: preview vs bake mean rel {rel.mean():.3g}, "
          f"p99 {np.percentile(rel, 99):.3g}; from the eye instead {rel_unclipped.mean():.3g}; "
          f"T mean abs {T_err.mean():.3g}; {beyond:.1%} pixels miss (beyond clip_end)")
    assert beyond > 0.1  # the far plane really cuts the floor
    assert rel.mean() <= 1e-4
    assert np.percentile(rel, 99) <= 1e-3
    assert T_err.mean() <= 1e-4
    if camera_type == 'PERSP':
        assert rel_unclipped.mean() > 0.1  # the near plane matters here


def test03_handler_uses_camera_clip_start(addon, fog_scene):
    wm = bpy.context.window_manager
    addon._state["error"] = None
    wm.airlight_preview = True
    wm.airlight_preview_scale = 'HALF'  # the capture holds the reduced fog image
    view3d().spaces.active.region_3d.view_perspective = 'CAMERA'
    cam = fog_scene.camera.data
    old = cam.clip_start
    caps = []
    try:
        for clip_start in (0.1, 4.0):
            cam.clip_start = clip_start
            addon._state["capture"] = cap = {}
            redraw()
            assert addon._state["error"] is None, addon._state["error"]
            caps.append(cap)
    finally:
        cam.clip_start = old
        wm.airlight_preview = False
        addon._state["capture"] = None
    assert caps[0]["clip"][0] == pytest.approx(0.1)
    assert caps[1]["clip"] == pytest.approx((4.0, cam.clip_end))
    a, b = caps[0]["fog_lo"][..., :3], caps[1]["fog_lo"][..., :3]
    assert np.abs(a - b).max() > 1e-2 * np.abs(a).max()
