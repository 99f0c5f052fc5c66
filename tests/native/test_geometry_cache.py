"""The bakes of one process share Embree's BVH while their geometry stays the same
(image/raycast.h, RayCaster::shared): per-light passes, lens and shutter samples and the
frames of an animation build it once. Tests: a bake of the same vertices and triangles builds
none; one moved vertex, or other triangles, builds again and sees the new surface (depth
against the plane's distance); a bake refused for its camera leaves the next bake of the
same geometry as it was; clear_geometry_cache drops the kept mesh.

The shadow volumes are shared the same way (ShadowVolumes::shared, the last two sets): a
frame's soft-shadow probe and its bake, and the frames of a static shot, build them once. A
shared set bakes bit for bit what a new one does; a moved light, caster or camera builds
again.
"""
import math

import numpy as np
import pytest

import _native
from scene_util import camera_matrix, merge, perspective, plane_z, rotation_x

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


BOX = (np.array([[x, y, z] for x in (-0.3, 0.3) for y in (1.2, 1.8) for z in (-0.2, 0.4)], np.float32),
       np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                 [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]], np.uint32))


def shadowed(vertices, triangles, **kw):
    """bake() with a box casting shadows from the light into the fog (the camera does not see it)."""
    args = dict(occluder_vertices=BOX[0], occluder_triangles=BOX[1], shadows=True)
    args.update(kw)
    return bake(vertices, triangles, **args)


def test06_a_moving_camera_shares_the_volumes_bit_for_bit():
    """The volumes are built about the casters and reach as far as the farthest caster or the
    camera (a power of 2): a camera moving among them shares them, and its bakes are the ones
    a fresh process makes. The film and the traced crossings take the camera where it is."""
    v, t = plane_z(-1.0)
    box_v, box_t = BOX
    seen = (np.concatenate([v, box_v]), np.concatenate([t, box_t + np.uint32(len(v))]))
    path = [[0.0, 0.0, EYE_Z], [0.3, 0.2, EYE_Z], [-0.4, 0.5, EYE_Z + 0.3], [0.2, 1.0, EYE_Z - 0.2]]
    cameras = [camera_matrix(rotation_x(math.radians(-30.0 + 3.0 * k)), p) for k, p in enumerate(path)]

    def frame(camera, crossings, box_seen):
        kw = dict(cam_to_world=camera, shadow_crossings=crossings, surface=True)
        return bake(*seen, shadows=True, **kw) if box_seen else shadowed(v, t, **kw)

    for crossings in ("film", "traced"):
        for box_seen in (False, True):  # (seen: its caps cut for the camera's rays and the glow's)
            fresh = []
            for camera in cameras:
                _native.clear_geometry_cache()
                fresh.append(frame(camera, crossings, box_seen))
            _native.clear_geometry_cache()
            before = _native.shadow_volume_builds()
            for camera, alone in zip(cameras, fresh):
                shared = frame(camera, crossings, box_seen)
                for name in ("airlight", "surface_glow"):
                    np.testing.assert_array_equal(shared[name], alone[name])
            assert _native.shadow_volume_builds() == before + 1
            assert not np.array_equal(fresh[0]["airlight"], fresh[1]["airlight"])


def test04_same_casters_lights_and_camera_share_the_shadow_volumes():
    v, t = plane_z(-1.0)
    _native.clear_geometry_cache()
    before = _native.shadow_volume_builds()
    first = shadowed(v, t)
    assert _native.shadow_volume_builds() == before + 1
    again = shadowed(v.copy(), t.copy(), sigma_t=0.2)  # other fog, the same volumes
    assert _native.shadow_volume_builds() == before + 1
    _native.clear_geometry_cache()
    fresh = shadowed(v, t)
    assert _native.shadow_volume_builds() == before + 2
    np.testing.assert_array_equal(shadowed(v, t)["airlight"], fresh["airlight"])  # shared: bit for bit
    assert _native.shadow_volume_builds() == before + 2
    lit = bake(v, t)["airlight"]
    assert np.sum(lit) > 1.05 * np.sum(first["airlight"])  # (the box does shadow the fog)
    assert not np.array_equal(again["airlight"], first["airlight"])


def test05_a_moved_light_caster_or_far_camera_builds_the_volumes_again():
    v, t = plane_z(-1.0)
    shadowed(v, t)
    before = _native.shadow_volume_builds()
    moved_light = shadowed(v, t, light_positions=np.array([[0.2, 3.0, 1.0]]))
    assert _native.shadow_volume_builds() == before + 1
    # The last two sets are kept: the probe's samples between a frame's two bakes of its centre.
    soft = shadowed(v, t, light_radii=np.array([0.3]), shadow_samples=8)
    assert _native.shadow_volume_builds() == before + 2
    shadowed(v, t, light_positions=np.array([[0.2, 3.0, 1.0]]))
    assert _native.shadow_volume_builds() == before + 2
    camera = camera_matrix(rotation_x(math.radians(-30.0)), [0.0, -60.0, EYE_Z])  # R grows
    shadowed(v, t, cam_to_world=camera)
    assert _native.shadow_volume_builds() == before + 3
    box = np.array([[x, y, z] for x in (-0.3, 0.3) for y in (1.2, 1.8) for z in (-0.2, 0.41)], np.float32)
    raised = shadowed(v, t, occluder_vertices=box)
    assert _native.shadow_volume_builds() == before + 4
    assert not np.array_equal(raised["airlight"], shadowed(v, t)["airlight"])
    assert not np.array_equal(soft["airlight"], moved_light["airlight"])


def grid(n, x, y, z):
    """A grid of n x n quads (2 n^2 triangles) over [x0, x1] x [y0, y1] at height _z_."""
    xs, ys = np.meshgrid(np.linspace(*x, n + 1), np.linspace(*y, n + 1))
    vertices = np.stack([xs.ravel(), ys.ravel(), np.full(xs.size, z)], axis=1).astype(np.float32)
    a = (np.arange(n)[None, :] + (n + 1) * np.arange(n)[:, None]).ravel()
    triangles = np.concatenate([np.stack([a, a + 1, a + n + 2], 1), np.stack([a, a + n + 2, a + n + 1], 1)])
    return vertices, triangles.astype(np.uint32)


def test07_a_moved_object_rebuilds_its_own_bvhs_and_shadow_faces_only_bit_for_bit():
    """Each object of the soup (a run that indexes only its own vertices) has its own BVH, for
    the camera's rays and for the casters' counts (image/embree_blocks.h), and its own faces of
    each light's shadow volume (shadow/block_faces.h): an object that moves builds those of its
    block again, the others are shared, and the bake is a fresh process's."""
    floor = grid(130, (-4.0, 4.0), (-1.0, 7.0), -1.0)   # 33,800 triangles: a block of its own
    wall = grid(130, (-4.0, 4.0), (-1.0, 7.0), -1.6)    # another, under the floor (seen through no hole)
    box_v, box_t = BOX

    def frame(box_shift):
        # (Moved across, inside the grids' box: the volumes' frame, the casters' centre, stays.)
        v, t = merge([floor, wall, (box_v + np.array([box_shift, box_shift, 0.0], np.float32), box_t)])
        return bake(v, t, shadows=True, surface=True)

    _native.clear_geometry_cache()
    frame(0.0)
    built = _native.geometry_blocks_built()
    for shift in (0.1, 0.2):
        before = _native.raycaster_builds()
        moved = frame(shift)
        after = _native.geometry_blocks_built()
        # The box joins the last grid's block (blocks have at least kMinBlockTriangles).
        assert after["camera"] == built["camera"] + 1
        assert after["casters"] == built["casters"] + 1
        assert after["volume_faces"] == built["volume_faces"] + 1  # (one light)
        assert _native.raycaster_builds() == before + 1
        built = after
        _native.clear_geometry_cache()
        alone = frame(shift)
        built = _native.geometry_blocks_built()
        for name in ("depth", "airlight", "surface_glow"):
            np.testing.assert_array_equal(moved[name], alone[name])
    assert not np.array_equal(frame(0.0)["airlight"], alone["airlight"])
