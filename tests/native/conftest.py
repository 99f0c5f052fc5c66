"""pytest setup for the native tests: makes `import _native` work, or stops the run.

The module is looked up in $AIRLIGHT_NATIVE_DIR when that is set (a private build, e.g.
cmake -DAIRLIGHT_MODULE_DIR=..., as `make sanitize` does), else in addon/airlight where
`make build` writes it, and nowhere else. It is imported here, before any test is
collected: a module that is missing, fails to load, or is found anywhere but in that
directory fails the whole run with the directory searched. The native tests never skip.

Files are collected by pytest's default rules (test_*.py). The helpers beside them are
plain modules that the tests import:
  scene_util.py       cameras, pixel rays, meshes (planes, merged parts), Gaussian clouds;
  scene_floor.py, scene_surface.py, scene_fog_objects.py
                      the scenes that more than one test file bakes;
  reference_util.py   independent numpy/scipy references (phase functions, eq. 31, fog-layer
                      paths, Sun's surface G) and the relative-error statistics;
  stability_cases.py  the stability table (also printed by benchmarks/stability_table.py).
"""
import os
import sys

import pytest

_ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
_NATIVE = pytest.StashKey()
NATIVE_DIR = os.path.abspath(os.environ.get("AIRLIGHT_NATIVE_DIR") or os.path.join(_ROOT, "addon", "airlight"))


def _import_native():
    """Import `_native` from NATIVE_DIR; a pytest.UsageError (the run fails) with the
    directory searched and the reason if it is not there or does not load."""
    hint = ("build it with `make build`" if "AIRLIGHT_NATIVE_DIR" not in os.environ else
            "point AIRLIGHT_NATIVE_DIR at a directory holding a _native build, or unset it to test "
            "the one `make build` writes to addon/airlight")
    sys.path.insert(0, NATIVE_DIR)
    try:
        import _native
    except Exception as e:  # ImportError, or whatever a broken module raises while it loads
        listing = sorted(f for f in os.listdir(NATIVE_DIR) if f.startswith("_native")) \
            if os.path.isdir(NATIVE_DIR) else None
        found = "the directory does not exist" if listing is None else f"_native files there: {listing or 'none'}"
        raise pytest.UsageError(f"the native module _native does not import from {NATIVE_DIR} ({found}): "
                                f"{type(e).__name__}: {e}\n  {hint}") from None
    where = os.path.dirname(os.path.abspath(_native.__file__))
    if not (os.path.isdir(NATIVE_DIR) and os.path.samefile(where, NATIVE_DIR)):
        raise pytest.UsageError(f"_native was imported from {_native.__file__}, not from {NATIVE_DIR} "
                                f"(no module there)\n  {hint}")
    return _native


def pytest_configure(config):
    """Session start: import the module once, before any test file is collected."""
    config.stash[_NATIVE] = _import_native()


def pytest_report_header(config):
    native = config.stash[_NATIVE]
    return f"airlight _native {native.__version__}: {native.__file__}"
