"""Sensor models: deterministic from the seed, inside their range and word, clipping, exact presets, inverses."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from firmware_model.spec.atmosphere import G0, altitude_m, density_kg_m3
from firmware_model.runtime.errors import UserError
from firmware_model.flights.inputs.sensors import ACCEL_PRESETS, BARO_PRESETS, AccelSensor, BaroSensor
from tests.support.profiles import examples

SHARED = Path(os.environ.get("FWEMU_SHARED_FLIGHTS")
              or Path(__file__).resolve().parents[2].parent / "shared" / "flights")

baro_sensors = st.one_of(
    st.sampled_from(sorted(BARO_PRESETS)).map(BaroSensor.preset),
    st.builds(BaroSensor.adc_linear, bits=st.integers(8, 16), p_min_pa=st.floats(1_000, 50_000),
              p_max_pa=st.floats(60_000, 130_000), sign=st.sampled_from([-1, 1])),
)
noise = st.tuples(st.floats(0, 50), st.floats(0, 5))
pressures = st.lists(st.floats(0.0, 200_000.0), min_size=1, max_size=50).map(np.array)


@settings(max_examples=examples(80))
@given(sensor=baro_sensors, nz=noise, p=pressures, seed=st.integers(0, 2**32 - 1))
def test_baro_deterministic_and_in_range(sensor: BaroSensor, nz, p: np.ndarray, seed: int) -> None:
    s = BaroSensor(**{**sensor.to_dict(), "noise_pa": nz[0], "noise_counts": nz[1]})
    a = s.counts(p, np.random.default_rng(seed))
    b = s.counts(p, seed)                                   # an int seed is the same generator
    np.testing.assert_array_equal(a, b)
    assert a.dtype == np.int64
    if s.kind == "adc":
        assert a.min() >= 0 and a.max() <= (1 << s.bits) - 1
    else:
        assert a.min() >= s.p_min_pa and a.max() <= s.p_max_pa
    # noise-free: clipping at the sensor's range, then nearest count, computed independently
    exact = BaroSensor(**{**sensor.to_dict(), "noise_pa": 0.0, "noise_counts": 0.0})
    pc = np.minimum(np.maximum(p, s.p_min_pa), s.p_max_pa)
    hi = (1 << s.bits) - 1 if s.kind == "adc" else s.p_max_pa
    lo = 0 if s.kind == "adc" else s.p_min_pa
    want = np.minimum(np.maximum(np.round(s.counts_per_pa * pc + s.offset_counts), lo), hi)
    np.testing.assert_array_equal(exact.counts(p), want)


@settings(max_examples=examples(60))
@given(sensor=baro_sensors, c=st.floats(0.0, 1.0))
def test_baro_inverse(sensor: BaroSensor, c: float) -> None:
    lo = sensor.ideal_counts(sensor.p_min_pa)
    hi = sensor.ideal_counts(sensor.p_max_pa)
    counts = lo + c * (hi - lo)
    p = sensor.pressure_of_counts(counts)
    assert sensor.ideal_counts(p) == pytest.approx(counts, abs=1e-6 * max(1.0, abs(counts)))


def test_baro_noise_statistics_and_sign() -> None:
    s = BaroSensor.preset("mpx4115_12bit", noise_counts=2.0)
    p = np.full(20_000, 85_000.0)
    c = s.counts(p, 7)
    assert abs(np.std(c) - 2.0) < 0.1
    assert not np.array_equal(c, s.counts(p, 8))
    assert BaroSensor.preset("telemetrum_v1").sign == -1
    assert BaroSensor.adc_linear(10, sign=1).sign == 1
    inc = BaroSensor.adc_linear(10, sign=1)
    assert inc.counts(np.array([110_000.0]))[0] < inc.counts(np.array([20_000.0]))[0]
    with pytest.raises(UserError):
        s.counts(p)                                          # noise without a generator
    with pytest.raises(UserError, match="8..16 bits"):
        BaroSensor(bits=7)
    with pytest.raises(UserError, match="pascal"):
        BaroSensor(kind="pascal", bits=16)


def test_telemetrum_v1_exact_formula() -> None:
    """The README formula raw = round((P/1000*0.009 - 0.095)*2047*16), evaluated as written."""
    s = BaroSensor.preset("telemetrum_v1")
    p = np.linspace(20_000, 110_000, 5001)
    want = np.round((p / 1000 * 0.009 - 0.095) * 2047 * 16)
    np.testing.assert_array_equal(s.counts(p), want)


@pytest.mark.skipif(not SHARED.is_dir(), reason="../shared/flights is absent")
def test_telemetrum_v1_on_its_logs() -> None:
    from firmware_model.flights.readers import read_flight

    s = BaroSensor.preset("telemetrum_v1")
    for name in ("2012-04-07-serial-882-flight-001", "2012-05-28-serial-319-flight-005"):
        rec = read_flight(SHARED / "altosui" / f"{name}.csv")
        counts = s.counts(rec.pressure_pa)
        # the log's pressures come from integer counts: our inverse maps each count back within 0.01 Pa
        assert np.max(np.abs(s.pressure_of_counts(counts) - rec.pressure_pa)) < 0.01


def test_counts_per_metre() -> None:
    s = BaroSensor.preset("telemetrum_v1")
    p0 = 86_440.0
    h = float(altitude_m(p0))
    assert s.counts_per_metre(p0) == pytest.approx(0.294768 * float(density_kg_m3(h)) * G0, rel=1e-12)
    # against a finite difference of the transfer function through the standard atmosphere
    from firmware_model.spec.atmosphere import pressure_pa

    fd = (s.ideal_counts(pressure_pa(h - 0.5)) - s.ideal_counts(pressure_pa(h + 0.5)))
    assert s.counts_per_metre(p0) == pytest.approx(float(fd), rel=1e-3)


accel_sensors = st.one_of(
    st.sampled_from(sorted(ACCEL_PRESETS)).map(AccelSensor.preset),
    st.builds(AccelSensor, bits=st.integers(10, 16), range_g=st.floats(2, 400),
              counts_per_mps2=st.floats(0.5, 500), offset_counts=st.floats(-500, 500), noise_counts=st.floats(0, 30)),
)


def test_accel_rejects_impossible_sensors() -> None:
    with pytest.raises(UserError, match="outside the 8-bit word"):
        AccelSensor(bits=8, range_g=2.0, counts_per_mps2=1.0, offset_counts=147.0)
    with pytest.raises(UserError, match="less than one count"):
        AccelSensor(range_g=0.01, counts_per_mps2=1.0)


@settings(max_examples=examples(80))
@given(sensor=accel_sensors, f=st.lists(st.floats(-5000, 5000), min_size=1, max_size=50).map(np.array),
       seed=st.integers(0, 2**32 - 1))
def test_accel_deterministic_and_clipped(sensor: AccelSensor, f: np.ndarray, seed: int) -> None:
    a = sensor.counts(f, np.random.default_rng(seed))
    np.testing.assert_array_equal(a, sensor.counts(f, seed))
    lo, hi = sensor.count_limits
    assert -(1 << (sensor.bits - 1)) <= lo and hi <= (1 << (sensor.bits - 1)) - 1
    assert a.min() >= lo and a.max() <= hi
    quiet = AccelSensor(**{**sensor.to_dict(), "noise_counts": 0.0})
    want = np.clip(np.round(sensor.offset_counts + sensor.counts_per_mps2 * f), lo, hi)
    np.testing.assert_array_equal(quiet.counts(f), want)
    big = quiet.counts(np.array([1e6, -1e6]))
    assert big[0] == hi and big[1] == lo


def test_accel_default_matches_build_default() -> None:
    from firmware_model.spec.config import BuildConfig

    s = AccelSensor.preset("default")
    assert s.counts_per_mps2 == BuildConfig().accel_counts_per_mps2
    assert s.counts(np.array([G0]))[0] == 2048
    assert s.count_limits == (-32768, 32767)
