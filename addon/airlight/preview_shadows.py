"""Volumetric shadows in the viewport preview: shadow maps of the scene's shadow casters,
drawn with `gpu`, that the fog shaders march through (shaders/shadow_maps.glsl).

The bake decides which lights are shadowed (scene_export.shadow_arguments: Volumetric
Shadows on, the light's Cast Shadow on, not left clear by Automatic); the preview shadows
the same lights, up to MAX_SHADOW_MAPS of them (the rest stay unshadowed and the panel
says so). Each gets one row of an R32F atlas holding the distance to the nearest caster:
- point lights and spots: a cube of six SHADOW_RES^2 perspective faces around the light
  (`cube_face_matrix`, the convention of shadow_maps.glsl), near and far planes from the
  casters' bounding box;
- suns: one orthographic map (3 x 2 faces' texels) over the casters' bounding box seen
  along the sun (`sun_matrix`); points outside its footprint are lit.
The casters are the bake's: render-visible objects whose Ray Visibility > Shadow is on,
fog objects excepted (`preview._caster_instances`). The atlas is drawn again only when its key
changes (a depsgraph update, a frame change, or a light's placement), not when the view
moves.
"""

import gpu
import numpy as np
from mathutils import Matrix

from . import gpu_shaders as gs

SHADOW_RES = gs.SHADOW_RES
MAX_SHADOW_MAPS = 8
# (major axis, sign) of the cube faces +X -X +Y -Y +Z -Z (shadow_maps.glsl).
FACES = ((0, 1.0), (0, -1.0), (1, 1.0), (1, -1.0), (2, 1.0), (2, -1.0))


def cube_face_matrix(light, face, near, far):
    """Projection @ view of cube face _face_ (0..5) around _light_: clip = (d_b, d_c, z,
    |d_a|) for d = p - light, major axis a and (b, c) the next two axes in cyclic order,
    z mapping |d_a| in [near, far] to [-1, 1] (OpenGL), as shadow_lit reads it."""
    a, sign = FACES[face]
    b, c = (a + 1) % 3, (a + 2) % 3
    L = np.asarray(light, dtype=np.float64)
    A = (far + near) / (far - near)
    B = -2.0 * far * near / (far - near)
    m = np.zeros((4, 4))
    m[0, b] = m[1, c] = 1.0
    m[3, a] = sign
    m[2, a] = A * sign
    m[:, 3] = -m[:, :3] @ L
    m[2, 3] += B
    return Matrix(m.tolist())


def _box_corners(box):
    lo, hi = np.asarray(box[0], np.float64), np.asarray(box[1], np.float64)
    return np.array([[(lo, hi)[i >> k & 1][k] for k in range(3)] for i in range(8)])


def cube_range(light, box):
    """(near, far) of a light's cube faces that hold the casters' bounding box."""
    corners = _box_corners(box)
    far = float(np.max(np.linalg.norm(corners - np.asarray(light, np.float64), axis=1)))
    far = max(far * 1.01, 1e-3)
    return max(1e-5 * far, 1e-4), far


def sun_frame(direction, box):
    """(ortho matrix, info rows) of a sun's map over the casters' box: map coordinates x,
    y in [-1, 1] across the box seen along the unit propagation direction w, depth over
    its extent along w. Info rows (shadow_info texels 0..3, shadow_maps.glsl): (texel
    size, 0, 0, 1), (e1 / h1, -c1 / h1), (e2 / h2, -c2 / h2), (w, -lo_w)."""
    w = np.asarray(direction, np.float64)
    w = w / np.linalg.norm(w)
    helper = np.array([1.0, 0.0, 0.0]) if abs(w[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = np.cross(w, helper)
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(w, e1)
    corners = _box_corners(box)
    p1, p2, pw = corners @ e1, corners @ e2, corners @ w
    if np.ptp(p2) > np.ptp(p1):  # the longer side across the 3R side of the tile
        e1, e2, p1, p2 = e2, e1, p2, p1
    c1, c2 = 0.5 * (p1.max() + p1.min()), 0.5 * (p2.max() + p2.min())
    h1 = max(0.5 * np.ptp(p1), 1e-4) * 1.01
    h2 = max(0.5 * np.ptp(p2), 1e-4) * 1.01
    lo_w, hi_w = pw.min() - 1e-3 * (1.0 + np.ptp(pw)), pw.max() + 1e-3 * (1.0 + np.ptp(pw))
    cw, hw = 0.5 * (lo_w + hi_w), 0.5 * (hi_w - lo_w)
    m = np.zeros((4, 4))
    m[0, :3], m[0, 3] = e1 / h1, -c1 / h1
    m[1, :3], m[1, 3] = e2 / h2, -c2 / h2
    m[2, :3], m[2, 3] = w / hw, -cw / hw
    m[3, 3] = 1.0
    texel = max(2.0 * h1 / (3 * SHADOW_RES), 2.0 * h2 / (2 * SHADOW_RES))
    info = np.array([[texel, 0.0, 0.0, 1.0], [*m[0, :3], m[0, 3]], [*m[1, :3], m[1, 3]],
                     [*w, -lo_w]])
    return Matrix(m.tolist()), info


def union_box(boxes):
    """(lo, hi) of world-space boxes ((2, 3) each), or None without any."""
    if not boxes:
        return None
    stacked = np.asarray(boxes, np.float64).reshape(-1, 2, 3)
    return stacked[:, 0].min(axis=0), stacked[:, 1].max(axis=0)


class ShadowMaps:
    """The atlas (shadow_maps), its info texture (shadow_info) and the key they were drawn
    for. `update` draws them again when the key changes."""

    def __init__(self):
        self.key = None
        self.maps = self.depth = self.info = None
        self.rows = 0

    def _textures(self, rows):
        if self.maps is None or self.rows != rows:
            size = (3 * SHADOW_RES, 2 * SHADOW_RES * rows)
            self.maps = gpu.types.GPUTexture(size, format='R32F')
            self.depth = gpu.types.GPUTexture(size, format='DEPTH_COMPONENT32F')
            self.rows = rows

    def update(self, key, requests, box, casters, shader):
        """Draws the maps of _requests_ ([('CUBE', position) or ('SUN', direction)], one row
        each in order) for the casters' union _box_ ((lo, hi)) and _casters_ ([(batch,
        model matrix)], or a callable returning them, called only when the maps are drawn)
        with the distance _shader_ (gpu_shaders.create_distance_shader), unless _key_ is
        the one they were drawn for. Restores the gpu state it changes."""
        if key == self.key and self.maps is not None:
            return
        if callable(casters):
            casters = casters()
        rows = max(1, len(requests))
        self._textures(rows)
        info = np.zeros((4, rows, 4), np.float32)
        R = SHADOW_RES
        fb = gpu.types.GPUFrameBuffer(depth_slot=self.depth, color_slots=(self.maps,))
        with gs.preserved_state(), fb.bind():
            gpu.state.viewport_set(0, 0, 3 * R, 2 * R * rows)
            gs.start_distances(fb, shader)
            for row, (kind, vector) in enumerate(requests):
                y0 = 2 * R * row
                if kind == 'SUN':
                    matrix, info[:, row] = sun_frame(vector, box)
                    faces = [(matrix, (0, y0, 3 * R, 2 * R), (0.0, 0.0, 0.0, 0.0), tuple(info[3, row]))]
                else:
                    near, far = cube_range(vector, box)
                    info[0, row, :3] = vector
                    faces = [(cube_face_matrix(vector, f, near, far), ((f % 3) * R, y0 + (f // 3) * R, R, R),
                              (*vector, 1.0), (0.0, 0.0, 1.0, 0.0)) for f in range(6)]
                for matrix, viewport, eye, axis in faces:
                    gpu.state.viewport_set(*viewport)
                    gs.draw_distances(shader, matrix, eye, axis, casters)
        self.info = gs.float_texture(info)
        self.key = key


def requests_of(lights, limit=MAX_SHADOW_MAPS):
    """The shadow-map requests of preview_lights' value _lights_ and the row of each light
    (-1: unshadowed): (requests, point_rows, spot_rows, sun_rows, dropped), _dropped_ the
    number of shadowed lights past _limit_ (left unshadowed)."""
    flags = lights.get("shadows") or {}
    requests, dropped = [], 0
    rows = {}
    for kind, vectors, key in (('CUBE', lights["positions"], "points"),
                               ('CUBE', lights["spots"]["positions"], "spots"),
                               ('SUN', lights["suns"]["directions"], "suns")):
        shadowed = flags.get(key) or ()
        out = []
        for i, vector in enumerate(vectors):
            if i < len(shadowed) and shadowed[i]:
                if len(requests) < limit:
                    out.append(len(requests))
                    requests.append((kind, tuple(vector)))
                    continue
                dropped += 1
            out.append(-1)
        rows[key] = out
    return requests, rows["points"], rows["spots"], rows["suns"], dropped
