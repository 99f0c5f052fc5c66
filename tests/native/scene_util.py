"""Small scenes for the bake tests, built independently of the C++ camera code: cameras,
projections and pixel rays, meshes (quads, axis-aligned planes, merged parts) and the
Gaussian clouds that several tests bake. Scenes shared whole live in scene_*.py."""
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


def crop_projection(projection, width, height, x0, y0, crop_width, crop_height):
    """The projection of the crop_width x crop_height pixels at (x0, y0) (row 0 at the top,
    as the bake's images) of a width x height image through _projection_ (perspective): a bake
    with it has the same pixels' rays as that window of the whole image."""
    q = np.array(projection, dtype=float)
    sx, sy = crop_width / width, crop_height / height
    cx = (x0 + crop_width / 2) / width * 2 - 1
    cy = (height - y0 - crop_height / 2) / height * 2 - 1  # (NDC y runs up)
    # x_clip' = (x_clip - cx w_clip) / sx, with w_clip the last row.
    q[0] = (q[0] - cx * q[3]) / sx
    q[1] = (q[1] - cy * q[3]) / sy
    return q


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


BIG = 1000.0  # half-width of the planes that fill the view


def plane_z(z, x=(-BIG, BIG), y=(-BIG, BIG)):
    """The rectangle x in _x_, y in _y_ of the plane z = _z_ (a floor or a wall facing the -z camera)."""
    return quad([[x[0], y[0], z], [x[1], y[0], z], [x[1], y[1], z], [x[0], y[1], z]])


def plane_y(y, x=(-BIG, BIG), z=(-BIG, BIG)):
    """The rectangle x in _x_, z in _z_ of the plane y = _y_ (a ground for a y-up scene)."""
    return quad([[x[0], y, z[0]], [x[1], y, z[0]], [x[1], y, z[1]], [x[0], y, z[1]]])


def merge(parts):
    """One mesh (vertices, triangles) from several, the triangles' indices shifted."""
    vs, ts, o = [], [], 0
    for v, t in parts:
        vs.append(v)
        ts.append(np.asarray(t) + o)
        o += len(v)
    return np.concatenate(vs).astype(np.float32), np.concatenate(ts).astype(np.uint32)


def in_camera_space(cam_to_world, mesh):
    """A mesh given in camera space, moved to world space by _cam_to_world_."""
    v, t = mesh
    return (v.astype(float) @ cam_to_world[:3, :3].T + cam_to_world[:3, 3]).astype(np.float32), t


def few_gaussians(scale=0.01, n=12, seed=5):
    """(centres, scales a, amplitudes c) of _n_ Gaussians 3-7 m wide, 20-36 m ahead of a
    camera at the origin looking down -z, peak densities _scale_ x 0.02-0.06 /m."""
    rng = np.random.default_rng(seed)
    b = np.column_stack([16 * rng.random(n) - 8, 4 * rng.random(n) - 2, -(20 + 16 * rng.random(n))])
    a = 0.15 + 0.15 * rng.random(n)
    c = scale * (0.02 + 0.04 * rng.random(n))
    return b, a, c


def gaussian_cloud(n=300, seed=11):
    """(centres, scales a, amplitudes c) of _n_ Gaussians 1-3 m wide filling x in [-18, 18],
    y in [-2, 5], z in [-45, -8], peak densities 0.02-0.08 /m."""
    rng = np.random.default_rng(seed)
    b = np.column_stack([rng.uniform(-18, 18, n), rng.uniform(-2, 5, n), rng.uniform(-45, -8, n)])
    a = 1.0 / rng.uniform(1.0, 3.0, n)
    c = rng.uniform(0.02, 0.08, n)
    return b, a, c


def floor_bake(bake, width, height, fov, floor_z, **kw):
    """The Airlight pass's first channel (float64, (height, width)) of _bake_ (`_native.bake`)
    for a pinhole at the origin looking down -z through a fov-wide perspective onto the floor
    z = _floor_z_ (160 m square), one sample a pixel, 2 threads, no point lights unless given;
    _kw_ adds to or overrides the arguments."""
    v, t = plane_z(floor_z, x=(-80.0, 80.0), y=(-80.0, 80.0))
    args = dict(width=width, height=height, cam_to_world=np.eye(4), projection=perspective(fov, width, height),
                vertices=v, triangles=t, light_positions=np.zeros((0, 3)), light_intensities=np.zeros((0, 3)),
                aa_samples=1, threads=2)
    args.update(kw)
    return bake(**args)["airlight"][..., 0].astype(np.float64)


def per_pixel_to_floor(fov, width, height, floor_z, integral):
    """(height, width) of _integral_(u, t1) per pixel: u the pixel's unit ray from the origin
    (pixel_dirs_camera), t1 its distance to the floor z = _floor_z_ (for the references that
    integrate the fog along each ray with scipy)."""
    d = pixel_dirs_camera(fov, width, height)
    out = np.empty((height, width))
    for j in range(height):
        for i in range(width):
            u = d[j, i]
            out[j, i] = integral(u, floor_z / u[2])
    return out
