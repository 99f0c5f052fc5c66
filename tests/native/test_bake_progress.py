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


def _table_bake(g, progress):
    """A biri06 bake whose 2048^2 Gamma table (a g no other test uses: built here, ~1-2 s)
    is built after the raycast, at the progress fraction 0.3."""
    return _native.bake(**args(model="biri06", phase="hg", g=g, table_size=2048, progress=progress))


def test05_progress_stays_alive_while_a_table_builds():
    """The model's table build reports the held fraction again every ~20 ms (it used to report
    nothing for the whole build: the bar stood at 30 % and Esc went unseen)."""
    seen = []
    _table_bake(0.4321, lambda fraction: seen.append(fraction))
    held = max(f for f in seen if f <= 0.3)
    assert seen.count(held) >= 5, seen[:20]
    assert all(b >= a for a, b in zip(seen, seen[1:]))


def test06_cancel_during_a_table_build_stops_it():
    """Returning False while the table builds cancels the bake there (before the airlight
    pass starts), and the cancelled table is not kept: the next bake builds it again."""
    calls = []

    def progress(fraction):
        calls.append(fraction)
        return not (fraction >= 0.3 and calls.count(fraction) >= 4)  # the raycast's end reports <= 2

    with pytest.raises(_native.BakeCancelled):
        _table_bake(0.4322, progress)
    assert max(calls) == calls[-1] and calls.count(calls[-1]) == 4
    again = []
    _table_bake(0.4322, lambda fraction: again.append(fraction))
    assert again.count(max(f for f in again if f <= 0.3)) >= 5
