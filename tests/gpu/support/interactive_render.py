"""Drives an interactive render (F12 or Ctrl+F12) in a windowed Blender, as a user would,
then exits: 0 when the render completed, 1 when it was cancelled, 2 on a timeout.

    tools/blender.sh file.blend --python interactive_render.py -- still|animation

`bpy.ops.render.render('INVOKE_DEFAULT')` starts the render job, which runs in its own
thread while Blender's main loop goes on (so this needs a window: run under xvfb-run);
a timer polls for the render_complete / render_cancel handlers.
"""

import os
import sys
import time

import bpy

ANIMATION = sys.argv[-1] == "animation"
TIMEOUT_S = 240.0
state = {"started": None, "end": None}


def _complete(*_):
    state["end"] = 0


def _cancel(*_):
    state["end"] = 1


def _tick():
    if state["started"] is None:
        state["started"] = time.monotonic()
        window = bpy.context.window_manager.windows[0]
        with bpy.context.temp_override(window=window, screen=window.screen, area=window.screen.areas[0]):
            result = bpy.ops.render.render('INVOKE_DEFAULT', animation=ANIMATION, write_still=True)
        print(f"interactive_render: render.render -> {result}", flush=True)
        return 0.1
    if state["end"] is not None or time.monotonic() - state["started"] > TIMEOUT_S:
        code = 2 if state["end"] is None else state["end"]
        print(f"interactive_render: exit {code}", flush=True)
        sys.stdout.flush()
        os._exit(code)
    return 0.1


bpy.app.handlers.render_complete.append(_complete)
bpy.app.handlers.render_cancel.append(_cancel)
bpy.app.timers.register(_tick, first_interval=0.5)
