"""The surface-shading scene of test_bake_surface.py, also baked by
test_surface_glow_phase.py: a 20 x 14 camera looking along +y, tilted 35 degrees down onto
the floor z = 0 (y < 8), two point lights above it and optionally a spot light."""
import math

import numpy as np

from scene_util import camera_matrix, perspective, pixel_dirs_camera, plane_z, rotation_x

W, H = 20, 14
FOV = math.radians(60.0)
SIGMA_T = 0.2
ALBEDO = (0.9, 0.8, 0.6)
TILT = math.radians(-35.0)
CAM_POS = np.array([0.0, -6.0, 3.0])
POINT_POS = np.array([[0.5, 0.0, 2.0], [-2.0, 3.0, 1.0]])
POINT_I = np.array([[30.0, 20.0, 10.0], [5.0, 8.0, 12.0]])
SPOT_POS = np.array([[1.0, 1.0, 4.0]])


def scene(surface=True, spots=False):
    """(the bake's arguments, the camera's rotation)."""
    # Camera looks along +Y (rotate -Z to +Y), tilted down onto the floor z = 0 (y < 8).
    R = rotation_x(math.pi / 2 + TILT)
    v, t = plane_z(0.0, x=(-30, 30), y=(-20, 8))
    kw = dict(width=W, height=H, cam_to_world=camera_matrix(R, CAM_POS), projection=perspective(FOV, W, H),
              vertices=v, triangles=t, light_positions=POINT_POS, light_intensities=POINT_I,
              sigma_t=SIGMA_T, albedo=ALBEDO, aa_samples=1, surface=surface, threads=2)
    if spots:
        kw.update(spot_positions=SPOT_POS, spot_axes=np.array([[0.0, 0.0, -1.0]]),
                  spot_intensities=np.array([[10.0, 10.0, 10.0]]), spot_size=np.array([1.0]),
                  spot_blend=np.array([0.1]))
    return kw, R


def hit_points(result, R):
    """The first hit of every pixel's centre ray, from the depth pass (inf where it misses)."""
    d = pixel_dirs_camera(FOV, W, H) @ R.T
    return CAM_POS + result["depth"][..., None] * d
