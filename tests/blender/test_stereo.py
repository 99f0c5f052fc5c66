"""Stereoscopy (Output > Stereoscopy): every view is baked from its own camera and the
compositor takes each view's passes.

The eyes' cameras follow Blender's Stereo 3D rules (scene_description._stereo_model_matrix,
_stereo_shift_x); the reference is Cycles: a pole against an empty world rendered in stereo,
whose silhouette (the alpha's centroid per row) must sit where the bake's own hits (its
transmittance > 0; the world behind is fog to infinity, T = 0) put it in each eye."""


import bpy
import numpy as np
import pytest

from airlight import bake, scene_description, views
from conftest import exr_pass, poles_scene, read_exr, run_blender

# Eyes 0.5 m apart, the pole 3 m away and the convergence plane at 50 m: ~5 px of disparity
# per eye at 64 px wide (a quarter of the interocular at a pivot eye: twice that), so
# that the scene camera's bake (no per-view camera) misses Cycles' silhouette by that much.
INTEROCULAR = 0.5


def _pole_scene(tmp_path, mode='OFFAXIS', pivot='CENTER'):
    scene, _ = poles_scene(tmp_path, [((0.3, 3.0, 1.0), (0.3, 0.3, 4.0))], 16)
    scene.render.image_settings.views_format = 'INDIVIDUAL'
    stereo = scene.camera.data.stereo
    stereo.interocular_distance = INTEROCULAR
    stereo.convergence_distance = 50.0
    stereo.convergence_mode = mode
    stereo.pivot = pivot
    scene.render.use_multiview = True
    scene.render.views_format = 'STEREO_3D'
    return scene


def _centroids(weight):
    """Per image row with enough weight, the weighted mean column (pixel centres)."""
    cols = np.arange(weight.shape[1]) + 0.5
    total = weight.sum(axis=1)
    rows = total > 2.0
    return rows, (weight * cols).sum(axis=1)[rows] / total[rows]


def test01_views_and_their_files():
    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    assert views.render_views(scene) == [(None, "")]
    assert bake.view_paths(scene, "/c/fog_0001.exr") == [(None, "/c/fog_0001.exr")]
    scene.render.use_multiview = True
    scene.render.views_format = 'STEREO_3D'
    assert views.render_views(scene) == [("left", "_L"), ("right", "_R")]
    assert bake.view_paths(scene, "/c/fog_0001.exr") == [("left", "/c/fog_0001_L.exr"),
                                                          ("right", "/c/fog_0001_R.exr")]
    scene.render.views["right"].use = False
    assert views.render_views(scene) == [("left", "_L")]
    scene.render.views["right"].use = True
    # Multi-View: each view's camera by its suffix (Blender's rule), else the scene camera.
    scene.render.views_format = 'MULTIVIEW'
    cams = {}
    for name, x in (("Cam_L", -1.0), ("Cam_R", 2.0)):
        cams[name] = bpy.data.objects.new(name, bpy.data.cameras.new(name))
        cams[name].location = (x, 0.0, 0.0)
        scene.collection.objects.link(cams[name])
    scene.camera = cams["Cam_L"]
    scene.render.resolution_x, scene.render.resolution_y = 32, 24
    assert views.view_camera(scene, "left") == cams["Cam_L"]
    assert views.view_camera(scene, "right") == cams["Cam_R"]
    depsgraph = bpy.context.evaluated_depsgraph_get()
    assert scene_description.export_camera(scene, depsgraph, "right")[2][0, 3] == pytest.approx(2.0)
    assert scene_description.export_camera(scene, depsgraph, "left")[2][0, 3] == pytest.approx(-1.0)
    scene.camera = bpy.data.objects.new("Other", bpy.data.cameras.new("Other"))
    scene.collection.objects.link(scene.camera)
    assert views.view_camera(scene, "right") == scene.camera


@pytest.mark.parametrize("mode,pivot", [('OFFAXIS', 'CENTER'), ('PARALLEL', 'CENTER'), ('TOE', 'CENTER'),
                                        ('OFFAXIS', 'LEFT'), ('TOE', 'RIGHT')])
def test02_each_eye_sees_the_pole_where_cycles_renders_it(tmp_path, mode, pivot):
    scene = _pole_scene(tmp_path, mode, pivot)
    # Cycles' stereo render, without the fog composite (its alpha is the pole's coverage).
    scene.airlight.enabled = False
    scene.render.filepath = str(tmp_path / "cycles")
    bpy.ops.render.render(write_still=True)
    scene.airlight.enabled = True
    depsgraph = bpy.context.evaluated_depsgraph_get()
    jobs = bake.prepare_views(scene, depsgraph, str(tmp_path / "fog.exr"))
    bake.run_views(jobs)
    centre_job = bake.prepare(scene, depsgraph) + (str(tmp_path / "centre.exr"),)
    bake.run(*centre_job)
    centre_T = exr_pass(centre_job[2], "Transmittance")[..., 0]
    report = []
    for (view, suffix), (_, _, path) in zip(views.render_views(scene), jobs):
        alpha = read_exr(str(tmp_path / f"cycles{suffix}.exr"))[0][..., 3]
        T = exr_pass(path, "Transmittance")[..., 0]
        rows_c, x_cycles = _centroids(alpha)
        rows_b, x_bake = _centroids((T > 1e-6).astype(np.float64))
        rows_0, x_centre = _centroids((centre_T > 1e-6).astype(np.float64))
        assert rows_c.sum() > 20 and (rows_c == rows_b).mean() > 0.9, (view, rows_c.sum(), rows_b.sum())
        both = rows_c & rows_b & rows_0
        error = np.abs(x_cycles[both[rows_c]] - x_bake[both[rows_b]]).mean()
        centre_error = np.abs(x_cycles[both[rows_c]] - x_centre[both[rows_0]]).mean()
        report.append((view, error, centre_error))
        # A pivot eye is the scene camera itself; the other eye(s) are ~5-10 px off it.
        pivot_eye = (pivot == 'LEFT' and view == "left") or (pivot == 'RIGHT' and view == "right")
        assert error < 0.5, report
        if not pivot_eye:
            assert centre_error > 3.0, report  # the test can tell the eyes apart
    print(f"{mode} {pivot}: " + ", ".join(f"{v} {e:.3f} px (scene camera {c:.2f} px)" for v, e, c in report))


def _check_views(tmp_path, out_prefix):
    """Each view of the render _out_prefix_ equals the plain render x T + A of its own bake."""
    for suffix in ("_L", "_R"):
        fog = str(tmp_path / "cache" / f"fog_0001{suffix}.exr")
        on = read_exr(str(tmp_path / f"{out_prefix}_0001{suffix}.exr"))[0]
        off = read_exr(str(tmp_path / f"off_0001{suffix}.exr"))[0]
        A, T = exr_pass(fog, "Airlight"), exr_pass(fog, "Transmittance")
        np.testing.assert_allclose(on[..., :3], off[..., :3] * T + A, rtol=1e-4, atol=1e-5)


def test03_stereo_render_composites_each_views_own_bake(tmp_path):
    scene = _pole_scene(tmp_path)
    scene.render.film_transparent = False
    scene.cycles.samples = 2
    bpy.ops.airlight.setup_compositor()
    blend = str(tmp_path / "stereo.blend")
    bpy.ops.wm.save_as_mainfile(filepath=blend)
    off_script = tmp_path / "fog_off.py"
    off_script.write_text("import bpy\nbpy.context.scene.airlight.enabled = False\n")
    for args in ((blend, "-o", str(tmp_path / "on_####"), "-f", "1"),
                 (blend, "--python", str(off_script), "-o", str(tmp_path / "off_####"), "-f", "1")):
        proc = run_blender(*args)
        assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    _check_views(tmp_path, "on")
    # The eyes' passes differ (the pole's silhouette moved), so each view took its own.
    T_L, T_R = (exr_pass(str(tmp_path / "cache" / f"fog_0001{v}.exr"), "Transmittance") for v in ("_L", "_R"))
    assert np.abs(T_L - T_R).max() > 0.1


def test04_stereo_switched_on_after_the_compositor_was_set_up(tmp_path):
    """A file whose fog nodes were set up without Stereoscopy (an older file, or stereo
    switched on by a script): the nodes for the views are added on load and when a script
    turns it on before rendering, so that the first frame composites each view's bake."""
    from airlight import compositor
    scene = _pole_scene(tmp_path)
    scene.render.film_transparent = False
    scene.cycles.samples = 2
    scene.render.use_multiview = False
    bpy.ops.airlight.setup_compositor()
    assert compositor.views_ready(scene)
    mono = str(tmp_path / "mono.blend")
    bpy.ops.wm.save_as_mainfile(filepath=mono)
    scene.render.use_multiview = True
    compositor.on_depsgraph_update_post(scene, bpy.context.evaluated_depsgraph_get())
    assert compositor.views_ready(scene)  # (the handler set them up)
    scene.render.use_multiview = False
    compositor.on_depsgraph_update_post(scene, bpy.context.evaluated_depsgraph_get())
    assert compositor.views_ready(scene) and not compositor._view_nodes(scene.node_tree)
    off_script = tmp_path / "fog_off.py"
    off_script.write_text("import bpy\nbpy.context.scene.render.use_multiview = True\n"
                          "bpy.context.scene.airlight.enabled = False\n")
    on_script = tmp_path / "stereo_on.py"
    on_script.write_text("import bpy\nbpy.context.scene.render.use_multiview = True\n")
    for args in ((mono, "--python", str(off_script), "-o", str(tmp_path / "off_####"), "-f", "1"),
                 (mono, "--python", str(on_script), "-o", str(tmp_path / "script_####"), "-f", "1")):
        proc = run_blender(*args)
        assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    _check_views(tmp_path, "script")


def test05_setting_up_again_changes_no_link(tmp_path, monkeypatch):
    """Each render points the fog nodes at the frame's files (compositor.sync, also from an
    interactive render's thread): with the views' switches in place that must not relink
    anything (the UI may be drawing the tree), surface shading's chain included."""
    from airlight import compositor
    scene = _pole_scene(tmp_path)
    scene.airlight.surface_shading = True
    bpy.ops.airlight.setup_compositor()
    path = bake.bake_frame(scene, bpy.context.evaluated_depsgraph_get())[0]
    compositor.sync(scene, path)
    tree = scene.node_tree
    assert compositor.views_ready(scene)
    switches = [n for n in tree.nodes if n.name.startswith(compositor.VIEW_SWITCH_PREFIX)]
    assert len(switches) >= 3, [n.name for n in switches]  # Airlight, Transmittance, a surface pass
    relinked = []
    link = compositor._link

    def spy(tree, from_socket, to_socket):  # records a link whose source _link changes
        source = to_socket.links[0].from_socket if to_socket.is_linked else None
        link(tree, from_socket, to_socket)
        if to_socket.links[0].from_socket != source:
            relinked.append((from_socket.node.name, from_socket.name, to_socket.node.name))
    monkeypatch.setattr(compositor, "_link", spy)
    before = [(l.from_node.name, l.from_socket.identifier, l.to_node.name, l.to_socket.identifier) for l in tree.links]
    path = bake.bake_frame(scene, bpy.context.evaluated_depsgraph_get())[0]
    compositor.sync(scene, path)
    after = [(l.from_node.name, l.from_socket.identifier, l.to_node.name, l.to_socket.identifier) for l in tree.links]
    assert not relinked and after == before, relinked
    # Without Stereoscopy the fog nodes read the Image node again.
    scene.render.use_multiview = False
    path = bake.bake_frame(scene, bpy.context.evaluated_depsgraph_get())[0]
    compositor.sync(scene, path)
    assert not compositor._view_nodes(tree) and compositor.is_complete(scene)
    image_node = tree.nodes[compositor.NODE_IMAGE]
    assert tree.nodes[compositor.NODE_MULTIPLY].inputs[2].links[0].from_node == image_node
