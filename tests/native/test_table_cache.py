"""The models' tables cached on disk across processes (native/core/table_cache.h).

Each check runs bakes in fresh Python processes (the cache is per process in memory, so
only a new process shows what the disk gives): a first process builds the tables it needs
and writes them; a second with the same folder builds none and bakes bit-identical passes;
corrupt, truncated or foreign files are refused with a note and rebuilt; two processes that
build one table at once both bake correctly and leave a valid entry."""
import json
import os
import subprocess
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))

# A bake that needs the F table, the surface G grid (body and tail: density 20 /m) and the
# sun glow table, then prints the table counts and a digest of the passes.
CHILD = r"""
import json, sys, hashlib
sys.path.insert(0, sys.argv[1]); sys.path.insert(0, sys.argv[2])
import numpy as np
import _native
from scene_util import camera_matrix, perspective, plane_z
v, t = plane_z(-5.0)
_native.set_table_cache_dir(sys.argv[3])
digest = hashlib.sha256()
for sigma in (0.1, 20.0):
    r = _native.bake(width=16, height=12, cam_to_world=camera_matrix(np.eye(3), np.zeros(3)),
                     projection=perspective(1.0, 16, 12), vertices=v, triangles=t,
                     light_positions=np.array([[0.5, 0.5, -3.0]]), light_intensities=np.ones((1, 3)),
                     sun_directions=np.array([[0.3, 0.2, -1.0]]), sun_irradiances=np.ones((1, 3)),
                     sigma_t=sigma, surface=True, threads=1)
    for key in ("airlight", "transmittance", "surface_glow"):
        digest.update(np.ascontiguousarray(r[key]).tobytes())
print(json.dumps(dict(_native.table_cache_counts(), digest=digest.hexdigest())))
"""


def native_dir():
    import _native
    return os.path.dirname(os.path.abspath(_native.__file__))


def run(cache, n=1):
    """_n_ child processes at once on the cache folder _cache_: their JSON lines and stderr."""
    procs = [subprocess.Popen([sys.executable, "-c", CHILD, native_dir(), HERE, str(cache)], stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True) for _ in range(n)]
    out = []
    for p in procs:
        stdout, stderr = p.communicate(timeout=600)
        assert p.returncode == 0, stderr
        out.append((json.loads(stdout.strip().splitlines()[-1]), stderr))
    return out


def entries(cache):
    return sorted(p for p in os.listdir(cache) if p.endswith(".table"))


def test_a_fresh_process_with_a_warm_cache_builds_no_table(tmp_path):
    (first, _), = run(tmp_path)
    assert first["built"] >= 3 and first["loaded"] == 0, first
    assert len(entries(tmp_path)) == first["built"]
    (second, _), = run(tmp_path)
    assert second["built"] == 0 and second["loaded"] == first["built"], second
    assert second["digest"] == first["digest"]          # the passes bit for bit
    assert not [p for p in os.listdir(tmp_path) if p.endswith(".tmp")]


def test_corrupt_truncated_and_foreign_files_are_rebuilt(tmp_path):
    (first, _), = run(tmp_path)
    names = entries(tmp_path)
    paths = [os.path.join(tmp_path, n) for n in names]
    with open(paths[0], "r+b") as f:          # a flipped byte in the values
        f.seek(-16, os.SEEK_END)
        byte = f.read(1)
        f.seek(-16, os.SEEK_END)
        f.write(bytes([byte[0] ^ 0xFF]))
    with open(paths[1], "r+b") as f:          # truncated
        f.truncate(os.path.getsize(paths[1]) // 2)
    with open(paths[2], "r+b") as f:          # another build's (its build hash)
        f.seek(8)
        f.write(b"\x00" * 8)
    (second, stderr), = run(tmp_path)
    assert second["refused"] == 3 and second["built"] == 3, (second, stderr)
    assert stderr.count("not used") == 3, stderr
    assert "checksum" in stderr and "truncated" in stderr and "another build" in stderr
    assert second["digest"] == first["digest"]
    (third, _), = run(tmp_path)                # rewritten: read again
    assert third["built"] == 0 and third["refused"] == 0, third


def test_two_processes_building_at_once(tmp_path):
    results = run(tmp_path, n=2)
    digests = {r["digest"] for r, _ in results}
    assert len(digests) == 1
    (after, _), = run(tmp_path)
    assert after["built"] == 0 and after["refused"] == 0 and after["digest"] in digests


def test_off_by_default_and_refuses_nul():
    import _native
    import pytest
    assert _native.table_cache_dir() == os.environ.get("AIRLIGHT_TABLE_CACHE", "")
    with pytest.raises(ValueError, match="NUL"):
        _native.set_table_cache_dir("a\0b")
