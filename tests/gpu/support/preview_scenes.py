"""What the viewport-preview tests share: the fog scene they draw, the preview drawn
offscreen for the scene camera, its comparison with the bake, the window's 3D viewport and
its redraw, and PNG snapshots of the images (out/test_artifacts/). Runs inside Blender."""

import os

import bpy
import gpu
import numpy as np
import pytest
from mathutils import Matrix, Vector

W, H = 160, 120
ALBEDO = (1.0, 0.8, 0.6)
FOG_SIGMA_T = 0.08  # the homogeneous preview tests' density (conftest.fog_scene)
GAUSS_SIGMA_T = 0.03  # the Gaussian-fog preview tests' density


def build_scene(sigma_t):
    """Floor, cube, two point lights, a camera (W x H); fog on, its other settings at their
    defaults (whatever an earlier test module left in the scene is reset)."""
    scene = bpy.context.scene
    for obj in list(scene.objects):
        bpy.data.objects.remove(obj)
    bpy.ops.mesh.primitive_plane_add(size=40.0, location=(0.0, 0.0, 0.0))
    bpy.ops.mesh.primitive_cube_add(size=2.0, location=(0.0, 0.0, 1.0))
    for name, loc, energy, colour in (("LampA", (2.0, -1.0, 3.0), 2000.0, (1.0, 1.0, 1.0)),
                                      ("LampB", (-4.0, 3.0, 2.0), 800.0, (1.0, 0.5, 0.2))):
        data = bpy.data.lights.new(name, 'POINT')
        data.energy = energy
        data.color = colour
        data.shadow_soft_size = 0.0
        obj = bpy.data.objects.new(name, data)
        obj.location = loc
        scene.collection.objects.link(obj)
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    cam.location = (1.0, -12.0, 5.0)
    direction = Vector((0.0, 0.0, 1.0)) - cam.location
    cam.rotation_euler = direction.to_track_quat('-Z', 'Y').to_euler()
    scene.collection.objects.link(cam)
    scene.camera = cam
    scene.render.resolution_x, scene.render.resolution_y = W, H
    scene.render.resolution_percentage = 100
    settings = scene.airlight
    for name in ("model", "phase", "anisotropy", "accuracy", "use_fog_top", "fog_top", "environment_glow",
                 "noise_amplitude", "noise_scale", "noise_offset"):
        settings.property_unset(name)
    settings.enabled = True
    settings.density = sigma_t
    settings.color = ALBEDO
    # These tests hold the unshadowed preview to the unshadowed bake (test_preview_shadows.py
    # holds the shadows).
    settings.volumetric_shadows = False
    bpy.context.view_layer.update()
    return scene


def save_png(path, rgb):
    """Saves (H, W, 3) linear float (row 0 = top) as an 8-bit PNG via bpy."""
    h, w, _ = rgb.shape
    img = bpy.data.images.new(os.path.basename(path), w, h, alpha=True, float_buffer=True)
    rgba = np.ones((h, w, 4), np.float32)
    rgba[..., :3] = rgb
    img.pixels.foreach_set(np.ascontiguousarray(rgba[::-1]).ravel())
    img.filepath_raw = path
    img.file_format = 'PNG'
    img.save()
    bpy.data.images.remove(img)


def random_gaussians(cam_location):
    """(centres, scales, amplitudes) of 60 random Gaussians over the floor and a broad faint
    one whose cull sphere holds the camera at _cam_location_ (the full-screen splat path)."""
    rng = np.random.default_rng(5)
    n = 60
    centres = np.column_stack([rng.uniform(-6.0, 6.0, n), rng.uniform(-4.0, 6.0, n),
                               rng.uniform(0.0, 4.0, n)])
    scales = rng.uniform(0.4, 1.2, n)
    amplitudes = rng.uniform(0.05, 0.6, n)
    centres = np.vstack([centres, np.array(cam_location)[None] + (0.5, 1.0, 0.0)])
    scales = np.append(scales, 0.15)
    amplitudes = np.append(amplitudes, 0.02)
    return centres, scales, amplitudes


def render_preview(addon, gs, scene, desc, gaussians, *, clip_start=None, scale=1, **extra):
    """(airlight (H, W, 3), transmittance (H, W)) of the preview (`preview.draw_fog`, the
    draw handler's code) of the scene camera's view, fed the depth of the bake's triangles
    (_desc_: scene_export.export_scene), top row first."""
    cam = scene.camera
    proj = Matrix(desc["projection"].tolist())
    persp = proj @ cam.matrix_world.inverted()
    depth_tex, _ = gs.render_depth(desc["vertices"], desc["triangles"], persp, W, H)
    positions, intensities = addon.scene_lights(scene, bpy.context.view_layer)
    off = gpu.types.GPUOffScreen(W, H, format='RGBA32F')
    try:
        with off.bind():
            fb = gpu.state.active_framebuffer_get()
            fb.clear(color=(0.0, 0.0, 0.0, 0.0))
            addon.draw_fog(depth_tex=depth_tex, perspective_matrix=persp,
                           view_origin=tuple(cam.matrix_world.translation),
                           is_perspective=True, viewport=(0, 0, W, H),
                           sigma_t=scene.airlight.density,
                           light_positions=positions, light_intensities=intensities,
                           clip_start=desc["clip_start"] if clip_start is None else clip_start,
                           window_depth=True, gaussians=gaussians, scale=scale, **extra)
        out = gs.read_offscreen(off)[::-1].astype(np.float64)
    finally:
        off.free()
    return out[..., :3], 1.0 - out[..., 3]


def compare(name, got, got_T, ref, ref_T):
    """(relative airlight differences where the bake's exceeds 1e-4 of its p99, absolute
    transmittance differences), printed."""
    floor = 1e-4 * np.percentile(ref, 99)
    use = ref > floor
    rel = np.abs(got - ref)[use] / ref[use]
    dT = np.abs(got_T - ref_T)
    print(f"\n{name}: airlight mean rel {rel.mean():.4g}, p99 {np.percentile(rel, 99):.4g}, "
          f"max {rel.max():.4g}; transmittance mean abs {dT.mean():.3g}, max {dT.max():.3g}")
    return rel, dT


def view3d():
    """The test window's 3D viewport area."""
    for area in bpy.context.window_manager.windows[0].screen.areas:
        if area.type == 'VIEW_3D':
            return area
    pytest.fail("no 3D viewport in the test window")


def redraw():
    """Draws the whole window now (also after a file load, when the script's context
    has no window any more)."""
    window = bpy.context.window_manager.windows[0]
    with bpy.context.temp_override(window=window, screen=window.screen):
        bpy.ops.wm.redraw_timer(type='DRAW_WIN_SWAP', iterations=1)


def capture_draw(addon):
    """The inputs of one draw of the window viewport's handler through the scene camera
    (preview._state["capture"]); fails the test if the draw kept an error."""
    import bpy
    addon._state["error"] = None
    wm = bpy.context.window_manager
    wm.airlight_preview = True
    view3d().spaces.active.region_3d.view_perspective = 'CAMERA'
    addon._state["capture"] = capture = {}
    try:
        redraw()
    finally:
        addon._state["capture"] = None
        wm.airlight_preview = False
    assert addon._state["error"] is None, addon._state["error"]
    return capture
