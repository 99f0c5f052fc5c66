"""pytest setup for the native module: makes `import _native` work.

The module is looked up in $AIRLIGHT_NATIVE_DIR first (a private build, e.g.
cmake -DAIRLIGHT_MODULE_DIR=...), then in addon/airlight where the build writes it.
"""
import os
import sys

_ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, os.path.join(_ROOT, "addon", "airlight"))
if os.environ.get("AIRLIGHT_NATIVE_DIR"):
    sys.path.insert(0, os.environ["AIRLIGHT_NATIVE_DIR"])


def pytest_collect_file(parent, file_path):
    """Collect the intent-numbered files (test01_import.py, ...) whatever python_files says."""
    import fnmatch

    import pytest

    if file_path.suffix != ".py" or not fnmatch.fnmatch(file_path.name, "test[0-9]*.py"):
        return None
    patterns = parent.config.getini("python_files")
    if any(fnmatch.fnmatch(file_path.name, p) for p in patterns) or parent.session.isinitpath(file_path):
        return None  # pytest collects it already (a file named on the command line too)
    return pytest.Module.from_parent(parent, path=file_path)
