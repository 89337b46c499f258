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


def _help_texts() -> dict[str, str]:
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    texts = {}
    for command in ([], ["asm"], ["exec"], ["design"], ["compare"], ["budget"], ["vectors"]):
        r = subprocess.run([sys.executable, "-m", "firmware_model.cli.main", *command, "--help"], capture_output=True,
                           text=True, env=env, timeout=120, check=True)
        texts[" ".join(command) or "fwemu"] = r.stdout
    return texts


def test_help_shows_no_rest_markup() -> None:
    for command, text in _help_texts().items():
        bad = re.findall(r"``|:(?:func|class|mod|data|meth|attr):`", text)
        assert not bad, f"fwemu {command} --help shows reST markup: {bad}\n{text}"
        assert "DESIGN.md" not in text, command


def test_plain_strips_roles_and_literals() -> None:
    from firmware_model.cli.main import plain

    assert plain("``fwemu vectors``: see :func:`~firmware_model.vectors.generate.check_set` and :class:`UserError`") == \
        "fwemu vectors: see check_set and UserError"


def test_docs_cite_no_file_missing_from_the_repository() -> None:
    # the README and the docs of the emulator, firmware, numerics and vectors (docs/flights*.md: the flights work)
    texts = [ROOT / "README.md"] + [ROOT / "docs" / f"{name}.md" for name in (
        "firmware-spec", "firmware-asm", "gain-design", "numerics", "vectors", "isa-internals", "isa-oracles")]
    for path in texts:
        assert "DESIGN.md" not in path.read_text(), f"{path.name} cites DESIGN.md, which is not in the repository"
    from firmware_model.cli.compare import bias_table

    assert "DESIGN" not in bias_table("kalman_baro", ks=(5,), seconds=2.0)


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
    """firmware_model/runtime/blas_threads.py: the CLI process (and the workers it spawns, which inherit the variable) has
    no OpenBLAS thread pool busy-waiting beside it; a user's OPENBLAS_NUM_THREADS is kept."""
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
