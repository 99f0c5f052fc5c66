"""The docs name only what exists: every repository path, file name, C++ test and pytest
selection that README.md, docs/*.md and the folders' README.md files cite in backticks.

Pure Python (no `_native`): it reads the Markdown and the sources.
  - a path under native/, tests/, benchmarks/, addon/, shaders/, tools/ or docs/ exists
    relative to the repository (a `<placeholder>` or `*` in it is not checked);
  - a bare file name (`splat.cpp`, `bench_rbf.py`) is the name of some file in the tree;
  - the pattern of `ctest -R PATTERN` matches some `Suite.Test` that a TEST/TEST_F/TEST_P
    in native/**/*_test.cpp defines, and every `Suite.Test` written in backticks is one
    (but `Fog.<pass>`, the EXR's passes);
  - the `-k` of `pytest tests/…/file.py -k NAME` names a test function of that file.
"""
import glob
import os
import re

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
ROOTS = ("native", "tests", "benchmarks", "addon", "shaders", "tools", "docs")
SKIP_DIRS = {".git", "build", "out", "__pycache__"}
# Files named in the docs that are not in the tree: Blender's own sources, and the logs the
# GPU harness writes (benchmarks/gpu_preview/README.md).
EXTERNAL_FILES = {"glsl_shader_defines.glsl", "GPU_shader_shared_utils.h",
                  "nvidia_smi.txt", "log_small.txt", "log_extra.txt"}
EXR_LAYERS = {"Fog"}  # `Fog.SurfaceGlow` is a pass of the EXR, not a test

_BACKTICKED = re.compile(r"`([^`\n]+)`")
_PATH = re.compile(r"(?<![\w./-])((?:%s)/[\w./<>*…-]*)" % "|".join(ROOTS))
_FILE_NAME = re.compile(r"^[\w-]+\.(?:py|cpp|h|glsl|md|sh|blend|txt|cmake)$")
_CTEST = re.compile(r"ctest\b[^`]*?-R\s+('[^']*'|\"[^\"]*\"|\S+)")
_TEST_NAME = re.compile(r"^([A-Z]\w*)\.((?:DISABLED_)?[A-Z]\w*)$")
_PYTEST_K = re.compile(r"pytest\s+(tests/\S+\.py)\s+[^`]*?-k\s+(\S+)")
_CPP_TEST = re.compile(r"^\s*TEST(?:_F|_P)?\(\s*(\w+)\s*,\s*(\w+)\s*\)", re.M)


def _docs():
    files = [os.path.join(ROOT, "README.md")]
    files += sorted(glob.glob(os.path.join(ROOT, "docs", "*.md")))
    files += sorted(glob.glob(os.path.join(ROOT, "native", "**", "README.md"), recursive=True))
    files += sorted(glob.glob(os.path.join(ROOT, "benchmarks", "**", "README.md"), recursive=True))
    return files


def _spans():
    """(doc, line number, backticked text) for every span in the docs."""
    for doc in _docs():
        with open(doc, encoding="utf-8") as f:
            for n, line in enumerate(f, 1):
                for m in _BACKTICKED.finditer(line):
                    span = m.group(1)
                    if line.lstrip().startswith("|"):  # in a table a code span writes | as \|
                        span = span.replace("\\|", "|")
                    yield os.path.relpath(doc, ROOT), n, span


def _file_names():
    names = set()
    for top, dirs, files in os.walk(ROOT):
        dirs[:] = [d for d in dirs if d not in SKIP_DIRS]
        names.update(files)
    return names


def _cpp_tests():
    names = set()
    for path in glob.glob(os.path.join(ROOT, "native", "**", "*_test.cpp"), recursive=True):
        with open(path, encoding="utf-8") as f:
            names.update(f"{suite}.{test}" for suite, test in _CPP_TEST.findall(f.read()))
    return names


def _pytest_functions(path):
    with open(os.path.join(ROOT, path), encoding="utf-8") as f:
        return re.findall(r"^\s*def (test\w*)\(", f.read(), re.M)


def test_paths_exist():
    missing = []
    for doc, n, span in _spans():
        for m in _PATH.finditer(span):
            path = m.group(1).rstrip(".,;:)")
            if any(c in path for c in "<>*…"):
                continue
            if not os.path.exists(os.path.join(ROOT, path)):
                missing.append(f"{doc}:{n}: {path}")
    assert not missing, "paths the docs cite that do not exist:\n" + "\n".join(missing)


def test_file_names_exist():
    names = _file_names()
    missing = [f"{doc}:{n}: {span}" for doc, n, span in _spans()
               if _FILE_NAME.match(span) and span not in names | EXTERNAL_FILES]
    assert not missing, "file names the docs cite that are no file of the tree:\n" + "\n".join(missing)


def test_ctest_names_exist():
    tests = _cpp_tests()
    assert len(tests) > 100, "no GoogleTest cases found under native/"
    bad = []
    for doc, n, span in _spans():
        for m in _CTEST.finditer(span):
            pattern = m.group(1).strip("'\"")
            if pattern.startswith("<") or pattern == "…":  # a placeholder: `ctest -R <Suite.Test>`
                continue
            # ctest -R takes a CMake regular expression; for what the docs write, Python's is the same.
            if not any(re.search(pattern, t) for t in tests):
                bad.append(f"{doc}:{n}: ctest -R {pattern} matches no test")
        name = _TEST_NAME.match(span)
        if name and name.group(1) not in EXR_LAYERS and span not in tests:
            bad.append(f"{doc}:{n}: {span} is no test")
    assert not bad, "C++ tests the docs cite that do not exist:\n" + "\n".join(bad)


def test_pytest_selections_exist():
    bad = []
    for doc, n, span in _spans():
        for m in _PYTEST_K.finditer(span):
            path, expr = m.group(1), m.group(2).strip("'\"")
            if not os.path.exists(os.path.join(ROOT, path)):
                continue  # test_paths_exist reports it
            functions = _pytest_functions(path)
            words = [w for w in re.split(r"\W+", expr) if w and w not in ("and", "or", "not")]
            for w in words:
                if not any(w in f for f in functions):
                    bad.append(f"{doc}:{n}: pytest {path} -k {w} selects no test")
    assert not bad, "pytest selections the docs cite that select nothing:\n" + "\n".join(bad)
