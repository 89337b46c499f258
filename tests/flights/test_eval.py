"""Evaluation: detection rule, pad-only streams, hypothesis subsonic flights, the apogee table, sweeps, --jobs."""

from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from firmware_model.runtime.errors import UserError
from firmware_model.flights.evaluation.evaluate import FlightResult
from firmware_model.flights.evaluation.methods import METHODS, Detection, detect_from_events, methods_named
from firmware_model.flights.evaluation.setup import Reference
from firmware_model.flights.evaluation.tables import render_csv, render_json, render_markdown, summarize
from firmware_model.model.trace import EVENT_BITS
from tests.support.profiles import examples

ANY_FLIGHT_EVENT = (EVENT_BITS["LIFTOFF"] | EVENT_BITS["ARMED"] | EVENT_BITS["APOGEE"] | EVENT_BITS["MACH_LOCKOUT"]
                    | EVENT_BITS["APOGEE_PREDICTED"] | EVENT_BITS["GATE_HIGH"])


def _sensor(bits: int) -> dict:
    from firmware_model.vectors.cases import units_per_metre_for

    return {"baro_bits": bits, "units_per_metre": units_per_metre_for(bits)}


def _events(method, cfg, adc, acc):
    """Per-sample EVENTS of ``method`` built as ``cfg`` (model or ideal float Kalman)."""
    if method.engine == "ideal":
        from firmware_model.model.float_reference import ideal_kalman

        return ideal_kalman(cfg, adc, acc).column("EVENTS").astype(np.int64)
    from firmware_model.spec.build_constants import build_constants
    from firmware_model.model.run import run_model

    return run_model(build_constants(cfg), adc, acc).column("EVENTS")


# ---------------------------------------------------------------------------------------------------- detection
def test_detection_is_the_first_apogee_sample_and_prediction_is_separate():
    bits = EVENT_BITS
    ev = np.array([0, bits["LIFTOFF"], bits["LIFTOFF"], bits["LIFTOFF"] | bits["APOGEE_PREDICTED"],
                   bits["LIFTOFF"] | bits["APOGEE_PREDICTED"] | bits["APOGEE"],
                   bits["LIFTOFF"] | bits["APOGEE_PREDICTED"] | bits["APOGEE"]])
    t = np.arange(6) * 0.125 + 10.0
    apfrac = np.array([0, 0, 0, 32768, 32768, 32768])
    d = detect_from_events("x", ev, t, 0.125, apfrac)
    assert d.sample == 4 and d.time_s == 10.5
    assert d.liftoff_s == 10.125
    assert d.predicted_s == pytest.approx(10.375 + 0.5 * 0.125)
    none = detect_from_events("x", np.zeros(6, dtype=np.int64), t, 0.125)
    assert none.sample == -1 and none.time_s is None and none.liftoff_s is None


def test_methods_and_their_builds():
    assert list(METHODS) == ["rec_half", "rec_quarter", "rec_eighth", "kalman_baro", "kalman_accel",
                             "ideal_kalman"]
    thr = {m: METHODS[m].config(7).threshold_q8 for m in ("rec_half", "rec_quarter", "rec_eighth")}
    assert thr == {"rec_half": 128, "rec_quarter": 64, "rec_eighth": 32}
    cfg = METHODS["kalman_baro"].config(5, {"baro_bits": 12, "units_per_metre": 0.2}, ratio=1e4)
    assert (cfg.program, cfg.k, cfg.baro_bits, cfg.units_per_metre, cfg.ratio) == ("kalman_baro", 5, 12, 0.2, 1e4)
    assert [m.name for m in methods_named(["kalman_baro,rec_half"])] == ["kalman_baro", "rec_half"]
    with pytest.raises(UserError, match="unknown method 'nope'"):
        methods_named(["nope"])


# ---------------------------------------------------------------------------------------------------- pad only
@st.composite
def pad_streams(draw, bits_choices=(12, 16)):
    """A rocket sitting on the pad: constant pressure + Gaussian barometer noise, +1 g + accelerometer noise."""
    bits = draw(st.sampled_from(bits_choices))
    k = draw(st.integers(4, 8))
    seconds = draw(st.floats(2.0, 20.0))
    n = max(2, int(seconds * 2 ** k))
    seed = draw(st.integers(0, 2 ** 32 - 1))
    baro_sigma = draw(st.floats(0.0, 3.0)) * 2.0 ** (bits - 16) + draw(st.floats(0.0, 0.6))
    accel_sigma = draw(st.floats(0.0, 40.0))
    level = draw(st.floats(0.3, 0.9)) * ((1 << bits) - 1)
    rng = np.random.default_rng(seed)
    adc = np.clip(np.rint(level + rng.standard_normal(n) * baro_sigma), 1, (1 << bits) - 2).astype(np.int64)
    acc = np.rint(2048.0 + rng.standard_normal(n) * accel_sigma).astype(np.int64)
    return bits, k, adc, acc


@settings(max_examples=examples(8))
@given(pad_streams(), st.sampled_from(list(METHODS)))
def test_pad_only_streams_give_no_event(stream, name):
    """On the pad (12- and 16-bit ADCs, barometer noise up to 3 counts at 16 bits, accelerometer noise up to 40 counts
    = 0.2 m/s^2, up to 20 s) no method sets any flight event: no liftoff, so nothing before liftoff."""
    bits, k, adc, acc = stream
    method = METHODS[name]
    try:
        cfg = method.config(k, _sensor(bits))
        ev = _events(method, cfg, adc, acc)
    except UserError as exc:          # e.g. kalman_accel gains below 2^-33 at k=8 on a coarse ADC
        assert "too small" in str(exc)
        return
    hit = np.nonzero(ev & ANY_FLIGHT_EVENT)[0]
    assert hit.size == 0, f"{name} k={k} {bits}-bit: event {int(ev[hit[0]])} at sample {hit[0]} of {adc.size}"


def test_finding_8bit_adc_kalman_baro_lifts_off_on_the_pad():
    """Finding (docs/evaluation.md): with an 8-bit ADC over the MPX4115's range one count is about 73 m; at k = 8
    kalman_baro's velocity answer to a single one-count step (the pad reading flickering to the next code) peaks
    near 74 m/s, above the 30 m/s liftoff threshold: LIFTOFF on the pad (at k = 4, 17 m/s: no liftoff). Since the
    field-ready firmware (docs/firmware-spec.md History: metres, innovation gate) the false liftoff is followed by a
    false APOGEE once the velocity has been negative for APO_N samples (the 73 m step is inside the gate, whose
    sigma is the 8-bit sensor's own noise in metres); before, no APOGEE followed. Since issue 30 kalman_baro's
    default Mach delay (8 s after liftoff) holds that false APOGEE off (the velocity is back near 0 by then; the
    floor guard does not: the step is 73 m above the pad); with no delay it follows as before unless the descent
    guard is on (issue 30's second round, the default): the reading never comes back down from its highest count,
    and by the time the hold has run out (4 s) the velocity estimate is back at zero."""
    for k, lifts in ((8, True), (4, False)):
        n = 20 * 2 ** k
        adc = np.full(n, 200, dtype=np.int64)
        adc[n // 4:] = 199                   # one count less pressure = one count "up"
        ev = _events(METHODS["kalman_baro"], METHODS["kalman_baro"].config(k, _sensor(8)), adc, None)
        assert bool(np.any(ev & EVENT_BITS["LIFTOFF"])) is lifts
        assert not np.any(ev & EVENT_BITS["APOGEE"])
        ev = _events(METHODS["kalman_baro"], METHODS["kalman_baro"].config(k, _sensor(8), mach_delay_s=0.0,
                                                                            guards=7), adc, None)
        assert bool(np.any(ev & EVENT_BITS["APOGEE"])) is lifts          # the descent guard off
        ev = _events(METHODS["kalman_baro"], METHODS["kalman_baro"].config(k, _sensor(8), mach_delay_s=0.0), adc,
                     None)
        assert not np.any(ev & EVENT_BITS["APOGEE"])


def test_finding_recursive_pad_bias_of_first_accel_sample():
    """Finding: with ACC0 the first accelerometer sample (cal_p = 0, the firmware before the field-ready change) an
    offset b of that one sample integrates to b*t on the pad, so the recursive program's LIFTOFF (VEL > 30 m/s)
    fires after t = 30 m/s / b with nothing moving. With the default pad calibration (2^(k-2) samples averaged,
    spec §5 step 1) the same offset is divided by 2^(k-2) and nothing fires in 40 s."""
    k = 5
    calibrated = METHODS["rec_quarter"].config(k, _sensor(16))
    assert calibrated.cal_p_bits == 3
    cfg = METHODS["rec_quarter"].config(k, _sensor(16), cal_p=0)
    n = 40 * 2 ** k
    acc = np.full(n, 2048, dtype=np.int64)
    bias = 300                               # counts = 1.44 m/s^2 at 2048 counts/g
    acc[0] -= bias                           # ACC0 too low: every later sample integrates +bias
    adc = np.full(n, 40000, dtype=np.int64)
    ev = _events(METHODS["rec_quarter"], cfg, adc, acc)
    first = int(np.argmax(ev & EVENT_BITS["LIFTOFF"] != 0))
    expected_s = 30.0 / (bias / cfg.accel_counts_per_mps2)
    assert np.any(ev & EVENT_BITS["LIFTOFF"])
    assert abs(first * cfg.dt - expected_s) < 2 * cfg.dt + 1e-9
    assert not np.any(ev & EVENT_BITS["APOGEE"])
    ev = _events(METHODS["rec_quarter"], calibrated, adc, acc)
    assert not np.any(ev & (EVENT_BITS["LIFTOFF"] | EVENT_BITS["APOGEE"]))


# ---------------------------------------------------------------------------------------------------- the table
def _result(name, ref, dets, altos=None, unc=0.0):
    return FlightResult(name, f"sim:{name}", 7, "test", Reference(ref, 100.0, unc, "truth"), altos,
                        {m: Detection(m, 0 if t is not None else -1, t) for m, t in dets.items()}, 10)


def test_summary_median_worst_misses():
    rs = [_result("a", 10.0, {"kalman_baro": 10.5, "rec_half": 11.0}, altos=12.0),
          _result("b", 20.0, {"kalman_baro": 19.0, "rec_half": None}),
          _result("c", 30.0, {"kalman_baro": 30.25, "rec_half": 30.5})]
    s = summarize(rs, "kalman_baro", "kb")
    assert (s.n, s.detected, s.median_abs_s, s.worst_abs_s, s.worst_flight, s.early, s.late) == \
        (3, 3, 0.5, 1.0, "b", 1, 2)
    r = summarize(rs, "rec_half", "r")
    assert (r.n, r.detected, r.median_abs_s, r.worst_abs_s) == (3, 2, 0.75, 1.0)
    a = summarize(rs, "altos", "AltOS")
    assert (a.n, a.detected, a.worst_abs_s) == (1, 1, 2.0)
    md = render_markdown(rs, command="fwemu evaluate x")
    assert "| a | 7 | test |" in md and "miss" in md and "`fwemu evaluate x`" in md
    # rec_half: +1.0, miss, +0.5: none early, burnout unknown, one missed; and the log's computer has a column
    assert "| recursive 1/2 LSB | 0 | 0 | 0 of 0 known | 0 | 1 |" in md
    assert "| flight | k | sensor | reference apogee s | alt m | log's computer |" in md
    assert "| AltOS +2.000 |" in md
    csv_text = render_csv(rs)
    assert csv_text.splitlines()[0].startswith("flight,source,k,sensor,n_samples,ref_time_s")
    head = csv_text.splitlines()[0].split(",")
    row_b = csv_text.splitlines()[2].split(",")
    j = head.index("rec_half_time_s")
    assert row_b[j:j + 2] == ["", ""] and row_b[head.index("kalman_baro_error_s")] == "-1.0"   # b: rec_half missed
    doc = json.loads(render_json(rs))
    assert doc["summary"]["kalman_baro"]["worst_abs_s"] == 1.0
    assert doc["flights"][1]["methods"]["rec_half"]["time_s"] is None


def test_summary_leaves_flagged_references_out_of_the_usable_worst_only():
    flagged = FlightResult("cato", "log", 7, "test", Reference(3.0, 100.0, 0.9, "baro_parabola", "not ballistic",
                                                               usable=False), None,
                           {"kalman_baro": Detection("kalman_baro", 0, 6.0)}, 10)
    rs = [_result("a", 10.0, {"kalman_baro": 9.6}), _result("b", 20.0, {"kalman_baro": 20.2}), flagged]
    s = summarize(rs, "kalman_baro", "kb")
    assert (s.worst_abs_s, s.worst_flight) == (3.0, "cato")            # the plain worst keeps every flight
    assert (s.worst_usable_abs_s, s.worst_usable_flight, s.unusable) == (pytest.approx(0.4), "a", 1)
    assert (s.most_early_s, s.most_early_flight) == (pytest.approx(-0.4), "a")
    md = render_markdown(rs)
    assert "(baro_parabola) ⚠" in md and "1 on flagged references left out" in md
    assert "| log's computer |" not in md                 # no flight has one: no empty column
    named = render_markdown([_result("rb-m1670 [8-bit, clean, k7]", 10.0, {"kalman_baro": 9.6}),
                             _result("serial-068 k7", 10.0, {"kalman_baro": 10.1})])
    # the flight named once: its sensing and k have their own columns
    per_flight = named.split("| method |")[0]            # (the summary names a row by its whole label)
    assert "| rb-m1670 | 7 | test |" in per_flight and "| serial-068 | 7 | test |" in per_flight
    assert "k7" not in per_flight
    late = summarize([_result("a", 10.0, {"kalman_baro": 10.5})], "kalman_baro", "kb")
    assert late.most_early_s is None and late.unusable == 0


# ---------------------------------------------------------------------------------------------------- subsonic flights
#: The stated window for kalman_baro (default build, k = 7; set when the default was R/q = 50,000, floor, and not
#: re-measured since issue 30 made R/q 1,000 with the guards the default) on subsonic 1-DOF flights sensed by a
#: noisy 16-bit MPX4115-class barometer: error = detection - true apogee in [-3.5, +0.6] s, and never before burnout.
#: Measured on 150 random flights of the same box (docs/evaluation.md), field-ready firmware: median +0.07 s, max
#: +0.32 s, min -2.53 s (before it: median -0.01 s, max +0.19 s, min -2.74 s); the
#: early tail is light, high-drag rockets (drag >> g after burnout) that the constant-acceleration model with a tiny
#: model variance follows too slowly; its velocity estimate crosses zero seconds before the rocket's.
SUBSONIC_WINDOW_S: tuple[float, float] = (-3.5, 0.6)


@settings(max_examples=examples(6))
@given(st.data())
def test_hypothesis_subsonic_flights_kalman_baro_within_window(data):
    from firmware_model.flights.evaluation.evaluate import evaluate_inputs
    from firmware_model.flights.evaluation.setup import FlightSpec, flight_inputs
    from firmware_model.flights.strategies import flights

    record = data.draw(flights(pad_s=(0.5, 1.0), descent_s=3.0, record_hz=100.0))
    spec = FlightSpec("hypothesis", k=7, baro="mpx4115_16bit", accel="default", noise=True,
                      seed=data.draw(st.integers(0, 2 ** 16)))
    inputs = flight_inputs(record, spec)
    res = evaluate_inputs(record, inputs, spec, [METHODS["kalman_baro"]])
    det = res.detections["kalman_baro"]
    err = res.error("kalman_baro")
    assert err is not None, "kalman_baro never fired on a subsonic flight"
    lo, hi = SUBSONIC_WINDOW_S
    assert lo <= err <= hi, f"error {err:+.3f} s outside [{lo}, {hi}] (apogee {record.truth.apogee_time_s:.2f} s)"
    assert det.time_s > record.provenance["summary"]["burnout_s"]
    # and nothing before liftoff: the first event of any kind is after the rocket left the pad
    assert det.liftoff_s is not None and det.liftoff_s >= record.provenance["summary"]["liftoff_s"]


# ---------------------------------------------------------------------------------------------------- flight vectors
def _flight_vector_docs():
    from pathlib import Path

    cases = Path(__file__).resolve().parents[2] / "vectors" / "cases"
    return {p.stem: json.loads(p.read_text()) for p in sorted(cases.glob("*.json"))
            if "_log_" in p.stem or "_sim_" in p.stem}


def test_flight_vector_cases_carry_provenance_and_licence():
    import hashlib
    import os
    from pathlib import Path

    from firmware_model.vectors.flight_cases import FLIGHT_CASES

    docs = _flight_vector_docs()
    assert len(docs) == sum(len(c[4]) for c in FLIGHT_CASES) == 11
    shared = Path(os.environ.get("FWEMU_SHARED_FLIGHTS")
                  or Path(__file__).resolve().parents[2].parent / "shared" / "flights")
    for name, doc in docs.items():
        prov, truth = doc["input"]["provenance"], doc["input"]["truth"]
        assert prov["licence"].startswith("MIT"), name
        assert "2012-" not in prov["source"], name                 # the GPL AltOS logs are not redistributed
        if "_log_" in name:
            assert prov["source"].startswith("../shared/flights/") and len(prov["file_sha256"]) == 64
            path = shared / prov["source"][len("../shared/flights/"):]
            if path.is_file():
                assert hashlib.sha256(path.read_bytes()).hexdigest() == prov["file_sha256"], name
        else:
            assert prov["scenario"] and truth["apogee_source"] == "truth"
        first = doc["events_first_sample"]
        assert 0 < first["LIFTOFF"] < truth["apogee_sample"] < doc["input"]["n_samples"], name
        # every flight case fires; kalman_baro and recursive within 2 s of the reference (k = 5: 64 samples);
        # kalman_accel is seconds early on these high flights (docs/history/evaluation-rounds.md: linear counts/m),
        # only fires
        assert first["APOGEE"] >= 0, name
        if not name.startswith("kalman_accel"):
            assert abs(first["APOGEE"] - truth["apogee_sample"]) <= 64, name
    accel = [d for n, d in docs.items() if n.startswith("kalman_accel")]
    assert any(d["events_first_sample"]["MACH_LOCKOUT"] >= 0 for d in accel)


def test_tuning_overrides():
    from firmware_model.flights.evaluation.methods import tuning_overrides
    from firmware_model.spec.tuning import RECOMMENDED

    assert tuning_overrides(METHODS["kalman_accel"], 6) == {}
    assert tuning_overrides(METHODS["kalman_accel"], 6, "recommended") == RECOMMENDED["kalman_accel"][6]
    assert tuning_overrides(METHODS["ideal_kalman"], 5, "recommended") == RECOMMENDED["kalman_baro"][5]
    assert tuning_overrides(METHODS["kalman_baro"], 8, "recommended") == {}          # no entry: the defaults
    cfg = METHODS["kalman_accel"].config(6, {}, **tuning_overrides(METHODS["kalman_accel"], 6, "recommended"))
    assert (cfg.ratio, cfg.rounding) == (1000.0, "half_up")
    with pytest.raises(UserError, match="--tuning 'best'"):
        tuning_overrides(METHODS["kalman_baro"], 6, "best")
    # a method's own threshold wins over the tuning's (recommended recursive: S = k - 2 at 1/2 LSB); the program
    # named as firmware has none of its own, so the tuning's applies (fwemu run / inputs --firmware recursive)
    from firmware_model.flights.evaluation.methods import method_for_firmware
    eighth = METHODS["rec_eighth"].config(6, {}, **tuning_overrides(METHODS["rec_eighth"], 6, "recommended"))
    assert (eighth.threshold_q8, eighth.shift) == (32, 4)
    rec = method_for_firmware("recursive")
    assert rec.config(6, {}, **tuning_overrides(rec, 6, "recommended")).threshold_q8 == 128
    assert rec.config(6, {}).threshold_q8 == 64
    from firmware_model.spec.tuning import describe_tuning
    said = describe_tuning("recursive", 6, "recommended", tuning_overrides(METHODS["rec_eighth"], 6, "recommended"))
    assert said == "tuning: recommended (shift=4, threshold_sigmas=3.0)"  # what the build took, not the 1/2 LSB
