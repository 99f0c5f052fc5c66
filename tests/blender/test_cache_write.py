"""The cache's EXR writes are atomic: a temporary file renamed over the frame's, so readers
and concurrent writers (two farm tasks rendering one frame) see whole files only."""
import os
import threading

import numpy as np

from conftest import exr_pass
from airlight import cache


def test_write_leaves_no_temporary_and_concurrent_writers_leave_a_whole_file(tmp_path):
    path = str(tmp_path / "fog_0001.exr")
    H, W = 64, 96
    writers = []
    for k in range(4):
        value = np.float32(k + 1)
        writers.append((np.full((H, W, 3), value, np.float32), np.full((H, W, 3), value / 10, np.float32)))
    errors = []

    def write(a, t):
        try:
            for _ in range(5):
                cache.write_passes(path, a, t)
        except Exception as ex:  # pragma: no cover - reported below
            errors.append(ex)
    threads = [threading.Thread(target=write, args=w) for w in writers]
    for th in threads:
        th.start()
    for th in threads:
        th.join()
    assert not errors, errors
    assert sorted(os.listdir(tmp_path)) == ["fog_0001.exr"]   # no temporary left
    airlight = exr_pass(path, "Airlight")
    transmittance = exr_pass(path, "Transmittance")
    k = float(airlight[0, 0, 0])
    assert k in (1.0, 2.0, 3.0, 4.0)
    np.testing.assert_array_equal(airlight, np.float32(k))            # one writer's, whole
    np.testing.assert_array_equal(transmittance, np.float32(k) / np.float32(10))


def test_a_failed_write_leaves_nothing(tmp_path):
    path = str(tmp_path / "fog_0002.exr")
    bad = np.zeros((4, 4, 3), np.float32)
    try:
        cache.write_passes(path, bad, np.zeros((5, 4, 3), np.float32))   # shapes differ: refused
    except (cache.CacheError, ValueError):
        pass
    assert os.listdir(tmp_path) == []
