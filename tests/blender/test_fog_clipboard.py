"""Fog copy/paste by screen rectangle (addon/airlight/fog_clipboard.py): the pure
functions against hand-computed projections, and the copy/paste operators (EXEC) on a
prepared selection, with expectations computed in numpy from the inputs."""
import bpy
import numpy as np
import pytest
from mathutils import Matrix

from airlight import fog_clipboard as fc
from airlight import fog_object as fo


def _ortho(half_width, half_height):
    """World -> clip of an orthographic top view of [-hw, hw] x [-hh, hh] (looking down -z)."""
    m = np.eye(4)
    m[0, 0] = 1.0 / half_width
    m[1, 1] = 1.0 / half_height
    m[2, 2] = -0.01
    return m


def _perspective(f=1.0, near=0.1, far=100.0):
    """A camera at the origin looking down -z: clip w = -z."""
    m = np.zeros((4, 4))
    m[0, 0] = m[1, 1] = f
    m[2, 2] = (far + near) / (near - far)
    m[2, 3] = 2 * far * near / (near - far)
    m[3, 2] = -1.0
    return m


# ---- pure functions ---------------------------------------------------------------------

def test01_select_in_rect_orthographic_exact():
    # 200 x 100 px region showing x in [-10, 10], y in [-5, 5]: pixel = (10 (x + 10), 10 (y + 5))
    centres = np.array([[0.0, 0.0, 0.0],     # px (100, 50)
                        [-5.0, 2.0, 3.0],    # px (50, 70)
                        [5.0, -2.0, -1.0],   # px (150, 30)
                        [9.0, 4.0, 0.0],     # px (190, 90)
                        [-2.0, 0.0, 0.0]])   # px (80, 50): on the rectangle's edge
    m = _ortho(10.0, 5.0)
    np.testing.assert_array_equal(
        fc.select_in_rect(centres, m, (200, 100), (80, 20, 160, 75)), [True, False, True, False, True])
    # corners in any order give the same mask
    np.testing.assert_array_equal(fc.select_in_rect(centres, m, (200, 100), (160, 75, 80, 20)),
                                  [True, False, True, False, True])
    np.testing.assert_array_equal(fc.select_in_rect(centres, m, (200, 100), (40, 60, 60, 80)),
                                  [False, True, False, False, False])
    np.testing.assert_array_equal(fc.select_in_rect(centres, m, (200, 100), (0, 0, 200, 100)),
                                  [True] * 5)
    assert not fc.select_in_rect(centres, m, (200, 100), (0, 0, 10, 10)).any()


def test02_select_in_rect_perspective_behind_never_selected():
    # f = 1, 100 x 100 px: pixel = 50 (x/(-z) + 1), 50 (y/(-z) + 1)
    m = _perspective()
    centres = np.array([[1.0, 0.0, -2.0],    # px (75, 50)
                        [-1.0, 0.0, 2.0],    # behind: x/w would give px (75, 50) too
                        [0.0, 0.0, 0.0],     # at the eye (w = 0)
                        [-4.0, 4.0, -8.0]])  # px (25, 75)
    full = (0, 0, 100, 100)
    np.testing.assert_array_equal(fc.select_in_rect(centres, m, (100, 100), full),
                                  [True, False, False, True])
    np.testing.assert_array_equal(fc.select_in_rect(centres, m, (100, 100), (70, 45, 80, 55)),
                                  [True, False, False, False])
    # the same through a view matrix (camera moved to z = 5): a point behind it at z = 6
    view = np.eye(4)
    view[2, 3] = -5.0
    vp = m @ view
    np.testing.assert_array_equal(
        fc.select_in_rect(np.array([[1.0, 0.0, 3.0], [0.0, 0.0, 6.0]]), vp, (100, 100), full),
        [True, False])


def test03_copy_paste_move_arrays():
    rng = np.random.default_rng(3)
    c, a, amp = rng.uniform(-5, 5, (20, 3)), rng.uniform(0.5, 2, 20), rng.uniform(0, 1, 20)
    mask = np.zeros(20, dtype=bool)
    mask[[2, 5, 11]] = True
    clip = fc.copy_selection((c, a, amp), mask)
    np.testing.assert_array_equal(clip["centres"], c[[2, 5, 11]])
    np.testing.assert_array_equal(clip["scales"], a[[2, 5, 11]])
    np.testing.assert_array_equal(clip["amplitudes"], amp[[2, 5, 11]])
    c[2] = 99.0  # the clipboard is a copy
    assert clip["centres"][0, 0] != 99.0

    target = np.array([1.0, -2.0, 0.5])
    pc, pa, pamp = fc.paste(clip, target=target)
    np.testing.assert_allclose(pc.mean(axis=0), target, atol=1e-12)
    np.testing.assert_allclose(pc - pc[0], clip["centres"] - clip["centres"][0], atol=1e-12)
    np.testing.assert_array_equal(pa, clip["scales"])
    np.testing.assert_array_equal(pamp, clip["amplitudes"])
    pc, _, _ = fc.paste(clip, offset=(0.0, 0.0, 2.0))
    np.testing.assert_allclose(pc, clip["centres"] + [0.0, 0.0, 2.0])
    with pytest.raises(ValueError):
        fc.paste(clip)

    c0 = c.copy()
    mc, ma, mamp = fc.move((c, a, amp), mask, (1.0, 2.0, 3.0))
    np.testing.assert_array_equal(c, c0)  # input untouched
    np.testing.assert_allclose(mc[mask], c0[mask] + [1.0, 2.0, 3.0])
    np.testing.assert_array_equal(mc[~mask], c0[~mask])
    np.testing.assert_array_equal(ma, a)
    np.testing.assert_array_equal(mamp, amp)


# ---- operators --------------------------------------------------------------------------

@pytest.fixture
def scene():
    bpy.ops.wm.read_homefile(use_factory_startup=True, use_empty=True)
    fc._clipboard["data"] = None
    return bpy.context.scene


def _activate(obj):
    bpy.context.view_layer.objects.active = obj
    obj.select_set(True)


def test04_selection_attribute_round_trip(scene):
    obj = fo.new_fog_object("F", scene.collection, np.zeros((5, 3)), 1.0, 0.1)
    np.testing.assert_array_equal(fc.read_selection(obj), [False] * 5)
    fc.write_selection(obj, [True, False, True, False, False])
    attr = obj.data.attributes[fc.SELECTED_ATTR]
    assert attr.data_type == 'BOOLEAN' and attr.domain == 'POINT'
    np.testing.assert_array_equal(fc.read_selection(obj), [True, False, True, False, False])
    with pytest.raises(ValueError):
        fc.write_selection(obj, [True])


def test05_copy_and_paste_operators(scene):
    """Copy from a transformed object (world space: matrix applied, a divided by the
    uniform scale), paste into another transformed object at the 3D cursor: world layout
    kept, centroid on the cursor, a in world space kept, pasted Gaussians selected."""
    rng = np.random.default_rng(7)
    c, a, amp = rng.uniform(-3, 3, (12, 3)), rng.uniform(0.5, 2, 12), rng.uniform(0.1, 1, 12)
    src = fo.new_fog_object("Src", scene.collection, c, a, amp, location=(1.0, 2.0, 3.0))
    src.rotation_euler = (0.3, 0.0, 0.7)
    src.scale = (2.0, 2.0, 2.0)
    dst = fo.new_fog_object("Dst", scene.collection, [[0.0, 0.0, 0.0]], 1.5, 0.2, location=(-4.0, 0.0, 1.0))
    dst.scale = (0.5, 0.5, 0.5)
    bpy.context.view_layer.update()
    _activate(src)

    # nothing selected: a clear refusal, the clipboard stays empty
    assert bpy.ops.airlight.fog_copy() == {'CANCELLED'}
    assert fc.clipboard() is None
    assert not bpy.ops.airlight.fog_paste.poll()

    mask = np.zeros(12, dtype=bool)
    mask[[0, 3, 4, 9]] = True
    fc.write_selection(src, mask)
    assert bpy.ops.airlight.fog_copy() == {'FINISHED'}
    M = np.array(src.matrix_world)
    world = c.astype(np.float32).astype(np.float64) @ M[:3, :3].T + M[:3, 3]
    clip = fc.clipboard()
    np.testing.assert_allclose(clip["centres"], world[mask], atol=1e-5)
    np.testing.assert_allclose(clip["scales"], a[mask] / 2.0, rtol=1e-6)
    np.testing.assert_allclose(clip["amplitudes"], amp[mask], rtol=1e-6)

    _activate(dst)
    scene.cursor.location = (5.0, -1.0, 2.0)
    assert bpy.ops.airlight.fog_paste() == {'FINISHED'}
    dc, da, damp = fo.read(dst)
    assert len(dc) == 1 + 4
    D = np.array(dst.matrix_world)
    pasted_world = dc[1:] @ D[:3, :3].T + D[:3, 3]
    expected = world[mask] - world[mask].mean(axis=0) + [5.0, -1.0, 2.0]
    np.testing.assert_allclose(pasted_world, expected, atol=1e-5)
    np.testing.assert_allclose(da[1:] / 0.5, a[mask] / 2.0, rtol=1e-6)  # world a kept
    np.testing.assert_allclose(damp[1:], amp[mask], rtol=1e-6)
    assert dc[0].tolist() == [0.0, 0.0, 0.0] and da[0] == pytest.approx(1.5)
    np.testing.assert_array_equal(fc.read_selection(dst), [False, True, True, True, True])

    # gather (what the bake sees) agrees with the pasted world-space Gaussians
    gc, ga, gamp = fo.gather(bpy.context.evaluated_depsgraph_get())
    hit = [np.argmin(np.linalg.norm(gc - p, axis=1)) for p in expected]
    np.testing.assert_allclose(gc[hit], expected, atol=1e-5)
    np.testing.assert_allclose(ga[hit], a[mask] / 2.0, rtol=1e-6)

    # pasting twice adds another copy (the clipboard is not consumed)
    assert bpy.ops.airlight.fog_paste() == {'FINISHED'}
    assert len(dst.data.vertices) == 9


def test06_poll_messages(scene):
    mesh_obj = bpy.data.objects.new("Plain", bpy.data.meshes.new("Plain"))
    scene.collection.objects.link(mesh_obj)
    _activate(mesh_obj)
    for op in (bpy.ops.airlight.fog_copy, bpy.ops.airlight.fog_paste,
               bpy.ops.airlight.fog_select_rect, bpy.ops.airlight.fog_move):
        assert not op.poll()
        with pytest.raises(RuntimeError, match="fog object|3D viewport"):
            op()
    for cls in fc.classes:
        assert cls.bl_options == {'REGISTER', 'UNDO'}


def test07_colours_survive_copy_paste_and_erase(scene):
    """Per-Gaussian colours (airlight_color, e.g. from emitters) travel with copy/paste; an
    uncoloured target gets the scene fog colour for its own Gaussians."""
    rgb = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]], dtype=np.float32)
    src = fo.new_fog_object("Src", scene.collection, [[0, 0, 0], [1, 0, 0], [2, 0, 0]], 1.0, 0.5, colors=rgb)
    dst = fo.new_fog_object("Dst", scene.collection, [[0.0, 0.0, 5.0]], 1.0, 0.2)
    scene.airlight.color = (0.5, 0.5, 0.5)
    bpy.context.view_layer.update()
    _activate(src)
    fc.write_selection(src, [False, True, True])
    assert bpy.ops.airlight.fog_copy() == {'FINISHED'}
    _activate(dst)
    assert bpy.ops.airlight.fog_paste() == {'FINISHED'}
    np.testing.assert_allclose(fo.read_colors(dst.data), [[0.5, 0.5, 0.5], rgb[1], rgb[2]], rtol=1e-6)
