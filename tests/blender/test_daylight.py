"""Model HOFFMAN02 from the add-on: sun lamps in Rayleigh + Mie daylight haze (native
hoffman02_model.cpp; its physics is held to scipy in tests/native/test_bake_hoffman02.py).
Here: the operator bakes it with the scene's Rayleigh Density, point lights are left out
(and the panel says so), the blue channel is extinguished most, and a non-HG phase gets a
clear message."""
import math

import bpy
import numpy as np
import pytest

from airlight import model_choice, ui
from conftest import build_plane_scene, exr_pass


def _daylight_scene(tmp_path):
    scene = build_plane_scene(tmp_path, size=(32, 24))   # has a point light "Lamp"
    scene.camera.rotation_euler = (math.radians(70.0), 0.0, 0.0)
    sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", 'SUN'))
    sun.data.energy = 3.0
    sun.rotation_euler = (math.radians(40.0), 0.0, math.radians(30.0))
    scene.collection.objects.link(sun)
    s = scene.airlight
    s.model = 'HOFFMAN02'
    s.density = 0.002
    s.rayleigh_density = 0.01
    s.use_fog_top = True
    s.fog_top = 20.0
    bpy.context.view_layer.update()
    return scene


def test01_bake_daylight(tmp_path):
    scene = _daylight_scene(tmp_path)
    path = str(tmp_path / "fog.exr")
    assert bpy.ops.airlight.bake('EXEC_DEFAULT', filepath=path) == {'FINISHED'}
    A = exr_pass(path, "Airlight")
    T = exr_pass(path, "Transmittance")
    assert np.all(np.isfinite(A)) and A.max() > 0.0
    floor = T[..., 0] > 0.0
    assert floor.sum() > 50
    # Rayleigh ~ 1/lambda^4: blue is extinguished more than red on every surface pixel.
    assert np.all(T[floor][:, 2] < T[floor][:, 0])
    # The point light is not in this fog; without Rayleigh the sky would be far less blue.
    lines = dict((text.split(":")[0], text) for text, _ in ui.light_lines(scene))
    assert "sun lamps only" in lines["Lamp"]
    assert lines["Sun"].startswith("Sun: Hoffman-Preetham 2002") or "Closed form" in lines["Sun"]
    assert model_choice.choose(scene.airlight)[0] == "hoffman02"


def test02_phase_problem(tmp_path):
    scene = _daylight_scene(tmp_path)
    scene.airlight.phase = 'RAYLEIGH'
    assert "Henyey-Greenstein" in model_choice.phase_problem(scene.airlight)
    scene.airlight.phase = 'HENYEY_GREENSTEIN'
    assert model_choice.phase_problem(scene.airlight) is None
