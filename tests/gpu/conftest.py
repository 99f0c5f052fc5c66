"""Shared fixtures of the GPU tests: the add-on's preview module, the native module, a place for
artifacts, the homogeneous fog scene. Runs inside Blender (see run_gpu_tests.py); the helpers
the test modules share live in support/ (preview_scenes.py, event_driver.py)."""

import os
import sys

import pytest

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.normpath(os.path.join(HERE, "..", ".."))
ARTIFACTS = os.path.join(REPO, "out", "test_artifacts")
sys.path.insert(0, os.path.join(HERE, "support"))


def pytest_configure(config):
    import gpu
    print(f"\nGPU: {gpu.platform.renderer_get()} / {gpu.platform.version_get()}")


@pytest.fixture(scope="session")
def gs():
    from airlight import gpu_shaders
    return gpu_shaders


@pytest.fixture(scope="module")
def addon():
    """The add-on's preview module, with the add-on registered (tools/blender.sh enables it;
    else register here)."""
    import bpy
    import airlight
    if not hasattr(bpy.types.Scene, "airlight"):
        airlight.register()
    from airlight import preview
    return preview


@pytest.fixture(scope="session", autouse=True)
def native():
    """The compiled module, checked for every test: a missing, broken or incomplete module
    FAILS the session's tests with the loader's reason (they hold the GLSL and the add-on to
    the C++, so they must never skip)."""
    from airlight import native as loader
    if not loader.available():
        pytest.fail(f"the Airlight native module is not available: {loader.error()} (run `make build`)",
                    pytrace=False)
    module = loader.get()
    needed = ("special_F", "special_F_table", "sun05_airlight")
    missing = [n for n in needed if not hasattr(module, n)]
    if missing:
        pytest.fail("_native lacks " + ", ".join(missing) + ": rebuild it (`make build`)", pytrace=False)
    return module


@pytest.fixture(scope="module")
def fog_scene(addon, native):
    """Floor, cube, two point lights, a camera; homogeneous fog on (preview_scenes.build_scene)."""
    import preview_scenes
    return preview_scenes.build_scene(preview_scenes.FOG_SIGMA_T)


@pytest.fixture(scope="session")
def artifacts():
    os.makedirs(ARTIFACTS, exist_ok=True)
    return ARTIFACTS


def draw_fullscreen(offscreen, shader, batch, *, samplers=(), uniforms=()):
    """Draws _batch_ with _shader_ into _offscreen_ (cleared to 0); no blending."""
    import gpu
    with offscreen.bind():
        fb = gpu.state.active_framebuffer_get()
        fb.clear(color=(0.0, 0.0, 0.0, 0.0))
        shader.bind()
        for name, tex in samplers:
            shader.uniform_sampler(name, tex)
        for name, value in uniforms:
            shader.uniform_float(name, value)
        batch.draw(shader)
