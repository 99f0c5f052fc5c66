"""The depsgraph's meshes as triangles, read again only as far as it takes to know they did
not change.

A mesh's loop triangles are a function of its polygons (their first loop and loop count),
its loops' vertices and its vertex positions: Blender splits quads and n-gons from those
alone. The three read in bulk at a fraction of the triangles' cost (Blender computes each
triangle's vertex on the way out; 1e7 triangles: 0.29 s, against 0.15 s for the three), so
`MeshReads` keeps, per object and mesh, what it read last, and reads the triangles again only
when one of the three differs, bit for bit. The world-space vertices are kept per world
matrix, and a soup of the same blocks as last time is the same soup. Nothing is trusted that
is not compared: an edit Blender was not told about, a modifier, a shape key or an
animated frame all change one of the three, or the count of triangles.

Objects that are not meshes in Object Mode (curves, text, a mesh in Edit Mode) go through
`to_mesh()` and are not kept.
"""

import contextlib

import numpy as np


class NotFinite(ValueError):
    """An object's world-space vertices are not all finite (the message names it)."""


def _read(collection, attribute, dtype, count):
    out = np.empty(count, dtype=dtype)
    collection.foreach_get(attribute, out)
    return out


def _triangles(mesh):
    """Loop triangles (M, 3) uint32 of _mesh_ (uint32: Blender's own type, which foreach_get
    copies without converting each value; an int32 buffer took 4x as long)."""
    return _read(mesh.loop_triangles, "vertices", np.uint32, 3 * len(mesh.loop_triangles)).reshape(-1, 3)


def _mesh_arrays(mesh):
    """Vertices (N,3) float32 and loop triangles (M,3) uint32 of _mesh_, or None when empty."""
    if len(mesh.vertices) == 0 or len(mesh.loop_triangles) == 0:
        return None
    return _read(mesh.vertices, "co", np.float32, 3 * len(mesh.vertices)).reshape(-1, 3), _triangles(mesh)


def _in_place(obj_eval):
    """An evaluated mesh object's data, which is its mesh with the modifiers applied, read in
    place without to_mesh()'s copy (1e7 triangles: 1.2-1.9 s against 3.0-3.4 s); None in Edit
    Mode (the edit mesh's wrapper, without vertices) and for the other types."""
    if obj_eval.type == 'MESH' and obj_eval.mode == 'OBJECT' and len(obj_eval.data.vertices):
        return obj_eval.data
    return None


def mesh_arrays(obj_eval):
    """Local-space vertices (N,3) float32 and triangles (M,3) uint32 of an evaluated object,
    or None without triangles."""
    mesh = _in_place(obj_eval)
    if mesh is not None:
        return _mesh_arrays(mesh)
    try:
        mesh = obj_eval.to_mesh()
    except RuntimeError:
        return None
    if mesh is None:
        return None
    try:
        mesh.calc_loop_triangles()
        return _mesh_arrays(mesh)
    finally:
        obj_eval.to_mesh_clear()


def world_vertices(name, local, matrix):
    """(N, 3) float32 world-space vertices of _local_ under _matrix_ (4, 4) float64;
    NotFinite where one is not."""
    world = local.astype(np.float64) @ matrix[:3, :3].T + matrix[:3, 3]
    if not np.isfinite(world).all():
        raise NotFinite(f"Object '{name}' has NaN or infinite vertices or transform")
    return world.astype(np.float32)


def _read_only(array):
    """_array_, which later frames share, made read-only: an edit in place raises."""
    array.flags.writeable = False
    return array


class _Mesh:
    """What was read of one object's mesh: the three it is compared by, its triangles, and its
    world-space vertices per world matrix (those of the last pass that used it)."""

    def __init__(self, key, triangles):
        self.key = key  # (positions, loop vertices, polygon starts, polygon sizes)
        self.triangles = _read_only(triangles)
        self.world = {}
        self.world_used = {}

    def same(self, key):
        return all(len(a) == len(b) and np.array_equal(a, b) for a, b in zip(self.key, key))


class MeshReads:
    """Per process: the meshes of the last export, compared and not read again (module
    docstring). One pass at a time (`reads.pass_()`): the meshes a pass did not meet are
    dropped when it ends, so that the kept memory is the last frame's geometry."""

    def __init__(self):
        self._meshes = {}
        self._soups = {}
        self._seen = None
        self.triangles_read = 0  # meshes whose triangles were read (the tests count them)

    def clear(self):
        self._meshes.clear()
        self._soups.clear()

    @contextlib.contextmanager
    def pass_(self):
        """One export's reads; the meshes it did not meet are dropped when it completes."""
        self._seen = {}
        try:
            yield self
        except BaseException:
            self._seen = None
            raise
        met = {id(m) for m in self._seen.values()}
        self._meshes = {k: m for k, m in self._meshes.items() if id(m) in met}
        for mesh in self._meshes.values():
            mesh.world, mesh.world_used = mesh.world_used, {}
        self._seen = None

    def _mesh(self, obj_eval, mesh):
        """The kept _Mesh of an evaluated mesh, read again where it changed."""
        pointer = mesh.as_pointer()  # unique among the data alive during one pass
        if self._seen is not None and pointer in self._seen:
            return self._seen[pointer]
        n_loops, n_polygons = len(mesh.loops), len(mesh.polygons)
        key = (_read(mesh.vertices, "co", np.float32, 3 * len(mesh.vertices)),
               _read(mesh.loops, "vertex_index", np.uint32, n_loops),
               _read(mesh.polygons, "loop_start", np.uint32, n_polygons),
               _read(mesh.polygons, "loop_total", np.uint32, n_polygons))
        name = (obj_eval.name, mesh.name)
        kept = self._meshes.get(name)
        if kept is None or not kept.same(key) or len(kept.triangles) != len(mesh.loop_triangles):
            kept = _Mesh(key, _triangles(mesh))
            self.triangles_read += 1
            self._meshes[name] = kept
        if self._seen is not None:
            self._seen[pointer] = kept
        return kept

    def world_triangles(self, obj_eval, matrix):
        """World-space (vertices (N, 3) float32, triangles (M, 3) uint32) of an evaluated
        object under _matrix_, or None without triangles."""
        mesh = _in_place(obj_eval)
        if mesh is None or self._seen is None:
            arrays = mesh_arrays(obj_eval)
            return None if arrays is None else (world_vertices(obj_eval.name, arrays[0], matrix), arrays[1])
        if len(mesh.loop_triangles) == 0:
            return None
        kept = self._mesh(obj_eval, mesh)
        at = matrix.tobytes()
        world = kept.world_used.get(at)
        if world is None:
            world = kept.world.get(at)
            if world is None:
                world = world_vertices(obj_eval.name, kept.key[0].reshape(-1, 3), matrix)
            kept.world_used[at] = _read_only(world)
        return world, kept.triangles

    def soup(self, role, blocks):
        """One triangle soup (vertices (N, 3) float32, triangles (M, 3) uint32) of _blocks_,
        the same arrays as the last soup of _role_ when its blocks are the same arrays."""
        last = self._soups.get(role)
        if last is not None and len(last[0]) == len(blocks) and all(
                a is c and b is d for (a, b), (c, d) in zip(last[0], blocks)):
            return last[1]
        out = tuple(_read_only(a) for a in soup(blocks))
        self._soups[role] = (list(blocks), out)
        return out


def soup(blocks):
    """One triangle soup (vertices (N, 3) float32, triangles (M, 3) uint32) of blocks."""
    if not blocks:
        return np.zeros((0, 3), np.float32), np.zeros((0, 3), np.uint32)
    if len(blocks) == 1:
        return blocks[0]
    vertices, triangles, base = [], [], 0
    for v, t in blocks:
        vertices.append(v)
        triangles.append(t + np.uint32(base))
        base += len(v)
    return np.concatenate(vertices), np.concatenate(triangles)


reads = MeshReads()
