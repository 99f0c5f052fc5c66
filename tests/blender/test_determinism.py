"""Determinism of the example street (blend_examples/street.blend, what `make demo` renders):
its frame baked by bpy.ops.airlight.bake with Threads 1 and 2 in this Blender, and in another
Blender process (a farm worker), gives the same EXR passes bit for bit. (The native paths one
by one: tests/native/test_bake_determinism.py; the bound across CPUs that pick different
SIMD clones: docs/architecture.md, "Determinism".)"""
import os

import bpy
import numpy as np

from conftest import REPO, read_exr, run_blender

STREET = os.path.join(REPO, "blend_examples", "street.blend")


def _open_street(tmp_path):
    bpy.ops.wm.open_mainfile(filepath=STREET)
    scene = bpy.context.scene
    scene.airlight.cache_dir = str(tmp_path / "cache") + os.sep  # not next to the example
    scene.airlight.auto_composite = False
    return scene


def test01_threads_and_processes_give_the_same_bits(tmp_path):
    scene = _open_street(tmp_path)
    paths = {}
    for threads in (1, 2):
        scene.airlight.threads = threads
        paths[threads] = str(tmp_path / f"threads{threads}.exr")
        assert bpy.ops.airlight.bake(filepath=paths[threads]) == {'FINISHED'}
    child = str(tmp_path / "child.exr")
    script = tmp_path / "child_bake.py"
    script.write_text("import bpy, sys\n"
                      f"s = bpy.context.scene\ns.airlight.cache_dir = {str(tmp_path / 'child_cache') + os.sep!r}\n"
                      "s.airlight.auto_composite = False\ns.airlight.threads = 2\n"
                      f"sys.exit(0 if bpy.ops.airlight.bake(filepath={child!r}) == {{'FINISHED'}} else 1)\n")
    proc = run_blender(STREET, "--python-exit-code", "1", "--python", str(script))
    assert proc.returncode == 0 and os.path.exists(child), proc.stdout[-3000:] + proc.stderr[-3000:]
    reference, names = read_exr(paths[1])
    assert "Fog.Airlight.R" in names and len(names) > 6  # surface shading passes too
    assert reference[..., names.index("Fog.Airlight.R")].max() > 0.0
    for label, path in (("threads=2", paths[2]), ("another process", child)):
        pixels, other_names = read_exr(path)
        assert other_names == names, label
        assert pixels.tobytes() == reference.tobytes(), (
            f"{label}: differs in {int((pixels != reference).sum())} values, "
            f"max {float(np.abs(pixels - reference).max())}")
