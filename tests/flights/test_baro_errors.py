"""The barometer errors of real flight (issue 20): the measured signatures of the shared logs, the error model
(pressure_errors.real_flight_errors) part by part with its signs and magnitudes, the rb- scenarios, the
supersonic_flights() strategy, the apogee table's danger columns and the --tuning option of run/compare."""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from firmware_model.cli.main import main
from firmware_model.flights.studies import baro_signatures as bs
from firmware_model.flights.simulate import pressure_errors as pe
from firmware_model.flights.simulate import scenarios as sc
from firmware_model.flights.simulate import sim1dof as s1
from firmware_model.flights.evaluation.evalset import k_set, named_set, scenario_variants, shared_dir
from firmware_model.flights.evaluation.evaluate import FlightResult
from firmware_model.flights.evaluation.methods import Detection
from firmware_model.flights.evaluation.setup import Reference, flight_context
from firmware_model.flights.evaluation.tables import render_csv, render_json, render_markdown, summarize
from firmware_model.flights.simulate.motors import load_motor
from firmware_model.flights.readers import read_flight
from firmware_model.flights.strategies import supersonic_flights
from firmware_model.runtime.errors import UserError
from firmware_model.spec import atmosphere as atm
from tests.support import profiles
from tests.support.profiles import examples


# ------------------------------------------------------------------------------------------------ a flight
def _flight(record_hz: float = 1000.0, delay: float = 0.0):
    """M1670, 12 kg, 127 mm at sea level: peak Mach ~1.05 (the rb-m1670-m105 rocket)."""
    rocket = s1.Rocket("t", dry_mass_kg=12.0, diameter_m=0.127, motor=load_motor("M1670"))
    rec = s1.simulate_1dof(rocket, s1.Launch(record_hz=record_hz, drogue_delay_s=delay, descent_s=3.0))[0]
    return rec, s1.mach_of(rec)


@pytest.fixture(scope="module")
def flight():
    return _flight()


def _alt_err(out, rec) -> np.ndarray:
    return np.asarray(atm.altitude_m(out.pressure_pa)) - np.asarray(atm.altitude_m(rec.pressure_pa))


QUIET = {"jump_m": 0.0, "burst_sigma_m": 0.0, "ejection_m": 0.0}


def test_port_and_dip_follow_the_dynamic_pressure(flight):
    rec, mach = flight
    model = pe.BaroErrorModel(**QUIET)
    out = pe.real_flight_errors(rec, mach, model)
    q = 0.7 * rec.pressure_pa * mach ** 2                 # gamma/2 p M^2, gamma = 1.4
    dp = out.pressure_pa - rec.pressure_pa
    assert np.all(dp >= 0)                                # the pressure only ever reads high (altitude low)
    slow = (mach > 0.2) & (mach < model.dip_mach_on)
    assert np.allclose(dp[slow] / q[slow], model.cp_port, rtol=1e-9)
    at_peak = np.abs(mach - model.dip_mach_peak) < 0.002
    assert at_peak.any()
    assert np.allclose(dp[at_peak] / q[at_peak], model.cp_port + model.dip_cp, rtol=0.01)
    err = _alt_err(out, rec)
    # the default dip on this sea-level Mach-1.05 flight: 300-800 m, within the range of real logs (100-800 m)
    assert -800.0 < err.min() < -300.0
    # the signature that fools a filter: the barometric altitude falls while the rocket climbs fast
    t = rec.time_s
    baro_alt = rec.truth.altitude_m + err
    boost = (t > 0.5) & (t < 5.0)
    dh = np.diff(baro_alt[boost])
    assert (dh < 0).sum() > 100 and np.all(rec.truth.velocity_mps[boost] > 50.0)


def test_no_port_error_above_the_transonic_range():
    rec, _ = _flight(record_hz=200.0)
    fast = np.linspace(0.0, 2.0, rec.n)                   # a made-up Mach series: the model takes any
    out = pe.real_flight_errors(rec, fast, pe.BaroErrorModel(**QUIET))
    above = fast >= pe.BaroErrorModel().dip_mach_off
    assert np.array_equal(out.pressure_pa[above], rec.pressure_pa[above])


def test_shock_jump_at_each_mach_one_crossing(flight):
    rec, mach = flight
    model = pe.BaroErrorModel(cp_port=0.0, dip_cp=0.0, jump_m=300.0, burst_sigma_m=0.0, ejection_m=0.0)
    out = pe.real_flight_errors(rec, mach, model)
    eff = out.provenance["effects"][-1]
    t = rec.time_s
    cross = eff["shock_crossings_s"]
    assert len(cross) == 2                               # up through Mach 1 and back down
    for tc in cross:
        i = np.argmin(np.abs(t - tc))
        assert abs(mach[i] - 1.0) < 0.01
    err = _alt_err(out, rec)
    assert np.all(np.abs(err[t < cross[0]]) < 1e-6)
    top = np.abs(t - (cross[0] + model.jump_rise_s)) < 0.0005
    assert err[top].max() == pytest.approx(300.0, rel=0.02)
    late = (t > cross[1] + model.jump_rise_s + 3 * model.jump_decay_s)
    # three time constants after the second jump peaked, what is left of both (they superpose)
    left = 300.0 * (np.exp(-3.0) + np.exp(-3.0 - (cross[1] - cross[0]) / model.jump_decay_s))
    assert np.all(err[late] <= left * 1.01) and err[late].max() > left * 0.9
    down = pe.real_flight_errors(rec, mach, pe.BaroErrorModel(**{**model.to_dict(), "jump_m": -300.0}))
    assert _alt_err(down, rec)[t < cross[1]].min() == pytest.approx(-300.0, rel=0.02)


def test_noise_bursts_only_at_burnout_and_deployment(flight):
    rec, mach = flight
    model = pe.BaroErrorModel(cp_port=0.0, dip_cp=0.0, jump_m=0.0, burst_sigma_m=100.0, burst_s=0.3,
                              ejection_m=0.0)
    out = pe.real_flight_errors(rec, mach, model, seed=5)
    err = _alt_err(out, rec)
    t = rec.time_s
    burn = rec.provenance["summary"]["burnout_s"]
    deploy = rec.truth.apogee_time_s
    assert out.provenance["effects"][-1]["burst_times_s"] == pytest.approx([burn, deploy])
    inside = ((t >= burn) & (t < burn + 0.3)) | ((t >= deploy) & (t < deploy + 0.3))
    assert np.all(np.abs(err[~inside]) < 1e-6)
    assert 80.0 < np.std(err[inside]) < 120.0          # ~600 samples of N(0, 100 m)
    again = pe.real_flight_errors(rec, mach, model, seed=5)
    assert np.array_equal(again.pressure_pa, out.pressure_pa)
    other = pe.real_flight_errors(rec, mach, model, seed=6)
    assert not np.array_equal(other.pressure_pa, out.pressure_pa)


def test_ejection_spike_at_the_deployment():
    rec, mach = _flight(delay=1.0)
    model = pe.BaroErrorModel(cp_port=0.0, dip_cp=0.0, jump_m=0.0, burst_sigma_m=0.0, ejection_m=-200.0,
                              ejection_s=0.3)
    out = pe.real_flight_errors(rec, mach, model)
    err = _alt_err(out, rec)
    t = rec.time_s
    deploy = rec.truth.apogee_time_s + 1.0
    assert out.provenance["effects"][-1]["deploy_s"] == pytest.approx(deploy)
    assert np.all(err[t < deploy] == 0)
    assert err.min() == pytest.approx(-200.0, rel=0.01)
    assert abs(t[np.argmin(err)] - deploy) < 0.002
    assert np.all(np.abs(err[t > deploy + 0.3]) < 200.0 * 0.06)    # mostly gone within ejection_s


def test_bad_parameters_are_user_errors(flight):
    rec, mach = flight
    with pytest.raises(UserError, match="dip_mach_on < dip_mach_peak"):
        pe.BaroErrorModel(dip_mach_on=1.0, dip_mach_peak=0.9)
    with pytest.raises(UserError, match="burst_s must be > 0"):
        pe.BaroErrorModel(burst_s=0.0)
    with pytest.raises(UserError, match="must be finite"):
        pe.BaroErrorModel(jump_m=float("nan"))
    with pytest.raises(UserError, match="mach has shape"):
        pe.real_flight_errors(rec, mach[:-1])


_FLIGHT_200HZ = _flight(record_hz=200.0)
_UNIT = st.floats(0.0, 1.0, exclude_max=True, allow_nan=False)


@settings(max_examples=examples(25))
@given(st.lists(_UNIT, min_size=len(pe.ISSUE20_PARAMS), max_size=len(pe.ISSUE20_PARAMS)),
       st.integers(0, 2**32 - 1))
def test_any_model_in_the_ranges_reads_high_in_proportion_to_q(u, seed):
    """For every model of the ranges: the Mach-dependent part reads high by between cp_port (below the dip) and
    cp_port + dip_cp times q, and never above the transonic range; the whole model dips 50-1300 m on this
    Mach-1.05 sea-level flight; the same seed gives the same bytes."""
    rec, mach = _FLIGHT_200HZ
    model = pe.draw_error_model(u=u)
    quiet = pe.BaroErrorModel(**{**model.to_dict(), **QUIET})
    dp = pe.real_flight_errors(rec, mach, quiet, seed=seed).pressure_pa - rec.pressure_pa
    q = 0.7 * rec.pressure_pa * mach ** 2
    moving = q > 100.0
    ratio = dp[moving] / q[moving]
    assert np.all(ratio >= -1e-9) and np.all(ratio <= model.cp_port + model.dip_cp + 1e-9)
    slow = moving & (mach <= model.dip_mach_on)
    assert np.allclose(dp[slow] / q[slow], model.cp_port, rtol=1e-6, atol=1e-12)
    assert np.all(dp[mach >= model.dip_mach_off] == 0)
    full = pe.real_flight_errors(rec, mach, model, seed=seed)
    assert -1300.0 < full.provenance["effects"][-1]["max_dip_m"] < -50.0
    assert np.array_equal(pe.real_flight_errors(rec, mach, model, seed=seed).pressure_pa, full.pressure_pa)


def test_draws_stay_inside_the_ranges():
    rng = np.random.default_rng(0)
    for _ in range(50):
        m = pe.draw_error_model(rng).to_dict()
        for name in pe.ISSUE20_PARAMS:
            lo, hi = pe.BARO_ERROR_RANGES[name]
            assert lo <= m[name] <= hi, name
        assert m["ram_cp"] == 0.0                 # issue 20's draws leave the ram error of issue 30 off
        m = pe.draw_error_model(rng, ram=True).to_dict()
        for name, (lo, hi) in pe.BARO_ERROR_RANGES.items():
            assert lo <= m[name] <= hi, name
    lo_model = pe.draw_error_model(u=[0.0] * len(pe.ISSUE20_PARAMS))
    assert lo_model.jump_m == -400.0 and lo_model.dip_cp == 0.02
    # a generator seeded as before draws the same issue-20 model (the rb- scenarios keep their meaning)
    a = pe.draw_error_model(np.random.default_rng(7)).to_dict()
    b = pe.draw_error_model(np.random.default_rng(7), ram=True).to_dict()
    assert all(a[n] == b[n] for n in pe.ISSUE20_PARAMS) and b["ram_cp"] > 0
    with pytest.raises(UserError, match="need 13 unit numbers"):
        pe.draw_error_model(u=[0.5] * len(pe.BARO_ERROR_RANGES))


def test_the_step_is_relabelled_not_realistic():
    assert "Kumar-style, not realistic" in pe.__doc__
    assert "Kumar-style" in sc.get_scenario("trans-m1670-m105").description


# ------------------------------------------------------------------------------------------------ scenarios
def test_real_baro_scenarios_cover_the_brief():
    rb = [sc.get_scenario(n) for n in sc.scenario_names() if sc.get_scenario(n).baro_errors is not None]
    assert len(rb) >= 12
    assert {s.simulator for s in rb} == {"1dof", "rocketpy"}
    assert sum(s.simulator == "rocketpy" for s in rb) >= 3
    assert {s.mach_class for s in rb} == {"transonic", "supersonic"}
    baros = {b for s in rb for b in s.tags["baro"]}
    assert {"analog-8", "analog-10", "analog-12", "analog-16", "ms5607"} <= baros
    specs, _ = k_set(only_real_baro=True)
    sims = [x for x in specs if x.source.startswith("sim:")]
    assert {x.k for x in sims} == {5, 6, 7} and len(sims) >= 36
    assert len({x.source for x in sims}) == len(rb)


def test_full_set_is_every_sensing_at_k_5_6_7():
    full = named_set("full")
    assert named_set("realbaro") == k_set(only_real_baro=True)[0]
    sims = [x for x in full if x.source.startswith("sim:")]
    assert {x.source[4:] for x in sims} == set(sc.scenario_names())
    assert {x.k for x in full} == {5, 6, 7}
    keys = [(x.source, x.baro, x.accel, x.noise, x.k) for x in sims]
    assert len(keys) == len(set(keys))                        # each distinct sensing once per k
    for n in sc.scenario_names():
        tagged = {v[:3] for v in scenario_variants(n)}
        got = {(x.baro, x.accel, x.noise) for x in sims if x.source == f"sim:{n}"}
        assert got == tagged, n
    with pytest.raises(UserError, match="known: eval, sim, logs, quick, full, realbaro, ram"):
        named_set("nope")


@pytest.mark.parametrize("name", [n for n in sc.scenario_names()
                                  if sc.get_scenario(n).baro_errors is not None
                                  and sc.get_scenario(n).simulator == "1dof"
                                  and sc.get_scenario(n).error_model().ram_cp == 0])
def test_real_baro_scenario_carries_a_dip(name):
    rec = sc.simulate_scenario(name)
    eff = [e for e in rec.provenance["effects"] if e["effect"] == "real_flight_errors"]
    assert len(eff) == 1
    # a dip of 100-1300 m (the README's 100-800 m; a shock jump of up to -400 m can add to it) near Mach 1
    assert -1300.0 < eff[0]["max_dip_m"] < -100.0
    assert 0.8 <= eff[0]["max_dip_mach"] <= 1.3


def test_cache_key_ignores_the_pressure_effects():
    s = sc.get_scenario("rp-rb-m1670-m105-wind4")
    from dataclasses import replace
    other = replace(s, baro_errors={"model": {"jump_m": -10.0}, "seed": 99})
    assert sc.cache_key(other) == sc.cache_key(s)
    assert sc.cache_key(replace(s, rocketpy={"inclination_deg": 80.0})) != sc.cache_key(s)


# ------------------------------------------------------------------------------------------------ strategy
@settings(max_examples=examples(8))
@given(supersonic_flights())
def test_supersonic_flights_strategy(rec):
    summ = rec.provenance["summary"]
    assert 0.95 <= summ["max_mach"] <= 2.0
    assert rec.truth.apogee_altitude_m > 500.0
    eff = rec.provenance["effects"][-1]
    assert eff["effect"] == "real_flight_errors"
    site = atm.altitude_m(rec.ground_pressure_pa)
    err = np.asarray(atm.altitude_m(rec.pressure_pa)) - site - rec.truth.altitude_m
    # every drawn model dips at least 0.02 q at Mach 1: ~100 m anywhere below 5 km
    assert err.min() < -60.0
    fast = s1.mach_of(rec) > 0.3
    assert np.all(err[~fast & (rec.time_s < 0)] == 0)     # nothing on the pad


def test_supersonic_flights_draws_are_varied():
    """What the default profile draws (docs/flights-sim.md reports it): varied rockets, Mach and error models."""
    seen = []

    @settings(max_examples=examples(8), database=None)
    @given(supersonic_flights())
    def collect(rec):
        eff = rec.provenance["effects"][-1]
        seen.append((rec.provenance["rocket"]["motor"], round(rec.provenance["summary"]["max_mach"], 2),
                     round(eff["model"]["jump_m"]), round(eff["max_dip_m"])))

    collect()
    assert len({m for m, *_ in seen}) >= 3
    assert len({mach for _, mach, *_ in seen}) >= 5
    jumps = [j for *_, j, _ in seen]
    assert min(jumps) < 0 < max(jumps)


# ------------------------------------------------------------------------------------------------ the table
def _res(name, ref, dets, burnout=None, mach=None, usable=True, altos=None):
    return FlightResult(name, f"sim:{name}", 6, "test", Reference(ref, 1000.0, 0.0, "truth", usable=usable), altos,
                        {m: Detection(m, 0 if t is not None else -1, t) for m, t in dets.items()}, 10,
                        burnout_s=burnout, mach_at=mach or {}, mach_source="truth")


def test_table_counts_dangerous_detections_first():
    rs = [_res("boosty", 25.0, {"kalman_baro": 2.9, "kalman_accel": 25.3}, burnout=3.9,
               mach={"kalman_baro": 1.0, "kalman_accel": 0.0}),
          _res("coasty", 25.0, {"kalman_baro": 12.0, "kalman_accel": 23.9}, burnout=3.9,
               mach={"kalman_baro": 0.7, "kalman_accel": 0.1}),
          _res("fine", 20.0, {"kalman_baro": 19.2, "kalman_accel": None}, burnout=2.0,
               mach={"kalman_baro": 0.05}),
          _res("flagged", 30.0, {"kalman_baro": 5.0, "kalman_accel": 30.1}, usable=False)]
    kb = summarize(rs, "kalman_baro", "kb")
    assert (kb.early_1s, kb.early_1s_flagged, kb.before_burnout, kb.fast) == (2, 1, 1, 1)
    assert kb.most_early_1s_flight == "boosty" and kb.burnout_known == 3
    ka = summarize(rs, "kalman_accel", "ka")
    assert (ka.early_1s, ka.before_burnout, ka.fast) == (1, 0, 0)           # 23.9 vs 25.0: 1.1 s early
    md = render_markdown(rs)
    assert md.startswith("**Detections more than 1 s before the reference apogee**: kalman_baro 2 of 4 "
                         "(+1 on flagged references); kalman_accel 1 of 4.")
    # one error per cell (issue 34: the detection times are in the CSV and JSON)
    assert "| -22.100 ‼ boost M1.00 |" in md and "| -13.000 ‼ |" in md and "| -0.800 |" in md
    assert "2.900" not in md.split("| method |")[0]
    summary = next(line for line in md.splitlines() if line.startswith("| kalman_baro |"))
    # 2 more than 1 s early on usable references, 1 on the flagged one, 1 of the 3 with a burnout before it, 1 at
    # Mach >= 0.8, none missed
    assert summary.startswith("| kalman_baro | 2 | 1 | 1 of 3 known | 1 | 0 |")
    head = next(line for line in md.splitlines() if line.startswith("| method |"))
    assert head.startswith("| method | > 1 s early | of them flagged | before burnout | above Mach 0.8 | missed |")
    csv_rows = render_csv(rs).splitlines()
    cols = csv_rows[0].split(",")
    assert csv_rows[1].split(",")[cols.index("kalman_baro_early_1s")] == "1"
    assert csv_rows[3].split(",")[cols.index("kalman_baro_early_1s")] == "0"
    doc = json.loads(render_json(rs))
    assert doc["summary"]["kalman_baro"]["early_1s"] == 2
    assert doc["flights"][0]["flags"]["kalman_baro"] == {"early_1s": True, "before_burnout": True, "fast": True}


# ------------------------------------------------------------------------------------------------ CLI --tuning
class _Out:
    def __init__(self, code: int, out: str, err: str) -> None:
        self.returncode, self.stdout, self.stderr = code, out, err


@pytest.fixture
def fwemu(capsys):
    def run(*args: str) -> _Out:
        capsys.readouterr()
        try:
            code = main(list(args))
        except SystemExit as exc:          # argparse's usage errors
            code = int(exc.code)
        out, err = capsys.readouterr()
        return _Out(code, out, err)
    return run


def test_run_takes_tuning(fwemu):
    base = ["run", "--firmware", "kalman_baro", "--input", "sim:sub-k400-300m", "--k", "6", "--model", "--quiet"]
    rec = fwemu(*base, "--tuning", "recommended")
    dflt = fwemu(*base)
    assert rec.returncode == 0 and dflt.returncode == 0, rec.stderr + dflt.stderr
    assert "tuning: recommended (ratio=1000.0)" in rec.stdout
    assert "tuning: default" in dflt.stdout
    apo = [line for line in rec.stdout.splitlines() if line.startswith("apogee:")]
    # since issue 30 the Kalman programs' defaults are the recommended designs: the same firmware, the same apogee
    assert apo and apo == [line for line in dflt.stdout.splitlines() if line.startswith("apogee:")]
    # the recursive filter's recommendation differs from its defaults (S = k - 2, 1/2 LSB): the tuning is applied
    rbase = ["run", "--firmware", "recursive", "--input", "sim:rb-m1670-m105", "--k", "6", "--model", "--quiet"]
    rrec, rdflt = fwemu(*rbase, "--tuning", "recommended"), fwemu(*rbase)
    assert rrec.returncode == 0 and rdflt.returncode == 0, rrec.stderr + rdflt.stderr
    assert "tuning: recommended (shift=4, threshold_q8=128, threshold_sigmas=3.0)" in rrec.stdout
    rapo = [line for line in rrec.stdout.splitlines() if line.startswith("apogee:")]
    assert rapo and rapo != [line for line in rdflt.stdout.splitlines() if line.startswith("apogee:")]
    bad = fwemu(*base, "--tuning", "best")
    assert bad.returncode == 2 and "invalid choice: 'best'" in bad.stderr and "Traceback" not in bad.stderr


def test_compare_takes_tuning(fwemu):
    rec = fwemu("compare", "--program", "kalman_accel", "--k", "6", "--tuning", "recommended")
    assert rec.returncode == 0, rec.stderr
    assert "tuning: recommended (ratio=1000.0, rounding=half_up, accel_model_g=0.15)" in rec.stdout
    assert "rounding=half_up" in rec.stdout.splitlines()[1]
    # a flag wins over the tuning
    floor = fwemu("compare", "--program", "kalman_accel", "--k", "6", "--tuning", "recommended",
                  "--rounding", "floor")
    assert floor.returncode == 0 and "rounding=floor" in floor.stdout.splitlines()[1]
    none = fwemu("compare", "--program", "kalman_baro", "--k", "9", "--tuning", "recommended")
    assert none.returncode == 0 and "no entry for kalman_baro at k=9" in none.stdout
    bias = fwemu("compare", "--bias-table", "--tuning", "recommended")
    assert bias.returncode == 2 and "--tuning" in bias.stderr and "Traceback" not in bias.stderr


# ------------------------------------------------------------------------------------------------ real logs
def _base() -> Path:
    base = shared_dir()
    if base is None or not (base / "euroc21" / "piccard-telemega.csv").is_file():
        pytest.skip("shared flights folder absent")
    return base


@pytest.fixture(scope="module")
def analysis():
    return bs.analyse(_base())


def _sig(an, log, event):
    return next(s for s in an.signatures if s.log == log and s.event == event)


def test_measured_signatures_as_documented(analysis):
    """docs/flights.md's table: prometheus dips ~320-330 m at Mach ~0.97; piccard ~940 m near Mach 1 with a
    ~+176 m jump as it slows through Mach 1; the three CATS barometers see what the TeleMega sees."""
    for log in ("prometheus-2022-06-24-telemega", "prometheus-2022-06-24-telemetrum"):
        dip = _sig(analysis, log, "transonic dip")
        assert -360.0 < dip.magnitude_m < -290.0 and 4.3 < dip.time_s < 5.2
        assert analysis.trajectories[log].mach.max() == pytest.approx(0.97, abs=0.03)
    dip = _sig(analysis, "piccard-telemega", "transonic dip")
    assert -1000.0 < dip.magnitude_m < -850.0
    jump = _sig(analysis, "piccard-telemega", "jump")
    assert 140.0 < jump.magnitude_m < 220.0 and 0.95 < jump.mach_start < 1.05
    for baro in ("BARO0", "BARO1", "BARO2"):
        cats = _sig(analysis, f"piccard-cats-{baro}", "transonic dip")
        assert abs(cats.magnitude_m - dip.magnitude_m) < 30.0
    # the barometric altitude went below the pad during boost on piccard (the README's "once below the pad")
    tr = next(t for t in analysis.traces if t.name == "piccard-telemega")
    boost = (tr.time_s > 1.0) & (tr.time_s < 4.0)
    assert tr.baro_m[boost].min() < -50.0


def test_boost_port_error_on_the_shared_logs(analysis):
    """docs/flights.md, "The port error in boost" (issue 30): during the boost, above Mach 0.5, the ports read
    0.06 of q high on both prometheus computers and 0.13-0.15 on all four piccard barometers (which read below the
    pad at Mach ~0.9 while 540-560 m up); the boost ends within 0.4 s of AltOS's own coast state."""
    rows = {r.log: r for r in analysis.boost()}
    assert len(rows) == len(analysis.traces)
    for log in ("prometheus-2022-06-24-telemega", "prometheus-2022-06-24-telemetrum"):
        r = rows[log]
        assert 0.05 < r.cp_median < 0.07 and r.cp_max < 0.08 and r.lowest_m > -10.0
    for log in ("piccard-telemega", "piccard-cats-BARO0", "piccard-cats-BARO1", "piccard-cats-BARO2"):
        r = rows[log]
        assert 0.12 < r.cp_median < 0.15 and r.cp_max < 0.16
        assert -100.0 < r.lowest_m < -60.0 and 0.8 < r.lowest_mach < 0.95 and r.lowest_true_m > 500.0
    for tr in analysis.traces:
        if "coast" in tr.events:
            assert abs(rows[tr.name].burnout_s - tr.events["coast"]) < 0.4
    table = bs.boost_table(analysis.boost()).splitlines()
    assert len(table) == 2 + len(rows) and table[0].startswith("| log | burnout s (Mach) |")


def test_signature_figure_and_table(analysis):
    if profiles.PROFILE == "thorough" or os.environ.get("FWEMU_SLOW") == "1":   # matplotlib: seconds
        assert bs.figure(analysis)[:8] == b"\x89PNG\r\n\x1a\n"
    table = bs.markdown_table(analysis.signatures).splitlines()
    assert table[0].startswith("| log | event | at s | magnitude m | duration s | Mach at start |")
    assert len(table) == 2 + len(analysis.signatures)


def test_log_mach_and_burnout_estimates_agree_with_the_signature_analysis(analysis):
    """The apogee table's estimate on logs (evaluate.flight_context: the specific force integrated from the
    log's boost) against baro_signatures' own trajectory (integrated from the last still pad sample)."""
    base = _base()
    for rel, name in (("euroc21/piccard-telemega.csv", "piccard-telemega"),
                      ("altosui/prometheus-2022-06-24-telemetrum.csv", "prometheus-2022-06-24-telemetrum")):
        rec = read_flight(base / rel)
        burn, mach, source = flight_context(rec, str(base / rel))
        assert source == "accelerometer estimate"
        assert float(mach.max()) == pytest.approx(float(analysis.trajectories[name].mach.max()), abs=0.03)
        coast = rec.events["altos_coast"]               # AltOS's own coast state: burnout within 0.7 s
        assert abs(burn - coast) < 0.7
