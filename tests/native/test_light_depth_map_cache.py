"""The light-depth maps a bake keeps for the next one (native/bake/map_cache.h): a bake whose
Gaussians, marched light and map size equal the last bake's takes that bake's map, and gives
the frame a bake that built its own would; any change to what a map is built from builds a new
one. The frames are compared with those of bakes after clear_light_depth_maps (a fresh map
each), so a map taken where it does not belong shows as a different frame."""
import math

import numpy as np
import pytest

import _native
from scene_util import camera_matrix, perspective, plane_y, rotation_x

TAU = 1.0 / math.sqrt(math.pi)  # amplitude c = TAU * tau * a: optical depth tau through the centre
THREE = [(0.3, 0.2, -15.0, 0.5, 5.0), (-3.0, 0.5, -17.0, 0.4, 0.4), (3.5, -0.5, -14.0, 0.6, 0.3)]
POINT = dict(light_positions=np.array([[0.0, 0.0, -15.0]]), light_intensities=np.array([[100.0, 80.0, 60.0]]))
SUN = dict(light_positions=np.zeros((0, 3)), light_intensities=np.zeros((0, 3)),
           sun_directions=np.array([[0.3, -0.8, -0.5]]), sun_irradiances=np.array([[3.0, 3.0, 3.0]]))


def bake(rows=THREE, lights=POINT, eye=(0.0, 0.0, 0.0), accuracy=0.01):
    rows = np.asarray(rows, float)
    v, t = plane_y(-3.0, x=(-300.0, 300.0), z=(1.0, -200.0))
    out = _native.bake(width=32, height=24, cam_to_world=camera_matrix(rotation_x(0.0), np.array(eye)),
                       projection=perspective(math.radians(60), 32, 24), vertices=v, triangles=t, sigma_t=0.01,
                       albedo=(0.9, 0.8, 0.7), clip_start=0.5, threads=2, aa_samples=1, model="biri06",
                       rbf_centres=rows[:, :3], rbf_scales=rows[:, 3], rbf_amplitudes=TAU * rows[:, 4] * rows[:, 3],
                       gaussian_accuracy=accuracy, **lights)
    assert out["stats"]["gaussian_marched_lights"] == 1  # (the scene's light is marched, with a map)
    return np.asarray(out["airlight"])


def fresh(**kw):
    """The frame with maps of its own."""
    _native.clear_light_depth_maps()
    return bake(**kw)


@pytest.mark.parametrize("lights", [POINT, SUN], ids=["point", "sun"])
def test_the_next_bake_of_the_same_fog_takes_the_map(lights):
    first = fresh(lights=lights)
    built = _native.light_depth_map_builds()
    again = bake(lights=lights)
    assert _native.light_depth_map_builds() == built
    np.testing.assert_array_equal(again, first)


@pytest.mark.parametrize("lights", [POINT, SUN], ids=["point", "sun"])
def test_another_camera_takes_the_map_and_sees_its_own_frame(lights):
    """A stereo pair's other eye, or the next frame of a camera move: the map is the light's."""
    fresh(lights=lights)
    built = _native.light_depth_map_builds()
    other = bake(lights=lights, eye=(0.5, 0.2, 0.0))
    assert _native.light_depth_map_builds() == built
    np.testing.assert_array_equal(other, fresh(lights=lights, eye=(0.5, 0.2, 0.0)))


MOVED = [THREE[0], (-2.5, 0.5, -17.0, 0.4, 0.4), THREE[2]]
CHANGES = {
    "a Gaussian moved": dict(rows=MOVED),
    "a Gaussian denser": dict(rows=[THREE[0], (-3.0, 0.5, -17.0, 0.4, 0.8), THREE[2]]),
    "the light moved": dict(lights=dict(POINT, light_positions=np.array([[0.5, 0.0, -15.0]]))),
    "the sun turned": dict(lights=dict(SUN, sun_directions=np.array([[0.35, -0.8, -0.5]]))),
    "another accuracy": dict(accuracy=0.05),
}


@pytest.mark.parametrize("change", list(CHANGES))
def test_a_change_builds_its_own_map(change):
    kw = CHANGES[change]
    fresh(lights=SUN if "sun" in change else POINT)  # (the scene before the change)
    built = _native.light_depth_map_builds()
    changed = bake(**kw)
    assert _native.light_depth_map_builds() > built
    np.testing.assert_array_equal(changed, fresh(**kw))
