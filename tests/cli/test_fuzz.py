"""Fuzz of the CLI's file inputs (issue 8 must-show): random CSV streams, config JSON files and assembly sources
never give a traceback or a partial output. Each outcome is either success (exit 0, a complete output that
passes its check) or one line ``fwemu: error: ...`` with exit 2 and no output at all; never a temporary name.

In-process calls of :func:`firmware_model.cli.main.main` for speed (hypothesis), plus a few subprocess cases."""

from __future__ import annotations

import contextlib
import io
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from firmware_model.vectors import generate as vectors
from firmware_model.cli.main import main
from firmware_model.spec.config import BuildConfig
from tests.support.profiles import examples

ROOT = Path(__file__).resolve().parents[2]
FIELDS = [f for f in BuildConfig.__dataclass_fields__]


def run_main(argv: list[str]) -> tuple[int, str]:
    err = io.StringIO()
    out = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(out):
        try:
            code = main(argv)
        except SystemExit as exc:   # argparse usage errors
            code = exc.code if isinstance(exc.code, int) else 2
    return code, err.getvalue()


def assert_clean_outcome(code: int, err: str, folder: Path, out: Path | None, source_context: bool = False) -> None:
    """``source_context``: the assembler's error line may be followed by the source line and a caret (indented)."""
    assert "Traceback" not in err, err
    assert code in (0, 2), (code, err)
    if code == 2:
        lines = [line for line in err.splitlines() if line.strip()]
        if source_context:
            lines = [lines[0]] + [line for line in lines[1:] if not line.startswith(" ")]
        assert len(lines) == 1 and lines[0].startswith("fwemu: error: "), err
        if out is not None:
            assert not out.exists(), f"partial output after an error: {sorted(p.name for p in out.rglob('*'))}"
    leftovers = [p for p in folder.rglob("*") if p.name.startswith(".fwemu")]
    assert leftovers == [], leftovers


# ------------------------------------------------------------------------------------------ CSV
_cell = st.one_of(st.integers(-70000, 140000).map(str), st.sampled_from(["", " ", "x", "1.5", "nan", "0x10", "+5",
                                                                          "1e3", "\"7\"", "9" * 30, "-0"]),
                  st.text(max_size=6))
_header_names = st.lists(st.sampled_from(["adc", "acc", "ADC", " acc ", "time", "", "adc", "p"]), min_size=1,
                         max_size=4)


@st.composite
def csv_bytes(draw: st.DrawFn) -> bytes:
    if draw(st.integers(0, 9)) == 0:
        return draw(st.binary(max_size=200))                     # raw garbage
    header = draw(_header_names)
    rows = draw(st.lists(st.lists(_cell, min_size=max(1, len(header) - 1), max_size=len(header) + 1),
                         max_size=12))
    lines = [",".join(header)] + [",".join(r) for r in rows]
    if draw(st.booleans()):
        lines.insert(draw(st.integers(0, len(lines))), "# comment " + draw(st.text(max_size=5)))
    text = draw(st.sampled_from(["\n", "\r\n"])).join(lines) + draw(st.sampled_from(["", "\n"]))
    data = text.encode("utf-8", "surrogatepass")
    if draw(st.booleans()):
        data = b"\xef\xbb\xbf" + data
    if draw(st.integers(0, 5)) == 0:
        pos = draw(st.integers(0, len(data)))
        data = data[:pos] + draw(st.sampled_from([b"\xff", b"\x00", b"\xe9", b"\"", b"\r"])) + data[pos:]
    return data


@settings(max_examples=examples(60, ci=15), suppress_health_check=[HealthCheck.too_slow], deadline=None)
@given(data=csv_bytes(), program=st.sampled_from(["kalman_baro", "kalman_accel", "recursive"]))
def test_fuzz_csv_input(data: bytes, program: str) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        csv = folder / "in.csv"
        csv.write_bytes(data)
        out = folder / "out"
        code, err = run_main(["vectors", "--firmware", program, "--input", str(csv), "--generator", "model",
                              "--out", str(out)])
        assert_clean_outcome(code, err, folder, out)
        if code == 0:
            assert vectors.check_set(out) == []
        code, err = run_main(["compare", "--program", program, "--input", str(csv)])
        assert_clean_outcome(code, err, folder, None)


# ------------------------------------------------------------------------------------------ config JSON
_json_scalar = st.one_of(st.none(), st.booleans(), st.integers(-2**70, 2**70), st.floats(allow_nan=True),
                         st.text(max_size=8), st.sampled_from(["kalman_baro", "kalman_accel", "recursive",
                                                               "recursive_seed_literal", "floor", "half_up",
                                                               "jerk", "dwna", "accel_only"]))
_json_value = st.recursive(_json_scalar, lambda inner: st.one_of(st.lists(inner, max_size=3),
                                                                 st.dictionaries(st.text(max_size=4), inner,
                                                                                 max_size=3)), max_leaves=6)
_plausible = {"k": st.integers(-2, 12), "ratio": st.floats(0.01, 1e7), "baro_bits": st.integers(6, 18),
              "shift": st.integers(0, 9), "units_per_metre": st.floats(-1, 1e5), "baro_min": st.integers(-5, 70000),
              "baro_max": st.integers(-5, 70000), "accel_counts_per_mps2": st.floats(1e-3, 1e6),
              "baro_sigma": st.floats(1e-3, 1e4), "accel_sigma": st.floats(1e-3, 1e4),
              "threshold_q8": st.integers(-5, 2**21), "mach_lo_mps": st.floats(-1, 1e3),
              "mach_hi_mps": st.floats(-1, 1e3), "liftoff_mps": st.floats(-1, 1e4), "gate_mps": st.floats(-1, 1e4)}


@st.composite
def config_text(draw: st.DrawFn) -> str:
    choice = draw(st.integers(0, 9))
    if choice == 0:
        return draw(st.text(max_size=40))
    keys = draw(st.lists(st.sampled_from(FIELDS + ["bogus", "Program"]), max_size=6))
    obj = {}
    for key in keys:
        strategy = _plausible.get(key) if draw(st.booleans()) else None
        obj[key] = draw(strategy if strategy is not None else _json_value)
    text = json.dumps(obj, allow_nan=True)
    if choice == 1 and keys:                       # a duplicate key
        text = text[:-1] + (", " if obj else "") + json.dumps(keys[0]) + ": 1}"
    return text


@settings(max_examples=examples(80, ci=20), suppress_health_check=[HealthCheck.too_slow], deadline=None)
@given(text=config_text(), program=st.sampled_from(["kalman_baro", "kalman_accel", "recursive"]))
def test_fuzz_config_json(text: str, program: str) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        cfg = folder / "c.json"
        cfg.write_text(text, encoding="utf-8", errors="surrogatepass")
        code, err = run_main(["design", "--config", str(cfg)])
        assert_clean_outcome(code, err, folder, None)
        csv = folder / "s.csv"
        csv.write_text("adc,acc\n" + "\n".join(f"{30000 + 7 * i},{2048 + i}" for i in range(24)) + "\n")
        out = folder / "out"
        code, err = run_main(["vectors", "--firmware", program, "--config", str(cfg), "--input", str(csv),
                              "--generator", "model", "--out", str(out)])
        assert_clean_outcome(code, err, folder, out)
        if code == 0:
            assert vectors.check_set(out) == []


# ------------------------------------------------------------------------------------------ assembly
_mnemonics = ["move.l", "move.w", "moveq", "add.l", "sub.w", "lsl.l", "asr.w", "muls", "divu", "bra", "beq.s",
              "dbra", "jsr", "rts", "trap", "lea", "cmp.l", "tst.w", "clr.b", "nop", "dc.w", "dc.l", "ds.b", "equ",
              "org", "even", "include", "macro", "endm", "if", "endif", "bogus"]
_operands = ["d0", "d7", "a0", "a7", "(a0)", "(a1)+", "-(a7)", "4(a0)", "2(a0,d1.w)", "#1", "#-1", "#$7fffffff",
             "#300", "label", "label(pc)", "$1000", "$FFF000.w", "$F000.w", "1", "\"s\"", "'x'", "", "d0-d3/a0",
             "#(1+2)*3", "9999999999999"]


@st.composite
def asm_text(draw: st.DrawFn) -> str:
    lines = []
    for _ in range(draw(st.integers(0, 12))):
        label = draw(st.sampled_from(["", "", "label:", "x:", "label"]))
        ops = ",".join(draw(st.lists(st.sampled_from(_operands), max_size=2)))
        comment = draw(st.sampled_from(["", " ; c", " ; caf\u00e9"]))
        lines.append(f"{label} {draw(st.sampled_from(_mnemonics))} {ops}{comment}")
    if draw(st.integers(0, 6)) == 0:
        lines.append(draw(st.text(max_size=20)))
    return "\n".join(lines) + "\n"


@settings(max_examples=examples(80, ci=20), suppress_health_check=[HealthCheck.too_slow], deadline=None)
@given(text=asm_text(), latin1=st.booleans())
def test_fuzz_assembly_source(text: str, latin1: bool) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        src = folder / "p.s"
        src.write_bytes(text.encode("latin-1", "replace") if latin1 else text.encode("utf-8", "surrogatepass"))
        binary = folder / "p.bin"
        code, err = run_main(["asm", str(src), "-o", str(binary)])
        assert_clean_outcome(code, err, folder, binary, source_context=True)


# ------------------------------------------------------------------------------------------ a few real processes
NASTY = {
    "csv": [b"\xef\xbb\xbfadc,adc\n1,2\n", b"\x00\x01\x02", b"adc\n" + b"9" * 5000 + b"\n", b"adc,acc\n\"1,2\n"],
    "json": [b'{"k": 1e400}', b"[" * 100000 + b"]" * 100000, b'{"ratio": NaN}', b'{"program": {}}'],
    "s": [b"\xff\xfe m o v e", b" dc.b " + b"1," * 5000 + b"1\n", b"x: macro\n x\n endm\n x\n"],
}


@pytest.mark.parametrize("kind, data", [(k, d) for k, ds in NASTY.items() for d in ds])
def test_nasty_files_in_a_real_process(kind: str, data: bytes, tmp_path: Path) -> None:
    f = tmp_path / f"in.{kind}"
    f.write_bytes(data)
    out = tmp_path / "out"
    argv = {"csv": ["vectors", "--firmware", "kalman_baro", "--generator", "model", "--input", str(f), "--out",
                    str(out)],
            "json": ["design", "--config", str(f)],
            "s": ["asm", str(f), "-o", str(out)]}[kind]
    r = subprocess.run([sys.executable, "-m", "firmware_model.cli.main", *argv], capture_output=True, text=True,
                       timeout=300, env=dict(os.environ, PYTHONPATH=str(ROOT)))
    assert_clean_outcome(r.returncode, r.stderr, tmp_path, out, source_context=kind == "s")
