"""The tables cached across Blender processes: a second `blender -b` bake of the example
street with the same cache folder builds no table and writes the same passes."""
import json
import os
import subprocess

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(os.path.dirname(HERE))
BLENDER_SH = os.path.join(REPO, "tools", "blender.sh")

SCRIPT = r"""
import bpy, json, sys
from airlight import native
scene = bpy.context.scene
scene.render.resolution_x, scene.render.resolution_y, scene.render.resolution_percentage = 96, 54, 100
s = scene.airlight
s.enabled = True
s.surface_shading = True
s.model = 'BIRI06'
s.anisotropy = 0.4
bpy.ops.airlight.bake(filepath=sys.argv[-1])
print("COUNTS " + json.dumps(native.get().table_cache_counts()))
"""


def bake(tmp_path, name):
    script = tmp_path / "bake.py"
    script.write_text(SCRIPT)
    out = tmp_path / f"{name}.exr"
    env = dict(os.environ, AIRLIGHT_TABLE_CACHE=str(tmp_path / "tables"))
    proc = subprocess.run([BLENDER_SH, "-b", os.path.join(REPO, "blend_examples", "street.blend"), "--python",
                           str(script), "--", str(out)], capture_output=True, text=True, timeout=600, env=env)
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    line = [l for l in proc.stdout.splitlines() if l.startswith("COUNTS ")][-1]
    return json.loads(line[len("COUNTS "):]), out


def test_second_process_builds_no_table(tmp_path):
    from conftest import exr_pass
    first, a = bake(tmp_path, "first")
    second, b = bake(tmp_path, "second")
    assert first["built"] >= 2 and first["loaded"] == 0, first     # Gamma, the phase G grid
    assert second["built"] == 0 and second["loaded"] == first["built"], second
    for name in ("Airlight", "Transmittance", "SurfaceGlow"):
        np.testing.assert_array_equal(exr_pass(str(b), name), exr_pass(str(a), name))
