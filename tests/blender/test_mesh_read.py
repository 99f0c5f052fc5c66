"""The export reads a mesh's triangles again only when the mesh changed (mesh_read).

Each test changes the scene as a user or a script would, then holds export_instances' soup
to Blender's own data read afresh (every object's loop triangles and vertices through
foreach_get, under its world matrix), and counts the triangle reads: an unchanged mesh is
not read again, and every change that alters the triangles is seen, including those that
keep every vertex where it was and every count (faces flipped, an edge rotated).
"""

import bmesh
import bpy
import numpy as np
import pytest

from airlight import mesh_read, scene_description
from conftest import reset_blender


def _fresh_soup(depsgraph):
    """The camera's soup read without the cache, object by object (the reference)."""
    blocks = []
    for instance in depsgraph.object_instances:
        obj = instance.object
        if obj.type != 'MESH':
            continue
        arrays = mesh_read.mesh_arrays(obj)
        if arrays is None:
            continue
        matrix = np.array(instance.matrix_world, dtype=np.float64)
        blocks.append((mesh_read.world_vertices(obj.name, arrays[0], matrix), arrays[1]))
    return mesh_read.soup(blocks)


def _export():
    """(vertices, triangles, how many meshes' triangles were read) of one export."""
    depsgraph = bpy.context.evaluated_depsgraph_get()
    before = mesh_read.reads.triangles_read
    _, vertices, triangles, _ = scene_description.export_instances(depsgraph)
    reference = _fresh_soup(depsgraph)
    np.testing.assert_array_equal(vertices, reference[0])
    np.testing.assert_array_equal(triangles, reference[1])
    return vertices, triangles, mesh_read.reads.triangles_read - before


@pytest.fixture
def scene():
    scene = reset_blender()
    mesh_read.reads.clear()
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=12, y_subdivisions=9, size=4.0)
    bpy.ops.mesh.primitive_uv_sphere_add(location=(3.0, 0.0, 1.0))
    bpy.ops.mesh.primitive_cube_add(location=(-3.0, 0.0, 1.0))
    _export()
    return scene


def _object(name):
    return bpy.data.objects[name]


def test_an_unchanged_frame_reads_no_triangles(scene):
    vertices, triangles, read = _export()
    assert read == 0
    again = _export()
    assert again[2] == 0 and again[0] is vertices and again[1] is triangles  # the same soup


def test_a_moved_object_keeps_its_triangles(scene):
    _object("Sphere").location.z += 0.5
    vertices, _, read = _export()
    assert read == 0
    assert vertices[:, 2].max() > 2.4


@pytest.mark.parametrize("edit", ["flip", "rotate_edge", "sort", "vertex"])
def test_an_edit_that_keeps_the_counts_is_seen(scene, edit):
    """Each edit keeps the mesh's vertex, loop, polygon and triangle counts; the first three
    keep every vertex where it was too, and change only how the triangles use them."""
    mesh = _object("Grid").data
    bm = bmesh.new()
    bm.from_mesh(mesh)
    if edit == "flip":
        bmesh.ops.reverse_faces(bm, faces=bm.faces[:])
    elif edit == "rotate_edge":
        bm.edges.ensure_lookup_table()
        inner = [e for e in bm.edges if len(e.link_faces) == 2][:5]
        bmesh.ops.rotate_edges(bm, edges=inner, use_ccw=False)
    elif edit == "sort":
        bm.faces.ensure_lookup_table()
        bm.faces.sort(key=lambda f: -f.index)
    else:
        bm.verts.ensure_lookup_table()
        bm.verts[40].co.z += 0.3
    counts = (len(bm.verts), len(bm.edges), len(bm.faces))
    bm.to_mesh(mesh)
    bm.free()
    mesh.update()
    assert (len(mesh.vertices), len(mesh.edges), len(mesh.polygons)) == counts
    _, _, read = _export()
    assert read == 1


def test_a_modifier_and_a_shape_key_are_seen(scene):
    cube = _object("Cube")
    cube.modifiers.new("subdivision", 'SUBSURF').levels = 1
    _, _, read = _export()
    assert read == 1
    cube.shape_key_add(name="Basis")
    key = cube.shape_key_add(name="Up")
    key.data[0].co.z += 1.0
    key.value = 0.5
    _, _, read = _export()
    assert read == 1
    _, _, read = _export()
    assert read == 0


def test_an_animated_modifier_is_read_on_each_frame(scene):
    grid = _object("Grid")
    wave = grid.modifiers.new("wave", 'WAVE')
    wave.height = 0.3
    previous = None
    for frame in (1, 7, 13):
        scene.frame_set(frame)
        vertices, _, _ = _export()
        if previous is not None:
            assert not np.array_equal(vertices, previous)
        previous = vertices.copy()


def test_linked_duplicates_and_edit_mode(scene):
    sphere = _object("Sphere")
    twin = sphere.copy()  # the same mesh
    twin.location.x += 2.0
    scene.collection.objects.link(twin)
    _, _, read = _export()
    assert read == 0  # the twin's evaluated mesh is the sphere's
    bpy.context.view_layer.objects.active = sphere
    bpy.ops.object.mode_set(mode='EDIT')
    try:
        bpy.ops.mesh.select_all(action='SELECT')
        bpy.ops.transform.translate(value=(0.0, 0.0, 0.25))
        _export()  # Edit Mode: through to_mesh(), compared to the same
    finally:
        bpy.ops.object.mode_set(mode='OBJECT')
    _, _, read = _export()
    assert read >= 1  # (once per object: after Edit Mode each has its own evaluated copy)


def test_a_removed_object_is_dropped(scene):
    bpy.data.objects.remove(_object("Grid"))
    _, triangles, read = _export()
    assert read == 0
    assert all(name[0] != "Grid" for name in mesh_read.reads._meshes)


def test_nan_is_still_an_export_error(scene):
    _object("Cube").data.vertices[0].co.x = float("nan")
    _object("Cube").data.update()
    with pytest.raises(scene_description.ExportError, match="Cube"):
        scene_description.export_instances(bpy.context.evaluated_depsgraph_get())
    _object("Cube").data.vertices[0].co.x = 1.0
    _object("Cube").data.update()
    _export()
