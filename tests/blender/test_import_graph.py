"""The add-on's modules import, and their imports of each other run one way.

Data flows Blender data -> scene_description -> model_choice (the plan) -> scene_export
(`_native.bake`'s arguments) -> bake, preview; names.py and views.py are leaves everyone
may import. A cycle (a module importing one that imports it back, directly or not) would
mean the flow goes back and forth, so the graph of `from . import x` / `from .x import y`
statements, parsed with ast from every module, must have none; and no module imports one
of the package's inside a function (the usual way to hide a cycle). The compiled
`_native`, which native.load() imports on first use by design, is no module of this graph.
"""

import ast
import importlib
import os

import pytest

import airlight

PACKAGE = os.path.dirname(os.path.realpath(airlight.__file__))
MODULES = sorted(name[:-3] for name in os.listdir(PACKAGE) if name.endswith(".py") and name != "__init__.py")
LEAVES = ("names", "views", "light_nodes")


def _imports(module):
    """{imported package module: [(line, inside a function or class)]} of _module_'s
    relative imports."""
    with open(os.path.join(PACKAGE, module + ".py"), encoding="utf-8") as f:
        tree = ast.parse(f.read(), filename=module + ".py")
    found = {}

    def visit(node, nested):
        for child in ast.iter_child_nodes(node):
            inner = nested or isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef, ast.Lambda))
            if isinstance(child, ast.ImportFrom) and child.level == 1:
                names = [child.module.split(".")[0]] if child.module else [alias.name for alias in child.names]
                for name in names:
                    if name in MODULES:
                        found.setdefault(name, []).append((child.lineno, inner))
            visit(child, inner)
    visit(tree, False)
    return found


GRAPH = {module: _imports(module) for module in MODULES}


def _cycle(graph):
    """A list of modules closing a cycle in {module: imported modules}, or None."""
    state, stack = {}, []

    def walk(node):
        state[node] = "open"
        stack.append(node)
        for other in sorted(graph[node]):
            if state.get(other) == "open":
                return stack[stack.index(other):] + [other]
            if other not in state:
                found = walk(other)
                if found:
                    return found
        stack.pop()
        state[node] = "done"
        return None
    for node in sorted(graph):
        if node not in state:
            found = walk(node)
            if found:
                return found
    return None


@pytest.mark.parametrize("module", MODULES)
def test01_every_module_imports(module):
    assert importlib.import_module(f"airlight.{module}").__name__ == f"airlight.{module}"


def test02_the_import_graph_has_no_cycle():
    assert len(MODULES) > 20 and "scene_description" in MODULES
    edges = {module: set(imported) for module, imported in GRAPH.items()}
    cycle = _cycle(edges)
    assert cycle is None, "import cycle: " + " -> ".join(cycle)
    # The graph's reading of itself: a made-up cycle is found.
    assert _cycle(dict(edges, names={"preview"})) is not None


def test03_no_module_imports_the_package_inside_a_function():
    nested = [f"{module}.py:{line} imports {other}" for module, imported in GRAPH.items()
              for other, places in imported.items() for line, inner in places if inner]
    assert not nested, nested


def test04_names_and_views_are_leaves():
    for leaf in LEAVES:
        assert GRAPH[leaf] == {}, (leaf, GRAPH[leaf])


def test05_data_flows_one_way():
    """The description does not know the plan, the plan not the bake's arguments, and none
    of the three the bake, the preview or the panels (what they feed)."""
    def reaches(module, target, seen=()):
        return any(other == target or (other not in seen and reaches(other, target, seen + (module,)))
                   for other in GRAPH[module])
    downstream = ("bake", "render", "preview", "ui", "compositor", "properties")
    for upstream, later in (("scene_description", ("model_choice", "scene_export")),
                            ("model_choice", ("scene_export",)), ("scene_export", ())):
        for target in later + downstream:
            assert not reaches(upstream, target), (upstream, target)
    assert reaches("bake", "scene_description") and reaches("preview", "scene_description")
