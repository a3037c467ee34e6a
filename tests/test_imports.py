"""Imports inside the package run one way (issue 33, ``DESIGN.md``: "Imports run one way, from
the front door down").

The graph is read from the source with :mod:`ast`, not by importing: every ``import`` of a
``tacswitch`` module is an edge, at module level or inside a function (a function-level import
hides a dependency, it does not remove it). Imports under ``if TYPE_CHECKING:`` never run and
are not edges. Imports of other packages (torch, cv2, onnxruntime) are not part of the graph,
so keeping those lazy costs nothing here.

``from pkg import name`` is an edge to ``pkg.name`` when that is a module, else to ``pkg``
(its ``__init__``), as Python resolves it.
"""

from __future__ import annotations

import ast
import itertools
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "python" / "tacswitch"

#: The layers above the front door (``tacswitch/__init__``): they may import it, nothing below may.
TOP = ("tacswitch.__main__", "tacswitch.cli")
#: Modules below the CLI that still reach into it, with the reason. Each entry is a debt: the
#: helpers (``collect_images``, ``video_frames``) belong in a module below the CLI; they move
#: when the open work on ``cli/sources.py`` (ROS bag sources) has landed.
CLI_REACHED_FROM_BELOW = {
    ("tacswitch.grasp.dataset", "tacswitch.cli.sources"),
    ("tacswitch.motion.data", "tacswitch.cli.sources"),
}


@dataclass(frozen=True)
class Edge:
    """One import statement of ``target`` in ``source`` (module names, dotted)."""

    source: str
    target: str
    line: int
    in_function: bool


def _modules(root: Path) -> dict[str, Path | None]:
    """Dotted module name -> file (None: a compiled extension, which imports nothing of ours).
    An extension is known by its binary or, in a source tree whose extension was installed
    elsewhere (a clean checkout after ``pip install .``), by its ``.pyi`` stub."""
    out: dict[str, Path | None] = {}
    for path in sorted(root.rglob("*")):
        if path.suffix not in (".py", ".so", ".pyd", ".pyi") or "__pycache__" in path.parts:
            continue
        if path.suffix == ".pyi" and path.with_suffix(".py").exists():
            continue  # the stub of a Python module: the module itself counts
        parts = list(path.relative_to(root.parent).parts)
        parts[-1] = parts[-1].split(".")[0]
        if parts[-1] == "__init__":
            parts.pop()
        out[".".join(parts)] = path if path.suffix == ".py" else None
    return out


def _package_of(name: str, path: Path) -> str:
    return name if path.name == "__init__.py" else name.rpartition(".")[0]


def _resolve(name: str, modules: dict[str, Path | None]) -> str | None:
    """The module ``name`` lives in: itself, or the longest module prefix of it."""
    parts = name.split(".")
    while parts:
        if ".".join(parts) in modules:
            return ".".join(parts)
        parts.pop()
    return None


def _under_type_checking(node: ast.AST, parents: dict[ast.AST, ast.AST]) -> bool:
    while node in parents:
        node = parents[node]
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            return True
    return False


def _in_function(node: ast.AST, parents: dict[ast.AST, ast.AST]) -> bool:
    while node in parents:
        node = parents[node]
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)):
            return True
    return False


def _imported(node: ast.Import | ast.ImportFrom, package: str,
              modules: dict[str, Path | None]) -> Iterator[str]:
    """Dotted names of the modules one import statement loads (package-internal or not)."""
    if isinstance(node, ast.Import):
        for alias in node.names:
            yield alias.name
        return
    if node.level:  # relative: from .x import y
        base = package.split(".")
        base = base[: len(base) - (node.level - 1)]
        origin = ".".join(base + ([node.module] if node.module else []))
    else:
        origin = node.module or ""
    for alias in node.names:
        sub = f"{origin}.{alias.name}"
        yield sub if sub in modules else origin


def import_graph(root: Path) -> list[Edge]:
    """Every import of a module of the package at ``root`` by another module of it."""
    modules = _modules(root)
    top = root.name
    edges: list[Edge] = []
    for name, path in modules.items():
        if path is None:
            continue
        tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
        parents = {child: node for node in ast.walk(tree) for child in ast.iter_child_nodes(node)}
        for node in ast.walk(tree):
            if not isinstance(node, (ast.Import, ast.ImportFrom)):
                continue
            if _under_type_checking(node, parents):
                continue
            for imported in _imported(node, _package_of(name, path), modules):
                if imported != top and not imported.startswith(top + "."):
                    continue
                target = _resolve(imported, modules)
                if target is not None and target != name:
                    edges.append(Edge(name, target, node.lineno, _in_function(node, parents)))
    return edges


def circles(edges: list[Edge]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan), each as one closed
    path through it (first module repeated at the end), sorted."""
    graph: dict[str, set[str]] = {}
    for e in edges:
        graph.setdefault(e.source, set()).add(e.target)
        graph.setdefault(e.target, set())
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[set[str]] = []

    def visit(v: str) -> None:  # recursion depth <= number of modules (~200)
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = set()
            while True:
                w = stack.pop()
                on_stack.discard(w)
                comp.add(w)
                if w == v:
                    break
            if len(comp) > 1:
                found.append(comp)

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return sorted(_closed_path(comp, graph) for comp in found)


def _closed_path(comp: set[str], graph: dict[str, set[str]]) -> list[str]:
    """A cycle through the component's first module (breadth-first back to it)."""
    start = min(comp)
    prev: dict[str, str] = {}
    frontier = [start]
    while frontier:
        nxt = []
        for v in frontier:
            for w in sorted(graph[v] & comp):
                if w == start:
                    path = [v]
                    while path[-1] != start:
                        path.append(prev[path[-1]])
                    return [start, *reversed(path[:-1]), start] if v != start else [start, start]
                if w not in prev:
                    prev[w] = v
                    nxt.append(w)
        frontier = nxt
    raise AssertionError(f"no cycle through {start}")  # pragma: no cover (comp is an SCC)


def _describe(path: list[str], edges: list[Edge]) -> str:
    steps = []
    for a, b in itertools.pairwise(path):
        lines = sorted({(e.line, e.in_function) for e in edges if e.source == a and e.target == b})
        where = ", ".join(f"line {n}{' (in a function)' if f else ''}" for n, f in lines)
        steps.append(f"  {a} -> {b}: {where}")
    return "\n".join(steps)


def _is_within(name: str, package: str) -> bool:
    return name == package or name.startswith(package + ".")


def arrows_back_up(edges: list[Edge], cli_allowed: set[tuple[str, str]]) -> list[str]:
    """Imports that run against the layers, described:

    - a module importing the ``__init__`` of a package that contains it (a package's facade sits
      above its members), except the CLI and ``__main__``, which sit above the front door;
    - a module outside the CLI importing the CLI (nothing but ``__main__`` imports it), unless
      ``(source, target)`` is in ``cli_allowed``.
    """
    bad = []
    for e in edges:
        top = any(_is_within(e.source, t) for t in TOP)
        if _is_within(e.source, e.target) and not (top and e.target == "tacswitch"):
            bad.append(f"{e.source} -> {e.target} (line {e.line}): imports its own package's "
                       "front door; import the module that defines the name")
        if (_is_within(e.target, "tacswitch.cli") and not top
                and (e.source, e.target) not in cli_allowed):
            bad.append(f"{e.source} -> {e.target} (line {e.line}): reaches up into the CLI")
    return sorted(set(bad))


def test_the_package_has_no_import_circle() -> None:
    edges = import_graph(PACKAGE)
    assert len({e.source for e in edges}) > 50  # the graph was read (not an empty walk)
    found = circles(edges)
    assert not found, "import circles in the package:\n" + "\n".join(
        _describe(path, edges) for path in found)


def test_no_import_runs_back_up() -> None:
    bad = arrows_back_up(import_graph(PACKAGE), CLI_REACHED_FROM_BELOW)
    assert not bad, "imports that run back up:\n" + "\n".join(bad)


def test_the_cli_exceptions_are_still_needed() -> None:
    """An entry of :data:`CLI_REACHED_FROM_BELOW` that no longer happens must go."""
    present = {(e.source, e.target) for e in import_graph(PACKAGE)}
    assert CLI_REACHED_FROM_BELOW <= present, CLI_REACHED_FROM_BELOW - present


def _write(root: Path, files: dict[str, str]) -> Path:
    for rel, text in files.items():
        (root / rel).parent.mkdir(parents=True, exist_ok=True)
        (root / rel).write_text(text)
    return root / "tacswitch"


def test_a_circle_through_a_function_level_import_is_found(tmp_path: Path) -> None:
    root = _write(tmp_path, {
        "tacswitch/__init__.py": "from tacswitch.front import go\n",
        "tacswitch/front.py": ("from tacswitch.sub import method\n\n"
                               "def go():\n    return method()\n"),
        "tacswitch/sub/__init__.py": "",
        "tacswitch/sub/method.py": (
            "import numpy\n\ndef method():\n    from tacswitch import front\n    import torch\n"),
        "tacswitch/_native.pyi": "",
    })
    edges = import_graph(root)
    assert circles(edges) == [["tacswitch.front", "tacswitch.sub.method", "tacswitch.front"]]
    assert "line 4 (in a function)" in _describe(circles(edges)[0], edges)
    # torch and numpy are not package modules: no edge, whatever the place.
    assert {e.target for e in edges} == {"tacswitch.front", "tacswitch.sub.method"}


def test_type_checking_imports_and_outside_packages_are_not_edges(tmp_path: Path) -> None:
    root = _write(tmp_path, {
        "tacswitch/__init__.py": "",
        "tacswitch/a.py": "from tacswitch import b\n",
        "tacswitch/b.py": ("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n"
                           "    from tacswitch.a import x\n"),
    })
    assert circles(import_graph(root)) == []


@pytest.mark.parametrize(("source", "text", "reason"), [
    ("tacswitch/low.py", "import tacswitch as ts\n", "front door"),
    ("tacswitch/sub/low.py", "from tacswitch.sub import thing\n", "front door"),
    ("tacswitch/low.py", "def f():\n    from tacswitch.cli.helpers import h\n", "into the CLI"),
])
def test_arrows_back_up_are_found(tmp_path: Path, source: str, text: str, reason: str) -> None:
    root = _write(tmp_path, {
        "tacswitch/__init__.py": "", "tacswitch/sub/__init__.py": "thing = 1\n",
        "tacswitch/cli/__init__.py": "import tacswitch\n", "tacswitch/cli/helpers.py": "",
        source: text,
    })
    bad = arrows_back_up(import_graph(root), set())
    assert len(bad) == 1 and reason in bad[0], bad
