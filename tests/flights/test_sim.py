"""Flight simulators: the 1-DOF model against closed forms and an independent atmosphere, the pressure-error
effects, the scenario catalogue, the ``flights()`` strategy, and (with rocketpy) the RocketPy model and the
cross-check of the two (docs/flights-sim.md)."""

from __future__ import annotations

import hashlib

import numpy as np
import pytest
from hypothesis import given, settings
from scipy import integrate, optimize

from firmware_model.spec import atmosphere as atm
from firmware_model.runtime.errors import UserError
from firmware_model.flights.simulate import motors as mo
from firmware_model.flights.simulate import pressure_errors as pe
from firmware_model.flights.simulate import scenarios as sc
from firmware_model.flights.simulate import sim1dof as s1
from firmware_model.flights.strategies import flights
from tests.support.profiles import examples
from tests.support.sim1dof_numpy import simulate_numpy

G = atm.G0


def _digest(rec) -> str:
    h = hashlib.sha256()
    for a in (rec.time_s, rec.pressure_pa, rec.accel_mps2, rec.truth.altitude_m, rec.truth.velocity_mps,
              rec.truth.accel_mps2):
        h.update(np.ascontiguousarray(a, dtype=np.float64).tobytes())
    h.update(repr((rec.truth.apogee_time_s, rec.truth.apogee_altitude_m)).encode())
    return h.hexdigest()


def _motor(times, thrusts, prop_kg, name="test") -> mo.ThrustCurve:
    return mo.ThrustCurve(name=name, time_s=np.array(times, float), thrust_n=np.array(thrusts, float),
                          propellant_mass_kg=prop_kg, total_mass_kg=prop_kg + 0.5, diameter_m=0.054,
                          length_m=0.4)


# ---------------------------------------------------------------------------------------------------- motors

def test_shipped_motors_parse_and_impulse_matches_quadrature():
    for name in mo.motor_names():
        m = mo.load_motor(name)
        assert m.time_s[0] == 0.0 and m.thrust_n[0] == 0.0 and m.thrust_n[-1] == 0.0
        quad = sum(integrate.quad(lambda t: float(m.thrust_at(t)), a, b)[0]
                   for a, b in zip(m.time_s[:-1], m.time_s[1:]))
        assert m.total_impulse_ns == pytest.approx(quad, rel=1e-9)
        tm = 0.37 * m.burn_time_s
        part = integrate.quad(lambda t: float(m.thrust_at(t)), 0, tm, points=list(m.time_s[m.time_s < tm]),
                              limit=200)[0]
        assert float(m.impulse_at(tm)) == pytest.approx(part, rel=1e-9)
        assert float(m.propellant_at(m.burn_time_s)) == pytest.approx(0.0, abs=1e-12)
    # class letters of the names agree with the impulse (K: 640..1280? no: K 1280.01..2560, L ..5120, M ..10240)
    bounds = {"K": (1280, 2560), "L": (2560, 5120), "M": (5120, 10240)}
    for name in mo.motor_names():
        lo, hi = bounds[name[0]]
        assert lo < mo.load_motor(name).total_impulse_ns <= hi, name


@pytest.mark.parametrize("text,msg", [
    ("K1 54 300 P 0.5 1.0 X\n0.1 100\n0.1 50\n0.5 0\n", ":3: time does not increase"),
    ("K1 54 300 P 0.5 1.0 X\n0.1 100\n0.2 abc\n", ":3: unparseable thrust row"),
    ("K1 54 300\n0.1 100\n", ":1: RASP header needs 7 fields"),
    ("; only\n", "no RASP header"),
    ("K1 54 300 P 0.5 1.0 X\n0.1 100\n0.3 20\n", "last thrust row must be 0 N"),
    ("K1 54 300 P 0.5 1.0 X\n0.1 -100\n0.3 0\n", ":2: negative thrust"),
])
def test_eng_parser_rejects_bad_files_with_line(text, msg):
    with pytest.raises(UserError, match=msg):
        mo.parse_eng(text, "bad.eng")


# ------------------------------------------------------------------------------------------------ 1-DOF model

def test_drag_free_flight_matches_rocket_equation():
    """Without drag the free-flight velocity is exact for any thrust profile when mass flow is proportional to
    thrust: v(t) = ve ln(m(t_lift)/m(t)) - g (t - t_lift), ve = I/m_prop; then a ballistic arc."""
    motor = _motor([0, 0.05, 0.3, 1.8, 2.2, 2.4], [0, 300, 420, 380, 120, 0], 0.6)
    dry = 3.0
    rocket = s1.Rocket("nodrag", dry, 0.1, motor, cd_scale=0.0, drogue_cd_area_m2=0.0)
    rec = s1.simulate_1dof(rocket, s1.Launch(record_hz=1000.0, descent_s=1.0))[0]
    ve = motor.total_impulse_ns / motor.propellant_mass_kg
    mass = lambda t: dry + float(motor.propellant_at(t))
    t_l = optimize.brentq(lambda t: float(motor.thrust_at(t)) - mass(t) * G, 1e-6, 0.05)
    v = lambda t: ve * np.log(mass(t_l) / mass(t)) - G * (t - t_l)
    tb = motor.burn_time_s
    vb = v(tb)
    zb = integrate.quad(v, t_l, tb, points=list(motor.time_s[1:-1]), epsabs=1e-10, limit=200)[0]
    t_apo = tb + vb / G
    z_apo = zb + vb * vb / (2 * G)
    i = int(np.searchsorted(rec.time_s, tb - 1e-9))
    assert rec.truth.velocity_mps[i] == pytest.approx(vb, abs=2e-4)
    assert rec.truth.apogee_time_s == pytest.approx(t_apo, abs=1e-5)
    # measured: +0.53 mm at 1 kHz, converging ~h^2 (RK4 loses order at lift-off and the table's kinks)
    assert rec.truth.apogee_altitude_m == pytest.approx(z_apo, abs=1e-3)
    assert rec.provenance["summary"]["liftoff_s"] == pytest.approx(t_l, abs=1.1e-3)


def test_terminal_velocity_under_drogue():
    """Long descent, no body drag: the descent rate approaches sqrt(2 m g / (rho CdA))."""
    motor = _motor([0, 0.05, 1.0, 1.1], [0, 400, 400, 0], 0.3)
    rocket = s1.Rocket("chute", 2.0, 0.1, motor, cd_scale=0.0, drogue_cd_area_m2=0.4)
    rec = s1.simulate_1dof(rocket, s1.Launch(record_hz=100.0, descent_s=25.0, site_altitude_m=800.0))[0]
    assert rec.truth.altitude_m[-1] > 10.0, "landed before terminal speed"
    rho = atm.density_kg_m3(800.0 + rec.truth.altitude_m[-1])
    vt = np.sqrt(2 * 2.0 * G / (rho * 0.4))
    assert -rec.truth.velocity_mps[-1] == pytest.approx(vt, rel=2e-3)
    assert rec.accel_mps2[-1] == pytest.approx(G, abs=0.05)   # hanging under the drogue: ~ +1 g sensed


def test_record_fields_pad_and_consistency():
    rocket = s1.Rocket("r", 8.0, 0.1, mo.load_motor("K400C"))
    launch = s1.Launch(site_altitude_m=1234.0, pad_s=1.5, record_hz=500.0)
    rec = s1.simulate_1dof(rocket, launch)[0]
    t = rec.time_s
    assert np.allclose(np.diff(t), 1 / 500.0, rtol=0, atol=1e-12) and t[0] == pytest.approx(-1.5)
    pad = t < 0
    assert pad.sum() == 750
    assert np.all(rec.accel_mps2[pad] == G) and np.all(rec.truth.altitude_m[pad] == 0)
    # pressure: the standard atmosphere, checked against an independent implementation (ambiance)
    ambiance = pytest.importorskip("ambiance")
    idx = np.linspace(0, rec.n - 1, 25).astype(int)
    geo = 1234.0 + rec.truth.altitude_m[idx]
    geometric = geo * 6356766.0 / (6356766.0 - geo)          # ambiance takes geometric altitude
    assert np.allclose(rec.pressure_pa[idx], ambiance.Atmosphere(geometric).pressure, rtol=2e-5)
    assert rec.ground_pressure_pa == pytest.approx(float(ambiance.Atmosphere(1234.0 * 6356766.0 /
                                                                            (6356766.0 - 1234.0)).pressure[0]),
                                                   rel=2e-5)
    # truth acceleration is the derivative of truth velocity, velocity the derivative of altitude
    fly = (t > 0.1) & (t < rec.truth.apogee_time_s - 0.1)
    burn = mo.load_motor("K400C").time_s
    smooth = fly & np.all(np.abs(t[:, None] - burn[None, :]) > 0.01, axis=1)
    dv = np.gradient(rec.truth.velocity_mps, t)
    dz = np.gradient(rec.truth.altitude_m, t)
    assert np.max(np.abs(dv - rec.truth.accel_mps2)[smooth]) < 0.05
    assert np.max(np.abs(dz - rec.truth.velocity_mps)[fly]) < 1e-3
    # coast: the accelerometer reads minus drag over mass (negative), burn: positive specific force
    coast = (t > 3.5) & (t < rec.truth.apogee_time_s)
    assert np.all(rec.accel_mps2[coast] < 0) and np.all(rec.accel_mps2[(t > 0.1) & (t < 2.5)] > G)
    # apogee: the velocity changes sign there, the altitude there is the maximum
    k = int(np.searchsorted(t, rec.truth.apogee_time_s))
    assert rec.truth.velocity_mps[k - 1] > 0 >= rec.truth.velocity_mps[k]
    assert 0 <= rec.truth.apogee_altitude_m - rec.truth.altitude_m.max() < 1e-4
    assert t[-1] == pytest.approx(rec.truth.apogee_time_s + 5.0, abs=2e-3)


def test_step_size_error_is_below_a_centimetre():
    rockets = [s1.Rocket("a", 8.0, 0.1, mo.load_motor("K400C")), s1.Rocket("b", 12.0, 0.1, mo.load_motor("M6400"))]
    fine = s1.simulate_1dof(rockets, s1.Launch(record_hz=500.0, internal_hz=4000.0))
    base = s1.simulate_1dof(rockets, s1.Launch(record_hz=500.0, internal_hz=1000.0))
    for f, b in zip(fine, base):
        assert abs(f.truth.apogee_altitude_m - b.truth.apogee_altitude_m) < 0.01
        assert abs(f.truth.apogee_time_s - b.truth.apogee_time_s) < 1e-4


def test_engines_agree_with_the_numpy_oracle_and_runs_are_deterministic():
    """The per-flight loop (shared point-mass helpers), uncompiled and compiled, gives the bytes of the
    independent numpy integrator (tests/support/sim1dof_numpy.py), flight by flight and in a batch."""
    rockets = [s1.Rocket("a", 14.0, 0.1, mo.load_motor("K400C")),
               s1.Rocket("b", 3.0, 0.1, mo.load_motor("K828FJ").scaled(0.5, 1.0), drogue_cd_area_m2=0.3)]
    launch = s1.Launch(record_hz=50.0, internal_hz=250.0, descent_s=2.0)
    ref = [_digest(r) for r in simulate_numpy(rockets, launch)]
    assert ref == [_digest(r) for r in simulate_numpy(rockets, launch)]
    assert ref == [_digest(r) for r in s1.simulate_1dof(rockets, launch, engine="python")]
    if s1.HAVE_NUMBA:
        assert ref == [_digest(r) for r in s1.simulate_1dof(rockets, launch, engine="kernel")]
    # batching does not change a flight
    assert ref[1] == _digest(simulate_numpy(rockets[1], launch)[0])
    assert ref[1] == _digest(s1.simulate_1dof(rockets[1], launch, engine="python")[0])
    with pytest.raises(UserError, match="unknown engine 'numpy'"):
        s1.simulate_1dof(rockets[1], launch, engine="numpy")


def test_random_flights_seeded():
    a = s1.random_flights(6, seed=5, launch=s1.Launch(record_hz=100.0))
    b = s1.random_flights(6, seed=5, launch=s1.Launch(record_hz=100.0))
    c = s1.random_flights(6, seed=6, launch=s1.Launch(record_hz=100.0))
    assert [_digest(r) for r in a] == [_digest(r) for r in b]
    assert [_digest(r) for r in a] != [_digest(r) for r in c]
    for r in a:
        assert r.provenance["seed"] == 5 and r.truth.apogee_altitude_m > 50


def test_bad_parameters_are_user_errors():
    m = mo.load_motor("K400C")
    with pytest.raises(UserError, match="masses and diameter"):
        s1.simulate_1dof(s1.Rocket("x", -1.0, 0.1, m))
    with pytest.raises(UserError, match="site altitude"):
        s1.simulate_1dof(s1.Rocket("x", 5.0, 0.1, m), s1.Launch(site_altitude_m=9000.0))
    with pytest.raises(UserError, match="not finished"):
        s1.simulate_1dof(s1.Rocket("x", 5.0, 0.1, m), s1.Launch(max_time_s=3.0), engine="python")
    with pytest.raises(UserError, match="not finished"):
        simulate_numpy(s1.Rocket("x", 5.0, 0.1, m), s1.Launch(max_time_s=3.0))
    with pytest.raises(UserError, match="thrust never exceeds weight"):
        s1.simulate_1dof(s1.Rocket("x", 60.0, 0.1, m))
    with pytest.raises(UserError, match="unknown motor"):
        mo.load_motor("Z9")


# ------------------------------------------------------------------------------------------- pressure errors

def _transonic_record():
    return sc.simulate_scenario("trans-m1670-m105-clean")


def test_transonic_step_follows_mach_and_the_seed_sign():
    rec = _transonic_record()
    mach = s1.mach_of(rec)
    out = pe.transonic_pressure_error(rec, altitude_step_m=60.0)
    above = mach >= 1.0
    assert above.any() and (~above).any()
    p0, p1 = rec.pressure_pa, out.pressure_pa
    assert np.array_equal(p1[~above], p0[~above])
    dh = atm.altitude_m(p1[above]) - atm.altitude_m(p0[above])
    assert np.allclose(dh, 60.0, atol=1e-6)
    assert np.all(p1[above] < p0[above])               # Schultz n.d.: pressure altitude steps UP above Mach 1
    (t_on, t_off), = out.provenance["effects"][-1]["intervals_s"]
    t = rec.time_s
    assert t_on == t[np.argmax(above)] and t_off == t[len(above) - 1 - np.argmax(above[::-1])]
    # ramp: 0 well below, full well above, monotone in between while accelerating
    ramp = pe.transonic_pressure_error(rec, altitude_step_m=-30.0, shape="ramp", width_mach=0.1)
    dh = atm.altitude_m(ramp.pressure_pa) - atm.altitude_m(p0)
    assert np.allclose(dh[mach < 0.95], 0.0, atol=1e-9) and np.allclose(dh[mach > 1.05], -30.0, atol=1e-6)


def test_transonic_hysteresis():
    mach = np.array([0.5, 0.99, 1.0, 1.1, 1.0, 0.97, 0.96, 0.94, 0.99, 1.0, 0.5])
    f = pe.supersonic_fraction(mach, mach_on=1.0, mach_off=0.95)
    assert f.tolist() == [0, 0, 1, 1, 1, 1, 1, 0, 0, 1, 0]


def test_pressure_spikes_touch_single_samples():
    rec = sc.simulate_scenario("sub-k400-900m")
    out = pe.pressure_spikes(rec, count=5, magnitude_pa=900.0, seed=1)
    d = out.pressure_pa - rec.pressure_pa
    nz = np.nonzero(d)[0]
    assert nz.size == 5 and np.allclose(np.abs(d[nz]), 900.0)
    assert np.all(np.diff(nz) > 1)                      # isolated
    eff = out.provenance["effects"][-1]
    assert eff["times_s"] == [float(x) for x in rec.time_s[nz]]
    again = pe.pressure_spikes(rec, count=5, magnitude_pa=900.0, seed=1)
    assert np.array_equal(again.pressure_pa, out.pressure_pa)
    at = pe.pressure_spikes(rec, times_s=[3.0, 10.0], sign=-1, magnitude_pa=100.0)
    assert np.count_nonzero(at.pressure_pa - rec.pressure_pa) == 2
    assert rec.provenance.get("effects") is None        # the input record is untouched
    with pytest.raises(UserError, match="sign"):
        pe.pressure_spikes(rec, sign=2)


# ------------------------------------------------------------------------------------------------- scenarios

def test_catalogue_covers_the_brief():
    names = sc.scenario_names()
    assert len(names) >= 20 and len(set(names)) == len(names)
    cat = sc.scenario_catalogue()
    classes = [v["mach_class"] for v in cat.values()]
    for c in ("subsonic", "transonic", "supersonic"):
        assert classes.count(c) >= 5, c
    assert sum(v["transonic"] for v in cat.values()) >= 5 and sum(v["spikes"] for v in cat.values()) >= 3


@pytest.mark.parametrize("name", [n for n in sc.scenario_names() if sc.get_scenario(n).simulator == "1dof"])
def test_scenario_is_in_its_class_and_deterministic(name):
    s = sc.get_scenario(name)
    rec = sc.simulate_scenario(name)
    lo, hi = sc.MACH_CLASSES[s.mach_class]
    peak = rec.provenance["summary"]["max_mach"]
    assert lo <= peak <= hi, (name, peak)
    assert float(np.max(sc.scenario_mach(name))) == pytest.approx(peak, abs=0.01)
    assert 250.0 <= rec.truth.apogee_altitude_m <= 10_500.0
    kinds = [e["effect"] for e in rec.provenance.get("effects", [])]
    assert ("transonic_pressure_error" in kinds) == (s.transonic is not None)
    assert ("pressure_spikes" in kinds) == (s.spikes is not None)
    assert ("real_flight_errors" in kinds) == (s.baro_errors is not None)
    again, mach = sc._simulate_physics(s)
    assert _digest(sc.finish_record(s, again, mach)[0]) == _digest(rec)


def test_unknown_scenario():
    with pytest.raises(UserError, match="unknown scenario 'nope'"):
        sc.simulate_scenario("nope")


def test_cache_roundtrip(tmp_path):
    rec = sc.simulate_scenario("sub-k400-300m")
    mach = sc.scenario_mach("sub-k400-300m")
    path = tmp_path / "x.npz"
    sc.save_record(rec, mach, path)
    back, m2 = sc.load_record(path)
    assert _digest(back) == _digest(rec) and np.array_equal(m2, mach)
    assert back.provenance == rec.provenance
    assert [p.name for p in tmp_path.iterdir()] == ["x.npz"]


# -------------------------------------------------------------------------------------------------- strategy

@settings(max_examples=examples(15))
@given(flights(record_hz=100.0))
def test_flights_strategy_subsonic_with_truth(rec):
    t = rec.time_s
    assert np.allclose(np.diff(t), 0.01, atol=1e-12)
    assert rec.provenance["summary"]["max_mach"] <= 0.8
    assert rec.truth.apogee_altitude_m > 20.0
    assert 0.0 < rec.truth.apogee_time_s < t[-1]
    assert np.all(rec.accel_mps2[t < 0] == G)
    assert rec.ground_pressure_pa == pytest.approx(rec.pressure_pa[0])


# --------------------------------------------------------------------------------------------------- RocketPy

def test_rocketpy_missing_is_a_user_error(monkeypatch):
    import sys

    from firmware_model.flights.simulate import rocketpy_sim
    monkeypatch.setitem(sys.modules, "rocketpy", None)
    with pytest.raises(UserError, match="install the flights extra"):
        rocketpy_sim.simulate_rocketpy(s1.Rocket("x", 8.0, 0.1, mo.load_motor("K400C")))


def test_rocketpy_cross_check_and_record():
    """Vertical, no wind, same rocket in both simulators. Measured (docs/flights-sim.md): K828FJ subsonic
    +0.006 % apogee, +5.8 ms, +0.008 % burnout velocity; M1670 transonic -0.048 %, +11.9 ms, -0.014 %.
    Asserted bounds for both: 0.1 %, 25 ms, 0.05 %."""
    pytest.importorskip("rocketpy")
    from firmware_model.flights.simulate import crosscheck
    name = "K828FJ subsonic"
    c = crosscheck.compare(name, crosscheck.CROSS_CHECK_ROCKETS[name])
    assert abs(c.apogee_rel) < 1e-3, c.line()
    assert abs(c.apogee_dt) < 0.025, c.line()
    assert abs(c.burnout_rel) < 5e-4, c.line()
    # the accelerometers agree (checks the body-axis projection of RocketPy's acceleration): measured max
    # 0.051 m/s^2 (K828FJ) and 0.056 (M1670) from 0.5 s to apogee, 20 ms away from the thrust table's points
    n = min(c.one.n, c.rpy.n)
    tt = c.one.time_s[:n]
    knots = crosscheck.CROSS_CHECK_ROCKETS[name].motor.time_s
    away = np.all(np.abs(tt[:, None] - knots[None, :]) > 0.02, axis=1) & (tt > 0.5) & (tt < c.one.truth.apogee_time_s)
    assert np.max(np.abs(c.rpy.accel_mps2[:n] - c.one.accel_mps2[:n])[away]) < 0.1
    rec = c.rpy
    t = rec.time_s
    assert np.allclose(np.diff(t), 1e-3, atol=1e-12) and np.all(rec.accel_mps2[t < 0] == pytest.approx(G))
    coast = (t > 3.0) & (t < rec.truth.apogee_time_s)
    fast = coast & (rec.truth.velocity_mps > 30.0)
    assert np.all(rec.accel_mps2[fast] < 0)            # drag decelerates: the accelerometer reads negative
    assert np.all(rec.accel_mps2[coast] < 0.01)        # (near apogee RocketPy's frame terms give ~+2e-3 m/s^2)
    # the pressure is the standard atmosphere at the truth (geopotential) altitude
    site = atm.altitude_m(rec.ground_pressure_pa)
    assert np.allclose(atm.altitude_m(rec.pressure_pa), site + rec.truth.altitude_m, atol=1e-6)
    assert abs(rec.truth.apogee_altitude_m - rec.truth.altitude_m.max()) < 0.05
    # same inputs, same bytes
    again = crosscheck.compare(name, crosscheck.CROSS_CHECK_ROCKETS[name]).rpy
    assert _digest(again) == _digest(rec)


def _slow() -> bool:
    import os

    from tests.support import profiles
    return profiles.PROFILE == "thorough" or os.environ.get("FWEMU_SLOW") == "1"


@pytest.mark.parametrize("name", [n for n in sc.scenario_names() if sc.get_scenario(n).simulator == "rocketpy"])
def test_rocketpy_scenario_is_in_its_class(name):
    pytest.importorskip("rocketpy")
    if not _slow():
        pytest.skip("RocketPy scenarios take seconds each: run with HYPOTHESIS_PROFILE=thorough or FWEMU_SLOW=1")
    s = sc.get_scenario(name)
    rec = sc.simulate_scenario(name)
    lo, hi = sc.MACH_CLASSES[s.mach_class]
    assert lo <= rec.provenance["summary"]["max_mach"] <= hi
    assert 250.0 <= rec.truth.apogee_altitude_m <= 10_500.0
    kinds = [e["effect"] for e in rec.provenance.get("effects", [])]
    assert ("transonic_pressure_error" in kinds) == (s.transonic is not None)
    assert ("real_flight_errors" in kinds) == (s.baro_errors is not None)


def test_same_bytes_in_a_fresh_process():
    """Determinism does not depend on process state (numba compiled or cached, import order, earlier runs)."""
    import os
    import subprocess
    import sys
    from pathlib import Path

    root = Path(__file__).resolve().parents[2]
    code = ("from tests.flights.test_sim import _digest; from firmware_model.flights.simulate import sim1dof as s1; "
            "print(' '.join(_digest(r) for r in s1.random_flights(3, 9, launch=s1.Launch(record_hz=50.0))))")
    env = dict(os.environ, PYTHONPATH=str(root))
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, cwd=root,
                         check=True).stdout.split()
    here = [_digest(r) for r in s1.random_flights(3, 9, launch=s1.Launch(record_hz=50.0))]
    assert out == here


@settings(max_examples=examples(5))
@given(flights(mach=(0.9, 2.0), motors=("M1670", "M6400", "M2245", "L1350"), record_hz=50.0))
def test_flights_strategy_widened_to_supersonic(rec):
    assert 0.9 <= rec.provenance["summary"]["max_mach"] <= 2.0
    assert rec.truth.apogee_altitude_m > 500.0
