"""Compositor fog nodes: Composite = source x Transmittance + Airlight.

`setup(scene)` adds (idempotently, never removing the user's nodes) a frame
"Airlight Fog" holding an Image node on the baked multilayer EXR, a MixRGB Multiply and
a MixRGB Add, inserted between whatever fed the Composite node (or the Render Layers
node) and the Composite/Viewer nodes. A Set Alpha node after them gives the composite the
fog's coverage as Cycles' transparent film does for a volume: alpha = 1 - (1 - alpha) T,
T the mean of the Transmittance pass's channels (opaque pixels stay opaque; with
Film > Transparent the fog in front of the empty background covers 1 - T of it). Nodes
the user adds after the fog stay after it. `sync(scene, filepath)` points the Image node
at a baked file and mutes the fog nodes when the fog is disabled, so the image passes
through.

With surface shading (surface.py; Cycles only) a chain in the same frame first corrects the
render's surfaces for the fog: Image + sum_g Combined_<g> x Surface_<g> + DiffCol x
SurfaceGlow, and that feeds the x Transmittance node.

The passes reach the fog nodes through a node group ("Airlight Fog Passes", the node named
"Airlight Passes"), one output per pass. Inside it each output is fed either by the
multilayer EXR's Image node (a bake's file: Bake Fog, F12) or by an Image node per pass on
an in-memory float image (background renders, -f/-a: choose_source). In memory the fog
is baked beside the render engine (render._BakeBeside) and handed over with fill() just
before the compositor runs, about 2 ms a 1080p pass once make_images() has made the images
(50 ms each, the first time in a process, while the bake finishes), where reloading the EXR
took 0.3-0.8 s; the EXR is still written, after the bake. Only the outputs something is
linked to are filled.
"""

import os
import threading
import time
import zlib

import bpy
import numpy as np
from bpy.app.handlers import persistent

from . import cache, native, surface
from .names import PASS_AIRLIGHT, PASS_TRANSMITTANCE
from .views import render_size, render_views

FRAME = "Airlight Fog"
NODE_IMAGE = "Airlight Passes"
NODE_MULTIPLY = "Airlight Multiply"
NODE_ADD = "Airlight Add"
# The alpha nodes (see the module docstring): NODE_ALPHA sets it, the others compute it.
NODE_ALPHA = "Airlight Alpha"
ALPHA_NODE_PREFIX = "Airlight Alpha "
IMAGE_NAME = "Airlight Passes"
# The passes' node group (module docstring): the file's Image node in it, and per pass an
# Image node on an in-memory image.
GROUP_NAME = "Airlight Fog Passes"
NODE_FILE = "Airlight Passes File"
MEMORY_PREFIX = "Airlight Pass "  # the in-memory Image nodes and their images
# Stereoscopy (_setup_views): an Image node per view after the first, a Switch View node per pass.
VIEW_IMAGE_PREFIX = "Airlight View Image "
VIEW_SWITCH_PREFIX = "Airlight View Switch "
# Surface-shading chain (surface.py), rebuilt by every setup(); its first Add node takes
# the render's Image.
SURFACE_NODE_PREFIX = "Airlight Surface "
NODE_SURFACE_FIRST = SURFACE_NODE_PREFIX + "Add 0"
SURFACE_SIGNATURE = "airlight_surface_chain"  # node tree ID property: the chain's groups


def _fog_nodes(tree):
    return [tree.nodes.get(name) for name in (NODE_IMAGE, NODE_MULTIPLY, NODE_ADD)]


def _alpha_nodes(tree):
    return [node for node in tree.nodes if node.name == NODE_ALPHA or node.name.startswith(ALPHA_NODE_PREFIX)]


def _link(tree, from_socket, to_socket):
    """Links unless already so (a new link re-evaluates the compositor), also through a
    view's Switch View node (_setup_views) that takes _from_socket_."""
    if to_socket.is_linked:
        source = to_socket.links[0].from_socket
        if source == from_socket:
            return
        node = source.node
        if node.name.startswith(VIEW_SWITCH_PREFIX) and any(
                link.from_socket == from_socket for socket in node.inputs for link in socket.links):
            return
    tree.links.new(from_socket, to_socket)


def _setup_alpha(tree, frame, image_node, add):
    """The Set Alpha node after the Add node and its alpha, 1 - (1 - alpha) mean(T), as
    MULTIPLY_ADD((alpha - 1) / 3, T_r + T_g + T_b, 1); returns the Set Alpha node."""
    x, y = add.location.x, add.location.y - 420  # a row below the fog nodes
    color = _node(tree, ALPHA_NODE_PREFIX + "Image", "CompositorNodeSeparateColor", "Fog: image alpha",
                  (x - 900, y), frame)
    trans = _node(tree, ALPHA_NODE_PREFIX + "Transmittance", "CompositorNodeSeparateColor",
                  "Fog: transmittance channels", (x - 900, y - 160), frame)
    ops = {}
    for k, (name, op, value) in enumerate((("Sum RG", 'ADD', None), ("Sum RGB", 'ADD', None),
                                           ("Minus 1", 'SUBTRACT', 1.0), ("Third", 'MULTIPLY', 1.0 / 3.0),
                                           ("Value", 'MULTIPLY_ADD', 1.0))):
        node = _node(tree, ALPHA_NODE_PREFIX + name, "CompositorNodeMath", f"Fog alpha: {name.lower()}",
                     (x - 720 + 160 * k, y - 80), frame)
        node.operation = op
        node.use_clamp = False
        if value is not None:
            node.inputs[1 if op != 'MULTIPLY_ADD' else 2].default_value = value
        ops[name] = node
    alpha = _node(tree, NODE_ALPHA, "CompositorNodeSetAlpha", "Fog: coverage alpha", (x + 80, y - 80), frame)
    alpha.mode = 'REPLACE_ALPHA'
    for sep in (color, trans):
        sep.mode = 'RGB'
    transmittance = image_node.outputs.get(PASS_TRANSMITTANCE)
    if transmittance is not None:
        _link(tree, transmittance, trans.inputs[0])
    else:  # no passes yet: T = 1 keeps the alpha
        trans.inputs[0].default_value = (1.0, 1.0, 1.0, 1.0)
    _link(tree, add.outputs[0], color.inputs[0])
    _link(tree, trans.outputs["Red"], ops["Sum RG"].inputs[0])
    _link(tree, trans.outputs["Green"], ops["Sum RG"].inputs[1])
    _link(tree, ops["Sum RG"].outputs[0], ops["Sum RGB"].inputs[0])
    _link(tree, trans.outputs["Blue"], ops["Sum RGB"].inputs[1])
    _link(tree, color.outputs["Alpha"], ops["Minus 1"].inputs[0])
    _link(tree, ops["Minus 1"].outputs[0], ops["Third"].inputs[0])
    _link(tree, ops["Third"].outputs[0], ops["Value"].inputs[0])
    _link(tree, ops["Sum RGB"].outputs[0], ops["Value"].inputs[1])
    _link(tree, add.outputs[0], alpha.inputs["Image"])
    _link(tree, ops["Value"].outputs[0], alpha.inputs["Alpha"])
    return alpha


def _feeds(tree, node, socket):
    """Whether _node_ lies upstream of the input _socket_ (through any links)."""
    seen = set()
    stack = [link.from_node for link in socket.links]
    while stack:
        current = stack.pop()
        if current == node:
            return True
        if current.name in seen:
            continue
        seen.add(current.name)
        stack.extend(link.from_node for socket in current.inputs for link in socket.links)
    return False


def is_set_up(scene):
    tree = scene.node_tree if scene.use_nodes else None
    return tree is not None and all(n is not None for n in _fog_nodes(tree))


def is_complete(scene):
    """Set up, with the alpha node and the passes' group (a tree from an earlier version
    may lack them), and the group's pass outputs linked into the fog nodes."""
    if not is_set_up(scene) or scene.node_tree.nodes.get(NODE_ALPHA) is None:
        return False
    image_node, multiply, add = _fog_nodes(scene.node_tree)
    return (image_node.bl_idname == "CompositorNodeGroup" and multiply.inputs[2].is_linked
            and add.inputs[2].is_linked)


def _node(tree, name, bl_idname, label, location, parent=None):
    node = tree.nodes.get(name)
    if node is None or node.bl_idname != bl_idname:
        node = tree.nodes.new(bl_idname)
        node.name = name
        node.location = location
    # Written only where they differ: the per-frame paths (fill) look nodes up through here,
    # and setting a property to its own value still counts as an edit of the tree.
    if node.label != label:
        node.label = label
    if parent is not None and node.parent != parent:
        node.parent = parent
    return node


def _first_of_type(tree, node_type):
    for node in tree.nodes:
        if node.type == node_type:
            return node
    return None


def _neutral_value(name):
    """A pass's value that leaves the image as it is: Transmittance 1, the others 0."""
    return 1.0 if name == PASS_TRANSMITTANCE else 0.0


def _group():
    """The passes' node group (module docstring), created on first use."""
    group = bpy.data.node_groups.get(GROUP_NAME)
    if group is None or group.bl_idname != "CompositorNodeTree":
        group = bpy.data.node_groups.new(GROUP_NAME, "CompositorNodeTree")
    if _group_output(group) is None:
        group.nodes.new("NodeGroupOutput").location = (300, 0)
    _node(group, NODE_FILE, "CompositorNodeImage", "Baked passes (EXR file)", (-300, 0))
    return group


def _group_output(group):
    return next((node for node in group.nodes if node.type == 'GROUP_OUTPUT'), None)


def _pass_sockets(group):
    """The group's output node's inputs, one per pass (not the empty one that adds outputs)."""
    return [socket for socket in _group_output(group).inputs if socket.bl_idname != "NodeSocketVirtual"]


def _expose(group, names):
    """Gives the group an output per pass in _names_ it lacks (outputs are kept once made:
    a user's link to a light's pass survives a bake without that light, reading 0)."""
    for name in names:
        if group.outputs.get(name) is None:
            socket = group.outputs.new("NodeSocketColor", name)
            value = _neutral_value(name)
            socket.default_value = (value, value, value, 1.0)


def _memory_name(name):
    """The name of a pass's in-memory Image node and image (Blender's names hold 63 bytes)."""
    full = MEMORY_PREFIX + name
    return full if len(full.encode()) <= 63 else f"{MEMORY_PREFIX}{zlib.crc32(name.encode()):08x}"


def _new_memory_image(name):
    """A new in-memory float image for pass _name_ that regenerates to the pass's neutral
    value (what a reopened file shows: its pixels are not saved)."""
    image = bpy.data.images.new(_memory_name(name), 4, 4, alpha=True, float_buffer=True)
    value = _neutral_value(name)
    image.generated_color = (value, value, value, 1.0)
    return image


def _memory_node(group, name):
    """The group's Image node of pass _name_ in memory, with its own generated float image
    (a new one if a user gave it another)."""
    node = _node(group, _memory_name(name), "CompositorNodeImage", f"{name} (in memory)",
                 (0, -200 - 160 * len(group.nodes)))
    image = node.image
    if image is None or image.source != 'GENERATED' or not image.is_float:
        node.image = _new_memory_image(name)
    return node


def _route(group, memory):
    """Feeds each of the group's outputs from the in-memory images (_memory_) or from the
    file's Image node; an output the file lacks is left unlinked (its neutral default)."""
    file_node = group.nodes[NODE_FILE]
    for socket in _pass_sockets(group):
        if memory:
            source = _memory_node(group, socket.name).outputs["Image"]
        else:
            source = file_node.outputs.get(socket.name)
            source = source if source is not None and source.enabled else None
        if source is None:
            for link in list(socket.links):
                group.links.remove(link)
        else:
            _link(group, source, socket)


def _passes_node(tree, frame, location):
    """The group node that hands the fog nodes the passes. A tree from an earlier version
    has a multilayer Image node there: its image and its outputs' links move to the group."""
    node = tree.nodes.get(NODE_IMAGE)
    group = _group()
    if node is not None and node.bl_idname != "CompositorNodeGroup":
        image = getattr(node, "image", None)
        moved = [(socket.name, link.to_socket) for socket in node.outputs for link in socket.links]
        location = node.location.copy()
        tree.nodes.remove(node)
        node = None
        if image is not None:
            group.nodes[NODE_FILE].image = image
        _expose(group, [name for name, _ in moved])
    else:
        moved = []
    node = _node(tree, NODE_IMAGE, "CompositorNodeGroup", "Airlight Passes", location, frame)
    if node.node_tree != group:
        node.node_tree = group
    for name, target in moved:
        tree.links.new(node.outputs[name], target)
    return node


def file_image(tree):
    """The baked file's image the passes node reads, or None."""
    node = tree.nodes.get(NODE_IMAGE)
    if node is None or node.bl_idname != "CompositorNodeGroup" or node.node_tree is None:
        return getattr(node, "image", None)
    file_node = node.node_tree.nodes.get(NODE_FILE)
    return file_node.image if file_node is not None else None


def in_memory(scene):
    """The fog nodes take their passes from memory (fill), not from a file."""
    tree = scene.node_tree if scene.use_nodes else None
    node = tree.nodes.get(NODE_IMAGE) if tree is not None else None
    if node is None or node.bl_idname != "CompositorNodeGroup" or node.node_tree is None:
        return False
    socket = _group_output(node.node_tree).inputs.get(PASS_TRANSMITTANCE)
    return (socket is not None and socket.is_linked
            and socket.links[0].from_node.name.startswith(MEMORY_PREFIX))


def choose_source(scene):
    """Main thread, before a render starts (render.on_render_init) and on loading a file:
    routes the passes from memory for a background render of one view, where nothing shows
    the images and no dialog offers to save them, else from the files (Stereoscopy:
    _setup_views; a file saved after a background render, opened in the UI)."""
    if not is_complete(scene):
        return
    tree = scene.node_tree
    memory = bpy.app.background and len(render_views(scene)) < 2
    if memory:
        # The surface-shading chain as the render's engine needs it (gone without Cycles):
        # every pass it reads is filled per frame.
        image_node, multiply, _ = _fog_nodes(tree)
        _setup_surface(scene, tree, tree.nodes.get(FRAME), image_node, multiply)
    if in_memory(scene) != memory:
        _route(tree.nodes[NODE_IMAGE].node_tree, memory)


def _linked_images(scene, width, height):
    """The in-memory images of the passes node's outputs something reads, sized _width_ x
    _height_ (a new size makes Blender regenerate the image on its next use)."""
    node = scene.node_tree.nodes[NODE_IMAGE]
    images = {}
    for socket in node.outputs:
        if socket.is_linked:
            image = _memory_node(node.node_tree, socket.name).image
            if tuple(image.size) != (width, height):
                image.generated_width, image.generated_height = width, height
            images[socket.name] = image
    return images


def make_images(scene):
    """Makes the in-memory images fill() will copy a bake of the render's size into (Blender
    regenerates a resized image on its first use: 50 ms a 1080p image), ahead of the bake."""
    width, height = render_size(scene)
    for image in _linked_images(scene, max(width, 1), max(height, 1)).values():
        if not image.has_data:
            image.update()


def fill(scene, passes):
    """Copies a bake's passes ({name: (H, W, 3) float32}, rows from the top) into the
    in-memory images of the group's outputs that something is linked to; one such output the
    bake lacks (a light gone since) gets its neutral value. Returns the seconds it took."""
    t0 = time.perf_counter()
    _expose(scene.node_tree.nodes[NODE_IMAGE].node_tree, passes)
    height, width = passes[PASS_TRANSMITTANCE].shape[:2]
    rgba = np.empty((height, width, 4), np.float32)
    rgba[..., 3] = 1.0
    for name, image in _linked_images(scene, width, height).items():
        data = passes.get(name)
        rgba[..., :3] = data[::-1] if data is not None else _neutral_value(name)
        image.pixels.foreach_set(rgba.ravel())
    return time.perf_counter() - t0


def fill_neutral(scene):
    """Gives the in-memory images something reads their neutral value at the render's size:
    Blender regenerates them from their generated colour (nothing to copy or allocate here,
    so this holds where fill() failed for want of memory)."""
    width, height = render_size(scene)
    for image in _linked_images(scene, max(width, 1), max(height, 1)).values():
        image.reload()


def _image(filepath, name=IMAGE_NAME):
    """The image datablock _name_ of baked passes, loaded from `filepath` (or None)."""
    image = bpy.data.images.get(name)
    if filepath is None:
        return image
    if image is None:
        image = bpy.data.images.load(filepath, check_existing=False)
        image.name = name
    elif bpy.path.abspath(image.filepath) != filepath:
        image.filepath = filepath
    image.source = 'FILE'
    if os.path.exists(filepath):
        image.reload()
    return image


def _is_view_file(scene, filepath):
    """_filepath_ is the first view's file of a stereo bake of _scene_ (bake.view_paths)."""
    if filepath is None:
        return False
    view, suffix = render_views(scene)[0]
    return view is not None and bool(suffix) and os.path.splitext(filepath)[0].endswith(suffix)


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
    image_node = _passes_node(tree, frame, (x - 480, y - 200))
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
    group = image_node.node_tree
    file_node = group.nodes[NODE_FILE]
    image = _image(filepath) if filepath is not None or file_node.image is None else file_node.image
    if image is not None:
        file_node.image = image
        _expose(group, [socket.name for socket in file_node.outputs if socket.enabled])
    if filepath is not None or not in_memory(scene) or len(render_views(scene)) > 1:
        _route(group, memory=False)  # a file given is what the composite shows

    alpha = _setup_alpha(tree, frame, image_node, add)
    # A tree set up before the alpha nodes existed: what the Add node fed (the Composite,
    # the Viewer, a user's node after the fog) now takes the alpha node's output.
    for link in list(add.outputs[0].links):
        if link.to_node != alpha and not link.to_node.name.startswith(ALPHA_NODE_PREFIX):
            tree.links.new(alpha.outputs[0], link.to_socket)
    # Insert between the Composite node's current source and the Composite node, unless
    # the fog already feeds it, directly or through the user's nodes after it (re-inserting
    # there would close a loop through them).
    target = composite.inputs["Image"]
    if not _feeds(tree, alpha, target):
        source = target.links[0].from_socket if target.is_linked else None
        if source is None:
            render_layers = _first_of_type(tree, 'R_LAYERS')
            if render_layers is None:
                render_layers = tree.nodes.new("CompositorNodeRLayers")
                render_layers.location = (x - 900, y)
            source = render_layers.outputs["Image"]
        for link in list(multiply.inputs[1].links):
            tree.links.remove(link)
        tree.links.new(source, multiply.inputs[1])
        tree.links.new(alpha.outputs[0], target)
    if not add.inputs[1].is_linked:
        tree.links.new(multiply.outputs[0], add.inputs[1])
    # The Viewer shows the fogged image when it shows nothing else (a user's Viewer link
    # elsewhere is theirs).
    viewer = _first_of_type(tree, 'VIEWER')
    if viewer is None:
        viewer = tree.nodes.new("CompositorNodeViewer")
        viewer.location = (x, y - 250)
    if not viewer.inputs["Image"].is_linked:
        tree.links.new(alpha.outputs[0], viewer.inputs["Image"])

    _link_passes(tree, image_node, multiply, add)
    _setup_surface(scene, tree, frame, image_node, multiply)
    _setup_views(scene, tree, frame, image_node, filepath)
    _mute(scene, tree)
    return image_node, multiply, add


def _setup_views(scene, tree, frame, image_node, filepath):
    """Stereoscopy: each view composites its own bake (bake.view_paths). When the render
    makes several views, an Image node per view after the first loads that view's file, and
    each pass the fog nodes read goes through a Switch View node (an input per view), which
    feeds what the Image node's output fed. The nodes are there as soon as the compositor
    is set up with Stereoscopy on: a background render (-f, -a) composites with the tree as
    it was before its render_pre handler, which then only points the images at the frame's
    files. _filepath_: the first view's file of a stereo bake (the others are derived), or
    passes for every view (a plain bake, neutral passes), or None (the views' images stay).
    Without Stereoscopy the switches and the views' Image nodes go and their targets read
    the Image node again. (Blender's multi-view images do not take multilayer EXR passes
    per view file, hence the switches.)"""
    views = render_views(scene)
    switches = {node.name[len(VIEW_SWITCH_PREFIX):]: node for node in tree.nodes
                if node.name.startswith(VIEW_SWITCH_PREFIX)}
    if len(views) < 2:
        for name, switch in switches.items():
            source = image_node.outputs.get(name)
            for link in list(switch.outputs[0].links):
                if source is not None:
                    tree.links.new(source, link.to_socket)
        for node in _view_nodes(tree):
            tree.nodes.remove(node)
        return
    per_view = _is_view_file(scene, filepath)
    if per_view:
        root, ext = os.path.splitext(filepath)
        root = root[:len(root) - len(views[0][1])]
    images = {views[0][0]: image_node}
    x, y = image_node.location.x, image_node.location.y
    for k, (view, suffix) in enumerate(views[1:], start=1):
        node = _node(tree, VIEW_IMAGE_PREFIX + view, "CompositorNodeImage", f"Airlight Passes ({view})",
                     (x, y - 220 * k), frame)
        name = f"{IMAGE_NAME} ({view})"
        if per_view:
            node.image = _image(root + suffix + ext, name)
        elif filepath is not None or node.image is None:
            main = file_image(tree)
            node.image = _image(bpy.path.abspath(main.filepath), name) if main is not None else None
        images[view] = node
    for node in _view_nodes(tree):
        if node.name.startswith(VIEW_IMAGE_PREFIX) and node.name[len(VIEW_IMAGE_PREFIX):] not in images:
            tree.nodes.remove(node)
    for k, socket in enumerate(image_node.outputs):
        targets = [link.to_socket for link in socket.links if not link.to_node.name.startswith(VIEW_SWITCH_PREFIX)]
        switch = switches.pop(socket.name, None)
        if not targets and switch is None:
            continue
        if switch is None:
            switch = _node(tree, VIEW_SWITCH_PREFIX + socket.name, "CompositorNodeSwitchView",
                           f"Fog: {socket.name} per view", (x + 180, y - 60 * k), frame)
        for view, node in images.items():
            source = node.outputs.get(socket.name)
            if source is not None and view in switch.inputs:
                _link(tree, source, switch.inputs[view])
        for target in targets:
            tree.links.new(switch.outputs[0], target)
    for switch in switches.values():  # passes the new bake does not have
        tree.nodes.remove(switch)


def views_ready(scene):
    """The fog nodes take each view's passes as the render's views need (_setup_views): a
    Switch View node on the Transmittance pass and an Image node per view after the first
    with Stereoscopy, neither without."""
    tree = scene.node_tree
    if tree is None:
        return False
    views = render_views(scene)
    nodes = _view_nodes(tree)
    if len(views) < 2:
        return not nodes
    names = {node.name for node in nodes}
    return (VIEW_SWITCH_PREFIX + PASS_TRANSMITTANCE in names
            and all(VIEW_IMAGE_PREFIX + view in names for view, _ in views[1:]))


def ensure_views(scene):
    """Main thread: sets the fog nodes up for the render's views when they are not
    (views_ready); a render composites with the nodes it starts with."""
    if is_set_up(scene) and not views_ready(scene):
        setup(scene)


def _view_nodes(tree):
    return [node for node in tree.nodes
            if node.name.startswith(VIEW_IMAGE_PREFIX) or node.name.startswith(VIEW_SWITCH_PREFIX)]


def _surface_nodes(tree):
    return [node for node in tree.nodes if node.name.startswith(SURFACE_NODE_PREFIX)]


def _setup_surface(scene, tree, frame, image_node, multiply):
    """Builds the surface-shading chain (surface.py) in front of the x Transmittance node:

        Image -> + Combined_<g> x Surface_<g> (per light group g) -> + DiffCol x SurfaceGlow

    from the Render Layers node's passes and the baked EXR's. Only when surface shading is
    active (Cycles) and the fog multiplies the Render Layers' Image directly (a user's own
    processing in between is left alone: then no surface shading, said in the console).
    Passes missing on either side are skipped (a light without its group, or an EXR baked
    without surface shading). An unchanged chain is kept as it is (render_pre calls this
    while a render starts).
    """
    chain = _surface_nodes(tree)
    first = tree.nodes.get(NODE_SURFACE_FIRST)
    # The chain's source: what feeds its first Add node, else what feeds the multiply node.
    if first is not None and first.inputs[1].is_linked:
        source = first.inputs[1].links[0].from_socket
    elif multiply.inputs[1].is_linked and not multiply.inputs[1].links[0].from_node.name.startswith(
            SURFACE_NODE_PREFIX):
        source = multiply.inputs[1].links[0].from_socket
    else:
        source = None
    terms = []
    render_layers = source.node if source is not None else None
    if surface.active(scene) and render_layers is not None:
        if render_layers.type != 'R_LAYERS' or source.name != "Image":
            print("Airlight: surface shading skipped: the fog's input is not the Render Layers "
                  "node's Image output", flush=True)
        else:
            for output in image_node.outputs:
                if output.name.startswith(surface.PASS_PREFIX):
                    group = output.name[len(surface.PASS_PREFIX):]
                    light = render_layers.outputs.get("Combined_" + group)
                    if light is not None and light.enabled:
                        terms.append((group, light, output))
            glow = image_node.outputs.get(surface.PASS_GLOW)
            diffcol = render_layers.outputs.get("DiffCol")
            if glow is not None and diffcol is not None and diffcol.enabled:
                terms.append(("glow", diffcol, glow))
            gloss = image_node.outputs.get(surface.PASS_GLOSS)
            glosscol = render_layers.outputs.get("GlossCol")
            if (gloss is not None and glosscol is not None and glosscol.enabled
                    and surface.gloss_exponent(scene) > 0.0):
                terms.append(("gloss", glosscol, gloss))
    signature = ",".join(group for group, _, _ in terms)
    if chain and tree.get(SURFACE_SIGNATURE) == signature and len(chain) == 2 * len(terms):
        return
    # Rebuild: take the old chain out and reconnect its source to the multiply node.
    for node in chain:
        tree.nodes.remove(node)
    tree[SURFACE_SIGNATURE] = signature
    if source is None:
        return
    if not terms:
        tree.links.new(source, multiply.inputs[1])
        return
    x, y = multiply.location.x, multiply.location.y
    accumulated = source
    n = len(terms)
    for k, (group, light, baked) in enumerate(terms):
        label = {"glow": "Glow", "gloss": "Gloss"}.get(group, group)
        scale = _node(tree, f"{SURFACE_NODE_PREFIX}Multiply {k}", "CompositorNodeMixRGB",
                      f"Surface: {label} x pass", (x - 420 - 360 * (n - k), y - 220), frame)
        plus = _node(tree, f"{SURFACE_NODE_PREFIX}Add {k}", "CompositorNodeMixRGB",
                     f"Surface: + {label}", (x - 240 - 360 * (n - k), y), frame)
        scale.blend_type = 'MULTIPLY'
        plus.blend_type = 'ADD'
        for node in (scale, plus):
            node.use_alpha = False
            node.use_clamp = False
            node.inputs[0].default_value = 1.0
        tree.links.new(light, scale.inputs[1])
        tree.links.new(baked, scale.inputs[2])
        tree.links.new(accumulated, plus.inputs[1])
        tree.links.new(scale.outputs[0], plus.inputs[2])
        accumulated = plus.outputs[0]
    tree.links.new(accumulated, multiply.inputs[1])


def neutral_passes(scene, depsgraph=None):
    """Path of pass-through passes at the render size, or None if they cannot be written.
    With surface shading (main thread) it first sets up the light groups for the scene as
    _depsgraph_ (default: the context's) has it."""
    if not native.available():
        return None
    width, height = render_size(scene)
    names = ()
    if surface.active(scene) and threading.current_thread() is threading.main_thread():
        # Enable the light groups now (before any render starts) and expose their passes.
        try:
            groups = surface.ensure_passes(scene, depsgraph or bpy.context.evaluated_depsgraph_get())
            names = [surface.PASS_PREFIX + g for g in groups if g is not None] + [surface.PASS_GLOW]
            if surface.gloss_exponent(scene) > 0.0:
                names.append(surface.PASS_GLOSS)
            world_group = surface.ensure_world_group(scene)
            if world_group is not None:
                names.append(surface.PASS_PREFIX + world_group)
        except Exception as ex:  # never block the plain fog composite
            print(f"Airlight: surface shading passes not set up: {ex}", flush=True)
    try:
        return cache.neutral_path(scene, max(width, 1), max(height, 1), names)
    except cache.CacheError as ex:
        print(f"Airlight: {ex}", flush=True)
        return None


def _mute(scene, tree, muted=None):
    """Mutes the fog nodes (the image then passes through them unchanged) when the fog is
    off or the native module is missing (nothing could bake the passes they read: a worker
    with the add-on but not its compiled module composited a missing image as magenta), or
    as _muted_ says."""
    if muted is None:
        muted = not scene.airlight.enabled or not native.available()
    for node in _fog_nodes(tree)[1:] + _surface_nodes(tree) + _alpha_nodes(tree):
        if node is not None and node.mute != muted:
            node.mute = muted


# Saved files hold the fog nodes muted, and the frame says why: a machine without the add-on
# (a render farm worker it was not installed on) has no cache file for the Image node, whose
# missing image composited as magenta over every frame while Blender exited 0. There the
# render now passes through the muted nodes unfogged. With the add-on, load_post (render.py)
# and save_post un-mute them again, before any render starts: a render composites with the
# node tree as it was before its render_pre handler (checked in Blender 3.4), so un-muting
# there would come too late.
SAVED_LABEL = FRAME + " (muted in the file: the add-on enables it)"  # (labels: 63 characters)
_muted_for_save = []


@persistent
def on_save_pre(*_):
    _muted_for_save.clear()
    for scene in bpy.data.scenes:
        if getattr(scene, "airlight", None) is None or not is_set_up(scene):
            continue
        tree = scene.node_tree
        _mute(scene, tree, muted=True)
        frame = tree.nodes.get(FRAME)
        if frame is not None:
            frame.label = SAVED_LABEL
        _muted_for_save.append(scene.name)


@persistent
def on_save_post(*_):
    for name in _muted_for_save:
        scene = bpy.data.scenes.get(name)
        if scene is not None and is_set_up(scene):
            unmute_loaded(scene)
    _muted_for_save.clear()


def unmute_loaded(scene):
    """Gives a scene's fog nodes, muted as saved (on_save_pre), their state in this session:
    on when the fog is, and the frame its label."""
    tree = scene.node_tree
    frame = tree.nodes.get(FRAME)
    if frame is not None and frame.label != FRAME:
        frame.label = FRAME
    _mute(scene, tree)


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


def surface_ready(scene, depsgraph):
    """The surface shading's light groups are in place for the scene as it is now, and the
    Image node exposes each one's pass (the chain is built from those outputs)."""
    groups, ready = surface.groups_in_place(scene, depsgraph)
    image_node = _fog_nodes(scene.node_tree)[0]
    return ready and all(image_node.outputs.get(surface.PASS_PREFIX + g) is not None for g in groups)


def complete_surface(scene, depsgraph):
    """Sets up the surface shading's light groups and the chain's passes (neutral until the
    next bake) where the scene as _depsgraph_ has it needs more; main thread only."""
    if not surface_ready(scene, depsgraph):
        setup(scene, neutral_passes(scene, depsgraph))
    elif is_complete(scene):
        # The chain itself (a background render with another engine left the file without it:
        # choose_source).
        tree = scene.node_tree
        image_node, multiply, _ = _fog_nodes(tree)
        _setup_surface(scene, tree, tree.nodes.get(FRAME), image_node, multiply)


def _touches_lights(depsgraph):
    """Whether an update can change the surface shading's light groups: a light, a World,
    the scene (its World, Environment Glow), a collection (objects added or hidden)."""
    for update in depsgraph.updates:
        data = update.id
        if isinstance(data, (bpy.types.Light, bpy.types.World, bpy.types.Scene, bpy.types.Collection)):
            return True
        if isinstance(data, bpy.types.Object) and data.type == 'LIGHT':
            return True
    return False


@persistent
def on_depsgraph_update_post(scene, depsgraph):
    """Keeps the surface-shading passes and the per-view nodes (Stereoscopy) in step with the
    user's edits (a new light, a World, Environment Glow on, stereo on): a render composites with the node links it starts with, and an
    interactive render's thread cannot add light groups (render.py), so they are set up
    here, in the main thread, when an edit needs them."""
    if threading.current_thread() is not threading.main_thread() or bpy.app.is_job_running('RENDER'):
        return
    settings = getattr(scene, "airlight", None)
    if settings is None or not (settings.enabled and settings.auto_composite) or not is_set_up(scene):
        return
    try:
        # Stereoscopy switched on or off (or a view added): the per-view nodes.
        ensure_views(scene)
        if surface.active(scene) and _touches_lights(depsgraph):
            complete_surface(scene, depsgraph)
    except Exception as ex:  # a handler must never break editing
        print(f"Airlight: cannot update the compositor's fog nodes: {ex}", flush=True)


_HANDLERS = (
    (bpy.app.handlers.depsgraph_update_post, on_depsgraph_update_post),
    (bpy.app.handlers.save_pre, on_save_pre),
    (bpy.app.handlers.save_post, on_save_post),
)


def register():
    for handlers, function in _HANDLERS:
        if function not in handlers:
            handlers.append(function)


def unregister():
    for handlers, function in _HANDLERS:
        while function in handlers:
            handlers.remove(function)
