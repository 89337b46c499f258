"""The fuzz tier of issue 33: hypothesis mutates real logs, build configs and Monte Carlo specs and feeds them to
the command line (in-process, :func:`firmware_model.cli.main.main`). Every outcome is exit 0 with its whole output,
or exit 2 with one line ``fwemu: error: FILE...`` naming the input file, no traceback and no output at all (no
partial CSV, no chunk folder, no temporary name). The default (``ci``) profile runs a few examples per door; the
``thorough`` profile 20 times more. ``FWEMU_FUZZ_LOG=FILE`` appends one JSON line per try (door, exit code, the
error's first words): docs/testing.md's table of tries and outcomes per door is counted from it.

The teeth test removes one validation (the build config's upper bound on ``baro_sigma``) and shows that the
door's check then fails on the issue's example (an OverflowError traceback)."""

from __future__ import annotations

import contextlib
import io
import json
import os
import re
import tempfile
from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from firmware_model.cli.main import main
from firmware_model.spec import config as config_module
from firmware_model.spec.config import FIELDS, Rule
from tests.support.profiles import examples

SHARED = Path(os.environ.get("FWEMU_SHARED_FLIGHTS", Path(__file__).resolve().parents[3] / "shared" / "flights"))
#: Small real logs of four readers (RRC3, Eggtimer, Raven, AltosUI); each runs in well under a second.
LOGS = ["rocketpy/juno3-rrc3.csv", "euroc21/euler-eggtimer.csv", "rocketpy/ndrt-2020-raven.csv",
        "altosui/2012-05-28-serial-319-flight-005.csv"]
needs_logs = pytest.mark.skipif(not all((SHARED / p).is_file() for p in LOGS), reason="shared flight logs absent")

#: What a field can be replaced with: extremes, wrong types, long text, control bytes.
NASTY_FIELDS = ["1e308", "-1e308", "1e-320", "nan", "inf", "", "x", "-0", "0", "99999999999999999999", "1e6",
                "-1", "0x10", "\x00" * 50, "é", "9" * 400, "1,5", "  ", "true"]


def run_main(argv: list[str]) -> tuple[int, str, str]:
    err, out = io.StringIO(), io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(out):
        try:
            code = main(argv)
        except SystemExit as exc:
            code = exc.code if isinstance(exc.code, int) else 2
        except Exception as exc:  # noqa: BLE001 - any escape is the finding: what a user would see as a traceback, exit 1
            print(f"Traceback (most recent call last): ... {type(exc).__name__}: {exc}", file=err)
            code = 1
    return code, out.getvalue(), err.getvalue()


def record(door: str, code: int, err: str) -> None:
    path = os.environ.get("FWEMU_FUZZ_LOG")
    if not path:
        return
    words = ""
    if code == 2:
        line = err.strip().splitlines()[-1] if err.strip() else ""
        m = re.match(r"fwemu(?: [\w-]+)?: error: (?:[^:]*?/)?[^/:]*?(?::\d+)*: ([^:;]{0,40})", line)
        words = m.group(1).strip() if m else line[:40]
    with open(path, "a", encoding="utf-8") as f:
        f.write(json.dumps({"door": door, "code": code, "error": words}) + "\n")


def assert_door(door: str, code: int, err: str, folder: Path, name: str, outputs: list[Path]) -> None:
    """Exit 0, or exit 2 with one error line naming ``name`` (the input file) and none of ``outputs``; never a
    traceback, never a temporary name left in ``folder``."""
    record(door, code, err)
    assert "Traceback" not in err and "Warning" not in err, err
    assert code in (0, 2), (code, err)
    if code == 2:
        lines = [line for line in err.splitlines() if line.strip()]
        if lines and lines[0].startswith("usage: "):       # argparse: its usage block, then the one error line
            lines = [line for line in lines[1:] if not line.startswith(" ")]
        assert len(lines) == 1 and re.match(r"fwemu(?: [\w-]+)?: error: ", lines[0]), err
        assert name in lines[0], (name, lines[0])
        assert len(lines[0]) < 1200, len(lines[0])
        for out in outputs:
            assert not out.exists(), f"partial output after an error: {out}"
    assert [p for p in folder.rglob("*") if p.name.startswith(".fwemu")] == []


# ------------------------------------------------------------------------------------------ logs
@st.composite
def mutated_log(draw: st.DrawFn) -> tuple[str, bytes]:
    rel = draw(st.sampled_from(LOGS))
    data = (SHARED / rel).read_bytes()
    lines = data.split(b"\n")
    for _ in range(draw(st.integers(1, 3))):
        op = draw(st.sampled_from(["field", "field", "time_jump", "negate_time", "truncate", "drop", "dup",
                                   "bytes"]))
        i = draw(st.integers(1, max(1, len(lines) - 2)))
        sep = b";" if b";" in lines[0] else b","
        if op == "field":
            cells = lines[i].split(sep)
            j = draw(st.integers(0, max(0, len(cells) - 1)))
            cells[j] = draw(st.sampled_from(NASTY_FIELDS)).encode()
            lines[i] = sep.join(cells)
        elif op in ("time_jump", "negate_time"):
            col = 3 if rel.endswith("raven.csv") else 0        # Raven's altitude series has its own time column
            for k in range(i, len(lines)):
                cells = lines[k].split(sep)
                try:
                    t = float(cells[col])
                except (ValueError, IndexError):
                    continue
                cells[col] = repr(t + 1e6 if op == "time_jump" else -t).encode()
                lines[k] = sep.join(cells)
        elif op == "truncate":
            lines = lines[:i] + [lines[i][: draw(st.integers(0, len(lines[i])))]]
        elif op == "drop":
            del lines[i: i + draw(st.integers(1, 50))]
        elif op == "dup":
            lines[i:i] = [lines[i]] * draw(st.integers(1, 3))
        else:
            lines[i] = lines[i] + draw(st.sampled_from([b"\x00" * 20, b"\xff\xfe", b"\r", b'"']))
    return rel, b"\n".join(lines)


@needs_logs
@settings(max_examples=examples(12, ci=6), suppress_health_check=list(HealthCheck), deadline=None)
@given(log=mutated_log())
def test_fuzz_mutated_real_logs(log: tuple[str, bytes]) -> None:
    rel, data = log
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        src = folder / Path(rel).name
        src.write_bytes(data)
        out = folder / "states.csv"
        code, _, err = run_main(["run", "--firmware", "kalman_baro", "--model", "--input", str(src), "--out",
                                 str(out), "--quiet"])
        assert_door("log (run)", code, err, folder, src.name, [out])
        if code == 0:
            assert out.stat().st_size > 0


# ------------------------------------------------------------------------------------------ build configs
_value = st.one_of(st.sampled_from([0, -1, 1, 2, 3, 5, 16, 17, 1e308, -1e308, 1e200, 5e-324, 1e12, 1e13, 3000.5,
                                    65536, 131073, 2**31, 2**63, "abc", "", None, True, [], {}, "floor",
                                    "pascal", "recursive", "x" * 300]),
                   st.floats(allow_nan=False, allow_infinity=False), st.integers(-2**40, 2**40))


@st.composite
def mutated_config(draw: st.DrawFn) -> str:
    base: dict[str, Any] = {"program": draw(st.sampled_from(["kalman_baro", "kalman_accel", "recursive"])),
                            "k": draw(st.integers(3, 8))}
    for key in draw(st.lists(st.sampled_from(list(FIELDS) + ["extra", "bogus"]), min_size=1, max_size=4)):
        base[key] = draw(_value)
    text = json.dumps(base, indent=1)
    if draw(st.integers(0, 9)) == 0:
        text = text[: draw(st.integers(0, len(text)))]
    return text


def check_config(text: str, folder: Path, door: str = "build config") -> None:
    cfg = folder / "cfg.json"
    cfg.write_text(text)
    code, _, err = run_main(["design", "--config", str(cfg)])
    assert_door(door, code, err, folder, "cfg.json", [])


@settings(max_examples=examples(40, ci=25), suppress_health_check=list(HealthCheck), deadline=None)
@given(text=mutated_config())
def test_fuzz_build_configs(text: str) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        check_config(text, Path(tmp))


# ------------------------------------------------------------------------------------------ Monte Carlo specs
MC_BASE: dict[str, Any] = {"scenario": "sub-k400-300m", "k": 5, "methods": ["rec_quarter"], "tunings": ["default"],
                           "chunk_flights": 2, "descent_s": 2.0,
                           "dispersions": {"wind_speed_mps": {"uniform": [0.0, 5.0]}}}
MC_KEYS = {"dispersions": ["wind_speed_mps", "rail_inclination_deg", "baro_gain", "spike_rate", "impulse_scale",
                           "temperature_offset_k", "site_altitude_m", "baro", "accel_range_g"],
           "launch": ["site_altitude_m", "drogue_delay_s"], "": ["k", "chunk_flights", "descent_s", "pad_s",
                                                                  "max_time_s", "scenario", "launch", "rocket"]}
_dist = st.one_of(_value, st.builds(lambda a, b: {"uniform": [a, b]}, _value, _value),
                  st.builds(lambda a, b, lo, hi: {"normal": [a, b], "min": lo, "max": hi}, _value, _value, _value,
                            _value),
                  st.builds(lambda c: {"choice": c}, st.lists(_value, max_size=3)))


@st.composite
def mutated_spec(draw: st.DrawFn) -> dict[str, Any]:
    spec = json.loads(json.dumps(MC_BASE))
    for _ in range(draw(st.integers(1, 2))):
        table = draw(st.sampled_from(list(MC_KEYS)))
        key = draw(st.sampled_from(MC_KEYS[table]))
        if table == "":
            spec[key] = draw(_value)
        else:
            if not isinstance(spec.get(table), dict):
                spec[table] = {}
            spec[table][key] = draw(_dist if table == "dispersions" else _value)
    return spec


@settings(max_examples=examples(12, ci=8), suppress_health_check=list(HealthCheck), deadline=None)
@given(spec=mutated_spec(), n=st.sampled_from(["1", "2", "0", "-5", "x", "99999999999999999999"]))
def test_fuzz_montecarlo_specs(spec: dict[str, Any], n: str) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        src = folder / "spec.json"
        src.write_text(json.dumps(spec))
        out = folder / "mc"
        code, _, err = run_main(["montecarlo", str(src), "-n", n, "--out", str(out), "--no-figures", "--quiet"])
        name = "spec.json" if "-n/--flights" not in err else "-n"
        assert_door("Monte Carlo spec", code, err, folder, name, [out])
        if code == 0:
            assert (out / "summary.md").is_file()


# ------------------------------------------------------------------------------------------ teeth
ISSUE_CONFIGS = ['{"alt_shift": 1}', '{"baro_sigma": 1e200}', '{"quant_alt_m": 1e308}',
                 '{"units_per_metre": 1e308}', '{"gate_mps": 1e308}']


def test_the_issue_configs_pass_the_door(tmp_path: Path) -> None:
    for text in ISSUE_CONFIGS:
        check_config(text, tmp_path)
        key = next(iter(json.loads(text)))
        code, _, err = run_main(["design", "--config", str(tmp_path / "cfg.json")])
        assert code == 2 and re.search(rf"cfg\.json:1: {key}: ", err), err    # the key the user wrote


def test_teeth_removing_one_validation_fails_the_door(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Without baro_sigma's upper bound, {"baro_sigma": 1e200} reaches the gain design and overflows: the
    door's check (no traceback, exit 0 or 2) fails."""
    monkeypatch.delenv("FWEMU_FUZZ_LOG", raising=False)                # not a try of the fuzz table
    check_config('{"baro_sigma": 1e200}', tmp_path)                      # with it: a clean error
    monkeypatch.setitem(config_module.FIELDS, "baro_sigma", Rule("number", 0.0, None, lo_open=True))
    monkeypatch.setattr(config_module, "WHOLE_RANGE_FIELDS", ("units_per_metre",))
    with pytest.raises(AssertionError, match="Traceback|OverflowError"):
        check_config('{"baro_sigma": 1e200}', tmp_path)
