"""Compositor fog nodes: idempotent setup that keeps the user's nodes."""
import bpy

from airlight import compositor
from conftest import build_plane_scene, needs_native


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
    assert _airlight_nodes(tree) == ["Airlight Add", "Airlight Fog", "Airlight Multiply", "Airlight Passes"]
    composite = next(n for n in tree.nodes if n.type == 'COMPOSITE')
    assert composite.inputs["Image"].links[0].from_node.name == "Airlight Add"
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
    assert composite.inputs["Image"].links[0].from_node.name == "Airlight Add"


@needs_native
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
    scene.airlight.enabled = True
    assert not tree.nodes["Airlight Add"].mute
