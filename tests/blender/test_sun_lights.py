"""Sun lamps in the export, the Automatic model's light skipping (a faint far light is
skipped and the image changes by less than the accuracy target; a bright one never is),
the rigour of the bounds it uses against the native bake, and the panel's light list."""
import math

import bpy
import numpy as np
import pytest

from airlight import bake, fog_object, light_bounds, model_choice, names, native, scene_description, scene_export, ui

SIGMA = 0.1


def build_scene(tmp_path, far_energy=10.0):
    """Camera 1.5 m above a ground plane looking along +Y into open fog; a bright point
    light in frame and a faint one 40 m behind the camera; a sun lamp."""
    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    mesh = bpy.data.meshes.new("Ground")
    half = 200.0
    mesh.from_pydata([(-half, -half, 0), (half, -half, 0), (half, half, 0), (-half, half, 0)], [], [(0, 1, 2, 3)])
    scene.collection.objects.link(bpy.data.objects.new("Ground", mesh))

    def lamp(name, kind, energy, location, rotation=(0.0, 0.0, 0.0)):
        data = bpy.data.lights.new(name, kind)
        data.energy = energy
        if kind != 'SUN':
            data.shadow_soft_size = 0.0
        obj = bpy.data.objects.new(name, data)
        obj.location = location
        obj.rotation_euler = rotation
        scene.collection.objects.link(obj)
        return obj

    lamp("Near", 'POINT', 1000.0, (0.5, 6.0, 2.0))
    lamp("Far", 'POINT', far_energy, (0.0, -40.0, 3.0))
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    cam.location = (0.0, 0.0, 1.5)
    cam.rotation_euler = (math.radians(90.0), 0.0, 0.0)
    scene.collection.objects.link(cam)
    scene.camera = cam
    scene.render.resolution_x, scene.render.resolution_y = 48, 32
    scene.render.resolution_percentage = 100
    settings = scene.airlight
    settings.density = SIGMA
    settings.cache_dir = str(tmp_path / "cache") + "/"
    settings.model = 'AUTO'
    settings.accuracy = 1.0
    bpy.context.view_layer.update()
    return scene


def plan(scene):
    return {row.name: row for row in model_choice.light_plan(scene, bpy.context.evaluated_depsgraph_get())}


def test01_sun_is_exported(tmp_path):
    scene = build_scene(tmp_path)
    sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", 'SUN'))
    sun.data.energy = 3.0
    sun.data.color = (1.0, 0.9, 0.8)
    sun.rotation_euler = (math.radians(30.0), 0.0, 0.0)
    scene.collection.objects.link(sun)
    scene.airlight.fog_top = 12.5
    depsgraph = bpy.context.evaluated_depsgraph_get()
    description = scene_export.export_scene(scene, depsgraph)
    expected_dir = -np.array(sun.matrix_world.col[2][:3])
    np.testing.assert_allclose(description["sun_directions"], [expected_dir], atol=1e-6)
    np.testing.assert_allclose(description["sun_irradiances"], [[3.0, 2.7, 2.4]], rtol=1e-6)
    assert description["fog_top"] == pytest.approx(12.5)
    assert description["light_positions"].shape == (1, 3)  # Far is skipped (test02), the sun apart
    scene.airlight.use_fog_top = False
    assert scene_export.export_scene(scene, depsgraph)["fog_top"] == math.inf
    sun.data.airlight.participate = False
    assert "sun_directions" not in scene_export.export_scene(scene, depsgraph)
    assert 'SUN' in names.SUPPORTED_LIGHT_TYPES


def test02_faint_far_light_is_skipped_bright_one_never(tmp_path):
    scene = build_scene(tmp_path)
    rows = plan(scene)
    assert rows["Far"].status == 'skipped' and rows["Near"].status == 'fog'
    assert math.isinf(rows["Near"].share)   # in frame: no finite bound
    scene.airlight.model = 'SUN05'          # explicit models bake every light
    assert plan(scene)["Far"].status == 'fog'
    scene = build_scene(tmp_path, far_energy=1.0e6)
    assert plan(scene)["Far"].status == 'fog'
    scene = build_scene(tmp_path)
    scene.airlight.accuracy = 0.01           # target too tight for the faint light too
    assert plan(scene)["Far"].status == 'fog'


def test02b_no_light_is_skipped_with_a_fog_object(tmp_path):
    """The faint-light bounds are the homogeneous fog's: with a (render-visible) fog object
    in the scene, which a faint light may still light brightly, Automatic skips nothing."""
    from airlight import fog_object
    scene = build_scene(tmp_path)
    assert plan(scene)["Far"].status == 'skipped'
    fog = fog_object.new_fog_object("Fog", scene.collection, np.array([[0.0, -30.0, 3.0]]), 0.5, 0.2)
    assert plan(scene)["Far"].status == 'fog'
    fog.hide_render = True
    assert plan(scene)["Far"].status == 'skipped'


def _bake(scene, model=None):
    if model is not None:
        scene.airlight.model = model
    description, settings = bake.prepare(scene, bpy.context.evaluated_depsgraph_get())
    settings["aa_samples"] = 1
    return native.get().bake(**description, **bake.native_settings(settings)), description


def test03_skipping_changes_the_image_by_less_than_the_target(tmp_path):
    scene = build_scene(tmp_path)
    auto, description = _bake(scene)          # AUTO -> sun05, Far skipped
    assert description["light_positions"].shape == (1, 3)
    full, description = _bake(scene, 'SUN05')
    assert description["light_positions"].shape == (2, 3)
    A_full, A_auto = full["airlight"].astype(float), auto["airlight"].astype(float)
    far = np.isinf(full["depth"]) | (full["depth"] >= 1.0 / SIGMA)
    assert far.sum() > 100
    rel = np.abs(A_auto - A_full) / A_full
    assert rel[far].max() < 0.01
    assert rel.mean() < 0.01
    assert np.abs(A_auto - A_full).max() > 0.0   # the far light did light the fog


def test04_bounds_hold_against_the_bake(tmp_path):
    """Each light's upper bound is above its airlight on every pixel; its lower bound below
    it on every pixel that looks at least one mean free path deep."""
    scene = build_scene(tmp_path, far_energy=500.0)
    scene.airlight.model = 'SUN05'
    depsgraph = bpy.context.evaluated_depsgraph_get()
    frame = scene_description.bounds_frame(scene, depsgraph)
    p_min, p_max = light_bounds.phase_range("isotropic", 0.0)
    for name in ("Near", "Far"):
        for obj in scene.objects:
            if obj.type == 'LIGHT':
                obj.data.airlight.participate = obj.name == name
        result, description = _bake(scene)
        A = result["airlight"].astype(float)
        obj = scene.objects[name]
        upper, lower = light_bounds.point_bounds(
            frame, [tuple(obj.matrix_world.translation)], [np.ones(3) * obj.data.energy / (4 * math.pi)],
            SIGMA, (1.0, 1.0, 1.0), p_min, p_max)
        upper, lower = upper[0], lower[0]
        assert np.all(A <= upper[None, None, :] * (1 + 1e-5))
        deep = np.isinf(result["depth"]) | (result["depth"] >= 1.0 / SIGMA)
        assert np.all(A[deep] >= lower[None, :] * (1 - 1e-5))
        if name == "Far":
            assert A.max() > 0.05 * upper.max()   # not uselessly loose


def test05_panel_lines(tmp_path):
    scene = build_scene(tmp_path)
    sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", 'SUN'))
    scene.collection.objects.link(sun)
    area = bpy.data.objects.new("Panel", bpy.data.lights.new("Panel", 'AREA'))
    scene.collection.objects.link(area)
    narrow = bpy.data.objects.new("Narrow", bpy.data.lights.new("Narrow", 'AREA'))
    narrow.data.spread = math.radians(90.0)
    narrow.data.size = 2.0
    scene.collection.objects.link(narrow)
    bpy.context.view_layer.update()
    lines = dict((text.split(":")[0], text) for text, _ in ui.light_lines(scene))
    assert lines["Far"].startswith("Far: skipped: below ")
    label, error = model_choice.choose(scene.airlight)[1:]
    # (the ground casts volumetric shadows: on by default)
    assert lines["Near"] == f"Near: {label}, error \u2264 {100 * error:.2g} %, shadowed"
    assert lines["Sun"].startswith("Sun: Closed form (sun)")
    assert lines["Panel"].startswith("Panel: area light as 1 spot (")   # 0.25 m: one sample
    # Spread 90 degrees halves the cell (names.area_grid): 2 m / (0.395 m / 2) -> 10 x 10
    assert lines["Narrow"].startswith("Narrow: area light as 100 spots ("), lines["Narrow"]
    assert "sampled for 1 % beyond its image" in lines["Narrow"], lines["Narrow"]
    scene.airlight.accuracy = 0.01            # the list follows the settings: Far back in
    lines = dict((text.split(":")[0], text) for text, _ in ui.light_lines(scene))
    label = model_choice.choose(scene.airlight)[1]  # the cheapest model meeting 0.01 %
    assert lines["Far"].startswith(f"Far: {label}")
    scene.airlight.model = 'BASELINE'
    lines = dict((text.split(":")[0], text) for text, _ in ui.light_lines(scene))
    assert lines["Near"].endswith("error unbounded, shadowed")
    # With a fog object the rows say their error is the uniform fog's (the Gaussians' is on
    # the Fog Objects panel).
    fog_object.new_fog_object("Fog", scene.collection, centres=[(0.0, 0.0, 1.0)])
    lines = dict((text.split(":")[0], text) for text, _ in ui.light_lines(scene))
    assert lines["Near"].endswith("error unbounded in the uniform fog, shadowed")
    assert "in the uniform fog" in lines["Narrow"]   # baked now: its row is the uniform fog's too
