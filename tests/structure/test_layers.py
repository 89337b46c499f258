"""The layers of firmware_model (docs/architecture.md): every project import runs downwards, no circle, and no
project import hides inside a function (the documented lazy loads aside).

runtime <- spec <- model <- firmware, flights <- vectors <- budget <- cli; isa stands apart and imports none of it.
Read from the source with :mod:`ast` (nothing is imported), so a violation is reported with its file and line.
"""

from __future__ import annotations

import ast
import shutil
from pathlib import Path

import pytest

from tests.support.imports import PACKAGE as PKG
from tests.support.imports import ROOT, find_cycle, import_graph, module_graph, parse_source

#: Layer of each package: a module may import its own package and any package of a lower layer.
LAYERS: dict[str, int] = {"runtime": 0, "spec": 1, "model": 2, "firmware": 3, "flights": 3, "vectors": 4,
                          "budget": 5, "cli": 6}

#: The rooms of flights/ (docs/architecture.md), lowest first: a flights module may import its own room and any
#: lower one. The record type and the plot helpers sit in flights/ itself; ``strategies`` (the public hypothesis
#: strategies, path documented in the README) draws simulated flights; the studies import the library, never the
#: reverse.
ROOMS: dict[str, int] = {"record": 0, "plot": 0, "__init__": 0, "readers": 1, "simulate": 2, "reference": 3,
                         "inputs": 4, "reconstruct": 5, "evaluation": 6, "montecarlo": 7, "strategies": 8,
                         "studies": 9}

#: Imports allowed inside a function, each a documented lazy load of a heavy optional dependency behind it:
#: (importing module, imported module) -> why.
LAZY: dict[tuple[str, str], str] = {
    ("firmware_model.model.run", "firmware_model.model.kernels"): "the kernels import numba (about 1.5 s)",
    ("firmware_model.flights.reconstruct.ukf", "firmware_model.flights.reconstruct.kernels"):
        "the reconstruction's kernels import numba (about 1.5 s) for every command's parser otherwise",
}


def module_name(path: Path, root: Path = ROOT) -> str:
    parts = path.relative_to(root).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def package_of(module: str) -> str | None:
    parts = module.split(".")
    return parts[1] if len(parts) > 1 and parts[0] == "firmware_model" else None


def room_of(module: str) -> str | None:
    """The room of a firmware_model.flights module (None outside flights, "__init__" for the package itself)."""
    parts = module.split(".")
    if parts[:2] != ["firmware_model", "flights"]:
        return None
    return parts[2] if len(parts) > 2 else "__init__"


def project_imports(path: Path, root: Path = ROOT) -> list[tuple[str, int, bool]]:
    """(imported module, line, inside a function or TYPE_CHECKING block) for every firmware_model / isa import."""
    tree = parse_source(path)
    found: list[tuple[str, int, bool]] = []

    def visit(node: ast.AST, nested: bool) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.ImportFrom) and child.module and not child.level:
                if child.module.split(".")[0] in ("firmware_model", "isa"):
                    subs = [m for a in child.names if _is_module(m := f"{child.module}.{a.name}", root)]
                    found.extend((m, child.lineno, nested) for m in (subs or [child.module]))
            elif isinstance(child, ast.Import):
                found.extend((a.name, child.lineno, nested) for a in child.names
                             if a.name.split(".")[0] in ("firmware_model", "isa"))
            elif isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef)):
                visit(child, True)
            elif isinstance(child, ast.If) and "TYPE_CHECKING" in ast.unparse(child.test):
                visit(child, True)
            else:
                visit(child, nested)

    visit(tree, False)
    return found


def _is_module(name: str, root: Path) -> bool:
    p = root.joinpath(*name.split("."))
    return p.with_suffix(".py").is_file() or (p / "__init__.py").is_file()


def layer_violations(package: Path = PKG) -> list[str]:
    """Every import of ``package`` (a firmware_model tree) that runs upwards, sideways between layers, into cli
    from elsewhere, from one command module into another, or hides inside a function without a LAZY entry."""
    root = package.parent
    bad: list[str] = []
    for path in sorted(package.rglob("*.py")):
        me = module_name(path, root)
        mine = package_of(me)
        where = path.relative_to(root)
        for target, line, nested in project_imports(path, root):
            theirs = package_of(target)
            if nested and (me, target) not in LAZY:
                bad.append(f"{where}:{line}: {target} imported inside a function or TYPE_CHECKING block")
            if mine is None or theirs is None:
                continue
            if theirs != mine and LAYERS[theirs] >= LAYERS[mine]:
                bad.append(f"{where}:{line}: {mine} (layer {LAYERS[mine]}) imports {target} (layer {LAYERS[theirs]})")
            if mine == theirs == "flights" and (a := room_of(me)) and (b := room_of(target)) and (
                    ROOMS[b] > ROOMS[a] or (a != b and ROOMS[a] == ROOMS[b] > 0)):
                bad.append(f"{where}:{line}: flights room {a} (rank {ROOMS[a]}) imports {target} (room {b}, "
                           f"rank {ROOMS[b]})")
            if mine == theirs == "cli" and me != "firmware_model.cli.main" and target not in (
                    "firmware_model.cli", "firmware_model.cli.args"):
                bad.append(f"{where}:{line}: command module {me} imports command module {target}")
    return bad


def test_sources_found() -> None:
    modules = {module_name(p) for p in PKG.rglob("*.py")}
    assert len(modules) > 50 and set(LAYERS) <= {package_of(m) for m in modules}
    assert {room_of(m) for m in modules if room_of(m)} == set(ROOMS), "a flights room or module the ROOMS list lacks"


def test_imports_run_downwards_and_none_is_deferred() -> None:
    bad = layer_violations()
    assert not bad, "\n".join(bad)


def test_lazy_loads_still_exist() -> None:
    """Each allowed lazy load is still there (an entry for a removed one would hide a new one silently)."""
    for (me, target), why in LAZY.items():
        path = ROOT.joinpath(*me.split(".")).with_suffix(".py")
        assert any(t == target and nested for t, _, nested in project_imports(path)), (me, target, why)


@pytest.mark.parametrize("module, line, expect", [
    ("spec/config.py", "from firmware_model.model.run import run_model", "spec (layer 1) imports"),
    ("runtime/output.py", "from firmware_model.cli.args import positive_int", "runtime (layer 0) imports"),
    ("flights/simulate/sim1dof.py", "from firmware_model.firmware.harness import run_firmware",
     "flights (layer 3) imports"),
    ("cli/plot.py", "from firmware_model.cli.run import run_run", "command module"),
    ("flights/simulate/sim1dof.py", "from firmware_model.flights.evaluation.evaluate import evaluate_many",
     "flights room simulate"),
    ("flights/reconstruct/run.py", "from firmware_model.flights.studies import reconstruct_study",
     "flights room reconstruct"),
    ("flights/readers/aim.py", "from firmware_model.flights.inputs import sensors", "flights room readers"),
    ("model/trace.py", "def _late():\n    from firmware_model.spec.config import BuildConfig",
     "imported inside a function"),
])
def test_the_layer_check_sees_each_kind_of_violation(tmp_path: Path, module: str, line: str, expect: str) -> None:
    """Teeth: a copy of firmware_model with one bad import added fails the check, naming file and line."""
    copy = tmp_path / "firmware_model"
    shutil.copytree(PKG, copy, ignore=shutil.ignore_patterns("__pycache__"))
    assert not layer_violations(copy)
    target = copy / module
    target.write_text(target.read_text() + "\n\n" + line + "\n")
    bad = layer_violations(copy)
    assert len(bad) == 1 and expect in bad[0] and bad[0].startswith(f"firmware_model/{module}:"), bad


def test_isa_imports_no_firmware_model() -> None:
    bad = []
    for path in sorted((ROOT / "isa").rglob("*.py")):
        bad += [f"{path.relative_to(ROOT)}:{line}: {t}" for t, line, _ in project_imports(path)
                if t.split(".")[0] == "firmware_model"]
    assert not bad


def test_firmware_model_has_no_import_cycle() -> None:
    full = import_graph()
    assert "firmware_model.spec.build_constants" in full and "firmware_model.spec.gain_design" in full
    graph = module_graph(PKG)
    assert find_cycle(graph) is None, " -> ".join(find_cycle(graph) or [])


def test_isa_has_no_import_cycle() -> None:
    graph = module_graph(ROOT / "isa")
    # the block compiler's three modules are seen, with the edges they have (a pure split of isa/blocks.py)
    assert {"isa.block_plan", "isa.block_codegen"} <= graph["isa.blocks"]
    assert "isa.block_plan" in graph["isa.block_codegen"] and "isa.blocks" in graph["isa.cpu"]
    assert find_cycle(graph) is None, " -> ".join(find_cycle(graph) or [])


def test_the_isa_cycle_check_sees_a_cycle(tmp_path: Path) -> None:
    """The isa check fails on a cycle: a copy of isa/ where block_plan imports isa.blocks back has one."""
    copy = tmp_path / "isa"
    copy.mkdir()
    for f in (ROOT / "isa").glob("*.py"):
        (copy / f.name).write_text(f.read_text())
    plan = copy / "block_plan.py"
    plan.write_text(plan.read_text() + "\n\ndef _late() -> None:\n    from isa.blocks import compile_block\n")
    cycle = find_cycle(module_graph(copy))
    assert cycle is not None and "isa.block_plan" in cycle and "isa.blocks" in cycle


def test_the_cycle_finder_finds_cycles() -> None:
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]
    assert find_cycle({"a": {"b"}, "b": set()}) is None
