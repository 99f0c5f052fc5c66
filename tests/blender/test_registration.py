"""Registering and unregistering the add-on, and the fog property definitions."""
import math

import addon_utils
import bpy
import pytest

def _our_handlers():
    found = []
    for name in dir(bpy.app.handlers):
        handlers = getattr(bpy.app.handlers, name)
        if isinstance(handlers, list):
            found += [f"{name}:{h.__name__}" for h in handlers
                      if getattr(h, "__module__", "").startswith("airlight")]
    return found


def test01_unregister_leaves_no_handlers_or_types():
    installed = _our_handlers()
    assert "render_pre:on_render_pre" in installed and "load_post:on_load_post" in installed
    assert len(set(installed)) == len(installed)
    addon_utils.disable("airlight", default_set=True)
    try:
        assert _our_handlers() == []
        assert not hasattr(bpy.types.Scene, "airlight")
        assert not hasattr(bpy.types.Light, "airlight")
        for name in ("AIRLIGHT_OT_bake", "AIRLIGHT_OT_setup_compositor", "AIRLIGHT_PT_scene",
                     "AIRLIGHT_PT_light"):
            assert not hasattr(bpy.types, name), name
    finally:
        addon_utils.enable("airlight", default_set=True)
    assert hasattr(bpy.types.Scene, "airlight")
    assert sorted(_our_handlers()) == sorted(installed)  # back, not duplicated


def test02_register_twice_does_not_duplicate_handlers():
    before = _our_handlers()
    addon_utils.disable("airlight", default_set=True)
    addon_utils.enable("airlight", default_set=True)
    addon_utils.disable("airlight", default_set=True)
    addon_utils.enable("airlight", default_set=True)
    assert sorted(_our_handlers()) == sorted(before)


def test03_scene_property_defaults():
    bpy.ops.wm.read_homefile(use_empty=True)
    s = bpy.context.scene.airlight
    assert s.enabled is False
    assert s.density == pytest.approx(0.05)
    assert tuple(s.color) == pytest.approx((1.0, 1.0, 1.0))
    assert s.model == 'AUTO'
    assert s.accuracy == pytest.approx(1.0)
    assert s.aa_samples == 4
    assert s.threads == 0
    assert s.cache_dir == "//airlight_cache/"
    assert s.auto_composite is True
    light = bpy.data.lights.new("L", 'POINT')
    assert light.airlight.participate is True


def test04_property_limits_clamp():
    s = bpy.context.scene.airlight
    s.density = -1.0
    assert s.density == 0.0
    s.aa_samples = 100
    assert s.aa_samples == 8
    s.aa_samples = 0
    assert s.aa_samples == 1
    s.threads = -3
    assert s.threads == 0
    s.color = (2.0, -1.0, 0.5)
    assert tuple(s.color) == pytest.approx((1.0, 0.0, 0.5))
    props = type(s).bl_rna.properties
    s.anisotropy = 1.5
    assert s.anisotropy == pytest.approx(0.99)
    s.anisotropy = -1.5
    assert s.anisotropy == pytest.approx(-0.99)
    for name in ("enabled", "density", "color", "model", "accuracy", "aa_samples", "threads",
                 "cache_dir", "auto_composite", "phase", "anisotropy", "use_fog_top", "fog_top"):
        description = props[name].description
        assert description and description[0].isupper(), name
    assert {item.identifier for item in props["model"].enum_items} == {
        'AUTO', 'SUN05', 'SUN05_EXACT', 'QUADRATURE', 'BIRI06', 'BASELINE', 'PEGORARO10', 'HOFFMAN02'}
    assert {item.identifier for item in props["phase"].enum_items} == {
        'HENYEY_GREENSTEIN', 'RAYLEIGH', 'MIE_HAZY', 'MIE_MURKY'}
    assert props["phase"].default == 'HENYEY_GREENSTEIN' and props["anisotropy"].default == 0.0


def test05_operators_poll_defined():
    from airlight import bake
    for cls in bake.classes:
        assert "poll" in cls.__dict__, cls.__name__
