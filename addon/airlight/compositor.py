"""Compositor fog nodes: Composite = source x Transmittance + Airlight.

`setup(scene)` adds (idempotently, never removing the user's nodes) a frame
"Airlight Fog" holding an Image node on the baked multilayer EXR, a MixRGB Multiply and
a MixRGB Add, inserted between whatever fed the Composite node (or the Render Layers
node) and the Composite/Viewer nodes. `sync(scene, filepath)` points the Image node at a
baked file and mutes the fog nodes when the fog is disabled, so the image passes through.
"""

import os

import bpy

from . import cache, native
from .cache import PASS_AIRLIGHT, PASS_TRANSMITTANCE

FRAME = "Airlight Fog"
NODE_IMAGE = "Airlight Passes"
NODE_MULTIPLY = "Airlight Multiply"
NODE_ADD = "Airlight Add"
IMAGE_NAME = "Airlight Passes"


def _fog_nodes(tree):
    return [tree.nodes.get(name) for name in (NODE_IMAGE, NODE_MULTIPLY, NODE_ADD)]


def is_set_up(scene):
    tree = scene.node_tree if scene.use_nodes else None
    return tree is not None and all(n is not None for n in _fog_nodes(tree))


def is_complete(scene):
    """Set up, and the Image node's pass outputs are linked into the fog nodes."""
    if not is_set_up(scene):
        return False
    image_node, multiply, add = _fog_nodes(scene.node_tree)
    return multiply.inputs[2].is_linked and add.inputs[2].is_linked


def _node(tree, name, bl_idname, label, location, parent=None):
    node = tree.nodes.get(name)
    if node is None or node.bl_idname != bl_idname:
        node = tree.nodes.new(bl_idname)
        node.name = name
        node.location = location
    node.label = label
    if parent is not None:
        node.parent = parent
    return node


def _first_of_type(tree, node_type):
    for node in tree.nodes:
        if node.type == node_type:
            return node
    return None


def _image(filepath):
    """The image datablock of the baked passes, loaded from `filepath` (or None)."""
    image = bpy.data.images.get(IMAGE_NAME)
    if filepath is None:
        return image
    if image is None:
        image = bpy.data.images.load(filepath, check_existing=False)
        image.name = IMAGE_NAME
    elif bpy.path.abspath(image.filepath) != filepath:
        image.filepath = filepath
    image.source = 'FILE'
    if os.path.exists(filepath):
        image.reload()
    return image


def _link_passes(tree, image_node, multiply, add):
    """Links the Image node's pass outputs once the EXR exposes them."""
    transmittance = image_node.outputs.get(PASS_TRANSMITTANCE)
    airlight = image_node.outputs.get(PASS_AIRLIGHT)
    if transmittance is not None and not multiply.inputs[2].is_linked:
        tree.links.new(transmittance, multiply.inputs[2])
    if airlight is not None and not add.inputs[2].is_linked:
        tree.links.new(airlight, add.inputs[2])


def setup(scene, filepath=None):
    """Creates or completes the fog nodes; returns (image node, multiply, add).

    Without `filepath` the Image node keeps its image, or gets neutral passes so that
    its pass outputs exist and can be linked.
    """
    scene.use_nodes = True
    tree = scene.node_tree
    composite = _first_of_type(tree, 'COMPOSITE')
    if composite is None:
        composite = tree.nodes.new("CompositorNodeComposite")
        composite.location = (600, 300)
    x, y = composite.location.x, composite.location.y

    frame = _node(tree, FRAME, "NodeFrame", FRAME, (x - 500, y + 100))
    image_node = _node(tree, NODE_IMAGE, "CompositorNodeImage", "Airlight Passes",
                       (x - 480, y - 200), frame)
    multiply = _node(tree, NODE_MULTIPLY, "CompositorNodeMixRGB", "Fog: x Transmittance",
                     (x - 260, y), frame)
    add = _node(tree, NODE_ADD, "CompositorNodeMixRGB", "Fog: + Airlight",
                (x - 80, y), frame)
    multiply.blend_type = 'MULTIPLY'
    add.blend_type = 'ADD'
    for node in (multiply, add):
        node.use_alpha = False
        node.inputs[0].default_value = 1.0
    # Neutral defaults while no passes are loaded: x 1, + 0.
    multiply.inputs[2].default_value = (1.0, 1.0, 1.0, 1.0)
    add.inputs[2].default_value = (0.0, 0.0, 0.0, 1.0)

    if filepath is None and not image_node.outputs.get(PASS_AIRLIGHT):
        filepath = neutral_passes(scene)
    image = _image(filepath)
    if image is not None:
        image_node.image = image

    # Insert between the Composite node's current source and the Composite node.
    target = composite.inputs["Image"]
    source = target.links[0].from_socket if target.is_linked else None
    if source is None or source.node != add:
        if source is None:
            render_layers = _first_of_type(tree, 'R_LAYERS')
            if render_layers is None:
                render_layers = tree.nodes.new("CompositorNodeRLayers")
                render_layers.location = (x - 900, y)
            source = render_layers.outputs["Image"]
        for link in list(multiply.inputs[1].links):
            tree.links.remove(link)
        tree.links.new(source, multiply.inputs[1])
        tree.links.new(add.outputs[0], target)
    if not add.inputs[1].is_linked:
        tree.links.new(multiply.outputs[0], add.inputs[1])
    viewer = _first_of_type(tree, 'VIEWER')
    if viewer is None:
        viewer = tree.nodes.new("CompositorNodeViewer")
        viewer.location = (x, y - 250)
    if not (viewer.inputs["Image"].is_linked
            and viewer.inputs["Image"].links[0].from_node == add):
        tree.links.new(add.outputs[0], viewer.inputs["Image"])

    _link_passes(tree, image_node, multiply, add)
    _mute(scene, tree)
    return image_node, multiply, add


def neutral_passes(scene):
    """Path of pass-through passes at the render size, or None if they cannot be written."""
    from .scene_export import render_size
    if not native.available():
        return None
    width, height = render_size(scene)
    try:
        return cache.neutral_path(scene, max(width, 1), max(height, 1))
    except cache.CacheError as ex:
        print(f"Airlight: {ex}", flush=True)
        return None


def _mute(scene, tree):
    muted = not scene.airlight.enabled
    for node in _fog_nodes(tree)[1:]:
        if node is not None and node.mute != muted:
            node.mute = muted


def sync(scene, filepath=None):
    """Points the fog nodes at `filepath` (if given) and mutes them when the fog is off.

    Creates the nodes when `auto_composite` is on and they are missing.
    """
    if scene.airlight.auto_composite and (filepath is not None or scene.airlight.enabled):
        if not is_set_up(scene) or filepath is not None:
            setup(scene, filepath)
            return
    if scene.node_tree is not None:
        _mute(scene, scene.node_tree)


def register():
    pass


def unregister():
    pass
