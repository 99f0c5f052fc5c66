"""Light Passes: each fogged light's airlight as its own pass, Fog.Airlight_<light name>,
beside the total Fog.Airlight (issue: a pass per light).

- test01: two point lights (one named with a dot), a spot and a sun in homogeneous fog with
  volumetric shadows: one pass per light, named as the light groups are, each equal to a bake
  of that light alone (its Scatter in Fog kept, the others' off; the costliest light's pass
  is the total less the others'), and their sum the total.
- test02: an area light (its samples in one pass), Environment Glow (Fog.Airlight_World) and
  fog objects: the passes still sum to the total.
- test03: on by default, with a limit of 8 fogged lights; test04: over the limit, no
  per-light pass, and the console line and the panel say so.
- test05: one light: its pass is the total, with no second bake. test06: off.
"""
import math

import bpy
import numpy as np

from conftest import build_plane_scene, exr_pass, read_exr


def _light(scene, name, kind, location, energy, **settings):
    data = bpy.data.lights.new(name, kind)
    data.energy = energy
    for key, value in settings.items():
        setattr(data, key, value)
    obj = bpy.data.objects.new(name, data)
    obj.location = location
    scene.collection.objects.link(obj)
    return obj


def _scene(tmp_path):
    scene = build_plane_scene(tmp_path, size=(48, 36))
    scene.camera.location = (0.0, -6.0, 2.0)
    scene.camera.rotation_euler = (1.3, 0.0, 0.0)
    bpy.data.objects["Lamp"].name = "Lamp.001"
    _light(scene, "Street", 'POINT', (2.0, 1.0, 1.5), 200.0)
    spot = _light(scene, "Spot", 'SPOT', (-1.5, 0.0, 3.0), 500.0, spot_size=math.radians(60.0))
    spot.rotation_euler = (0.3, 0.0, 0.0)
    sun = _light(scene, "Sun", 'SUN', (0.0, 0.0, 10.0), 2.0)
    sun.rotation_euler = (0.6, 0.2, 0.0)
    mesh = bpy.data.meshes.new("Wall")
    mesh.from_pydata([(-1, 1, 0), (1, 1, 0), (1, 1, 2), (-1, 1, 2)], [], [(0, 1, 2, 3)])
    scene.collection.objects.link(bpy.data.objects.new("Wall", mesh))
    st = scene.airlight
    st.density = 0.08
    st.volumetric_shadows = True
    st.shadow_samples = 1  # hard shadows: no probe bakes (soft ones: test_volumetric_shadows.py)
    st.light_passes = True
    st.model = 'SUN05'
    bpy.context.view_layer.update()
    return scene


def _bake(tmp_path, name):
    path = str(tmp_path / f"{name}.exr")
    assert bpy.ops.airlight.bake(frame=1, filepath=path) == {'FINISHED'}
    return path


def _light_pass_names(path):
    _, names = read_exr(path)
    return sorted({n.split(".")[1] for n in names if n.startswith("Fog.Airlight_")})


def test01_one_pass_per_light_each_its_light_alone(tmp_path):
    scene = _scene(tmp_path)
    path = _bake(tmp_path, "all")
    assert _light_pass_names(path) == ["Airlight_Lamp_001", "Airlight_Spot", "Airlight_Street", "Airlight_Sun"]
    total = exr_pass(path, "Airlight").astype(np.float64)
    parts = {name: exr_pass(path, name).astype(np.float64) for name in _light_pass_names(path)}
    np.testing.assert_allclose(sum(parts.values()), total, rtol=1e-5, atol=1e-7 * total.max())
    assert all(p.max() > 1e-3 * total.max() for p in parts.values())
    lights = {"Airlight_Lamp_001": "Lamp.001", "Airlight_Spot": "Spot", "Airlight_Street": "Street",
              "Airlight_Sun": "Sun"}
    scene.airlight.light_passes = False
    for pass_name, light in lights.items():
        for obj in scene.objects:
            if obj.type == 'LIGHT':
                obj.data.airlight.participate = obj.name == light
        alone = exr_pass(_bake(tmp_path, pass_name), "Airlight").astype(np.float64)
        np.testing.assert_allclose(parts[pass_name], alone, rtol=1e-5, atol=1e-7 * total.max())


def test02_area_light_world_and_fog_objects_sum_to_the_total(tmp_path):
    scene = _scene(tmp_path)
    _light(scene, "Panel", 'AREA', (0.0, 2.0, 2.5), 300.0, size=1.0)
    scene.airlight.model = 'AUTO'
    scene.airlight.environment_glow = True
    world = bpy.data.worlds.new("W")
    world.color = (0.05, 0.05, 0.08)
    scene.world = world
    from airlight import fog_object
    fog_object.new_fog_object("Blob", scene.collection, np.array([[0.5, 1.5, 1.0], [-0.5, 0.5, 1.2]]),
                              np.array([1.2, 1.5]), np.array([0.4, 0.3]))
    bpy.context.view_layer.update()
    path = _bake(tmp_path, "mixed")
    names = _light_pass_names(path)
    assert "Airlight_Panel" in names and "Airlight_World" in names, names
    total = exr_pass(path, "Airlight").astype(np.float64)
    parts = sum(exr_pass(path, name).astype(np.float64) for name in names)
    np.testing.assert_allclose(parts, total, rtol=1e-5, atol=1e-6 * total.max())
    assert exr_pass(path, "Airlight_World").max() > 0.0


def test03_on_by_default_up_to_the_limit(tmp_path):
    scene = _scene(tmp_path)
    scene.airlight.property_unset("light_passes")
    scene.airlight.property_unset("light_pass_limit")
    assert scene.airlight.light_passes and scene.airlight.light_pass_limit == 8
    assert len(_light_pass_names(_bake(tmp_path, "default"))) == 4
    from airlight import ui
    assert ui.light_pass_note(scene) is None


def test04_over_the_limit_none_and_says_so(tmp_path):
    from airlight import bake, ui
    scene = _scene(tmp_path)
    scene.airlight.light_pass_limit = 3
    assert _light_pass_names(_bake(tmp_path, "over")) == []
    description, settings = bake.prepare(scene, bpy.context.evaluated_depsgraph_get())
    stats, _ = bake.run(description, settings, str(tmp_path / "over_run.exr"))
    assert "4 fogged lights, over the Light Pass Limit of 3" in bake.parts_line(stats)
    assert ui.light_pass_note(scene) == "4 fogged lights, over the limit: no light passes"
    scene.airlight.light_passes = False
    assert ui.light_pass_note(scene) is None


def test05_one_light_costs_no_extra_bake(tmp_path):
    from airlight import bake
    scene = _scene(tmp_path)
    for obj in scene.objects:
        if obj.type == 'LIGHT':
            obj.data.airlight.participate = obj.name == "Street"
    description, settings = bake.prepare(scene, bpy.context.evaluated_depsgraph_get())
    calls = []
    module = bake.native.get()

    class Counting:
        def __getattr__(self, name):
            return getattr(module, name)

        def bake(self, **kwargs):
            calls.append(1)
            return module.bake(**kwargs)

    original = bake.native.get
    bake.native.get = lambda: Counting()
    try:
        path = str(tmp_path / "one.exr")
        bake.run(description, settings, path)
    finally:
        bake.native.get = original
    assert len(calls) == 1
    assert _light_pass_names(path) == ["Airlight_Street"]
    np.testing.assert_array_equal(exr_pass(path, "Airlight_Street"), exr_pass(path, "Airlight"))


def test06_off(tmp_path):
    scene = _scene(tmp_path)
    scene.airlight.light_passes = False
    assert _light_pass_names(_bake(tmp_path, "off")) == []
