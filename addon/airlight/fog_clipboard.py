"""Fog copy/paste by screen rectangle (Zhou et al. 2007, "Fogshop", section 6).

- `airlight.fog_select_rect`: drag a rectangle in the 3D viewport; the Gaussians of the
  active fog object whose centres project inside it are selected (Shift+drag adds,
  Ctrl+drag removes). The selection is a boolean point attribute "airlight_selected" on
  the fog mesh, so it saves and undoes with the object.
- `airlight.fog_copy`: the selected Gaussians -> the fog clipboard, in world space (the
  object's transform applied, scales divided by its uniform scale as fog_object.gather
  does).
- `airlight.fog_paste`: the clipboard into the active fog object, its centroid at the 3D
  cursor, the relative layout kept; the pasted Gaussians become the selection.
- `airlight.fog_move`: the selected Gaussians follow the mouse in the view plane through
  their centroid; Enter/click confirms, Esc/right-click restores.

The clipboard is module state of this Python session: it is NOT saved with the .blend
and is not affected by undo (like the system clipboard). Every operator is one undo
step. The geometry is in pure functions (`select_in_rect`, `copy_selection`, `paste`,
`move`), tested headless; the operators only feed them Blender data and events.
"""

import bpy
import numpy as np
from bpy.props import EnumProperty

from . import brush_ops, fog_object

SELECTED_ATTR = "airlight_selected"

# ---- pure functions ---------------------------------------------------------------------


def select_in_rect(centres_world, view_projection, region_size, rect):
    """Mask (n,) of the _centres_world_ (n, 3) whose projection under the 4x4
    _view_projection_ (world -> clip) lands inside the pixel rectangle _rect_ =
    (x0, y0, x1, y1) of a region of size (width, height); corners in any order, edges
    inclusive. Centres behind the viewer (clip w <= 0) are never selected."""
    width, height = region_size
    xy, in_front = brush_ops.project_points(centres_world, view_projection, width, height)
    x0, y0, x1, y1 = (float(v) for v in rect)
    lo = np.array([min(x0, x1), min(y0, y1)])
    hi = np.array([max(x0, x1), max(y0, y1)])
    return in_front & np.all((xy >= lo) & (xy <= hi), axis=1)


def copy_selection(arrays, mask):
    """Clipboard of the masked Gaussians: dict of copied numpy arrays "centres" (k, 3)
    (world space), "scales" (k,), "amplitudes" (k,). _arrays_ = (centres, scales,
    amplitudes) in world space."""
    centres, scales, amplitudes = arrays
    mask = np.asarray(mask, dtype=bool)
    return {
        "centres": np.array(np.asarray(centres, dtype=np.float64).reshape(-1, 3)[mask]),
        "scales": np.array(np.asarray(scales, dtype=np.float64)[mask]),
        "amplitudes": np.array(np.asarray(amplitudes, dtype=np.float64)[mask]),
    }


def paste(clipboard, offset=None, target=None):
    """World-space (centres, scales, amplitudes) of a paste of _clipboard_: centres moved
    by _offset_, or (given _target_ instead) so that their centroid (mean) lands on
    _target_. The relative layout, scales and amplitudes are kept."""
    centres = np.asarray(clipboard["centres"], dtype=np.float64).reshape(-1, 3)
    if (offset is None) == (target is None):
        raise ValueError("paste needs exactly one of offset or target")
    if target is not None:
        if len(centres) == 0:
            offset = np.zeros(3)
        else:
            offset = np.asarray(target, dtype=np.float64) - centres.mean(axis=0)
    return (centres + np.asarray(offset, dtype=np.float64).reshape(3),
            np.array(clipboard["scales"], dtype=np.float64),
            np.array(clipboard["amplitudes"], dtype=np.float64))


def move(arrays, mask, offset):
    """(centres, scales, amplitudes) with the masked centres moved by _offset_ (3,);
    new arrays, the input is not modified."""
    centres, scales, amplitudes = arrays
    centres = np.array(centres, dtype=np.float64).reshape(-1, 3)
    centres[np.asarray(mask, dtype=bool)] += np.asarray(offset, dtype=np.float64).reshape(3)
    return centres, np.array(scales, dtype=np.float64), np.array(amplitudes, dtype=np.float64)


# ---- Blender data -----------------------------------------------------------------------

# The fog clipboard: world-space arrays from copy_selection, or None. Session state only.
_clipboard = {"data": None}


def clipboard():
    return _clipboard["data"]


def read_selection(obj):
    """Boolean mask (n,) of the fog object's selected Gaussians (all False without the
    attribute)."""
    mesh = obj.data
    n = len(mesh.vertices)
    mask = np.zeros(n, dtype=bool)
    attr = mesh.attributes.get(SELECTED_ATTR)
    if attr is not None and attr.domain == 'POINT' and attr.data_type == 'BOOLEAN' and n:
        attr.data.foreach_get("value", mask)
    return mask


def write_selection(obj, mask):
    """Stores _mask_ as the boolean point attribute "airlight_selected", in bulk."""
    mesh = obj.data
    attr = mesh.attributes.get(SELECTED_ATTR)
    if attr is not None and (attr.domain != 'POINT' or attr.data_type != 'BOOLEAN'):
        mesh.attributes.remove(attr)
        attr = None
    if attr is None:
        attr = mesh.attributes.new(SELECTED_ATTR, 'BOOLEAN', 'POINT')
    mask = np.ascontiguousarray(mask, dtype=bool).reshape(-1)
    if len(mask) != len(mesh.vertices):
        raise ValueError(f"selection has {len(mask)} entries for {len(mesh.vertices)} Gaussians")
    attr.data.foreach_set("value", mask)
    mesh.update()


def read_world(obj):
    """World-space (centres, scales, amplitudes) of a fog object (as fog_object.gather)."""
    centres, scales, amplitudes = fog_object.read(obj)
    matrix = np.array(obj.matrix_world, dtype=np.float64)
    s = fog_object.uniform_scale(matrix[:3, :3])
    return centres @ matrix[:3, :3].T + matrix[:3, 3], scales / s, amplitudes


def _to_local(obj, centres_world, scales_world):
    matrix = np.array(obj.matrix_world, dtype=np.float64)
    s = fog_object.uniform_scale(matrix[:3, :3])
    local = (np.asarray(centres_world) - matrix[:3, 3]) @ np.linalg.inv(matrix[:3, :3]).T
    return local, np.asarray(scales_world) * s


def _object_poll(cls, context, need_view3d, edits=True):
    """The clipboard operators' poll; _edits_: the operator writes the active fog object
    (selection, paste, move), which linked data cannot keep (fog_object.edit_problem)."""
    if need_view3d and (context.area is None or context.area.type != 'VIEW_3D'):
        cls.poll_message_set("Run from a 3D viewport")
        return False
    if context.mode != 'OBJECT':
        cls.poll_message_set("Switch to Object Mode")
        return False
    if not fog_object.is_fog_object(context.active_object):
        cls.poll_message_set("Make a fog object active (Add > Airlight Fog Object)")
        return False
    return not edits or fog_object.poll_editable(cls, context.active_object)


# ---- drawing ----------------------------------------------------------------------------

_draw_handles = set()
_draw_count = [0]


class _DrawState:
    def __init__(self, region_pointer):
        self.region_pointer = region_pointer
        self.rect = None              # (x0, y0, x1, y1) region pixels
        self.points = np.zeros((0, 3))  # world space, drawn projected


def _draw_callback(state):
    outline = None
    if state.rect is not None:
        x0, y0, x1, y1 = state.rect
        outline = np.array([(x0, y0), (x1, y0), (x1, y1), (x0, y1), (x0, y0)])
    if brush_ops.draw_overlay(state, outline, (1.0, 1.0, 1.0, 0.9), (1.0, 0.6, 0.1, 0.9)):
        _draw_count[0] += 1


class _ModalInView:
    """Draw handler, header/status text and mouse coordinates of the modal tools."""
    hint = ""

    def _start(self, context, event):
        self._area = context.area
        self._region = brush_ops._window_region(context.area)
        if self._region is None or context.space_data.region_3d is None:
            self.report({'ERROR'}, "No 3D viewport region to work in")
            return False
        self._rv3d = context.space_data.region_3d
        self._object = context.active_object
        self._state = _DrawState(self._region.as_pointer())
        self._handle = bpy.types.SpaceView3D.draw_handler_add(
            _draw_callback, (self._state,), 'WINDOW', 'POST_PIXEL')
        _draw_handles.add(self._handle)
        self._set_text(context, self.hint)
        context.window_manager.modal_handler_add(self)
        self._area.tag_redraw()
        return True

    def _mouse(self, event):
        return (float(event.mouse_x - self._region.x), float(event.mouse_y - self._region.y))

    def _inside(self, xy):
        return 0 <= xy[0] < self._region.width and 0 <= xy[1] < self._region.height

    def _set_text(self, context, text):
        if self._area is not None:
            self._area.header_text_set(text)
        if context.workspace is not None:
            context.workspace.status_text_set(text)

    def _cleanup(self, context):
        brush_ops.remove_draw_handle(_draw_handles, self._handle)
        self._handle = None
        self._set_text(context, None)
        self._area.tag_redraw()

    def modal(self, context, event):
        try:
            return self._modal(context, event)
        except Exception:
            self._cleanup(context)
            raise


# ---- operators --------------------------------------------------------------------------


class AIRLIGHT_OT_fog_select_rect(_ModalInView, bpy.types.Operator):
    """Select the Gaussians of the active fog object whose centres lie in a screen
    rectangle (left-drag; Shift adds, Ctrl removes, Esc cancels)"""
    bl_idname = "airlight.fog_select_rect"
    bl_label = "Select Fog (Rectangle)"
    bl_options = {'REGISTER', 'UNDO'}
    hint = ("Fog Select: left-drag a rectangle (Shift adds, Ctrl removes), "
            "Esc/right-click cancels")

    mode: EnumProperty(
        name="Mode",
        description="How the rectangle combines with the current selection",
        items=(('SET', "Set", "Replace the selection"),
               ('ADD', "Add", "Add to the selection"),
               ('SUBTRACT', "Subtract", "Remove from the selection")),
        default='SET',
    )

    @classmethod
    def poll(cls, context):
        return _object_poll(cls, context, need_view3d=True)

    def invoke(self, context, event):
        if not self._start(context, event):
            return {'CANCELLED'}
        self._anchor = None
        if event.type == 'LEFTMOUSE' and event.value == 'PRESS':
            self._begin(event)
        return {'RUNNING_MODAL'}

    def _begin(self, event):
        self._anchor = self._mouse(event)
        if event.shift:
            self.mode = 'ADD'
        elif event.ctrl:
            self.mode = 'SUBTRACT'
        self._state.rect = self._anchor + self._anchor

    def _modal(self, context, event):
        self._area.tag_redraw()
        if event.type in {'ESC', 'RIGHTMOUSE'} and event.value == 'PRESS':
            self._cleanup(context)
            return {'CANCELLED'}
        if self._anchor is None:
            if event.type == 'LEFTMOUSE' and event.value == 'PRESS':
                if not self._inside(self._mouse(event)):
                    return {'PASS_THROUGH'}  # the sidebar, header or another editor
                self._begin(event)
                return {'RUNNING_MODAL'}
            return {'PASS_THROUGH'}  # navigate the view before dragging
        if event.type in {'MOUSEMOVE', 'INBETWEEN_MOUSEMOVE'}:
            self._state.rect = self._anchor + self._mouse(event)
            return {'RUNNING_MODAL'}
        if event.type == 'LEFTMOUSE' and event.value == 'RELEASE':
            rect = self._anchor + self._mouse(event)
            self._cleanup(context)
            obj = self._object
            centres, _, _ = read_world(obj)
            inside = select_in_rect(centres, np.array(self._rv3d.perspective_matrix),
                                    (self._region.width, self._region.height), rect)
            old = read_selection(obj)
            if self.mode == 'ADD':
                new = old | inside
            elif self.mode == 'SUBTRACT':
                new = old & ~inside
            else:
                new = inside
            write_selection(obj, new)
            self.report({'INFO'}, f"{int(new.sum())} of {len(new)} Gaussians selected")
            return {'FINISHED'}
        return {'RUNNING_MODAL'}


class AIRLIGHT_OT_fog_copy(bpy.types.Operator):
    """Copy the selected Gaussians of the active fog object to the fog clipboard (kept
    for this session only, not saved)"""
    bl_idname = "airlight.fog_copy"
    bl_label = "Copy Fog"
    bl_options = {'REGISTER', 'UNDO'}

    @classmethod
    def poll(cls, context):
        return _object_poll(cls, context, need_view3d=False, edits=False)

    def execute(self, context):
        obj = context.active_object
        mask = read_selection(obj)
        if not mask.any():
            self.report({'WARNING'}, f"No Gaussians of '{obj.name}' selected: drag a rectangle "
                                     "with Select Fog first")
            return {'CANCELLED'}
        _clipboard["data"] = copy_selection(read_world(obj), mask)
        colors = fog_object.read_colors(obj.data)  # per-Gaussian albedo travels with the copy
        if colors is not None:
            _clipboard["data"]["colors"] = np.array(colors[np.asarray(mask, dtype=bool)])
        self.report({'INFO'}, f"{int(mask.sum())} Gaussians copied")
        return {'FINISHED'}


class AIRLIGHT_OT_fog_paste(bpy.types.Operator):
    """Paste the fog clipboard into the active fog object, centred on the 3D cursor
    (the pasted Gaussians become the selection)"""
    bl_idname = "airlight.fog_paste"
    bl_label = "Paste Fog"
    bl_options = {'REGISTER', 'UNDO'}

    @classmethod
    def poll(cls, context):
        if not _object_poll(cls, context, need_view3d=False):
            return False
        if clipboard() is None or len(clipboard()["centres"]) == 0:
            cls.poll_message_set("The fog clipboard is empty: select Gaussians and Copy Fog first")
            return False
        return True

    def execute(self, context):
        obj = context.active_object
        centres, scales, amplitudes = paste(clipboard(), target=np.array(context.scene.cursor.location))
        local, local_scales = _to_local(obj, centres, scales)
        n_old = len(obj.data.vertices)
        # append keeps the object's colours (and gives uncoloured Gaussians the fog colour).
        fog_object.append(obj, local, local_scales, amplitudes, colors=clipboard().get("colors"))
        mask = np.zeros(n_old + len(local), dtype=bool)
        mask[n_old:] = True
        write_selection(obj, mask)
        self.report({'INFO'}, f"{len(local)} Gaussians pasted into '{obj.name}'")
        return {'FINISHED'}


class AIRLIGHT_OT_fog_move(_ModalInView, bpy.types.Operator):
    """Move the selected Gaussians of the active fog object with the mouse in the view
    plane (Enter/click confirms, Esc/right-click restores)"""
    bl_idname = "airlight.fog_move"
    bl_label = "Move Fog"
    bl_options = {'REGISTER', 'UNDO'}
    hint = "Fog Move: move the mouse, Enter/click confirms, Esc/right-click restores"

    @classmethod
    def poll(cls, context):
        return _object_poll(cls, context, need_view3d=True)

    def invoke(self, context, event):
        obj = context.active_object
        mask = read_selection(obj)
        if not mask.any():
            self.report({'WARNING'}, f"No Gaussians of '{obj.name}' selected: drag a rectangle "
                                     "with Select Fog first")
            return {'CANCELLED'}
        if not self._start(context, event):
            return {'CANCELLED'}
        self._mask = mask
        self._local, _, _ = fog_object.read(obj)  # the original, restored on cancel
        world, _, _ = read_world(obj)
        self._pivot = world[mask].mean(axis=0)
        self._start_xy = self._mouse(event)
        self._offset = np.zeros(3)
        self._state.points = world[mask]
        self._world_selected = world[mask]
        return {'RUNNING_MODAL'}

    def _plane_point(self, xy):
        from bpy_extras import view3d_utils
        p = view3d_utils.region_2d_to_location_3d(self._region, self._rv3d, xy, self._pivot)
        return np.array(p, dtype=np.float64)

    def _apply(self, world_offset):
        matrix = np.array(self._object.matrix_world, dtype=np.float64)
        local_offset = np.linalg.inv(matrix[:3, :3]) @ world_offset
        centres, _, _ = move((self._local, np.zeros(len(self._local)), np.zeros(len(self._local))),
                             self._mask, local_offset)
        # Only the coordinates change: the attributes (and the selection) stay.
        mesh = self._object.data
        mesh.vertices.foreach_set("co", centres.astype(np.float32).ravel())
        mesh.update()
        self._state.points = self._world_selected + world_offset

    def _modal(self, context, event):
        self._area.tag_redraw()
        if event.type in {'ESC', 'RIGHTMOUSE'} and event.value == 'PRESS':
            self._apply(np.zeros(3))
            self._cleanup(context)
            return {'CANCELLED'}
        if event.type in {'MOUSEMOVE', 'INBETWEEN_MOUSEMOVE'}:
            self._offset = self._plane_point(self._mouse(event)) - self._plane_point(self._start_xy)
            self._apply(self._offset)
            self._set_text(context, "Fog Move: offset ({:.3f}, {:.3f}, {:.3f}) m; Enter/click "
                                    "confirms, Esc/right-click restores".format(*self._offset))
            return {'RUNNING_MODAL'}
        if event.type in {'LEFTMOUSE', 'RET', 'NUMPAD_ENTER'} and event.value == 'PRESS':
            self._cleanup(context)
            return {'FINISHED'}
        return {'RUNNING_MODAL'}


classes = (AIRLIGHT_OT_fog_select_rect, AIRLIGHT_OT_fog_copy, AIRLIGHT_OT_fog_paste,
           AIRLIGHT_OT_fog_move)


def register():
    for cls in classes:
        bpy.utils.register_class(cls)


def unregister():
    for handle in list(_draw_handles):
        brush_ops.remove_draw_handle(_draw_handles, handle)
    for cls in reversed(classes):
        bpy.utils.unregister_class(cls)
