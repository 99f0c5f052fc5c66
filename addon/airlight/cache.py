"""Where baked fog passes live on disk, and the EXR layout the compositor reads."""

import os
import tempfile
import threading
import time
import zlib
from typing import NamedTuple

import bpy
import numpy as np

from . import native
# EXR layout (names.py): layer "Fog" with passes "Airlight" and "Transmittance", and with
# surface shading Surface_<light group> (attenuation - 1 per fogged light) and SurfaceGlow
# (Lambert glow per unit DiffCol): see surface.py.
from .names import LAYER_PREFIX, PASS_AIRLIGHT, PASS_TRANSMITTANCE


class CacheError(RuntimeError):
    """The cache folder cannot be used; the message says why."""


def cache_dir(scene):
    """Absolute cache folder. '//' with an unsaved .blend falls back to Blender's temp dir."""
    path = scene.airlight.cache_dir or "//airlight_cache/"
    if path.startswith("//") and not bpy.data.filepath:
        path = os.path.join(bpy.app.tempdir or "/tmp", path[2:] or "airlight_cache")
    return os.path.normpath(bpy.path.abspath(path))


def cache_path(scene, frame):
    """Where frame `frame`'s fog passes go: <cache_dir>/fog_####.exr."""
    return os.path.join(cache_dir(scene), f"fog_{frame:04d}.exr")


def ensure_parent_dir(filepath):
    folder = os.path.dirname(filepath) or "."
    try:
        os.makedirs(folder, exist_ok=True)
    except OSError as ex:
        raise CacheError(f"Cannot create the fog cache folder '{folder}': {ex.strerror or ex}. "
                         "Choose another Cache Folder in the Airlight Fog panel.") from None
    if not os.access(folder, os.W_OK):
        raise CacheError(f"The fog cache folder '{folder}' is not writable. "
                         "Choose another Cache Folder in the Airlight Fog panel.")


def pass_dict(airlight, transmittance, extra=None):
    """{pass name: (H, W, 3) float32} as the EXR's layer "Fog" holds them."""
    passes = {PASS_AIRLIGHT: airlight, PASS_TRANSMITTANCE: transmittance}
    passes.update(extra or {})
    return passes


def write_passes(filepath, airlight, transmittance, extra=None, half=False):
    """write_pass_dict of the two passes and those in _extra_."""
    write_pass_dict(filepath, pass_dict(airlight, transmittance, extra), half)


def write_pass_dict(filepath, passes, half=False):
    """Writes _passes_ (pass_dict: Airlight, Transmittance and e.g. surface.py's
    Surface_<group> and SurfaceGlow) as one multilayer EXR (through `_native.write_exr`:
    layer "Fog", pass <name>); _half_: 16-bit floats (Pass Precision).
    Written to a temporary file beside it and renamed over it (atomic on one file system),
    so a compositor or another farm task reading the file sees a whole one, never half of
    it, and two tasks writing one frame each leave a whole file."""
    ensure_parent_dir(filepath)
    tmp = f"{filepath}.{os.getpid()}.{threading.get_ident()}.tmp"
    try:
        native.get().write_exr(tmp, passes, layer_prefix=LAYER_PREFIX, half=half)
        os.replace(tmp, filepath)
    except (RuntimeError, OSError) as ex:
        try:
            os.remove(tmp)
        except OSError:
            pass
        raise CacheError(f"Cannot write the fog passes to '{filepath}': {ex}") from None


class PassFile(NamedTuple):
    """A frame's passes still to be written: where, {name: (H, W, 3) float32}, 16-bit."""
    filepath: str
    passes: dict
    half: bool


def write_files(files):
    """Writes the PassFiles _files_ (write_pass_dict; any thread: the native writer releases
    the GIL); returns (seconds, None) or (seconds, why one could not be written)."""
    t0 = time.perf_counter()
    try:
        for file in files:
            write_pass_dict(file.filepath, file.passes, file.half)
    except CacheError as ex:
        return time.perf_counter() - t0, str(ex)
    except Exception as ex:  # reported by the caller, never lost with a thread
        return time.perf_counter() - t0, f"{type(ex).__name__}: {ex}"
    return time.perf_counter() - t0, None


def neutral_path(scene, width, height, extra_names=()):
    """Passes that leave an image unchanged (Airlight 0, Transmittance 1), written on demand.

    The compositor links the Image node's pass outputs only when the file exposes them,
    and a render reads the links as they were before render_pre ran, so the node tree is
    set up on this file until a real bake replaces it.
    """
    extra_names = tuple(extra_names)
    # Surface passes (names depend on the lights) are 0: no correction, no glow.
    suffix = f"_{zlib.crc32(chr(0).join(extra_names).encode()):08x}" if extra_names else ""
    name = f"fog_neutral_{width}x{height}{suffix}.exr"
    filepath = os.path.join(cache_dir(scene), name)
    try:
        ensure_parent_dir(filepath)
    except CacheError:
        # The passes are constant: where the cache folder cannot be written (the bake that
        # failed there is why they are needed), the system's temporary folder holds them, so
        # the compositor never keeps reading an earlier frame's bake.
        filepath = os.path.join(tempfile.gettempdir(), "airlight_neutral", name)
    if not os.path.exists(filepath):
        # The ones and the writer's interleaved copy of every pass take memory (the zeros stay
        # unmapped pages): refuse before allocating what the machine does not have.
        needed = 4.0 * 3 * width * height * (1 + 2 + len(extra_names))
        available = native.get().available_memory()
        if needed > available:
            raise CacheError(f"The neutral fog passes for {width} x {height} pixels need about "
                             f"{needed / 1e9:.1f} GB but only {available / 1e9:.1f} GB of memory is "
                             "available; lower the resolution")
        zeros = np.zeros((height, width, 3), np.float32)
        write_passes(filepath, zeros, np.ones((height, width, 3), np.float32),
                     {name: zeros for name in extra_names})
    return filepath
