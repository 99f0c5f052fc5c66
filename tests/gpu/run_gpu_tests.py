"""Runs the GPU tests (pytest) inside a windowed Blender and hands back the exit code.

    xvfb-run -a -s "-screen 0 1280x1024x24" tools/blender.sh --python tests/gpu/run_gpu_tests.py -- [pytest args]

`blender -b` refuses GPU drawing, so Blender runs with a (virtual) window; the tests run
while this script executes (offscreen drawing and `wm.redraw_timer` need no event loop)
and Blender then exits with pytest's status without entering its main loop, so no GUI is
left running. Without tools/blender.sh (add-on not installed), the repository's addon/
folder is put on sys.path so `import airlight` finds the package and its _native module.
"""

import os
import sys
import traceback

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.normpath(os.path.join(HERE, "..", ".."))


def _pytest_args():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    return [HERE, "-p", "no:cacheprovider", "-o", "console_output_style=classic",
            "--rootdir", HERE] + argv


def main():
    try:
        import airlight  # noqa: F401  (enabled by tools/blender.sh)
    except ImportError:
        sys.path.insert(0, os.path.join(REPO, "addon"))
    sys.path.insert(0, HERE)
    import pytest
    return int(pytest.main(_pytest_args()))


if __name__ == "__main__":
    try:
        code = main()
    except BaseException:  # a crash in the harness must fail the run too
        traceback.print_exc()
        code = 3
    sys.stdout.flush()
    sys.stderr.flush()
    # Exit now with pytest's status: Blender's own quit path would return 0.
    os._exit(code)
