"""fwemu montecarlo: spec checks, the 3-DOF simulator against sim1dof, per-flight reproducibility, replay, Wilson
intervals, byte-identical rows for any backend, resume after an interrupt (docs/montecarlo.md).

Dask and pyarrow are the optional 'montecarlo' extra: the tests that need them skip without them (the engine test
with a killed Dask worker is in tests/runtime/test_engine.py)."""

from __future__ import annotations

import json
import math
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from firmware_model.cli.main import main
from firmware_model.flights.readers.generic import generic_csv
from firmware_model.flights.inputs.firmware_inputs import firmware_inputs
from firmware_model.flights.montecarlo import pipeline
from firmware_model.flights.montecarlo import spec as spec_mod
from firmware_model.flights.montecarlo.results import flights_for, have_pyarrow, read_rows, wilson
from firmware_model.flights.montecarlo.run import run_montecarlo
from firmware_model.flights.montecarlo.sim import P_COLS, drag_table, simulate_batch
from firmware_model.flights.montecarlo.spec import draw, flight_rng, load_spec, read_spec_file
from firmware_model.flights.readers import read_flight
from firmware_model.flights.simulate.scenarios import get_scenario
from firmware_model.flights.inputs.sensors import AccelSensor, BaroSensor
from firmware_model.flights.simulate.sim1dof import Launch, simulate_1dof
from firmware_model.runtime.engine import Backend
from firmware_model.runtime.errors import UserError

ROOT = Path(__file__).resolve().parents[2]

#: A short subsonic flight (apogee ~8 s), two methods, small chunks: seconds per run.
SMALL = {"scenario": "sub-k400-300m", "k": 5, "methods": ["rec_quarter", "kalman_accel"], "chunk_flights": 4,
         "descent_s": 2.0,
         "dispersions": {"impulse_scale": {"normal": [1.0, 0.05]}, "wind_speed_mps": {"uniform": [0.0, 9.0]},
                         "wind_direction_deg": {"uniform": [0.0, 360.0]},
                         "rail_inclination_deg": {"normal": [4.0, 2.0], "min": 0.0},
                         "temperature_offset_k": {"normal": [0.0, 10.0]}, "spike_rate": 1.0,
                         "baro_noise_pa": {"uniform": [1.0, 8.0]}, "accel_offset_counts": {"normal": [0, 30]}}}


def small_spec(**kw):
    return load_spec({**SMALL, **kw})


# --------------------------------------------------------------------------------------------- spec
def test_spec_errors_name_the_file_and_the_value(tmp_path):
    p = tmp_path / "bad.toml"
    p.write_text('scenario = "sub-k400-300m"\n[dispersions]\nwind_sped_mps = 3\n')
    with pytest.raises(UserError, match=r"bad.toml: dispersions: unknown parameter\(s\) wind_sped_mps"):
        load_spec(read_spec_file(p), where=str(p))
    p.write_text('scenario = "sub-k400-300m"\n[dispersions]\nimpulse_scale = {normal = [1.0, -0.1]}\n')
    with pytest.raises(UserError, match="normal sd -0.1 < 0"):
        load_spec(read_spec_file(p), where=str(p))
    p.write_text('scenario = "sub-k400-300m"\nk = = 3\n')
    with pytest.raises(UserError, match="bad.toml"):
        read_spec_file(p)
    j = tmp_path / "bad.json"
    j.write_text('{"scenario": "sub-k400-300m",\n "k": }')
    with pytest.raises(UserError, match=r"bad.json:2:"):
        read_spec_file(j)
    with pytest.raises(UserError, match="either scenario"):
        load_spec({"k": 6})
    with pytest.raises(UserError, match="recommended tuning exists for k = 5..7"):
        load_spec({"scenario": "sub-k400-300m", "k": 8})


def test_cli_bad_spec_is_one_line_exit_2(tmp_path):
    p = tmp_path / "s.toml"
    p.write_text('scenario = "nope"\n')
    r = subprocess.run([sys.executable, "-c", "from firmware_model.cli.main import entry; entry()", "montecarlo",
                        str(p), "--out", str(tmp_path / "o")], capture_output=True, text=True, cwd=ROOT,
                       env={**os.environ, "PYTHONPATH": str(ROOT)})
    assert r.returncode == 2, r.stderr
    assert "unknown scenario 'nope'" in r.stderr and "Traceback" not in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1


def test_draws_are_per_flight_and_per_parameter():
    spec = small_spec()
    a = draw(spec, flight_rng(7, 3))
    assert a == draw(spec, flight_rng(7, 3))
    assert a != draw(spec, flight_rng(7, 4)) and a != draw(spec, flight_rng(8, 3))
    # changing one parameter's distribution leaves the others' values alone (own slots)
    other = load_spec({**SMALL, "dispersions": {**SMALL["dispersions"], "wind_speed_mps": {"uniform": [0, 1]}}})
    b = draw(other, flight_rng(7, 3))
    assert b["impulse_scale"] == a["impulse_scale"] and b["wind_speed_mps"] != a["wind_speed_mps"]
    assert 0 <= b["wind_speed_mps"] <= 1
    # the normal draw: many flights' values have the stated mean and sd
    vals = np.array([draw(spec, flight_rng(1, f))["impulse_scale"] for f in range(4000)])
    assert abs(vals.mean() - 1.0) < 0.005 and abs(vals.std() - 0.05) < 0.004
    incl = np.array([draw(spec, flight_rng(1, f))["rail_inclination_deg"] for f in range(2000)])
    assert incl.min() == 0.0 and (incl == 0.0).mean() > 0.01     # min clips


# --------------------------------------------------------------------------------------------- simulator
@pytest.mark.parametrize("name", ["sub-k400-900m", "trans-m1670-m105"])
def test_vertical_still_air_flight_is_sim1dofs(name):
    """No wind, vertical rail, standard atmosphere: the 3-DOF kernel integrates sim1dof's equations with the same
    RK4 step, so altitude, velocity, specific force and apogee agree to rounding."""
    r = get_scenario(name).build_rocket()
    mach, cd = r.drag_curve()
    row = {"dry_kg": r.dry_mass_kg, "prop_kg": r.motor.propellant_mass_kg, "time_scale": 1.0, "thrust_scale": 1.0,
           "cd_scale": 1.0, "area_m2": r.area_m2, "drogue_cda_m2": r.drogue_cd_area_m2, "site_m": 300.0,
           "tscale": 1.0, "wind_mps": 0.0, "wind_dir_rad": 0.0, "wind_exp": 0.0, "incl_rad": 0.0, "rail_m": 2.0,
           "drogue_delay_s": 0.0, "descent_s": 3.0}
    out = simulate_batch(np.array([[row[c] for c in P_COLS]]), r.motor.time_s, r.motor.thrust_n,
                         drag_table(mach, cd), 64.0, 512.0, 120.0)
    rec = simulate_1dof(r, Launch(site_altitude_m=300.0, pad_s=0.0, descent_s=3.0, record_hz=64.0,
                                  internal_hz=512.0))[0]
    ev = out["events"][0]
    assert ev[0] > 0
    assert abs(ev[1] - rec.truth.apogee_time_s) < 1e-9 and abs(ev[2] - rec.truth.apogee_altitude_m) < 1e-6
    n = min(int(ev[0]), rec.n)
    assert n > 64 * 5
    np.testing.assert_allclose(out["z"][0, :n], rec.truth.altitude_m[:n], atol=1e-6)
    np.testing.assert_allclose(out["vz"][0, :n], rec.truth.velocity_mps[:n], atol=1e-6)
    np.testing.assert_allclose(out["fax"][0, :n], rec.accel_mps2[:n], atol=1e-6)


def test_wind_and_inclination_lower_the_apogee_and_tilt_the_accelerometer():
    r = get_scenario("sub-k400-900m").build_rocket()
    mach, cd = r.drag_curve()
    base = {"dry_kg": r.dry_mass_kg, "prop_kg": r.motor.propellant_mass_kg, "time_scale": 1.0, "thrust_scale": 1.0,
            "cd_scale": 1.0, "area_m2": r.area_m2, "drogue_cda_m2": r.drogue_cd_area_m2, "site_m": 0.0,
            "tscale": 1.0, "wind_mps": 0.0, "wind_dir_rad": 0.0, "wind_exp": 0.0, "incl_rad": 0.0, "rail_m": 2.0,
            "drogue_delay_s": 0.0, "descent_s": 2.0}
    rows = [base, {**base, "incl_rad": math.radians(10)}, {**base, "wind_mps": 10.0, "wind_dir_rad": math.pi},
            {**base, "tscale": 288.15 / 308.15}]
    out = simulate_batch(np.array([[row[c] for c in P_COLS] for row in rows]), r.motor.time_s, r.motor.thrust_n,
                         drag_table(mach, cd), 64.0, 256.0, 60.0)
    apo = out["events"][:, 2]
    assert apo[1] < apo[0] - 5 and apo[2] < apo[0] - 5        # tilted flight paths peak lower
    assert apo[3] > apo[0]                                     # hot air is thinner: higher
    assert abs(out["fax"][1, 0] - 9.80665 * math.cos(math.radians(10))) < 1e-9   # on the tilted pad: g cos


# --------------------------------------------------------------------------------------------- pipeline
def test_a_flight_is_the_same_alone_as_in_any_chunk():
    spec = small_spec()
    big = pipeline.run_chunk({"spec": spec, "seed": 5, "flights": list(range(6))})
    alone = pipeline.run_chunk({"spec": spec, "seed": 5, "flights": [4]})
    rows4 = big["flight"] == 4
    for name, col in alone.items():
        a, b = np.asarray(col), np.asarray(big[name])[rows4]
        if a.dtype == object:
            assert list(a) == list(b), name
        else:
            np.testing.assert_array_equal(a, b, err_msg=name)
    assert alone["fired"].any()


def test_replay_csv_reproduces_the_input_words(tmp_path):
    """--replay writes the flight so that reading it back with its sensor presets and no added noise gives the
    very ADC and accelerometer words the Monte Carlo fed the model."""
    spec = small_spec()
    s = pipeline.sense_chunk(spec, 3, [2])
    rec, prm = pipeline.replay_record(spec, 3, 2)
    path = tmp_path / "flight-2.csv"
    path.write_text(generic_csv(rec))
    back = read_flight(str(path))
    n = int(s.n[0])
    assert back.n == n
    assert abs(back.truth.apogee_time_s - s.events[0, 1]) < 1e-12
    # the stream starts pad_s before liftoff, as firmware_inputs' default: the same samples, not just the words
    inp = firmware_inputs(back, spec["k"], baro=BaroSensor.preset(str(prm["baro"])),
                          accel=AccelSensor.preset(str(prm["accel"]), range_g=1000.0))
    np.testing.assert_array_equal(inp.adc, s.adc[0, :n])
    np.testing.assert_array_equal(inp.acc, s.acc[0, :n])


def test_replayed_flight_through_fwemu_run_gives_the_rows_detection(tmp_path, capsys):
    # the record ends 1 s after the true apogee: the default recursive build (S = 5, a 1 s lag at k = 5) has not
    # fired by then on this flight, the others have (since the 40 m/s gate arms this 300 m flight, a record 2 s long
    # lets every method fire)
    small = {**SMALL, "descent_s": 1.0}
    spec_path = tmp_path / "s.json"
    spec_path.write_text(json.dumps(small))
    assert main(["montecarlo", str(spec_path), "--seed", "4", "--replay", "3", "--out", str(tmp_path)]) == 0
    rows = pipeline.run_chunk({"spec": load_spec(small), "seed": 4, "flights": [3]})
    assert len(rows["method"]) == 4 and rows["fired"].any() and not rows["fired"].all()   # both cases checked
    for i, (m, t) in enumerate(zip(rows["method"], rows["tuning"])):
        capsys.readouterr()
        assert main(["run", "--firmware", m, "--model", "--input", str(tmp_path / "flight-3.csv"),
                     "--config", str(tmp_path / f"flight-3.{m}-{t}.json"), "--k", str(SMALL["k"]),
                     "--baro", "mpx4115_12bit", "--accel", "default", "--no-noise"]) == 0
        line = next(x for x in capsys.readouterr().out.splitlines() if x.startswith("apogee:"))
        if rows["fired"][i]:
            assert float(line.split()[1]) == rows["detect_s"][i], (m, t, line)
        else:   # silent until the record's end (descent_s after the true apogee): "missed" in the rows
            assert line == "apogee: never declared", (m, t, line)


def test_spikes_and_transonic_step_reach_the_pressure():
    spec = load_spec({"scenario": "trans-m1670-m105", "k": 5, "methods": ["kalman_baro"], "tunings": ["default"],
                      "dispersions": {"spike_rate": 3.0},
                      "pressure_error": {"model": "step", "altitude_step_m": 80.0}})
    clean = load_spec({"scenario": "trans-m1670-m105", "k": 5, "methods": ["kalman_baro"], "tunings": ["default"],
                       "pressure_error": {"model": "none"}})
    a = pipeline.sense_chunk(spec, 1, [0])
    b = pipeline.sense_chunk(clean, 1, [0])
    d = a.pressure[0] - b.pressure[0]
    from firmware_model.spec import atmosphere as atm
    step = atm.altitude_m(a.pressure[0]) - atm.altitude_m(b.pressure[0])
    plateau = np.abs(step - 80.0) < 0.01
    assert plateau.sum() > 16                      # the supersonic part (~0.8 s at Mach > 1): +80 m
    on = np.nonzero(plateau)[0]
    assert on[-1] - on[0] + 1 - plateau.sum() <= 3  # one interval (a spike may sit inside it)
    spikes = np.abs(d) > 400                       # the spikes (default 1500 Pa) besides the step
    assert 1 <= (spikes & ~plateau).sum() <= 12


# --------------------------------------------------------------------------------------------- statistics
def _wilson_by_roots(x, n, z=1.959963984540054):
    """The interval as the roots of the score test (p_hat - p)^2 = z^2 p (1 - p) / n, solved as a quadratic."""
    ph = x / n
    a = 1 + z * z / n
    b = -(2 * ph + z * z / n)
    c = ph * ph
    r = np.roots([a, b, c])
    return float(min(r.real)), float(max(r.real))


@pytest.mark.parametrize("x,n", [(0, 10), (1, 10), (5, 10), (10, 10), (3, 1000), (0, 3000), (37, 420)])
def test_wilson_is_the_score_interval(x, n):
    lo, hi = wilson(x, n)
    rlo, rhi = _wilson_by_roots(x, n)
    assert abs(lo - max(0.0, rlo)) < 1e-9 and abs(hi - min(1.0, rhi)) < 1e-9
    assert lo <= x / n <= hi


def test_flights_for_one_in_a_thousand():
    assert flights_for(1e-3) == 2995 or flights_for(1e-3) == 2996       # -ln(0.05) / 1e-3 = 2995.7
    n = flights_for(1e-3)
    assert 1 - (1 - 1e-3) ** n >= 0.95 - 1e-3
    assert flights_for(1e-3, events=10) > 10_000


# --------------------------------------------------------------------------------------------- runs
def _bytes(folder: Path) -> bytes:
    return next(folder.glob("rows.*")).read_bytes()


def test_rows_identical_for_one_and_two_local_workers(tmp_path):
    fmt = "parquet" if have_pyarrow() else "csv"
    spec = small_spec()
    a = run_montecarlo(spec, 11, 10, tmp_path / "a", fmt=fmt, figures=False)
    run_montecarlo(spec, 11, 10, tmp_path / "b", Backend("local", 2), fmt=fmt, figures=False)
    assert _bytes(tmp_path / "a") == _bytes(tmp_path / "b")
    assert (tmp_path / "a" / "summary.md").read_bytes() == (tmp_path / "b" / "summary.md").read_bytes()
    rows = read_rows(a.rows_path)
    assert len(rows["flight"]) == 10 * 2 * 2
    assert sorted(set(rows["flight"].tolist())) == list(range(10))
    s = json.loads((tmp_path / "a" / "summary.json").read_text())["summary"]
    assert {(r["method"], r["tuning"]) for r in s} == {(m, t) for m in SMALL["methods"]
                                                       for t in ("default", "recommended")}


def test_resume_after_an_interrupt_equals_an_uninterrupted_run(tmp_path):
    spec = small_spec()
    run_montecarlo(spec, 2, 12, tmp_path / "full", fmt="csv", figures=False)

    class Stop(Exception):
        pass

    def stop_after_two(done, n, s):
        if done >= 8:
            raise Stop()

    with pytest.raises(Stop):
        run_montecarlo(spec, 2, 12, tmp_path / "cut", fmt="csv", progress=stop_after_two, figures=False)
    chunks = sorted(p.name for p in (tmp_path / "cut" / "chunks").iterdir())
    assert chunks == ["chunk-000000.csv", "chunk-000001.csv", "run.json"]     # nothing half-written
    assert not (tmp_path / "cut" / "rows.csv").exists()
    with pytest.raises(UserError, match="--resume"):
        run_montecarlo(spec, 2, 12, tmp_path / "cut", fmt="csv", figures=False)
    with pytest.raises(UserError, match="different run"):
        run_montecarlo(spec, 3, 12, tmp_path / "cut", fmt="csv", resume=True, figures=False)
    res = run_montecarlo(spec, 2, 12, tmp_path / "cut", fmt="csv", resume=True, figures=False)
    assert res.resumed_chunks == 2
    assert _bytes(tmp_path / "cut") == _bytes(tmp_path / "full")


def test_sigkill_mid_run_leaves_only_whole_chunks_and_resume_completes(tmp_path):
    """A real interrupt: the CLI killed with SIGKILL while it commits chunks; every chunk file on disk is whole
    (readable, all its rows), no temporary or rows file is left, and --resume finishes with the rows of a run that
    was never interrupted."""
    spec_path = tmp_path / "s.json"
    spec_path.write_text(json.dumps({**SMALL, "chunk_flights": 2}))
    cmd = [sys.executable, "-c", "from firmware_model.cli.main import entry; entry()", "montecarlo", str(spec_path),
           "-n", "40", "--format", "csv", "--no-figures", "--quiet"]
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    out = tmp_path / "cut"
    proc = subprocess.Popen(cmd + ["--out", str(out)], cwd=ROOT, env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE)
    deadline = time.time() + 300
    while time.time() < deadline:
        if len(list((out / "chunks").glob("chunk-*.csv"))) >= 3 if (out / "chunks").exists() else False:
            break
        if proc.poll() is not None:
            pytest.fail(f"finished before it could be killed: {proc.stderr.read().decode()}")
        time.sleep(0.02)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    files = sorted((out / "chunks").iterdir())
    done = [p for p in files if p.name.startswith("chunk-")]
    assert 3 <= len(done) < 20
    for p in done:
        lines = p.read_text().splitlines()
        assert len(lines) == 1 + 2 * 2 * 2, p.name       # header + 2 flights x 2 methods x 2 tunings
    assert not (out / "rows.csv").exists()
    r = subprocess.run(cmd + ["--out", str(out), "--resume"], cwd=ROOT, env=env, capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    run_montecarlo(load_spec({**SMALL, "chunk_flights": 2}), 0, 40, tmp_path / "full", fmt="csv", figures=False)
    assert (out / "rows.csv").read_bytes() == (tmp_path / "full" / "rows.csv").read_bytes()
    assert not [p for p in out.rglob(".fwemu-*")]


def test_transonic_dip_model_reads_low_inside_the_mach_band():
    kw = {"scenario": "sup-m1670-m145", "k": 5, "methods": ["kalman_baro"], "tunings": ["default"]}
    a = pipeline.sense_chunk(load_spec({**kw, "pressure_error": {"model": "transonic_dip", "dip_m": 300.0}}), 1, [0])
    b = pipeline.sense_chunk(load_spec({**kw, "pressure_error": {"model": "none"}}), 1, [0])
    from firmware_model.spec import atmosphere as atm
    d = atm.altitude_m(a.pressure[0]) - atm.altitude_m(b.pressure[0])
    hit = np.nonzero(np.abs(d) > 1e-6)[0]
    np.testing.assert_allclose(d[hit], -300.0, atol=1e-6)
    runs = np.split(hit, np.nonzero(np.diff(hit) > 1)[0] + 1)
    assert len(runs) == 2                          # through the band accelerating, and again slowing down
    t_apo_sample = int(round(a.events[0, 1] * 32)) + 64
    assert runs[1][-1] < t_apo_sample              # both during the climb


def test_real_flight_model_matches_the_deterministic_model_of_issue_20():
    """The Monte Carlo's "real_flight" pressure error (batched over flights, per-flight parameters) equals
    flights.pressure_errors.real_flight_errors (issue 20) flight by flight, its noise bursts and ejection spike off:
    port error, transonic dip, and the jump at each crossing of jump_mach."""
    from firmware_model.flights.simulate import pressure_errors as pe
    from firmware_model.flights.record import FlightRecord
    from firmware_model.spec import atmosphere as atm
    dt = 1 / 32
    t = np.arange(0, 30, dt)
    h = 4000 * np.sin(np.pi * t / 60)                                  # climbing, pressure falling
    p = atm.pressure_pa(h)
    machs = np.vstack([1.4 * np.sin(np.pi * t / 30), 0.6 * np.sin(np.pi * t / 30)])   # through Mach 1 twice; never
    models = [pe.BaroErrorModel(jump_m=350.0, dip_cp=0.09, jump_decay_s=0.6, burst_sigma_m=0.0, ejection_m=0.0),
              pe.BaroErrorModel(jump_m=-120.0, cp_port=0.01, burst_sigma_m=0.0, ejection_m=0.0)]
    names = list(spec_mod.PRESSURE_ERROR_PARAMS["real_flight"])
    prm = {n: np.array([getattr(m, n) for m in models]) for n in names}
    prm["_dt"] = np.full(2, dt)
    got = pipeline.PRESSURE_ERROR_MODELS["real_flight"](np.vstack([p, p]), machs, prm)
    for f, model in enumerate(models):
        rec = FlightRecord(name=f"f{f}", time_s=t, pressure_pa=p.copy())
        want = pe.real_flight_errors(rec, machs[f], model, burst_times_s=[]).pressure_pa
        np.testing.assert_allclose(got[f], want, rtol=1e-12, atol=1e-9)
    dip = atm.altitude_m(got[0]) - h
    assert dip.min() < -200.0 and np.diff(dip).max() > 100.0        # a deep dip, and the shock's jump
    assert not np.array_equal(got[1], p)                             # the subsonic flight: its port error only


def test_real_flight_ram_model_matches_the_deterministic_model_of_issue_30():
    """"real_flight_ram" (batched, per-flight parameters and burnouts) equals flights.pressure_errors.real_flight_errors
    with the ram error in boost flight by flight (noise bursts and ejection off); the ram part reads high by ram_cp q
    while fully on before burnout and not at all after burnout + fade."""
    from firmware_model.flights.simulate import pressure_errors as pe
    from firmware_model.flights.record import FlightRecord
    from firmware_model.spec import atmosphere as atm
    dt = 1 / 64
    t = np.arange(0, 20, dt)
    h = 3000 * np.sin(np.pi * t / 40)
    p = atm.pressure_pa(h)
    machs = np.vstack([1.5 * np.sin(np.pi * t / 12), 1.2 * np.sin(np.pi * t / 12)])
    models = [pe.BaroErrorModel(ram_cp=0.17, ram_mach_on=0.7, ram_fade_s=0.5, burst_sigma_m=0.0, ejection_m=0.0),
              pe.BaroErrorModel(ram_cp=0.03, ram_mach_on=0.85, ram_fade_s=0.0, jump_m=-150.0, burst_sigma_m=0.0,
                                ejection_m=0.0)]
    burnouts = np.array([4.0, 5.3])
    names = list(spec_mod.PRESSURE_ERROR_PARAMS["real_flight_ram"])
    prm = {n: np.array([getattr(m, n) for m in models]) for n in names}
    prm["_dt"] = np.full(2, dt)
    prm["_burnout_s"] = burnouts
    got = pipeline.PRESSURE_ERROR_MODELS["real_flight_ram"](np.vstack([p, p]), machs, prm)
    base = pipeline.PRESSURE_ERROR_MODELS["real_flight"](np.vstack([p, p]), machs,
                                                         {k: v for k, v in prm.items() if not k.startswith("ram_")})
    for f, model in enumerate(models):
        rec = FlightRecord(name=f"f{f}", time_s=t, pressure_pa=p.copy())
        want = pe.real_flight_errors(rec, machs[f], model, burst_times_s=[], burnout_s=float(burnouts[f])).pressure_pa
        np.testing.assert_allclose(got[f], want, rtol=1e-12, atol=1e-9)
        after = t > burnouts[f] + model.ram_fade_s
        np.testing.assert_array_equal(got[f][after], base[f][after])
        on = (machs[f] > model.ram_mach_on + 0.1) & (t < burnouts[f])
        assert on.sum() > 50 and np.all(got[f][on] > base[f][on])
    # the strong one reads below the pad during the boost
    assert (atm.altitude_m(got[0]) < 0).any() and not (atm.altitude_m(base[0]) < 0).any()


def test_real_flight_ram_spec_draws_the_ram_error_in_the_pipeline():
    """docs/montecarlo/ram-pressure.toml loads; against the same draws with ram_cp = 0, each flight's barometer
    reads higher in boost (by up to 0.20 q: kPa), and the same after burnout + fade."""
    raw = read_spec_file(Path(__file__).resolve().parents[2] / "docs" / "montecarlo" / "ram-pressure.toml")
    assert set(load_spec(raw)["dispersions"]["baro"]["choice"]) == {"mpx4115_10bit", "mpx4115_12bit",
                                                                    "mpx4115_16bit", "ms5607"}
    # one build (kalman_baro, default tuning, one preset) keeps the test short; the draws are the spec's
    raw = {**raw, "methods": ["kalman_baro"], "tunings": ["default"],
           "dispersions": {**raw["dispersions"], "baro": "mpx4115_12bit"}}
    spec = load_spec(raw)
    assert spec["pressure_error"]["model"] == "real_flight_ram"
    ids = list(range(6))
    a = pipeline.sense_chunk(spec, 2, ids)
    b = pipeline.sense_chunk(load_spec({**raw, "pressure_error": {**raw["pressure_error"], "ram_cp": 0.0}}), 2, ids)
    dt = 2.0 ** -spec["k"]
    for i in range(len(ids)):
        n = int(a.n[i])
        t = (np.arange(n) + a.offset[i]) * dt
        d = a.pressure[i, :n] - b.pressure[i, :n]
        fade = a.params[i]["pressure_error.ram_fade_s"]
        assert np.all(d[t < a.burnout_s[i]] >= -1e-9) and d.max() > 300.0
        after = t > a.burnout_s[i] + fade
        assert np.array_equal(a.pressure[i, :n][after], b.pressure[i, :n][after])
    ps = [prm["pressure_error.ram_cp"] for prm in a.params]
    assert len(set(ps)) == len(ids) and all(0.01 <= x <= 0.2 for x in ps)


def test_rocket_table_preset_choice_and_accel_range():
    """A [rocket] spec, the barometer drawn among an ADC part and a pascal part (one build each), and a clipping
    range below the boost acceleration."""
    spec = load_spec({"rocket": {"motor": "K400C", "dry_mass_kg": 6.0, "diameter_m": 0.1, "name": "mine"},
                      "k": 5, "methods": ["kalman_baro"], "tunings": ["default"],
                      "dispersions": {"baro": {"choice": ["mpx4115_10bit", "ms5607"]}, "accel_range_g": 2.0}})
    s = pipeline.sense_chunk(spec, 3, list(range(12)))
    names = [p["baro"] for p in s.params]
    assert set(names) == {"mpx4115_10bit", "ms5607"}
    for i, name in enumerate(names):
        words = s.adc[i, :s.n[i]]
        if name == "ms5607":
            assert words.min() > 80_000                     # pascals near the ground
        else:
            assert words.max() <= 1023
    lo, hi = AccelSensor.preset("default", range_g=2.0).count_limits
    assert s.acc.max() == hi                               # the boost clips at 2 g
    rows = pipeline.run_chunk({"spec": spec, "seed": 3, "flights": list(range(12))})
    assert list(rows["p_baro"]) == names and rows["fired"].all()
    plan = pipeline.plan_for(spec)
    assert {k[2] for k in plan.builds} == {"mpx4115_10bit", "ms5607"}
    assert plan.configs[("kalman_baro", "default", "ms5607", "default")].baro_kind == "pascal"
