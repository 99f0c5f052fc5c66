"""The Scene > Airlight Fog panels draw without errors, show only properties that exist
and have tooltips, and say what the model does with fog objects."""
import bpy
import numpy as np
import pytest

from airlight import fog_object, model_choice, ui
from conftest import build_plane_scene, draw_panel as _draw


@pytest.mark.parametrize("model", ['AUTO', 'QUADRATURE', 'BIRI06'])
def test01_scene_panels_draw(tmp_path, model):
    scene = build_plane_scene(tmp_path)
    scene.airlight.model = model
    seen = _draw("AIRLIGHT_PT_scene")
    assert {"density", "color", "model", "accuracy", "surface_shading", "airlight.bake"} <= set(seen)
    # The Surface Shading line names the glow model: Sun's G0 for the isotropic phase, the
    # phase-aware G for an anisotropic one, or Biri's eq. 10 when the Glow Model asks for it.
    assert any(text.startswith("Glow: Sun 2005 G0") for text in seen), seen
    scene.airlight.anisotropy = 0.5
    seen = _draw("AIRLIGHT_PT_scene")
    assert "surface_glow_model" in seen
    assert any(text.startswith("Glow:") and "phase-aware" in text for text in seen), seen
    scene.airlight.surface_glow_model = 'BIRI06_EQ10'
    seen = _draw("AIRLIGHT_PT_scene")
    assert any(text.startswith("Glow:") and "eq. 10" in text for text in seen), seen
    scene.airlight.surface_glow_model = 'EXACT'
    scene.airlight.anisotropy = 0.0
    seen = _draw("AIRLIGHT_PT_fog_objects")
    assert {"noise_amplitude", "noise_scale", "noise_offset"} <= set(seen)
    assert any(text.startswith("No fog objects") for text in seen)
    fog_object.new_fog_object("Fog", scene.collection, np.zeros((3, 3)), 1.0, 0.1)
    seen = _draw("AIRLIGHT_PT_fog_objects")
    assert "1 fog object" in seen
    note = {'AUTO': "Fogshop 2007", 'QUADRATURE': "Exact", 'BIRI06': "Fogshop 2007"}[model]
    assert any(note in text for text in seen), seen
    scene.airlight.environment_glow = True
    seen = _draw("AIRLIGHT_PT_environment")
    assert {"environment_distance", "environment_sh_order"} <= set(seen)


def test02_fog_object_note_matches_what_the_bake_does():
    assert "Fogshop" in ui.fog_object_note("sun05") and "Fogshop" in ui.fog_object_note("sun05_exact")
    assert "Exact" in ui.fog_object_note("quadrature")
    for name in ("biri06", "pegoraro10"):  # any phase, spots and suns too
        assert "sun lamps, any phase" in ui.fog_object_note(name)
    assert "does not take fog objects" in ui.fog_object_note("hoffman02")


def test02b_automatic_fog_object_note_shows_the_target_and_the_last_bakes_bound():
    scene = bpy.context.scene
    scene.airlight.model = 'AUTO'
    scene.airlight.accuracy = 1.0
    assert model_choice.gaussian_accuracy(scene.airlight) == 0.01
    assert "refined to the 1 % target" in ui.fog_object_note("sun05", scene.airlight)
    last = dict(accuracy=0.01, error_bound=0.0073, pairs=40, background_rays=10)
    note = ui.fog_object_note("sun05", scene.airlight, last)
    assert "0.73 %" in note and "marched" not in note, note
    assert "2 lights marched" in ui.fog_object_note("sun05", scene.airlight, dict(last, marched=2))
    assert "over its budget" in ui.fog_object_note("sun05", scene.airlight, dict(last, abandoned=True))
    scene.airlight.accuracy = 5.0  # the last bake was for another target: not shown as this one's
    assert "refined to the 5 % target" in ui.fog_object_note("sun05", scene.airlight, last)
    scene.airlight.model = 'BIRI06'  # explicit models keep Fogshop alone
    assert model_choice.gaussian_accuracy(scene.airlight) == 0.0
    assert "12-29 %" in ui.fog_object_note("biri06", scene.airlight, last)


def test03_what_the_fog_composite_cannot_do_is_said_in_the_panel_and_the_console(tmp_path, capsys):
    """With Output > Post Processing > Compositing off a render skips the compositor, so the
    fog never reaches the image; depth of field and motion blur leave the fog passes sharp: the panel and each render's
    console line say so."""
    from airlight import render
    scene = build_plane_scene(tmp_path, size=(16, 12))
    assert render.COMPOSITING_OFF not in _draw("AIRLIGHT_PT_scene")
    render.on_render_pre(scene)
    assert "Compositing is off" not in capsys.readouterr().out
    scene.render.use_compositing = False
    assert render.COMPOSITING_OFF in _draw("AIRLIGHT_PT_scene")
    render.on_render_pre(scene)
    out = capsys.readouterr().out
    assert "baked" in out and f"frame {scene.frame_current}: {render.COMPOSITING_OFF}" in out
    scene.render.use_compositing = True
    # Stereoscopy: every view is baked from its own camera (test_stereo.py), nothing to say.
    scene.render.use_multiview = True
    assert not any("Stereoscopy" in line for line in _draw("AIRLIGHT_PT_scene"))
    render.on_render_pre(scene)
    assert "Stereoscopy" not in capsys.readouterr().out
    scene.render.use_multiview = False
    # Depth of field and motion blur: the passes stay sharp.
    scene.camera.data.dof.use_dof = True
    assert render.DEPTH_OF_FIELD not in _draw("AIRLIGHT_PT_scene")  # sampled over the lens
    scene.airlight.lens_samples = 1
    scene.render.use_motion_blur = True
    seen = _draw("AIRLIGHT_PT_scene")
    assert render.DEPTH_OF_FIELD in seen and render.MOTION_BLUR_INTERACTIVE in seen
    scene.airlight.motion_samples = 1
    seen = _draw("AIRLIGHT_PT_scene")
    assert render.DEPTH_OF_FIELD in seen and render.MOTION_BLUR in seen
    render.on_render_pre(scene)
    out = capsys.readouterr().out
    assert render.DEPTH_OF_FIELD in out and render.MOTION_BLUR in out
    scene.airlight.enabled = False
    seen = _draw("AIRLIGHT_PT_scene")
    assert not {render.COMPOSITING_OFF, render.DEPTH_OF_FIELD, render.MOTION_BLUR,
                render.MOTION_BLUR_INTERACTIVE} & set(seen)
