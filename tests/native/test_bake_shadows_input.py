"""Volumetric shadows on bad and extreme geometry: open, non-manifold, zero-area and huge
meshes, a light inside geometry and on a caster's surface, the camera inside a shadow, and
10^6 occluder triangles.

The reference is the `quadrature` model, whose integrand asks a shadow ray (Embree, from
every quadrature node to the light) whether the node is lit: visibility found independently
of the shadow volumes the other models take their lit intervals from. Passes must be finite,
and sun05's lit intervals must agree with it (to the table's 1e-4 plus float output)."""
import math

import numpy as np

import _native
from scene_util import camera_matrix, merge, perspective, quad

W, H = 24, 16
FOV = math.radians(60.0)
SIGMA_T = 0.1
LIGHT = np.array([[0.3, 0.4, -6.0]])
I0 = np.array([[50.0, 50.0, 50.0]])
BACK_Z = -14.0


def backdrop():
    """A far wall behind everything, so every ray ends on a surface."""
    return quad([[-60, -60, BACK_Z], [60, -60, BACK_Z], [60, 60, BACK_Z], [-60, 60, BACK_Z]])


def bake(casters, model="sun05", light=LIGHT, cam=(0.0, 0.0, 0.0), shadows=True, visible=True, **extra):
    """The casters also stop the camera's rays unless _visible_ is False (Camera visibility off)."""
    ov, ot = casters
    v, t = merge([backdrop(), casters]) if visible else backdrop()
    args = dict(width=W, height=H, cam_to_world=camera_matrix(np.eye(3), np.array(cam, float)),
                projection=perspective(FOV, W, H), vertices=v, triangles=t, light_positions=light,
                light_intensities=I0, sigma_t=SIGMA_T, model=model, aa_samples=1, threads=2,
                shadows=shadows, occluder_vertices=np.asarray(ov, np.float32),
                occluder_triangles=np.asarray(ot, np.uint32))
    args.update(extra)
    return _native.bake(**args)["airlight"][..., 0].astype(np.float64)


def assert_matches_quadrature(casters, bound=2e-3, **kw):
    got = bake(casters, **kw)
    ref = bake(casters, model="quadrature", **kw)
    assert np.isfinite(got).all() and np.isfinite(ref).all()
    scale = np.percentile(ref, 99)
    assert scale > 0.0
    err = np.abs(got - ref) / np.maximum(ref, 0.05 * scale)
    assert err.max() < bound, (err.max(), np.unravel_index(err.argmax(), err.shape))
    return got, ref


def panel(z=-4.0, half=0.8, cx=0.3, cy=0.4):
    return quad([[cx - half, cy - half, z], [cx + half, cy - half, z], [cx + half, cy + half, z],
                 [cx - half, cy + half, z]])


def test_open_panel_shadows_against_shadow_rays():
    assert_matches_quadrature(panel(), visible=False)  # the rays cross the panel's shadow and the light
    got, ref = assert_matches_quadrature(panel())
    unshadowed = bake(panel(), shadows=False)
    assert got.sum() < 0.9 * unshadowed.sum()  # the shadow is there


def test_non_manifold_fin_and_zero_area_triangles():
    """Three quads sharing one edge (a fin: the edge has three triangles), plus degenerate
    triangles (a repeated vertex, three collinear points): the degenerate ones change nothing."""
    a = panel(z=-4.0)
    fin = quad([[-0.5, 0.4, -4.0], [1.1, 0.4, -4.0], [1.1, 0.4, -5.0], [-0.5, 0.4, -5.0]])
    fin2 = quad([[-0.5, 0.4, -4.0], [1.1, 0.4, -4.0], [1.1, 1.4, -3.5], [-0.5, 1.4, -3.5]])
    soup = merge([a, fin, fin2])
    assert_matches_quadrature(soup)
    v, t = soup
    n = len(v)
    dv = np.array([[0.0, 0.0, -3.0], [1.0, 0.0, -3.0], [2.0, 0.0, -3.0]], np.float32)
    degenerate = (np.concatenate([v, dv]), np.concatenate([t, [[n, n, n + 1], [n, n + 1, n + 2]]]).astype(np.uint32))
    np.testing.assert_array_equal(bake(degenerate), bake(soup))


def test_huge_mesh():
    """A caster 2e6 m across (a ground-size plane cut by a small hole near the light)."""
    big = 1e6
    hole = (-0.2, 0.8)
    xs = (-big, hole[0], hole[1], big)
    ys = (-big, hole[0], hole[1], big)
    verts = [(x, y, -4.0) for y in ys for x in xs]
    faces = []
    for j in range(3):
        for i in range(3):
            if (i, j) == (1, 1):
                continue
            k = j * 4 + i
            faces += [(k, k + 1, k + 5), (k, k + 5, k + 4)]
    got, ref = assert_matches_quadrature((verts, faces))
    assert ref.max() > 0.0


def test_light_inside_closed_box_and_on_a_surface():
    """A light in a closed box: nothing outside is lit. A light on a caster's face: finite."""
    c = LIGHT[0]
    h = 0.5
    corners = np.array([[c[0] + sx * h, c[1] + sy * h, c[2] + sz * h]
                        for sz in (-1, 1) for sy in (-1, 1) for sx in (-1, 1)], np.float32)
    faces = [(0, 2, 3), (0, 3, 1), (4, 5, 7), (4, 7, 6), (0, 1, 5), (0, 5, 4),
             (2, 6, 7), (2, 7, 3), (0, 4, 6), (0, 6, 2), (1, 3, 7), (1, 7, 5)]
    boxed = bake((corners, faces))
    assert np.isfinite(boxed).all()
    assert boxed.max() < 1e-6 * bake((corners, faces), shadows=False).max()
    # The light on a panel's face: every segment to the light meets the panel's plane at the
    # light only, so nothing is shadowed (exactly: the unshadowed bake). The shadow rays of the
    # quadrature graze the panel in floats there, so it is not the reference here.
    on = panel(z=float(c[2]), half=1.0, cx=float(c[0]), cy=float(c[1]))
    got = bake(on)
    assert np.isfinite(got).all()
    np.testing.assert_allclose(got, bake(on, shadows=False), rtol=1e-6)


def test_camera_inside_a_shadow():
    """The camera in the panel's shadow cone: the fog near the eye is dark on every ray that
    crosses the cone, and the bake agrees with the shadow rays."""
    got, ref = assert_matches_quadrature(panel(z=-3.0, half=1.5), cam=(0.3, 0.4, 0.0))
    assert got[H // 2, W // 2] < 0.05 * np.percentile(bake(panel(z=-3.0, half=1.5), cam=(0.3, 0.4, 0.0),
                                                         shadows=False), 99)


def test_camera_on_a_shadow_boundary():
    """The camera and the light in the planes of two faces of a box, the segment between them
    along its edge: the eye lies on the boundary of the box's shadow, so rays into the shadow
    and rays beside it start with different counts (a spot between two slats, level with a
    camera, left the whole sky above the slats dark). The bake agrees with the shadow rays,
    and the shadow is there."""
    light = np.array([[0.0, 0.0, -6.0]])
    lo, hi = np.array([0.0, 0.0, -4.0]), np.array([1.0, 0.6, -3.0])
    corners = np.array([[(lo, hi)[i & 1][0], (lo, hi)[i >> 1 & 1][1], (lo, hi)[i >> 2 & 1][2]]
                        for i in range(8)], np.float32)
    faces = [(0, 2, 3), (0, 3, 1), (4, 5, 7), (4, 7, 6), (0, 1, 5), (0, 5, 4),
             (2, 6, 7), (2, 7, 3), (0, 4, 6), (0, 6, 2), (1, 3, 7), (1, 7, 5)]
    got, ref = assert_matches_quadrature((corners, faces), light=light)
    off = bake((corners, faces), light=light, shadows=False)
    assert got.sum() < 0.97 * off.sum()


def test_a_million_occluder_triangles():
    """10^6 small random triangles around the light: the bake completes with finite passes,
    shadowed at most as bright as unshadowed, and darker (they block light)."""
    rng = np.random.default_rng(7)
    n = 1_000_000
    centres = LIGHT[0] + rng.uniform(-3.0, 3.0, size=(n, 3))
    keep = np.linalg.norm(centres - LIGHT[0], axis=1) > 0.5
    centres = centres[keep]
    tri = centres[:, None, :] + rng.normal(scale=0.02, size=(len(centres), 3, 3))
    verts = tri.reshape(-1, 3).astype(np.float32)
    faces = np.arange(len(verts), dtype=np.uint32).reshape(-1, 3)
    got = bake((verts, faces))
    off = bake((verts, faces), shadows=False)
    assert np.isfinite(got).all()
    assert (got <= off * (1 + 1e-4) + 1e-9).all()
    assert got.sum() < 0.99 * off.sum()
