"""Fog objects (addon/airlight/fog_object.py): Gaussians stored as mesh vertices with
point attributes; bulk I/O, persistence, duplication, gather() with transforms, errors.
Expectations are computed independently from the inputs (transforms in numpy)."""
import math
import time

import bpy
import numpy as np
import pytest

from airlight import fog_object as fo


def _cloud(n, seed=0):
    rng = np.random.default_rng(seed)
    return (rng.uniform(-5, 5, (n, 3)), rng.uniform(0.2, 3.0, n), rng.uniform(0.0, 1.0, n))


@pytest.fixture
def scene():
    bpy.ops.wm.read_homefile(use_factory_startup=True, use_empty=True)
    return bpy.context.scene


def test01_add_operator_creates_fog_object(scene):
    scene.cursor.location = (1.0, 2.0, 3.0)
    assert bpy.ops.airlight.add_fog_object(scale=2.0, amplitude=0.25) == {'FINISHED'}
    obj = bpy.context.view_layer.objects.active
    assert fo.is_fog_object(obj) and obj.type == 'MESH'
    assert tuple(obj.location) == pytest.approx((1.0, 2.0, 3.0))
    c, a, amp = fo.read(obj)
    np.testing.assert_array_equal(c, [[0.0, 0.0, 0.0]])
    assert a[0] == pytest.approx(2.0) and amp[0] == pytest.approx(0.25)
    # renders nothing: only vertices
    assert len(obj.data.polygons) == 0 and len(obj.data.edges) == 0
    assert obj.data.attributes[fo.SCALE_ATTR].domain == 'POINT'
    # in the Add menu
    assert fo._menu_add in bpy.types.VIEW3D_MT_add._dyn_ui_initialize()


def test02_attributes_round_trip(scene):
    c, a, amp = _cloud(1000)
    obj = fo.new_fog_object("F", scene.collection, c, a, amp)
    c2, a2, amp2 = fo.read(obj)
    np.testing.assert_array_equal(c2, c.astype(np.float32))
    np.testing.assert_array_equal(a2, a.astype(np.float32))
    np.testing.assert_array_equal(amp2, amp.astype(np.float32))
    fo.append(obj, [[9.0, 9.0, 9.0]], 4.0, 0.5)
    c3, a3, amp3 = fo.read(obj)
    assert len(c3) == 1001
    np.testing.assert_array_equal(c3[:1000], c2)
    assert tuple(c3[-1]) == (9.0, 9.0, 9.0) and a3[-1] == 4.0 and amp3[-1] == 0.5
    fo.write(obj, c[:10], a[:10], amp[:10])  # shrinking keeps attributes consistent
    assert [len(x) for x in fo.read(obj)] == [10, 10, 10]


def test03_bulk_io_timing_1e5(scene):
    n = 100_000
    c, a, amp = _cloud(n, 1)
    obj = fo.new_fog_object("Big", scene.collection)
    t0 = time.perf_counter()
    fo.write(obj, c, a, amp)
    t1 = time.perf_counter()
    c2, a2, amp2 = fo.read(obj)
    t2 = time.perf_counter()
    print(f"\nfog object 1e5 Gaussians: write {1e3 * (t1 - t0):.1f} ms, read {1e3 * (t2 - t1):.1f} ms")
    np.testing.assert_array_equal(amp2, amp.astype(np.float32))
    assert (t2 - t0) < 0.5


def test04_save_and_reload(scene, tmp_path):
    c, a, amp = _cloud(50, 2)
    obj = fo.new_fog_object("Saved", scene.collection, c, a, amp)
    obj.scale = (2.0, 2.0, 2.0)
    path = str(tmp_path / "fog.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    bpy.ops.wm.read_homefile(use_factory_startup=True, use_empty=True)
    assert "Saved" not in bpy.data.objects
    bpy.ops.wm.open_mainfile(filepath=path)
    obj = bpy.data.objects["Saved"]
    assert fo.is_fog_object(obj)
    c2, a2, amp2 = fo.read(obj)
    np.testing.assert_array_equal(c2, c.astype(np.float32))
    np.testing.assert_array_equal(a2, a.astype(np.float32))
    np.testing.assert_array_equal(amp2, amp.astype(np.float32))


# Undo/redo of the add operator needs a window (ed.undo's poll fails under -b): it is
# tested in the GPU tier, tests/gpu/test_brush_ops_modal.py.


def test06_duplicate_copies_data(scene):
    c, a, amp = _cloud(20, 3)
    obj = fo.new_fog_object("Orig", scene.collection, c, a, amp)
    bpy.context.view_layer.objects.active = obj
    obj.select_set(True)
    bpy.ops.object.duplicate(linked=False)
    dup = bpy.context.view_layer.objects.active
    assert dup is not obj and dup.data is not obj.data and fo.is_fog_object(dup)
    fo.write(dup, c[:5], a[:5], amp[:5])
    assert len(fo.read(obj)[0]) == 20 and len(fo.read(dup)[0]) == 5


def test07_gather_two_objects_with_transforms(scene):
    c1, a1, amp1 = _cloud(30, 4)
    c2, a2, amp2 = _cloud(40, 5)
    o1 = fo.new_fog_object("A", scene.collection, c1, a1, amp1)
    o2 = fo.new_fog_object("B", scene.collection, c2, a2, amp2)
    o1.location = (1.0, -2.0, 0.5)
    o1.rotation_euler = (0.3, 0.0, 1.1)
    o1.scale = (2.0, 2.0, 2.0)
    o2.location = (-3.0, 0.0, 4.0)
    # not gathered: hidden in render, or not a fog object
    hidden = fo.new_fog_object("Hidden", scene.collection, c1[:3], 1.0, 1.0)
    hidden.hide_render = True
    plain = fo.new_fog_object("Plain", scene.collection, c1[:3], 1.0, 1.0)
    plain.airlight_fog.is_fog = False
    bpy.context.view_layer.update()
    centres, scales, amps = fo.gather(bpy.context.evaluated_depsgraph_get())
    assert centres.shape == (70, 3) and scales.shape == (70,) and amps.shape == (70,)
    # expected: rotation R, scale 2, translation
    rz, rx = 1.1, 0.3
    Rz = np.array([[math.cos(rz), -math.sin(rz), 0], [math.sin(rz), math.cos(rz), 0], [0, 0, 1]])
    Rx = np.array([[1, 0, 0], [0, math.cos(rx), -math.sin(rx)], [0, math.sin(rx), math.cos(rx)]])
    w1 = (c1.astype(np.float32) @ (2.0 * Rz @ Rx).T) + [1.0, -2.0, 0.5]
    w2 = c2.astype(np.float32) + [-3.0, 0.0, 4.0]
    order = np.argsort(amps)
    exp_c = np.concatenate([w1, w2])
    exp_s = np.concatenate([a1.astype(np.float32) / 2.0, a2.astype(np.float32)])
    exp_a = np.concatenate([amp1, amp2]).astype(np.float32)
    exp_order = np.argsort(exp_a)
    np.testing.assert_allclose(centres[order], exp_c[exp_order], atol=1e-5)
    np.testing.assert_allclose(scales[order], exp_s[exp_order], rtol=1e-6)
    np.testing.assert_array_equal(amps[order], exp_a[exp_order].astype(np.float64))


def test08_gather_nonuniform_scale_uses_geometric_mean(scene):
    o = fo.new_fog_object("N", scene.collection, [[1.0, 1.0, 1.0]], 3.0, 0.5)
    o.scale = (1.0, 2.0, 4.0)
    bpy.context.view_layer.update()
    centres, scales, _ = fo.gather(bpy.context.evaluated_depsgraph_get())
    np.testing.assert_allclose(centres, [[1.0, 2.0, 4.0]])
    assert scales[0] == pytest.approx(3.0 / 2.0)  # (1*2*4)^(1/3) = 2


@pytest.mark.parametrize("case", ["empty", "zero_scale", "negative_scale", "nan_centre",
                                  "nan_scale", "nan_amplitude", "negative_amplitude",
                                  "missing_attribute"])
def test09_bad_input_raises_with_object_name(scene, case):
    c, a, amp = _cloud(5, 6)
    if case == "zero_scale":
        a[2] = 0.0
    elif case == "negative_scale":
        a[1] = -1.0
    elif case == "nan_centre":
        c[3, 1] = np.nan
    elif case == "nan_scale":
        a[0] = np.nan
    elif case == "nan_amplitude":
        amp[4] = np.nan
    elif case == "negative_amplitude":
        amp[4] = -0.1
    obj = fo.new_fog_object(f"Bad_{case}", scene.collection, *((c[:0], a[:0], amp[:0]) if case == "empty" else (c, a, amp)))
    if case == "missing_attribute":
        obj.data.attributes.remove(obj.data.attributes[fo.AMPLITUDE_ATTR])
    fo.new_fog_object("Good", scene.collection, c[:2], 1.0, 1.0)
    bpy.context.view_layer.update()
    with pytest.raises(fo.FogObjectError) as info:
        fo.gather(bpy.context.evaluated_depsgraph_get())
    assert isinstance(info.value, ValueError)
    assert info.value.object_name == f"Bad_{case}" and f"Bad_{case}" in str(info.value)
    print(f"\n{case}: {info.value}")


def test10_gather_without_fog_objects_is_empty(scene):
    c, s, a = fo.gather(bpy.context.evaluated_depsgraph_get())
    assert c.shape == (0, 3) and s.shape == (0,) and a.shape == (0,)


# ---- paintbrush and eraser logic (addon/airlight/brush_ops.py, pure functions) ----------

from airlight import brush_ops as bo  # noqa: E402


def test11_resample_stroke_spacing_exact():
    # an L-shaped polyline of length 3 + 4 = 7, spacing 0.5: 15 positions at s = 0..7
    pts = np.array([[0.0, 0.0, 0.0], [3.0, 0.0, 0.0], [3.0, 4.0, 0.0]])
    pos, tan, s = bo.resample_stroke(pts, 0.5)
    np.testing.assert_allclose(s, 0.5 * np.arange(15))
    assert len(pos) == 15
    np.testing.assert_allclose(pos[6], [3.0, 0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(pos[8], [3.0, 1.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(pos[-1], [3.0, 4.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(tan[:6], np.tile([1.0, 0.0, 0.0], (6, 1)))
    np.testing.assert_allclose(tan[7:], np.tile([0.0, 1.0, 0.0], (8, 1)))
    # offset start, repeated points ignored
    pos, _, s = bo.resample_stroke(np.array([[0.0, 0, 0], [0, 0, 0], [1.0, 0, 0]]), 0.3, offset=0.2)
    np.testing.assert_allclose(s, [0.2, 0.5, 0.8])
    # a click: one position
    pos, tan, s = bo.resample_stroke(np.array([[1.0, 2.0, 3.0]]), 0.3)
    np.testing.assert_array_equal(pos, [[1.0, 2.0, 3.0]])
    with pytest.raises(ValueError):
        bo.resample_stroke(pts, 0.0)


@pytest.mark.parametrize("a", [0.5, 2.0, 10.0])
def test12_paint_dabs_spacing_and_offsets(a):
    """Default spacing 0.75/a along the stroke; each offset perpendicular to the stroke
    and shorter than 1/a (Fogshop section 6); the offsets fill the disc (not degenerate)."""
    length = 40.0 / a
    pts = np.array([[0.0, 0.0, 1.0], [length, 0.0, 1.0]])
    dabs = bo.paint_dabs(pts, a, seed=7)
    expected_n = int(np.floor(length / (0.75 / a) + 1e-9)) + 1
    assert len(dabs) == expected_n == 54
    along = dabs[:, 0]
    np.testing.assert_allclose(along, 0.75 / a * np.arange(expected_n), atol=1e-12)  # no tangential jitter
    radial = np.linalg.norm(dabs[:, 1:] - [0.0, 1.0], axis=1)
    assert radial.max() < 1.0 / a
    assert radial.max() > 0.8 / a and (dabs[:, 1] > 0).any() and (dabs[:, 1] < 0).any()
    assert (np.abs(dabs[:, 2] - 1.0) > 0.1 / a).any()  # offsets leave the stroke's plane too
    # deterministic per seed, different across seeds; a longer stroke extends a shorter one
    np.testing.assert_array_equal(dabs, bo.paint_dabs(pts, a, seed=7))
    assert not np.allclose(dabs, bo.paint_dabs(pts, a, seed=8))
    longer = bo.paint_dabs(np.array([[0.0, 0.0, 1.0], [length, 0.0, 1.0], [length, 5.0, 1.0]]), a, seed=7)
    np.testing.assert_allclose(longer[:expected_n], dabs, atol=1e-12)
    # jitter 0: exactly on the stroke; custom spacing
    exact = bo.paint_dabs(pts, a, spacing=2.0, jitter=0.0)
    np.testing.assert_allclose(exact, np.stack([2.0 / a * np.arange(len(exact)),
                                                np.zeros(len(exact)), np.ones(len(exact))], 1))


def test13_perpendicular_offsets_any_direction():
    rng = np.random.default_rng(3)
    t = rng.standard_normal((500, 3))
    t /= np.linalg.norm(t, axis=1, keepdims=True)
    t[0] = [1.0, 0.0, 0.0]
    t[1] = [0.0, 0.0, -1.0]
    off = bo.perpendicular_offsets(t, 0.25, np.random.default_rng(0))
    np.testing.assert_allclose(np.einsum("ij,ij->i", off, t), 0.0, atol=1e-12)
    assert np.linalg.norm(off, axis=1).max() < 0.25


def test14_project_points_matches_matrix():
    # orthographic top view of a 10 x 8 m box into 200 x 160 pixels
    m = np.diag([2.0 / 10.0, 2.0 / 8.0, -0.01, 1.0])
    xy, vis = bo.project_points([[0.0, 0.0, 0.0], [5.0, -4.0, 0.0], [-2.5, 2.0, 3.0]], m, 200, 160)
    np.testing.assert_allclose(xy, [[100.0, 80.0], [200.0, 0.0], [50.0, 120.0]])
    assert vis.all()
    # perspective: a point behind the viewer (w <= 0) is not visible
    persp = np.array([[1.0, 0, 0, 0], [0, 1.0, 0, 0], [0, 0, -1.0, -0.2], [0, 0, -1.0, 0]])
    _, vis = bo.project_points([[0.0, 0.0, -5.0], [0.0, 0.0, 5.0]], persp, 100, 100)
    assert vis.tolist() == [True, False]


def test15_erase_lowers_with_falloff_and_deletes_at_zero():
    xy = np.array([[50.0, 50.0], [60.0, 50.0], [75.0, 50.0], [100.0, 50.0], [50.0, 50.0]])
    visible = np.array([True, True, True, True, False])
    amp = np.array([0.5, 0.5, 0.5, 0.5, 0.5])
    new, keep = bo.erase(xy, visible, amp, (50.0, 50.0), 50.0, 0.2)
    f = (1.0 - (np.array([0.0, 10.0, 25.0]) / 50.0) ** 2) ** 2
    np.testing.assert_allclose(new[:3], 0.5 - 0.2 * f)
    assert new[3] == 0.5 and new[4] == 0.5  # outside the radius; not visible
    assert keep.all()
    # repeated dabs reach zero at the centre first, exactly zero (clamped) and deleted
    a = amp.copy()
    for _ in range(2):  # 2 x 0.25 removes exactly the 0.5 at the centre
        a, keep = bo.erase(xy, visible, a, (50.0, 50.0), 50.0, 0.25)
    assert a[0] == 0.0 and not keep[0] and keep[1:].all()
    assert a[1] == pytest.approx(0.5 - 0.5 * (1 - 0.2 ** 2) ** 2) and 0.0 < a[1] < a[2] < 0.5


def test16_unregister_removes_fog_types():
    import addon_utils
    addon_utils.disable("airlight", default_set=True)
    try:
        assert not hasattr(bpy.types.Object, "airlight_fog")
        assert not hasattr(bpy.types.Scene, "airlight_brush")
        for name in ("AIRLIGHT_OT_add_fog_object", "AIRLIGHT_OT_fog_paint", "AIRLIGHT_OT_fog_erase",
                     "AIRLIGHT_PT_fog_tools"):
            assert not hasattr(bpy.types, name), name
        assert bo._draw_handles == set()
    finally:
        addon_utils.enable("airlight", default_set=True)
    assert hasattr(bpy.types.Object, "airlight_fog") and hasattr(bpy.types.Scene, "airlight_brush")
    assert hasattr(bpy.types, "AIRLIGHT_OT_fog_erase") and hasattr(bpy.types, "AIRLIGHT_PT_fog_tools")


def test17_linked_fog_bakes_and_copies_but_the_tools_refuse_to_edit_it(scene, tmp_path):
    """A fog object linked from a library (or overridden) renders like any object, but
    Blender saves no edit of its data: the tools that write it refuse it with a message
    saying how to edit it, so that no stroke is lost on save; made local, it edits."""
    from types import SimpleNamespace
    from airlight import airbrush, brush_ops, fog_clipboard

    c, a, amp = _cloud(5, seed=3)
    lib_obj = fo.new_fog_object("LibFog", scene.collection, centres=c, scales=a, amplitudes=amp,
                                location=(1.0, 0.0, 0.0))
    assert bpy.ops.airlight.add_emitter() == {'FINISHED'}
    lib_emitter = bpy.context.view_layer.objects.active
    lib_emitter.name = "LibEmitter"
    lib = str(tmp_path / "fog_library.blend")
    bpy.data.libraries.write(lib, {lib_obj, lib_emitter})
    bpy.ops.wm.read_homefile(use_factory_startup=True, use_empty=True)
    scene = bpy.context.scene
    with bpy.data.libraries.load(lib, link=True) as (_, into):
        into.objects = ["LibFog", "LibEmitter"]
    linked = bpy.data.objects["LibFog"]
    scene.collection.objects.link(linked)
    assert linked.library is not None

    # It renders: gather() sees its Gaussians where the library put them.
    gathered = fo.gather(bpy.context.evaluated_depsgraph_get())
    np.testing.assert_allclose(gathered[0], c + [1.0, 0.0, 0.0], atol=1e-5)

    problem = fo.edit_problem(linked)
    assert "linked from fog_library.blend" in problem and "Make Local" in problem

    # The clipboard: copying from it works, writing into it (select, paste, move) does not.
    local = fo.new_fog_object("Local", scene.collection, centres=[(0.0, 0.0, 0.0)])
    fog_clipboard.write_selection(local, np.ones(1, bool))
    bpy.context.view_layer.objects.active = local
    assert bpy.ops.airlight.fog_copy() == {'FINISHED'}
    bpy.context.view_layer.objects.active = linked
    assert bpy.ops.airlight.fog_copy.poll()
    assert not bpy.ops.airlight.fog_paste.poll()
    with pytest.raises(RuntimeError, match="linked from fog_library.blend"):
        bpy.ops.airlight.fog_paste()
    assert len(linked.data.vertices) == 5

    # Paint, erase, airbrush and the fill (their polls, as the viewport calls them).
    view3d = SimpleNamespace(area=SimpleNamespace(type='VIEW_3D'), mode='OBJECT', active_object=linked)
    for cls in (brush_ops.AIRLIGHT_OT_fog_paint, brush_ops.AIRLIGHT_OT_fog_erase, airbrush.AIRLIGHT_OT_airbrush,
                fog_clipboard.AIRLIGHT_OT_fog_select_rect, fog_clipboard.AIRLIGHT_OT_fog_move):
        assert not cls.poll(view3d), cls.__name__
    box = bpy.data.objects.new("Box", bpy.data.meshes.new("Box"))
    scene.collection.objects.link(box)
    box.select_set(True)
    assert not bpy.ops.airlight.fill_mesh.poll()
    with pytest.raises(RuntimeError, match="linked from"):
        bpy.ops.airlight.fill_mesh()

    # A library override keeps its mesh in the library: refused too.
    override = linked.override_create(remap_local_usages=True)
    assert fo.edit_problem(override) is not None
    bpy.context.view_layer.objects.active = override
    assert not bpy.ops.airlight.fog_paste.poll()

    # Made local as the message says (Object > Relations > Make Local, object and data), it
    # is the user's to edit.
    for obj in scene.objects:
        obj.select_set(obj == override)
    assert bpy.ops.object.make_local(type='SELECT_OBDATA') == {'FINISHED'}
    override = bpy.context.view_layer.objects.active
    assert fo.edit_problem(override) is None
    assert bpy.ops.airlight.fog_paste.poll()
    assert bpy.ops.airlight.fog_paste() == {'FINISHED'}
    assert len(override.data.vertices) == 6
    assert all(cls.poll(SimpleNamespace(area=SimpleNamespace(type='VIEW_3D'), mode='OBJECT',
                                        active_object=override))
               for cls in (brush_ops.AIRLIGHT_OT_fog_paint, brush_ops.AIRLIGHT_OT_fog_erase))

    # A linked emitter cannot store baked frames in this file either.
    linked_emitter = bpy.data.objects["LibEmitter"]
    scene.collection.objects.link(linked_emitter)
    bpy.context.view_layer.objects.active = linked_emitter
    assert linked_emitter.airlight_emitter.is_emitter
    assert not bpy.ops.airlight.emitter_bake.poll()
    with pytest.raises(RuntimeError, match="linked from fog_library.blend"):
        bpy.ops.airlight.emitter_bake()
