"""Compositor fog nodes: idempotent setup that keeps the user's nodes."""
import bpy

from airlight import compositor
from conftest import build_plane_scene


def _airlight_nodes(tree):
    return sorted(n.name for n in tree.nodes if n.name.startswith("Airlight"))


def test01_setup_twice_gives_one_set_of_nodes(tmp_path):
    scene = build_plane_scene(tmp_path)
    bpy.ops.airlight.setup_compositor()
    tree = scene.node_tree
    first = (_airlight_nodes(tree), len(tree.nodes), len(tree.links))
    bpy.ops.airlight.setup_compositor()
    compositor.setup(scene)
    assert (_airlight_nodes(tree), len(tree.nodes), len(tree.links)) == first
    alpha_nodes = ["Airlight Alpha"] + [f"Airlight Alpha {n}" for n in (
        "Image", "Minus 1", "Sum RG", "Sum RGB", "Third", "Transmittance", "Value")]
    assert _airlight_nodes(tree) == sorted(["Airlight Add", "Airlight Fog", "Airlight Multiply",
                                            "Airlight Passes"] + alpha_nodes)
    composite = next(n for n in tree.nodes if n.type == 'COMPOSITE')
    assert composite.inputs["Image"].links[0].from_node.name == "Airlight Alpha"
    assert tree.nodes["Airlight Alpha"].inputs["Image"].links[0].from_node.name == "Airlight Add"
    multiply = tree.nodes["Airlight Multiply"]
    assert multiply.inputs[1].links[0].from_node.type == 'R_LAYERS'
    assert multiply.blend_type == 'MULTIPLY' and tree.nodes["Airlight Add"].blend_type == 'ADD'
    assert tree.nodes["Airlight Passes"].parent.name == "Airlight Fog"


def test02_inserts_after_users_node_and_keeps_it(tmp_path):
    scene = build_plane_scene(tmp_path)
    scene.use_nodes = True
    tree = scene.node_tree
    render_layers = next(n for n in tree.nodes if n.type == 'R_LAYERS')
    composite = next(n for n in tree.nodes if n.type == 'COMPOSITE')
    glare = tree.nodes.new("CompositorNodeGlare")
    glare.name = "User Glare"
    tree.links.new(render_layers.outputs["Image"], glare.inputs["Image"])
    tree.links.new(glare.outputs["Image"], composite.inputs["Image"])
    compositor.setup(scene)
    compositor.setup(scene)
    assert "User Glare" in tree.nodes
    assert glare.inputs["Image"].links[0].from_node == render_layers
    multiply = tree.nodes["Airlight Multiply"]
    assert multiply.inputs[1].links[0].from_node == glare
    assert composite.inputs["Image"].links[0].from_node.name == "Airlight Alpha"


def test03_passes_are_linked_and_muted_when_fog_off(tmp_path):
    scene = build_plane_scene(tmp_path)
    compositor.setup(scene)
    tree = scene.node_tree
    image_node = tree.nodes["Airlight Passes"]
    assert tree.nodes["Airlight Multiply"].inputs[2].links[0].from_socket == image_node.outputs["Transmittance"]
    assert tree.nodes["Airlight Add"].inputs[2].links[0].from_socket == image_node.outputs["Airlight"]
    assert compositor.is_complete(scene)
    assert not tree.nodes["Airlight Add"].mute
    scene.airlight.enabled = False
    assert tree.nodes["Airlight Add"].mute and tree.nodes["Airlight Multiply"].mute
    assert tree.nodes["Airlight Alpha"].mute
    scene.airlight.enabled = True
    assert not tree.nodes["Airlight Add"].mute and not tree.nodes["Airlight Alpha"].mute


def test04_tree_set_up_before_the_alpha_nodes_gets_them_once(tmp_path):
    """A .blend set up by an earlier version (Composite fed by the Add node) gets the alpha
    nodes on the next setup, with the Composite moved after them and nothing doubled."""
    scene = build_plane_scene(tmp_path)
    compositor.setup(scene)
    tree = scene.node_tree
    add = tree.nodes["Airlight Add"]
    for node in [n for n in tree.nodes if n.name.startswith("Airlight Alpha")]:
        tree.nodes.remove(node)
    composite = next(n for n in tree.nodes if n.type == 'COMPOSITE')
    tree.links.new(add.outputs[0], composite.inputs["Image"])
    before = len(tree.nodes)
    compositor.setup(scene)
    compositor.setup(scene)
    assert len(tree.nodes) == before + 8
    assert composite.inputs["Image"].links[0].from_node.name == "Airlight Alpha"
    assert tree.nodes["Airlight Multiply"].inputs[1].links[0].from_node.type == 'R_LAYERS'


def test06_users_nodes_after_the_fog_stay_after_it(tmp_path):
    """A grade added between the fog and the Composite node stays there through later
    setups (each render runs one): the fog is not inserted again after it (that closed a
    loop through the grade and broke the composite); the user's Viewer link is theirs. An
    earlier version's tree (Add -> grade -> Composite) gets the alpha node before the grade."""
    scene = build_plane_scene(tmp_path)
    compositor.setup(scene)
    tree = scene.node_tree
    composite = next(n for n in tree.nodes if n.type == 'COMPOSITE')
    viewer = next(n for n in tree.nodes if n.type == 'VIEWER')
    render_layers = next(n for n in tree.nodes if n.type == 'R_LAYERS')
    grade = tree.nodes.new("CompositorNodeGamma")
    grade.name = "User Grade"
    tree.links.new(tree.nodes["Airlight Alpha"].outputs[0], grade.inputs["Image"])
    tree.links.new(grade.outputs["Image"], composite.inputs["Image"])
    tree.links.new(render_layers.outputs["Image"], viewer.inputs["Image"])
    for _ in range(2):
        compositor.setup(scene)
        assert all(link.is_valid for link in tree.links)
        assert composite.inputs["Image"].links[0].from_node == grade
        assert grade.inputs["Image"].links[0].from_node.name == "Airlight Alpha"
        assert tree.nodes["Airlight Multiply"].inputs[1].links[0].from_node == render_layers
        assert viewer.inputs["Image"].links[0].from_node == render_layers

    for node in [n for n in tree.nodes if n.name.startswith("Airlight Alpha")]:
        tree.nodes.remove(node)
    tree.links.new(tree.nodes["Airlight Add"].outputs[0], grade.inputs["Image"])
    compositor.setup(scene)
    assert all(link.is_valid for link in tree.links)
    assert grade.inputs["Image"].links[0].from_node.name == "Airlight Alpha"
    assert tree.nodes["Airlight Alpha"].inputs["Image"].links[0].from_node.name == "Airlight Add"
    assert composite.inputs["Image"].links[0].from_node == grade


def test05_transparent_film_alpha_is_the_fogs_coverage(tmp_path):
    """Film > Transparent: as Cycles does for a volume, the composite's alpha is
    1 - (1 - alpha) T (T the mean of the Transmittance pass), the RGB render x T + A: fog
    in front of the empty background covers it by 1 - T, opaque pixels stay opaque."""
    import numpy as np
    from airlight import fog_object
    from conftest import exr_pass, read_exr, run_blender
    scene = build_plane_scene(tmp_path, size=(48, 36))
    scene.airlight.density = 0.0  # fog objects only: the background's T is not 0
    fog_object.new_fog_object("Fog", scene.collection, centres=[(0.0, 2.0, 1.2), (1.5, 3.0, 1.0)],
                              scales=0.6, amplitudes=0.8)
    cam = scene.camera
    cam.location = (0.0, -4.0, 1.0)
    cam.rotation_euler = (1.45, 0.0, 0.0)  # the horizon crosses the frame
    scene.render.engine = 'CYCLES'
    scene.cycles.samples = 4
    scene.cycles.use_denoising = False
    scene.render.film_transparent = True
    scene.airlight.surface_shading = False
    settings = scene.render.image_settings
    settings.file_format = 'OPEN_EXR'
    settings.color_depth = '32'
    settings.color_mode = 'RGBA'
    scene.view_settings.view_transform = 'Standard'
    bpy.ops.airlight.setup_compositor()
    blend = str(tmp_path / "transparent.blend")
    bpy.ops.wm.save_as_mainfile(filepath=blend)
    off_script = tmp_path / "fog_off.py"
    off_script.write_text("import bpy\nbpy.context.scene.airlight.enabled = False\n")
    for args in (("-o", str(tmp_path / "on_####")), ("--python", str(off_script), "-o", str(tmp_path / "off_####"))):
        proc = run_blender(blend, *args, "-f", "1")
        assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    on, _ = read_exr(str(tmp_path / "on_0001.exr"))
    off, _ = read_exr(str(tmp_path / "off_0001.exr"))
    fog = str(tmp_path / "cache" / "fog_0001.exr")
    A, T = exr_pass(fog, "Airlight"), exr_pass(fog, "Transmittance")
    np.testing.assert_allclose(on[..., :3], off[..., :3] * T + A, rtol=1e-4, atol=1e-5)
    expected_alpha = 1.0 - (1.0 - off[..., 3]) * T.mean(axis=2)
    np.testing.assert_allclose(on[..., 3], expected_alpha, rtol=1e-5, atol=1e-6)
    sky = off[..., 3] == 0.0
    assert sky.any() and (off[..., 3] == 1.0).any()
    # the fog's coverage of the background: partial (neither the plain render's 0 nor 1)
    assert on[..., 3][sky].max() > 0.05 and on[..., 3][sky].min() < 0.95
