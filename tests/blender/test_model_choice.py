"""The Automatic model picks the cheapest model whose measured error meets the target,
and the bake operator runs the model it names."""
import bpy
import numpy as np
import pytest

from airlight import bake, model_choice, native
from conftest import build_plane_scene


def test01_auto_follows_accuracy_target():
    settings = bpy.context.scene.airlight
    settings.model = 'AUTO'
    settings.accuracy = 1.0   # 1 % > the table path's measured worst case (0.19 %)
    assert model_choice.choose(settings)[0] == "sun05"
    settings.accuracy = 0.05  # below it: the cheapest of the exact models (the closed form)
    name, _, error = model_choice.choose(settings)
    assert name == "pegoraro10" and error <= 0.05 / 100.0


@pytest.fixture(autouse=True)
def isotropic_default():
    """Each test starts from the isotropic phase and leaves it so."""
    settings = bpy.context.scene.airlight
    settings.phase, settings.anisotropy = 'HENYEY_GREENSTEIN', 0.0
    yield
    settings.phase, settings.anisotropy = 'HENYEY_GREENSTEIN', 0.0


def test02_explicit_model_is_kept():
    settings = bpy.context.scene.airlight
    settings.accuracy = 0.01
    settings.model = 'SUN05'
    assert model_choice.choose(settings)[0] == "sun05"
    settings.model = 'SUN05_EXACT'
    assert model_choice.choose(settings)[0] == "sun05_exact"


def test03_every_choice_is_a_native_model():
    names = {name for name, _ in native.get().models()} if native.available() else set(model_choice.MEASURED)
    assert set(model_choice.MEASURED) <= names


def test04_bake_settings_carry_the_choice():
    settings = bpy.context.scene.airlight
    settings.model = 'AUTO'
    settings.accuracy = 0.05
    assert bake.bake_settings(bpy.context.scene)["model"] == "pegoraro10"
    settings.accuracy = 2.0
    assert bake.bake_settings(bpy.context.scene)["model"] == "sun05"


def test05_isotropic_auto_is_unchanged_by_biri06():
    """HG with g = 0 is the isotropic phase: AUTO picks as before (biri06 is no candidate)."""
    settings = bpy.context.scene.airlight
    settings.model = 'AUTO'
    for accuracy, expected in ((1.0, "sun05"), (0.1, "pegoraro10"), (0.05, "pegoraro10")):
        settings.accuracy = accuracy
        assert model_choice.choose(settings)[0] == expected
    assert model_choice.native_phase(settings) == ("isotropic", 0.0)


def test06_anisotropic_auto_needs_a_phase_model():
    """biri06 where its measured error meets the target, else the phase-aware quadrature."""
    settings = bpy.context.scene.airlight
    settings.model = 'AUTO'
    settings.anisotropy = 0.6
    settings.accuracy = 1.0
    name, _, error = model_choice.choose(settings)
    assert name == "biri06" and error == pytest.approx(8.9e-4)
    settings.accuracy = 0.05   # below biri06's 8.9e-4: the closed form (HG g = 0.6 truncated at its order)
    assert model_choice.choose(settings)[:3:2] == ("pegoraro10", pytest.approx(2.6e-7))
    settings.accuracy = 0.5    # meets 8.9e-4, but not the narrow-lobe 6e-3; pegoraro10 can't reach |g| = 0.97
    settings.anisotropy = -0.97
    name, _, error = model_choice.choose(settings)
    assert name == "quadrature" and error <= 0.005
    settings.accuracy = 1.0
    assert model_choice.choose(settings)[:3:2] == ("biri06", pytest.approx(6e-3))
    for phase, native_name in (('RAYLEIGH', "rayleigh"), ('MIE_HAZY', "mie_hazy"), ('MIE_MURKY', "mie_murky")):
        settings.phase = phase
        assert model_choice.choose(settings)[0] == "biri06"
        assert model_choice.native_phase(settings) == (native_name, 0.0)   # g is HG's only
    assert model_choice.phase_problem(settings) is None


def test07_explicit_sun05_with_anisotropic_phase_is_flagged():
    settings = bpy.context.scene.airlight
    settings.anisotropy = 0.6
    for model in ('SUN05', 'SUN05_EXACT'):
        settings.model = model
        assert "isotropic" in model_choice.phase_problem(settings)
        assert model_choice.choose(settings)[2] == float("inf")   # no error figure for the wrong phase
    for model in ('BIRI06', 'QUADRATURE', 'AUTO'):
        settings.model = model
        assert model_choice.phase_problem(settings) is None
    settings.model = 'PEGORARO10'
    assert model_choice.phase_problem(settings) is None   # g = 0.6: within order 96
    settings.anisotropy = 0.9
    assert "Pegoraro" in model_choice.phase_problem(settings)
    assert model_choice.choose(settings)[2] == float("inf")


def test08_bake_refuses_sun05_with_anisotropic_phase(tmp_path):
    """The bake path reports a clear error rather than baking isotropic fog."""
    scene = build_plane_scene(tmp_path)
    scene.airlight.model = 'SUN05'
    scene.airlight.anisotropy = 0.6
    description, settings = bake.prepare(scene, bpy.context.evaluated_depsgraph_get())
    assert description["phase"] == "hg" and settings["model"] == "sun05"
    with pytest.raises(bake.BakeError, match="isotropic"):
        bake.run(description, settings, str(tmp_path / "fog.exr"))
    scene.airlight.model = 'BIRI06'
    description, settings = bake.prepare(scene, bpy.context.evaluated_depsgraph_get())
    stats, _ = bake.run(description, settings, str(tmp_path / "fog.exr"))


def test20_gaussian_resolution_default_meets_default_accuracy():
    """Fog objects: Quarter by default, and its measured error meets the default 1 % target,
    so Automatic keeps it; stricter targets step to Half, then Full; never coarser than the
    user's choice; explicit models keep the choice."""
    settings = bpy.context.scene.airlight
    prop = settings.bl_rna.properties["gaussian_resolution"]
    assert prop.default == 'QUARTER'
    assert model_choice.GAUSSIAN_RESOLUTION_ERROR['QUARTER'] * 100.0 <= prop_default(settings, "accuracy")
    old = settings.model, settings.accuracy, settings.gaussian_resolution
    try:
        settings.model = 'AUTO'
        settings.gaussian_resolution = 'QUARTER'
        cases = ((1.0, "quarter"), (0.3, "half"), (0.1, "half"), (0.05, "full"), (0.01, "full"))
        for accuracy, expected in cases:
            settings.accuracy = accuracy
            assert model_choice.gaussian_resolution(settings) == expected, accuracy
            assert bake.bake_settings(bpy.context.scene)["gaussian_resolution"] == expected
        settings.accuracy = 1.0
        settings.gaussian_resolution = 'HALF'
        assert model_choice.gaussian_resolution(settings) == "half"
        settings.gaussian_resolution = 'FULL'
        assert model_choice.gaussian_resolution(settings) == "full"
        settings.model = 'SUN05'
        settings.accuracy = 0.01
        settings.gaussian_resolution = 'QUARTER'
        assert model_choice.gaussian_resolution(settings) == "quarter"
        # Fog noise is interpolated too, with its own (larger) measured error.
        settings.model = 'AUTO'
        settings.noise_amplitude = 0.4
        for accuracy, expected in ((1.0, "full"), (2.0, "half"), (6.0, "quarter")):
            settings.accuracy = accuracy
            assert model_choice.gaussian_resolution(settings) == expected, accuracy
    finally:
        settings.model, settings.accuracy, settings.gaussian_resolution = old
        settings.noise_amplitude = 0.0


def test21_gaussian_resolution_follows_the_render_pixel_size(tmp_path):
    """The reduced resolutions' error grows as the square of a pixel's angle (measured at
    1080p with a 60-degree lens, model_choice): at 1 %, Automatic bakes a 60-degree view
    at Quarter at 1920x1080, Half at 960x540 (error x4) and Full at 480x270 (x16); a render
    region does not change a pixel's size."""
    import math
    from conftest import build_plane_scene
    scene = build_plane_scene(tmp_path, size=(1920, 1080))
    scene.camera.data.sensor_fit = 'HORIZONTAL'
    scene.camera.data.angle = math.radians(60.0)
    settings = scene.airlight
    settings.model, settings.accuracy, settings.gaussian_resolution = 'AUTO', 1.0, 'QUARTER'
    from airlight import fog_object
    fog_object.new_fog_object("Fog", scene.collection, np.zeros((1, 3)), 1.0, 0.1)
    chosen = {}
    for width, height in ((1920, 1080), (960, 540), (480, 270)):
        scene.render.resolution_x, scene.render.resolution_y = width, height
        description, baked = bake.prepare(scene, bpy.context.evaluated_depsgraph_get())
        angle = model_choice.pixel_angle(description["projection"], description["width"])
        assert angle == pytest.approx(model_choice.REFERENCE_PIXEL_ANGLE * 1920 / width, rel=1e-6)
        chosen[width] = baked["gaussian_resolution"]
    assert chosen == {1920: "quarter", 960: "half", 480: "full"}
    scene.render.resolution_x, scene.render.resolution_y = 960, 540
    scene.render.use_border = True
    scene.render.border_min_x, scene.render.border_max_x = 0.1, 0.3
    description, baked = bake.prepare(scene, bpy.context.evaluated_depsgraph_get())
    assert description["width"] < 300 and baked["gaussian_resolution"] == "half"
    # Orthographic cameras bake fog objects at full resolution anyway: no pixel angle.
    scene.camera.data.type = 'ORTHO'
    description, _ = bake.prepare(scene, bpy.context.evaluated_depsgraph_get())
    assert model_choice.pixel_angle(description["projection"], description["width"]) is None


def prop_default(settings, name):
    return settings.bl_rna.properties[name].default


def test22_fog_objects_panel_says_when_automatic_goes_finer(tmp_path):
    """The Fog Objects panel says which resolution Automatic bakes when the render's pixels
    make it finer than the setting, and nothing when the setting stands."""
    import math
    from airlight import fog_object, ui
    from conftest import build_plane_scene, draw_panel
    scene = build_plane_scene(tmp_path, size=(1920, 1080))
    scene.camera.data.sensor_fit = 'HORIZONTAL'
    scene.camera.data.angle = math.radians(60.0)
    fog_object.new_fog_object("Fog", scene.collection, np.zeros((1, 3)), 1.0, 0.1)
    settings = scene.airlight
    settings.model, settings.accuracy, settings.gaussian_resolution = 'AUTO', 1.0, 'QUARTER'
    assert ui.resolution_note(bpy.context) is None
    scene.render.resolution_x, scene.render.resolution_y = 960, 540
    note = ui.resolution_note(bpy.context)
    assert note.startswith("Automatic bakes Half here") and "4.0x" in note
    assert note in draw_panel("AIRLIGHT_PT_fog_objects")
    settings.model = 'SUN05'  # an explicit model keeps the setting
    assert ui.resolution_note(bpy.context) is None


def test_light_size_tolerance_follows_the_accuracy():
    """A light's Radius is skipped where it changes that light's airlight by less than a
    quarter of Automatic's target (at most 5e-3, where the skip's bound holds); explicit
    models keep the bake's default 1e-3. The bake gets it (bake_settings)."""
    settings = bpy.context.scene.airlight
    settings.model = 'AUTO'
    for accuracy, tol in ((1.0, 0.0025), (0.1, 0.00025), (5.0, 0.005), (20.0, 0.005)):
        settings.accuracy = accuracy
        assert model_choice.light_size_tolerance(settings) == pytest.approx(tol)
        assert bake.bake_settings(bpy.context.scene)["light_size_tolerance"] == pytest.approx(tol)
    settings.model = 'SUN05'
    assert model_choice.light_size_tolerance(settings) == 1e-3
    settings.model, settings.accuracy = 'AUTO', 1.0
