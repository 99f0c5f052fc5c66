"""Shared harness of the modal-tool tests that need real window events.

A test module runs ITSELF as the --python script of a second Blender started with
--enable-event-simulate (same Xvfb display): there, `drive(steps, record, out_path)`
steps a generator from a bpy.app.timers callback (the generator invokes modal operators
and feeds them Window.event_simulate() events), then writes `record` as JSON and exits.
On the pytest side, `run_child(script, tmp_dir)` starts that Blender and returns the
checked record.
"""

import json
import os
import subprocess
import sys

REPO = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", ".."))


def drive(gen, record, out_path):
    """In the child Blender: run generator `gen` one step per timer tick, then dump
    `record` (with "done" or the traceback under "error") to `out_path` and exit."""
    import traceback

    import bpy

    def tick():
        try:
            next(gen)
            return 0.05
        except StopIteration:
            record["done"] = True
        except Exception:
            record["error"] = traceback.format_exc()
        with open(out_path, "w") as f:
            json.dump(record, f)
        sys.stdout.flush()
        os._exit(0)

    bpy.app.timers.register(tick, first_interval=1.0)


def run_child(script, tmp_dir):
    """In pytest: run `script` in an event-simulating Blender; returns its record and
    fails the test with the child's output if it recorded nothing or an error."""
    import pytest

    out = os.path.join(str(tmp_dir), "record.json")
    cmd = [os.path.join(REPO, "tools", "blender.sh"), "--enable-event-simulate",
           "--python", os.path.abspath(script), "--", out]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=240)
    if not os.path.exists(out):
        pytest.fail(f"event driver wrote nothing (rc {proc.returncode}):\n"
                    f"{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}")
    with open(out) as f:
        rec = json.load(f)
    assert "error" not in rec, rec["error"]
    assert rec.get("done"), rec
    return rec
