"""No function over 120 lines in isa/, firmware_model/ or bench/ (issue 34): a long body is split into named steps,
or its ``def`` says why not. docs/testing.md, "Function length and lint".

A function's length runs from its ``def`` line to its last line (decorators excluded; docstring, comments and
nested functions included; a nested function is also measured on its own). The documented exemption is a comment
``# long: <reason>`` on one of the lines of the ``def`` statement (the ``def`` line up to the colon), e.g.::

    def emit_table(rows):  # long: one statement per output row, in the order of the generated C file

Generated Python files are exempt by path (:data:`GENERATED`). Read from the source with :mod:`ast` and the parse
cache the other structure tests share (nothing is imported)."""

from __future__ import annotations

import ast
import re
from pathlib import Path

from tests.support.imports import ROOT, parse_source

#: Longest body allowed without a reason, in lines.
LIMIT = 120
#: Folders whose Python files are measured.
FOLDERS: tuple[str, ...] = ("isa", "firmware_model", "bench")
#: Generated Python files (relative to the checkout), exempt whole. None is checked in today: the block
#: compiler's generated functions (isa/blocks.py) are built in memory and never stored as files. A generator
#: that writes a .py file into these folders names its output here.
GENERATED: frozenset[str] = frozenset()
#: Long functions being split on other branches (issue 34), "path::qualified name". The lead empties this set as
#: those branches merge; an entry whose function is gone or no longer long fails test_pending_entries_are_live,
#: so a stale entry cannot hide a new long function of the same name.
PENDING: frozenset[str] = frozenset()

_REASON = re.compile(r"#\s*long:\s*\S")


def _header_lines(fn: ast.FunctionDef | ast.AsyncFunctionDef) -> range:
    """Line numbers of the ``def`` statement of ``fn``: from the ``def`` line up to the line before its body."""
    return range(fn.lineno, max(fn.lineno, fn.body[0].lineno - 1) + 1)


def functions(tree: ast.Module) -> list[tuple[str, ast.FunctionDef | ast.AsyncFunctionDef]]:
    """(qualified name, node) of every function of ``tree``, methods and nested functions included."""
    found: list[tuple[str, ast.FunctionDef | ast.AsyncFunctionDef]] = []

    def visit(node: ast.AST, prefix: str) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef)):
                found.append((prefix + child.name, child))
                visit(child, f"{prefix}{child.name}.")
            elif isinstance(child, ast.ClassDef):
                visit(child, f"{prefix}{child.name}.")
            else:
                visit(child, prefix)

    visit(tree, "")
    return found


def length(fn: ast.FunctionDef | ast.AsyncFunctionDef) -> int:
    assert fn.end_lineno is not None
    return fn.end_lineno - fn.lineno + 1


def long_functions(root: Path = ROOT, folders: tuple[str, ...] = FOLDERS,
                   generated: frozenset[str] = GENERATED) -> dict[str, tuple[int, bool]]:
    """"path::qualified name" -> (length, has a ``# long:`` reason) for every function over :data:`LIMIT` lines
    under ``folders`` of ``root``, the ``generated`` files left out."""
    out: dict[str, tuple[int, bool]] = {}
    for folder in folders:
        for path in sorted((root / folder).rglob("*.py")):
            rel = path.relative_to(root).as_posix()
            if rel in generated:
                continue
            lines = path.read_text(encoding="utf-8").splitlines()
            for name, fn in functions(parse_source(path)):
                if length(fn) > LIMIT:
                    reason = any(_REASON.search(lines[n - 1]) for n in _header_lines(fn))
                    out[f"{rel}::{name}"] = (length(fn), reason)
    return out


def violations(found: dict[str, tuple[int, bool]], pending: frozenset[str] = PENDING) -> list[str]:
    return [f"{key}: {n} lines (limit {LIMIT}): split it into named steps, or give the reason on its def line "
            f"as '# long: <reason>'" for key, (n, reason) in sorted(found.items()) if not reason and key not in pending]


def test_no_function_over_the_limit_without_a_reason() -> None:
    bad = violations(long_functions())
    assert not bad, "\n".join(bad)


def test_pending_entries_are_live() -> None:
    """Every PENDING entry names a function that is still long and has no reason: once its branch lands, the
    entry goes (the lead's merge), so the set only shrinks."""
    found = long_functions()
    stale = sorted(key for key in PENDING if key not in found or found[key][1])
    assert not stale, f"PENDING entries no longer long (remove them from {__name__}.PENDING): {stale}"


def test_generated_paths_exist() -> None:
    missing = sorted(p for p in GENERATED if not (ROOT / p).is_file())
    assert not missing, f"GENERATED names files that do not exist: {missing}"


def _write_function(path: Path, name: str, body_lines: int, def_comment: str = "") -> None:
    """A module with one function ``name`` of exactly ``body_lines + 1`` lines (its def line and ``body_lines``
    statements)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    body = "".join(f"    x{i} = {i}\n" for i in range(body_lines))
    path.write_text(f"def {name}():{def_comment}\n{body}")


def test_the_length_rule_has_teeth(tmp_path: Path) -> None:
    """A synthetic 121-line function fails; 120 lines pass; a reason on the def line, a PENDING entry or a
    GENERATED path exempts it; an empty reason does not; methods and nested functions are measured."""
    _write_function(tmp_path / "isa" / "a.py", "long_one", LIMIT)           # 121 lines
    _write_function(tmp_path / "isa" / "b.py", "just_fits", LIMIT - 1)      # 120 lines
    _write_function(tmp_path / "bench" / "c.py", "with_reason", LIMIT, "  # long: mirrors its generated output")
    _write_function(tmp_path / "bench" / "d.py", "empty_reason", LIMIT, "  # long:")
    _write_function(tmp_path / "firmware_model" / "gen" / "out.py", "generated", 2 * LIMIT)
    nested = "class K:\n    def outer(self):\n        def inner():\n" + "".join(
        f"            y{i} = {i}\n" for i in range(LIMIT)) + "        return inner\n"
    (tmp_path / "firmware_model" / "e.py").write_text(nested)
    two_line = "def two_line_def(a,\n                 b):  # long: a reason after the colon\n"
    (tmp_path / "isa" / "f.py").write_text(two_line + "".join(f"    z{i} = {i}\n" for i in range(LIMIT)))
    found = long_functions(tmp_path, generated=frozenset({"firmware_model/gen/out.py"}))
    assert sorted(found) == ["bench/c.py::with_reason", "bench/d.py::empty_reason", "firmware_model/e.py::K.outer",
                             "firmware_model/e.py::K.outer.inner", "isa/a.py::long_one", "isa/f.py::two_line_def"]
    assert found["isa/f.py::two_line_def"] == (LIMIT + 2, True)
    assert found["isa/a.py::long_one"] == (LIMIT + 1, False)
    assert found["firmware_model/e.py::K.outer.inner"] == (LIMIT + 1, False)
    bad = violations(found, pending=frozenset({"firmware_model/e.py::K.outer"}))
    assert [b.split(": ")[0] for b in bad] == [
        "bench/d.py::empty_reason", "firmware_model/e.py::K.outer.inner", "isa/a.py::long_one"]
    assert "121 lines" in bad[-1]
