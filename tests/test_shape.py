"""The shape of the code (issue 35), read from its syntax trees: no import cycle, no class over
250 lines, no function over 80, no solver module over 500, and the dependency direction
``service -> workflows -> solver``.

Every ``import`` and ``from ... import`` counts, those inside functions (a deferred import
still ties the modules together) and under ``if TYPE_CHECKING`` too. The one exemption: a
package's ``__init__`` importing its own children to re-export them; a name imported from a
package is followed to the child module its ``__init__`` takes it from.
"""
from __future__ import annotations

import ast
from collections.abc import Iterator
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("solver", "workflows", "service")
MAX_CLASS_LINES = 250
MAX_FUNCTION_LINES = 80
MAX_SOLVER_MODULE_LINES = 500

def modules(root: Path, packages: tuple[str, ...] = PACKAGES) -> dict[str, Path]:
    """``{dotted module name: path}`` of every module of ``packages`` under ``root``
    (a package is named by its folder, for its ``__init__.py``)."""
    found = {}
    for package in packages:
        for path in sorted((root / package).rglob("*.py")):
            parts = path.relative_to(root).with_suffix("").parts
            found[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path
    return found


def _is_package(path: Path) -> bool:
    return path.name == "__init__.py"


def _imported(name: str, path: Path, node: ast.ImportFrom | ast.Import) -> Iterator[tuple[str, str]]:
    """``(module, imported name or "")`` of one import statement of module ``name``."""
    if isinstance(node, ast.Import):
        for alias in node.names:
            yield alias.name, ""
        return
    if node.level:
        base = name.split(".") if _is_package(path) else name.split(".")[:-1]
        base = base[:len(base) - (node.level - 1)]
        module = ".".join(base + ([node.module] if node.module else []))
    else:
        module = node.module or ""
    for alias in node.names:
        yield module, alias.name


def _reexports(found: dict[str, Path]) -> dict[tuple[str, str], str]:
    """``{(package, name): child module}`` for each name a package's ``__init__`` imports from
    one of its own children."""
    out = {}
    for name, path in found.items():
        if not _is_package(path):
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom):
                for module, alias in _imported(name, path, node):
                    child = f"{module}.{alias}" if f"{module}.{alias}" in found else module
                    if child.startswith(name + ".") and child in found:
                        out[(name, alias)] = child
    return out


def import_graph(root: Path, packages: tuple[str, ...] = PACKAGES) -> dict[str, dict[str, int]]:
    """``{module: {module it imports: line}}`` among the modules of ``packages``."""
    found = modules(root, packages)
    reexports = _reexports(found)
    graph: dict[str, dict[str, int]] = {name: {} for name in found}
    for name, path in found.items():
        for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
            if not isinstance(node, (ast.Import, ast.ImportFrom)):
                continue
            for module, alias in _imported(name, path, node):
                target = f"{module}.{alias}" if f"{module}.{alias}" in found else module
                target = reexports.get((target, alias), target)
                while target and target not in found:  # `import a.b.c` of a name inside a.b
                    target = target.rpartition(".")[0]
                if not target or target == name:
                    continue
                if _is_package(path) and target.startswith(name + "."):
                    continue  # the __init__ re-exporting its own children
                graph[name].setdefault(target, node.lineno)
    return graph


def find_cycle(graph: dict[str, dict[str, int]]) -> list[str] | None:
    """One import cycle of ``graph`` as ``[a, b, ..., a]``, or None (iterative depth-first search)."""
    state: dict[str, int] = {}  # 1: on the current path, 2: done
    for start in sorted(graph):
        if start in state:
            continue
        path, stack = [start], [iter(sorted(graph[start]))]
        state[start] = 1
        while stack:
            nxt = next(stack[-1], None)
            if nxt is None:
                state[path.pop()] = 2
                stack.pop()
            elif state.get(nxt) == 1:
                return path[path.index(nxt):] + [nxt]
            elif nxt not in state:
                state[nxt] = 1
                path.append(nxt)
                stack.append(iter(sorted(graph.get(nxt, {}))))
    return None


def describe(cycle: list[str], graph: dict[str, dict[str, int]]) -> str:
    return "import cycle:\n" + "\n".join(f"  {a} (line {graph[a][b]}) -> {b}" for a, b in zip(cycle, cycle[1:]))


def too_long(path: Path) -> list[str]:
    """Classes over :data:`MAX_CLASS_LINES` and functions over :data:`MAX_FUNCTION_LINES` in ``path``."""
    out = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            lines = node.end_lineno - node.lineno + 1
            limit = MAX_CLASS_LINES if isinstance(node, ast.ClassDef) else MAX_FUNCTION_LINES
            if lines > limit:
                out.append(f"{path.relative_to(ROOT) if path.is_relative_to(ROOT) else path}:{node.lineno} "
                           f"{node.name}: {lines} lines (at most {limit})")
    return out


def _per_package():
    return pytest.mark.parametrize("package", ["solver", "workflows", "service"])


@_per_package()
def test_no_import_cycle(package):
    graph = import_graph(ROOT, (package,))
    assert len(graph) > 5
    cycle = find_cycle(graph)
    assert cycle is None, describe(cycle, graph)


@_per_package()
def test_no_long_class_or_function(package):
    found = [line for path in modules(ROOT, (package,)).values() for line in too_long(path)]
    assert not found, "\n".join(found)


def test_no_long_solver_module():
    long = {str(p.relative_to(ROOT)): n for p in modules(ROOT, ("solver",)).values()
            if (n := len(p.read_text().splitlines())) > MAX_SOLVER_MODULE_LINES}
    assert not long, long


def test_dependency_direction():
    """``service -> workflows -> solver``, never backwards (STYLE.md); across the three packages
    this leaves no room for a cycle."""
    graph = import_graph(ROOT)
    rank = {"solver": 0, "workflows": 1, "service": 2}
    backwards = [f"{a} (line {line}) -> {b}" for a, targets in graph.items() for b, line in targets.items()
                 if rank[b.split(".")[0]] > rank[a.split(".")[0]]]
    assert not backwards, "\n".join(backwards)


# -- the checks themselves can fail ---------------------------------------------------------------

def _package(root: Path, files: dict[str, str]) -> None:
    for name, text in files.items():
        path = root / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)


def test_a_deferred_import_closing_a_circle_is_a_cycle(tmp_path):
    _package(tmp_path, {
        "workflows/__init__.py": "from .a import f\n",
        "workflows/a.py": "from .b import g\ndef f():\n    return g()\n",
        "workflows/b.py": "def g():\n    from workflows.c import h\n    return h()\n",
        "workflows/c.py": "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from . import a\ndef h(): pass\n",
    })
    graph = import_graph(tmp_path, ("workflows",))
    assert graph["workflows.b"] == {"workflows.c": 2}
    cycle = find_cycle(graph)
    assert cycle is not None and cycle[0] == cycle[-1]
    assert set(cycle) == {"workflows.a", "workflows.b", "workflows.c"}
    assert "workflows.b (line 2) -> workflows.c" in describe(cycle, graph)


def test_an_init_reexporting_its_children_is_no_cycle(tmp_path):
    """``a`` imports a name of its package that ``__init__`` takes from ``b``: the edge goes to
    ``b``, and ``__init__``'s own imports of ``a`` and ``b`` close nothing."""
    _package(tmp_path, {
        "service/__init__.py": "from .a import f\nfrom .b import g\n",
        "service/a.py": "from service import g\ndef f(): return g()\n",
        "service/b.py": "def g(): pass\n",
    })
    graph = import_graph(tmp_path, ("service",))
    assert graph == {"service": {}, "service.a": {"service.b": 1}, "service.b": {}}
    assert find_cycle(graph) is None
    _package(tmp_path, {"service/b.py": "import service.a\ndef g(): pass\n"})  # now a true circle
    assert find_cycle(import_graph(tmp_path, ("service",))) in (["service.a", "service.b", "service.a"],
                                                                 ["service.b", "service.a", "service.b"])


def test_long_definitions_are_found(tmp_path):
    body = "\n".join(f"    x{i} = {i}" for i in range(MAX_FUNCTION_LINES))
    path = tmp_path / "m.py"
    path.write_text(f"def short():\n    pass\n\n\ndef long():\n{body}\n")
    found = too_long(path)
    assert len(found) == 1 and f"long: {MAX_FUNCTION_LINES + 1} lines" in found[0]
