"""The airlight.bake operator: EXR contents and errors."""
import math
import os

import bpy
import numpy as np
import pytest

from airlight import bake, native, scene_export
from conftest import build_plane_scene, exr_pass, read_exr


def _bake(filepath, **kwargs):
    result = bpy.ops.airlight.bake(filepath=str(filepath), **kwargs)
    assert result == {'FINISHED'}
    return str(filepath)


def test01_exr_passes_equal_native_bake_of_exported_scene(tmp_path):
    scene = build_plane_scene(tmp_path)
    path = _bake(tmp_path / "fog.exr")
    _, names = read_exr(path)
    # (Light Passes, on by default: the one lamp's pass is the total.)
    assert sorted(names) == sorted(f"Fog.{p}.{c}" for p in ("Airlight", "Airlight_Lamp", "Transmittance")
                                   for c in "RGB")
    description = scene_export.export_scene(scene, bpy.context.evaluated_depsgraph_get())
    reference = native.get().bake(**description, **bake.bake_settings(scene))
    np.testing.assert_array_equal(exr_pass(path, "Airlight"), reference["airlight"])
    np.testing.assert_array_equal(exr_pass(path, "Airlight_Lamp"), reference["airlight"])
    np.testing.assert_array_equal(exr_pass(path, "Transmittance"), reference["transmittance"])
    assert reference["airlight"].max() > 0.0


def test02_transmittance_of_plane_is_exp_minus_sigma_distance(tmp_path):
    """Camera 2 m above the plane z=0 looking straight down: d = 2 sqrt(1 + x^2 + y^2),
    of which the first clip_start sqrt(1 + x^2 + y^2) lie before the near plane."""
    width, height = 64, 48
    scene = build_plane_scene(tmp_path, size=(width, height))
    path = _bake(tmp_path / "fog.exr")
    T = exr_pass(path, "Transmittance")
    cam = scene.camera.data
    scale = cam.sensor_width / cam.lens / width  # sensor fit AUTO, landscape: width fits
    i = np.arange(width) + 0.5 - width / 2
    j = height / 2 - (np.arange(height) + 0.5)
    x, y = np.meshgrid(i * scale, j * scale)
    # As in Cycles the fog begins on the near plane (view depth clip_start, 0.1 m here).
    expected = np.exp(-0.2 * (2.0 - cam.clip_start) * np.sqrt(1.0 + x * x + y * y))
    for c in range(3):
        np.testing.assert_allclose(T[..., c], expected, rtol=2e-5)


def test03_default_path_is_cache_dir_frame(tmp_path):
    scene = build_plane_scene(tmp_path)
    scene.frame_set(3)
    assert bpy.ops.airlight.bake() == {'FINISHED'}
    assert os.path.exists(tmp_path / "cache" / "fog_0003.exr")
    assert bpy.ops.airlight.bake(frame=5) == {'FINISHED'}
    assert os.path.exists(tmp_path / "cache" / "fog_0005.exr")
    assert scene.frame_current == 3


def test04_no_camera_is_a_clear_error(tmp_path):
    build_plane_scene(tmp_path, camera=False)
    with pytest.raises(RuntimeError, match="no active camera"):
        bpy.ops.airlight.bake(filepath=str(tmp_path / "x.exr"))
    assert not os.path.exists(tmp_path / "x.exr")


def test05_nan_density_is_a_clear_error(tmp_path):
    scene = build_plane_scene(tmp_path)
    scene.airlight.density = float("nan")
    if not math.isnan(scene.airlight.density):
        pytest.skip("RNA rejected NaN itself")
    with pytest.raises(RuntimeError, match="density must be a finite number"):
        bpy.ops.airlight.bake(filepath=str(tmp_path / "x.exr"))


def test06_broken_cache_dir_is_a_clear_error(tmp_path):
    scene = build_plane_scene(tmp_path)
    blocker = tmp_path / "not_a_folder"
    blocker.write_text("a file where the cache folder should be")
    scene.airlight.cache_dir = str(blocker / "cache") + os.sep
    with pytest.raises(RuntimeError, match="Cannot create the fog cache folder"):
        bpy.ops.airlight.bake()


def test07_poll_explains_missing_native(monkeypatch):
    monkeypatch.setattr(native, "_module", None)
    monkeypatch.setattr(native, "_error", "The Airlight native module could not be loaded (test).")
    monkeypatch.setattr(native, "_tried", True)
    assert not bpy.ops.airlight.bake.poll()
    with pytest.raises(RuntimeError, match="native module could not be loaded"):
        bpy.ops.airlight.bake()


def test08_progress_returning_false_cancels_without_writing(tmp_path):
    scene = build_plane_scene(tmp_path)
    description, settings = bake.prepare(scene, bpy.context.evaluated_depsgraph_get())
    calls = []

    def progress(fraction):
        calls.append(fraction)
        return False

    path = tmp_path / "cancelled.exr"
    with pytest.raises(native.get().BakeCancelled):
        bake.run(description, settings, str(path), progress)
    assert calls and not path.exists()


def test09_edge_samples_follow_the_render_pixel_filter(tmp_path):
    """The bake's edge sub-samples use the render's pixel filter width (Cycles' Film >
    Pixel Filter; EEVEE's Filter Size), so that its silhouette pixels average the fog as
    the render averages the surfaces behind it: the operator's passes equal the native bake
    at that width, and differ from the default 1.5 px on edge pixels only."""
    scene = build_plane_scene(tmp_path, size=(64, 48))
    scene.camera.location = (0.0, -6.0, 1.5)
    scene.camera.rotation_euler = (1.35, 0.0, 0.0)  # the horizon: edge pixels
    scene.render.engine = 'CYCLES'
    scene.cycles.filter_width = 3.0
    assert bake.bake_settings(scene)["filter_width"] == 3.0
    scene.render.engine = 'BLENDER_EEVEE'
    scene.render.filter_size = 2.25
    assert bake.bake_settings(scene)["filter_width"] == 2.25
    scene.render.engine = 'CYCLES'
    path = _bake(tmp_path / "fog.exr")
    description = scene_export.export_scene(scene, bpy.context.evaluated_depsgraph_get())
    settings = bake.bake_settings(scene)
    wide = native.get().bake(**description, **settings)
    default = native.get().bake(**description, **dict(settings, filter_width=1.5))
    np.testing.assert_array_equal(exr_pass(path, "Transmittance"), wide["transmittance"])
    differs = np.any(wide["transmittance"] != default["transmittance"], axis=2)
    assert 0 < differs.sum() <= wide["stats"]["supersampled_pixels"]


def test10_half_precision_passes(tmp_path):
    """Pass Precision Half: the cache file holds the bake's passes rounded to 16-bit floats
    (numpy's float16 rounding of the native bake), in a much smaller file."""
    scene = build_plane_scene(tmp_path, size=(64, 48))
    scene.airlight.pass_precision = 'FULL'
    full = _bake(tmp_path / "full.exr")
    scene.airlight.pass_precision = 'HALF'
    half = _bake(tmp_path / "half.exr")
    description = scene_export.export_scene(scene, bpy.context.evaluated_depsgraph_get())
    reference = native.get().bake(**description, **bake.bake_settings(scene))
    for name, key in (("Airlight", "airlight"), ("Transmittance", "transmittance")):
        np.testing.assert_array_equal(exr_pass(half, name), reference[key].astype(np.float16).astype(np.float32))
        np.testing.assert_array_equal(exr_pass(full, name), reference[key])
    assert os.path.getsize(half) < 0.5 * os.path.getsize(full)


def test10b_automatic_precision_follows_the_output(tmp_path):
    """Pass Precision Automatic (the default): half floats for an 8-bit output, whose step
    (1/255) the rounding (<= 4.9e-4) stays below; full floats for float and 16-bit outputs."""
    scene = build_plane_scene(tmp_path, size=(16, 12))
    settings, image = scene.airlight, scene.render.image_settings
    assert settings.bl_rna.properties["pass_precision"].default == 'AUTO'
    settings.pass_precision = 'AUTO'
    for file_format, depth, half in (('PNG', '8', True), ('JPEG', '8', True), ('PNG', '16', False),
                                     ('OPEN_EXR', '32', False), ('OPEN_EXR_MULTILAYER', '16', False),
                                     ('TIFF', '16', False), ('FFMPEG', '8', True)):
        image.file_format = file_format
        image.color_depth = depth
        assert bake.half_passes(scene) is half, (file_format, depth)
        description, prepared = bake.prepare(scene, bpy.context.evaluated_depsgraph_get())
        assert bool(prepared.get(bake.HALF_PASSES)) is half, (file_format, depth)
    settings.pass_precision = 'FULL'
    image.file_format, image.color_depth = 'PNG', '8'
    assert not bake.half_passes(scene)
    settings.pass_precision = 'HALF'
    image.file_format, image.color_depth = 'OPEN_EXR', '32'
    assert bake.half_passes(scene)
    settings.pass_precision = 'AUTO'
    image.file_format, image.color_depth = 'PNG', '8'


def test11_bake_larger_than_memory_is_refused_before_allocating(tmp_path):
    """A bake whose images would not fit in the memory available (here 32768 x 32768 pixels
    with surface shading for 40 lights, ~590 GB) is refused with the estimate and the memory
    available, before it allocates anything; no file is written."""
    scene = build_plane_scene(tmp_path)
    scene.render.engine = 'CYCLES'
    scene.airlight.surface_shading = True
    for k in range(39):
        lamp = bpy.data.objects.new(f"Lamp{k}", bpy.data.lights.new(f"Lamp{k}", 'POINT'))
        lamp.location = (0.1 * k, 0.0, 1.0)
        scene.collection.objects.link(lamp)
    scene.render.resolution_x = scene.render.resolution_y = 32768
    path = tmp_path / "huge.exr"
    with pytest.raises(RuntimeError, match=r"32768 x 32768 pixels needs about \d+\.\d GB but only .* of memory "
                                           r"is available; lower the resolution"):
        bpy.ops.airlight.bake(filepath=str(path))
    assert not os.path.exists(path)


def test12_anisotropy_past_its_range_through_the_raw_property_is_refused(tmp_path):
    """scene.airlight["anisotropy"] (the raw ID property) skips the property's [-0.99, 0.99]:
    the bake refuses such a g with the range (it went on to the models: the Biri 2006 table
    build for |g| >= 0.998 never finished), and the range's ends still bake."""
    scene = build_plane_scene(tmp_path, size=(32, 24))
    scene.airlight.phase = 'HENYEY_GREENSTEIN'
    scene.airlight["anisotropy"] = 0.999
    assert scene.airlight.anisotropy == pytest.approx(0.999)
    with pytest.raises(RuntimeError, match=r"anisotropy must be a finite number in \[-0\.99, 0\.99\] \(got 0\.999\)"):
        bpy.ops.airlight.bake(filepath=str(tmp_path / "x.exr"))
    assert not os.path.exists(tmp_path / "x.exr")
    for g in (-0.99, 0.99):
        scene.airlight.anisotropy = g
        assert exr_pass(_bake(tmp_path / f"g{g}.exr"), "Airlight").max() > 0.0
