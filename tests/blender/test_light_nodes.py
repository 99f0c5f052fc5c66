"""A light's shader nodes (Light > Use Nodes) in the fog: light_nodes.py.

- test01 (Cycles): an Emission of Color (1, 0.5, 0.25) x Strength 2.5 multiplies Cycles'
  fog by that colour (two renders, with and without the nodes, measured by Cycles itself),
  and the bake with the nodes equals that factor times the independent bake of the lamp
  without nodes (cycles_scenes.bake_inputs), and Cycles with the nodes within its noise.
- test02: Light Falloff's Quadratic output into Strength is the node's Strength; nothing
  into the Light Output's Surface is a black light.
- test03: an IES Texture with a linked Strength, an image texture on the Color, an Add Shader: the
  bake refuses the frame with a message naming the light and the node (the panel shows it),
  never bakes the light as if it had no nodes.
- test04: EEVEE and Workbench ignore light nodes: so does the fog there.
"""
import os
import sys

import bpy
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(os.path.dirname(HERE))
sys.path.insert(0, HERE)
import cycles_scenes as cs  # noqa: E402

from airlight import light_nodes, scene_export, ui  # noqa: E402

ARTIFACTS = os.path.join(REPO, "out", "test_artifacts", "light_nodes")
COLOR, STRENGTH = (1.0, 0.5, 0.25), 2.5


def _lamp(scene):
    return next(o for o in scene.objects if o.type == 'LIGHT')


def _emission(light, color=(1.0, 1.0, 1.0), strength=1.0):
    light.use_nodes = True
    tree = light.node_tree
    emission = next(n for n in tree.nodes if n.type == 'EMISSION')
    emission.inputs["Color"].default_value = (*color, 1.0)
    emission.inputs["Strength"].default_value = strength
    return tree, emission


def _intensities(scene):
    return scene_export.export_scene(scene, bpy.context.evaluated_depsgraph_get())["light_intensities"]


def test01_constant_emission_scales_the_fog_as_in_cycles():
    from airlight import native
    desc = cs.FogScene(width=48, height=36, samples=128)
    scene = cs.build(desc)
    scene.render.engine = 'CYCLES'
    scene.airlight.density = desc.sigma_t
    lamp = _lamp(scene)
    (plain,), _ = cs.render_seeds(scene, ARTIFACTS, "plain", (1,))
    inputs = cs.bake_inputs(scene)
    reference = native.get().bake(**inputs, sigma_t=desc.sigma_t, aa_samples=1, threads=2)["airlight"]
    base = _intensities(scene)
    _emission(lamp.data, COLOR, STRENGTH)
    bpy.context.view_layer.update()
    (c1, c2), _ = cs.render_seeds(scene, ARTIFACTS, "nodes", (1, 2))
    factor = np.array(COLOR) * STRENGTH
    # Cycles itself: the image's fog scales by Color x Strength per channel.
    ratio = (0.5 * (c1 + c2)).reshape(-1, 3).sum(axis=0) / plain.reshape(-1, 3).sum(axis=0)
    np.testing.assert_allclose(ratio, factor, rtol=0.05)
    # The export carries the factor ...
    np.testing.assert_allclose(_intensities(scene), base * factor, rtol=1e-12)
    # ... so the bake is factor x the independent bake of the plain lamp, and matches Cycles.
    exported = scene_export.export_scene(scene, bpy.context.evaluated_depsgraph_get())
    baked = native.get().bake(**exported, aa_samples=1, threads=2)["airlight"].astype(np.float64)
    np.testing.assert_allclose(baked, reference * factor, rtol=2e-5, atol=1e-9)
    C = 0.5 * (c1 + c2)
    noise = cs.seed_noise(c1[..., 0], c2[..., 0])
    mask = (C[..., 0] > 0.0) & (noise < 0.5)
    mean, _ = cs.rel_stats(baked[..., 0], C[..., 0], mask)
    print(f"[light_nodes] Cycles with / without nodes {ratio.round(4).tolist()} (factor {factor.tolist()}); "
          f"bake vs Cycles mean {mean:.4f}, noise {float(noise[mask].mean()):.4f}, {int(mask.sum())} px")
    assert mask.sum() > 0.5 * mask.size
    assert mean < 1.5 * float(noise[mask].mean()) + 0.02, (mean, float(noise[mask].mean()))


def test02_light_falloff_quadratic_and_an_empty_output():
    light = bpy.data.lights.new("Nodes", 'POINT')
    tree, emission = _emission(light, strength=1.0)
    falloff = tree.nodes.new("ShaderNodeLightFalloff")
    falloff.inputs["Strength"].default_value = 3.0
    falloff.inputs["Smooth"].default_value = 0.0
    tree.links.new(falloff.outputs["Quadratic"], emission.inputs["Strength"])
    np.testing.assert_allclose(light_nodes.emission_factor("Nodes", light, 'CYCLES'), [3.0, 3.0, 3.0])
    falloff.inputs["Smooth"].default_value = 1.0  # a smoothed falloff changes the shape: refused
    try:
        light_nodes.emission_factor("Nodes", light, 'CYCLES')
        raise AssertionError("a smoothed Light Falloff was taken")
    except light_nodes.LightNodeError as ex:
        assert "Light Falloff" in str(ex)
    output = next(n for n in tree.nodes if n.type == 'OUTPUT_LIGHT')
    for link in list(output.inputs["Surface"].links):
        tree.links.remove(link)
    np.testing.assert_array_equal(light_nodes.emission_factor("Nodes", light, 'CYCLES'), [0.0, 0.0, 0.0])
    light.use_nodes = False
    np.testing.assert_array_equal(light_nodes.emission_factor("Nodes", light, 'CYCLES'), [1.0, 1.0, 1.0])


def _refused(scene, tmp_path, words):
    bpy.context.view_layer.update()
    try:
        result = bpy.ops.airlight.bake(filepath=str(tmp_path / "refused.exr"))
    except RuntimeError as ex:  # the operator's error report
        result = str(ex)
    assert result != {'FINISHED'} and not os.path.exists(str(tmp_path / "refused.exr")), result
    try:
        scene_export.export_scene(scene, bpy.context.evaluated_depsgraph_get())
        raise AssertionError("exported")
    except scene_export.ExportError as ex:
        for word in words:
            assert word in str(ex), (word, str(ex))
    lines = ui.light_node_problem(_lamp(scene).data, scene)
    assert lines and "Light 'Lamp'" in lines[0], lines


def test03_setups_the_fog_cannot_take_are_refused(tmp_path):
    from conftest import build_plane_scene
    scene = build_plane_scene(tmp_path)
    scene.render.engine = 'CYCLES'
    lamp = _lamp(scene)
    lamp.name = "Lamp"
    tree, emission = _emission(lamp.data)
    ies = tree.nodes.new("ShaderNodeTexIES")
    tree.links.new(ies.outputs["Fac"], emission.inputs["Strength"])
    value = tree.nodes.new("ShaderNodeValue")
    tree.links.new(value.outputs[0], ies.inputs["Strength"])
    _refused(scene, tmp_path, ("Lamp", "IES Texture", "linked Vector or Strength"))
    tree.nodes.remove(value)
    tree.nodes.remove(ies)
    image = tree.nodes.new("ShaderNodeTexImage")
    tree.links.new(image.outputs["Color"], emission.inputs["Color"])
    _refused(scene, tmp_path, ("Emission Color", "Image Texture"))
    tree.nodes.remove(image)
    add = tree.nodes.new("ShaderNodeAddShader")
    output = next(n for n in tree.nodes if n.type == 'OUTPUT_LIGHT')
    tree.links.new(add.outputs[0], output.inputs["Surface"])
    _refused(scene, tmp_path, ("Add Shader", "not an Emission shader"))
    lamp.data.airlight.participate = False  # kept out of the fog: bakes
    bpy.context.view_layer.update()
    assert bpy.ops.airlight.bake(filepath=str(tmp_path / "kept_out.exr")) == {'FINISHED'}


def test04_other_engines_ignore_light_nodes(tmp_path):
    from conftest import build_plane_scene
    scene = build_plane_scene(tmp_path)
    lamp = _lamp(scene)
    tree, emission = _emission(lamp.data, COLOR, STRENGTH)
    tree.links.new(tree.nodes.new("ShaderNodeTexIES").outputs["Fac"], emission.inputs["Strength"])
    for engine in ('BLENDER_EEVEE', 'BLENDER_WORKBENCH'):
        scene.render.engine = engine
        lamp.data.use_nodes = False
        bpy.context.view_layer.update()
        plain = _intensities(scene)
        lamp.data.use_nodes = True
        bpy.context.view_layer.update()
        np.testing.assert_array_equal(_intensities(scene), plain)
        assert ui.light_node_problem(lamp.data, scene) is None
