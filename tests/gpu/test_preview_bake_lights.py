"""The draw handler in the window's 3D viewport draws the lights the bake bakes: its
captured inputs (preview._state["capture"]) hold the point lights, spots and sun lamps of
bake.prepare's `_native.bake` arguments (times the fog's albedo), so lights inside a
collection instance are drawn and the lights Automatic skips are not; a scene the bake
refuses (a negative light it does not skip) draws no fog and says why in the panel, and
the next draw after the fix draws again. (The Blender tier holds preview.preview_lights to
the same: tests/blender/test_preview_lights.py.)"""

import bpy
import numpy as np
import pytest

from preview_scenes import build_scene, capture_draw


def _light(scene, name, kind, location, energy, collection=None):
    data = bpy.data.lights.new(name, kind)
    data.energy = energy
    data.shadow_soft_size = 0.0
    if kind == 'SPOT':
        data.spot_size, data.spot_blend = 1.0, 0.2
    obj = bpy.data.objects.new(name, data)
    obj.location = location
    obj.rotation_euler = (0.3, 0.2, 0.0)
    (collection or scene.collection).objects.link(obj)
    return obj


@pytest.fixture(scope="module")
def lights_scene(addon, native):
    """The preview scene's two lamps, a collection holding a point light and a spot instanced
    twice, a sun lamp, and a faint point light far behind the camera (Automatic skips it)."""
    scene = build_scene(0.05)
    props = bpy.data.collections.new("LightProps")
    scene.collection.children.link(props)
    _light(scene, "InstPoint", 'POINT', (0.0, 0.0, 1.5), 300.0, props)
    _light(scene, "InstSpot", 'SPOT', (0.5, 0.0, 2.5), 600.0, props)
    bpy.context.view_layer.layer_collection.children["LightProps"].exclude = True
    for k, x in enumerate((-3.0, 2.5)):
        empty = bpy.data.objects.new(f"LightInstance{k}", None)
        empty.instance_type = 'COLLECTION'
        empty.instance_collection = props
        empty.location = (x, 2.0, 0.0)
        scene.collection.objects.link(empty)
    _light(scene, "Sun", 'SUN', (0.0, 0.0, 10.0), 2.0)
    _light(scene, "Faint", 'POINT', (0.0, -300.0, 4.0), 0.001)
    scene.airlight.model = 'AUTO'
    bpy.context.view_layer.update()
    yield scene
    for obj in list(scene.objects):
        bpy.data.objects.remove(obj)
    bpy.data.collections.remove(props)


def test01_handler_draws_the_bakes_lights(addon, lights_scene):
    from airlight import bake, model_choice
    scene = lights_scene
    depsgraph = bpy.context.evaluated_depsgraph_get()
    assert model_choice.skipped_lights(scene, depsgraph) == {"Faint"}
    description, _settings = bake.prepare(scene, depsgraph)
    cap = capture_draw(addon)
    albedo = np.asarray(scene.airlight.color, dtype=np.float64)

    def same(got, expected, scale=1.0):
        np.testing.assert_allclose(np.asarray(got, dtype=np.float64).reshape(-1, 3),
                                   np.asarray(expected, dtype=np.float64).reshape(-1, 3) * scale, rtol=1e-12)
    positions, intensities = cap["lights"]
    same(positions, description["light_positions"])
    same(intensities, description["light_intensities"], albedo)
    assert len(positions) == 4  # LampA, LampB and InstPoint twice; not Faint
    same(cap["spots"]["positions"], description["spot_positions"])
    same(cap["spots"]["axes"], description["spot_axes"])
    same(cap["spots"]["intensities"], description["spot_intensities"], albedo)
    assert cap["spots"]["sizes"] == list(description["spot_size"]) and len(cap["spots"]["sizes"]) == 2
    assert cap["spots"]["blends"] == list(description["spot_blend"])
    same(cap["suns"]["directions"], description["sun_directions"])
    same(cap["suns"]["irradiances"], description["sun_irradiances"], albedo)
    assert cap["suns"]["fog_top"] == description["fog_top"]


def test02_a_scene_the_bake_refuses_draws_no_fog(addon, lights_scene):
    from airlight import bake
    scene = lights_scene
    lamp = bpy.data.lights["LampB"]
    lamp.energy = -5.0
    scene.airlight.model = 'SUN05'  # (Automatic would skip it: its upper bound is 0)
    try:
        with pytest.raises(bake.BakeError, match="negative power"):
            bake.prepare(scene, bpy.context.evaluated_depsgraph_get())
        n = addon._state["draws"]
        cap = capture_draw(addon)
        assert cap == {} and addon._state["draws"] == n
        assert "negative power" in addon._state["problem"]
    finally:
        lamp.energy = 800.0
        scene.airlight.model = 'AUTO'
    cap = capture_draw(addon)
    assert addon._state["problem"] is None and len(cap["lights"][0]) == 4
