"""Renders through `blender -b file -f/-a` with the add-on: fog is baked and composited."""

import os

import bpy
import numpy as np
import pytest

from airlight import render
from conftest import build_plane_scene, cycles_exr_render, draw_panel, exr_pass, read_exr, run_blender


def _render_scene(tmp_path):
    """Tiny Cycles scene: plane, lamp, camera tilted and animated over frames 1-2."""
    scene = build_plane_scene(tmp_path, size=(64, 48))
    cam = scene.camera
    cam.location = (0.0, -6.0, 1.5)
    cam.rotation_euler = (1.35, 0.0, 0.0)
    cam.keyframe_insert("location", frame=1)
    cam.location = (1.5, -5.0, 1.5)
    cam.keyframe_insert("location", frame=2)
    scene.frame_start, scene.frame_end = 1, 2
    cycles_exr_render(scene, 2)
    scene.render.use_compositing = True
    scene.airlight.density = 0.1
    # The plain composite render x T + A (surface shading, on by default with Cycles, adds
    # the light groups' corrections: test_cycles_surface.py).
    scene.airlight.surface_shading = False
    bpy.ops.airlight.setup_compositor()
    path = str(tmp_path / "scene.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    return scene, path


def _run(*args):
    proc = run_blender(*args)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    return proc.stdout


def test01_render_is_plain_render_times_T_plus_A_and_animated_frames_differ(tmp_path):
    scene, blend = _render_scene(tmp_path)
    off_script = tmp_path / "fog_off.py"
    off_script.write_text("import bpy\nbpy.context.scene.airlight.enabled = False\n")
    out_on = _run(blend, "-o", str(tmp_path / "on_####"), "-a")
    assert "Airlight: fog of frame 1 baked" in out_on and "Airlight: fog of frame 2 baked" in out_on
    # A background render composites from memory and writes each frame's EXR beside it.
    assert out_on.count("(passes in memory)") == 2, out_on[-3000:]
    assert "Airlight: frame 2: EXR" in out_on and "beside the render" in out_on, out_on[-3000:]
    _run(blend, "--python", str(off_script), "-o", str(tmp_path / "off_####"), "-a")

    fog1 = tmp_path / "cache" / "fog_0001.exr"
    fog2 = tmp_path / "cache" / "fog_0002.exr"
    # Each frame composites its own fog (baked beside the render, handed over before the
    # compositor reads it): never the images' neutral passes, nor the frame before's.
    for frame, baked in ((1, fog1), (2, fog2)):
        on, _ = read_exr(str(tmp_path / f"on_{frame:04d}.exr"))
        off, _ = read_exr(str(tmp_path / f"off_{frame:04d}.exr"))
        A, T = exr_pass(str(baked), "Airlight"), exr_pass(str(baked), "Transmittance")
        assert A.max() > 0.01 and T.min() < 0.99
        np.testing.assert_allclose(on[..., :3], off[..., :3] * T + A, rtol=1e-4, atol=1e-5)
        assert np.abs(on[..., :3] - off[..., :3]).max() > 0.01

    # The frames baked during -a follow the animated camera: each equals a bake of that
    # frame made here, and they differ from each other.
    for frame, baked in ((1, fog1), (2, fog2)):
        reference = str(tmp_path / f"ref_{frame}.exr")
        assert bpy.ops.airlight.bake(frame=frame, filepath=reference) == {'FINISHED'}
        for name in ("Airlight", "Transmittance"):
            np.testing.assert_allclose(exr_pass(str(baked), name), exr_pass(reference, name),
                                       rtol=1e-6, atol=1e-7)
    assert np.abs(exr_pass(str(fog1), "Airlight") - exr_pass(str(fog2), "Airlight")).max() > 1e-3


def test02_single_frame_render_uses_that_frames_camera(tmp_path):
    scene, blend = _render_scene(tmp_path)
    _run(blend, "-o", str(tmp_path / "on_####"), "-f", "2")
    reference = str(tmp_path / "ref_2.exr")
    assert bpy.ops.airlight.bake(frame=2, filepath=reference) == {'FINISHED'}
    np.testing.assert_allclose(exr_pass(str(tmp_path / "cache" / "fog_0002.exr"), "Airlight"),
                               exr_pass(reference, "Airlight"), rtol=1e-6, atol=1e-7)


def test03_handler_without_camera_prints_instead_of_raising(tmp_path, capsys):
    """The render goes on without fog; the console and the Airlight Fog panel say why, until
    a bake at render time succeeds."""
    scene = build_plane_scene(tmp_path, camera=False)
    render.on_render_pre(scene)
    out = capsys.readouterr().out
    assert "rendered without fog" in out
    frame, reason = render.render_problem(scene)
    assert frame == scene.frame_current and "camera" in reason.lower(), reason
    seen = draw_panel("AIRLIGHT_PT_scene")
    assert f"Frame {frame} rendered without fog:" in seen and reason[:120] in seen
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    cam.location = (0.0, 0.0, 2.0)
    scene.collection.objects.link(cam)
    scene.camera = cam
    render.on_render_pre(scene)
    assert "baked" in capsys.readouterr().out
    assert render.render_problem(scene) is None
    assert not any(str(text).startswith(f"Frame {frame} rendered without fog") for text in draw_panel("AIRLIGHT_PT_scene"))


def test04_settings_persist_through_save_and_reload(tmp_path):
    scene = build_plane_scene(tmp_path)
    scene.airlight.density = 0.125
    scene.airlight.color = (0.5, 0.6, 0.7)
    scene.airlight.model = 'QUADRATURE'
    scene.airlight.aa_samples = 3
    bpy.data.lights["Lamp"].airlight.participate = False
    path = str(tmp_path / "persist.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    bpy.ops.wm.read_homefile(use_empty=True)
    assert bpy.context.scene.airlight.density == pytest.approx(0.05)
    bpy.ops.wm.open_mainfile(filepath=path)
    s = bpy.context.scene.airlight
    assert s.enabled and s.density == pytest.approx(0.125)
    assert tuple(s.color) == pytest.approx((0.5, 0.6, 0.7))
    assert s.model == 'QUADRATURE' and s.aa_samples == 3
    assert bpy.data.lights["Lamp"].airlight.participate is False


def test05_render_region_bakes_the_region_and_composites_in_place(tmp_path):
    """Render > Format > Render Region: the bake covers the region only (and a margin for
    its edge test), and its passes equal the whole frame's bake there to float rounding;
    cropped to the region the passes are the region's size, else they are placed in a
    whole frame of neutral passes. Either way the composite is render x T + A."""
    from airlight import views
    scene, blend = _render_scene(tmp_path)
    whole_ref = str(tmp_path / "whole.exr")
    assert bpy.ops.airlight.bake(frame=1, filepath=whole_ref) == {'FINISHED'}
    r = scene.render
    r.use_border = True
    r.border_min_x, r.border_max_x, r.border_min_y, r.border_max_y = 0.21, 0.67, 0.33, 0.9
    x0, y0, x1, y1 = views.render_region(scene)
    W, H = views.render_size(scene)
    assert (x0, y0, x1, y1) == (13, 15, 42, 43)  # Blender truncates border x size
    rows, cols = slice(H - y1, H - y0), slice(x0, x1)  # EXR rows are top first
    off_script = tmp_path / "fog_off.py"
    off_script.write_text("import bpy\nbpy.context.scene.airlight.enabled = False\n")
    for crop in (True, False):
        r.use_crop_to_border = crop
        path = str(tmp_path / f"region_{crop}.blend")
        bpy.ops.wm.save_as_mainfile(filepath=path, copy=True)
        _run(path, "-o", str(tmp_path / f"on_{crop}_####"), "-f", "1")
        _run(path, "--python", str(off_script), "-o", str(tmp_path / f"off_{crop}_####"), "-f", "1")
        on, _ = read_exr(str(tmp_path / f"on_{crop}_0001.exr"))
        off, _ = read_exr(str(tmp_path / f"off_{crop}_0001.exr"))
        fog = str(tmp_path / "cache" / "fog_0001.exr")
        A, T = exr_pass(fog, "Airlight"), exr_pass(fog, "Transmittance")
        assert A.shape == on[..., :3].shape == ((y1 - y0, x1 - x0, 3) if crop else (H, W, 3))
        np.testing.assert_allclose(on[..., :3], off[..., :3] * T + A, rtol=1e-4, atol=1e-5)
        inside = (slice(None), slice(None)) if crop else (rows, cols)
        for name, baked in (("Airlight", A), ("Transmittance", T)):
            np.testing.assert_allclose(baked[inside], exr_pass(whole_ref, name)[rows, cols], rtol=1e-5, atol=1e-7)
        assert A[inside].max() > 0.01 and T[inside].min() < 0.99
        if not crop:
            outside = np.ones((H, W), bool)
            outside[rows, cols] = False
            assert (A[outside] == 0.0).all() and (T[outside] == 1.0).all()


def _run_without_addon(tmp_path, *args):
    """Plain `blender -b --factory-startup` with empty user folders: a render farm worker the
    add-on was never installed on."""
    import os
    import subprocess
    user = tmp_path / "worker_user"
    (user / "scripts").mkdir(parents=True, exist_ok=True)
    (user / "config").mkdir(exist_ok=True)
    env = dict(os.environ, BLENDER_USER_SCRIPTS=str(user / "scripts"), BLENDER_USER_CONFIG=str(user / "config"))
    proc = subprocess.run([os.environ.get("BLENDER", "blender"), "-b", "--factory-startup", *args],
                          capture_output=True, text=True, timeout=120, env=env)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    assert "Airlight: " not in proc.stdout  # the add-on (which prints so) is not there
    return proc.stdout


def test06_fog_blend_renders_unfogged_on_a_machine_without_the_addon(tmp_path):
    """A fog .blend rendered without the add-on and without its cache folder (a farm worker):
    the frame equals the plain render (it came out magenta: the compositor's Image node read a
    missing EXR). The file holds the fog nodes muted, the frame's label says why, and this
    session keeps them on, unchanged by the save; with the add-on the render is fogged."""
    import json
    import shutil
    scene, _ = _render_scene(tmp_path)
    assert bpy.ops.airlight.bake(frame=1) == {'FINISHED'}
    tree = scene.node_tree
    fog_nodes = [n for n in tree.nodes if n.name.startswith("Airlight") and n.bl_idname != "NodeFrame"
                 and n.name != "Airlight Passes"]
    assert fog_nodes and not any(n.mute for n in fog_nodes)
    blend = str(tmp_path / "farm.blend")
    bpy.ops.wm.save_as_mainfile(filepath=blend)
    assert not any(n.mute for n in fog_nodes) and tree.nodes["Airlight Fog"].label == "Airlight Fog"
    assert not bpy.data.is_dirty
    shutil.rmtree(tmp_path / "cache")
    _run_without_addon(tmp_path, blend, "-o", str(tmp_path / "worker_####"), "-f", "1")
    _run_without_addon(tmp_path, blend, "--python-expr", "import bpy; bpy.context.scene.render.use_compositing = False",
                       "-o", str(tmp_path / "plain_####"), "-f", "1")
    worker, _ = read_exr(str(tmp_path / "worker_0001.exr"))
    plain, _ = read_exr(str(tmp_path / "plain_0001.exr"))
    np.testing.assert_array_equal(worker, plain)
    magenta = (worker[..., 0] > 0.5) & (worker[..., 2] > 0.5) & (worker[..., 1] < 0.1 * worker[..., 0])
    assert not magenta.any()
    listing = _run_without_addon(tmp_path, blend, "--python-expr", (
        "import bpy, json\nfor n in bpy.context.scene.node_tree.nodes:\n"
        "    print('NODE', json.dumps([n.name, n.mute, n.label]))"))
    saved = {name: (mute, label) for name, mute, label in
             (json.loads(line[5:]) for line in listing.splitlines() if line.startswith("NODE "))}
    assert all(saved[n.name][0] for n in fog_nodes), saved
    assert saved["Airlight Fog"][1] == "Airlight Fog (muted in the file: the add-on enables it)"

    out = _run(blend, "-o", str(tmp_path / "fogged_####"), "-f", "1")
    assert "Airlight: fog of frame 1 baked" in out
    fogged, _ = read_exr(str(tmp_path / "fogged_0001.exr"))
    A = exr_pass(str(tmp_path / "cache" / "fog_0001.exr"), "Airlight")
    T = exr_pass(str(tmp_path / "cache" / "fog_0001.exr"), "Transmittance")
    np.testing.assert_allclose(fogged[..., :3], plain[..., :3] * T + A, rtol=1e-4, atol=1e-5)


def test07_a_failed_bake_never_composites_an_earlier_frame(tmp_path, capsys):
    """Frame 1 bakes; then the cache folder cannot be written (a farm's shared storage gone
    read-only): frame 2 renders without fog, and the compositor reads neutral passes (kept
    in the system's temporary folder then), not frame 1's fog."""
    from airlight import compositor
    scene = build_plane_scene(tmp_path)
    scene.airlight.cache_dir = str(tmp_path / "cache")
    bpy.ops.airlight.setup_compositor()
    scene.frame_set(1)
    render.on_render_pre(scene)
    image = bpy.data.images[compositor.IMAGE_NAME]
    assert bpy.path.abspath(image.filepath) == str(tmp_path / "cache" / "fog_0001.exr")
    scene.airlight.cache_dir = "/proc/airlight_no_such_folder/"
    scene.frame_set(2)
    capsys.readouterr()
    render.on_render_pre(scene)
    assert "Airlight: frame 2 rendered without fog" in capsys.readouterr().out
    path = bpy.path.abspath(bpy.data.images[compositor.IMAGE_NAME].filepath)
    assert "fog_neutral_" in os.path.basename(path) and os.path.exists(path), path
    assert exr_pass(path, "Airlight").max() == 0.0 and exr_pass(path, "Transmittance").min() == 1.0
