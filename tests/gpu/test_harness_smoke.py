"""Smoke tests of the GPU harness: shaders from shaders/ compile, draw offscreen and read
back the expected values (constant colour, gradient, float texture round trip)."""

import gpu
import numpy as np
import pytest

from conftest import draw_fullscreen

W, H = 16, 8


@pytest.fixture
def offscreen():
    off = gpu.types.GPUOffScreen(W, H, format='RGBA32F')
    yield off
    off.free()


def test01_constant_colour(gs, offscreen):
    shader = gs.create_fullscreen_shader("constant", "test_constant_frag.glsl",
                                         push_constants=(('VEC4', "color"),))
    colour = (0.25, 0.5, 0.125, 0.75)
    draw_fullscreen(offscreen, shader, gs.fullscreen_batch(shader),
                    uniforms=(("color", colour),))
    pixels = gs.read_offscreen(offscreen)
    assert pixels.shape == (H, W, 4)
    np.testing.assert_array_equal(pixels, np.broadcast_to(np.float32(colour), pixels.shape))


def test02_gradient(gs, offscreen):
    shader = gs.create_fullscreen_shader("gradient", "test_gradient_frag.glsl")
    draw_fullscreen(offscreen, shader, gs.fullscreen_batch(shader))
    pixels = gs.read_offscreen(offscreen)
    x = (np.arange(W) + 0.5) / W
    y = (np.arange(H) + 0.5) / H
    np.testing.assert_allclose(pixels[..., 0], np.broadcast_to(x, (H, W)), atol=1e-5)
    np.testing.assert_allclose(pixels[..., 1], np.broadcast_to(y[:, None], (H, W)), atol=1e-5)
    np.testing.assert_array_equal(pixels[..., 2:], np.broadcast_to([0.25, 1.0], (H, W, 2)))


def test03_float_texture_round_trip(gs, offscreen):
    """Float32 inputs reach the shader bit-exactly (the agreement test relies on it)."""
    rng = np.random.default_rng(1)
    values = (rng.standard_normal((H, W, 4)) * 10.0 ** rng.integers(-8, 8, (H, W, 4)))
    values = values.astype(np.float32)
    shader = gs.create_fullscreen_shader("texel", "test_texel_frag.glsl", samplers=("values",))
    draw_fullscreen(offscreen, shader, gs.fullscreen_batch(shader),
                    samplers=(("values", gs.float_texture(values)),))
    pixels = gs.read_offscreen(offscreen)
    expected = np.float32(2.0) * values + np.float32(1.0)
    np.testing.assert_allclose(pixels, expected, rtol=2e-7, atol=0)


def test04_compile_error_is_reported(gs):
    """A GLSL error raises (with the compiler log), it does not draw garbage."""
    with pytest.raises(Exception):
        gs.create_fullscreen_shader("broken", "test_constant_frag.glsl",
                                    push_constants=())  # `color` undeclared
