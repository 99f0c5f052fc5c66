"""Fog paintbrush and eraser modal operators (addon/airlight/brush_ops.py) driven by
synthetic events in a real window, plus undo/redo of the fog object operators.

Modal operators only receive events from Blender's event loop, which the GPU test
runner never enters (it exits when pytest returns). So this module starts a second
Blender (same Xvfb display) with --enable-event-simulate and runs ITSELF there as the
--python script: a bpy.app.timers generator invokes the operators in the 3D viewport,
feeds them Window.event_simulate() events one loop iteration at a time, records what
happened (JSON) and exits. The pytest side checks the record against expectations
computed independently (bpy_extras.view3d_utils for the view mapping, the Fogshop
spacing 0.75/a and offset bound 1/a).
"""

import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "support"))
import event_driver  # noqa: E402
from event_driver import fog_objects  # noqa: E402

SCALE = 2.0        # a (1/m): spacing 0.75/a = 0.375 m, offsets < 0.5 m
AMPLITUDE = 0.3
STROKE_PX = ((-150, 0), (150, 0))   # relative to the region centre
VIEW_DISTANCE = 10.0


# ---- the driver (runs in the child Blender) ---------------------------------------------

def _drive(out_path):

    import bpy
    import numpy as np

    from airlight import brush_ops, fog_object

    record = {}

    def steps():
        vp = event_driver.Viewport()
        override, ev, to_world = vp.override, vp.event, vp.to_world

        def st():  # the settings, looked up again: an undo replaces all data blocks
            return vp.scene.airlight_brush
        vp.top_view(VIEW_DISTANCE)
        vp.scene.cursor.location = (0.0, 0.0, 0.0)
        for _ in range(5):
            yield
        with override():
            bpy.ops.ed.undo_push(message="test setup")

        # 1. add fog object: undo removes it, redo brings it back. bpy.ops called from a
        # script does not push undo steps (measured: the stack is unchanged), so push as
        # the UI's call does; this checks that the object and its data are undoable.
        with override():
            bpy.ops.airlight.add_fog_object(scale=1.0, amplitude=0.1)
            bpy.ops.ed.undo_push(message="Airlight Fog Object")
        n_added = len(fog_objects())
        yield
        with override():
            bpy.ops.ed.undo()
        n_undone = len(fog_objects())
        yield
        with override():
            bpy.ops.ed.redo()
        yield
        record["add_undo_redo"] = [n_added, n_undone, len(fog_objects())]
        obj = fog_objects()[0]
        bpy.context.view_layer.objects.active = obj
        st().plane = 'GROUND'
        st().scale = SCALE
        st().amplitude = AMPLITUDE
        st().seed = 1
        with override():
            bpy.ops.ed.undo_push(message="brush settings")
        yield

        # 2. paint one stroke
        (x0, y0), (x1, y1) = STROKE_PX
        with override():
            record["paint_invoke"] = list(bpy.ops.airlight.fog_paint('INVOKE_DEFAULT'))
        ev('MOUSEMOVE', 'NOTHING', x0, y0)
        yield
        ev('LEFTMOUSE', 'PRESS', x0, y0)
        yield
        for k in range(1, 11):
            ev('MOUSEMOVE', 'NOTHING', x0 + (x1 - x0) * k / 10, y0 + (y1 - y0) * k / 10)
            yield
        record["handles_during_stroke"] = len(brush_ops._draw_handles)
        record["draws_during_stroke"] = brush_ops._draw_count[0]
        record["count_during_stroke"] = len(fog_objects()[0].data.vertices)
        ev('LEFTMOUSE', 'RELEASE', x1, y1)
        yield
        yield
        record["handles_after_stroke"] = len(brush_ops._draw_handles)
        obj = fog_objects()[0]
        centres, scales, amps = fog_object.read(obj)
        record["painted"] = dict(centres=centres.tolist(), scales=scales.tolist(), amplitudes=amps.tolist())
        record["stroke_world"] = [to_world(x0, y0).tolist(), to_world(x1, y1).tolist()]

        # 3. one undo removes the whole stroke, redo restores it
        with override():
            bpy.ops.ed.undo()
        yield
        record["count_after_undo"] = len(fog_objects()[0].data.vertices)
        with override():
            bpy.ops.ed.redo()
        yield
        record["count_after_redo"] = len(fog_objects()[0].data.vertices)

        # 4. Esc and right-click in the middle of a stroke leave no Gaussians
        for cancel in ('ESC', 'RIGHTMOUSE'):
            with override():
                bpy.ops.airlight.fog_paint('INVOKE_DEFAULT')
            ev('MOUSEMOVE', 'NOTHING', 0, 50)
            yield
            ev('LEFTMOUSE', 'PRESS', 0, 50)
            yield
            ev('MOUSEMOVE', 'NOTHING', 100, 80)
            yield
            ev(cancel, 'PRESS', 100, 80)
            yield
            yield
            record[f"cancel_{cancel}"] = [len(fog_objects()[0].data.vertices), len(brush_ops._draw_handles)]

        # 5. F (size) and Shift+F (strength): mouse x scales by 2^(dx/100); Esc restores
        with override():
            bpy.ops.airlight.fog_paint('INVOKE_DEFAULT')
        ev('MOUSEMOVE', 'NOTHING', 0, 0)
        yield
        ev('F', 'PRESS', 0, 0)
        yield
        ev('MOUSEMOVE', 'NOTHING', 100, 0)
        yield
        ev('LEFTMOUSE', 'PRESS', 100, 0)
        yield
        record["after_F_confirm"] = st().scale
        ev('F', 'PRESS', 100, 0)
        yield
        ev('MOUSEMOVE', 'NOTHING', 250, 0)
        yield
        record["during_F"] = st().scale
        ev('ESC', 'PRESS', 250, 0)
        yield
        record["after_F_escape"] = st().scale
        ev('F', 'PRESS', 250, 0, shift=True)
        yield
        ev('MOUSEMOVE', 'NOTHING', 150, 0)
        yield
        ev('RET', 'PRESS', 150, 0)
        yield
        record["after_shiftF_confirm"] = st().amplitude
        record["count_after_adjust"] = len(fog_objects()[0].data.vertices)
        ev('ESC', 'PRESS', 150, 0)  # leaves the operator
        yield
        yield
        record["handles_after_adjust"] = len(brush_ops._draw_handles)
        st().scale, st().amplitude = SCALE, AMPLITUDE

        # 6. eraser: one dab at the stroke's middle
        st().radius = 30.0
        st().strength = 10.0
        obj = fog_objects()[0]
        before_c, _, before_a = fog_object.read(obj)
        world = before_c @ np.array(obj.matrix_world)[:3, :3].T + np.array(obj.matrix_world)[:3, 3]
        record["erase_pixels"] = vp.pixels(world).tolist()
        record["erase_before"] = before_a.tolist()
        with override():
            bpy.ops.ed.undo_push(message="eraser settings")
        with override():
            bpy.ops.airlight.fog_erase('INVOKE_DEFAULT')
        ev('MOUSEMOVE', 'NOTHING', 0, 0)
        yield
        ev('LEFTMOUSE', 'PRESS', 0, 0)
        yield
        ev('LEFTMOUSE', 'RELEASE', 0, 0)
        yield
        yield
        _, _, after_a = fog_object.read(fog_objects()[0])
        record["erase_after"] = after_a.tolist()
        record["handles_after_erase"] = len(brush_ops._draw_handles)
        with override():
            bpy.ops.ed.undo()
        yield
        record["count_after_erase_undo"] = len(fog_objects()[0].data.vertices)

        # 7. the other planes: VIEW (top view: z = cursor z) and SURFACE (a floor at
        # z = 0.5, centres lifted by 1/a along its normal)
        with override():
            bpy.ops.mesh.primitive_plane_add(size=40.0, location=(0.0, 0.0, 0.5))
        bpy.context.view_layer.objects.active = fog_objects()[0]
        for plane, cursor_z in (('VIEW', -1.0), ('SURFACE', 3.0)):
            st().plane = plane
            vp.scene.cursor.location = (0.0, 0.0, cursor_z)
            n0 = len(fog_objects()[0].data.vertices)
            with override():
                bpy.ops.airlight.fog_paint('INVOKE_DEFAULT')
            ev('MOUSEMOVE', 'NOTHING', x0, 100)
            yield
            ev('LEFTMOUSE', 'PRESS', x0, 100)
            yield
            ev('MOUSEMOVE', 'NOTHING', x1, 100)
            yield
            ev('LEFTMOUSE', 'RELEASE', x1, 100)
            yield
            c, _, _ = fog_object.read(fog_objects()[0])
            record[f"plane_{plane}"] = dict(
                centres=c[n0:].tolist(),
                start=to_world(x0, 100).tolist())
        record["draws_total"] = brush_ops._draw_count[0]

    event_driver.run(steps(), record, out_path)


if __name__ == "__main__":
    event_driver.main(_drive)


# ---- the checks (pytest, in the GPU test Blender) ---------------------------------------
else:
    import numpy as np
    import pytest

    record = event_driver.record_fixture(__file__, "brush")

    def test01_add_fog_object_undo_redo(record):
        assert record["add_undo_redo"] == [1, 0, 1]

    def test02_paint_stroke_along_line(record):
        """Gaussians along the projected stroke: spacing 0.75/a along it (offsets are
        perpendicular, so the along-stroke coordinates are exact), perpendicular offsets
        < 1/a, scale and amplitude as set; appended only on release."""
        assert record["paint_invoke"] == ["RUNNING_MODAL"]
        assert record["count_during_stroke"] == 1  # nothing written while dragging
        p = record["painted"]
        c = np.array(p["centres"])[1:]
        a = np.array(p["scales"])[1:]
        amp = np.array(p["amplitudes"])[1:]
        w0, w1 = (np.array(w) for w in record["stroke_world"])
        length = np.linalg.norm(w1 - w0)
        t = (w1 - w0) / length
        assert abs(w0[2]) < 1e-9 and abs(w1[2]) < 1e-9 and length > 1.0
        expected_n = int(np.floor(length / (0.75 / SCALE) + 1e-9)) + 1
        print(f"\nstroke {length:.3f} m -> {len(c)} Gaussians (expected {expected_n})")
        assert len(c) == expected_n
        along = np.sort((c - w0) @ t)
        np.testing.assert_allclose(along, 0.75 / SCALE * np.arange(expected_n), atol=1e-4)
        perp = c - w0 - np.outer((c - w0) @ t, t)
        r = np.linalg.norm(perp, axis=1)
        assert r.max() < 1.0 / SCALE + 1e-6 and r.max() > 0.5 / SCALE
        np.testing.assert_allclose(a, SCALE, rtol=1e-6)
        np.testing.assert_allclose(amp, AMPLITUDE, rtol=1e-6)

    def test03_brush_circle_drawn_and_removed(record):
        assert record["handles_during_stroke"] == 1
        assert record["draws_during_stroke"] > 0 and record["draws_total"] > record["draws_during_stroke"]
        assert record["handles_after_stroke"] == 0

    def test04_one_undo_removes_the_stroke(record):
        n = len(record["painted"]["centres"])
        assert n > 1
        assert record["count_after_undo"] == 1
        assert record["count_after_redo"] == n

    @pytest.mark.parametrize("cancel", ["ESC", "RIGHTMOUSE"])
    def test05_cancel_leaves_no_gaussians(record, cancel):
        n = len(record["painted"]["centres"])
        assert record[f"cancel_{cancel}"] == [n, 0]

    def test06_f_and_shift_f_adjust(record):
        # F: radius 1/a doubled by +100 px -> a halved; Esc restores; Shift+F -100 px halves c
        assert record["after_F_confirm"] == pytest.approx(SCALE / 2.0, rel=1e-5)
        assert record["during_F"] == pytest.approx(SCALE / 2.0 / 2.0 ** 1.5, rel=1e-5)
        assert record["after_F_escape"] == pytest.approx(SCALE / 2.0, rel=1e-5)
        assert record["after_shiftF_confirm"] == pytest.approx(AMPLITUDE / 2.0, rel=1e-5)
        assert record["count_after_adjust"] == len(record["painted"]["centres"])
        assert record["handles_after_adjust"] == 0

    def test07_eraser_dab(record):
        """Strength 10 per dab, radius 30 px, smooth falloff (1 - (d/R)^2)^2: Gaussians
        whose centres project within the radius lose 10 f(d) (deleted at zero); the others
        are untouched. Pixels from view3d_utils, independent of brush_ops.project_points."""
        xy = np.array(record["erase_pixels"])
        before = np.array(record["erase_before"])
        d = np.linalg.norm(xy, axis=1)
        f = np.where(d < 30.0, (1.0 - np.minimum(d / 30.0, 1.0) ** 2) ** 2, 0.0)
        expected = np.maximum(before - 10.0 * f, 0.0)
        expected = expected[expected > 0.0]
        after = np.array(record["erase_after"])
        deleted = len(before) - len(after)
        print(f"\neraser: {deleted} of {len(before)} Gaussians deleted")
        assert deleted >= 3
        np.testing.assert_allclose(after, expected, rtol=1e-5, atol=1e-4)
        assert record["handles_after_erase"] == 0
        assert record["count_after_erase_undo"] == len(before)

    @pytest.mark.parametrize("plane,height", [("VIEW", -1.0), ("SURFACE", 0.5 + 1.0 / SCALE)])
    def test08_view_and_surface_planes(record, plane, height):
        """A horizontal stroke in the top view: on the view plane through the cursor
        (z = -1), and on the floor z = 0.5 lifted by 1/a; offsets < 1/a in the y-z plane."""
        rec = record[f"plane_{plane}"]
        c = np.array(rec["centres"])
        y0 = rec["start"][1]
        assert len(c) >= 5
        along = np.sort(c[:, 0] - c[:, 0].min())
        np.testing.assert_allclose(np.diff(along), 0.75 / SCALE, atol=1e-4)
        r = np.hypot(c[:, 1] - y0, c[:, 2] - height)
        assert r.max() < 1.0 / SCALE + 1e-6
        assert abs(np.mean(c[:, 2]) - height) < 0.5 / SCALE
