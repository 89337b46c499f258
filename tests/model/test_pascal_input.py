"""The digital barometer's 32-bit pascal word (``baro_kind`` pascal, docs/firmware-spec.md §2, §2a, §5, §6).

* CPU (68000 assembly on ``isa``) == integer model (numba kernels) == numpy model on EVERY word, for every program
  and both roundings, on hypothesis streams over the whole 32-bit word range (valid pascals, the valid range's
  edges, words inside the table but outside the valid range, negative and huge words) and on pascal flights.
* The pascal table against an independent standard atmosphere (PyPI ``ambiance``) over every valid pascal.
* Integer model vs float mirror within the derived bound for pascal builds, with teeth.
* Bad input words and bad pascal configs are one-line :class:`UserError`\\ s.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from firmware_model.flights import strategies as fst
from firmware_model.spec.alt_table import AltTable, exact_altitude_m, linear_transfer
from firmware_model.spec.atmosphere import altitude_m
from firmware_model.spec.config import PROGRAMS, BuildConfig
from firmware_model.spec.build_constants import build_constants
from firmware_model.runtime.errors import UserError
from firmware_model.model.streams import FlightParams, synthetic_pascal_flight
from firmware_model.model.run import run_model
from tests.support.model_numpy import run_model_numpy
from firmware_model.model.trace import EVENT_BITS
from tests.support.profiles import examples
from tests.model.test_kalman import _check_bound

KALMAN = ("kalman_baro", "kalman_accel")
ROUNDINGS = ("floor", "half_up")
#: Pascals per metre at a sea-level pad (rho g): the pascal kind's units_per_metre.
PA_PER_M = 12.01


def pascal_cfg(program: str, k: int = 6, rounding: str = "floor", **kw: object) -> BuildConfig:
    kw.setdefault("units_per_metre", PA_PER_M)
    if program == "kalman_accel":
        kw.setdefault("ratio", 100.0)
    return BuildConfig(program=program, k=k, rounding=rounding, baro_kind="pascal", **kw)  # type: ignore[arg-type]  # **kw of mixed BuildConfig field types


def assert_cpu_equals_models(cfg: BuildConfig, p: np.ndarray, acc: np.ndarray):
    """CPU, compiled model and numpy model on the same pascal stream; fail at the first differing word."""
    pytest.importorskip("isa.cpu")
    from firmware_model.firmware.assemble import build_firmware
    from firmware_model.firmware.harness import run_firmware

    build = build_firmware(cfg)
    cpu = run_firmware(build, p, acc)
    model = run_model(build.consts, p, acc)
    numpy_model = run_model_numpy(build.consts, p, acc)
    for name, other in (("model", model), ("numpy model", numpy_model)):
        assert np.array_equal(cpu.init_words, other.init_words), (name, cpu.init_words, other.init_words, p[:1])
        if not np.array_equal(cpu.words, other.words):
            i, j = np.argwhere(cpu.words != other.words)[0]
            pytest.fail(f"{cfg.program} {cfg.rounding} k={cfg.k}: sample {i} word {cpu.names[j]}: cpu "
                        f"{cpu.words[i].tolist()} != {name} {other.words[i].tolist()}; p[:{i + 1}]="
                        f"{p[:i + 1].tolist()}; acc[:{i + 1}]={acc[:i + 1].tolist()}")
    assert model.first_wrap == numpy_model.first_wrap
    return cpu, model


# ---------------------------------------------------------------------------------------------------- CPU == model
@pytest.mark.parametrize("program", PROGRAMS)
@pytest.mark.parametrize("rounding", ROUNDINGS)
@settings(max_examples=examples(5), deadline=None)
@given(data=st.data())
def test_cpu_equals_model_on_any_pascal_word(program: str, rounding: str, data: st.DataObject) -> None:
    """Every word of every sample, streams over the whole signed 32-bit register (valid, edge, invalid)."""
    k = data.draw(st.sampled_from((4, 5, 6, 7, 8)))
    p = data.draw(fst.pascal_streams(min_len=1, max_len=100))
    acc = data.draw(fst.accel_streams(min_len=len(p), max_len=len(p)))
    kw = {}
    if program in ("recursive", "recursive_seed_literal"):
        kw = {"shift": data.draw(st.integers(1, 8)), "threshold_q8": data.draw(st.sampled_from((32, 64, 128)))}
    else:
        kw = {"alt_shift": data.draw(st.sampled_from((None, 6, 8, 9))),
              "baro_min": data.draw(st.sampled_from((None, 0, 1000, 20000))),
              "baro_max": data.draw(st.sampled_from((None, 120000, 131071)))}
    assert_cpu_equals_models(pascal_cfg(program, k, rounding, **kw), p, acc)


@pytest.mark.parametrize("program", PROGRAMS)
@settings(max_examples=examples(3), deadline=None)
@given(data=st.data())
def test_cpu_equals_model_on_quick_pascal_flights(program: str, data: st.DataObject) -> None:
    cfg = pascal_cfg(program, data.draw(st.sampled_from((4, 5, 6))), data.draw(st.sampled_from(ROUNDINGS)))
    p, acc = data.draw(fst.pascal_flight_streams(cfg, max_len=300))
    assert_cpu_equals_models(cfg, p, acc)


@pytest.mark.parametrize("program", PROGRAMS)
@pytest.mark.parametrize("k,rounding", [(5, "floor"), (6, "half_up")])
def test_pascal_flight_all_programs_events_and_apogee(program: str, k: int, rounding: str) -> None:
    """A 1.5 km flight from a 1,200 m pad (integer pascals, 3 Pa noise) with two invalid words and a
    transonic-free profile: CPU == models on every word, and the flight logic really runs: LIFTOFF, APOGEE
    (Kalman: within 0.5 s of the true apogee), BARO_INVALID on the invalid words only."""
    s = synthetic_pascal_flight(k, seed=7, params=FlightParams(pad_altitude_m=1200.0, boost_accel_g=12.0,
                                                               burn_s=1.6, pad_s=1.0))
    p = s.adc.copy()
    bad = [len(p) // 3, len(p) // 2]
    p[bad[0]], p[bad[1]] = 0, 2**31 - 1
    extra = {"recursive": {"gate_mps": 30.0}, "kalman_baro": {"ratio": 1000.0, "baro_sigma": 3.0},
             "kalman_accel": {"baro_sigma": 3.0}}.get(program, {})
    cfg = pascal_cfg(program, k, rounding, **extra)
    cpu, model = assert_cpu_equals_models(cfg, p, s.acc)
    if program == "recursive_seed_literal":
        return
    first = model.first_event("LIFTOFF")
    assert 0 < first < s.truth["apogee_sample"]
    apo = model.first_event("APOGEE")
    assert apo > 0
    if program in KALMAN:
        assert abs(apo - s.truth["apogee_sample"]) * 2.0**-k <= 0.5, (apo, s.truth)
        invalid = np.flatnonzero(model.column("EVENTS") & EVENT_BITS["BARO_INVALID"])
        assert invalid.tolist() == bad
        assert model.first_wrap == -1


def test_recursive_wraps_exactly_on_huge_words() -> None:
    """A pascal word beyond 2^23 makes z << 8 wrap; the CPU (NEG.L/LSL.L) and the model agree on the wrapped
    words and the model reports the wrap (the ADC kind can never get there)."""
    p = np.array([1 << 23, (1 << 31) - 1, -(1 << 31), 101325, 5], dtype=np.int64)
    acc = np.zeros_like(p)
    for program in ("recursive", "recursive_seed_literal"):
        # gate_sigmas 0: the recursive rate gate (spec §5 step 5) would hold these jumps out and nothing would wrap
        # (the gated build is checked too: CPU == models, no wrap)
        cpu, model = assert_cpu_equals_models(pascal_cfg(program, 5, gate_sigmas=0.0), p, acc)
        assert model.first_wrap >= 0
        if program == "recursive":
            _, gated = assert_cpu_equals_models(pascal_cfg(program, 5), p, acc)
            assert gated.first_wrap == -1
        assert cpu.init_words[0] == -(1 << 31)       # -(2^23) << 8 = -2^31: exact, the last value that fits


# ---------------------------------------------------------------------------------------------------- the table
ambiance = pytest.importorskip("ambiance")


def _pascal_check(table: AltTable, mode: str, lo: int = 1000, hi: int = 120000) -> np.ndarray:
    """|table - ambiance| at every pascal lo..hi within the interpolation bound of tests/spec/test_alt_table.py:
    D^2/8 max|h''| (over the segment and its neighbours) + 1/256 m rounding + 0.02 m (two atmospheres)."""
    p = np.arange(lo, hi + 1)
    got = table.lookup(p, mode) / 256.0
    ref = ambiance.Atmosphere.from_pressure(p.astype(np.float64)).H
    tf = linear_transfer(1.0, 0.0, -1)
    s = table.shift
    nseg = len(table.nodes) - 1
    hx = exact_altitude_m(tf, np.arange(max(lo - (2 << s), 500), min(hi + (2 << s), 1 << 17) + 1), 500.0)
    first = max(lo - (2 << s), 500)
    d2 = np.abs(np.diff(hx, 2))
    seg = (np.arange(len(d2)) + first + 1) >> s
    seg_max = np.zeros(nseg + 1)
    np.maximum.at(seg_max, seg, d2)
    around = np.maximum(seg_max, np.maximum(np.roll(seg_max, 1), np.roll(seg_max, -1)))
    bound = (2.0**s) ** 2 / 8 * around[p >> s] + 1 / 256 + 0.02
    err = np.abs(got - ref)
    badi = np.flatnonzero(err > bound)
    assert badi.size == 0, (p[badi[:5]], err[badi[:5]], bound[badi[:5]])
    return err


@pytest.mark.parametrize("mode", ROUNDINGS)
def test_default_pascal_table_error_against_ambiance_over_every_valid_pascal(mode: str) -> None:
    """The default pascal table (nodes every 128 Pa over 0..2^17 Pa: 1,025 nodes, 4,100 bytes) at every pascal of
    1,000..120,000 (-1.5 km .. 31 km): measured max 8.43 m at 1,024 Pa (31 km), 2.18 m from 2 kPa (26 km), 0.33 m
    from 5 kPa (20 km), 0.072 m from 10 kPa (16 km), 0.025 m from 20 kPa (12 km); asserted with a little room."""
    c = build_constants(pascal_cfg("kalman_baro"))
    table = AltTable(c.ALT_TABLE, c.ALT_SHIFT, 17)
    assert (len(table.nodes), table.rom_bytes(), c.ALT_SHIFT, c.BARO_MIN, c.BARO_MAX) == (1025, 4100, 7, 1000, 120000)
    err = _pascal_check(table, mode)
    p = np.arange(1000, 120001)
    for lo, worst in ((1000, 8.5), (2000, 2.2), (5000, 0.34), (10000, 0.075), (20000, 0.026)):
        assert err[p >= lo].max() <= worst, (lo, err[p >= lo].max())


@settings(max_examples=examples(6), deadline=None)
@given(shift=st.integers(6, 10), lo=st.integers(1000, 60000), width=st.integers(1, 60000),
       mode=st.sampled_from(ROUNDINGS))
def test_pascal_table_error_bounded_for_any_segment_width_and_range(shift: int, lo: int, width: int,
                                                                    mode: str) -> None:
    cfg = pascal_cfg("kalman_baro", alt_shift=shift, baro_min=lo, baro_max=min(120000, lo + width))
    c = build_constants(cfg)
    _pascal_check(AltTable(c.ALT_TABLE, c.ALT_SHIFT, 17), mode, c.BARO_MIN, c.BARO_MAX)


def test_pascal_table_check_has_teeth() -> None:
    """A node 0.25 m off, or the ADC floor's kink at 1,000 Pa (the table fitted with counts below 1,000 Pa clamped
    there: 82 m of error), fails the same check."""
    c = build_constants(pascal_cfg("kalman_baro"))
    table = AltTable(c.ALT_TABLE, c.ALT_SHIFT, 17)
    nodes = list(table.nodes)
    nodes[400] += 64                      # 51,200 Pa
    with pytest.raises(AssertionError):
        _pascal_check(dataclasses.replace(table, nodes=tuple(nodes)), "floor")
    from firmware_model.spec.alt_table import P_FLOOR_PA, fit_table

    kinked = fit_table(linear_transfer(1.0, 0.0, -1), 17, 7, P_FLOOR_PA)
    with pytest.raises(AssertionError):
        _pascal_check(kinked, "floor")
    assert altitude_m(np.array([1000.0]))[0] > 31_000


# ---------------------------------------------------------------------------------------------------- mirror bound
@st.composite
def _pascal_case(draw):
    cfg = draw(fst.build_configs(programs=KALMAN, baro_kind="pascal", units_per_metre=PA_PER_M,
                                 baro_sigma=draw(st.sampled_from((2.0, 5.0)))))
    if draw(st.booleans()):
        p, acc = draw(fst.pascal_flight_streams(cfg, max_len=400))
    else:
        p = draw(fst.pascal_streams(min_len=1, max_len=300, lo=cfg.baro_range[0], hi=cfg.baro_range[1])
                 .map(lambda a: np.clip(a, 1000, 120000)))
        acc = draw(fst.accel_streams(min_len=len(p), max_len=len(p)))
    return cfg, p, acc


@settings(max_examples=examples(20, ci=5), deadline=None)
@given(case=_pascal_case())
def test_pascal_kalman_within_derived_bound_of_float_mirror(case) -> None:
    cfg, p, acc = case
    _check_bound(build_constants(cfg), p, acc)


def _pascal_walk(k: int, n: int = 1500, walk: float = 3.0):
    rng = np.random.default_rng(k)
    p = np.clip(np.round(90000 + np.cumsum(rng.normal(0, walk, n)) + rng.normal(0, 3, n)), 1000, 120000)
    return p.astype(np.int64), np.round(2048 + rng.normal(0, 20, n)).astype(np.int64)


@pytest.mark.parametrize("program", KALMAN)
@pytest.mark.parametrize("rounding", ROUNDINGS)
def test_pascal_bound_on_a_long_walk_is_not_vacuous(program: str, rounding: str) -> None:
    p, acc = _pascal_walk(6, walk=3.0 if program == "kalman_baro" else 0.1)
    ratio = _check_bound(build_constants(pascal_cfg(program, 6, rounding, baro_sigma=3.0)), p, acc)
    assert ratio.max() > 0.005


def test_pascal_bound_has_teeth_a_wrong_node_or_a_16_bit_read_breaks_it() -> None:
    """The integer model with one table node 1/8 m off in the segment the walk uses, or reading only the low 16
    bits of the pascal word (a port that kept the ADC register), fails the check the correct model passes."""
    consts = build_constants(pascal_cfg("kalman_baro", 6, baro_sigma=3.0, gate_sigmas=0.0))
    p, acc = _pascal_walk(6, walk=1.0)
    _check_bound(consts, p, acc)
    table = list(consts.ALT_TABLE)
    table[int(np.bincount(p >> consts.ALT_SHIFT).argmax())] += 32
    with pytest.raises(AssertionError):
        _check_bound(consts, p, acc, int_consts=dataclasses.replace(consts, ALT_TABLE=tuple(table)))
    from firmware_model.model.float_reference import kalman_switched_bound, mirror

    fm = mirror(consts, p, acc)
    sb = kalman_switched_bound(consts, fm, p, acc)
    low16 = run_model(consts, np.where(p & 0xFFFF >= consts.BARO_MIN, p & 0xFFFF, consts.BARO_MIN), acc)
    assert np.any(np.abs(low16.words[:, :3] - fm.words[:, :3]) > sb.bound)


# ---------------------------------------------------------------------------------------------------- errors
def test_pascal_inputs_and_configs_are_user_errors() -> None:
    pytest.importorskip("isa.cpu")
    from firmware_model.firmware.assemble import build_firmware
    from firmware_model.firmware.harness import run_firmware

    consts = build_constants(pascal_cfg("kalman_baro"))
    for bad in ([101325, 2**31], [-(2**31) - 1]):
        with pytest.raises(UserError, match=r"outside -2147483648\.\.2147483647 \(signed 32-bit pascal"):
            run_model(consts, np.array(bad, dtype=np.int64))
        with pytest.raises(UserError, match="BARO_PA"):
            run_model_numpy(consts, bad)
    with pytest.raises(UserError, match="BARO_PA"):
        run_firmware(build_firmware(pascal_cfg("recursive")), [2**32])
    with pytest.raises(UserError, match=r"16-bit input register BARO_ADC"):
        run_model(build_constants(BuildConfig()), np.array([101325]))
    for kw, match in (({"baro_kind": "digital"}, "baro_kind"), ({"baro_max": 131072}, "pascal range"),
                      ({"baro_min": -1}, "pascal range"), ({"baro_pa_per_count": 1.0}, "baro_pa_per_count"),
                      ({"baro_sign": 1}, "baro_sign"), ({"alt_shift": 16}, "alt_shift"),
                      ({"alt_shift": 5}, "16 KB ROM")):
        with pytest.raises(UserError, match=match):
            BuildConfig(**{"baro_kind": "pascal", **kw})  # type: ignore[arg-type]  # **kw of mixed BuildConfig field types
    cfg = pascal_cfg("kalman_accel")
    assert cfg.to_dict()["baro_kind"] == "pascal" and "baro_kind" not in BuildConfig().to_dict()
    assert BuildConfig.from_dict(cfg.to_dict()) == cfg


# ---------------------------------------------------------------------------------------------------- CLI
def _fwemu(*argv: str):
    import os
    import subprocess
    import sys
    from pathlib import Path

    root = Path(__file__).resolve().parents[2]
    env = {**os.environ, "PYTHONPATH": str(root)}
    return subprocess.run([sys.executable, "-m", "firmware_model.cli.main", *argv], capture_output=True, text=True,
                          env=env, cwd=root)


def test_cli_vectors_input_takes_pascal_words_and_refuses_bad_ones(tmp_path) -> None:
    """``fwemu vectors --input`` with a pascal build config: a 32-bit word (negative, invalid for the Kalman
    range) is accepted and marked BARO_INVALID; a word beyond int32 is one line naming file:line, exit 2; the same
    pascals against an ADC build are refused as outside the 16-bit register."""
    import json

    cfg = tmp_path / "pa.json"
    cfg.write_text(json.dumps({"baro_kind": "pascal", "units_per_metre": 12.0}))
    ok = tmp_path / "ok.csv"
    ok.write_text("adc,acc\n101325,2048\n101320,2050\n-5,2048\n99000,2100\n")
    r = _fwemu("vectors", "--firmware", "kalman_accel", "--input", str(ok), "--config", str(cfg), "--out",
               str(tmp_path / "v"), "--generator", "model")
    assert r.returncode == 0, r.stderr
    doc = json.loads((tmp_path / "v" / "cases" / "kalman_accel_half_up_k7_pa_ok.json").read_text())
    assert doc["adc"] == [101325, 101320, -5, 99000] and doc["input"]["adc_bits"] == 32
    assert doc["events_first_sample"]["BARO_INVALID"] == 2
    assert "int32_t fwv_kalman_accel_half_up_k7_pa_ok_pa[4]" in (tmp_path / "v" / "cases" /
                                                              "kalman_accel_half_up_k7_pa_ok.h").read_text()
    bad = tmp_path / "bad.csv"
    bad.write_text("adc,acc\n101325,2048\n2147483648,2048\n")
    r = _fwemu("vectors", "--firmware", "kalman_accel", "--input", str(bad), "--config", str(cfg), "--out",
               str(tmp_path / "w"))
    assert r.returncode == 2 and r.stderr.strip().count("\n") == 0, r.stderr
    assert "bad.csv:3: adc=2147483648 outside [-2147483648, 2147483647] (signed 32-bit pascal word)" in r.stderr
    r = _fwemu("vectors", "--firmware", "kalman_accel", "--input", str(ok), "--out", str(tmp_path / "x"))
    assert r.returncode == 2 and "ok.csv:2: adc=101325 outside [0, 65535] (16-bit barometer ADC)" in r.stderr


def test_cli_budget_pascal_build(tmp_path) -> None:
    """``fwemu budget`` on a pascal build runs the pascal flight and edge streams (invalid words included) under
    the static bound and reports the 1,025-node table's ROM."""
    import json

    cfg = tmp_path / "pa.json"
    cfg.write_text(json.dumps({"baro_kind": "pascal", "units_per_metre": 12.0, "program": "kalman_baro"}))
    r = _fwemu("budget", "--config", str(cfg), "--k", "5", "--out", str(tmp_path / "b"))
    assert r.returncode == 0, r.stderr
    data = json.loads((tmp_path / "b" / "budget.json").read_text())
    b = data[0] if isinstance(data, list) else data
    assert b["rom_bytes"] > 4100 and b["cycles_max"] <= b["static_bound"]
    assert {s["name"] for s in b["streams"]} >= {"flight", "edge_adc_min", "edge_alternating"}
