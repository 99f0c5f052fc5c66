"""The Automatic model picks the cheapest model whose measured error meets the target,
and the bake operator runs the model it names."""
import bpy
import numpy as np

from airlight import bake, model_choice, native
from conftest import needs_real_native


def test01_auto_follows_accuracy_target():
    settings = bpy.context.scene.airlight
    settings.model = 'AUTO'
    settings.accuracy = 1.0   # 1 % > the table path's measured worst case (0.19 %)
    assert model_choice.choose(settings)[0] == "sun05"
    settings.accuracy = 0.05  # below it: the cheaper of the exact models
    name, _, error = model_choice.choose(settings)
    assert name == "quadrature" and error <= 0.05 / 100.0


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


@needs_real_native
def test04_bake_settings_carry_the_choice():
    settings = bpy.context.scene.airlight
    settings.model = 'AUTO'
    settings.accuracy = 0.05
    assert bake.bake_settings(bpy.context.scene)["model"] == "quadrature"
    settings.accuracy = 2.0
    assert bake.bake_settings(bpy.context.scene)["model"] == "sun05"
