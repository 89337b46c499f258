"""The README's two recipes (issue 34), run verbatim: each fenced ``sh`` block after a ``<!-- recipe: NAME``
marker is executed by bash (``-e -u -o pipefail``) in a fresh folder, with ``fwemu`` on PATH running this
checkout's code. The evaluation recipe copies a log from ``../shared/flights``: the folder is laid out as a
checkout beside ``shared/`` (a link to the real logs), and the test skips when they are absent."""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from tests.support.imports import ROOT

SHARED = Path(os.environ.get("FWEMU_SHARED_FLIGHTS") or ROOT.parent / "shared" / "flights")
_BLOCK = re.compile(r"<!-- recipe: ([\w-]+)[^>]*-->\s*\n```sh\n(.*?)\n```", re.S)


def _recipes() -> dict[str, str]:
    return dict(_BLOCK.findall((ROOT / "README.md").read_text(encoding="utf-8")))


def _run(name: str, tmp_path: Path) -> Path:
    """Run the recipe ``name`` in ``tmp_path/checkout`` (``tmp_path/shared/flights`` = the shared logs); returns
    the folder it ran in."""
    script = _recipes()[name]
    bin_dir = tmp_path / "bin"
    bin_dir.mkdir()
    fwemu = bin_dir / "fwemu"
    # the installed console script of a worktree may point at another checkout: run this one's code
    fwemu.write_text(f"#!/bin/sh\nPYTHONPATH={ROOT} exec {sys.executable} -m firmware_model.cli.main \"$@\"\n")
    fwemu.chmod(0o755)
    work = tmp_path / "checkout"
    work.mkdir()
    if SHARED.is_dir():
        (tmp_path / "shared").mkdir()
        (tmp_path / "shared" / "flights").symlink_to(SHARED)
    env = dict(os.environ, PATH=f"{bin_dir}{os.pathsep}{os.environ.get('PATH', '')}",
               FWEMU_SHARED_FLIGHTS=str(SHARED), OPENBLAS_NUM_THREADS="1")
    r = subprocess.run(["bash", "-euo", "pipefail", "-c", script], cwd=work, env=env, capture_output=True,
                       text=True, timeout=600)
    assert r.returncode == 0, f"README recipe {name} failed (exit {r.returncode}):\n{r.stdout}\n{r.stderr}"
    assert not [p.name for p in work.iterdir() if p.name.startswith(".fwemu-")]   # no temporary names left
    return work


def test_the_readme_has_both_recipes() -> None:
    recipes = _recipes()
    assert set(recipes) == {"port-vectors", "evaluate-log"}
    assert "fwemu inputs" in recipes["port-vectors"] and "fwemu vectors" in recipes["port-vectors"]
    for flag in ("--baro", "--columns"):
        assert flag in recipes["evaluate-log"]


def test_golden_vectors_for_my_port_from_my_flight(tmp_path: Path) -> None:
    if shutil.which("bash") is None:
        pytest.skip("bash is not installed")
    work = _run("port-vectors", tmp_path)
    manifest = json.loads((work / "my_vectors" / "manifest.json").read_text())
    assert manifest                                                   # a set with its manifest
    cases = list((work / "my_vectors" / "cases").glob("*.json"))
    headers = list((work / "my_vectors" / "cases").glob("*.h"))
    assert len(cases) == 1 and len(headers) == 1                      # the files the README says a team drops in
    assert list((work / "my_vectors" / "tables").glob("*.h")) and (work / "my_vectors" / "c" / "cases.h").is_file()
    case = json.loads(cases[0].read_text())
    assert case["firmware"]["program"] == "kalman_accel" and case["events_first_sample"]["APOGEE"] is not None


@pytest.mark.skipif(not (SHARED / "ncsu" / "jackpot-launch-3-firm.csv").is_file(),
                    reason="../shared/flights is absent")
def test_evaluate_my_log(tmp_path: Path) -> None:
    if shutil.which("bash") is None:
        pytest.skip("bash is not installed")
    work = _run("evaluate-log", tmp_path)
    tables = {name: (work / name / "apogee.md").read_text()
              for name in ("my_eval", "my_eval_12bit", "my_eval_columns")}
    # the sensor the README says is applied by default, and the preset when one is named
    assert "telemetrum_v1/default, log noise |" in tables["my_eval"]
    assert "12-bit/default, log noise + added" in tables["my_eval_12bit"]
    # the column map reads the same pressure and axis as the board's own reader: every Kalman run detects
    for name, text in tables.items():
        row = next(line for line in text.splitlines() if line.startswith("| mylog |"))
        assert "miss" not in row, (name, row)
