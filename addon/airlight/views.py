"""What a render of the scene makes: its size in pixels, its render region, the pixels the
bake covers, and its views (Stereoscopy) with the camera of each.

A leaf module (numpy only; it reads the scene it is given): the exporter, the bake, the
compositor and the panels all ask it.
"""

import numpy as np


def render_size(scene):
    """Render resolution in pixels after the percentage scale, as Blender computes it."""
    render = scene.render
    width = render.resolution_x * render.resolution_percentage // 100
    height = render.resolution_y * render.resolution_percentage // 100
    return width, height


def render_region(scene):
    """The render region (Render > Format > Render Region) in pixels as Blender renders it:
    (x0, y0, x1, y1) within render_size(), y counted from the bottom, or None without one.
    Blender truncates border x render size in single precision (render pipeline,
    R_BORDER); a region of no pixels is left to the render to refuse ("Image too small")
    and is ignored here, as is one covering the whole frame."""
    render = scene.render
    if not render.use_border:
        return None
    width, height = render_size(scene)
    f32 = np.float32
    x0, x1 = (int(f32(v) * f32(width)) for v in (render.border_min_x, render.border_max_x))
    y0, y1 = (int(f32(v) * f32(height)) for v in (render.border_min_y, render.border_max_y))
    if x1 <= x0 or y1 <= y0 or (x0, y0, x1, y1) == (0, 0, width, height):
        return None
    return x0, y0, x1, y1


# Pixels baked around a render region on each side (within the frame) and dropped after:
# the bake's edge test looks two pixels away (a pixel is an edge when a neighbour's depth
# has a kink), so with this margin the region's pixels bake as in the whole frame's bake.
REGION_MARGIN = 2


def bake_window(scene):
    """The pixels the bake covers, (x0, y0, x1, y1) as render_region (y from the bottom):
    the render region grown by REGION_MARGIN within the frame, or None (the whole frame)."""
    region = render_region(scene)
    if region is None:
        return None
    width, height = render_size(scene)
    x0, y0, x1, y1 = region
    m = REGION_MARGIN
    return max(0, x0 - m), max(0, y0 - m), min(width, x1 + m), min(height, y1 + m)


def region_projection(projection, width, height, region):
    """The projection of the pixels of _region_ ((x0, y0, x1, y1) of a width x height
    frame, y from the bottom) as a frame of their own: the clip-space x, y of the whole
    frame's _projection_ scaled and shifted so that the region spans the new frame's
    [-1, 1] (pixel centres stay on the whole frame's; perspective and orthographic)."""
    x0, y0, x1, y1 = region
    sx, sy = width / (x1 - x0), height / (y1 - y0)
    cx, cy = (x0 + x1) / width - 1.0, (y0 + y1) / height - 1.0
    window = np.array([[sx, 0.0, 0.0, -sx * cx],
                       [0.0, sy, 0.0, -sy * cy],
                       [0.0, 0.0, 1.0, 0.0],
                       [0.0, 0.0, 0.0, 1.0]])
    return window @ projection


def render_views(scene):
    """[(view name, file suffix)] of the views a render of _scene_ makes: with Output >
    Stereoscopy on, its enabled views (Stereo 3D: "left" and "right"; Multi-View: every
    enabled view, each with its own camera), else [(None, "")] (one plain view)."""
    render = scene.render
    if not render.use_multiview:
        return [(None, "")]
    if render.views_format == 'STEREO_3D':
        views = [v for v in render.views if v.name in ("left", "right") and v.use]
    else:
        views = [v for v in render.views if v.use]
    return [(v.name, v.file_suffix) for v in views] or [(None, "")]


def view_camera(scene, view):
    """The camera object that renders _view_ (a name from render_views): the scene camera,
    or in Multi-View format the object named like it with the view's suffix in place of
    another view's suffix (Blender's rule: "Camera_L" -> "Camera_R")."""
    camera = scene.camera
    render = scene.render
    if view is None or camera is None or not render.use_multiview or render.views_format != 'MULTIVIEW':
        return camera
    suffix = render.views[view].file_suffix
    best = None
    for v in render.views:  # (every view, as Blender: the longest suffix the name ends with)
        if v.file_suffix and camera.name.endswith(v.file_suffix):
            if best is None or len(v.file_suffix) >= len(best):
                best = v.file_suffix
    if best is None:
        return camera
    other = scene.objects.get(camera.name[:len(camera.name) - len(best)] + suffix)
    return other if other is not None else camera
