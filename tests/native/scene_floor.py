"""The tiny floor scene of test_bake_passes.py, also baked by test_bake_F_table.py: a
48 x 32 camera pitched down 10 degrees over the floor z = -8, which fills the view, in
uniform fog, one point light by default."""
import math

import numpy as np

import _native
from scene_util import camera_matrix, perspective, pixel_dirs_camera, plane_z, rotation_x

W, H = 48, 32
FOV = math.radians(60.0)
SIGMA_T = 0.08
TILT = math.radians(-10.0)          # camera pitched down by 10 degrees
CAM_POS = np.array([0.5, 1.0, 2.0])
PLANE_Z = -8.0                       # the floor z = -8 fills the whole view (camera looks down -Z)


def floor():
    return plane_z(PLANE_Z)


def bake(lights=((1.0, 3.0, -5.0),), intensities=((2.0, 2.0, 2.0),), geometry=None, **kw):
    vertices, triangles = floor() if geometry is None else geometry
    args = dict(width=W, height=H, cam_to_world=camera_matrix(rotation_x(TILT), CAM_POS),
                projection=perspective(FOV, W, H), vertices=vertices, triangles=triangles,
                light_positions=np.array(lights, dtype=float).reshape(-1, 3),
                light_intensities=np.array(intensities, dtype=float).reshape(-1, 3),
                sigma_t=SIGMA_T, threads=2)
    args.update(kw)
    return _native.bake(**args)


def world_dirs():
    return pixel_dirs_camera(FOV, W, H) @ rotation_x(TILT).T


def analytic_depth():
    d = world_dirs()
    return (CAM_POS[2] - PLANE_Z) / -d[..., 2]
