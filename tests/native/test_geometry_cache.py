"""The bakes of one process share Embree's BVH while their geometry stays the same
(image/raycast.h, RayCaster::shared): per-light passes, lens and shutter samples and the
frames of an animation build it once. Tests: a bake of the same vertices and triangles builds
none; one moved vertex, or other triangles, builds again and sees the new surface (depth
against the plane's distance); a bake refused for its camera leaves the next bake of the
same geometry as it was; clear_geometry_cache drops the kept mesh.
"""
import math

import numpy as np
import pytest

import _native
from scene_util import camera_matrix, perspective, plane_z, rotation_x

W, H = 48, 32
EYE_Z = 2.0


def bake(vertices, triangles, **kw):
    args = dict(width=W, height=H, cam_to_world=camera_matrix(rotation_x(math.radians(-30.0)), [0.0, 0.0, EYE_Z]),
                projection=perspective(math.radians(60.0), W, H), vertices=vertices, triangles=triangles,
                light_positions=np.array([[0.0, 3.0, 1.0]]), light_intensities=np.full((1, 3), 5.0),
                sigma_t=0.05, threads=2)
    args.update(kw)
    return _native.bake(**args)


def test01_same_geometry_shares_the_bvh_and_new_geometry_rebuilds():
    v, t = plane_z(-1.0)
    bake(v, t)
    before = _native.raycaster_builds()
    first = bake(v.copy(), t.copy())
    assert _native.raycaster_builds() == before  # equal arrays (copies): shared
    bake(v, t, sigma_t=0.2, light_positions=np.array([[1.0, 2.0, 0.5]]))  # other fog, same mesh
    assert _native.raycaster_builds() == before
    lower = v.copy()
    lower[:, 2] = -3.0  # every vertex moved: the plane at z = -3
    moved = bake(lower, t)
    assert _native.raycaster_builds() == before + 1
    hit = np.isfinite(first["depth"])
    assert hit.sum() > 0.3 * hit.size
    # Depth along a ray scales with the eye's height above the plane: (2 + 3) / (2 + 1).
    np.testing.assert_allclose(moved["depth"][hit], first["depth"][hit] * (EYE_Z + 3.0) / (EYE_Z + 1.0), rtol=1e-5)
    one = v.copy()
    one[0, 2] += 1e-3  # a single vertex moved by a millimetre: not the same mesh
    bake(one, t)
    assert _native.raycaster_builds() == before + 2
    bake(v, t[::-1].copy())  # the same vertices, triangles in another order
    assert _native.raycaster_builds() == before + 3


def test02_a_refused_bake_leaves_the_shared_geometry_as_it_was():
    v, t = plane_z(-1.0)
    good = bake(v, t)
    huge = np.eye(4)
    huge[:3, 3] = 1e30  # a camera far beyond float range: its rays cannot be traced
    with pytest.raises(ValueError):
        bake(v, t, cam_to_world=huge)
    again = bake(v, t)
    np.testing.assert_array_equal(again["depth"], good["depth"])


def test03_clear_drops_the_kept_geometry():
    v, t = plane_z(-1.0)
    bake(v, t)
    before = _native.raycaster_builds()
    _native.clear_geometry_cache()
    bake(v, t)
    assert _native.raycaster_builds() == before + 1
