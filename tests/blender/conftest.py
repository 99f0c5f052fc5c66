"""Shared fixtures for the headless Blender tests (run through run_tests.py).

The compiled `_native` must load: when it is missing, stale or broken every test fails
(`native_module`, with native.error()'s reason), since the tests hold the add-on to it;
none is ever skipped for it. Build it with `make build`.
"""
import os
import subprocess
import sys

import bpy
import numpy as np
import pytest

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(os.path.dirname(HERE))
BLENDER_SH = os.path.join(REPO, "tools", "blender.sh")
sys.path.insert(0, os.path.join(HERE, "support"))

import airlight  # noqa: E402
from exr_files import exr_pass, read_exr  # noqa: E402,F401  (the tests import them from here)
from airlight import native  # noqa: E402


@pytest.fixture(scope="session", autouse=True)
def native_module():
    """The add-on's compiled module; a missing or broken one fails every test, loudly."""
    if not native.available():
        pytest.fail(f"the Airlight native module is not available: {native.error()} "
                    "(run `make build`)", pytrace=False)
    return native.get()


def reset_blender():
    """Starts from a known state: the factory startup file with no data (what
    --factory-startup gives the first test) and the add-on registered.

    Tests build their scenes in bpy.context.scene, so whatever an earlier test left in it
    (scene.airlight.enabled, whose render_pre handler bakes and composites fog onto any
    render; compositor nodes; colour management; other scenes, worlds, images) leaks into
    the next one. Measured: the Cycles reference renders came out 28-46 % off after
    test_compositor's scene (fog enabled, density 0.2) was left behind. read_homefile keeps
    the preferences, hence the add-on enabled by tools/blender.sh; a test that disabled it
    (test_registration re-enables it, but may fail half way) is covered by enabling it here.
    """
    import addon_utils
    bpy.ops.wm.read_homefile(use_factory_startup=True, use_empty=True)
    if not hasattr(bpy.types.Scene, "airlight"):
        addon_utils.enable("airlight", default_set=True)
    scene = bpy.context.scene
    assert not scene.airlight.enabled and not scene.use_nodes, "reset_blender left fog or nodes on"
    return scene


@pytest.fixture(scope="module", autouse=True)
def fresh_blender_per_module():
    """Every test module starts from reset_blender()'s state (module scope, so a module's
    own module-scoped fixtures, e.g. the Cycles reference scene, survive its tests)."""
    reset_blender()
    yield


def run_blender(*args, timeout=120):
    """Runs tools/blender.sh in a subprocess; returns CompletedProcess (text output)."""
    cmd = [BLENDER_SH, "-b", *args]
    return subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)


def build_plane_scene(tmp_path, fog=True, light=True, camera=True, size=(64, 48)):
    """A fresh scene: ground plane z=0, point light, camera at z=2 looking down -Z."""
    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    mesh = bpy.data.meshes.new("Ground")
    half = 50.0
    mesh.from_pydata([(-half, -half, 0), (half, -half, 0), (half, half, 0), (-half, half, 0)],
                     [], [(0, 1, 2, 3)])
    ground = bpy.data.objects.new("Ground", mesh)
    scene.collection.objects.link(ground)
    if light:
        light_data = bpy.data.lights.new("Lamp", 'POINT')
        light_data.energy = 300.0
        light_data.color = (1.0, 0.5, 0.25)
        light_data.shadow_soft_size = 0.0
        lamp = bpy.data.objects.new("Lamp", light_data)
        lamp.location = (0.5, 0.3, 1.0)
        scene.collection.objects.link(lamp)
    if camera:
        cam_data = bpy.data.cameras.new("Cam")
        cam_data.lens = 35.0
        cam = bpy.data.objects.new("Cam", cam_data)
        cam.location = (0.0, 0.0, 2.0)
        scene.collection.objects.link(cam)
        scene.camera = cam
    scene.render.resolution_x, scene.render.resolution_y = size
    scene.render.resolution_percentage = 100
    scene.airlight.density = 0.2
    scene.airlight.cache_dir = str(tmp_path / "cache") + os.sep
    scene.airlight.enabled = fog
    # Full floats whatever the output: the tests compare the cache EXR's passes with the bake
    # bit for bit (test_bake_operator.py's test10b checks the default, Automatic).
    scene.airlight.pass_precision = 'FULL'
    return scene


def cycles_exr_render(scene, samples):
    """Cycles on the CPU with _samples_ samples (no denoiser), a black World, the Standard
    view transform and 32-bit float EXR output: renders the tests compare to the passes."""
    scene.render.engine = 'CYCLES'
    scene.cycles.samples = samples
    scene.cycles.use_denoising = False
    scene.cycles.device = 'CPU'
    world = bpy.data.worlds.new("Dark")
    world.color = (0.0, 0.0, 0.0)
    scene.world = world
    scene.view_settings.view_transform = 'Standard'
    settings = scene.render.image_settings
    settings.file_format = 'OPEN_EXR'
    settings.color_depth = '32'
    return settings


def poles_scene(tmp_path, poles, samples):
    """The camera tests' scene: an empty world (transparent film: Cycles' alpha is the
    coverage), the camera at (0, 0, 1) looking along +y, and a box pole per (location,
    (sx, sy, sz)) of _poles_ (returned in order); Cycles at _samples_ (cycles_exr_render),
    fog of density 0.2 without surface shading."""
    scene = build_plane_scene(tmp_path, size=(64, 48))
    bpy.data.objects.remove(bpy.data.objects["Ground"])
    objects = []
    for location, scale in poles:
        bpy.ops.mesh.primitive_cube_add(size=1.0, location=location)
        objects.append(bpy.context.active_object)
        objects[-1].scale = scale
    cam = scene.camera
    cam.location = (0.0, 0.0, 1.0)
    cam.rotation_euler = (1.5707963267948966, 0.0, 0.0)  # looking along +y
    scene.render.film_transparent = True
    cycles_exr_render(scene, samples)
    scene.airlight.density = 0.2
    scene.airlight.surface_shading = False
    return scene, objects


def hit_coverage(descriptions, settings):
    """Per pixel, the fraction of the bakes of _descriptions_ (with _settings_) whose centre
    ray hits a surface."""
    from airlight import bake
    hit = 0.0
    for description in descriptions:
        result = native.get().bake(**description, **bake.native_settings(settings))
        hit = hit + np.isfinite(result["depth"]).astype(np.float64)
    return hit / len(descriptions)


def coverage_errors(alpha, sampled, single):
    """Against Cycles' coverage _alpha_, over the pixels partly covered in it or in _sampled_:
    (their count, the mean absolute error of _sampled_, that of _single_)."""
    band = ((alpha > 0.02) & (alpha < 0.98)) | ((sampled > 0.02) & (sampled < 0.98))
    return int(band.sum()), np.abs(sampled - alpha)[band].mean(), np.abs(single - alpha)[band].mean()


class RecordingLayout:
    """A stand-in for a panel's layout: records what the panel draws (property names,
    operator ids, label texts) and checks that each property exists and has a tooltip and
    each operator exists."""

    def __init__(self, seen):
        self.seen = seen
        self.use_property_split = self.use_property_decorate = self.alert = self.active = False
        self.scale_y = 1.0

    def _child(self, *args, **kwargs):
        return RecordingLayout(self.seen)
    row = column = box = _child

    def prop(self, data, name, **kwargs):
        assert name in data.bl_rna.properties, name
        assert data.bl_rna.properties[name].description, name
        self.seen.append(name)

    def operator(self, idname, **kwargs):
        module, name = idname.split(".")
        assert hasattr(getattr(bpy.ops, module), name), idname
        self.seen.append(idname)

    def label(self, **kwargs):
        self.seen.append(kwargs.get("text", ""))


def draw_panel(panel):
    """What the panel class bpy.types.<panel> draws in the current context (RecordingLayout)."""
    seen = []

    class Fake:
        layout = RecordingLayout(seen)
    getattr(bpy.types, panel).draw(Fake(), bpy.context)
    return seen
