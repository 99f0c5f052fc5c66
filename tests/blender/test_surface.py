"""Surface shading plumbing (surface.py, compositor.py): light groups and passes enabled
automatically, the compositor chain built once and removed when off, the Eevee fallback, the
bake's light order, and the surface passes in the baked EXR."""
import math
import os

import bpy
import numpy as np

from airlight import compositor, scene_export, surface
from conftest import build_plane_scene, exr_pass, run_blender


def _surface_nodes(tree):
    return sorted(n.name for n in tree.nodes if n.name.startswith(compositor.SURFACE_NODE_PREFIX))


def _add_light(scene, name, kind, location, group=""):
    data = bpy.data.lights.new(name, kind)
    data.energy = 100.0
    obj = bpy.data.objects.new(name, data)
    obj.location = location
    obj.lightgroup = group
    scene.collection.objects.link(obj)
    return obj


def test01_light_order_matches_the_export(tmp_path):
    """fogged_lights lists the lights in the bake's order: point lights, spots, then suns."""
    scene = build_plane_scene(tmp_path)
    _add_light(scene, "Spot A", 'SPOT', (1.0, 2.0, 3.0))
    _add_light(scene, "Key", 'POINT', (-1.0, 0.5, 1.5), group="user_key")
    _add_light(scene, "Sun", 'SUN', (0.0, 0.0, 10.0))
    _add_light(scene, "Fill.001", 'POINT', (2.0, -1.0, 1.0))
    bpy.context.view_layer.update()
    depsgraph = bpy.context.evaluated_depsgraph_get()
    rows = surface.fogged_lights(depsgraph)
    description = scene_export.export_scene(scene, depsgraph)
    positions = np.concatenate([description["light_positions"],
                                description.get("spot_positions", np.zeros((0, 3)))])
    assert len(rows) == len(positions) + len(description["sun_directions"]) == 5
    for (obj, _), p in zip(rows, positions):
        np.testing.assert_allclose(np.array(obj.matrix_world.translation), p, atol=1e-6)
    assert rows[-1][0].name == "Sun"
    groups = {obj.name: group for obj, group in rows}
    assert groups["Sun"] == "fog_Sun"
    # The user's own light group is kept (no surface attenuation for that light).
    assert groups["Key"] is None
    assert groups["Fill.001"] == "fog_Fill_001" and groups["Spot A"] == "fog_Spot_A"


def test02_eevee_keeps_the_plain_composite(tmp_path):
    scene = build_plane_scene(tmp_path)
    scene.render.engine = 'BLENDER_EEVEE'
    assert scene.airlight.surface_shading
    compositor.setup(scene)
    tree = scene.node_tree
    assert _surface_nodes(tree) == []
    assert tree.nodes["Airlight Multiply"].inputs[1].links[0].from_node.type == 'R_LAYERS'
    assert len(bpy.context.view_layer.lightgroups) == 0


def test03_cycles_bake_sets_up_groups_passes_and_chain(tmp_path):
    scene = build_plane_scene(tmp_path)
    scene.render.engine = 'CYCLES'
    _add_light(scene, "Key", 'POINT', (-1.0, 0.5, 1.5), group="user_key")
    path = str(tmp_path / "fog.exr")
    assert bpy.ops.airlight.bake('EXEC_DEFAULT', filepath=path) == {'FINISHED'}
    view_layer = bpy.context.view_layer
    assert [lg.name for lg in view_layer.lightgroups] == ["fog_Lamp"]
    assert scene.objects["Lamp"].lightgroup == "fog_Lamp"
    assert scene.objects["Key"].lightgroup == "user_key"
    assert view_layer.use_pass_diffuse_color
    # The EXR has the surface passes: attenuation - 1 (in (-1, 0]) and the glow (>= 0).
    delta = exr_pass(path, "Surface_fog_Lamp")
    glow = exr_pass(path, "SurfaceGlow")
    assert np.all(delta <= 0.0) and np.all(delta > -1.0) and delta.min() < -0.1
    assert np.all(glow >= 0.0) and glow.max() > 0.0
    # Chain: Image + Combined_fog_Lamp x Surface_fog_Lamp + DiffCol x SurfaceGlow -> x T.
    tree = scene.node_tree
    assert _surface_nodes(tree) == ["Airlight Surface Add 0", "Airlight Surface Add 1",
                                    "Airlight Surface Multiply 0", "Airlight Surface Multiply 1"]
    render_layers = next(n for n in tree.nodes if n.type == 'R_LAYERS')
    m0, m1 = tree.nodes["Airlight Surface Multiply 0"], tree.nodes["Airlight Surface Multiply 1"]
    a0, a1 = tree.nodes["Airlight Surface Add 0"], tree.nodes["Airlight Surface Add 1"]
    assert m0.inputs[1].links[0].from_socket == render_layers.outputs["Combined_fog_Lamp"]
    assert m0.inputs[2].links[0].from_socket.name == "Surface_fog_Lamp"
    assert m1.inputs[1].links[0].from_socket == render_layers.outputs["DiffCol"]
    assert m1.inputs[2].links[0].from_socket.name == "SurfaceGlow"
    assert a0.inputs[1].links[0].from_socket == render_layers.outputs["Image"]
    assert a1.inputs[1].links[0].from_node == a0
    assert tree.nodes["Airlight Multiply"].inputs[1].links[0].from_node == a1
    # Idempotent.
    before = (len(tree.nodes), len(tree.links))
    compositor.setup(scene, path)
    compositor.setup(scene)
    assert (len(tree.nodes), len(tree.links)) == before
    # Fog off mutes the chain too.
    scene.airlight.enabled = False
    assert a0.mute and m1.mute
    scene.airlight.enabled = True
    assert not a0.mute
    # Surface shading off: the chain goes, the render feeds the fog nodes directly.
    scene.airlight.surface_shading = False
    assert _surface_nodes(tree) == []
    assert tree.nodes["Airlight Multiply"].inputs[1].links[0].from_socket == render_layers.outputs["Image"]
    # And back on: neutral passes with the surface names until the next bake.
    scene.airlight.surface_shading = True
    assert len(_surface_nodes(tree)) == 4


def test04_bake_without_surface_writes_no_surface_passes(tmp_path):
    from conftest import read_exr
    scene = build_plane_scene(tmp_path)
    scene.render.engine = 'CYCLES'
    scene.airlight.surface_shading = False
    path = str(tmp_path / "fog.exr")
    assert bpy.ops.airlight.bake('EXEC_DEFAULT', filepath=path) == {'FINISHED'}
    _, names = read_exr(path)
    assert not any("Surface" in n for n in names)
    assert len(bpy.context.view_layer.lightgroups) == 0


def test05_gloss_exponent_adds_the_glossy_glow(tmp_path):
    """Gloss Exponent > 0: the bake writes SurfaceGloss (Sun 2005 eq. 18 glossy glow, the
    kernel is held to scipy in tests/native/test_bake_surface.py), equal to the native
    bake with that exponent; Glossy Color is enabled and the chain adds GlossCol x it."""
    from airlight import bake
    scene = build_plane_scene(tmp_path)
    scene.render.engine = 'CYCLES'
    scene.airlight.surface_gloss = 20.0
    path = str(tmp_path / "fog.exr")
    assert bpy.ops.airlight.bake('EXEC_DEFAULT', filepath=path) == {'FINISHED'}
    assert bpy.context.view_layer.use_pass_glossy_color
    gloss = exr_pass(path, surface.PASS_GLOSS)
    assert np.all(gloss >= 0.0) and gloss.max() > 0.0
    description, settings = bake.prepare(scene, bpy.context.evaluated_depsgraph_get())
    assert settings["surface_phong_exponent"] == 20.0
    from airlight import native
    kw = bake.native_settings(settings)
    ref = native.get().bake(**description, **kw)["surface_gloss_glow"]
    np.testing.assert_allclose(gloss, ref, rtol=1e-5, atol=1e-9)
    tree = scene.node_tree
    render_layers = next(n for n in tree.nodes if n.type == 'R_LAYERS')
    links = {(l.from_socket.name, l.to_node.name) for l in tree.links}
    assert any(name == "GlossCol" for name, _ in links), links
    assert any(name == surface.PASS_GLOSS for name, _ in links), links
    assert render_layers.outputs["GlossCol"].enabled
    # 0 turns it off again: no pass, no term.
    scene.airlight.surface_gloss = 0.0
    assert bpy.ops.airlight.bake('EXEC_DEFAULT', filepath=path) == {'FINISHED'}
    from conftest import read_exr
    _, names = read_exr(path)
    assert not any(surface.PASS_GLOSS in n for n in names)
    assert not any(l.from_socket.name == "GlossCol" for l in tree.links)


def test06_skipped_lights_keep_groups_aligned(tmp_path):
    """Automatic skips a faint light (not exported to the bake): its group must not take a
    place in the bake's light order, or the attenuation images would shift onto the wrong
    light groups. The faint light comes first in the scene so a shift would show."""
    from airlight import bake, model_choice
    scene = build_plane_scene(tmp_path, light=False)
    scene.render.engine = 'CYCLES'
    _add_light(scene, "Faint", 'POINT', (0.0, -60.0, 3.0)).data.energy = 0.01
    _add_light(scene, "Key", 'POINT', (0.5, 0.3, 1.0)).data.energy = 300.0
    scene.airlight.model = 'AUTO'
    bpy.context.view_layer.update()
    depsgraph = bpy.context.evaluated_depsgraph_get()
    assert model_choice.skipped_lights(scene, depsgraph) == {"Faint"}
    description, settings = bake.prepare(scene, depsgraph)
    assert len(description["light_positions"]) == 1
    assert settings[bake.SURFACE_GROUPS] == ["fog_Key"]
    path = str(tmp_path / "fog.exr")
    assert bpy.ops.airlight.bake('EXEC_DEFAULT', filepath=path) == {'FINISHED'}
    from conftest import read_exr
    _, names = read_exr(path)
    assert {n.rsplit(".", 1)[0] for n in names if n.startswith("Fog.Surface_")} == {"Fog.Surface_fog_Key"}
    from airlight import native
    kw = bake.native_settings(settings)
    ref = native.get().bake(**description, **kw)["surface_attenuation"][0] - 1.0
    np.testing.assert_allclose(exr_pass(path, "Surface_fog_Key"), ref, rtol=1e-5, atol=1e-7)


def test07_sun_light_on_surfaces_is_dimmed_by_the_fog_layer(tmp_path):
    """A sun lamp's light on a surface inside the fog layer crosses (top - z) / mu_s of fog:
    its group's pass is e^(-sigma (top - z) / mu_s) - 1 (sunlight_layer.h), computed here from the
    hit points; without a fog top the sun is unattenuated (pass 0)."""
    from airlight import bake
    scene = build_plane_scene(tmp_path, light=False)
    scene.render.engine = 'CYCLES'
    sun = _add_light(scene, "Sun", 'SUN', (0.0, 0.0, 10.0))
    sun.rotation_euler = (math.radians(30.0), 0.0, 0.0)
    scene.airlight.density = 0.05
    scene.airlight.use_fog_top = True
    scene.airlight.fog_top = 8.0
    bpy.context.view_layer.update()
    path = str(tmp_path / "fog.exr")
    assert bpy.ops.airlight.bake('EXEC_DEFAULT', filepath=path) == {'FINISHED'}
    delta = exr_pass(path, "Surface_fog_Sun")[..., 0]
    floor = delta != 0.0
    assert floor.sum() > 100
    mu_s = math.cos(math.radians(30.0))          # the lamp's -Z tilted 30 deg from straight down
    want = math.exp(-0.05 * (8.0 - 0.0) / mu_s) - 1.0   # the floor is at z = 0
    np.testing.assert_allclose(delta[floor], want, rtol=1e-5)
    scene.airlight.use_fog_top = False
    assert bpy.ops.airlight.bake('EXEC_DEFAULT', filepath=path) == {'FINISHED'}
    np.testing.assert_array_equal(exr_pass(path, "Surface_fog_Sun"), 0.0)


def _centre_pixel_glow(scene, G):
    """The Lambert glow the bake should write at pixel (32, 24) of build_plane_scene's view
    (camera at z = 2 looking down -Z, 35 mm lens on a 36 mm sensor): albedo I0 sigma_t G(T,
    theta_s) / (2 pi^2 D) for the scene's one point light, G given as G(T, theta_s)."""
    W, H = scene.render.resolution_x, scene.render.resolution_y
    i, j = 32, 24
    half = 18.0 / 35.0
    x = ((i + 0.5) / W * 2.0 - 1.0) * half
    y = (1.0 - (j + 0.5) / H * 2.0) * half * H / W
    p = np.array([2.0 * x, 2.0 * y, 0.0])
    lamp = scene.objects["Lamp"]
    v = np.array(lamp.location) - p
    D = float(np.linalg.norm(v))
    sigma = scene.airlight.density
    I0 = np.array(lamp.data.color) * lamp.data.energy / (4.0 * math.pi)
    albedo = np.array(scene.airlight.color)
    return albedo * I0 * sigma * G(sigma * D, math.acos(v[2] / D)) / (2.0 * math.pi ** 2 * D)


def test08_anisotropic_phase_glow(tmp_path):
    """An anisotropic phase changes the glow: the phase-aware G_p (Biri 2006 eq. 8-13) for the
    default glow model (every fog model), Biri's own eq. 10 (Gamma_L x cos, clamped) with Glow
    Model 'Biri 2006 eq. 10'; each equals the
    native exact kernel at a pixel (the kernels are held to scipy in tests/native/test16). The
    panel line says which glow model is used."""
    from airlight import native
    _native = native.get()
    scene = build_plane_scene(tmp_path)
    scene.render.engine = 'CYCLES'
    path = str(tmp_path / "fog.exr")
    scene.airlight.model = 'QUADRATURE'
    assert bpy.ops.airlight.bake('EXEC_DEFAULT', filepath=path) == {'FINISHED'}
    iso = exr_pass(path, surface.PASS_GLOW)
    assert surface.glow_model_text(scene.airlight, "quadrature").startswith("Glow: Sun 2005 G0")
    scene.airlight.phase = 'HENYEY_GREENSTEIN'
    scene.airlight.anisotropy = 0.6
    assert bpy.ops.airlight.bake('EXEC_DEFAULT', filepath=path) == {'FINISHED'}
    hg = exr_pass(path, surface.PASS_GLOW)
    assert np.max(np.abs(hg / iso - 1.0)) > 0.05
    expected = _centre_pixel_glow(scene, lambda T, th: _native.surface_G(T, th, phase="hg", g=0.6)[()])
    np.testing.assert_allclose(hg[24, 32], expected, rtol=5e-3)
    assert "phase-aware" in surface.glow_model_text(scene.airlight, "quadrature")
    # biri06 keeps the exact glow; Biri's Lambert model eq. 10 on request.
    scene.airlight.model = 'BIRI06'
    assert "phase-aware" in surface.glow_model_text(scene.airlight, "biri06")
    scene.airlight.surface_glow_model = 'BIRI06_EQ10'
    assert bpy.ops.airlight.bake('EXEC_DEFAULT', filepath=path) == {'FINISHED'}
    biri = exr_pass(path, surface.PASS_GLOW)
    G_B = lambda T, th: max(0.0, 4 * math.pi ** 2 * math.cos(th) * _native.biri06_gamma_L(T, phase="hg", g=0.6)[()])
    np.testing.assert_allclose(biri[24, 32], _centre_pixel_glow(scene, G_B), rtol=5e-3)
    assert "eq. 10" in surface.glow_model_text(scene.airlight, "biri06")


def test09_lights_added_later_get_their_groups_before_a_render(tmp_path):
    """A render composites with the node links it starts with, and an interactive render's
    thread cannot add light groups: a light added after the fog nodes exist gets its group
    and its pass in the chain at the next depsgraph update (compositor's
    on_depsgraph_update_post; tests/gpu/test_interactive_render.py renders such a scene with Ctrl+F12), and a
    file saved without that (an older add-on) gets it when loaded (render.on_load_post)."""
    scene = build_plane_scene(tmp_path)
    scene.render.engine = 'CYCLES'
    bpy.ops.airlight.setup_compositor()
    view_layer = bpy.context.view_layer
    tree = scene.node_tree
    assert scene.objects["Lamp"].lightgroup == "fog_Lamp"
    assert len(_surface_nodes(tree)) == 4  # Lamp and the glow
    key = _add_light(scene, "Key", 'POINT', (-1.0, 0.5, 1.5))
    assert key.lightgroup == ""
    view_layer.update()
    assert key.lightgroup == "fog_Key"
    assert {"fog_Lamp", "fog_Key"} <= {lg.name for lg in view_layer.lightgroups}
    assert tree.nodes[compositor.NODE_IMAGE].outputs.get("Surface_fog_Key") is not None
    assert len(_surface_nodes(tree)) == 6
    # Moving a light (no new group needed) changes nothing.
    before = (len(tree.nodes), len(tree.links), compositor.file_image(tree).filepath)
    key.location.x += 1.0
    view_layer.update()
    assert (len(tree.nodes), len(tree.links), compositor.file_image(tree).filepath) == before

    bpy.app.handlers.depsgraph_update_post.remove(compositor.on_depsgraph_update_post)
    try:
        fill = _add_light(scene, "Fill", 'SPOT', (1.0, -0.5, 1.5))
        view_layer.update()
        assert fill.lightgroup == ""
        blend = str(tmp_path / "later.blend")
        bpy.ops.wm.save_as_mainfile(filepath=blend)
    finally:
        bpy.app.handlers.depsgraph_update_post.append(compositor.on_depsgraph_update_post)
    script = tmp_path / "groups.py"
    script.write_text(
        "import bpy\n"
        "scene = bpy.context.scene\n"
        "node = scene.node_tree.nodes['" + compositor.NODE_IMAGE + "']\n"
        "print('GROUP', scene.objects['Fill'].lightgroup, node.outputs.get('Surface_fog_Fill') is not None,\n"
        "      'fog_Fill' in {lg.name for lg in scene.view_layers[0].lightgroups})\n")
    proc = run_blender(blend, "--python", str(script))
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    assert "GROUP fog_Fill True True" in proc.stdout, proc.stdout[-3000:]
