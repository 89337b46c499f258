"""The C99 port in vectors/c reproduces every committed golden vector, bit for bit, on the host (strict warnings,
and again under UBSan/ASan) and on an 8-bit AVR (ATmega2560 under simavr); the harness reports a corrupted vector
with the exact message firmware teams will see."""

from __future__ import annotations

import json
import re
import shutil
import subprocess
from pathlib import Path

import pytest
from hypothesis import given, strategies as st, settings

from firmware_model.vectors.cases import AVR_CASES

from tests.support.profiles import examples

ROOT = Path(__file__).resolve().parents[2]
VECTORS = ROOT / "vectors"
CDIR = VECTORS / "c"

needs_gcc = pytest.mark.skipif(shutil.which("gcc") is None or shutil.which("make") is None,
                               reason="gcc/make not installed")
needs_avr = pytest.mark.skipif(shutil.which("avr-gcc") is None or shutil.which("simavr") is None,
                               reason="avr-gcc/avr-libc/simavr not installed (Debian: gcc-avr avr-libc simavr)")


def n_cases() -> int:
    return json.loads((VECTORS / "manifest.json").read_text())["n_cases"]


def make(*targets: str, vectors: Path = VECTORS, build: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(["make", "-s", "-C", str(CDIR), f"VECTORS={vectors}", f"BUILD={build}", *targets],
                          capture_output=True, text=True, timeout=300)


@needs_gcc
def test_host_build_reproduces_every_committed_case(tmp_path: Path) -> None:
    r = make("check", build=tmp_path)
    assert r.returncode == 0, r.stdout + r.stderr
    assert f"{n_cases()} passed, 0 failed" in r.stdout
    assert "case " not in r.stdout


def subset_set(dest: Path, names: list[str]) -> Path:
    """A vector set in ``dest`` holding only the committed cases ``names`` (their headers and altitude tables,
    and a case table of just them, rendered as ``fwemu vectors`` renders one): the harness built on a few cases
    instead of all of them (issue 29: the whole set's compile was 38 s of this test)."""
    from firmware_model.vectors.c_header import cases_table_header
    from firmware_model.vectors.generate import read_committed_case

    cases = [read_committed_case(VECTORS, n) for n in names]
    (dest / "cases").mkdir(parents=True)
    (dest / "c").mkdir()
    for n in names:
        shutil.copy(VECTORS / "cases" / f"{n}.h", dest / "cases" / f"{n}.h")
    shutil.copytree(VECTORS / "tables", dest / "tables")
    (dest / "c" / "cases.h").write_text(cases_table_header(cases, "FWV_CASES_H"))
    return dest


@needs_gcc
def test_corrupted_expected_word_fails_with_precise_message(tmp_path: Path) -> None:
    name = "kalman_accel_half_up_k5_b16_flight"
    others = ["recursive_floor_k4_b16_edge_step", "kalman_baro_half_up_k5_b16_flight"]
    copy = subset_set(tmp_path / "vectors", [others[0], name, others[1]])
    header = copy / "cases" / f"{name}.h"
    text = header.read_text()
    doc = json.loads((VECTORS / "cases" / f"{name}.json").read_text())
    sample, word = 17, "X2"
    col = doc["words"].index(word)
    want = doc["expected"][sample][col]
    # rows of the expected array are "    { w0, w1, ... }" in sample order
    start = text.index(f"fwv_{name}_expected[")
    rows = re.findall(r"^    \{ ([^}]*) \}", text[start:], flags=re.M)
    cells = rows[sample].split(", ")
    assert int(cells[col]) == want
    cells[col] = str(want + 1)
    old_row = "    { " + rows[sample] + " }"
    new_row = "    { " + ", ".join(cells) + " }"
    pos = text.index(old_row, start)
    header.write_text(text[:pos] + new_row + text[pos + len(old_row):])
    r = make("check", vectors=copy, build=tmp_path / "build")
    assert r.returncode != 0
    lines = r.stdout.splitlines()
    assert f"case {name} sample {sample} word {word}: expected {want + 1} got {want}" in lines
    assert "2 passed, 1 failed" in lines


@needs_gcc
def test_a_subset_of_committed_cases_passes_unchanged(tmp_path: Path) -> None:
    """The subset the test above corrupts passes as it is (so the failure above is the corrupted word's)."""
    names = ["recursive_floor_k4_b16_edge_step", "kalman_accel_half_up_k5_b16_flight",
             "kalman_baro_half_up_k5_b16_flight"]
    r = make("check", vectors=subset_set(tmp_path / "vectors", names), build=tmp_path / "build")
    assert r.returncode == 0, r.stdout + r.stderr
    assert "3 passed, 0 failed" in r.stdout.splitlines()


@needs_gcc
def test_ubsan_asan_build_passes(tmp_path: Path) -> None:
    r = make("ubsan", build=tmp_path)
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-2000:]
    assert f"{n_cases()} passed, 0 failed" in r.stdout
    assert "runtime error" not in r.stdout + r.stderr


AVR_LINE = re.compile(r"cycles program (\d): samples (\d+) min (\d+) mean (\d+) max (\d+)")


@needs_avr
def test_avr_simavr_run_passes(tmp_path: Path) -> None:
    r = make("avr", build=tmp_path)
    log = re.sub(r"\x1b\[[0-9;]*m", "", (tmp_path / "avr.log").read_text()) if (tmp_path / "avr.log").exists() else ""
    assert r.returncode == 0, r.stdout + r.stderr + log
    passed = re.search(r"^(\d+) passed, 0 failed", log, flags=re.M)
    assert passed and int(passed.group(1)) == len(AVR_CASES), log      # every case of the subset ran
    stats = {int(m.group(1)): tuple(int(g) for g in m.groups()[1:]) for m in AVR_LINE.finditer(log)}
    assert set(stats) == {0, 1, 2, 3}, log              # every program ran on the AVR
    for prog, (n, lo, mean, hi) in stats.items():
        assert n > 0 and 0 < lo <= mean <= hi < 65536, (prog, log)
    assert "OVERFLOW" not in log


@needs_avr
def test_avr_run_reports_a_corrupted_vector(tmp_path: Path) -> None:
    copy = tmp_path / "vectors"
    shutil.copytree(VECTORS, copy, ignore=shutil.ignore_patterns("build"))
    name = "recursive_floor_k4_b16_edge_step"
    header = copy / "cases" / f"{name}.h"
    text = header.read_text()
    start = text.index(f"fwv_{name}_expected[")
    m = re.compile(r"^    \{ (-?\d+), ", flags=re.M).search(text, start)
    assert m is not None
    est = int(m.group(1))
    header.write_text(text[:m.start(1)] + str(est - 1) + text[m.end(1):])
    r = make("avr", vectors=copy, build=tmp_path / "build")
    log = re.sub(r"\x1b\[[0-9;]*m", "", (tmp_path / "build" / "avr.log").read_text())
    assert r.returncode != 0
    assert f"case {name} sample 0 word EST: expected {est - 1} got {est}" in log


# ----------------------------------------------------------------------------- the exact helpers of fw.c
HELPER_MAIN = r"""
#include <stdio.h>
#include <inttypes.h>
#include "fw.h"
int main(void) {
    long long x; int s, mode; long long m;
    while (scanf("%lld %d %d %lld", &x, &s, &mode, &m) == 4) {
        fw_gain g; g.m = (int32_t)m; g.s = s;
        printf("%" PRId64 " %" PRId32 " %" PRId32 "\n", fw_rs((int64_t)x, s, mode), fw_wrap32((int64_t)x),
               fw_mulg((int64_t)(int32_t)fw_wrap32((int64_t)x), g, mode));
    }
    return 0;
}
"""


@pytest.fixture(scope="module")
def helper_exe(tmp_path_factory: pytest.TempPathFactory) -> Path:
    if shutil.which("gcc") is None:
        pytest.skip("gcc not installed")
    d = tmp_path_factory.mktemp("helpers")
    (d / "main.c").write_text(HELPER_MAIN)
    exe = d / "helpers"
    subprocess.run(["gcc", "-std=c99", "-Wall", "-Wextra", "-Werror", "-O2", "-fsanitize=undefined",
                    "-fno-sanitize-recover=all", f"-I{CDIR}", str(CDIR / "fw.c"), str(d / "main.c"), "-o", str(exe)],
                   check=True, capture_output=True)
    return exe


def _py_rs(x: int, s: int, mode: int) -> int:
    """Spec §1 rs with Python's exact integer floor shift (an independent oracle for fw_rs)."""
    if s == 0:
        return x
    return (x + (1 << (s - 1))) >> s if mode else x >> s


def _py_wrap32(x: int) -> int:
    return ((x + (1 << 31)) % (1 << 32)) - (1 << 31)


@given(st.lists(st.tuples(st.one_of(st.integers(-(1 << 48), 1 << 48),
                                    st.sampled_from([0, 1, -1, (1 << 31) - 1, -(1 << 31), 1 << 31, -(1 << 47),
                                                     (1 << 47) - 1, 127, 128, -128, -129, 384, -384])),
                          st.integers(0, 47), st.integers(0, 1), st.integers(-32768, 32767)),
                min_size=1, max_size=50))
@settings(max_examples=examples(40))
def test_rs_wrap_mulg_match_exact_integer_arithmetic(helper_exe: Path,
                                                    rows: list[tuple[int, int, int, int]]) -> None:
    text = "".join(f"{x} {s} {mode} {m}\n" for x, s, mode, m in rows)
    out = subprocess.run([str(helper_exe)], input=text, capture_output=True, text=True, check=True).stdout.split("\n")
    for (x, s, mode, m), line in zip(rows, out):
        rs_c, wrap_c, mulg_c = (int(v) for v in line.split())
        assert rs_c == _py_rs(x, s, mode), (x, s, mode)
        assert wrap_c == _py_wrap32(x), x
        assert mulg_c == _py_wrap32(_py_rs(_py_wrap32(x) * m, s, mode)), (x, s, mode, m)
