"""Structure and documentation of the CLI (issue 8 items 13 and 14): no import cycles in firmware_model (nor in
isa, issue 10 item 5), --help
without reST markup, no citation of a file the repository does not have, the input-register addressing the spec
documents is what the assembler accepts."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

import isa
from tests.support.imports import ROOT


def test_budget_command_lives_in_cli_budget() -> None:
    from firmware_model.cli import main as cli

    assert "firmware_model.cli.budget" in cli.COMMAND_MODULES
    parser = cli.build_parser()
    sub = next(a for a in parser._actions if a.__class__.__name__ == "_SubParsersAction")
    assert sub.choices["budget"].get_default("func").__module__ == "firmware_model.cli.budget"


def test_the_command_table_is_what_the_modules_register() -> None:
    """cli.main.COMMANDS (which module to import for which command) against the full parser: every command is in
    the table under the module that registers it, and a parser built for one command gives that command's help
    exactly as the full parser does."""
    from firmware_model.cli import main as cli

    parser = cli.build_parser()
    sub = next(a for a in parser._actions if a.__class__.__name__ == "_SubParsersAction")
    assert set(sub.choices) == set(cli.COMMANDS)
    for name, p in sub.choices.items():
        assert p.get_default("func").__module__ == cli.COMMANDS[name], name
        one = cli.build_parser([name, "--help"])
        one_sub = next(a for a in one._actions if a.__class__.__name__ == "_SubParsersAction")
        assert list(one_sub.choices) == [n for n, m in cli.COMMANDS.items() if m == cli.COMMANDS[name]]
        assert one_sub.choices[name].format_help() == p.format_help(), name


_HELP_COMMANDS = ([], ["asm"], ["exec"], ["design"], ["compare"], ["budget"], ["vectors"])
_HELP_SCRIPT = """
import contextlib, io, sys
from firmware_model.cli.main import main
for command in {commands!r}:
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        try:
            main(command + ["--help"])
        except SystemExit as e:
            assert e.code in (0, None), (command, e.code)
    sys.stdout.write(buf.getvalue() + "\\0")
"""


def _help_texts() -> dict[str, str]:
    """Every command's --help as the CLI prints it, in one child interpreter (one start-up instead of seven)."""
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    r = subprocess.run([sys.executable, "-c", _HELP_SCRIPT.format(commands=list(_HELP_COMMANDS))],
                       capture_output=True, text=True, env=env, timeout=120, check=True)
    parts = r.stdout.split("\0")[:-1]
    assert len(parts) == len(_HELP_COMMANDS), r.stdout[-500:]
    return {" ".join(c) or "fwemu": text for c, text in zip(_HELP_COMMANDS, parts)}


def test_help_shows_no_rest_markup() -> None:
    for command, text in _help_texts().items():
        bad = re.findall(r"``|:(?:func|class|mod|data|meth|attr):`", text)
        assert not bad, f"fwemu {command} --help shows reST markup: {bad}\n{text}"
        assert not UNFOLLOWABLE.search(text), command


def test_plain_strips_roles_and_literals() -> None:
    from firmware_model.cli.main import plain

    text = "``fwemu vectors``: see :func:`~firmware_model.vectors.generate.check_set` and :class:`UserError`"
    assert plain(text) == "fwemu vectors: see check_set and UserError"


#: A citation the reader cannot follow: the brief the project was written from, or a paper by its file number
#: (papers are cited by author and year, docs/references.md). Built so that this file does not match itself.
UNFOLLOWABLE = re.compile(r"\bDESIGN" + r"\.md|\b(?i:seeds? \d{3}|seed-\d{3}|design brief)\b")


def test_nothing_cites_a_paper_by_number_or_a_file_missing_from_the_repository() -> None:
    """README, every doc, every source and test file, the C port and the help texts."""
    tracked = subprocess.run(["git", "ls-files"], cwd=ROOT, capture_output=True, text=True, check=True).stdout.split()
    paths = [ROOT / f for f in tracked if f.endswith((".md", ".py", ".c", ".h", ".s", ".inc", ".toml"))
             and not f.startswith(("vectors/cases/", "vectors/tables/")) and f != "tests/cli/test_structure.py"]
    assert len(paths) > 150 and ROOT / "README.md" in paths
    bad = [f"{p.relative_to(ROOT)}:{i}: {m.group(0)}" for p in paths
           for i, line in enumerate(p.read_text().splitlines(), 1) if (m := UNFOLLOWABLE.search(line))]
    assert not bad, "\n".join(bad)
    from firmware_model.cli.compare import bias_table

    assert not UNFOLLOWABLE.search(bias_table("kalman_baro", ks=(5,), seconds=2.0))


def test_the_citation_check_sees_each_form() -> None:
    for text in ("see DESIGN" + ".md §7", "(seed 000 Figure 10)", "seeds 000 and 002", "the seed-002 step",
                 "the design brief"):
        assert UNFOLLOWABLE.search(text), text
    assert not UNFOLLOWABLE.search("seed 0 (numpy), Schultz 2002, seed=12, docs/gain-design.md")


def test_input_registers_addressing_as_the_spec_says() -> None:
    spec = (ROOT / "docs" / "firmware-spec.md").read_text()
    assert "`$F000.w`, `$F002.w`)" not in spec      # the old claim
    assert "BARO_ADC.w" in spec and "($FFF000).w" in spec
    for operand in ("BARO_ADC.w", "($FFF000).w"):
        program = isa.assemble(f"BARO_ADC EQU $FFF000\n move.w {operand},d0\n trap #0\n", origin=0x1000)
        assert program.code[:4] == bytes.fromhex("3038F000"), operand
    with pytest.raises(isa.errors.IsaError, match="does not fit abs.w"):
        isa.assemble(" move.w $F000.w,d0\n", origin=0x1000)


_BLAS_PROBE = """
import os, sys
import firmware_model.cli.main   # the CLI module: asks for one BLAS thread before anything imports numpy
import numpy as np
np.linalg.solve(np.eye(300) * 2.0, np.ones(300))   # a call large enough for OpenBLAS to use its pool
print(len(os.listdir("/proc/self/task")), os.environ.get("OPENBLAS_NUM_THREADS"))
"""


@pytest.mark.skipif(not Path("/proc/self/task").is_dir() or (os.cpu_count() or 1) < 2,
                    reason="needs Linux /proc and 2+ cores (OpenBLAS starts no pool on one core)")
@pytest.mark.parametrize("preset", [None, "2"])
def test_the_cli_runs_numpy_with_one_blas_thread_unless_told_otherwise(preset: str | None) -> None:
    """firmware_model/runtime/blas_threads.py: the CLI process (and the workers it spawns, which inherit the variable)
    has no OpenBLAS thread pool busy-waiting beside it; a user's OPENBLAS_NUM_THREADS is kept."""
    env = {k: v for k, v in os.environ.items() if k not in ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")}
    env["PYTHONPATH"] = str(ROOT)
    if preset is not None:
        env["OPENBLAS_NUM_THREADS"] = preset
    r = subprocess.run([sys.executable, "-c", _BLAS_PROBE], capture_output=True, text=True, env=env, timeout=120)
    assert r.returncode == 0, r.stderr
    threads, value = r.stdout.split()
    if preset is None:
        assert (threads, value) == ("1", "1")
    else:   # the user's setting is kept, and it is what OpenBLAS used: one main thread + one pool thread
        assert (threads, value) == ("2", "2")
