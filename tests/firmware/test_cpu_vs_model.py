"""The firmware assembled and run on the emulated 68000 equals the integer model (firmware_model.model.run) on EVERY
state word of EVERY sample (and after init), for every program, k = 4..8 and both roundings.

Inputs: hypothesis streams from the public strategies (uniform random, edge patterns with rounding ties, quick
flights), seeded synthetic flights with a transonic barometer error and an out-of-range barometer (so Mach
lockout, baro-invalid, liftoff, apogee and apogee prediction all happen: checked, so the flight logic is really
exercised), and a few long streams. Also: the harness's sequencing, counters and fault reporting.

The two sides are independent implementations of docs/firmware-spec.md (68000 assembly vs numpy); neither is
derived from the other.
"""

from __future__ import annotations

import dataclasses
import functools
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tests.support.profiles import examples

pytest.importorskip("isa.assembler")
pytest.importorskip("isa.cpu")

from firmware_model.flights import strategies as fst
from firmware_model.firmware.assemble import STACK_TOP, build_firmware
from firmware_model.spec.config import PROGRAMS, BuildConfig
from firmware_model.firmware.harness import FirmwareTrace, run_firmware
from firmware_model.model.streams import FlightParams, synthetic_flight
from firmware_model.model.run import run_model
from firmware_model.spec.build_constants import build_constants
from firmware_model.model.trace import EVENT_BITS

KS = (4, 5, 6, 7, 8)
ROUNDINGS = ("floor", "half_up")
KALMAN = ("kalman_baro", "kalman_accel")


def assert_same(cfg_or_build: object, adc: np.ndarray, acc: np.ndarray | None = None) -> FirmwareTrace:
    """Run CPU and model on the same input; fail at the first differing word with a reproducer."""
    build = cfg_or_build if hasattr(cfg_or_build, "step_address") else build_firmware(cfg_or_build)  # type: ignore  # a BuildConfig or an already built firmware
    cpu = run_firmware(build, adc, acc)
    model = run_model(build.consts, adc, acc)
    assert cpu.names == model.names
    if not np.array_equal(cpu.init_words, model.init_words):
        pytest.fail(f"{build.program_name}: after init cpu {cpu.init_words.tolist()} != model "
                    f"{model.init_words.tolist()} ({cpu.names}); adc[0]={int(np.ravel(adc)[0])}")
    if not np.array_equal(cpu.words, model.words):
        bad = np.argwhere(cpu.words != model.words)[0]
        i = tuple(bad[:-1])
        word = cpu.names[bad[-1]]
        pytest.fail(f"{build.program_name} K={build.consts.K} ROUND={build.consts.ROUND}: sample {i} word {word}: "
                    f"cpu {cpu.words[i].tolist()} != model {model.words[i].tolist()} ({cpu.names}); "
                    f"equates={build.consts.equates()}; adc[:{i[-1] + 1}]={np.asarray(adc)[..., :i[-1] + 1].tolist()}"
                    + ("" if acc is None else f"; acc[:{i[-1] + 1}]={np.asarray(acc)[..., :i[-1] + 1].tolist()}"))
    return cpu


def assert_reaches_apogee(trace: FirmwareTrace, cfg: BuildConfig) -> None:
    """The flight set LIFTOFF and then APOGEE (programs with an EVENTS word)."""
    if "EVENTS" not in trace.names:
        return
    events = int(np.bitwise_or.reduce(trace.column("EVENTS")))
    for bit in ("LIFTOFF", "APOGEE"):
        assert events & EVENT_BITS[bit], f"{cfg.program} k={cfg.k} {cfg.rounding}: the flight never set {bit}"


def _cfg(program: str, k: int, rounding: str, **kw: object) -> BuildConfig:
    """A build; the Kalman programs get the altitude table of the synthetic flights' linear sensor (the golden
    vectors' case sensor), so that the flights below are physically consistent (field-ready, spec §2a)."""
    if program in KALMAN:
        # kalman_baro's default Mach delay (8 s since issue 30) outlasts these flights' climbs: 0, as the vectors
        kw.setdefault("mach_delay_s", 0.0)
    if program in KALMAN and "baro_pa_per_count" not in kw:
        from firmware_model.vectors.cases import _flight_sensor

        kw["baro_pa_per_count"], kw["baro_pa_at_zero"] = _flight_sensor(16)
    return BuildConfig(program=program, k=k, rounding=rounding, **kw)  # type: ignore[arg-type]  # **kw of mixed BuildConfig field types


COMBOS = [(p, k, r) for p in PROGRAMS for k in KS for r in ROUNDINGS]


def flight_lengths(cfg: BuildConfig) -> tuple[int, int]:
    """(min_len, max_len) samples of the quick flights for ``cfg``: long enough at every k that every shape
    ``fst.flight_like_streams`` draws reaches apogee. Its slowest shape coasts for 1/8 of the stream, i.e. climbs
    at g x duration / 8 after burnout: the stream lasts long enough for 15 m/s above the liftoff speed (Kalman
    programs: 35 s at the default 30 m/s) or, for the recursive programs, above the velocity gate that arms their
    apogee detection (62 s at the default 61 m/s), up to 15 % longer. The streams were 8..400 (200) samples, too
    short to lift off at k >= 6: 3 of the 60 quick-flight runs reached apogee, none of the random build configs'."""
    speed = max(cfg.liftoff_mps, cfg.gate_mps if cfg.program.startswith("recursive") else 0.0) + 15.0
    seconds = 8.0 * speed / 9.80665
    per_s = 1 << cfg.k
    return math.ceil(seconds * per_s), math.ceil(1.15 * seconds * per_s)


# ---------------------------------------------------------------------------------------------------- random streams
@pytest.mark.parametrize("program,k,rounding", COMBOS)
@settings(max_examples=examples(4))
@given(data=st.data())
def test_cpu_equals_model_random_and_edge_streams(program: str, k: int, rounding: str, data: st.DataObject) -> None:
    """Uniform random ADC/accelerometer values (the worst case for headroom and rounding: wrap-around included)
    and edge patterns (constant, full-scale steps/alternation, ramps, rounding ties), 1..120 samples."""
    adc = data.draw(st.one_of(fst.adc_streams(min_len=1, max_len=120),
                              fst.edge_streams(length=data.draw(st.integers(1, 120), label="length"),
                                               shifts=(5, 6, 7, 8))), label="adc")
    acc = data.draw(st.one_of(
        st.just(np.zeros_like(adc)),
        fst.accel_streams(min_len=len(adc), max_len=len(adc)),
        st.integers(-32768, 32767).map(lambda c: np.full(len(adc), c, dtype=np.int64)),
    ), label="acc")
    assert_same(_cfg(program, k, rounding), adc, acc)


@pytest.mark.parametrize("program,k,rounding", [c for c in COMBOS if c[0] in KALMAN or c[0] == "recursive"])
@settings(max_examples=examples(2))
@given(data=st.data())
def test_cpu_equals_model_quick_flights(program: str, k: int, rounding: str, data: st.DataObject) -> None:
    """Flight-shaped streams (pad, boost, coast, apogee, descent + noise) of 35-72 s (:func:`flight_lengths`):
    liftoff and apogee at every k (asserted, so the flight logic is compared, not only the filter's pad).

    The Kalman builds leave the gravity guard of issue 30 out (guards = 5): these shapes' barometer is linear in
    counts per metre, not the altitude table's atmosphere, so a flight to several km reads, in table metres, a
    descent accelerating at up to 6 g, which the guard rightly refuses as faster than free fall; the guards are
    compared on physical flights below (the ram-pressure scenarios, the dip flights)."""
    cfg = _cfg(program, k, rounding, **({"guards": 5} if program in KALMAN else {}))
    lo, hi = flight_lengths(cfg)
    adc, acc = data.draw(fst.flight_like_streams(cfg, min_len=lo, max_len=hi), label="flight")
    assert_reaches_apogee(assert_same(cfg, adc, acc), cfg)


@settings(max_examples=examples(12))
@given(cfg=fst.build_configs(), data=st.data())
def test_cpu_equals_model_random_build_configs(cfg: BuildConfig, data: st.DataObject) -> None:
    """Random designs: noise model, R/q ratio (hence every gain mantissa and shift), S, threshold, rounding, k; on
    flights long enough to reach apogee (:func:`flight_lengths`)."""
    lo, hi = flight_lengths(cfg)
    adc, acc = data.draw(fst.flight_like_streams(cfg, min_len=lo, max_len=hi), label="flight")
    assert_reaches_apogee(assert_same(cfg, adc, acc), cfg)


@settings(max_examples=examples(10))
@given(program=st.sampled_from(PROGRAMS), k=st.sampled_from(KS), rounding=st.sampled_from(ROUNDINGS),
       baro_sign=st.sampled_from((1, -1)), bits=st.integers(8, 16), data=st.data())
def test_cpu_equals_model_sign_bits_and_range(program: str, k: int, rounding: str, baro_sign: int, bits: int,
                                              data: st.DataObject) -> None:
    """BARO_SIGN +1/-1, ADC widths 8..16 and a restricted valid range (BARO_MIN/BARO_MAX checks)."""
    full = (1 << bits) - 1
    lo = data.draw(st.integers(0, full), label="baro_min")
    hi = data.draw(st.integers(lo, full), label="baro_max")
    cfg = _cfg(program, k, rounding, baro_sign=baro_sign, baro_bits=bits, baro_min=lo, baro_max=hi)
    adc = data.draw(st.one_of(fst.adc_streams(bits=bits, max_len=80),
                              fst.edge_streams(bits=bits, length=60)), label="adc")
    acc = data.draw(fst.accel_streams(min_len=len(adc), max_len=len(adc)), label="acc")
    assert_same(cfg, adc, acc)


# ---------------------------------------------------------------------------------------------------- flight logic
# A Mach window moved down to 40..100 m/s (20 m innovation) and a 40 m barometer error while the true speed is in
# 50..90 m/s: the same lockout code runs as in a transonic flight, on a short flight (12 g for 1 s).
LOW_MACH = dict(mach_lo_mps=40.0, mach_hi_mps=100.0, mach_innov_m=20.0, baro_max=65000)
LOW_MACH_FLIGHT = FlightParams(boost_accel_g=12.0, burn_s=1.0, transonic_error_m=40.0,
                               transonic_band_mps=(50.0, 90.0), after_apogee_s=1.5)
KALMAN_EVENTS = ("LIFTOFF", "APOGEE", "MACH_LOCKOUT", "BARO_INVALID", "APOGEE_PREDICTED", "BARO_REJECT")
#: Bits a program never sets (spec §4-§6): the transonic gains (MACH_LOCKOUT bit) exist only in kalman_accel.
NEVER_SET = {"kalman_baro": ("MACH_LOCKOUT", "ARMED", "GATE_HIGH"), "kalman_accel": ("ARMED", "GATE_HIGH")}


@pytest.mark.parametrize("program", KALMAN)
@pytest.mark.parametrize("rounding", ROUNDINGS)
@pytest.mark.parametrize("k", KS)
def test_cpu_equals_model_flights_all_kalman_events(program: str, k: int, rounding: str) -> None:
    """Two flights per build, CPU == model on every sample of both: (a) a barometer error inside a (lowered) Mach
    window plus samples above BARO_MAX; (b) clean flights with the default config. Together they must set every
    event bit of the program (kalman_accel: all Kalman bits; kalman_baro: all but MACH_LOCKOUT, which it must
    never set), so the whole flight logic is compared, not just the filter, and APFRAC must be written."""
    s = synthetic_flight(k, seed=k, params=LOW_MACH_FLIGHT)
    adc = s.adc.copy()
    adc[len(adc) // 3::97] = 65535              # over-range glitches: BARO_INVALID
    # single-sample spikes in the coast (valid words far from the estimate): BARO_REJECT (since issue 30 the
    # barometer is out for the whole boost in kalman_accel, where the gate used to reject the boost's samples)
    if program == "kalman_accel":
        spikes = np.arange(len(adc) * 3 // 5, len(adc), 89)
        adc[spikes] = np.clip(adc[spikes] + 3000, 1, 65534)
    glitchy = assert_same(_cfg(program, k, rounding, **LOW_MACH), adc, s.acc)
    events = int(np.bitwise_or.reduce(glitchy.column("EVENTS")))
    apfrac = int(glitchy.column("APFRAC").max())
    expected = [bit for bit in KALMAN_EVENTS if bit not in NEVER_SET[program]]
    want = sum(EVENT_BITS[bit] for bit in expected)
    # Apogee prediction needs 0 < X2 < -rs(X3, K) on some sample, which noise can jump over (at k = 4 the
    # per-sample velocity step is ~0.6 m/s): up to 8 seeded clean flights, stopping when every event was seen.
    for seed in range(k + 1, k + 9):
        if events & want == want:
            break
        f = synthetic_flight(k, seed=seed, params=FlightParams(boost_accel_g=12.0, burn_s=1.0, after_apogee_s=1.5))
        clean = assert_same(_cfg(program, k, rounding), f.adc, f.acc)
        events |= int(np.bitwise_or.reduce(clean.column("EVENTS")))
        apfrac = max(apfrac, int(clean.column("APFRAC").max()))
    for bit in expected:
        assert events & EVENT_BITS[bit], f"{program} k={k} {rounding}: the flights never set {bit}"
    for bit in NEVER_SET[program]:
        assert not events & EVENT_BITS[bit], f"{program} k={k} {rounding}: {bit} must never be set"
    assert apfrac > 0


@pytest.mark.parametrize("rounding", ROUNDINGS)
@pytest.mark.parametrize("k", KS)
def test_cpu_equals_model_recursive_flight_all_events(k: int, rounding: str) -> None:
    """A subsonic flight for the recursive filter: LIFTOFF, GATE_HIGH, ARMED and APOGEE must all occur, in that
    order (ARMED strictly after GATE_HIGH: the velocity came back below the gate)."""
    s = synthetic_flight(k, seed=100 + k, params=FlightParams(after_apogee_s=2.0))
    cpu = assert_same(_cfg("recursive", k, rounding, threshold_q8=128), s.adc, s.acc)
    events = np.bitwise_or.reduce(cpu.column("EVENTS"))
    for bit in ("LIFTOFF", "GATE_HIGH", "ARMED", "APOGEE"):
        assert events & EVENT_BITS[bit], f"recursive k={k} {rounding}: the flight never set {bit}"
    order = [cpu.first_event(bit) for bit in ("LIFTOFF", "GATE_HIGH", "ARMED", "APOGEE")]
    assert order == sorted(set(order)), f"recursive k={k} {rounding}: first samples {order}"


@pytest.mark.parametrize("program", PROGRAMS)
@pytest.mark.parametrize("rounding", ROUNDINGS)
def test_cpu_equals_model_long_streams(program: str, rounding: str) -> None:
    """Thousands of samples: a full synthetic flight at k = 7 (pad to landing-ish) plus uniform noise streams."""
    s = synthetic_flight(7, seed=7, params=FlightParams(after_apogee_s=6.0))
    assert len(s.adc) > 1000
    assert_same(_cfg(program, 7, rounding), s.adc, s.acc)
    rng = np.random.default_rng(1234)
    n = 1500
    assert_same(_cfg(program, 6, rounding), rng.integers(0, 65536, n), rng.integers(-32768, 32768, n))


# ---------------------------------------------------------------------------------------------------- harness
def test_harness_many_streams_and_counters() -> None:
    """(streams, n) input gives the same words as one stream at a time; cycles, stack and RAM counters."""
    cfg = _cfg("kalman_accel", 6, "half_up")
    build = build_firmware(cfg)
    rng = np.random.default_rng(5)
    adc = rng.integers(20000, 20100, (3, 50))
    acc = rng.integers(-500, 3000, (3, 50))
    many = assert_same(build, adc, acc)
    assert many.words.shape == (3, 50, len(many.names)) and many.cycles.shape == (3, 50)
    for j in range(3):
        one = run_firmware(build, adc[j], acc[j])
        assert np.array_equal(one.words, many.words[j]) and np.array_equal(one.cycles, many.cycles[j])
    # Every filter step (after the pad calibration) takes at least the straight-line MULG work, and the harness saw
    # the 4-byte return address only.
    ncal = 1 << build.consts.CAL_P
    assert many.cycles[:, ncal:].min() > 500 and many.cycles[:, :ncal].min() > 0
    assert int(np.asarray(many.init_cycles).min()) > 0
    assert many.stack_bytes == 4
    assert many.ram_written == build.ram_bytes + 4
    assert STACK_TOP - 4 >= 0x4000 + build.ram_bytes  # the stack never meets the variables


def test_harness_sequencing_init_sees_sample_zero() -> None:
    """init reads sample 0 (X1 = GND = alt(adc) by the table, spec §2a), then step runs on sample 0 again: spec §7
    (the first step is the first pad-calibration sample: SUMZ = alt(adc), CAL = 1)."""
    build = build_firmware(_cfg("kalman_baro", 5, "floor"))
    tr = run_firmware(build, np.array([40000, 40000]))
    t, s = build.consts.ALT_TABLE, build.consts.ALT_SHIFT
    i, f = 40000 >> s, 40000 & ((1 << s) - 1)
    alt = t[i] + (t[i + 1] - t[i]) * f // (1 << s)            # floor rounding, Python's exact floor division
    assert tr.init_words[tr.names.index("X1")] == alt == tr.init_words[tr.names.index("GND")]
    assert tr.words[0, tr.names.index("SUMZ")] == alt and tr.words[0, tr.names.index("CAL")] == 1
    assert tr.words.shape == (2, len(tr.names))


def test_harness_fault_names_sample() -> None:
    """A CPU fault (here the per-call clock limit) is re-raised with the sample index and the same fault class."""
    from isa.errors import CPUFault, LimitExceeded

    build = build_firmware(_cfg("kalman_accel", 5, "floor", cal_p=0))
    init_clocks = run_firmware(build, np.array([40000])).init_cycles
    with pytest.raises(LimitExceeded, match="sample 1") as info:   # sample 0 is the (short) calibration step
        run_firmware(build, np.array([40000, 40000, 40000]), max_cycles_per_call=int(init_clocks) + 10)
    assert isinstance(info.value, CPUFault)
    bad = dataclasses.replace(build, step_address=build.step_address + 1)   # odd PC: address error
    with pytest.raises(CPUFault, match="sample 0"):
        run_firmware(bad, np.array([100]))


@pytest.mark.parametrize("adc,acc,match", [
    (np.array([70000]), None, r"adc: sample 0 = 70000 outside 0\.\.65535"),
    (np.array([1, -1]), None, r"adc: sample 1 = -1"),
    (np.array([1, 2]), np.array([0, 40000]), r"acc: sample 1 = 40000"),
    (np.array([1, 2]), np.array([0]), r"acc: shape"),
    (np.array([], dtype=np.int64), None, r"empty"),
    (np.array([1.5]), None, r"not an integer"),
])
def test_harness_rejects_bad_input(adc: np.ndarray, acc: np.ndarray | None, match: str) -> None:
    from firmware_model.runtime.errors import UserError

    build = build_firmware(_cfg("recursive", 5, "floor"))
    with pytest.raises(UserError, match=match):
        run_firmware(build, adc, acc)


# ---------------------------------------------------------------------------------------------------- issue 20
def _dip_flight_stream(program: str, k: int, rounding: str, pascal: bool):
    """A supersonic flight with a 500 m transonic dip, a jump and a noise burst (tests/support/transonic.py), for the
    ADC kind (the vectors' case sensor) or the pascal kind; Kalman builds with R/q 1,000 (the recommended tuning) and a
    12 s Mach delay (so DLY still counts when COAST begins). The accelerometer also reads a 0.5 s glitch of -8 g 1.5 s
    into the boost, which starts and then breaks a coast count and makes kalman_accel's velocity fall faster than the
    plausibility bound DV allows."""
    from firmware_model.vectors.cases import case_config
    from tests.support.transonic import DipFlight, dip_stream

    f = DipFlight(k=k, boost_g=12.0, burn_s=3.5, drag_per_m=0.0002, dip_m=500.0, dip_s=1.5, jump_m=150.0,
                  burst_m=80.0, burst_at=0.1, seed=11)
    extra = {} if program in ("recursive", "recursive_seed_literal") else {"mach_delay_s": 12.0, "ratio": 1000.0}
    if pascal:
        cfg = BuildConfig(program=program, k=k, rounding=rounding, baro_kind="pascal", units_per_metre=12.01, **extra)
    else:
        cfg = case_config(program, rounding, k, 16).replace(**extra)
    from firmware_model.model.streams import flight_params_for

    s = dip_stream(f, flight_params_for(cfg), pascal=pascal)
    gap = slice(int((s["pad_s"] + 1.5) * 2**k), int((s["pad_s"] + 2.0) * 2**k))
    s["acc"][gap] = int(round(-8.0 * 9.80665 * cfg.accel_counts_per_mps2))
    return cfg, s


@pytest.mark.parametrize("program", PROGRAMS)
@pytest.mark.parametrize("rounding", ROUNDINGS)
@pytest.mark.parametrize("kind", ["adc", "pascal"])
def test_cpu_equals_model_supersonic_dip_flights_reach_every_new_branch(program: str, rounding: str,
                                                                       kind: str) -> None:
    """CPU == model on every word of a supersonic flight with a transonic dip (both barometer kinds), and the
    flight reaches every branch of issue 20's logic (spec §4a, §6 steps 4, 7-10): every PHASE value, a coast
    counter reset, the Mach delay counting down; kalman_accel's lockout, its settling, the re-base and (with the
    re-base sample made invalid) the wait for a valid sample; VB both falling at DV and rising at DU, and holding
    apogee off while X2 < 0 in COAST."""
    k = 5
    cfg, s = _dip_flight_stream(program, k, rounding, kind == "pascal")
    adc, acc = s["adc"].copy(), s["acc"]
    model = run_model(build_constants(cfg), adc, acc)
    if program == "kalman_accel":
        lock = model.column("LOCK")
        back = np.flatnonzero((lock[:-1] == 1) & (lock[1:] == 0)) + 1
        adc[back[0]] = 65535 if kind == "adc" else -5        # invalid on the re-base sample: LOCK waits at 1
    cpu = assert_same(cfg, adc, acc)
    if program == "recursive_seed_literal":
        return
    phase, cst = cpu.column("PHASE"), cpu.column("CST")
    assert set(np.unique(phase)) == {0, 1, 2, 3, 4}, np.unique(phase)
    if kind == "adc":   # (the pascal build's barometer, 12 Pa/m at 2 Pa sigma, outweighs the staging gap in X3)
        assert ((cst[:-1] > 0) & (cst[1:] == 0) & (phase[1:] == 1)).any()        # a coast count broken in boost
    if program == "recursive":
        return
    vb, dly = cpu.column("VB"), cpu.column("DLY")
    assert dly.max() == build_constants(cfg).DLY_N > 0 and dly[-1] == 0
    dv, du = build_constants(cfg).DV, build_constants(cfg).DU
    assert (np.diff(vb) == -dv).any()                                            # VB fell at its limit
    # VB rose at its limit (kalman_accel's X2 cannot: its +-16 g accelerometer stays below the 30 g bound; the
    # code is the one kalman_baro runs, kalman.inc)
    assert (np.diff(vb) == du).any() or program == "kalman_accel"
    coast = phase == 2
    assert (coast & (dly > 0)).any() and (coast & (dly == 0) & (vb >= 0)).any()  # both ways apogee is held off
    assert (coast & (dly == 0) & (vb < 0)).any()                                 # and the evidence
    if program == "kalman_accel":
        ev, lock = cpu.column("EVENTS"), cpu.column("LOCK")
        assert (ev & EVENT_BITS["MACH_LOCKOUT"]).any()
        assert ((lock[:-1] == 1) & (lock[1:] == 1) & ((ev[1:] & EVENT_BITS["BARO_INVALID"]) != 0)).any()
        assert ((lock[:-1] == 1) & (lock[1:] == 0)).any()


@pytest.mark.parametrize("program", ["recursive", "kalman_accel"])
@pytest.mark.parametrize("k, rounding", [(5, "floor"), (5, "half_up"), (7, "floor"), (7, "half_up")])
def test_cpu_equals_model_on_a_clipped_supersonic_flight(program: str, k: int, rounding: str) -> None:
    """The clip logic (spec §5 steps 2, 3, 6; §6 steps 4, 7, 9) on the emulated 68000: a 30 g boost at the +-16 g
    accelerometer's rail for 1.4 s with a 400 m transonic dip (tests/model/test_kalman.py's clipped flight): every
    word of every sample equal, and the run really went through ACC_CLIP, the drag-low counting (recursive) or the
    2^(k+1)-sample window and the velocity re-base (kalman_accel), CLIP_CLEAR and then APOGEE."""
    from firmware_model.model.streams import flight_params_for
    from firmware_model.vectors.cases import case_config
    from tests.support.transonic import DipFlight, dip_stream

    cfg = case_config(program, rounding, k, 16)
    f = DipFlight(k=k, boost_g=30.0, burn_s=1.4, drag_per_m=0.0002, dip_m=400.0, dip_s=1.5, jump_m=150.0,
                  burst_m=50.0, burst_at=0.1, seed=k)
    s = dip_stream(f, flight_params_for(cfg))
    cpu = assert_same(cfg, s["adc"], s["acc"])
    clip, clear, apogee = (cpu.first_event(b) for b in ("ACC_CLIP", "CLIP_CLEAR", "APOGEE"))
    assert 0 < clip < clear < apogee, (clip, clear, apogee)
    clp = cpu.column("CLP")
    assert clp[clear - 1] == (2 ** (k + 1) - 1 if program == "kalman_accel" else 2 ** k - 1), clp[clear - 1]
    if program == "kalman_accel":
        x2 = cpu.column("X2")
        assert x2[clear] - x2[clear - 1] > 100 * 256       # the re-base restores > 100 m/s the rail cut off
        # the low-rate prediction waits for CLIP_CLEAR too (spec §6 step 10): before it X2 is only a lower bound
        # (at k = 7 the per-sample velocity change is below the prediction's resolution here: never predicted)
        pred = cpu.first_event("APOGEE_PREDICTED")
        assert pred == -1 or pred > clear, (pred, clear)
        assert pred > clear or k == 7, (pred, clear, k)


# ---------------------------------------------------------------------------------------------------- clipped accel
@functools.lru_cache(maxsize=None)
def _clipped_flight(scenario: str, k: int) -> tuple[np.ndarray, np.ndarray, dict]:
    """A simulated M6400 flight at Mach 1.67 (30-51 g boost: the default +-16 g accelerometer sits at its rail for
    the whole burn) sensed as the apogee table senses it (16-bit MPX4115 barometer, default accelerometer, noisy),
    cut 3 s after the reference apogee: (adc, acc, the sensor's BuildConfig fields)."""
    from firmware_model.flights.evaluation.setup import (FlightSpec, load_record, reference_for, sensor_config,
                                                         sensors_for)
    from firmware_model.flights.inputs.firmware_inputs import firmware_inputs

    record = load_record(f"sim:{scenario}")
    ref = reference_for(record)
    baro, accel = sensors_for(FlightSpec(f"sim:{scenario}", k=k, baro="mpx4115_16bit", accel="default", noise=True))
    inputs = firmware_inputs(record, k, baro=baro, accel=accel, method="linear", seed=0, t_end=ref.time_s + 3.0)
    return (np.asarray(inputs.adc, dtype=np.int64), np.asarray(inputs.acc, dtype=np.int64),
            sensor_config(inputs))


@pytest.mark.parametrize("scenario", ["rb-m6400-m167", "sup-m6400-m167"])
@pytest.mark.parametrize("program", ["recursive", "kalman_baro", "kalman_accel"])
@pytest.mark.parametrize("rounding", ROUNDINGS)
@pytest.mark.parametrize("k", [5, 7])
def test_cpu_equals_model_clipped_accelerometer_flights(scenario: str, program: str, rounding: str, k: int) -> None:
    """CPU == model on every word of a flight whose accelerometer clips (spec §5 steps 2, 3, 6; §6 steps 4, 7b, 9b),
    and the flight reaches the whole clip logic, so the comparison cannot pass vacuously: the rail count CLP reaches
    CLIP_N and sets ACC_CLIP in BOOST; no apogee evidence before CLIP_CLEAR; CLIP_CLEAR set later (recursive: CLP at
    2^K in COAST; kalman_accel: the 2^(K+1)-sample window complete, LOCK from MACH_N to 0, E0 non-zero, VB
    re-based); then APOGEE. kalman_baro has no accelerometer logic: it sets neither bit."""
    from firmware_model.flights.evaluation.methods import METHODS

    adc, acc, sensor = _clipped_flight(scenario, k)
    cfg = METHODS["rec_quarter" if program == "recursive" else program].config(k, sensor, rounding=rounding)
    cpu = assert_same(cfg, adc, acc)
    c = build_constants(cfg)
    ev = cpu.column("EVENTS")
    clip, clear, apogee = EVENT_BITS["ACC_CLIP"], EVENT_BITS["CLIP_CLEAR"], EVENT_BITS["APOGEE"]
    assert (ev & apogee).any(), f"{program} k={k} {rounding}: no apogee"
    if program == "kalman_baro":
        assert not (ev & (clip | clear)).any()
        return
    assert (acc == 32767).sum() >= c.CLIP_N
    first_clip, first_clear = cpu.first_event("ACC_CLIP"), cpu.first_event("CLIP_CLEAR")
    assert 0 < first_clip < first_clear, (first_clip, first_clear)
    phase, clp = cpu.column("PHASE"), cpu.column("CLP")
    assert phase[first_clip] == 1 and clp[first_clip - 1] == c.CLIP_N - 1 and clp[first_clip] == 0
    assert cpu.first_event("APOGEE") > first_clear                  # evidence only once the speed is known again
    assert phase[first_clear] == 2
    if program == "recursive":
        assert clp[first_clear] == 1 << c.K
        return
    lock, e0, vb, x2 = cpu.column("LOCK"), cpu.column("E0"), cpu.column("VB"), cpu.column("X2")
    i = first_clear
    assert clp[i] == 2 << c.K and lock[i - 1] == c.MACH_N and lock[i] == 0 and e0[i] != 0
    assert not ev[i] & EVENT_BITS["MACH_LOCKOUT"] and (ev[first_clip + 1:i] & EVENT_BITS["MACH_LOCKOUT"]).all()
    assert vb[i] != vb[i - 1] and x2[i] != x2[i - 1]


# ---------------------------------------------------------------------------------------------------- issue 30
#: The ram-pressure scenarios of issue 30 (firmware_model.flights.simulate.scenarios: a port reading ram pressure in
#: boost, 1-DOF and RocketPy, some logs starting in boost), each with the first barometer of its set:full variants.
RAM_SCENARIOS: tuple[tuple[str, str], ...] = (
    ("ram-m1670-m156-easymega-boostlog", "ms5607"), ("ram-l1350-m114-telemega", "analog-12"),
    ("ram-l1350-m137-weak", "analog-10"), ("ram-m1670-m145-boostlog", "ms5607"),
    ("ram-m6400-m167-strong", "analog-16"), ("ram-k828-m118-drawn", "analog-12"),
    ("ram-m2245-m17-highsite-drawn-boostlog", "ms5607"), ("rp-ram-m2245-m17-wind3-boostlog", "analog-16"),
    ("rp-ram-l1350-m137-windprofile-drawn", "analog-10"), ("rp-ram-m1670-m156-easymega", "analog-16"))


@functools.lru_cache(maxsize=None)
def _ram_flight(scenario: str, baro: str, k: int) -> tuple[np.ndarray, np.ndarray, dict]:
    """The scenario sensed as set:full senses it (its barometer, default accelerometer, noisy): (adc, acc, the
    sensor's BuildConfig fields)."""
    from firmware_model.flights.evaluation.evalset import BARO_TAGS
    from firmware_model.flights.evaluation.setup import FlightSpec, flight_inputs, load_record, sensor_config

    spec = FlightSpec(f"sim:{scenario}", k=k, baro=BARO_TAGS.get(baro, baro), noise=True)
    inputs = flight_inputs(load_record(spec.source), spec)
    return (np.asarray(inputs.adc, dtype=np.int64), np.asarray(inputs.acc, dtype=np.int64),
            sensor_config(inputs))


@pytest.mark.parametrize("scenario,baro", RAM_SCENARIOS)
@pytest.mark.parametrize("rounding", ROUNDINGS)
def test_cpu_equals_model_on_the_ram_pressure_scenarios(scenario: str, baro: str, rounding: str) -> None:
    """Issue 30: CPU == model on every word of every program (the recursive filter at its three thresholds'
    middle one, the Kalman programs with all guards) on each ram-pressure scenario at k = 5, and the guards'
    branches are reached, so the comparison is not vacuous: kalman_accel locks the barometer out on the pad's
    thrust samples or in BOOST from the sample after liftoff; both Kalman programs pass through COAST and fire."""
    from firmware_model.flights.evaluation.methods import METHODS

    adc, acc, sensor = _ram_flight(scenario, baro, 5)
    for program in ("recursive", "recursive_seed_literal", "kalman_baro", "kalman_accel"):
        method = {"recursive": "rec_quarter", "recursive_seed_literal": "rec_quarter"}.get(program, program)
        cfg = METHODS[method].config(5, sensor, rounding=rounding)
        if program == "recursive_seed_literal":
            cfg = dataclasses.replace(cfg, program=program)
        cpu = assert_same(cfg, adc, acc)
        if program in KALMAN:
            assert build_constants(cfg).GUARDS == 15
            phase, ev = cpu.column("PHASE"), cpu.column("EVENTS")
            assert (phase == 2).any() and (ev & EVENT_BITS["APOGEE"]).any(), (program, scenario)
            if program == "kalman_accel":
                lift = cpu.first_event("LIFTOFF")
                boost = np.flatnonzero(phase == 1)
                # every sample after one that left PHASE in BOOST is locked out (the thrust guard)
                assert (ev[boost[boost < len(ev) - 1] + 1] & EVENT_BITS["MACH_LOCKOUT"]).all()
                assert lift >= 0 and boost.size > 0
