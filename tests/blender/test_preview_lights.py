"""The viewport preview draws the lights the bake bakes: both take them from the same
scene_description and model_choice plan (preview.preview_lights, the draw handler's own
input, against bake.prepare's `_native.bake` arguments), so lights inside a collection
instance are in both and the lights Automatic skips are in neither. The GPU tier holds the
draw handler's captured inputs to the same (tests/gpu/test_preview_bake_lights.py)."""

import math

import bpy
import numpy as np
import pytest

from airlight import bake, model_choice, preview
from conftest import build_plane_scene

ALBEDO = (0.9, 0.7, 0.5)


def _light(scene, name, kind, location, energy, collection=None, rotation=(0.4, 0.2, 0.0)):
    data = bpy.data.lights.new(name, kind)
    data.energy = energy
    data.color = (1.0, 0.8, 0.6)
    if kind == 'SPOT':
        data.spot_size, data.spot_blend = 1.2, 0.3
    obj = bpy.data.objects.new(name, data)
    obj.location = location
    obj.rotation_euler = rotation
    (collection or scene.collection).objects.link(obj)
    return obj


def _instanced_lights(scene):
    """A point light and a spot in a collection excluded from the view layer, instanced
    twice by empties (so only their instances render), beside the scene's own lamp."""
    props = bpy.data.collections.new("LightProps")
    scene.collection.children.link(props)
    _light(scene, "InstPoint", 'POINT', (0.0, 0.0, 1.0), 200.0, props)
    _light(scene, "InstSpot", 'SPOT', (0.5, 0.0, 2.0), 400.0, props)
    bpy.context.view_layer.layer_collection.children["LightProps"].exclude = True
    for k, x in enumerate((-2.0, 3.0)):
        empty = bpy.data.objects.new(f"LightInstance{k}", None)
        empty.instance_type = 'COLLECTION'
        empty.instance_collection = props
        empty.location = (x, 1.0, 0.5)
        scene.collection.objects.link(empty)


def _same_lights(scene):
    """Asserts preview_lights == the bake's lights (positions, intensities x albedo, cones,
    directions); returns the bake's arguments."""
    depsgraph = bpy.context.evaluated_depsgraph_get()
    description, _settings = bake.prepare(scene, depsgraph)
    lights = preview.preview_lights(scene, depsgraph)
    albedo = np.asarray(scene.airlight.color, dtype=np.float64)

    def check(got, expected, scale=1.0):
        expected = np.asarray(expected, dtype=np.float64).reshape(-1, 3) * scale
        np.testing.assert_allclose(np.asarray(got, dtype=np.float64).reshape(-1, 3), expected, rtol=1e-12, atol=0.0)
    check(lights["positions"], description["light_positions"])
    check(lights["I0"], description["light_intensities"])
    check(lights["intensities"], description["light_intensities"], albedo)
    spots = lights["spots"]
    check(spots["positions"], description.get("spot_positions", ()))
    check(spots["axes"], description.get("spot_axes", ()))
    check(spots["intensities"], description.get("spot_intensities", ()), albedo)
    assert spots["sizes"] == list(description.get("spot_size", ()))
    assert spots["blends"] == list(description.get("spot_blend", ()))
    suns = lights["suns"]
    check(suns["directions"], description.get("sun_directions", ()))
    check(suns["irradiances"], description.get("sun_irradiances", ()), albedo)
    assert suns["fog_top"] == description.get("fog_top", suns["fog_top"])
    # The compatibility readers of the preview give the same.
    assert preview.scene_lights(scene, bpy.context.view_layer) == (lights["positions"], lights["intensities"])
    assert preview.scene_spots(scene) == spots and preview.scene_suns(scene) == suns
    return description


def test01_lights_inside_a_collection_instance(tmp_path):
    """Two instances of a collection holding a point light and a spot: the preview draws
    all four instanced lights where the bake puts them, plus the scene's own lamp and sun."""
    scene = build_plane_scene(tmp_path)
    scene.airlight.color = ALBEDO
    _instanced_lights(scene)
    _light(scene, "Sun", 'SUN', (0.0, 0.0, 10.0), 2.0)
    bpy.context.view_layer.update()
    description = _same_lights(scene)
    assert len(description["light_positions"]) == 3   # Lamp + InstPoint twice
    assert len(description["spot_positions"]) == 2    # InstSpot twice
    assert len(description["sun_directions"]) == 1
    # The instances sit at their empties (x = -2 and 3) plus the light's own offset.
    xs = sorted(p[0] for p in preview.preview_lights(scene, bpy.context.evaluated_depsgraph_get())["positions"])
    assert xs == pytest.approx([-2.0, 0.5, 3.0])


def test02_lights_automatic_skips(tmp_path):
    """Automatic skips a faint far point light and a faint far spot (light_bounds.py): the
    preview leaves out the same ones. The same lights in an instance are never skipped, and
    an explicit model skips nothing, in both."""
    scene = build_plane_scene(tmp_path)
    scene.airlight.color = ALBEDO
    _light(scene, "FaintPoint", 'POINT', (0.0, -200.0, 3.0), 0.001)
    _light(scene, "FaintSpot", 'SPOT', (0.0, -220.0, 3.0), 0.001)
    _light(scene, "Key", 'SPOT', (0.5, -1.0, 3.0), 500.0, rotation=(0.0, 0.0, 0.0))
    scene.airlight.model = 'AUTO'
    bpy.context.view_layer.update()
    depsgraph = bpy.context.evaluated_depsgraph_get()
    assert model_choice.skipped_lights(scene, depsgraph) == {"FaintPoint", "FaintSpot"}
    description = _same_lights(scene)
    assert len(description["light_positions"]) == 1 and len(description["spot_positions"]) == 1
    # A negative light Automatic skips stops neither; once it is not skipped, both refuse it.
    bpy.data.lights["FaintPoint"].energy = -1.0
    _same_lights(scene)
    scene.airlight.model = 'SUN05'
    bpy.context.view_layer.update()
    depsgraph = bpy.context.evaluated_depsgraph_get()
    with pytest.raises(bake.BakeError, match="negative power"):
        bake.prepare(scene, depsgraph)
    with pytest.raises(ValueError, match="negative power"):
        preview.preview_lights(scene, depsgraph)
    bpy.data.lights["FaintPoint"].energy = 0.001
    description = _same_lights(scene)
    assert len(description["light_positions"]) == 2 and len(description["spot_positions"]) == 2


def test03_daylight_has_sun_lamps_only(tmp_path):
    """Hoffman-Preetham (daylight) bakes sun lamps alone: so does the preview."""
    scene = build_plane_scene(tmp_path)
    _light(scene, "Sun", 'SUN', (0.0, 0.0, 10.0), 3.0)
    _light(scene, "Spot", 'SPOT', (0.0, 0.0, 3.0), 300.0)
    scene.airlight.model = 'HOFFMAN02'
    scene.airlight.use_fog_top = False
    bpy.context.view_layer.update()
    description = _same_lights(scene)
    assert len(description["light_positions"]) == 0 and "spot_positions" not in description
    assert description["fog_top"] == math.inf


def test_panel_says_what_the_preview_shadows(tmp_path):
    """The preview panel with Volumetric Shadows on: the Shadows setting, and the lines for
    lights past the shadow maps' limit and for a GPU that could not hold the maps."""
    from conftest import build_plane_scene, draw_panel
    scene = build_plane_scene(tmp_path)
    scene.airlight.volumetric_shadows = True
    state = preview._state
    seen = " ".join(map(str, draw_panel("AIRLIGHT_PT_viewport_preview")))
    assert "airlight_preview_shadows" in seen, seen
    state["shadow_dropped"], state["shadow_error"] = 3, "RuntimeError: texture too large"
    try:
        seen = " ".join(map(str, draw_panel("AIRLIGHT_PT_viewport_preview")))
    finally:
        state["shadow_dropped"], state["shadow_error"] = 0, None
    assert "3 shadowed lights past 8" in seen and "texture too large" in seen, seen
