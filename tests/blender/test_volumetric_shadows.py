"""Volumetric Shadows in the add-on: which objects cast, which lights are shadowed (Cast
Shadow, Automatic's lights with no caster near enough to matter, fog objects), the panel's
lines, and the bake operator's passes (a lamp shut in a box lights no fog outside it).
The shadows' accuracy against Cycles is test_cycles_shadows.py's."""
import math

import bpy
import numpy as np
import pytest

from conftest import build_plane_scene, exr_pass
from airlight import model_choice, scene_export, ui


def _cube(name, location, size, scene):
    bpy.ops.mesh.primitive_cube_add(size=size, location=location)
    obj = bpy.context.active_object
    obj.name = name
    if obj.name not in scene.collection.objects:
        scene.collection.objects.link(obj)
    return obj


def _export(scene):
    return scene_export.export_scene(scene, bpy.context.evaluated_depsgraph_get())


def test01_cast_shadow_off_means_no_shadow_arguments(tmp_path):
    scene = build_plane_scene(tmp_path)
    assert scene.airlight.volumetric_shadows          # on by default
    assert _export(scene)["shadows"] is True
    bpy.data.lights["Lamp"].use_shadow = False
    description = _export(scene)
    assert "shadows" not in description and "light_shadows" not in description
    rows = {row.name: row for row in model_choice.light_plan(scene)}
    assert rows["Lamp"].shadow == 'no shadow'
    lines = dict((text.split(":")[0], text) for text, _ in ui.light_lines(scene))
    assert lines["Lamp"].endswith("unshadowed (Cast Shadow off)")


def test02_one_flag_per_light_in_bake_order(tmp_path):
    scene = build_plane_scene(tmp_path)
    second = bpy.data.objects.new("Second", bpy.data.lights.new("Second", 'POINT'))
    second.location = (-0.5, 0.2, 1.2)
    second.data.use_shadow = False
    scene.collection.objects.link(second)
    spot = bpy.data.objects.new("Spot", bpy.data.lights.new("Spot", 'SPOT'))
    spot.location = (0.0, 0.0, 1.5)
    scene.collection.objects.link(spot)
    bpy.context.view_layer.update()
    description = _export(scene)
    order = [tuple(np.round(p, 4)) for p in description["light_positions"]]
    flags = dict(zip(order, description["light_shadows"]))
    assert flags == {(0.5, 0.3, 1.0): 1.0, (-0.5, 0.2, 1.2): 0.0}
    assert list(description["spot_shadows"]) == [1.0]


def test03_ray_visibility_picks_the_casters(tmp_path):
    """Shadow off: still seen, casts nothing; Camera off: unseen, still casts."""
    scene = build_plane_scene(tmp_path)
    seen_only = _cube("SeenOnly", (2.0, 0.0, 0.5), 0.5, scene)
    seen_only.visible_shadow = False
    caster_only = _cube("CasterOnly", (-2.0, 0.0, 0.5), 0.5, scene)
    caster_only.visible_camera = False
    bpy.context.view_layer.update()
    description = _export(scene)
    camera_x = description["vertices"][:, 0]
    casters_x = description["occluder_vertices"][:, 0]
    assert np.any(np.isclose(camera_x, 2.25)) and not np.any(np.isclose(camera_x, -2.25))
    assert np.any(np.isclose(casters_x, -2.25)) and not np.any(np.isclose(casters_x, 2.25))
    # Both ground and caster-only cube in the casters: 2 + 12 triangles, the ground's (seen by
    # the camera too: its caps cut no camera ray) first.
    assert len(description["occluder_triangles"]) == 14 and description["occluder_seen_triangles"] == 2
    assert np.all(np.isclose(description["occluder_vertices"][description["occluder_triangles"][2:].ravel(), 0],
                             -2.0, atol=0.26))
    seen_only.visible_shadow = True
    caster_only.visible_camera = True
    bpy.context.view_layer.update()
    assert "occluder_vertices" not in _export(scene)    # the same soup: not sent twice


def test04_automatic_leaves_far_lights_clear(tmp_path):
    """A dim caster 2 km from thick fog's light: its shadow cannot reach the accuracy target."""
    scene = build_plane_scene(tmp_path)
    bpy.data.objects.remove(bpy.data.objects["Ground"])
    _cube("FarBox", (0.0, 2000.0, 0.0), 1.0, scene)
    scene.airlight.density = 0.05
    bpy.context.view_layer.update()
    rows = {row.name: row for row in model_choice.light_plan(scene)}
    assert rows["Lamp"].shadow == 'clear'
    assert "shadows" not in _export(scene)
    scene.airlight.model = 'SUN05_EXACT'       # a model chosen by hand: every caster counts
    rows = {row.name: row for row in model_choice.light_plan(scene)}
    assert rows["Lamp"].shadow == 'shadowed'
    assert _export(scene)["shadows"] is True


def test05_off_and_no_caster_and_fog_objects(tmp_path):
    from airlight import fog_object
    scene = build_plane_scene(tmp_path)
    scene.airlight.volumetric_shadows = False
    assert "shadows" not in _export(scene)
    assert ui.shadow_note(scene) is None
    scene.airlight.volumetric_shadows = True
    bpy.data.objects["Ground"].visible_shadow = False
    bpy.context.view_layer.update()
    assert "shadows" not in _export(scene)
    assert "No object casts shadows" in ui.shadow_note(scene)
    bpy.data.objects["Ground"].visible_shadow = True
    fog_object.new_fog_object("Fog", scene.collection, centres=[(0.0, 0.0, 1.0)])
    bpy.context.view_layer.update()
    # Fog objects: point lights shadowed (no 'clear': the bound is the uniform fog's).
    assert ui.shadow_note(scene) is None
    rows = {row.name: row for row in model_choice.light_plan(scene)}
    assert rows["Lamp"].shadow == 'shadowed'
    exported = _export(scene)
    assert exported["shadows"] is True and "rbf_centres" in exported


def test06_bake_operator_lamp_in_a_closed_box(tmp_path):
    """The operator's Airlight pass: no fog outside a closed box around the lamp with
    Volumetric Shadows on; off, it glows (and Transmittance is the same)."""
    scene = build_plane_scene(tmp_path)
    box = _cube("Box", (0.5, 0.3, 1.0), 0.4, scene)
    box.visible_camera = True
    scene.camera.location = (0.0, -6.0, 1.0)
    scene.camera.rotation_euler = (math.pi / 2, 0.0, 0.0)
    bpy.context.view_layer.update()
    passes = {}
    for on in (True, False):
        scene.airlight.volumetric_shadows = on
        path = tmp_path / f"fog_{on}.exr"
        assert bpy.ops.airlight.bake(filepath=str(path)) == {'FINISHED'}
        passes[on] = (exr_pass(str(path), "Airlight"), exr_pass(str(path), "Transmittance"))
    lit_off, lit_on = passes[False][0].sum(), passes[True][0].sum()
    assert lit_off > 0.0
    assert lit_on < 1e-5 * lit_off, (lit_on, lit_off)
    # (the same to rounding: with shadows the edge samples take the per-ray path, not the lattice)
    np.testing.assert_allclose(passes[True][1], passes[False][1], rtol=1e-6, atol=1e-9)


def test07_soft_shadow_samples_automatic(tmp_path):
    """Soft Shadow Samples: Automatic (the default) probes a lamp with a Radius behind a caster
    and reports the count it took (console line and stats); a lamp without Radius, an explicit
    count or shadows off take no probe; the explicit count reaches the bake."""
    from airlight import bake
    scene = build_plane_scene(tmp_path)
    assert scene.airlight.shadow_samples == 0  # Automatic
    _cube("Caster", (0.5, 0.3, 0.3), 0.2, scene)
    lamp = bpy.data.lights["Lamp"]
    lamp.shadow_soft_size = 0.3
    bpy.context.view_layer.update()
    depsgraph = bpy.context.evaluated_depsgraph_get()
    description, settings = bake.prepare(scene, depsgraph)
    assert settings[bake.SOFT_SHADOW_TARGET] == pytest.approx(0.01) and settings["shadow_samples"] == 1
    stats, _ = bake.run(description, settings, str(tmp_path / "auto.exr"))
    samples, error, seconds, limited, _ = stats["soft_shadows"]
    assert samples in (1, 8, 16, 32, 64) and error <= 0.005 and seconds > 0.0 and limited == ""
    assert f"soft shadows {samples} sample(s)" in bake.parts_line(stats)
    bake.LAST_SOFT_SHADOWS.pop(scene.name, None)
    assert "measured per frame" in ui.soft_shadow_note(scene)
    assert bpy.ops.airlight.bake(filepath=str(tmp_path / "op.exr")) == {'FINISHED'}  # (the panel's line)
    assert bake.LAST_SOFT_SHADOWS[scene.name].remembered  # the same frame: not measured again
    assert "remembered from an earlier bake of this frame" in ui.soft_shadow_note(scene)
    assert ui.soft_shadow_note(scene).startswith(f"Automatic, last bake: {bake.LAST_SOFT_SHADOWS[scene.name].samples} "
                                                 "sample(s)")
    scene.airlight.accuracy = 0.01  # below what the samples can show: the most
    description, settings = bake.prepare(scene, depsgraph)
    fine = bake.run(description, settings, str(tmp_path / "fine.exr"))[0]
    assert fine["soft_shadows"].samples == 64 and fine["soft_shadows"].limited == "ladder"
    assert "the most it takes" in bake.parts_line(fine)
    scene.airlight.shadow_samples = 4
    description, settings = bake.prepare(scene, depsgraph)
    assert bake.SOFT_SHADOW_TARGET not in settings and settings["shadow_samples"] == 4
    assert "soft_shadows" not in bake.run(description, settings, str(tmp_path / "four.exr"))[0]
    scene.airlight.shadow_samples = 0
    lamp.shadow_soft_size = 0.0
    bpy.context.view_layer.update()
    assert bake.SOFT_SHADOW_TARGET not in bake.prepare(scene, bpy.context.evaluated_depsgraph_get())[1]
