"""Flamenco 3: tools/flamenco/airlight_render.js, compiled by node through a harness of the
Manager's job-compiler API (support/flamenco_harness.js: author.Task / Command,
frameChunker, path, print), and its commands run as a Flamenco worker runs a
`blender-render` command: {blender} {blenderArgs} argsBefore blendfile args, with the
Manager's default blenderArgs "-b -y". Flamenco itself (Manager, Worker) is not run here.

- test01: frames 1-4 in chunks of 2 compile to two render tasks whose Blender loads the
  add-on, checks it and renders its frames; run with the package installed in a Blender
  user folder, they give the local `-a` render's frames bit for bit.
- test02: the same commands on a worker without the add-on exit 1 with the reason and write
  no frame (Flamenco fails the task).
- test03: bad settings (no frames, chunk 0, a video format) are refused by compileJob.
"""
import json
import os
import shutil
import subprocess

import numpy as np
import pytest

from conftest import FRAMES, HERE, REPO, read_frames, run, user_env

JOB_TYPE = os.path.join(REPO, "tools", "flamenco", "airlight_render.js")
HARNESS = os.path.join(HERE, "support", "flamenco_harness.js")
BLENDER_ARGS = ["-b", "-y"]  # the Manager's default {blenderArgs}


def compile_job(tmp_path, **settings):
    node = shutil.which("node")
    if node is None:
        pytest.fail("node not found: install nodejs (tools/install_deps.sh)", pytrace=False)
    path = tmp_path / "settings.json"
    path.write_text(json.dumps(settings))
    return json.loads(run([node, HARNESS, JOB_TYPE, str(path)]).stdout)


def worker_argv(command):
    """The command line a Flamenco worker runs for a blender-render command."""
    p = command["parameters"]
    assert p["exe"] == "{blender}" and p["exeArgs"] == "{blenderArgs}"
    return ["blender", *BLENDER_ARGS, *p["argsBefore"], p["blendfile"], *p["args"]]


def settings_for(scene_file, out):
    return dict(frames=f"{FRAMES[0]}-{FRAMES[1]}", chunk_size=2, render_output_root=str(out),
                render_output_path=str(out / "frame_####"), blendfile=str(scene_file), format="OPEN_EXR")


def test01_compiled_tasks_render_the_local_frames(scene_file, package, local_frames, tmp_path):
    out = tmp_path / "frames"
    job = compile_job(tmp_path, **settings_for(scene_file, out))
    assert job["label"] == "Airlight Render" and "error" not in job, job
    assert [t["name"] for t in job["tasks"]] == ["render-1-2", "render-3-4"]
    env = user_env(tmp_path / "user", package)
    for task in job["tasks"]:
        (command,) = task["commands"]
        assert command["type"] == "blender-render"
        argv = worker_argv(command)
        assert argv.index("--addons") < argv.index(str(scene_file)) < argv.index("--python-expr") \
            < argv.index("--render-frame")
        proc = run(argv, env=env)
        assert "Airlight: add-on and native module loaded" in proc.stdout
    frames, local = read_frames(str(out / "frame_*.exr")), local_frames["fogged"]
    assert sorted(frames) == sorted(local)
    for f, img in frames.items():
        assert np.array_equal(img, local[f]), f"frame {f}: max diff {np.abs(img - local[f]).max()}"


def test02_a_worker_without_the_addon_fails_the_task(scene_file, tmp_path):
    out = tmp_path / "frames"
    job = compile_job(tmp_path, **settings_for(scene_file, out))
    env = user_env(tmp_path / "user")
    for task in job["tasks"]:
        proc = subprocess.run(worker_argv(task["commands"][0]), env=env, capture_output=True, text=True)
        assert proc.returncode == 1, (proc.returncode, proc.stdout[-2000:])
        assert "No module named 'airlight'" in proc.stdout + proc.stderr
    assert not out.exists() or not list(out.iterdir())


@pytest.mark.parametrize("change,message", [
    (dict(frames=""), "no frames"),
    (dict(chunk_size=0), "chunk_size must be at least 1"),
    (dict(format="FFMPEG"), "renders images"),
    (dict(frames="4-1"), "invalid frame range"),
])
def test03_bad_settings_are_refused(scene_file, tmp_path, change, message):
    job = compile_job(tmp_path, **dict(settings_for(scene_file, tmp_path / "frames"), **change))
    assert message in job.get("error", ""), job
