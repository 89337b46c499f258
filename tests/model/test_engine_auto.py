"""``run_model(engine="auto")`` runs a process's first samples (``AUTO_PURE_MAX_SAMPLES`` over all calls) on the
plain-Python kernels while the compiled ones are not loaded, then the compiled kernels: the words are the same, a
short CLI run never imports numba, and the budget is cumulative (a long sequence of short calls still ends up
compiled). Each check runs in a fresh interpreter (this worker has loaded the compiled kernels already)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import pytest

from firmware_model.spec.config import BuildConfig
from firmware_model.spec.build_constants import build_constants
from firmware_model.model.run import AUTO_PURE_MAX_SAMPLES, compiled_kernels, run_model

ROOT = Path(__file__).resolve().parents[2]

_PROBE = """
import json, sys
import numpy as np
from firmware_model.spec.config import BuildConfig
from firmware_model.spec.build_constants import build_constants
from firmware_model.model.run import run_model
rows = []
for program, n in json.loads(sys.argv[1]):
    c = build_constants(BuildConfig(program=program, k=7))
    rng = np.random.default_rng(n)
    adc = 40000 - 30000 * np.minimum(np.arange(n), n - np.arange(n)) // n + rng.integers(-20, 21, n)  # up, down
    acc = rng.integers(-2000, 6000, n)
    t = run_model(c, adc, acc)
    rows.append([program, n, "numba" in sys.modules, t.words.tolist(), t.first_wrap])
with open(sys.argv[2], "w") as out:  # a file, not stdout: an unbuffered stdout (PYTHONUNBUFFERED) interrupted
    json.dump(rows, out)             # by a signal may write part of a large print and drop the rest
"""


def _probe(calls: list[tuple[str, int]]) -> list[list[object]]:
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    env.pop("FWEMU_NO_NUMBA", None)
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "rows.json"
        r = subprocess.run([sys.executable, "-c", _PROBE, json.dumps(calls), str(out)], env=env,
                           capture_output=True, text=True, timeout=600)
        assert r.returncode == 0, r.stderr
        return json.loads(out.read_text())


def _compiled_words(program: str, n: int) -> list[list[int]]:
    c = build_constants(BuildConfig(program=program, k=7))
    rng = np.random.default_rng(n)
    adc = 40000 - 30000 * np.minimum(np.arange(n), n - np.arange(n)) // n + rng.integers(-20, 21, n)  # up, down
    acc = rng.integers(-2000, 6000, n)
    return run_model(c, adc, acc, engine="numba").words.tolist()


@pytest.mark.skipif(not compiled_kernels().COMPILED, reason="numba not importable: auto is plain Python anyway")
def test_short_calls_run_uncompiled_then_the_budget_switches_to_numba() -> None:
    small = AUTO_PURE_MAX_SAMPLES // 4
    calls = [("kalman_accel", 300), ("recursive", small), ("kalman_baro", small), ("kalman_accel", small),
             ("kalman_accel", small)]   # the last one passes the budget: compiled
    rows = _probe(calls)
    assert [r[2] for r in rows] == [False, False, False, False, True]
    for (program, n), (_, _, _, words, first) in zip(calls, rows):
        assert words == _compiled_words(program, n), (program, n)
        assert first == -1


@pytest.mark.skipif(not compiled_kernels().COMPILED, reason="numba not importable: auto is plain Python anyway")
def test_one_call_over_the_budget_is_compiled_from_the_start() -> None:
    rows = _probe([("kalman_accel", AUTO_PURE_MAX_SAMPLES + 1)])
    assert rows[0][2] is True and rows[0][3] == _compiled_words("kalman_accel", AUTO_PURE_MAX_SAMPLES + 1)


def test_a_short_cli_vectors_run_does_not_import_numba(tmp_path: Path) -> None:
    csv = tmp_path / "s.csv"
    csv.write_text("adc,acc\n" + "\n".join(f"{30000 - 3 * i},2048" for i in range(400)) + "\n")
    code = ("import sys\nfrom firmware_model.cli.main import main\n"
            f"rc = main(['vectors', '--firmware', 'kalman_accel', '--input', {str(csv)!r}, '--generator', 'model',"
            f" '--out', {str(tmp_path / 'v')!r}])\n"
            "print(rc, 'numba' in sys.modules)\n")
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    r = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    assert r.stdout.split()[-2:] == ["0", "False"], r.stdout + r.stderr
