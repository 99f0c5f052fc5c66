"""Airbrush modal operator (addon/airlight/airbrush.py) driven by synthetic events in a
real window (see event_driver.py): a held stroke adds Gaussians only on release, they stay
above the floor they were sprayed at (bounced, never through it), one undo removes them
all, Esc and right-click leave the object as it was, F adjusts the radius."""

import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "support"))
import event_driver  # noqa: E402
from event_driver import fog_objects  # noqa: E402

SCALE = 4.0
AMPLITUDE = 0.05
VIEW_DISTANCE = 12.0


def _drive(out_path):
    import time

    import bpy

    from airlight import brush_ops, fog_object

    record = {}

    def steps():
        vp = event_driver.Viewport()
        override, ev = vp.override, vp.event

        def st():
            return vp.scene.airlight_airbrush

        vp.top_view(VIEW_DISTANCE)
        scene = vp.scene
        with override():
            bpy.ops.mesh.primitive_plane_add(size=40.0, location=(0.0, 0.0, 0.0))
        fog = fog_object.new_fog_object("Fog", scene.collection, centres=[(0.0, 0.0, 5.0)],
                                        scales=1.0, amplitudes=0.1)
        for o in scene.objects:
            o.select_set(False)
        bpy.context.view_layer.objects.active = fog
        st().scale = SCALE
        st().amplitude = AMPLITUDE
        st().rate = 400.0
        st().speed = 4.0
        for _ in range(5):
            yield
        with override():
            bpy.ops.ed.undo_push(message="test setup")
        yield

        # 1. a held stroke: nothing is written until release
        with override():
            record["invoke"] = list(bpy.ops.airlight.airbrush('INVOKE_DEFAULT'))
        ev('MOUSEMOVE', 'NOTHING', 0, 0)
        yield
        ev('LEFTMOUSE', 'PRESS', 0, 0)
        yield
        t0 = time.perf_counter()
        for k in range(8):
            ev('MOUSEMOVE', 'NOTHING', 5 * k, 0)
            yield
        record["held_s"] = time.perf_counter() - t0
        record["handles_during"] = len(brush_ops._draw_handles)
        record["count_during"] = len(fog_objects()[0].data.vertices)
        ev('LEFTMOUSE', 'RELEASE', 35, 0)
        yield
        yield
        record["handles_after"] = len(brush_ops._draw_handles)
        c, a, amp = fog_object.read(fog_objects()[0])
        record["sprayed"] = dict(centres=c.tolist(), scales=a.tolist(), amplitudes=amp.tolist())

        # 2. one undo removes every particle, redo restores them
        with override():
            bpy.ops.ed.undo()
        yield
        record["count_after_undo"] = len(fog_objects()[0].data.vertices)
        with override():
            bpy.ops.ed.redo()
        yield
        record["count_after_redo"] = len(fog_objects()[0].data.vertices)

        # 3. Esc / right-click mid-stroke: the object is unchanged
        for cancel in ('ESC', 'RIGHTMOUSE'):
            before = [x.tolist() for x in fog_object.read(fog_objects()[0])]
            with override():
                bpy.ops.airlight.airbrush('INVOKE_DEFAULT')
            ev('MOUSEMOVE', 'NOTHING', 50, 50)
            yield
            ev('LEFTMOUSE', 'PRESS', 50, 50)
            yield
            ev('MOUSEMOVE', 'NOTHING', 60, 50)
            yield
            ev(cancel, 'PRESS', 60, 50)
            yield
            yield
            after = [x.tolist() for x in fog_object.read(fog_objects()[0])]
            record[f"cancel_{cancel}"] = [before == after, len(brush_ops._draw_handles)]

        # 4. F: +100 px doubles the radius 1/a
        with override():
            bpy.ops.airlight.airbrush('INVOKE_DEFAULT')
        ev('MOUSEMOVE', 'NOTHING', 0, 0)
        yield
        ev('F', 'PRESS', 0, 0)
        yield
        ev('MOUSEMOVE', 'NOTHING', 100, 0)
        yield
        ev('LEFTMOUSE', 'PRESS', 100, 0)
        yield
        record["after_F"] = st().scale
        ev('ESC', 'PRESS', 100, 0)
        yield
        yield
        record["handles_end"] = len(brush_ops._draw_handles)

    event_driver.run(steps(), record, out_path)


if __name__ == "__main__":
    event_driver.main(_drive)


else:
    import numpy as np
    import pytest

    record = event_driver.record_fixture(__file__, "airbrush")

    def test01_stroke_adds_gaussians_on_release(record):
        assert record["invoke"] == ["RUNNING_MODAL"]
        assert record["count_during"] == 1
        assert record["handles_during"] == 1 and record["handles_after"] == 0
        s = record["sprayed"]
        c = np.array(s["centres"])[1:]
        print(f"\nairbrush: {len(c)} particles in {record['held_s']:.2f} s held")
        assert len(c) >= 10
        np.testing.assert_allclose(np.array(s["scales"])[1:], SCALE, rtol=1e-6)
        np.testing.assert_allclose(np.array(s["amplitudes"])[1:], AMPLITUDE, rtol=1e-6)
        # sprayed at the floor z = 0 (started 1/a above it): bounced, never through it
        assert (c[:, 2] > 0.0).all()
        assert np.abs(c[:, :2]).max() < 20.0

    def test02_one_undo_removes_the_stroke(record):
        n = len(record["sprayed"]["centres"])
        assert record["count_after_undo"] == 1
        assert record["count_after_redo"] == n

    @pytest.mark.parametrize("cancel", ["ESC", "RIGHTMOUSE"])
    def test03_cancel_restores(record, cancel):
        assert record[f"cancel_{cancel}"] == [True, 0]

    def test04_f_adjusts_radius(record):
        assert record["after_F"] == pytest.approx(SCALE / 2.0, rel=1e-5)
        assert record["handles_end"] == 0
