"""Slurm: tools/slurm_render.sh on a single-node cluster started here (support/
slurm_cluster.py), against the same frames rendered locally.

- test01: 4 frames in 2 array tasks of 2 (chunk 2), each task installing the package into
  its own Blender user folder: every frame equals the local `-a` render, bit for bit (same
  machine, same build).
- test02: a package without its compiled module: each task checks the add-on first and
  FAILS (exit 1, the reason in its log), and no frame is written.
- test03: the submitter refuses bad arguments before sbatch (a missing file or package, an
  empty range) with a message.
"""
import os
import subprocess

import numpy as np
import pytest

import slurm_cluster
from conftest import FRAMES, REPO, read_frames, run

SCRIPT = os.path.join(REPO, "tools", "slurm_render.sh")


@pytest.fixture(scope="module")
def cluster(tmp_path_factory):
    why = slurm_cluster.missing()
    if why:
        pytest.fail(f"cannot start the test cluster: {why}", pytrace=False)
    with slurm_cluster.Cluster(tmp_path_factory.mktemp("slurm")) as c:
        yield c


def submit(cluster, scene_file, package, out, logs, chunk=2):
    proc = run([SCRIPT, str(scene_file), str(FRAMES[0]), str(FRAMES[1]), "--chunk", str(chunk), "--package",
                str(package), "--output", str(out / "frame_####"), "--", f"--output={logs}/task_%A_%a.log"],
               env=cluster.env)
    return int(proc.stdout.strip().split(";")[0])


def test01_array_frames_equal_the_local_render(cluster, scene_file, package, local_frames, tmp_path):
    out, logs = tmp_path / "frames", tmp_path / "logs"
    out.mkdir(), logs.mkdir()
    job = submit(cluster, scene_file, package, out, logs)
    tasks = cluster.wait(job)
    text = "\n".join(open(logs / name).read() for name in sorted(os.listdir(logs)))
    assert len(tasks) == 2, tasks
    assert all(t.get("JobState") == "COMPLETED" and t.get("ExitCode") == "0:0" for t in tasks), (tasks, text)
    frames, local = read_frames(str(out / "frame_*.exr")), local_frames["fogged"]
    assert sorted(frames) == sorted(local), (sorted(frames), text)
    for f, img in frames.items():
        assert np.array_equal(img, local[f]), f"frame {f}: max diff {np.abs(img - local[f]).max()}"
    assert text.count("renders frames") == 2


def test02_a_task_without_the_native_module_fails(cluster, scene_file, broken_package, tmp_path):
    broken = broken_package
    out, logs = tmp_path / "frames", tmp_path / "logs"
    out.mkdir(), logs.mkdir()
    tasks = cluster.wait(submit(cluster, scene_file, broken, out, logs))
    text = "\n".join(open(logs / name).read() for name in sorted(os.listdir(logs)))
    assert len(tasks) == 2 and all(t.get("JobState") == "FAILED" for t in tasks), (tasks, text)
    assert text.count("did not load") == 2, text
    assert "native module" in text, text
    assert not list(out.iterdir())


@pytest.mark.parametrize("args,message", [
    (["missing.blend", "1", "4"], "no such .blend file"),
    (["SCENE", "4", "1"], "is before START"),
    (["SCENE", "1", "4", "--package", "missing.zip"], "no add-on package"),
    (["SCENE", "1", "x"], "must be integers"),
])
def test03_bad_arguments_are_refused(scene_file, args, message):
    args = [str(scene_file) if a == "SCENE" else a for a in args]
    proc = subprocess.run([SCRIPT, *args], capture_output=True, text=True)
    assert proc.returncode == 2 and message in proc.stderr, (proc.returncode, proc.stderr)
