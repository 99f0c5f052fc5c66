"""The passes' node group: the multilayer file or in-memory images feed the fog nodes.

A background render (these tests run in one) composites from memory (compositor.fill); the
renders' own comparison with the baked EXR is test_render.py's test01.
"""
import os

import bpy
import numpy as np

from airlight import cache, compositor, render
from conftest import build_plane_scene, exr_pass


def _old_tree(scene, tmp_path, extra_pass):
    """A tree as an earlier version set it up: a multilayer Image node named "Airlight
    Passes" on a baked file, and a user's Mix node reading its pass _extra_pass_."""
    compositor.setup(scene)
    tree = scene.node_tree
    group_node = tree.nodes[compositor.NODE_IMAGE]
    targets = {s.name: [l.to_socket for l in s.links] for s in group_node.outputs}
    tree.nodes.remove(group_node)
    path = str(tmp_path / "old.exr")
    h, w = 12, 16
    cache.write_passes(path, np.zeros((h, w, 3), np.float32), np.ones((h, w, 3), np.float32),
                       {extra_pass: np.full((h, w, 3), 0.5, np.float32)})
    old = tree.nodes.new("CompositorNodeImage")
    old.name = compositor.NODE_IMAGE
    old.image = bpy.data.images.load(path)
    for name, sockets in targets.items():
        for socket in sockets:
            tree.links.new(old.outputs[name], socket)
    user = tree.nodes.new("CompositorNodeMixRGB")
    user.name = "User Mix"
    tree.links.new(old.outputs[extra_pass], user.inputs[1])
    return tree, user


def test01_a_tree_from_an_earlier_version_moves_to_the_group_with_the_users_links(tmp_path):
    scene = build_plane_scene(tmp_path)
    tree, user = _old_tree(scene, tmp_path, "Airlight_Key")
    assert not compositor.is_complete(scene)
    compositor.setup(scene)
    node = tree.nodes[compositor.NODE_IMAGE]
    assert node.bl_idname == "CompositorNodeGroup" and node.node_tree.name == compositor.GROUP_NAME
    assert compositor.is_complete(scene)
    assert user.inputs[1].links[0].from_socket == node.outputs["Airlight_Key"]
    assert tree.nodes["Airlight Multiply"].inputs[2].links[0].from_socket == node.outputs["Transmittance"]
    assert compositor.file_image(tree).filepath.endswith("old.exr")
    assert len([n for n in tree.nodes if n.name.startswith(compositor.NODE_IMAGE)]) == 1
    compositor.setup(scene)
    assert len([n for n in tree.nodes if n.name.startswith(compositor.NODE_IMAGE)]) == 1


def test02_a_background_render_reads_memory_and_a_baked_file_moves_it_back(tmp_path):
    scene = build_plane_scene(tmp_path)
    compositor.setup(scene)
    assert not compositor.in_memory(scene)  # set up on neutral passes from a file
    compositor.choose_source(scene)  # (what render_init does; these tests run in the background)
    assert compositor.in_memory(scene)
    path = str(tmp_path / "baked.exr")
    cache.write_passes(path, np.zeros((4, 4, 3), np.float32), np.ones((4, 4, 3), np.float32))
    compositor.sync(scene, path)  # Bake Fog: the file is what the composite shows
    assert not compositor.in_memory(scene)
    group = scene.node_tree.nodes[compositor.NODE_IMAGE].node_tree
    socket = next(s for s in group.nodes if s.type == 'GROUP_OUTPUT').inputs["Transmittance"]
    assert socket.links[0].from_node.name == compositor.NODE_FILE


def _image(name):
    group = bpy.data.node_groups[compositor.GROUP_NAME]
    return group.nodes[compositor._memory_name(name)].image


def _pixels(name):
    image = _image(name)
    w, h = image.size
    out = np.empty(w * h * 4, np.float32)
    image.pixels.foreach_get(out)
    return out.reshape(h, w, 4)


def test03_fill_copies_the_linked_passes_top_row_first_and_a_missing_one_is_neutral(tmp_path):
    scene = build_plane_scene(tmp_path, size=(32, 24))
    tree, user = _old_tree(scene, tmp_path, "Airlight_Key")
    compositor.setup(scene)
    compositor.choose_source(scene)
    h, w = 24, 32
    rows = np.linspace(0.0, 1.0, h, dtype=np.float32)[:, None, None]
    airlight = np.broadcast_to(rows * np.array([1.0, 2.0, 3.0], np.float32), (h, w, 3)).copy()
    transmittance = np.full((h, w, 3), 0.25, np.float32)
    compositor.fill(scene, {"Airlight": airlight, "Transmittance": transmittance, "Unlinked": airlight})
    got = _pixels("Airlight")
    np.testing.assert_array_equal(got[::-1, :, :3], airlight)  # Blender's rows start at the bottom
    assert (got[..., 3] == 1.0).all()
    np.testing.assert_array_equal(_pixels("Transmittance")[..., :3], 0.25)
    # The user's light pass is not in this bake (the light is gone): 0, not the last frame's.
    np.testing.assert_array_equal(_pixels("Airlight_Key")[..., :3], 0.0)
    # An output nothing reads is not copied.
    unlinked = bpy.data.node_groups[compositor.GROUP_NAME].nodes.get(compositor._memory_name("Unlinked"))
    assert unlinked is None or tuple(unlinked.image.size) != (w, h)
    # A new render size: the images follow.
    small = {"Airlight": airlight[:12, :16].copy(), "Transmittance": transmittance[:12, :16].copy()}
    compositor.fill(scene, small)
    assert tuple(_image("Airlight").size) == (16, 12)
    np.testing.assert_array_equal(_pixels("Airlight")[::-1, :, :3], small["Airlight"])


def test04_reopened_in_memory_images_are_neutral(tmp_path):
    """A file saved after a background render keeps no pixels of the in-memory images: they
    regenerate as passes that leave the image unchanged."""
    scene = build_plane_scene(tmp_path)
    compositor.setup(scene)
    compositor.choose_source(scene)
    h, w = 8, 8
    compositor.fill(scene, {"Airlight": np.full((h, w, 3), 0.3, np.float32),
                            "Transmittance": np.full((h, w, 3), 0.2, np.float32)})
    path = str(tmp_path / "saved.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    bpy.ops.wm.open_mainfile(filepath=path)
    np.testing.assert_array_equal(_pixels("Airlight")[..., :3], 0.0)
    np.testing.assert_array_equal(_pixels("Transmittance")[..., :3], 1.0)


def test05_fill_neutral_leaves_the_image_unchanged(tmp_path):
    scene = build_plane_scene(tmp_path, size=(20, 10))
    compositor.setup(scene)
    compositor.choose_source(scene)
    compositor.fill(scene, {"Airlight": np.full((10, 20, 3), 0.3, np.float32),
                            "Transmittance": np.full((10, 20, 3), 0.2, np.float32)})
    compositor.fill_neutral(scene)
    np.testing.assert_array_equal(_pixels("Airlight")[..., :3], 0.0)
    np.testing.assert_array_equal(_pixels("Transmittance")[..., :3], 1.0)


def test06_a_render_without_cycles_drops_the_surface_chain_and_loading_brings_it_back(tmp_path):
    """The surface-shading chain reads passes only Cycles makes: a background render with
    another engine composites without it (nothing to fill), and the file, saved then,
    gets it back when it opens for Cycles."""
    scene = build_plane_scene(tmp_path)
    scene.render.engine = 'CYCLES'
    bpy.ops.airlight.setup_compositor()
    surface_nodes = lambda: [n for n in scene.node_tree.nodes  # noqa: E731
                             if n.name.startswith(compositor.SURFACE_NODE_PREFIX)]
    assert surface_nodes()
    scene.render.engine = 'BLENDER_WORKBENCH'
    compositor.choose_source(scene)
    assert compositor.in_memory(scene) and not surface_nodes()
    outputs = [s.name for s in scene.node_tree.nodes[compositor.NODE_IMAGE].outputs if s.is_linked]
    assert sorted(outputs) == ["Airlight", "Transmittance"]
    scene.render.engine = 'CYCLES'
    path = str(tmp_path / "after_workbench.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    bpy.ops.wm.open_mainfile(filepath=path)
    scene = bpy.context.scene
    assert surface_nodes()


def test07_pass_files_written_beside_the_render_say_how_it_went(tmp_path):
    zeros = np.zeros((4, 4, 3), np.float32)
    passes = {"Airlight": zeros, "Transmittance": zeros + 1.0}
    good = cache.PassFile(str(tmp_path / "good.exr"), passes, True)
    bad = cache.PassFile("/proc/airlight_no_such_folder/bad.exr", passes, True)
    seconds, error = cache.write_files([good])
    assert error is None and seconds >= 0.0 and os.path.exists(good.filepath)
    _, error = cache.write_files([bad])
    assert "Cannot create the fog cache folder" in error


def test08_a_frame_whose_passes_cannot_reach_the_compositor_says_so_and_composites_none(
        tmp_path, monkeypatch, capsys):
    scene = build_plane_scene(tmp_path, size=(16, 12))
    scene.airlight.cache_dir = str(tmp_path / "cache")
    compositor.setup(scene)
    compositor.choose_source(scene)
    compositor.fill(scene, {"Airlight": np.full((12, 16, 3), 0.3, np.float32),
                            "Transmittance": np.full((12, 16, 3), 0.2, np.float32)})

    def no_memory(*_):
        raise MemoryError("no room for the images")
    monkeypatch.setattr(compositor, "fill", no_memory)
    capsys.readouterr()
    render.on_render_pre(scene)
    render.on_render_post(scene)
    out = capsys.readouterr().out
    assert "rendered without fog: cannot hand the passes to the compositor: MemoryError" in out, out
    np.testing.assert_array_equal(_pixels("Airlight")[..., :3], 0.0)  # not the last frame's fog
    np.testing.assert_array_equal(_pixels("Transmittance")[..., :3], 1.0)
    assert "EXR" in out and os.path.exists(tmp_path / "cache" / "fog_0001.exr")  # still saved


def test09_the_bake_beside_the_render_reaches_the_compositor_when_it_announces_itself(tmp_path, capsys):
    """A Workbench render's bake runs in a thread beside the render (render._BakeBeside):
    render_pre only starts it, the compositor's first statistics line hands its passes to the
    images, and a bake that fails in the thread (the cache folder gone) says so there and
    leaves neutral passes, not the frame before's fog."""
    scene = build_plane_scene(tmp_path, size=(16, 12))
    scene.render.engine = 'BLENDER_WORKBENCH'
    scene.airlight.cache_dir = str(tmp_path / "cache")
    compositor.setup(scene)
    compositor.choose_source(scene)
    compositor.fill_neutral(scene)
    scene.frame_set(1)
    render.on_render_pre(scene)
    job = render._beside["job"]
    assert job is not None and not job.composited  # baking beside the render
    render.on_render_stats(None)
    assert job.composited
    fog1 = str(tmp_path / "cache" / "fog_0001.exr")
    render.on_render_post(scene)  # the EXR is whole
    assert render._beside["job"] is None
    np.testing.assert_allclose(_pixels("Airlight")[::-1, :, :3], exr_pass(fog1, "Airlight"), rtol=1e-3, atol=1e-6)
    assert _pixels("Airlight")[..., :3].max() > 0.01

    scene.airlight.cache_dir = "/proc/airlight_no_such_folder/"
    scene.frame_set(2)
    capsys.readouterr()
    render.on_render_pre(scene)
    render.on_render_stats(None)
    out = capsys.readouterr().out
    assert "Airlight: frame 2 rendered without fog" in out and "fog cache folder" in out, out
    render.on_render_post(scene)
    np.testing.assert_array_equal(_pixels("Airlight")[..., :3], 0.0)
    np.testing.assert_array_equal(_pixels("Transmittance")[..., :3], 1.0)


def test10_the_bake_gives_way_only_to_an_engine_that_leaves_a_core_idle(tmp_path, monkeypatch):
    """Beside Workbench the bake's thread lowers its priority (and the native bake's threads
    inherit it: native/core/parallel_test.cpp); with Cycles render_pre waits for the bake
    itself, at the normal priority (an EXR written at the lowest one beside Cycles waited
    for the render's end)."""
    scene = build_plane_scene(tmp_path, size=(16, 12))
    scene.airlight.cache_dir = str(tmp_path / "cache")
    compositor.setup(scene)
    compositor.choose_source(scene)
    lowered = []
    real = render._yield_to_the_engine
    monkeypatch.setattr(render, "_yield_to_the_engine", lambda: (lowered.append(True), real()))
    for frame, engine in ((1, 'BLENDER_WORKBENCH'), (2, 'CYCLES')):
        scene.render.engine = engine
        scene.frame_set(frame)
        render.on_render_pre(scene)
        job = render._beside["job"]
        assert job.yields == (engine == 'BLENDER_WORKBENCH')
        assert job.composited == (engine == 'CYCLES'), engine  # Cycles: baked before the engine starts
        render.on_render_stats(None)
        render.on_render_post(scene)
        assert os.path.exists(tmp_path / "cache" / f"fog_{frame:04d}.exr")
    assert lowered == [True]
