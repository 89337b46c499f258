"""The project's import graph, read from the source with :mod:`ast` (nothing is imported): the structure tests
(tests/structure/test_layers.py, tests/cli/test_structure.py) and their teeth tests share it."""

from __future__ import annotations

import ast
import functools
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
PACKAGE = ROOT / "firmware_model"


def _module_name(path: Path, root: Path = ROOT) -> str:
    rel = path.relative_to(root).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def parse_source(path: Path) -> ast.Module:
    """The syntax tree of ``path``, parsed once per distinct text in this process (the structure tests and their
    teeth tests read the same ~300 files, and copies of them, several times; the callers only read the trees)."""
    return _parse_text(path.read_text(), str(path.name))


@functools.lru_cache(maxsize=4096)
def _parse_text(text: str, name: str) -> ast.Module:
    return ast.parse(text, name)


def import_graph(package: Path = PACKAGE) -> dict[str, set[str]]:
    """``package`` (default firmware_model) module -> the modules of that package it imports anywhere at run time
    (top level or inside functions; not the annotation-only imports under ``if TYPE_CHECKING:``)."""
    modules = {_module_name(p, package.parent): p for p in package.rglob("*.py")}
    graph: dict[str, set[str]] = {}
    for name, path in modules.items():
        deps: set[str] = set()
        tree = parse_source(path)
        typing_only = {id(n) for block in ast.walk(tree) if isinstance(block, ast.If)
                       and "TYPE_CHECKING" in ast.unparse(block.test) for n in ast.walk(block)}
        for node in ast.walk(tree):
            if id(node) in typing_only:   # `if TYPE_CHECKING:` imports are for annotations, never executed
                continue
            if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
                targets = [node.module] + [f"{node.module}.{a.name}" for a in node.names]
            elif isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            else:
                continue
            deps |= {t for t in targets if t in modules and t != name}
        graph[name] = deps
    return graph


def find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(node: str) -> list[str] | None:
        state[node] = 1
        stack.append(node)
        for dep in sorted(graph[node]):
            if state.get(dep) == 1:
                return stack[stack.index(dep):] + [dep]
            if dep not in state and (found := visit(dep)):
                return found
        stack.pop()
        state[node] = 2
        return None

    for node in sorted(graph):
        if node not in state and (found := visit(node)):
            return found
    return None


def module_graph(package: Path) -> dict[str, set[str]]:
    """:func:`import_graph` without the edges to packages: packages import their submodules' names through
    ``__init__``; only module-to-module cycles count."""
    return {m: {d for d in deps if not (package / Path(*d.split(".")[1:]) / "__init__.py").exists()}
            for m, deps in import_graph(package).items()}
