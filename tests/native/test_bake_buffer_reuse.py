"""The bake's recycled output buffers (bake.h acquire_image_buffer / recycle_image_buffer):
arrays still alive are never reused, and a bake on recycled memory equals one on fresh memory
(no value of an earlier bake survives in any pass)."""
import math

import numpy as np

import _native
from scene_util import camera_matrix, perspective, plane_z, rotation_x

W, H = 512, 256  # passes of 0.5-1.5 MB: above the pool's 1 MB floor for the RGB passes


def bake(sigma_t, lights, half_floor=False, **kw):
    x1 = 0.0 if half_floor else 1000.0  # half the view misses: inf depth, Tr 0 there
    v, t = plane_z(-8.0, x=(-1000.0, x1))
    args = dict(width=W, height=H, cam_to_world=camera_matrix(rotation_x(math.radians(-10.0)), [0.5, 1.0, 2.0]),
                projection=perspective(math.radians(60.0), W, H), vertices=v, triangles=t,
                light_positions=np.array(lights, float).reshape(-1, 3),
                light_intensities=np.full((len(lights), 3), 2.0).reshape(-1, 3), sigma_t=sigma_t, threads=2)
    args.update(kw)
    return _native.bake(**args)


def arrays(res):
    return {k: v.copy() for k, v in res.items() if isinstance(v, np.ndarray)}


def test01_live_arrays_are_not_reused_and_recycled_bakes_equal_fresh():
    a = bake(0.08, [(1.0, 3.0, -5.0), (-2.0, 0.0, -3.0)], surface=True)
    a_copy = arrays(a)
    # B while A is alive: B gets fresh memory (or other recycled buffers), never A's.
    b_fresh = arrays(bake(0.02, [(0.0, 1.0, -4.0)], half_floor=True, surface=True))
    for k, v in a_copy.items():
        assert np.array_equal(a[k], v, equal_nan=True), k
    # A freed: its buffers go to the pool; B baked again on them must equal B on fresh memory.
    del a
    for _ in range(2):
        b = bake(0.02, [(0.0, 1.0, -4.0)], half_floor=True, surface=True)
        assert set(arrays(b)) == set(b_fresh)
        for k, v in b_fresh.items():
            assert np.array_equal(b[k], v, equal_nan=True), k
        del b
    # A smaller image on the recycled buffers of a bigger one: its own size, same values.
    small = bake(0.02, [(0.0, 1.0, -4.0)], width=400, height=250, projection=perspective(math.radians(60.0), 400, 250))
    assert small["airlight"].shape == (250, 400, 3)
    assert np.isinf(small["depth"]).sum() == 0 and np.all(np.isfinite(small["airlight"]))
