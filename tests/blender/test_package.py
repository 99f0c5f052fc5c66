"""The installable zip (`make package`, tools/package.py) as a user installs it: into a
clean Blender (its own user folders, factory settings) through Preferences > Add-ons >
Install, then enabled, a saved scene opened and rendered with `-f`. Its fog passes must be
those of the add-on under test here, and the GLSL sources must travel with it."""
import glob
import importlib.util
import os
import subprocess
import zipfile

import bpy
import numpy as np

from conftest import REPO, build_plane_scene, exr_pass

_spec = importlib.util.spec_from_file_location("airlight_package", os.path.join(REPO, "tools", "package.py"))
package = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(package)

# Runs inside the clean Blender: install the zip, enable it, open the scene, render frame 1.
INSTALL = """
import sys, bpy
zip_path, blend = sys.argv[sys.argv.index("--") + 1:]
assert bpy.ops.preferences.addon_install(filepath=zip_path) == {'FINISHED'}
assert bpy.ops.preferences.addon_enable(module="airlight") == {'FINISHED'}
import airlight, airlight.gpu_shaders
print("INSTALLED", airlight.__file__)
bpy.ops.wm.open_mainfile(filepath=blend)
bpy.ops.render.render(write_still=True)
"""


def test01_zip_installs_into_a_clean_blender_and_bakes_the_same_fog(tmp_path):
    zip_path = str(tmp_path / "airlight.zip")
    names = package.make_zip(zip_path)
    with zipfile.ZipFile(zip_path) as zf:
        members = set(zf.namelist())
        assert zf.testzip() is None
    assert members == set(names)
    assert all(n.startswith("airlight/") for n in members)
    assert "airlight/__init__.py" in members
    assert any(n.startswith("airlight/_native") and n.endswith(".so") for n in members)
    assert not any("__pycache__" in n or n.endswith(".pyc") for n in members)
    shaders = {os.path.basename(p) for p in glob.glob(os.path.join(REPO, "shaders", "*.glsl"))}
    assert shaders and {f"airlight/shaders/{s}" for s in shaders} <= members

    scene = build_plane_scene(tmp_path, size=(48, 32))
    scene.camera.location = (0.0, -6.0, 1.5)
    scene.camera.rotation_euler = (1.35, 0.0, 0.0)
    scene.render.engine = 'CYCLES'
    scene.cycles.samples = 1
    scene.cycles.use_denoising = False
    scene.cycles.device = 'CPU'
    scene.render.filepath = str(tmp_path / "render_")
    scene.airlight.density = 0.1
    bpy.ops.airlight.setup_compositor()
    blend = str(tmp_path / "scene.blend")
    bpy.ops.wm.save_as_mainfile(filepath=blend)
    reference = str(tmp_path / "reference.exr")
    assert bpy.ops.airlight.bake(frame=1, filepath=reference) == {'FINISHED'}

    user = tmp_path / "clean_user"
    env = dict(os.environ, BLENDER_USER_SCRIPTS=str(user / "scripts"), BLENDER_USER_CONFIG=str(user / "config"))
    script = tmp_path / "install.py"
    script.write_text(INSTALL)
    proc = subprocess.run([os.environ.get("BLENDER", "blender"), "-b", "--factory-startup", "--python",
                           str(script), "--", zip_path, blend], capture_output=True, text=True, timeout=180,
                          env=env)
    log = proc.stdout[-3000:] + proc.stderr[-3000:]
    assert proc.returncode == 0, log
    installed = os.path.join(str(user / "scripts"), "addons", "airlight")
    assert f"INSTALLED {os.path.join(installed, '__init__.py')}" in proc.stdout, log
    assert "Airlight: fog of frame 1 baked" in proc.stdout, log
    # The installed copy finds its shaders inside itself (gpu_shaders.py's search path).
    for s in shaders:
        assert os.path.isfile(os.path.join(installed, "shaders", s))

    baked = str(tmp_path / "cache" / "fog_0001.exr")
    for name in ("Airlight", "Transmittance"):
        ours, theirs = exr_pass(reference, name), exr_pass(baked, name)
        np.testing.assert_allclose(theirs, ours, rtol=1e-6, atol=1e-7)
    assert exr_pass(baked, "Airlight").max() > 1e-3 and exr_pass(baked, "Transmittance").min() < 0.99


def test02_package_without_the_compiled_module_says_so(tmp_path, monkeypatch):
    empty = tmp_path / "addon"
    empty.mkdir()
    (empty / "__init__.py").write_text("")
    monkeypatch.setattr(package, "ADDON", str(empty))
    out = str(tmp_path / "airlight.zip")
    try:
        package.make_zip(out)
    except FileNotFoundError as e:
        assert "make build" in str(e)
    else:
        raise AssertionError("make_zip accepted an add-on without _native")
    assert not os.path.exists(out)
    assert package.main([out]) == 1 and not os.path.exists(out)
