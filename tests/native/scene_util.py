"""Small scenes for the bake tests, built independently of the C++ camera code."""
import math

import numpy as np


def perspective(fov_x, width, height, near=0.1, far=1000.0):
    """OpenGL projection as Blender's calc_matrix_camera gives it (sensor fit along x)."""
    r = near * math.tan(fov_x / 2.0)
    t = r * height / width
    return np.array([
        [near / r, 0.0, 0.0, 0.0],
        [0.0, near / t, 0.0, 0.0],
        [0.0, 0.0, -(far + near) / (far - near), -2.0 * far * near / (far - near)],
        [0.0, 0.0, -1.0, 0.0],
    ])


def orthographic(scale_x, width, height, near=0.1, far=1000.0):
    """OpenGL orthographic projection with half-widths scale_x/2 and the aspect's height."""
    r = scale_x / 2.0
    t = r * height / width
    return np.array([
        [1.0 / r, 0.0, 0.0, 0.0],
        [0.0, 1.0 / t, 0.0, 0.0],
        [0.0, 0.0, -2.0 / (far - near), -(far + near) / (far - near)],
        [0.0, 0.0, 0.0, 1.0],
    ])


def pixel_dirs_camera(fov_x, width, height):
    """Unit camera-space directions through every pixel centre, shape (H, W, 3), top row first."""
    tx = math.tan(fov_x / 2.0)
    ty = tx * height / width
    i = np.arange(width) + 0.5
    j = np.arange(height) + 0.5
    x = (2.0 * i / width - 1.0) * tx
    y = (1.0 - 2.0 * j / height) * ty
    X, Y = np.meshgrid(x, y)
    d = np.stack([X, Y, -np.ones_like(X)], axis=-1)
    return d / np.linalg.norm(d, axis=-1, keepdims=True)


def rotation_x(angle):
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]], dtype=float)


def camera_matrix(rotation, position):
    m = np.eye(4)
    m[:3, :3] = rotation
    m[:3, 3] = position
    return m


def quad(corners):
    """Two triangles for the quadrilateral with the given 4 corners (in order)."""
    v = np.asarray(corners, dtype=np.float32)
    tris = np.array([[0, 1, 2], [0, 2, 3]], dtype=np.uint32)
    return v, tris
