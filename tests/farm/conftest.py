"""The farm tests run in plain Python (/usr/bin/python3 -m pytest tests/farm): they start
Blender, Slurm and node themselves as subprocesses. Shared: the repository's paths, a fresh
add-on package, the animated fog scene and its local reference render."""
import glob
import os
import subprocess
import sys

import numpy as np
import pytest

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.normpath(os.path.join(HERE, "..", ".."))
sys.path.insert(0, os.path.join(HERE, "support"))
BLENDER_SH = os.path.join(REPO, "tools", "blender.sh")
FRAMES = (1, 4)


def run(cmd, **kw):
    """Runs _cmd_, failing the test with its output when it exits non-zero."""
    proc = subprocess.run(cmd, capture_output=True, text=True, **kw)
    if proc.returncode != 0:
        pytest.fail(f"{cmd[0]} exited {proc.returncode}:\n{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}",
                    pytrace=False)
    return proc


def read_frames(pattern):
    """{frame: (H, W, C) float32} of the EXR files matching _pattern_ (a glob), by frame number."""
    import OpenImageIO as oiio
    out = {}
    for path in sorted(glob.glob(pattern)):
        frame = int(os.path.splitext(os.path.basename(path))[0].split("_")[-1])
        buf = oiio.ImageBuf(path)
        assert not buf.has_error, buf.geterror()
        out[frame] = buf.get_pixels(oiio.FLOAT)
    return out


@pytest.fixture(scope="session")
def package(tmp_path_factory):
    """A zip of the add-on as built now (tools/package.py: the compiled module included)."""
    path = tmp_path_factory.mktemp("package") / "airlight.zip"
    run([sys.executable, os.path.join(REPO, "tools", "package.py"), str(path)])
    return path


@pytest.fixture(scope="session")
def broken_package(package, tmp_path_factory):
    """The package without its compiled module (a worker whose Python cannot load it)."""
    import zipfile
    path = tmp_path_factory.mktemp("broken") / "airlight.zip"
    with zipfile.ZipFile(package) as src, zipfile.ZipFile(path, "w") as dst:
        for item in src.infolist():
            if "_native" not in item.filename:
                dst.writestr(item, src.read(item))
    return path


def user_env(folder, package=None):
    """Environment for a Blender whose user folder _folder_ holds the add-on unpacked from
    _package_ (None: no add-on)."""
    import zipfile
    addons = folder / "scripts" / "addons"
    addons.mkdir(parents=True)
    (folder / "config").mkdir()
    if package is not None:
        with zipfile.ZipFile(package) as z:
            z.extractall(addons)
    return dict(os.environ, BLENDER_USER_SCRIPTS=str(folder / "scripts"), BLENDER_USER_CONFIG=str(folder / "config"))


@pytest.fixture(scope="session")
def scene_file(tmp_path_factory):
    """The animated fog scene (support/make_anim.py), on 'shared storage' (a temp folder)."""
    folder = tmp_path_factory.mktemp("shared")
    path = folder / "anim.blend"
    run([BLENDER_SH, "-b", "--python", os.path.join(HERE, "support", "make_anim.py"), "--", str(path)])
    return path


@pytest.fixture(scope="session")
def local_frames(scene_file, tmp_path_factory):
    """Frames 1-4 rendered on this machine with `-a` (tools/blender.sh: the add-on linked from
    the repository), and the same with the fog off, to show the fog is there."""
    out = tmp_path_factory.mktemp("local")
    run([BLENDER_SH, "-b", str(scene_file), "-o", str(out / "frame_####"), "-s", str(FRAMES[0]),
         "-e", str(FRAMES[1]), "-a"])
    off = tmp_path_factory.mktemp("local_off")
    run([BLENDER_SH, "-b", str(scene_file), "--python-expr", "import bpy; bpy.context.scene.airlight.enabled = False",
         "-o", str(off / "frame_####"), "-s", str(FRAMES[0]), "-e", str(FRAMES[1]), "-a"])
    frames, unfogged = read_frames(str(out / "frame_*.exr")), read_frames(str(off / "frame_*.exr"))
    assert sorted(frames) == list(range(FRAMES[0], FRAMES[1] + 1)), sorted(frames)
    for f in frames:
        assert np.abs(frames[f] - unfogged[f]).mean() > 0.01 * np.abs(unfogged[f]).mean() + 1e-4, \
            f"frame {f}: the fog is missing from the local render"
    assert np.abs(frames[1] - frames[4]).mean() > 1e-3, "the light's move changes nothing"
    return dict(fogged=frames, unfogged=unfogged)
