"""Shared fixtures of the GPU tests: the add-on's preview module, the native module, a place for
artifacts. Runs inside Blender (see run_gpu_tests.py)."""

import os

import pytest

REPO = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", ".."))
ARTIFACTS = os.path.join(REPO, "out", "test_artifacts")


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


@pytest.fixture(scope="session")
def native():
    """The compiled module; a missing or incomplete module FAILS the tests that need it
    (they are the check that GLSL and C++ agree, so they must not skip silently)."""
    try:
        from airlight import _native
    except ImportError as ex:
        pytest.fail(f"_native could not be imported: {ex}. Build it first (see README).")
    needed = ("special_F", "special_F_table", "sun05_airlight")
    missing = [n for n in needed if not hasattr(_native, n)]
    if missing:
        pytest.fail("_native lacks " + ", ".join(missing))
    return _native


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
