"""Installs fake_native as airlight._native in this Blender process (development only).

Run with `--python tests/blender/support/use_fake_native.py` before the render args.
Does nothing when the real module imports.
"""
import os
import sys

import addon_utils


def install():
    import airlight
    from airlight import native
    if native.available():
        return False
    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
    import fake_native
    sys.modules["airlight._native"] = fake_native
    native._tried, native._module, native._error = False, None, None
    native.load()
    print("Airlight tests: using the pure-numpy fake _native", flush=True)
    return True


if addon_utils.check("airlight")[1]:
    install()
