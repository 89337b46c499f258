"""The C99 port in vectors/c reproduces every committed golden vector on Cortex-M0, M3 and M4 under qemu-system-arm
(-Os and -O2), a deliberate rounding defect fails on every core, the instruction counts are exact (checked on a
function of known length), and the splitting of large cases for small MCUs still checks every sample."""

from __future__ import annotations

import json
import re
import shutil
import subprocess
from pathlib import Path
from typing import Callable

import pytest

ROOT = Path(__file__).resolve().parents[2]
VECTORS = ROOT / "vectors"
CDIR = VECTORS / "c"
CORES = ("m0", "m3", "m4")

needs_arm = pytest.mark.skipif(
    shutil.which("arm-none-eabi-gcc") is None or shutil.which("qemu-system-arm") is None,
    reason="arm-none-eabi-gcc/newlib/qemu-system-arm not installed "
           "(Debian: gcc-arm-none-eabi libnewlib-arm-none-eabi qemu-system-arm)")
needs_avr = pytest.mark.skipif(shutil.which("avr-gcc") is None or shutil.which("simavr") is None,
                               reason="avr-gcc/avr-libc/simavr not installed")


def n_cases() -> int:
    return json.loads((VECTORS / "manifest.json").read_text())["n_cases"]


def make(cdir: Path, *targets: str, build: Path, **variables: str) -> subprocess.CompletedProcess[str]:
    args = [f"{k}={v}" for k, v in variables.items()]
    return subprocess.run(["make", "-s", "-C", str(cdir), f"VECTORS={VECTORS}", f"BUILD={build}", *args, *targets],
                          capture_output=True, text=True, timeout=900)


@needs_arm
@pytest.mark.parametrize("core", CORES)
def test_every_case_on_each_cortex_m_core_at_both_levels(core: str, tmp_path: Path,
                                                         record_property: Callable[[str, object], None]) -> None:
    r = make(CDIR, "cortex-m", build=tmp_path, CM_CORES=core)
    for line in r.stdout.splitlines():   # the closing lines, printed at the end of the run (tests/conftest.py)
        if re.fullmatch(rf"cortex-{core}-O[s2]: \d+ passed, \d+ failed", line):
            record_property("closing_line", line)
    assert r.returncode == 0, r.stdout[-4000:] + r.stderr[-4000:]
    for opt in ("Os", "O2"):
        assert f"cortex-{core}-{opt}: {n_cases()} passed, 0 failed" in r.stdout.splitlines()
    assert "case " not in r.stdout


def _defective_port(tmp_path: Path) -> Path:
    """A copy of vectors/c whose half-up rounding drops the +2^(s-1): one wrong rounding."""
    cdir = tmp_path / "c"
    shutil.copytree(CDIR, cdir, ignore=shutil.ignore_patterns("build"))
    src = (cdir / "fw.c").read_text()
    # fw_rs: the half-up branch adds 2^(s-1) before the floor shift; remove exactly that addition.
    patched, n = re.subn(r"x \+ \(\(int64_t\)1 << \(s - 1\)\)", "x", src)
    assert n == 1, "fw_rs's half-up rounding not found: update this test with fw.c"
    (cdir / "fw.c").write_text(patched)
    return cdir


@needs_arm
def test_a_wrong_rounding_fails_on_every_core(tmp_path: Path) -> None:
    cdir = _defective_port(tmp_path)
    r = make(cdir, "cortex-m", build=tmp_path / "build", CM_OPTS="Os", CM_CASES="half_up_k5_b16_(flight|edge_ties)")
    assert r.returncode != 0
    for core in CORES:
        line = next(l for l in r.stdout.splitlines() if l.startswith(f"cortex-{core}-Os: "))
        m = re.fullmatch(rf"cortex-{core}-Os: (\d+) passed, (\d+) failed", line)
        assert m and int(m.group(2)) > 0, line
    assert re.search(r"^case \w+ sample \d+ word \w+: expected -?\d+ got -?\d+$", r.stdout, flags=re.M)


@needs_arm
@pytest.mark.parametrize("core", ("m0", "m3"))
def test_instruction_counts_are_exact_on_a_known_function(core: str, tmp_path: Path) -> None:
    r = make(CDIR, "cortex-m-icount", build=tmp_path, CM_CORES=core, CM_OPTS="Os",
             CM_CASES="^kalman_accel_floor_k7_b16_edge_step$")
    assert r.returncode == 0, r.stdout + r.stderr
    assert "calibration: known 101 instructions counted as 101" in r.stdout
    m = re.search(r"^icount program 2: samples (\d+) min (\d+) mean (\d+) max (\d+) at (\S+) sample (\d+)$",
                  r.stdout, flags=re.M)
    assert m, r.stdout
    lo, mean, hi = (int(m.group(i)) for i in (2, 3, 4))
    assert 0 < lo <= mean <= hi


@needs_arm
def test_without_icount_the_count_is_flagged(tmp_path: Path) -> None:
    """The counting relies on -icount shift=0; run without it, the harness must not pass silently."""
    r = subprocess.run(["bash", str(CDIR / "mcu" / "check.sh"), "m3", "Os", str(VECTORS), str(tmp_path),
                        "^kalman_accel_floor_k7_b16_edge_step$"],
                       capture_output=True, text=True, timeout=300,
                       env={"PATH": "/usr/bin:/bin", "CM_DEFS": "-DFWV_ICOUNT"})
    assert re.search(r"^calibration: known 101 instructions counted as \d+$", r.stdout, flags=re.M), r.stdout + r.stderr
    assert "calibration: known 101 instructions counted as 101" not in r.stdout
    assert "icount: the calibration is wrong" in r.stdout
    assert r.returncode != 0


@needs_avr
def test_split_cases_check_every_sample_on_the_avr(tmp_path: Path) -> None:
    """kalman_accel k7 flight's expected array is over avr-gcc's 32 KiB object limit: it runs as slices, and a
    corrupted word in the last slice is still found, by name and sample."""
    name = "kalman_accel_floor_k7_b16_flight"
    copy = tmp_path / "vectors"
    shutil.copytree(VECTORS, copy, ignore=shutil.ignore_patterns("build"))
    doc = json.loads((copy / "cases" / f"{name}.json").read_text())
    last = len(doc["expected"]) - 1
    header = copy / "cases" / f"{name}.h"
    text = header.read_text()
    start = text.index(f"fwv_{name}_expected[")
    rows = list(re.finditer(r"^    \{ ([^}]*) \}", text[start:], flags=re.M))
    row = rows[last]
    cells = row.group(1).split(", ")
    cells[0] = str(int(cells[0]) + 1)
    a, b = start + row.start(1), start + row.end(1)
    header.write_text(text[:a] + ", ".join(cells) + text[b:])
    r = subprocess.run(["bash", str(CDIR / "mcu" / "check.sh"), "avr", "Os", str(copy), str(tmp_path / "b"),
                        f"^{name}$"], capture_output=True, text=True, timeout=900)
    assert r.returncode != 0
    assert re.search(rf"^case {name}\[\d+:{last + 1}\) sample {last} word {doc['words'][0]}: ", r.stdout, flags=re.M), \
        r.stdout
    assert "avr-Os: 0 passed, 1 failed" in r.stdout


@needs_arm
@needs_avr
def test_budget_mcu_reports_every_target_with_its_worst_input(tmp_path: Path) -> None:
    import os
    import sys

    env = dict(os.environ, PYTHONPATH=str(ROOT))
    # k = 4: the budget inputs at 16 samples/s (the flight is 8x shorter than at the default k = 7); what is checked
    # is the report (every target, its worst input, sizes, load), not a sample rate (issue 29: the suite's time)
    r = subprocess.run([sys.executable, "-m", "firmware_model.cli.main", "budget", "--mcu", "--program", "kalman_baro",
                        "--k", "4", "--out", str(tmp_path / "out")], capture_output=True, text=True, timeout=900,
                       env=env)
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    data = json.loads((tmp_path / "out" / "mcu.json").read_text())
    assert [b["program"] for b in data] == ["kalman_baro"]
    steps = data[0]["steps"]
    assert set(steps) == {"avr-Os", "m0-Os", "m0-O2", "m3-Os", "m3-O2", "m4-Os", "m4-O2"}
    for key, m in steps.items():
        assert m["passed"] and 0 < m["min"] <= m["mean"] <= m["max"], key
        assert re.fullmatch(r"kalman_baro_floor_k4_b16_budget_\w+(\[\d+:\d+\))? sample \d+", m["max_at"]), m["max_at"]
        assert 0 < m["load"] < 1
    sizes = data[0]["sizes"]
    assert all(s["code_bytes"] > 0 and s["state_bytes"] > 0 and s["stack_bytes"] > 0 for s in sizes.values())
    md = (tmp_path / "out" / "mcu.md").read_text()
    assert "instructions" in md and "| kalman_baro k=4 floor | MC68000 (ours) |" in md
