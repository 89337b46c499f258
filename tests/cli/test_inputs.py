"""Input files and precedence of the CLI (issue 8 items 10 and 11): one rule everywhere (flags override the config
file; a different program is an error), CSV and config JSON validation with one-line errors naming file and line.

CLI cases run the real ``fwemu`` in a subprocess."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from firmware_model.spec.config import BuildConfig, load_config
from firmware_model.runtime.errors import UserError
from firmware_model.model.streams import read_stream_csv

ROOT = Path(__file__).resolve().parents[2]


def fwemu(*argv: str, cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    return subprocess.run([sys.executable, "-m", "firmware_model.cli.main", *argv], capture_output=True, text=True,
                          env=env, timeout=300, cwd=cwd)


def error_line(r: subprocess.CompletedProcess[str]) -> str:
    assert r.returncode == 2, (r.returncode, r.stdout, r.stderr)
    lines = [line for line in r.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and "Traceback" not in r.stderr and lines[0].startswith("fwemu: error: "), r.stderr
    return lines[0]


def write(path: Path, text: str | bytes) -> Path:
    path.write_bytes(text.encode() if isinstance(text, str) else text)
    return path


def stream_csv(path: Path, acc: bool = True, n: int = 40) -> Path:
    rows = ["adc,acc" if acc else "adc"] + [f"{40000 - 3 * i},{2048 + i % 3}" if acc else f"{40000 - 3 * i}"
                                            for i in range(n)]
    return write(path, "\n".join(rows) + "\n")


# ------------------------------------------------------------------------------------------ precedence (item 10)
def test_compare_flags_override_the_config_file(tmp_path: Path) -> None:
    cfg = write(tmp_path / "c.json", json.dumps({"k": 5, "rounding": "half_up"}))
    r = fwemu("compare", "--config", str(cfg), "--k", "6", "--synthetic", "1")
    assert r.returncode == 0, r.stderr
    assert r.stdout.splitlines()[0].startswith("tuning: default"), r.stdout   # compare names its tuning first
    assert r.stdout.splitlines()[1].startswith("program=kalman_baro k=6 rounding=half_up "), r.stdout
    r = fwemu("compare", "--config", str(cfg), "--program", "recursive", "--synthetic", "1")
    assert r.returncode == 0, r.stderr     # the file names no program: the flag picks it
    assert r.stdout.splitlines()[1].startswith("program=recursive k=5 rounding=half_up "), r.stdout


@pytest.mark.parametrize("argv", [
    ["compare", "--program", "recursive", "--synthetic", "1"],
    ["design", "--program", "kalman_baro"],
    ["budget", "--program", "recursive", "--out", "o"],
    ["vectors", "--firmware", "kalman_baro", "--input", "s.csv", "--out", "o"],
])
def test_a_program_flag_against_the_file_is_an_error(argv: list[str], tmp_path: Path) -> None:
    write(tmp_path / "c.json", json.dumps({"program": "kalman_accel", "ratio": 100.0}))
    stream_csv(tmp_path / "s.csv")
    line = error_line(fwemu(*argv, "--config", "c.json", cwd=tmp_path))
    assert "c.json: program='kalman_accel' contradicts" in line
    assert ("--firmware kalman_baro" if argv[0] == "vectors" else f"--program {argv[2]}") in line
    assert not (tmp_path / "o").exists()


def test_vectors_firmware_and_config_that_agree(tmp_path: Path) -> None:
    write(tmp_path / "c.json", json.dumps({"program": "kalman_accel", "ratio": 100.0, "k": 5}))
    stream_csv(tmp_path / "s.csv")
    r = fwemu("vectors", "--firmware", "kalman_accel", "--input", "s.csv", "--config", "c.json", "--generator",
              "model", "--out", "o", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    # half_up: kalman_accel's default rounding
    doc = json.loads((tmp_path / "o" / "cases" / "kalman_accel_half_up_k5_b16_s.json").read_text())
    assert doc["build_config"]["program"] == "kalman_accel" and doc["build_config"]["ratio"] == 100.0


def test_load_config_rule() -> None:
    assert load_config(None, {"k": 5, "program": None}).k == 5
    assert load_config(None, {}) == BuildConfig()


def test_bias_table_uses_and_names_the_program() -> None:
    from firmware_model.cli.compare import bias_table

    baro = bias_table("kalman_baro", ks=(5,), seconds=8.0)
    accel = bias_table("kalman_accel", ks=(5,), seconds=8.0)
    assert baro.splitlines()[0].startswith("kalman_baro: ") and accel.splitlines()[0].startswith("kalman_accel: ")
    assert "acc = 1 g" in accel and "acc = " not in baro
    row = lambda text: [line for line in text.splitlines() if line.startswith("| 5 | floor |")][0]
    assert row(baro) != row(accel)
    with pytest.raises(UserError, match="for kalman_baro, kalman_accel, not recursive"):
        bias_table("recursive", ks=(5,), seconds=1.0)


def test_bias_table_for_a_recursive_program_is_refused() -> None:
    line = error_line(fwemu("compare", "--program", "recursive", "--bias-table"))
    assert "not recursive" in line


# ------------------------------------------------------------------------------------------ input CSV (item 11)
def test_csv_with_a_utf8_bom_is_accepted(tmp_path: Path) -> None:
    f = write(tmp_path / "excel.csv", b"\xef\xbb\xbfadc,acc\r\n40000,2048\r\n39990,2050\r\n")
    s = read_stream_csv(f, 16, 7, require_acc=True)
    assert s.adc.tolist() == [40000, 39990] and s.acc.tolist() == [2048, 2050]
    r = fwemu("vectors", "--firmware", "kalman_accel", "--input", str(f), "--generator", "model", "--out",
              str(tmp_path / "o"))
    assert r.returncode == 0, r.stderr


def test_csv_with_a_duplicate_column_is_refused(tmp_path: Path) -> None:
    f = write(tmp_path / "d.csv", "time,adc,acc,adc\n0,1,2,3\n")
    line = error_line(fwemu("vectors", "--firmware", "kalman_baro", "--input", str(f), "--out", str(tmp_path / "o")))
    assert line == f"fwemu: error: {f}:1: duplicate column 'adc' in the header"


@pytest.mark.parametrize("program", ["kalman_accel", "recursive"])
def test_programs_reading_the_accelerometer_need_an_acc_column(program: str, tmp_path: Path) -> None:
    f = stream_csv(tmp_path / "baro_only.csv", acc=False)
    line = error_line(fwemu("vectors", "--firmware", program, "--input", str(f), "--generator", "model",
                            "--out", str(tmp_path / "o")))
    assert f"{f}:1: this program reads the accelerometer: the header needs an 'acc' column" in line
    line = error_line(fwemu("compare", "--program", program, "--input", str(f)))
    assert "needs an 'acc' column" in line
    assert not (tmp_path / "o").exists()


def test_kalman_baro_without_acc_is_fine(tmp_path: Path) -> None:
    s = read_stream_csv(stream_csv(tmp_path / "b.csv", acc=False), 16, 7)
    assert s.provenance["columns"] == "adc" and not s.acc.any()


def test_csv_undecodable_bytes_name_the_line(tmp_path: Path) -> None:
    f = write(tmp_path / "latin.csv", b"adc\n100\n# caf\xe9\n200\n")
    with pytest.raises(UserError, match=r"latin\.csv:3: not UTF-8 text \(byte 0xe9\)"):
        read_stream_csv(f, 16, 7)


# ------------------------------------------------------------------------------------------ config JSON (item 11)
@pytest.mark.parametrize("text, expected", [
    ('{"k": 5,\n "rounding": "floor",\n "k": 6}', "c.json:3: duplicate key 'k' (JSON keys must be unique)"),
    ('{"extra": 5}', "c.json:1: extra: 5 is not a JSON object"),
    ('{"bogus": 1}', "c.json: 'bogus': unknown field; known: "),
    ('{"program": "kalman_baro", "ratio": 500}', "c.json:1: ratio: 500 is below the documented range for "
                                                 "kalman_baro; allowed: R/q >= 1000"),
    ('{"program": "kalman_accel",\n "ratio": 5.0}', "c.json:2: ratio: 5.0 is below the documented range for "
                                                    "kalman_accel; allowed: R/q >= 10"),
    ('{"k": true}', "c.json:1: k: True is true/false; allowed: an integer 0..10"),
    ('[1, 2]', "a build config must be a JSON object"),
    ('{"k": 5', "c.json:1:8: invalid JSON"),
])
def test_config_json_errors(text: str, expected: str, tmp_path: Path) -> None:
    write(tmp_path / "c.json", text)
    line = error_line(fwemu("design", "--config", "c.json", cwd=tmp_path))
    assert expected in line, line


def test_config_json_with_bom_and_ratio_at_the_bound(tmp_path: Path) -> None:
    write(tmp_path / "c.json", b"\xef\xbb\xbf" + json.dumps({"ratio": 1000.0, "k": 6}).encode())
    assert load_config(tmp_path / "c.json").ratio == 1000.0
    line = error_line(fwemu("design", "--ratio", "999", cwd=tmp_path))   # a flag below the range, too
    assert "--ratio: ratio: 999.0 is below the documented range" in line
    assert load_config(None, {"program": "recursive", "ratio": 1.0}).ratio == 1.0   # ratio unused there


def test_design_flags_override_the_file(tmp_path: Path) -> None:
    write(tmp_path / "c.json", json.dumps({"k": 5, "rounding": "half_up"}))
    r = fwemu("design", "--config", "c.json", "--k", "6", "--json", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    cfg = json.loads(r.stdout)["config"]
    assert cfg["k"] == 6 and cfg["rounding"] == "half_up"
    assert np.isfinite(json.loads(r.stdout)["dt"])


# ------------------------------------------------------------------------------ the CSV reader against its rules
def _plain_reader(path: Path, bits: int, require_acc: bool) -> tuple[list[int], list[int]] | str:
    """The user-CSV rules of firmware_model.model.streams.iter_stream_csv written plainly, one rule after the other
    (this is how the reader was written before its data rows were rewritten for speed): the samples, or the
    error message. Only what the data rows do differently is modelled: header errors come from the header."""
    import csv

    lo, hi = (-(1 << 31), (1 << 31) - 1) if bits == 32 else (0, (1 << bits) - 1)
    what = " (signed 32-bit pascal word)" if bits == 32 else f" ({bits}-bit barometer ADC)"
    header = None
    adc: list[int] = []
    acc: list[int] = []
    reader = csv.reader(path.read_text(encoding="utf-8").splitlines(keepends=True))
    for row in reader:
        n = reader.line_num
        cells = [c.strip() for c in row]
        if not cells or all(c == "" for c in cells) or cells[0].startswith("#"):
            continue
        if header is None:
            header = [c.lower() for c in cells]
            continue
        if len(cells) != len(header):
            return f"{path}:{n}: expected {len(header)} fields, got {len(cells)}"
        for col, idx, a, b, dest in (("adc", header.index("adc"), lo, hi, adc),
                                     ("acc", header.index("acc") if "acc" in header else None, -32768, 32767, acc)):
            if idx is None:
                dest.append(0)
                continue
            try:
                v = int(cells[idx], 10)
            except ValueError:
                return f"{path}:{n}: {col}={cells[idx][:40]!r} is not an integer"
            if not a <= v <= b:
                return f"{path}:{n}: {col}={v} outside [{a}, {b}]" + (what if col == "adc" else "")
            dest.append(v)
    if not adc:
        return f"{path}: no samples after the header"
    return adc, acc


_CELLS = ["0", "1", "4095", "4096", "65535", "65536", "-1", " 12 ", "\t7", "+3", "1_0", "", " ", "x", "#", "# c",
          "2147483647", "2147483648", "-2147483648", "-32768", "32767", "32768", "0x10", "١٢", '"5"', '" 6 "']


@pytest.mark.parametrize("bits", [12, 16, 32])
@settings(max_examples=150, deadline=None)
@given(data=st.data())
def test_csv_data_rows_follow_the_plain_rules(bits: int, data: st.DataObject, tmp_path_factory) -> None:
    """Random data rows (blank, comment, whitespace, quoted, signed, underscored, non-ASCII digits, out of
    range, wrong field counts) under a random header: the reader's samples or its one-line error are the plain
    rules' (any chunk size)."""
    from firmware_model.model.streams import CsvInfo, iter_stream_csv

    header = data.draw(st.sampled_from(["adc,acc", "acc,adc", "adc", "t,adc,acc", "adc,acc,note"]))
    ncol = header.count(",") + 1
    rows = data.draw(st.lists(st.one_of(
        st.lists(st.sampled_from(_CELLS), min_size=ncol, max_size=ncol),
        st.lists(st.sampled_from(_CELLS), min_size=0, max_size=ncol + 1)).map(",".join), max_size=12))
    path = tmp_path_factory.mktemp("csv") / "s.csv"
    path.write_text(header + "\n" + "".join(r + "\n" for r in rows), encoding="utf-8")
    chunk = data.draw(st.sampled_from([1, 2, 1000]))
    expect = _plain_reader(path, bits, False)
    try:
        parts = list(iter_stream_csv(path, bits, 5, chunk=chunk, info=CsvInfo(path, bits, 5)))
    except UserError as exc:
        assert str(exc) == expect
        return
    assert not isinstance(expect, str), expect
    assert [v for a, _ in parts for v in a.tolist()] == expect[0]
    assert [v for _, b in parts for v in b.tolist()] == expect[1]
