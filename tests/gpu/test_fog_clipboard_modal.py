"""Fog rectangle selection and move (addon/airlight/fog_clipboard.py) driven by synthetic
events in a real window, as in test_brush_ops_modal.py: this module starts a second Blender
(same Xvfb display) with --enable-event-simulate and runs ITSELF there as the --python
script; a bpy.app.timers generator invokes the modal operators in the 3D viewport, feeds
them Window.event_simulate() events, records what happened (JSON) and exits. The pytest
side checks the record against expectations from bpy_extras.view3d_utils (independent of
fog_clipboard's own projection).
"""

import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "support"))
import event_driver  # noqa: E402

N = 60
RECT_PX = ((-110.0, -70.0), (90.0, 60.0))    # relative to the region centre
ADD_RECT_PX = ((100.0, 70.0), (180.0, 140.0))
MOVE_PX = ((10.0, 5.0), (110.0, -45.0))       # mouse at invoke, mouse at confirm
VIEW_DISTANCE = 12.0


# ---- the driver (runs in the child Blender) ---------------------------------------------

def _drive(out_path):

    import bpy
    import numpy as np

    from airlight import fog_clipboard, fog_object

    record = {}

    def steps():
        vp = event_driver.Viewport()
        override, ev = vp.override, vp.event

        def fog():  # looked up again: an undo replaces all data blocks
            return bpy.data.objects["Fog"]

        def world_centres():
            obj = fog()
            c, _, _ = fog_object.read(obj)
            m = np.array(obj.matrix_world)
            return c @ m[:3, :3].T + m[:3, 3]

        vp.top_view(VIEW_DISTANCE)
        scene = vp.scene
        rng = np.random.default_rng(5)
        local = rng.uniform(-2.5, 2.5, (N, 3))
        obj = fog_object.new_fog_object("Fog", scene.collection, local, rng.uniform(0.5, 2.0, N),
                                        rng.uniform(0.1, 1.0, N), location=(0.5, -0.3, 1.0))
        obj.rotation_euler = (0.0, 0.0, 0.4)
        obj.scale = (1.5, 1.5, 1.5)
        bpy.context.view_layer.objects.active = obj
        obj.select_set(True)
        for _ in range(5):
            yield
        with override():
            bpy.ops.ed.undo_push(message="test setup")
        record["pixels"] = vp.pixels(world_centres()).tolist()
        record["region"] = [vp.region.width, vp.region.height]

        # 1. drag a rectangle
        (x0, y0), (x1, y1) = RECT_PX
        with override():
            record["select_invoke"] = list(bpy.ops.airlight.fog_select_rect('INVOKE_DEFAULT'))
        ev('MOUSEMOVE', 'NOTHING', x0, y0)
        yield
        ev('LEFTMOUSE', 'PRESS', x0, y0)
        yield
        for k in range(1, 6):
            ev('MOUSEMOVE', 'NOTHING', x0 + (x1 - x0) * k / 5, y0 + (y1 - y0) * k / 5)
            yield
        record["handles_during_drag"] = len(fog_clipboard._draw_handles)
        record["draws_during_drag"] = fog_clipboard._draw_count[0]
        ev('LEFTMOUSE', 'RELEASE', x1, y1)
        yield
        yield
        record["handles_after_drag"] = len(fog_clipboard._draw_handles)
        record["selected"] = fog_clipboard.read_selection(fog()).tolist()

        # 2. Esc during a second drag keeps the selection
        with override():
            bpy.ops.airlight.fog_select_rect('INVOKE_DEFAULT')
        ev('MOUSEMOVE', 'NOTHING', -150, -120)
        yield
        ev('LEFTMOUSE', 'PRESS', -150, -120)
        yield
        ev('MOUSEMOVE', 'NOTHING', 150, 120)
        yield
        ev('ESC', 'PRESS', 150, 120)
        yield
        yield
        record["selected_after_esc"] = fog_clipboard.read_selection(fog()).tolist()
        record["handles_after_esc"] = len(fog_clipboard._draw_handles)

        # 3. Shift+drag adds a second rectangle
        (a0, b0), (a1, b1) = ADD_RECT_PX
        with override():
            bpy.ops.airlight.fog_select_rect('INVOKE_DEFAULT')
        ev('MOUSEMOVE', 'NOTHING', a0, b0, shift=True)
        yield
        ev('LEFTMOUSE', 'PRESS', a0, b0, shift=True)
        yield
        ev('MOUSEMOVE', 'NOTHING', a1, b1, shift=True)
        yield
        ev('LEFTMOUSE', 'RELEASE', a1, b1, shift=True)
        yield
        yield
        record["selected_added"] = fog_clipboard.read_selection(fog()).tolist()
        # back to the first selection for the move
        fog_clipboard.write_selection(fog(), np.array(record["selected"], dtype=bool))
        with override():
            bpy.ops.ed.undo_push(message="selection")
        yield

        # 4. move, then Esc: everything back where it was
        before = world_centres()
        record["before_move"] = before.tolist()
        (m0, n0), (m1, n1) = MOVE_PX
        ev('MOUSEMOVE', 'NOTHING', m0, n0)
        yield
        with override():
            record["move_invoke"] = list(bpy.ops.airlight.fog_move('INVOKE_DEFAULT'))
        ev('MOUSEMOVE', 'NOTHING', (m0 + m1) / 2, (n0 + n1) / 2)
        yield
        ev('MOUSEMOVE', 'NOTHING', m1, n1)
        yield
        record["during_move"] = world_centres().tolist()
        record["handles_during_move"] = len(fog_clipboard._draw_handles)
        ev('ESC', 'PRESS', m1, n1)
        yield
        yield
        record["after_move_esc"] = world_centres().tolist()
        record["handles_after_move_esc"] = len(fog_clipboard._draw_handles)

        # 5. move and confirm with a click; one undo restores, redo moves again
        ev('MOUSEMOVE', 'NOTHING', m0, n0)
        yield
        with override():
            bpy.ops.airlight.fog_move('INVOKE_DEFAULT')
        ev('MOUSEMOVE', 'NOTHING', m1, n1)
        yield
        ev('LEFTMOUSE', 'PRESS', m1, n1)
        yield
        yield
        ev('LEFTMOUSE', 'RELEASE', m1, n1)
        yield
        record["after_move"] = world_centres().tolist()
        record["selected_after_move"] = fog_clipboard.read_selection(fog()).tolist()
        record["handles_after_move"] = len(fog_clipboard._draw_handles)
        record["move_offset"] = (vp.to_world(m1, n1) - vp.to_world(m0, n0)).tolist()
        with override():
            bpy.ops.ed.undo()
        yield
        record["after_undo"] = world_centres().tolist()
        with override():
            bpy.ops.ed.redo()
        yield
        record["after_redo"] = world_centres().tolist()
        record["draws_total"] = fog_clipboard._draw_count[0]

    event_driver.run(steps(), record, out_path)


if __name__ == "__main__":
    event_driver.main(_drive)


# ---- the checks (pytest, in the GPU test Blender) ---------------------------------------
else:
    import numpy as np

    record = event_driver.record_fixture(__file__, "clipboard")

    def _inside(xy, rect):
        (x0, y0), (x1, y1) = rect
        return ((xy[:, 0] >= min(x0, x1)) & (xy[:, 0] <= max(x0, x1))
                & (xy[:, 1] >= min(y0, y1)) & (xy[:, 1] <= max(y0, y1)))

    def test01_rectangle_selects_projected_centres(record):
        """The selection is exactly the centres whose view3d_utils pixels lie in the dragged
        rectangle (none within 0.5 px of an edge, so rounding cannot decide)."""
        assert record["select_invoke"] == ["RUNNING_MODAL"]
        xy = np.array(record["pixels"])
        (x0, y0), (x1, y1) = RECT_PX
        edge = np.minimum.reduce([np.abs(xy[:, 0] - x0), np.abs(xy[:, 0] - x1),
                                  np.abs(xy[:, 1] - y0), np.abs(xy[:, 1] - y1)])
        assert edge.min() > 0.5
        expected = _inside(xy, RECT_PX)
        selected = np.array(record["selected"])
        print(f"\nrectangle: {selected.sum()} of {len(selected)} Gaussians selected")
        assert 5 <= expected.sum() <= N - 5
        np.testing.assert_array_equal(selected, expected)

    def test02_rectangle_drawn_and_handler_removed(record):
        assert record["handles_during_drag"] == 1
        assert record["draws_during_drag"] > 0
        assert record["handles_after_drag"] == 0
        assert record["handles_after_esc"] == 0
        assert record["draws_total"] > record["draws_during_drag"]

    def test03_esc_keeps_selection_and_shift_adds(record):
        assert record["selected_after_esc"] == record["selected"]
        xy = np.array(record["pixels"])
        expected = _inside(xy, RECT_PX) | _inside(xy, ADD_RECT_PX)
        np.testing.assert_array_equal(record["selected_added"], expected)

    def test04_move_follows_mouse_and_esc_restores(record):
        """Selected centres move by the view-plane offset between the mouse positions (top
        ortho view: the world offset of the two pixels); the others stay; Esc restores."""
        assert record["move_invoke"] == ["RUNNING_MODAL"]
        before = np.array(record["before_move"])
        sel = np.array(record["selected"])
        offset = np.array(record["move_offset"])
        assert abs(offset[2]) < 1e-9 and np.linalg.norm(offset) > 0.5
        expected = before.copy()
        expected[sel] += offset
        np.testing.assert_allclose(record["during_move"], expected, atol=1e-4)
        assert record["handles_during_move"] == 1
        np.testing.assert_allclose(record["after_move_esc"], before, atol=1e-5)
        assert record["handles_after_move_esc"] == 0

    def test05_confirmed_move_is_one_undo_step(record):
        before = np.array(record["before_move"])
        sel = np.array(record["selected"])
        expected = before.copy()
        expected[sel] += np.array(record["move_offset"])
        np.testing.assert_allclose(record["after_move"], expected, atol=1e-4)
        assert record["selected_after_move"] == record["selected"]
        assert record["handles_after_move"] == 0
        np.testing.assert_allclose(record["after_undo"], before, atol=1e-5)
        np.testing.assert_allclose(record["after_redo"], expected, atol=1e-4)
