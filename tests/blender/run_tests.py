"""Runs the headless Blender tests with pytest inside Blender and hands back its exit code.

    tools/blender.sh -b --python tests/blender/run_tests.py -- [pytest args]

Blender's own exit code ignores sys.exit() raised from a --python script, so the code
is passed with os._exit after flushing output.
"""
import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))


def main():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    try:
        import pytest
    except ImportError as ex:
        print(f"run_tests: pytest is not importable in Blender's Python: {ex}", flush=True)
        return 2
    args = ["-p", "no:cacheprovider", "--rootdir", HERE, HERE] if not any(
        a.endswith(".py") or os.path.isdir(a) or "::" in a for a in argv) else ["-p", "no:cacheprovider"]
    return int(pytest.main(args + argv))


if __name__ == "__main__":
    code = 1
    try:
        code = main()
    finally:
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code)
