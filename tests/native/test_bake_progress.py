"""Progress reporting and cancellation from the calling thread."""
import threading

import numpy as np
import pytest

import _native
from scene_util import perspective, plane_z


def args(**kw):
    v, t = plane_z(-3.0, x=(-50.0, 50.0), y=(-50.0, 50.0))
    a = dict(width=64, height=80, cam_to_world=np.eye(4), projection=perspective(1.0, 64, 80),
             vertices=v, triangles=t, light_positions=[[0.0, 1.0, -1.0]],
             light_intensities=[[1.0, 1.0, 1.0]], sigma_t=0.1, threads=2)
    a.update(kw)
    return a


def test01_fractions_increase_to_one():
    seen, threads = [], set()

    def progress(fraction):
        seen.append(fraction)
        threads.add(threading.get_ident())

    _native.bake(**args(progress=progress))
    assert len(seen) >= 3
    assert all(0.0 <= f <= 1.0 for f in seen)
    assert all(b >= a for a, b in zip(seen, seen[1:]))
    assert seen[-1] == 1.0
    assert threads == {threading.get_ident()}


def test02_returning_false_cancels():
    calls = []

    def progress(fraction):
        calls.append(fraction)
        return fraction < 0.2

    with pytest.raises(_native.BakeCancelled):
        _native.bake(**args(progress=progress))
    assert calls[-1] >= 0.2 and max(calls) < 1.0


def test03_callback_exception_propagates():
    def progress(fraction):
        if fraction > 0.1:
            raise KeyError("from the callback")

    with pytest.raises(KeyError, match="from the callback"):
        _native.bake(**args(progress=progress))


def test04_true_continues():
    out = _native.bake(**args(progress=lambda f: True))
    assert out["airlight"].shape == (80, 64, 3)
