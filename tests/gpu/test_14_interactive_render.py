"""Interactive renders (F12 / Ctrl+F12 in a window) bake each frame's fog at that frame.

They run in the render job's thread, where the add-on cannot set the frame: the bake
takes the render's own depsgraph (render.py's on_render_frame_evaluated, a
frame_change_post handler). A windowed Blender (support/interactive_render.py) renders an
animation with Ctrl+F12 while the UI stays on frame 1, or a still with F12; the camera
and an emitter's smoke move over the frames. Each frame's baked fog must equal a bake of
that frame made here (bpy.ops.airlight.bake sets the frame in the main thread), so a bake
of the UI's frame instead fails the animation.
"""

import os
import subprocess

import bpy
import numpy as np
import pytest

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.normpath(os.path.join(HERE, "..", ".."))
DRIVER = os.path.join(HERE, "support", "interactive_render.py")


def _exr_pass(path, name):
    import OpenImageIO as oiio
    inp = oiio.ImageInput.open(path)
    assert inp is not None, oiio.geterror()
    spec = inp.spec()
    pixels = np.asarray(inp.read_image(oiio.FLOAT)).reshape(spec.height, spec.width, spec.nchannels)
    names = list(spec.channelnames)
    inp.close()
    return pixels[..., [names.index(f"Fog.{name}.{c}") for c in "RGB"]]


def _scene(tmp_path, ui_frame):
    """Ground plane, point lamp, a camera moving over frames 1-3 and an emitter's smoke;
    Cycles at 1 sample (the fog passes do not depend on it), EXR output."""
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
    scene.render.engine = 'CYCLES'
    scene.cycles.samples = 1
    scene.cycles.use_denoising = False
    scene.cycles.device = 'CPU'
    scene.view_settings.view_transform = 'Standard'
    scene.render.image_settings.file_format = 'OPEN_EXR'
    scene.render.image_settings.color_depth = '32'
    scene.render.use_compositing = True
    scene.render.filepath = str(tmp_path / "out_")
    scene.airlight.enabled = True
    scene.airlight.density = 0.02
    scene.airlight.cache_dir = str(tmp_path / "cache") + os.sep
    scene.cursor.location = (0.0, 0.0, 0.4)
    assert bpy.ops.airlight.add_emitter() == {'FINISHED'}
    emitter = next(o for o in scene.objects if o.airlight_emitter.is_emitter).airlight_emitter
    emitter.rate, emitter.lifetime, emitter.velocity = 16.0, 2.0, (0.6, 0.0, 0.4)
    emitter.scale, emitter.amplitude, emitter.frame_start, emitter.frame_end = 3.0, 3.0, 1, 3
    bpy.ops.airlight.setup_compositor()
    scene.frame_set(ui_frame)
    blend = str(tmp_path / "interactive.blend")
    bpy.ops.wm.save_as_mainfile(filepath=blend)
    return scene, blend


@pytest.mark.parametrize("mode", ["animation", "still"])
def test01_f12_and_ctrl_f12_bake_each_frame_at_that_frame(tmp_path, addon, mode):
    frames = (1, 2, 3) if mode == "animation" else (2,)
    scene, blend = _scene(tmp_path, ui_frame=frames[0] if mode == "animation" else 2)
    proc = subprocess.run([os.path.join(REPO, "tools", "blender.sh"), blend, "--python", DRIVER, "--", mode],
                          capture_output=True, text=True, timeout=300)
    log = proc.stdout[-4000:] + proc.stderr[-2000:]
    assert proc.returncode == 0, log
    for f in frames:
        assert f"Airlight: fog of frame {f} baked" in proc.stdout, log
        out = tmp_path / (f"out_{f:04d}.exr" if mode == "animation" else "out_.exr")
        assert os.path.exists(out), log
    airlight = {}
    for f in frames:
        baked = str(tmp_path / "cache" / f"fog_{f:04d}.exr")
        reference = str(tmp_path / f"ref_{f}.exr")
        assert bpy.ops.airlight.bake(frame=f, filepath=reference) == {'FINISHED'}
        airlight[f] = _exr_pass(baked, "Airlight")
        assert airlight[f].max() > 1e-3
        for name in ("Airlight", "Transmittance"):
            np.testing.assert_allclose(_exr_pass(baked, name), _exr_pass(reference, name), rtol=1e-5, atol=1e-7,
                                       err_msg=f"frame {f} {name}")
    if mode == "still":
        return
    # The fog moves: each frame's differs from the previous one.
    assert np.abs(airlight[1] - airlight[2]).max() > 1e-3
    assert np.abs(airlight[2] - airlight[3]).max() > 1e-3
