"""The fog-object scene of test_bake_gaussians.py and test_bake_gaussians_lights.py: a
32 x 24 camera at the origin looking down -z over the floor y = -3, thin uniform fog from
the near plane, two point lights, and Gaussians (scene_util.few_gaussians) where a test
adds them."""
import math

import numpy as np

import _native
from scene_util import camera_matrix, perspective, plane_y, rotation_x

W, H = 32, 24
FOV = math.radians(60.0)
SIGMA_T = 0.01
CLIP = 0.5
CAM_POS = np.zeros(3)
FLOOR_Y = -3.0
LIGHTS = np.array([[4.0, 30.0, -28.0], [-20.0, 10.0, -5.0]])
INTENSITY = np.array([[100.0, 80.0, 60.0], [30.0, 30.0, 40.0]])
ALBEDO = np.array([0.9, 0.8, 0.7])


def bake(gauss=None, **kw):
    """The scene's bake; _gauss_ = (centres, scales, amplitudes) adds fog objects."""
    v, t = plane_y(FLOOR_Y, x=(-300.0, 300.0), z=(1.0, -200.0))
    args = dict(width=W, height=H, cam_to_world=camera_matrix(rotation_x(0.0), CAM_POS),
                projection=perspective(FOV, W, H), vertices=v, triangles=t, light_positions=LIGHTS,
                light_intensities=INTENSITY, sigma_t=SIGMA_T, albedo=tuple(ALBEDO), clip_start=CLIP, threads=2,
                aa_samples=1)
    if gauss is not None:
        b, a, c = gauss
        args.update(rbf_centres=b, rbf_scales=a, rbf_amplitudes=c)
    args.update(kw)
    return _native.bake(**args)
