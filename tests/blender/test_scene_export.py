"""Blender scene -> plain description (scene_description) -> keyword arguments of _native.bake (scene_export)."""
import math

import bpy
import numpy as np
import pytest

from airlight import mesh_read, model_choice, scene_description, scene_export, visibility
from conftest import build_plane_scene


def _cube(name, location, collection):
    mesh = bpy.data.meshes.get("UnitCube")
    if mesh is None:
        mesh = bpy.data.meshes.new("UnitCube")
        v = [(x, y, z) for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]
        f = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
        mesh.from_pydata(v, [], f)
    obj = bpy.data.objects.new(name, mesh)
    obj.location = location
    collection.objects.link(obj)
    return obj


def test01_camera_matches_blender(tmp_path):
    scene = build_plane_scene(tmp_path, size=(80, 40))
    scene.render.resolution_percentage = 50
    scene.render.pixel_aspect_x = 2.0
    cam = scene.camera
    cam.data.shift_x = 0.1
    cam.rotation_euler = (0.3, 0.0, 0.7)
    depsgraph = bpy.context.evaluated_depsgraph_get()
    width, height, cam_to_world, projection = scene_description.export_camera(scene, depsgraph)
    assert (width, height) == (40, 20)
    np.testing.assert_allclose(cam_to_world, np.array(cam.matrix_world), atol=1e-12)
    expected = cam.calc_matrix_camera(depsgraph, x=40, y=20, scale_x=2.0, scale_y=1.0)
    np.testing.assert_allclose(projection, np.array(expected), atol=1e-12)
    assert cam_to_world.dtype == np.float64 and projection.shape == (4, 4)


def test02_geometry_counts_instances_and_skips_hidden(tmp_path):
    scene = build_plane_scene(tmp_path)
    _cube("Visible", (3, -5, 1), scene.collection)
    hidden = _cube("Hidden", (-3, 0, 1), scene.collection)
    hidden.hide_render = True
    # A collection instance: the source collection is excluded from the view layer,
    # its two instances render.
    source = bpy.data.collections.new("Props")
    scene.collection.children.link(source)
    _cube("Prop", (0, 0, 0), source)
    bpy.context.view_layer.layer_collection.children["Props"].exclude = True
    for i, x in enumerate((5.0, 7.0)):
        empty = bpy.data.objects.new(f"Instance{i}", None)
        empty.instance_type = 'COLLECTION'
        empty.instance_collection = source
        empty.location = (x, 1.0, 0.5)
        scene.collection.objects.link(empty)
    depsgraph = bpy.context.evaluated_depsgraph_get()
    _, vertices, triangles, _ = scene_description.export_instances(depsgraph)
    # plane 2 + visible cube 12 + 2 instanced cubes 24 (hidden cube and excluded source: 0)
    assert len(triangles) == 2 + 12 + 24
    assert vertices.dtype == np.float32 and triangles.dtype == np.uint32
    assert triangles.max() < len(vertices)
    # World-space placement of the instances: a cube spans x in [4, 6] and [6, 8].
    assert vertices[:, 0].max() == pytest.approx(50.0)
    tri_centres = vertices[triangles].mean(axis=1)
    inst = tri_centres[(tri_centres[:, 1] > 0.0) & (tri_centres[:, 1] < 2.1) & (tri_centres[:, 2] > 0.0)]
    assert inst[:, 0].min() >= 4.0 - 1e-5 and inst[:, 0].max() <= 8.0 + 1e-5


def test02b_render_visibility_follows_collections(tmp_path):
    """visibility.RenderVisibility (collections' members listed once) against the rule asked
    object by object (users_collection): hide_render, excluded and render-hidden
    collections (nested too), an object in a hidden and a shown collection, one only in the
    scene's master collection, one in a collection of another scene."""
    scene = build_plane_scene(tmp_path)
    view_layer = bpy.context.view_layer
    parent = bpy.data.collections.new("Parent")
    child = bpy.data.collections.new("Child")
    shown = bpy.data.collections.new("Shown")
    excluded = bpy.data.collections.new("Excluded")
    scene.collection.children.link(parent)
    parent.children.link(child)
    scene.collection.children.link(shown)
    scene.collection.children.link(excluded)
    parent.hide_render = True  # and so its child
    view_layer.layer_collection.children["Excluded"].exclude = True
    other = bpy.data.scenes.new("Other")
    elsewhere = bpy.data.collections.new("Elsewhere")
    other.collection.children.link(elsewhere)
    cases = {
        "Master": ([scene.collection], False, True),
        "MasterHidden": ([scene.collection], True, False),
        "InChild": ([child], False, False),
        "InParent": ([parent], False, False),
        "ChildAndShown": ([child, shown], False, True),
        "Excluded": ([excluded], False, False),
        "ExcludedAndMaster": ([excluded, scene.collection], False, True),
        "Elsewhere": ([elsewhere], False, True),  # outside this view layer's tree
    }
    objects = {}
    for name, (collections, hide, _) in cases.items():
        obj = bpy.data.objects.new(name, None)
        obj.hide_render = hide
        for collection in collections:
            collection.objects.link(obj)
        objects[name] = obj
    hidden = {"Parent", "Child", "Excluded"}

    def per_object(obj):
        return not obj.hide_render and (not obj.users_collection
                                        or any(c.name not in hidden for c in obj.users_collection))

    visible = visibility.RenderVisibility(view_layer)
    for name, (_, _, expected) in cases.items():
        assert visible(objects[name]) == expected == per_object(objects[name]), name
    assert visible(scene.objects["Lamp"]) and visible(scene.objects["Ground"])


def test03_light_intensity_is_colour_times_power_over_4pi(tmp_path):
    scene = build_plane_scene(tmp_path)
    off = bpy.data.lights.new("Off", 'POINT')
    off.airlight.participate = False
    obj_off = bpy.data.objects.new("Off", off)
    scene.collection.objects.link(obj_off)
    spot = bpy.data.objects.new("Spot", bpy.data.lights.new("Spot", 'SPOT'))
    scene.collection.objects.link(spot)
    depsgraph = bpy.context.evaluated_depsgraph_get()
    description = scene_description.describe(scene, depsgraph)
    assert {(light.name, light.participates) for light in description.lights} == {
        ("Lamp", True), ("Off", False), ("Spot", True)}
    plan = model_choice.plan(scene.airlight, description.survey)
    positions, intensities = scene_export.point_lights(description.lights, plan)
    assert positions.shape == (1, 3) and intensities.shape == (1, 3)
    np.testing.assert_allclose(positions[0], (0.5, 0.3, 1.0), atol=1e-6)
    np.testing.assert_allclose(intensities[0], np.array([1.0, 0.5, 0.25]) * 300.0 / (4 * math.pi), rtol=1e-6)
    assert len(scene_export.spot_lights(description.lights, plan)["spot_positions"]) == 1  # exported apart
    rows = {name: (supported, participates)
            for name, _, supported, participates in scene_description.fog_lights(scene)}
    assert rows == {"Lamp": (True, True), "Off": (True, False), "Spot": (True, True)}


def test04_description_keys_match_bake_arguments(tmp_path):
    scene = build_plane_scene(tmp_path)
    scene.airlight.color = (0.9, 0.8, 0.7)
    description = scene_export.export_scene(scene, bpy.context.evaluated_depsgraph_get())
    plain = {"width", "height", "cam_to_world", "projection", "clip_start", "clip_end", "vertices", "triangles",
             "light_positions", "light_intensities", "sigma_t", "albedo", "phase", "g"}
    # Volumetric Shadows (on by default): the ground casts them; its flag per point light.
    assert set(description) == plain | {"shadows", "light_shadows"}
    assert description["shadows"] is True and list(description["light_shadows"]) == [1.0]
    scene.airlight.volumetric_shadows = False
    description = scene_export.export_scene(scene, bpy.context.evaluated_depsgraph_get())
    assert set(description) == plain
    cam = scene.camera.data
    assert (description["clip_start"], description["clip_end"]) == pytest.approx((cam.clip_start, cam.clip_end))
    assert description["sigma_t"] == pytest.approx(0.2)
    assert description["albedo"] == pytest.approx((0.9, 0.8, 0.7))
    assert (description["phase"], description["g"]) == ("isotropic", 0.0)
    scene.airlight.anisotropy = 0.6
    description = scene_export.export_scene(scene, bpy.context.evaluated_depsgraph_get())
    assert (description["phase"], description["g"]) == ("hg", pytest.approx(0.6))
    scene.airlight.phase = 'MIE_MURKY'
    description = scene_export.export_scene(scene, bpy.context.evaluated_depsgraph_get())
    assert (description["phase"], description["g"]) == ("mie_murky", 0.0)


def test05_errors_are_clear(tmp_path):
    scene = build_plane_scene(tmp_path, camera=False)
    depsgraph = bpy.context.evaluated_depsgraph_get()
    with pytest.raises(scene_export.ExportError, match="no active camera"):
        scene_export.export_scene(scene, depsgraph)
    scene = build_plane_scene(tmp_path)
    scene.camera.data.type = 'PANO'
    with pytest.raises(scene_export.ExportError, match="panoramic"):
        scene_export.export_scene(scene, bpy.context.evaluated_depsgraph_get())


@pytest.mark.parametrize("label, mutate, message", [
    ("negative power", lambda s: setattr(bpy.data.lights["Lamp"], "energy", -100.0),
     r"Light 'Lamp' has a negative power \(-100\).*Scatter in Fog"),
    ("NaN power", lambda s: setattr(bpy.data.lights["Lamp"], "energy", float("nan")),
     "Light 'Lamp' has a NaN or infinite colour or power"),
    ("NaN lamp location", lambda s: setattr(bpy.data.objects["Lamp"], "location", (float("nan"), 0.0, 1.0)),
     "Light 'Lamp' has a NaN or infinite location"),
    ("zero camera scale", lambda s: setattr(s.camera, "scale", (0.0, 0.0, 0.0)), "Camera 'Cam' has a zero scale"),
    ("NaN camera rotation", lambda s: setattr(s.camera, "rotation_euler", (float("nan"), 0.0, 0.0)),
     "Camera 'Cam' has a NaN or infinite transform"),
    ("NaN vertex", lambda s: setattr(bpy.data.objects["Ground"].data.vertices[0], "co", (float("nan"), 0.0, 0.0)),
     "Object 'Ground' has NaN or infinite vertices"),
    ("clip range", lambda s: (setattr(s.camera.data, "clip_start", 5.0), setattr(s.camera.data, "clip_end", 5.0)),
     r"Camera 'Cam': Clip Start \(5\) must be less than Clip End \(5\)"),
])
def test06_bad_objects_are_named(tmp_path, label, mutate, message):
    """Bad values in the scene (a negative or NaN light, a degenerate camera, NaN geometry
    from a driver) name the object and what to change, before the native bake sees them."""
    scene = build_plane_scene(tmp_path)
    mutate(scene)
    with pytest.raises(scene_export.ExportError, match=message):
        scene_export.export_scene(scene, bpy.context.evaluated_depsgraph_get())
    # The negative light kept out of the fog (Scatter in Fog off) no longer stops the bake.
    if label == "negative power":
        bpy.data.lights["Lamp"].airlight.participate = False
        scene_export.export_scene(scene, bpy.context.evaluated_depsgraph_get())


def test07_meshes_export_their_evaluated_geometry_in_every_mode(tmp_path):
    """A mesh object's triangles come from its evaluated mesh (modifiers applied) read in place,
    and in Edit Mode, where that mesh is the edit mesh's wrapper without vertices, from a copy:
    the edited vertices, never an empty or stale mesh. Checked against the modifier's own
    counts and the edit's displacement."""
    scene = build_plane_scene(tmp_path)
    smooth = _cube("Smooth", (3.0, -5.0, 1.0), scene.collection)
    smooth.modifiers.new("Subdivision", 'SUBSURF').levels = 2  # 6 quads -> 96 quads: 192 triangles
    edited = _cube("Edited", (-3.0, -5.0, 1.0), scene.collection)
    edited.data = edited.data.copy()
    depsgraph = bpy.context.evaluated_depsgraph_get()
    arrays = mesh_read.mesh_arrays(smooth.evaluated_get(depsgraph))
    assert arrays is not None and arrays[1].shape == (192, 3) and len(arrays[0]) == 98
    bpy.context.view_layer.objects.active = edited
    edited.select_set(True)
    bpy.ops.object.mode_set(mode='EDIT')
    try:
        bpy.ops.mesh.select_all(action='SELECT')
        bpy.ops.transform.translate(value=(0.0, 0.0, 2.0))
        depsgraph = bpy.context.evaluated_depsgraph_get()
        evaluated = edited.evaluated_get(depsgraph)
        assert evaluated.mode == 'EDIT'
        vertices, triangles = mesh_read.mesh_arrays(evaluated)
        assert triangles.shape == (12, 3)
        np.testing.assert_allclose(np.sort(np.unique(vertices[:, 2])), [1.0, 3.0])  # local z moved by 2
        _, world, _, _ = scene_description.export_instances(depsgraph)
        assert world[:, 2].max() == pytest.approx(4.0)  # the edited cube's top, in the world
    finally:
        bpy.ops.object.mode_set(mode='OBJECT')
