"""Finds and imports the compiled `_native` module once, and remembers why it failed.

The add-on registers even when the module is missing (not built, wrong Python): the
bake operators' poll() then fails with `error()` as the reason, and the add-on
preferences show it. Nothing is ever installed at run time.
"""

_module = None
_error = None
_tried = False


def load():
    """Imports `_native` from this package on first use; returns it, or None on failure."""
    global _module, _error, _tried
    if not _tried:
        _tried = True
        try:
            from . import _native
        except Exception as ex:  # ImportError, or an OSError from a missing shared library
            _error = (f"The Airlight native module could not be loaded ({type(ex).__name__}: {ex}). "
                      "Build it with CMake (see README.md) so that "
                      "_native.cpython-311-x86_64-linux-gnu.so lies in the add-on folder.")
        else:
            missing = [name for name in ("bake", "write_exr") if not hasattr(_native, name)]
            if missing:
                _error = ("The Airlight native module is incomplete (missing: "
                          + ", ".join(missing) + "). Rebuild it.")
            else:
                _module = _native
                _use_table_cache(_native)
    return _module


def table_cache_dir():
    """Where the models' tables are kept across processes (native/core/table_cache.h):
    $AIRLIGHT_TABLE_CACHE ("" or "off": none), else $XDG_CACHE_HOME/airlight/tables
    (~/.cache/airlight/tables). A farm's per-frame processes then build each table once."""
    import os
    env = os.environ.get("AIRLIGHT_TABLE_CACHE")
    if env is not None:
        return "" if env.strip().lower() in ("", "off") else env
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return os.path.join(base, "airlight", "tables")


def _use_table_cache(module):
    if hasattr(module, "set_table_cache_dir"):
        module.set_table_cache_dir(table_cache_dir())


def available():
    """True when `_native` imported and provides what the add-on needs."""
    return load() is not None


def error():
    """The reason the module is unavailable, or None."""
    load()
    return _error


def get():
    """Returns the module or raises RuntimeError with the import error text."""
    module = load()
    if module is None:
        raise RuntimeError(_error)
    return module


def version():
    module = load()
    return getattr(module, "__version__", "unknown") if module else None
