"""Shared harness of the modal-tool tests that need real window events.

A test module runs ITSELF as the --python script of a second Blender started with
--enable-event-simulate (same Xvfb display): there, `main(drive)` hands `drive` the path
to write to; `drive` builds a generator of steps (it invokes modal operators in the
window's 3D viewport, `Viewport`, and feeds them Window.event_simulate() events) and
passes it to `run(steps, record, out_path)`, which steps it from a bpy.app.timers callback,
then writes `record` as JSON and exits. On the pytest side, `record_fixture(script, name)`
is the module's `record` fixture: it starts that Blender and returns the checked record.

    if __name__ == "__main__":
        event_driver.main(_drive)
    else:
        record = event_driver.record_fixture(__file__, "brush")
        def test01_...(record): ...
"""

import json
import os
import subprocess
import sys

REPO = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", ".."))


class Viewport:
    """In the child Blender: the first window's largest 3D viewport and its main region,
    with the events and context overrides the modal tools are driven by. Pixel offsets are
    relative to the region's centre."""

    def __init__(self):
        import bpy
        self.window = bpy.context.window_manager.windows[0]
        self.area = max((a for a in self.window.screen.areas if a.type == 'VIEW_3D'),
                        key=lambda a: a.width * a.height)
        self.region = next(r for r in self.area.regions if r.type == 'WINDOW')
        self.rv3d = self.area.spaces.active.region_3d

    @property
    def centre(self):
        return self.region.width // 2, self.region.height // 2

    @property
    def scene(self):  # looked up again: an undo replaces all data blocks
        return self.window.scene

    def override(self):
        """A context override that puts operators in this viewport's region."""
        import bpy
        return bpy.context.temp_override(window=self.window, screen=self.window.screen,
                                         area=self.area, region=self.region)

    def event(self, kind, value, px, py, shift=False, ctrl=False):
        """Window.event_simulate at _px_, _py_ pixels from the region's centre."""
        cx, cy = self.centre
        self.window.event_simulate(kind, value, x=int(self.region.x + cx + px), y=int(self.region.y + cy + py),
                                   shift=shift, ctrl=ctrl)

    def top_view(self, distance):
        """An empty scene seen from the top (orthographic, looking down -Z at the origin)."""
        from mathutils import Quaternion
        import bpy
        for obj in list(self.scene.objects):
            bpy.data.objects.remove(obj)
        self.rv3d.view_perspective = 'ORTHO'
        self.rv3d.view_rotation = Quaternion((1.0, 0.0, 0.0, 0.0))
        self.rv3d.view_location = (0.0, 0.0, 0.0)
        self.rv3d.view_distance = distance

    def to_world(self, px, py):
        """The point of the view plane through the origin at pixel offset (px, py)."""
        import numpy as np
        from bpy_extras import view3d_utils
        cx, cy = self.centre
        return np.array(view3d_utils.region_2d_to_location_3d(self.region, self.rv3d, (cx + px, cy + py), (0, 0, 0)))

    def pixels(self, points):
        """Pixel offsets from the region's centre of world _points_ (view3d_utils)."""
        import numpy as np
        from bpy_extras import view3d_utils
        return np.array([view3d_utils.location_3d_to_region_2d(self.region, self.rv3d, p) for p in points]) \
            - np.array(self.centre)


def fog_objects():
    """The file's fog objects by name (looked up again each time: an undo replaces them)."""
    import bpy
    from airlight import fog_object
    return sorted((o for o in bpy.data.objects if fog_object.is_fog_object(o)), key=lambda o: o.name)


def run(gen, record, out_path):
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


def main(drive):
    """The child Blender's entry: drive(out_path) with the path after `--`."""
    drive(sys.argv[sys.argv.index("--") + 1])


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


def record_fixture(script, name):
    """The module-scoped `record` fixture of a modal-tool test module: run_child(_script_)."""
    import pytest

    @pytest.fixture(scope="module")
    def record(tmp_path_factory):
        return run_child(script, tmp_path_factory.mktemp(name))
    return record
