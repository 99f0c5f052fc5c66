"""Interactive renders (F12 / Ctrl+F12 in a window) bake each frame's fog at that frame.

They run in the render job's thread, where the add-on cannot set the frame: the bake
takes the render's own depsgraph (render.py's on_render_frame_evaluated, a
frame_change_post handler). A windowed Blender (support/interactive_render.py) renders an
animation with Ctrl+F12 while the UI stays on frame 1, or a still with F12 (Cycles, and
Eevee once); the camera and an emitter's smoke move over the frames. Each frame's baked
fog must equal a bake of that frame made here (bpy.ops.airlight.bake sets the frame in the
main thread), so a bake of the UI's frame instead fails the animation.
"""

import os
import subprocess
import sys

import bpy
import numpy as np
import pytest

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.normpath(os.path.join(HERE, "..", ".."))
DRIVER = os.path.join(HERE, "support", "interactive_render.py")
sys.path.insert(0, os.path.join(REPO, "tests", "blender", "support"))
from exr_files import read_exr  # noqa: E402


def _channels(path):
    """{channel name: (H, W) float32} of an EXR file."""
    pixels, names = read_exr(path)
    return {name: pixels[..., k] for k, name in enumerate(names)}


def _scene(tmp_path, ui_frame, surface, engine='CYCLES'):
    """Ground plane, point lamp, a camera moving over frames 1-3 and an emitter's smoke;
    _engine_ (Cycles or Eevee) at 1 sample (the fog passes do not depend on it), EXR output."""
    bpy.ops.wm.read_homefile(use_factory_startup=True, use_empty=True)
    scene = bpy.context.scene
    mesh = bpy.data.meshes.new("Ground")
    mesh.from_pydata([(-50, -50, 0), (50, -50, 0), (50, 50, 0), (-50, 50, 0)], [], [(0, 1, 2, 3)])
    scene.collection.objects.link(bpy.data.objects.new("Ground", mesh))
    lamp = bpy.data.objects.new("Lamp", bpy.data.lights.new("Lamp", 'POINT'))
    lamp.data.energy = 300.0
    lamp.location = (0.5, 0.3, 1.5)
    scene.collection.objects.link(lamp)
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    cam.data.lens = 30.0
    scene.collection.objects.link(cam)
    scene.camera = cam
    cam.rotation_euler = (1.2, 0.0, 0.0)
    for frame, x in ((1, 0.0), (3, 1.5)):
        cam.location = (x, -5.0, 1.5)
        cam.keyframe_insert("location", frame=frame)
    scene.render.resolution_x, scene.render.resolution_y = 48, 36
    scene.render.resolution_percentage = 100
    scene.render.fps = 4  # a quarter second per frame: the smoke moves a lot
    scene.frame_start, scene.frame_end = 1, 3
    scene.render.engine = engine
    scene.eevee.taa_render_samples = 1
    scene.cycles.samples = 1
    scene.cycles.use_denoising = False
    scene.cycles.device = 'CPU'
    scene.view_settings.view_transform = 'Standard'
    scene.render.image_settings.file_format = 'OPEN_EXR'
    scene.render.image_settings.color_depth = '32'
    scene.render.use_compositing = True
    scene.render.filepath = str(tmp_path / "out_")
    scene.airlight.enabled = True
    for frame, density in ((1, 0.02), (3, 0.06)):  # keyframed fog settings follow the frame too
        scene.airlight.density = density
        scene.airlight.keyframe_insert("density", frame=frame)
    scene.airlight.cache_dir = str(tmp_path / "cache") + os.sep
    scene.airlight.surface_shading = surface
    scene.cursor.location = (0.0, 0.0, 0.4)
    assert bpy.ops.airlight.add_emitter() == {'FINISHED'}
    emitter = next(o for o in scene.objects if o.airlight_emitter.is_emitter).airlight_emitter
    emitter.rate, emitter.lifetime, emitter.velocity = 16.0, 2.0, (0.6, 0.0, 0.4)
    emitter.scale, emitter.amplitude, emitter.frame_start, emitter.frame_end = 3.0, 3.0, 1, 3
    bpy.ops.airlight.setup_compositor()
    if surface:
        # Edits after the fog nodes exist, as a user makes them: Environment Glow, a World
        # and a second lamp. Their light groups must be set up before the render starts (its
        # thread cannot add them, and it composites with the links it started with): the
        # glow's property update and the depsgraph update after each edit (the main loop's;
        # view_layer.update here) do.
        scene.airlight.environment_glow = True
        scene.world = bpy.data.worlds.new("Grey")
        scene.world.color = (0.2, 0.2, 0.2)
        bpy.context.view_layer.update()
        lamp2 = bpy.data.objects.new("Lamp2", bpy.data.lights.new("Lamp2", 'POINT'))
        lamp2.data.energy = 200.0
        lamp2.location = (-1.0, 1.0, 1.0)
        scene.collection.objects.link(lamp2)
        bpy.context.view_layer.update()
    scene.frame_set(ui_frame)
    blend = str(tmp_path / "interactive.blend")
    bpy.ops.wm.save_as_mainfile(filepath=blend)
    return scene, blend


@pytest.mark.parametrize("mode,surface,engine", [("animation", False, 'CYCLES'), ("still", False, 'CYCLES'),
                                                ("animation", True, 'CYCLES'),
                                                ("animation", False, 'BLENDER_EEVEE')])
def test01_f12_and_ctrl_f12_bake_each_frame_at_that_frame(tmp_path, addon, mode, surface, engine):
    """With surface shading and the World's glow too (their passes in the same file)."""
    frames = (1, 2, 3) if mode == "animation" else (2,)
    scene, blend = _scene(tmp_path, ui_frame=frames[0] if mode == "animation" else 2, surface=surface,
                          engine=engine)
    proc = subprocess.run([os.path.join(REPO, "tools", "blender.sh"), blend, "--python", DRIVER, "--", mode],
                          capture_output=True, text=True, timeout=300)
    log = proc.stdout[-4000:] + proc.stderr[-2000:]
    assert proc.returncode == 0, log
    assert "rendered without fog" not in proc.stdout, log
    for f in frames:
        assert f"Airlight: fog of frame {f} baked" in proc.stdout, log
        out = tmp_path / (f"out_{f:04d}.exr" if mode == "animation" else "out_.exr")
        assert os.path.exists(out), log
    airlight = {}
    for f in frames:
        baked = _channels(str(tmp_path / "cache" / f"fog_{f:04d}.exr"))
        reference = str(tmp_path / f"ref_{f}.exr")
        assert bpy.ops.airlight.bake(frame=f, filepath=reference) == {'FINISHED'}
        reference = _channels(reference)
        # Every pass (with surface shading: Surface_<group> per light, SurfaceGlow, World).
        assert sorted(baked) == sorted(reference)
        assert any(n.startswith("Fog.Surface") for n in baked) == surface, sorted(baked)
        for name in baked:
            np.testing.assert_allclose(baked[name], reference[name], rtol=1e-5, atol=1e-7,
                                       err_msg=f"frame {f} {name}")
        airlight[f] = np.stack([baked[f"Fog.Airlight.{c}"] for c in "RGB"], axis=-1)
        assert airlight[f].max() > 1e-3
    if mode == "still":
        return
    # The fog moves: each frame's differs from the previous one.
    assert np.abs(airlight[1] - airlight[2]).max() > 1e-3
    assert np.abs(airlight[2] - airlight[3]).max() > 1e-3


def test02_render_thread_frame_changes_leave_the_preview_cache(addon):
    """The render thread's frame handlers (its own depsgraph) must not release the
    viewport preview's cached batches (GPU objects) there; the main thread's frame change
    (Blender's, when the render ends) does."""
    import threading
    state = addon._state
    sentinel = {("Ground", "Ground"): object()}
    state["meshes"] = dict(sentinel)
    generation = state["generation"]
    worker = threading.Thread(target=addon._on_frame_change, args=(bpy.context.scene,))
    worker.start()
    worker.join()
    assert state["meshes"] == sentinel and state["generation"] == generation
    addon._on_frame_change(bpy.context.scene)
    assert state["meshes"] == {} and state["generation"] == generation + 1


def test03_f12_in_stereo_bakes_and_composites_each_view(tmp_path, addon):
    """Stereoscopy in an interactive render: the render thread bakes each eye from its own
    camera (each view's file equals a bake of that view made here, and the eyes differ),
    and each view's composite takes its own passes: out = render x T + A per view, the
    render being the Render Result's view before the compositor (read back here from a
    second F12 with the fog off)."""
    scene, _ = _scene(tmp_path, ui_frame=2, surface=False)
    scene.render.use_multiview = True
    scene.render.views_format = 'STEREO_3D'
    scene.camera.data.stereo.interocular_distance = 0.3
    scene.render.image_settings.views_format = 'INDIVIDUAL'
    bpy.context.view_layer.update()  # the depsgraph handler adds the views' nodes
    blend = str(tmp_path / "stereo.blend")
    bpy.ops.wm.save_as_mainfile(filepath=blend)
    proc = subprocess.run([os.path.join(REPO, "tools", "blender.sh"), blend, "--python", DRIVER, "--", "still"],
                          capture_output=True, text=True, timeout=300)
    log = proc.stdout[-4000:] + proc.stderr[-2000:]
    assert proc.returncode == 0 and "rendered without fog" not in proc.stdout, log
    scene.airlight.enabled = False
    scene.render.filepath = str(tmp_path / "off_")
    bpy.ops.wm.save_as_mainfile(filepath=blend)
    proc = subprocess.run([os.path.join(REPO, "tools", "blender.sh"), blend, "--python", DRIVER, "--", "still"],
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout[-4000:] + proc.stderr[-2000:]
    scene.airlight.enabled = True
    reference = str(tmp_path / "ref.exr")
    assert bpy.ops.airlight.bake(frame=2, filepath=reference) == {'FINISHED'}
    passes = {}
    for suffix in ("_L", "_R"):
        baked = _channels(str(tmp_path / "cache" / f"fog_0002{suffix}.exr"))
        ref = _channels(str(tmp_path / f"ref{suffix}.exr"))
        for name in baked:
            np.testing.assert_allclose(baked[name], ref[name], rtol=1e-5, atol=1e-7, err_msg=f"{suffix} {name}")
        A = np.stack([baked[f"Fog.Airlight.{c}"] for c in "RGB"], axis=-1)
        T = np.stack([baked[f"Fog.Transmittance.{c}"] for c in "RGB"], axis=-1)
        on = read_exr(str(tmp_path / f"out_{suffix}.exr"))[0][..., :3]
        off = read_exr(str(tmp_path / f"off_{suffix}.exr"))[0][..., :3]
        np.testing.assert_allclose(on, off * T + A, rtol=1e-4, atol=1e-5, err_msg=suffix)
        passes[suffix] = A
    assert np.abs(passes["_L"] - passes["_R"]).max() > 1e-3
