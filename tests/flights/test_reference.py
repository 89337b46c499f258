"""Reference apogee: truth when the record has it; otherwise the robust parabola of docs/flights.md, checked on
synthetic ballistic flights with known vertex (noise, quantization, spikes, a 100 -> 10 Hz rate change) and on the
shared logs (the two computers of the same prometheus flight must agree)."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from firmware_model.spec.atmosphere import G0, altitude_m, pressure_pa
from firmware_model.flights.inputs.firmware_inputs import DEFAULT_PAD_S, firmware_inputs
from firmware_model.flights.record import FlightRecord, Truth
from firmware_model.flights.reference.apogee_reference import liftoff_time, reference_apogee
from firmware_model.flights.inputs.sensors import BaroSensor
from tests.support.profiles import examples

SHARED = Path(os.environ.get("FWEMU_SHARED_FLIGHTS")
              or Path(__file__).resolve().parents[2].parent / "shared" / "flights")
needs_shared = pytest.mark.skipif(not SHARED.is_dir(), reason="../shared/flights is absent")


def _ballistic(ta: float, v0: float, pad_alt: float, noise_m: float, quant_pa: float, spikes: int, seed: int,
               rate_change: bool) -> tuple[FlightRecord, float, float]:
    """Pad 1 s, boost at 60 m/s^2 for tb s, then vacuum-ballistic coast; apogee time ta after liftoff."""
    rng = np.random.default_rng(seed)
    tb = (ta * G0) / (60.0 + G0)                                         # v(tb) = 60 tb = g (ta - tb)
    t = np.arange(-1.0, ta, 0.01)
    tail = np.arange(t[-1] + 0.1, ta + 6.0, 0.1) if rate_change else np.arange(t[-1] + 0.01, ta + 6.0, 0.01)
    t = np.concatenate([t, tail])
    hb = 0.5 * 60.0 * tb * tb
    h = np.where(t < 0, 0.0, np.where(t < tb, 0.5 * 60.0 * t * t, hb + 60.0 * tb * (t - tb) - 0.5 * G0 * (t - tb) ** 2))
    ha = float(hb + (60.0 * tb) ** 2 / (2 * G0))
    hn = h + rng.normal(0, noise_m, t.size)
    p = np.asarray(pressure_pa(pad_alt + hn))
    if quant_pa:
        p = np.round(p / quant_pa) * quant_pa
    near = np.nonzero(np.abs(t - ta) < 1.5)[0]
    where = near[3 * rng.choice(near.size // 3, size=spikes, replace=False)]     # isolated: 3 samples apart at least
    p[where] -= rng.choice([-1, 1], spikes) * rng.uniform(300, 3000, spikes)   # single-sample pressure spikes
    f = np.where((t >= 0) & (t < tb), 60.0 + G0, np.where(t < 0, G0, 0.0))
    rec = FlightRecord(name="ballistic", time_s=t, pressure_pa=p, accel_mps2=f, provenance={"source": "test"})
    return rec, ta, ha


@settings(max_examples=examples(25))
@given(ta=st.floats(6, 30), pad_alt=st.floats(0, 2000), noise=st.floats(0, 2.0), quant=st.sampled_from([0, 1, 13.57]),
       spikes=st.integers(0, 3), seed=st.integers(0, 10_000), rate_change=st.booleans())
def test_parabola_finds_the_vertex(ta, pad_alt, noise, quant, spikes, seed, rate_change) -> None:
    rec, t_true, h_true = _ballistic(ta, 0, pad_alt, noise, quant, spikes, seed, rate_change)
    ref = reference_apogee(rec)
    # with rate_change the log drops to 10/s at apogee as AltOS does: that drop is the computer's apogee state
    # (flights/charge.py), so the reference may be the interval [a, drop] (issue 31)
    assert ref.source in ("baro_parabola", "baro_interval") and ref.window_s == 1.5
    assert rate_change or ref.notes.get("charge") is None
    # stated tolerance: 0.15 s + the reference's own uncertainty, for noise up to 2 m rms and 13.6 Pa steps
    assert abs(ref.time_s - t_true) <= 0.15 + ref.uncertainty_s, ref
    assert ref.uncertainty_s < 0.5
    assert abs(ref.altitude_m - h_true) < 3.0 + 3 * noise
    assert ref.notes["spikes_rejected"] >= (spikes if ref.notes.get("charge") is None else 0)
    assert abs(liftoff_time(rec)) <= 0.011


def test_truth_wins() -> None:
    t = np.linspace(0, 10, 101)
    tr = Truth(altitude_m=t * (10 - t), apogee_time_s=5.0, apogee_altitude_m=25.0)
    rec = FlightRecord(name="x", time_s=t, pressure_pa=np.asarray(pressure_pa(t * (10 - t))), truth=tr)
    ref = reference_apogee(rec)
    assert (ref.time_s, ref.altitude_m, ref.uncertainty_s, ref.source) == (5.0, 25.0, 0.0, "truth")


def test_firmware_inputs_pad_and_overrides() -> None:
    rec, _, _ = _ballistic(10.0, 0, 1400.0, 0.0, 0, 0, 1, True)
    fi = firmware_inputs(rec, 6, baro=BaroSensor.preset("mpx4115_12bit"))
    assert fi.time_s[0] == pytest.approx(liftoff_time(rec) - DEFAULT_PAD_S, abs=2.0 ** -6)
    assert np.all(np.diff(fi.time_s) == 2.0 ** -6)
    assert fi.report.before_log == int(np.sum(fi.time_s < rec.time_s[0]))
    pad = fi.adc[fi.time_s < -0.2]
    assert np.all(pad == pad[0]) and np.all(fi.acc[fi.time_s < -0.2] == 2048)
    ov = fi.config_overrides()
    from firmware_model.spec.config import BuildConfig

    cfg = BuildConfig(**ov)                         # consistent: a valid build
    assert cfg.baro_bits == 12 and cfg.baro_sign == -1 and cfg.k == 6
    # counts per metre at the pad, against a finite difference of the sensor through the atmosphere
    h0 = float(altitude_m(fi.ground_pressure_pa))
    fd = float(fi.baro.ideal_counts(pressure_pa(h0 - 1.0)) - fi.baro.ideal_counts(pressure_pa(h0 + 1.0))) / 2.0
    assert ov["units_per_metre"] == pytest.approx(fd, rel=1e-3)
    again = firmware_inputs(rec, 6, baro=BaroSensor.preset("mpx4115_12bit", noise_counts=1.0), seed=3)
    same = firmware_inputs(rec, 6, baro=BaroSensor.preset("mpx4115_12bit", noise_counts=1.0), seed=3)
    np.testing.assert_array_equal(again.adc, same.adc)
    assert not np.array_equal(again.adc, fi.adc)


@needs_shared
def test_prometheus_two_computers_agree() -> None:
    from firmware_model.flights.readers import read_flight

    a = reference_apogee(read_flight(SHARED / "altosui" / "prometheus-2022-06-24-telemetrum.csv"))
    b = reference_apogee(read_flight(SHARED / "altosui" / "prometheus-2022-06-24-telemega.csv"))
    assert abs(a.time_s - b.time_s) <= a.uncertainty_s + b.uncertainty_s
    assert abs(a.altitude_m - b.altitude_m) < 10.0


@needs_shared
@pytest.mark.parametrize("path", ["altosui/2012-04-07-serial-882-flight-001.csv",
                                  "altosui/2012-10-20-serial-068-flight-004.csv",
                                  "altosui/prometheus-2022-06-24-telemetrum.csv",
                                  "altosui/prometheus-2022-06-24-telemega.csv", "cats/hedy-baro.csv"])
def test_shared_logs_have_a_reference(path: str) -> None:
    from firmware_model.flights.readers import read_flight

    ref = reference_apogee(read_flight(SHARED / path))
    assert ref.source in ("baro_parabola", "baro_interval") and 0 < ref.uncertainty_s < 1.5
    # issue 31: nothing after the log's recovery charge unless justified (the flight still rising at it) or flagged
    charge = ref.notes.get("charge")
    if charge is not None and "warning" not in ref.notes:
        if ref.time_s > charge["time_s"]:
            assert "after_charge" in ref.notes
            assert ref.notes["velocity_at_charge_mps"] > 2 * ref.notes["velocity_at_charge_se_mps"]
        if ref.interval_s is not None:
            assert ref.interval_s[1] == charge["time_s"]


# ------------------------------------------------------------------ against simulated truth (an independent oracle)
def _as_log(rec: FlightRecord, noise_pa: float, seed: int, rate_hz: float = 100.0) -> FlightRecord:
    """What an altimeter would have logged: pressure at ``rate_hz``, integer pascals plus Gaussian noise, no
    truth."""
    t = np.arange(rec.time_s[0], rec.time_s[-1], 1.0 / rate_hz)
    p = np.interp(t, rec.time_s, rec.pressure_pa)
    p = np.round(p + np.random.default_rng(seed).normal(0.0, noise_pa, t.size)) if noise_pa else np.round(p)
    return FlightRecord(name=rec.name, time_s=t, pressure_pa=p, provenance={"source": rec.name})


from firmware_model.flights.strategies import flights  # noqa: E402 - after the helpers: the module is heavy to read


@settings(max_examples=examples(15))
@given(rec=flights(), noise=st.sampled_from([0.0, 5.0, 15.0]), seed=st.integers(0, 1000))
def test_parabola_against_simulated_truth(rec: FlightRecord, noise: float, seed: int) -> None:
    """On 1-DOF flights (drag, drogue after apogee) logged as integer pascals at 100 Hz with up to 15 Pa of noise,
    the baro-only reference lies within its own uncertainty + 0.03 s of the true apogee."""
    ref = reference_apogee(_as_log(rec, noise, seed))
    err = ref.time_s - rec.truth.apogee_time_s
    assert abs(err) <= ref.uncertainty_s + 0.03, (err, ref.uncertainty_s, ref.notes["fits"])
    assert ref.uncertainty_s < 0.3


@pytest.mark.parametrize("name", ["sub-k400-300m", "sub-k828-1400m", "trans-k828-m118", "trans-m6400-m109",
                                  "sup-m1670-m145", "sup-m2245-m19-9400m-spikes"])
def test_parabola_on_scenarios(name: str) -> None:
    from firmware_model.flights.simulate.scenarios import simulate_scenario

    rec = simulate_scenario(name)
    for noise in (0.0, 10.0):
        ref = reference_apogee(_as_log(rec, noise, 1))
        err = ref.time_s - rec.truth.apogee_time_s
        assert abs(err) <= ref.uncertainty_s + 0.03, (name, noise, err, ref.uncertainty_s)
        assert abs(ref.altitude_m - rec.truth.apogee_altitude_m) < 1.0


@pytest.mark.parametrize("name", ["sub-k400-300m", "sub-m1670-3200m", "trans-k828-m118", "sup-m6400-m167-clean"])
def test_liftoff_from_each_source(name: str) -> None:
    """Liftoff from truth, from the accelerometer alone and from the barometer alone agree within 0.03 s."""
    import dataclasses

    from firmware_model.flights.simulate.scenarios import simulate_scenario

    rec = simulate_scenario(name)
    v = rec.truth.velocity_mps
    true_t = float(rec.time_s[int(np.argmax(v > 0.01)) - 1])
    assert liftoff_time(rec) == true_t
    no_truth = dataclasses.replace(rec, truth=None)
    assert abs(liftoff_time(no_truth) - true_t) <= 0.01
    baro_only = dataclasses.replace(rec, truth=None, accel_mps2=None)
    assert abs(liftoff_time(baro_only) - true_t) <= 0.03


# ------------------------------------------------------------------ rule 5: a deployment inside the window
def _deployed_log(rec: FlightRecord, d: float, seed: int = 1) -> FlightRecord:
    """``rec`` logged at 100 Hz with 10 Pa of noise and an AltOS-like deployment ``d`` s after the true apogee:
    from then on the pressure is disturbed (40 Pa rms, a +30 m excursion 0.5-0.8 s later) and logged at 10 Hz."""
    rng = np.random.default_rng(seed)
    t = np.arange(rec.time_s[0], rec.time_s[-1], 0.01)
    p = np.interp(t, rec.time_s, rec.pressure_pa) + rng.normal(0.0, 10.0, t.size)
    td = float(rec.truth.apogee_time_s) + d
    after = t > td
    p[after] += rng.normal(0.0, 40.0, int(after.sum()))
    bump = (t > td + 0.5) & (t < td + 0.8)
    p[bump] = pressure_pa(altitude_m(p[bump]) + 30.0)
    keep = ~after | (np.round((t - td) * 100).astype(int) % 10 == 0)
    return FlightRecord(name=rec.name, time_s=t[keep], pressure_pa=np.round(p[keep]),
                        events={"altos_drogue": td}, provenance={"source": rec.name})


_DEPLOY_CASES = [(n, d) for n in ("sub-k400-300m", "sub-k828-1400m", "trans-k828-m118", "sup-m1670-m145",
                                  "sub-l1350-1900m-delay") for d in (0.1, 0.5, 1.5)]


@pytest.mark.parametrize("name,d", _DEPLOY_CASES)
def test_deployment_cut_against_truth(name: str, d: float) -> None:
    """With the computer's deployment 0.1-1.5 s after apogee and the pressure disturbed after it, rule 5 fits only
    the samples before the charge and lands within its uncertainty + 0.03 s of the true apogee (an interval
    reference: the truth inside it, +-0.03 s). sub-l1350-1900m-delay at 0.1 s, a measured miss of the unconstrained
    one-sided fit (+0.095 s against 0.053 s), is inside since the fit has its curvature prior (issue 31)."""
    from firmware_model.flights.simulate.scenarios import simulate_scenario

    rec = simulate_scenario(name)
    ref = reference_apogee(_deployed_log(rec, d))
    assert ref.notes["deployment_cut"] and ref.time_s <= ref.notes["deployment_s"]
    err = ref.time_s - rec.truth.apogee_time_s
    assert abs(err) <= ref.uncertainty_s + 0.03, (err, ref.uncertainty_s)
    if ref.interval_s is not None:
        assert ref.interval_s[0] - 0.03 <= rec.truth.apogee_time_s <= ref.interval_s[1] + 0.03


@pytest.mark.parametrize("early", [0.6, pytest.param(0.3, marks=pytest.mark.xfail(strict=True, reason=(
    "measured: a charge 0.3 s before apogee on this 10 Pa log gives the interval [-0.52, -0.30] s about the truth: "
    "the vertex with the curvature pinned at -g does not lie clearly after the charge, so the rule assumes the "
    "computer fired at or after apogee (issue 31 report)")))])
def test_charge_before_apogee_is_justified(early: float) -> None:
    """A charge fired 0.3-0.6 s before apogee: the flight before it is still rising (its fitted velocity at the
    charge is above twice its standard error), so the reference lies after the charge, says why, and holds the
    truth within its uncertainty + 0.03 s."""
    import dataclasses

    from firmware_model.flights.simulate.scenarios import simulate_scenario

    rec = simulate_scenario("sub-k828-1400m")
    ta = float(rec.truth.apogee_time_s)
    ref = reference_apogee(dataclasses.replace(_as_log(rec, 10.0, 1), events={"altos_apogee": ta - early}))
    assert ref.time_s > ta - early and "after_charge" in ref.notes and ref.interval_s is None
    assert ref.notes["velocity_at_charge_mps"] > 2 * ref.notes["velocity_at_charge_se_mps"]
    assert abs(ref.time_s - ta) <= ref.uncertainty_s + 0.03


def test_flat_top_before_the_charge_is_an_interval() -> None:
    """A charge 0-0.1 s after apogee on a noisy log: the pre-charge vertex does not lie clearly before it, so the
    reference is the interval [vertex - u, charge], which holds the truth (the old rule dropped the cut and fitted
    across the ejection)."""
    import dataclasses

    from firmware_model.flights.simulate.scenarios import simulate_scenario

    rec = simulate_scenario("sub-k828-1400m")
    ta = float(rec.truth.apogee_time_s)
    for d in (0.0, 0.1):
        ref = reference_apogee(dataclasses.replace(_as_log(rec, 10.0, 1), events={"altos_apogee": ta + d}))
        assert ref.source == "baro_interval" and ref.interval_s is not None
        assert ref.interval_s[1] == pytest.approx(ta + d)
        assert ref.interval_s[0] <= ta <= ref.interval_s[1]


@needs_shared
def test_068_deployment_cut() -> None:
    """2012-10-20 serial 068: AltOS fired at 18.28 s and the pressure is disturbed after it. Without rule 5 the
    fit's vertex sat 0.55 s after the charge with a curvature of -20 m/s^2 (flagged); with it the vertex lies
    before the charge and the curvature is ballistic (no warning)."""
    from firmware_model.flights.readers import read_flight

    ref = reference_apogee(read_flight(SHARED / "altosui" / "2012-10-20-serial-068-flight-004.csv"))
    assert ref.notes["deployment_cut"] and ref.notes["deployment_s"] == pytest.approx(18.28)
    assert 17.8 < ref.time_s <= 18.28 and "warning" not in ref.notes
    assert -1.5 * G0 < ref.notes["curvature_mps2"] < -0.75 * G0
