"""fwemu check-port (issue 24): the shipped C port passes for every program, rounding and barometer kind; one-line
porting mistakes, each patched into a copy of vectors/c/fw.c, are caught and shrunk to short streams within 60 s;
a port under other names and types runs through an adapter; the files written for a difference compile and
reproduce it (Unity and plain C); the golden vectors as a Unity runner pass with the shipped port and fail with
a broken one."""

from __future__ import annotations

import difflib
import json
import re
import shutil
import subprocess
import tempfile
from pathlib import Path

import numpy as np
import pytest

from firmware_model.cli.check_port import config_from_args
from firmware_model.cli.main import build_parser, main
from firmware_model.model.run import run_model
from firmware_model.model.trace import word_names
from firmware_model.spec.build_constants import build_constants
from firmware_model.spec.config import PROGRAMS, ROUNDINGS
from firmware_model.vectors.cases import case_config, pascal_case_config
from firmware_model.vectors.portcheck.adapter import const_slots
from firmware_model.vectors.portcheck.build import build_port
from firmware_model.vectors.portcheck.check import check_port, compare
from firmware_model.vectors.schema import case_schema, validate
from firmware_model.vectors.unity import RUNNER_NAME
from tests.support.profiles import examples

ROOT = Path(__file__).resolve().parents[2]
CDIR = ROOT / "vectors" / "c"
UNITY = ROOT.parent / "shared" / "vendor" / "unity"

needs_cc = pytest.mark.skipif(shutil.which("gcc") is None, reason="gcc not installed")
needs_unity = pytest.mark.skipif(not (UNITY / "unity.c").is_file(), reason="../shared/vendor/unity not present")
STRICT = ["gcc", "-std=c99", "-Wall", "-Wextra", "-Werror", "-pedantic", "-O1"]

# ------------------------------------------------------------------------------------------ the broken ports
#: (id, what a porter did, program, rounding, fw.c text, its one-line replacement). Each is found by the search
#: below within 60 s on one core and shrunk to at most SHRUNK_MAX samples (docs/port-check.md has the table).
MUTANTS: list[tuple[str, str, str, str, str, str]] = [
    ("floor_shift", "floor instead of half-up in one shift (the predict's X2 >> K)", "kalman_baro", "half_up",
     "    t1 = fw_rs(st->X2, K, mode) + fw_rs(st->X3, 2 * K + 1, mode);",
     "    t1 = fw_rs(st->X2, K, 0) + fw_rs(st->X3, 2 * K + 1, mode);"),
    ("mul16", "a 16-bit intermediate in the gain multiply (the innovation cast to int16_t)", "kalman_baro", "floor",
     "    return fw_wrap32(fw_rs(e * (int64_t)g.m, g.s, mode));",
     "    return fw_wrap32(fw_rs((int64_t)(int16_t)e * g.m, g.s, mode));"),
    ("rej_unsaturated", "a missing saturation: the gated-sample counter REJ not held at GATE_N once the gate opens",
     "kalman_baro", "floor",
     "            } else {\n                use = 1;\n            }",
     "            } else {\n                use = 1; st->REJ = (uint16_t)(st->REJ + 1u);\n            }"),
    ("cal_off_by_one", "an off-by-one in the pad calibration count (CAL <= 2^CAL_P)", "kalman_accel", "floor",
     "    if ((int32_t)st->CAL < ncal) {", "    if ((int32_t)st->CAL <= ncal) {"),
    ("logical_shr", ">> on a negative number done as a logical shift (of the 32-bit word)", "recursive", "floor",
     "    return ~((~x) >> s);", "    return (int64_t)((uint32_t)x >> s);"),
    ("gate_lt", "the barometer rate gate compared with < instead of <=", "recursive", "floor",
     "    if (d >= -(int64_t)c->E_GATE && d <= (int64_t)c->E_GATE) {",
     "    if (d >= -(int64_t)c->E_GATE && d < (int64_t)c->E_GATE) {"),
    ("kalman_gate_lt", "the Kalman innovation gate compared with < instead of <=", "kalman_baro", "floor",
     "        if ((int64_t)e1 >= -(int64_t)c->E_GATE && (int64_t)e1 <= (int64_t)c->E_GATE) {",
     "        if ((int64_t)e1 >= -(int64_t)c->E_GATE && (int64_t)e1 < (int64_t)c->E_GATE) {"),
    ("gate_n_le", "the gate re-opens one sample late (REJ <= GATE_N instead of <)", "kalman_accel", "half_up",
     "            } else if ((int32_t)st->REJ < c->GATE_N) {\n                st->REJ = (uint16_t)(st->REJ + 1u);\n"
     "                st->EVENTS |= FW_EV_BARO_REJECT;\n            } else {",
     "            } else if ((int32_t)st->REJ <= c->GATE_N) {\n                st->REJ = (uint16_t)(st->REJ + 1u);\n"
     "                st->EVENTS |= FW_EV_BARO_REJECT;\n            } else {"),
    ("clip_evidence", "apogee evidence during an accelerometer clip (the coast test without 'not ACC_CLIP or "
     "CLIP_CLEAR')", "kalman_accel", "floor",
     "        if (st->DLY == 0u && st->VB < 0 && !FW_CLIPPED(st->EVENTS) && phys && high) {",
     "        if (st->DLY == 0u && st->VB < 0 && phys && high) {"),
]
SHRUNK_MAX = 300
BUDGET_S = 60.0


def patched_port(tmp: Path, old: str, new: str) -> Path:
    """A copy of vectors/c (fw.c, fw.h) in ``tmp`` with ``old`` replaced by ``new`` in fw.c; asserts the patch
    applied exactly once and changed exactly one line."""
    tmp.mkdir(parents=True, exist_ok=True)
    text = (CDIR / "fw.c").read_text()
    assert text.count(old) == 1, old
    patched = text.replace(old, new)
    changed = [ln for ln in difflib.ndiff(text.splitlines(), patched.splitlines()) if ln[:2] in ("- ", "+ ")]
    assert len(changed) == 2, changed  # one line out, one line in
    (tmp / "fw.c").write_text(patched)
    shutil.copy(CDIR / "fw.h", tmp / "fw.h")
    return tmp / "fw.c"


@pytest.fixture(scope="module")
def shipped(tmp_path_factory: pytest.TempPathFactory):
    if shutil.which("gcc") is None:
        pytest.skip("gcc not installed")
    return build_port([CDIR / "fw.c"], workdir=tmp_path_factory.mktemp("shipped"))


def _cfg(program: str, rounding: str, kind: str, k: int = 5):
    return pascal_case_config(program, rounding, 4) if kind == "pascal" else case_config(program, rounding, k, 16)


@needs_cc
@pytest.mark.parametrize("kind", ("adc16", "pascal"))
@pytest.mark.parametrize("rounding", ROUNDINGS)
@pytest.mark.parametrize("program", PROGRAMS)
def test_shipped_port_passes(shipped, program: str, rounding: str, kind: str) -> None:
    cfg = _cfg(program, rounding, kind)
    res = check_port(shipped, cfg, examples=examples(30), seed=7)
    assert res.mismatch is None
    assert res.examples == examples(30)
    assert res.samples >= 20 * res.examples  # the streams are not trivial (flights run to thousands of samples)


@needs_cc
@pytest.mark.parametrize("k, bits", ((4, 12), (8, 16)))
@pytest.mark.parametrize("program", PROGRAMS)
def test_shipped_port_passes_other_k_and_widths(shipped, program: str, k: int, bits: int) -> None:
    cfg = case_config(program, "half_up" if k == 4 else "floor", k, bits)
    res = check_port(shipped, cfg, examples=examples(10), seed=11)
    assert res.mismatch is None and res.examples == examples(10)


@needs_cc
@pytest.mark.parametrize("mid", [m[0] for m in MUTANTS])
def test_broken_port_is_caught_and_shrunk(tmp_path: Path, shipped, mid: str) -> None:
    _, _what, program, rounding, old, new = next(m for m in MUTANTS if m[0] == mid)
    port = build_port([patched_port(tmp_path / "port", old, new)], workdir=tmp_path / "build")
    cfg = case_config(program, rounding, 5, 16)
    res = check_port(port, cfg, examples=None, seconds=BUDGET_S, seed=0)
    mm = res.mismatch
    assert mm is not None, f"{mid}: not found in {res.examples} streams, {res.seconds:.0f} s"
    assert res.seconds_to_failure + res.shrink_seconds <= BUDGET_S
    assert 1 <= len(mm.adc) <= SHRUNK_MAX
    assert mm.diff.sample == len(mm.adc) - 1 or (mm.diff.sample == -1 and len(mm.adc) == 1)  # cut after it
    # the difference is the port's: the model agrees with the shipped port on the shrunk stream
    diff, _ = compare(shipped, cfg, build_constants(cfg), mm.adc, mm.acc)
    assert diff is None
    model = run_model(build_constants(cfg), mm.adc, mm.acc)
    row = model.init_words if mm.diff.sample < 0 else model.words[mm.diff.sample]
    assert int(row[mm.diff.column]) == mm.diff.expected != mm.diff.actual


@needs_cc
def test_same_seed_replays_the_same_difference(tmp_path: Path) -> None:
    _, _, program, rounding, old, new = MUTANTS[0]
    port = build_port([patched_port(tmp_path / "port", old, new)], workdir=tmp_path / "build")
    cfg = case_config(program, rounding, 5, 16)
    a = check_port(port, cfg, examples=500, seed=3).mismatch
    b = check_port(port, cfg, examples=500, seed=3).mismatch
    assert a is not None and b is not None
    assert np.array_equal(a.adc, b.adc) and np.array_equal(a.acc, b.acc) and a.diff == b.diff


def _build_and_run(cmd: list[str], exe: Path) -> subprocess.CompletedProcess[str]:
    subprocess.run(cmd + ["-o", str(exe)], check=True, capture_output=True, text=True)
    return subprocess.run([str(exe)], capture_output=True, text=True, timeout=60, check=False)


@needs_cc
@needs_unity
def test_cli_difference_files_reproduce_it(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    _, _, program, rounding, old, new = next(m for m in MUTANTS if m[0] == "cal_off_by_one")
    src = patched_port(tmp_path / "port", old, new)
    out = tmp_path / "out"
    code = main(["check-port", str(src), "--program", program, "--rounding", rounding, "--k", "5",
                 "--time", "60", "--out", str(out), "--quiet"])
    text = capsys.readouterr().out
    assert code == 1
    m = re.search(r"DIFFERENCE at sample (\d+), word (\w+): expected (-?\d+) \(model\), actual (-?\d+)", text)
    assert m, text
    sample, word, want, got = int(m.group(1)), m.group(2), m.group(3), m.group(4)
    assert "acc: " in text and "adc: " in text
    unity = next(out.glob("test_*_unity.c"))
    plain = next(p for p in out.glob("test_*.c") if not p.name.endswith("_unity.c"))
    case = json.loads(next(out.glob("*.json")).read_text())
    assert validate(case, case_schema()) == []
    assert case["expected"][sample][case["words"].index(word)] == int(want)
    assert len(case["adc"]) == sample + 1
    # the plain test: fails on the broken port with the line check-port printed, passes on the shipped one
    bad = _build_and_run(STRICT + [f"-I{src.parent}", str(src), str(plain)], tmp_path / "plain_bad")
    assert bad.returncode == 1 and f"sample {sample} word {word}: expected {want} got {got}" in bad.stdout
    good = _build_and_run(STRICT + [f"-I{CDIR}", str(CDIR / "fw.c"), str(plain)], tmp_path / "plain_good")
    assert good.returncode == 0 and "PASS" in good.stdout
    ucmd = [f"-I{UNITY}", str(UNITY / "unity.c")]
    bad = _build_and_run(STRICT + [f"-I{src.parent}", str(src), *ucmd, str(unity)], tmp_path / "unity_bad")
    assert bad.returncode != 0 and f"Expected {want} Was {got}" in bad.stdout and "1 Failures" in bad.stdout
    good = _build_and_run(STRICT + [f"-I{CDIR}", str(CDIR / "fw.c"), *ucmd, str(unity)], tmp_path / "unity_good")
    assert good.returncode == 0 and "0 Failures" in good.stdout


@needs_cc
def test_cli_shipped_port_exit_0(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                 capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.chdir(tmp_path)
    (tmp_path / "tmp").mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path / "tmp"))
    code = main(["check-port", str(CDIR / "fw.c"), "--program", "kalman_accel", "--sensor", "pascal",
                 "--rounding", "half_up", "--examples", "20", "--quiet"])
    assert code == 0
    assert "no difference in 20 streams" in capsys.readouterr().out
    assert sorted(p.name for p in tmp_path.iterdir()) == ["tmp"]      # no .hypothesis, no port-check/
    assert list((tmp_path / "tmp").iterdir()) == []                   # the build folder is removed


@pytest.mark.parametrize("argv, want", [
    (["--program", "kalman_accel", "--k", "6", "--tuning", "recommended"],
     {"program": "kalman_accel", "k": 6, "rounding": "half_up", "ratio": 1000.0}),
    (["--program", "recursive", "--k", "7", "--tuning", "recommended", "--sensor", "adc12"],
     {"program": "recursive", "k": 7, "shift": 5, "baro_bits": 12}),
    (["--program", "kalman_baro", "--sensor", "pascal", "--rounding", "half_up"],
     {"program": "kalman_baro", "k": 5, "baro_kind": "pascal", "rounding": "half_up"}),
])
def test_build_flags(argv: list[str], want: dict) -> None:
    args = build_parser().parse_args(["check-port", "x.c", *argv])
    cfg, streams = config_from_args(args)
    assert {k: getattr(cfg, k) for k in want} == want and streams == []


@needs_cc
def test_cli_case_json_gives_the_build_and_its_stream(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    case = ROOT / "vectors" / "cases" / "kalman_accel_half_up_k5_b16_flight.json"
    code = main(["check-port", str(CDIR / "fw.c"), "--case", str(case), "--examples", "10", "--quiet"])
    assert code == 0
    out = capsys.readouterr().out
    assert "kalman_accel half_up k=5 16-bit ADC" in out and "no difference in 11 streams" in out
    # the case's own stream is checked first: a port broken on the pad fails on it, before any search
    _, _, _, _, old, new = next(m for m in MUTANTS if m[0] == "cal_off_by_one")
    src = patched_port(tmp_path / "port", old, new)
    code = main(["check-port", str(src), "--case", str(case), "--examples", "10", "--quiet", "--out",
                 str(tmp_path / "out")])
    out = capsys.readouterr().out
    assert code == 1
    n = len(json.loads(case.read_text())["adc"])
    assert f"(the given stream of {n}, cut after the first difference)" in out


# ------------------------------------------------------------------------------------------ usage errors
@pytest.mark.parametrize("argv, message", [
    (["check-port", "--program", "recursive"], "give the port's C sources"),
    (["check-port", "nowhere/fw.c"], "nowhere/fw.c: no such C source file"),
    (["check-port", str(CDIR / "fw.c"), "--lib", "x.so"], "not both"),
    (["check-port", str(CDIR / "fw.c"), "--case", "nowhere.json"], "nowhere.json: no such case file"),
])
def test_usage_errors_are_one_line_exit_2(argv: list[str], message: str, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and message in err[0], err


@needs_cc
def test_build_error_is_one_line_exit_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    src = patched_port(tmp_path, "    return ~((~x) >> s);", "    return ~((~x) >> s)")
    assert main(["check-port", str(src)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "compiling fw.c failed" in err[0] and "fw.c:" in err[0], err


@needs_cc
def test_port_with_other_word_names_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    src = patched_port(tmp_path, '"X1", "X2", "X3", "EVENTS", "APFRAC"', '"X1", "V", "X3", "EVENTS", "APFRAC"')
    assert main(["check-port", str(src), "--program", "kalman_baro"]) == 2
    err = capsys.readouterr().err
    assert "the port's state words for kalman_baro are X1 V X3" in err and "the model's are X1 X2 X3" in err


# ------------------------------------------------------------------------------------------ adapter
#: fw.c's identifiers renamed as a team might have named them (whole tokens, in fw.c and fw.h).
RENAMES = {
    "fw_init": "altf_reset", "fw_step": "altf_sample", "fw_words": "altf_dump", "fw_word_name": "altf_dump_name",
    "fw_state": "altf_state_t", "fw_consts": "altf_params_t", "fw_gain": "altf_gain_t", "fw_program": "altf_mode_t",
    "fw_wrap32": "altf_wrap", "fw_rs": "altf_shr", "fw_mulg": "altf_gmul", "fw_alt": "altf_table", "FW_H": "ALTF_H",
    "FW_RECURSIVE": "ALTF_REC", "FW_KALMAN_BARO": "ALTF_KB", "FW_KALMAN_ACCEL": "ALTF_KA",
    "FW_RECURSIVE_SEED_LITERAL": "ALTF_LIT",
    "EST": "est", "EXT": "ext_", "VEL": "vel", "X1": "h_q8", "X2": "v_q8", "X3": "a_q8", "ACC0": "acc_pad",
    "EVENTS": "flags", "APFRAC": "apo_frac", "GND": "ground", "SUMZ": "sum_h", "SUMA": "sum_a", "CAL": "n_cal",
    "REJ": "n_rej", "NEG": "n_neg", "ZL": "last_z",
    "K": "dt_shift", "ROUND": "round_mode", "BARO_SIGN": "baro_sign", "S": "filt_shift", "THR": "apo_thr",
    "V_LIFT": "v_liftoff", "V_GATE": "v_gate", "G11": "kb1", "G21": "kb2", "G31": "kb3", "G12": "ka1",
    "G22": "ka2", "G32": "ka3", "ACC_G": "acc_gain", "G11T": "kt1", "G21T": "kt2", "G31T": "kt3",
    "MACH_VLO": "v_mach", "MACH_VHI": "v_mach_hi", "MACH_E": "mach_e", "BARO_MIN": "baro_lo",
    "BARO_MAX": "baro_hi", "ALT_SHIFT": "tab_shift", "ALT_N": "tab_n", "CAL_P": "cal_bits", "E_GATE": "gate_e",
    "GATE_N": "gate_n", "APO_N": "apo_n", "ALT": "table",
}
#: ... and its own types: 16-bit gain mantissas, and in the state struct `long` for the 32-bit words and `unsigned
#: long` for the 16-bit ones (whatever fields the struct has: a word added to the spec gets them too).
RETYPE_GAIN = ("    int32_t m;\n    int32_t s;", "    int16_t mant;\n    uint8_t sh;")


def _retype_state(header: str) -> str:
    start = header.index("typedef struct {", header.index("altf_params_t;"))
    end = header.index("} altf_state_t;", start)
    block = re.sub(r"^    int32_t ", "    long ", header[start:end], flags=re.M)
    block = re.sub(r"^    uint16_t ", "    unsigned long ", block, flags=re.M)
    assert block.count("long ") >= 4, block
    return header[:start] + block + header[end:]


def team_port(tmp: Path, mutate: tuple[str, str] | None = None) -> tuple[Path, Path]:
    """fw.c/fw.h renamed and retyped into altf.c/altf.h, and the adapter JSON that maps them; optionally with one
    line of fw.c changed first."""
    tmp.mkdir(parents=True, exist_ok=True)
    token = re.compile(r"\b(" + "|".join(sorted(map(re.escape, RENAMES), key=len, reverse=True)) + r")\b")
    texts = {}
    for name in ("fw.c", "fw.h"):
        text = (CDIR / name).read_text()
        if mutate is not None and name == "fw.c":
            assert text.count(mutate[0]) == 1
            text = text.replace(mutate[0], mutate[1])
        text = token.sub(lambda m: RENAMES[m.group(1)], text)
        text = re.sub(r"\.m\b", ".mant", re.sub(r"\.s\b", ".sh", text)).replace('#include "fw.h"', '#include "altf.h"')
        texts[name] = text
    assert texts["fw.h"].count(RETYPE_GAIN[0]) == 1
    texts["fw.h"] = _retype_state(texts["fw.h"].replace(*RETYPE_GAIN))
    (tmp / "altf.c").write_text(texts["fw.c"])
    (tmp / "altf.h").write_text(texts["fw.h"])
    consts = {}
    for slot in const_slots():  # every constant check-port sets, under the team's name
        name, _, part = slot.partition(".")
        consts[slot] = f"{{c}}.{RENAMES.get(name, name)}" + (f".{'mant' if part == 'm' else 'sh'}" if part else "")
    consts["ALT"] = f"{{c}}.{RENAMES['ALT']}"
    words = {w: f"{{s}}.{RENAMES.get(w, w)}" for p in PROGRAMS for w in word_names(p)}
    adapter = {"include": ["altf.h"], "state_type": "altf_state_t", "consts_type": "altf_params_t",
               "programs": {"recursive": "ALTF_REC", "kalman_baro": "ALTF_KB", "kalman_accel": "ALTF_KA",
                            "recursive_seed_literal": "ALTF_LIT"},
               "consts": consts,
               "init": "altf_reset({program}, &{c}, &{s}, {baro}, {acc});",
               "step": "altf_sample({program}, &{c}, &{s}, {baro}, {acc});",
               "words": words}
    (tmp / "adapter.json").write_text(json.dumps(adapter, indent=1))
    return tmp / "altf.c", tmp / "adapter.json"


@needs_cc
def test_team_port_under_other_names_and_types_runs_through_the_adapter(tmp_path: Path,
                                                                        capsys: pytest.CaptureFixture[str]) -> None:
    src, adapter = team_port(tmp_path / "team")
    assert "fw_" not in src.read_text() and "X1" not in src.read_text()   # nothing of the fw.h API is left
    for program in PROGRAMS:
        code = main(["check-port", str(src), "--adapter", str(adapter), "--program", program, "--rounding",
                     "half_up", "--examples", str(examples(15)), "--quiet", "--out", str(tmp_path / "out")])
        assert code == 0, capsys.readouterr()
    # and a broken team port is caught through the adapter, its Unity test calls the team's names
    _, _, program, rounding, old, new = next(m for m in MUTANTS if m[0] == "gate_lt")
    src, adapter = team_port(tmp_path / "broken", (old, new))
    code = main(["check-port", str(src), "--adapter", str(adapter), "--program", program, "--rounding", rounding,
                 "--time", "60", "--quiet", "--out", str(tmp_path / "out2")])
    assert code == 1
    unity = next((tmp_path / "out2").glob("test_*_unity.c"))
    assert "altf_sample(ALTF_REC, &fwpc_c, &fwpc_s, baro[i], acc[i]);" in unity.read_text()
    plain = next(p for p in (tmp_path / "out2").glob("test_*.c") if not p.name.endswith("_unity.c"))
    bad = _build_and_run(STRICT + [f"-I{src.parent}", str(src), str(plain)], tmp_path / "plain_bad")
    assert bad.returncode == 1 and "expected" in bad.stdout
    if (UNITY / "unity.c").is_file():
        bad = _build_and_run(STRICT + [f"-I{src.parent}", f"-I{UNITY}", str(src), str(UNITY / "unity.c"), str(unity)],
                             tmp_path / "unity_bad")
        assert bad.returncode != 0 and "1 Failures" in bad.stdout


@pytest.mark.parametrize("doc, message", [
    ({"include": "a.h"}, "missing key 'state_type'"),
    ({"include": "a.h", "state_type": "s", "consts_type": "c", "programs": {"kalman": "X"}, "consts": {},
      "init": "i();", "step": "s();", "words": {"X1": "{s}.x"}}, "unknown program 'kalman'"),
    ({"include": "a.h", "state_type": "s", "consts_type": "c", "programs": {"kalman_baro": "X"},
      "consts": {"KK": "{c}.k"}, "init": "i();", "step": "s();", "words": {"X1": "{s}.x"}}, "unknown constant 'KK'"),
    ({"include": "a.h", "state_type": "s", "consts_type": "c", "programs": {"kalman_baro": "X"}, "consts": {},
      "init": "i({st});", "step": "s();", "words": {"X1": "{s}.x"}}, "unknown placeholder {st}"),
    ({"include": "a.h", "state_type": "s", "consts_type": "c", "programs": {"kalman_baro": "X"}, "consts": {},
      "init": "i();", "step": "s();", "words": {"X1": "{s}.x"}, "extra": 1}, "unknown key 'extra'"),
])
def test_bad_adapter_is_one_line_exit_2(tmp_path: Path, doc: dict, message: str,
                                        capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "adapter.json"
    path.write_text(json.dumps(doc, indent=1))
    assert main(["check-port", str(CDIR / "fw.c"), "--adapter", str(path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(path) in err[0] and message in err[0], err


@needs_cc
def test_adapter_missing_a_model_word_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    src, adapter = team_port(tmp_path)
    doc = json.loads(adapter.read_text())
    del doc["words"]["NEG"]
    adapter.write_text(json.dumps(doc))
    assert main(["check-port", str(src), "--adapter", str(adapter), "--program", "recursive"]) == 2
    err = capsys.readouterr().err
    assert "has no expression for NEG" in err and " ".join(word_names("recursive")) in err


# ------------------------------------------------------------------------------------------ --lib
@needs_cc
def test_prebuilt_library(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    lib = tmp_path / "libfw.so"
    subprocess.run(STRICT + ["-fPIC", "-shared", str(CDIR / "fw.c"), "-o", str(lib)], check=True)
    code = main(["check-port", "--lib", str(lib), "-I", str(CDIR), "--program", "recursive", "--examples", "10",
                 "--quiet"])
    assert code == 0, capsys.readouterr()


# ------------------------------------------------------------------------------------------ Unity runner
@needs_cc
@needs_unity
def test_vectors_unity_runner_passes_shipped_port_and_fails_broken_one(tmp_path: Path,
                                                                       capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["vectors", "--unity", str(tmp_path), "--out", str(ROOT / "vectors")]) == 0
    runner = tmp_path / RUNNER_NAME
    n_cases = json.loads((ROOT / "vectors" / "manifest.json").read_text())["n_cases"]
    assert runner.read_text().count("    RUN_TEST(test_") == n_cases
    # the runner (all the cases' data) is compiled once; the shipped and the broken port are linked with it
    obj = tmp_path / "runner.o"
    subprocess.run(STRICT + ["-c", f"-I{CDIR}", f"-I{ROOT / 'vectors' / 'cases'}", f"-I{UNITY}", str(runner), "-o",
                             str(obj)], check=True, capture_output=True)
    unity = [f"-I{UNITY}", str(UNITY / "unity.c"), str(obj)]
    good = _build_and_run(STRICT + [f"-I{CDIR}", str(CDIR / "fw.c"), *unity], tmp_path / "good")
    assert good.returncode == 0, good.stdout[-2000:]
    assert f"{n_cases} Tests 0 Failures 0 Ignored" in good.stdout
    _, _, _, _, old, new = next(m for m in MUTANTS if m[0] == "cal_off_by_one")
    bad_src = patched_port(tmp_path / "broken", old, new)
    bad = _build_and_run(STRICT + [f"-I{bad_src.parent}", str(bad_src), *unity], tmp_path / "bad")
    assert bad.returncode != 0
    fails = re.search(r"(\d+) Tests (\d+) Failures", bad.stdout)
    assert fails and int(fails.group(1)) == n_cases and int(fails.group(2)) > 0
    assert re.search(r"FAIL: Expected -?\d+ Was -?\d+:case kalman_accel_\w+ sample \d+ word \w+", bad.stdout)


@needs_cc
@needs_unity
def test_vectors_unity_runner_of_a_user_set(tmp_path: Path) -> None:
    csv = tmp_path / "s.csv"
    csv.write_text("adc,acc\n30000,2048\n30001,2048\n29990,2100\n29950,4000\n29900,4000\n")
    out = tmp_path / "set"
    assert main(["vectors", "--firmware", "kalman_baro", "--input", str(csv), "--out", str(out), "--unity",
                 str(out / "unity"), "--generator", "model"]) == 0
    inc = [f"-I{out / 'c'}", f"-I{CDIR}", f"-I{out / 'cases'}", f"-I{UNITY}", str(UNITY / "unity.c")]
    good = _build_and_run(STRICT + inc + [str(CDIR / "fw.c"), str(out / "unity" / RUNNER_NAME)], tmp_path / "run")
    assert good.returncode == 0 and "1 Tests 0 Failures 0 Ignored" in good.stdout
