"""A worker that has the add-on but cannot load its compiled module (a different Python, a
missing library): `blender -b file -f N` renders the frame unfogged, equal to the render
with the fog off, and prints why; it came out magenta (the compositor's fog nodes were set
up on load and read an image nothing could bake). (The farm scripts fail such a task before
it renders: test_slurm.py, test_flamenco.py.)"""
import numpy as np

from conftest import FRAMES, read_frames, run, user_env


def test01_no_native_module_renders_unfogged_and_says_why(scene_file, broken_package, local_frames, tmp_path):
    env = user_env(tmp_path / "user", broken_package)
    out = tmp_path / "frames"
    proc = run(["blender", "-b", "--factory-startup", "--addons", "airlight", str(scene_file), "-o",
                str(out / "frame_####"), "-f", str(FRAMES[0])], env=env)
    assert f"Airlight: frame {FRAMES[0]} rendered without fog: The Airlight native module could not be loaded" \
        in proc.stdout, proc.stdout[-2000:]
    (frame,) = read_frames(str(out / "frame_*.exr")).values()
    np.testing.assert_array_equal(frame, local_frames["unfogged"][FRAMES[0]])
