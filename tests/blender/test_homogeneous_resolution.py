"""scene.airlight.homogeneous_resolution: stored (default Full), passed to `_native.bake`, and
the operator's bake at Quarter equals the native bake at Quarter and stays within the lattice's
measured error of Full (tests/native/test_bake_homogeneous_lattice.py tests the lattice itself)."""
import bpy
import numpy as np

from airlight import bake, native, scene_export
from conftest import build_plane_scene, exr_pass


def test01_default_full_and_choices_reach_the_bake_settings():
    settings = bpy.context.scene.airlight
    assert settings.bl_rna.properties["homogeneous_resolution"].default == 'FULL'
    old = settings.homogeneous_resolution
    try:
        for name in ('FULL', 'HALF', 'QUARTER'):
            settings.homogeneous_resolution = name
            assert bake.bake_settings(bpy.context.scene)["homogeneous_resolution"] == name.lower()
    finally:
        settings.homogeneous_resolution = old


def test02_bake_operator_at_quarter(tmp_path):
    scene = build_plane_scene(tmp_path, size=(320, 240))
    settings = scene.airlight
    settings.model = 'SUN05'
    settings.homogeneous_resolution = 'QUARTER'
    path = str(tmp_path / "fog.exr")
    assert bpy.ops.airlight.bake(filepath=path) == {'FINISHED'}
    description = scene_export.export_scene(scene, bpy.context.evaluated_depsgraph_get())
    quarter = native.get().bake(**description, **bake.bake_settings(scene))
    np.testing.assert_array_equal(exr_pass(path, "Airlight"), quarter["airlight"])
    full = native.get().bake(**description, **dict(bake.bake_settings(scene), homogeneous_resolution="full"))
    ref = full["airlight"]
    mask = ref > 1e-6 * ref.max()
    rel = np.abs(quarter["airlight"][mask] / ref[mask] - 1.0)
    assert rel.max() < 3e-3
