"""A light's shader nodes (Cycles: Light > Use Nodes) as the fog sees them.

Cycles multiplies a light's Color x Power by the emission its node tree gives: the active
Light Output's Surface fed by an Emission shader, Color x Strength. The fog takes the setups
that come to a constant factor: an Emission whose Color and Strength are unlinked, or
whose Strength comes from a Light Falloff's Quadratic output (a light's own inverse-square
falloff: the node's Strength, its Smooth 0), or from an IES Texture's Fac (its Strength here;
its profile, a light distribution, through ies_node and ies_text), through reroutes. Anything
else (a Blackbody or other texture on the Color, mixed shaders) varies with direction or
position in a way the fog's models do not take: the bake refuses it with a message naming
the light and the node, rather than bake the light as if it had no nodes. A leaf module:
it imports none of the package's.

Only Cycles evaluates light nodes (EEVEE and Workbench ignore them), so the fog ignores them
too for the other engines. Nothing here calls the native module.
"""

import numpy as np

ENGINES = {'CYCLES'}


class LightNodeError(ValueError):
    """A light node setup the fog cannot take (the message says which and what to do);
    scene_description raises it on as its ExportError."""


def _refuse(light_name, what):
    raise LightNodeError(
        f"Light '{light_name}': {what}. The fog takes an Emission shader with a constant Color and "
        f"Strength (or Strength from a Light Falloff's Quadratic output) into the Light Output; "
        f"remove the other nodes, turn off Use Nodes, or untick the light's Scatter in Fog")


def _source(socket):
    """The (node, output socket) that feeds _socket_, through reroutes; (None, None) if unlinked."""
    while socket.is_linked:
        link = socket.links[0]
        if not link.is_valid or link.is_muted:
            return None, None
        node = link.from_node
        if node.type == 'REROUTE':
            socket = node.inputs[0]
            continue
        return node, link.from_socket
    return None, None


def _output(tree):
    """The Light Output node Cycles uses: the active one for Cycles or all renderers."""
    outputs = [n for n in tree.nodes if n.type == 'OUTPUT_LIGHT' and getattr(n, "target", 'ALL') in ('ALL', 'CYCLES')]
    active = [n for n in outputs if n.is_active_output]
    return (active or outputs or [None])[0]


def _strength(light_name, socket):
    node, out = _source(socket)
    if node is None:
        return float(socket.default_value)
    if node.type == 'TEX_IES' and out.name == "Fac":
        # Cycles: Fac = Strength x the profile's value towards the point; the profile comes from
        # ies_node / ies_text (a point or spot light's, the fog's light distribution).
        vector, strength = node.inputs["Vector"], node.inputs["Strength"]
        if _source(vector)[0] is None and _source(strength)[0] is None:
            return float(strength.default_value)
        _refuse(light_name, f"its IES Texture '{node.name}' has a linked Vector or Strength, which the fog "
                            "cannot evaluate")
    if node.type == 'LIGHT_FALLOFF' and out.name == "Quadratic":
        strength, smooth = node.inputs["Strength"], node.inputs["Smooth"]
        if _source(strength)[0] is None and _source(smooth)[0] is None and float(smooth.default_value) == 0.0:
            return float(strength.default_value)
    _refuse(light_name, f"its Emission Strength comes from node '{node.name}' ({node.bl_label}"
                        f"{' ' + out.name if out is not None else ''}), which the fog cannot evaluate")


def emission_factor(light_name, light, engine):
    """The RGB factor (3,) float64 that _light_'s node tree applies to its Color x Power for
    the render engine _engine_ (ones without nodes or outside Cycles). LightNodeError for a
    setup the fog cannot take."""
    ones = np.ones(3)
    tree = getattr(light, "node_tree", None)
    if engine not in ENGINES or not getattr(light, "use_nodes", False) or tree is None:
        return ones
    output = _output(tree)
    if output is None:
        return np.zeros(3)  # Cycles: no Light Output, no emission
    node, _ = _source(output.inputs["Surface"])
    if node is None:
        return np.zeros(3)  # nothing into Surface: no emission
    if node.type != 'EMISSION':
        _refuse(light_name, f"its Light Output takes node '{node.name}' ({node.bl_label}), not an Emission shader")
    color_node, _ = _source(node.inputs["Color"])
    if color_node is not None:
        _refuse(light_name, f"its Emission Color comes from node '{color_node.name}' ({color_node.bl_label}), "
                            "which the fog cannot evaluate")
    color = np.array(node.inputs["Color"].default_value[:3], dtype=np.float64)
    return color * _strength(light_name, node.inputs["Strength"])


def ies_node(light, engine):
    """The IES Texture whose Fac feeds the Emission Strength of _light_'s node tree (Cycles),
    through reroutes, or None."""
    tree = getattr(light, "node_tree", None)
    if engine not in ENGINES or not getattr(light, "use_nodes", False) or tree is None:
        return None
    output = _output(tree)
    emission = _source(output.inputs["Surface"])[0] if output is not None else None
    if emission is None or emission.type != 'EMISSION':
        return None
    node, out = _source(emission.inputs["Strength"])
    return node if node is not None and node.type == 'TEX_IES' and out.name == "Fac" else None


def ies_text(node):
    """(text, None) of an IES Texture's profile (its Text datablock, or its file), or (None,
    what is wrong): a light whose profile cannot be read bakes without it, and says so."""
    import bpy  # (only in Blender)
    if node.mode == 'INTERNAL':
        if node.ies is None:
            return None, f"IES Texture '{node.name}' has no Text datablock"
        return node.ies.as_string(), None
    path = bpy.path.abspath(node.filepath) if node.filepath else ""
    if not path:
        return None, f"IES Texture '{node.name}' has no file"
    try:
        with open(path, "r", encoding="latin-1") as f:
            return f.read(), None
    except OSError as ex:
        return None, f"IES file '{node.filepath}' cannot be read ({ex.strerror or ex})"


def safe_emission_factor(light_name, light, engine):
    """emission_factor, or ones where it refuses (for planning and the UI, which must not fail)."""
    try:
        return emission_factor(light_name, light, engine)
    except LightNodeError:
        return np.ones(3)
