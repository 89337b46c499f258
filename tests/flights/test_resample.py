"""Resampling: the 2^-k grid is exact (no drift), values are held / interpolated as documented, and the report
counts repeated and dropped input rows, gaps and rate changes (checked against independent counts)."""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from firmware_model.runtime.errors import UserError
from firmware_model.flights.inputs.resample import grid, resample
from tests.support.profiles import examples


@settings(max_examples=examples(60))
@given(k=st.integers(0, 12), t0=st.floats(-100, 100), span=st.floats(1.0, 3000))
def test_grid_exact_no_drift(k: int, t0: float, span: float) -> None:
    g = grid(k, t0, t0 + span)
    dt = Fraction(1, 1 << k)
    n0 = math.ceil(Fraction(t0) / dt)
    # every point is exactly (n0 + i) * 2^-k, computed here in exact rational arithmetic
    assert Fraction(g[0]) == n0 * dt and Fraction(g[0]) >= Fraction(t0) > Fraction(g[0]) - dt
    idx = np.arange(g.size)
    assert all(Fraction(float(x)) == (n0 + int(i)) * dt for x, i in zip(g[:: max(1, g.size // 50)],
                                                                      idx[:: max(1, g.size // 50)]))
    assert Fraction(g[-1]) == (n0 + g.size - 1) * dt and Fraction(g[-1]) <= Fraction(t0 + span)
    assert np.all(np.diff(g) == 2.0 ** -k)


@settings(max_examples=examples(60))
@given(k=st.integers(2, 9), rate=st.sampled_from([10.0, 20.0, 50.0, 100.0, 200.0, 500.0, 1000.0]),
       n=st.integers(20, 400), jitter=st.floats(0, 0.3), seed=st.integers(0, 1000),
       method=st.sampled_from(["hold", "linear"]))
def test_values_and_report(k: int, rate: float, n: int, jitter: float, seed: int, method: str) -> None:
    rng = np.random.default_rng(seed)
    n = max(n, math.ceil(8 * rate / 2.0 ** k) + 2)          # the log spans at least 8 grid periods
    t = np.arange(n) / rate + rng.uniform(0, jitter / rate, n)
    y = rng.normal(size=n)
    g, out, rep = resample(t, {"y": y, "none": None}, k, method)
    assert out["none"] is None
    assert rep.output_samples == g.size and rep.method == method
    # independent: source row of each grid time by brute force
    src = np.array([max(i for i in range(n) if t[i] <= x) for x in g])
    if method == "hold":
        np.testing.assert_array_equal(out["y"], y[src])
    else:
        nxt = np.minimum(src + 1, n - 1)
        w = np.where(nxt > src, (g - t[src]) / np.where(nxt > src, t[nxt] - t[src], 1), 0.0)
        np.testing.assert_allclose(out["y"], y[src] + w * (y[nxt] - y[src]), rtol=0, atol=1e-12)
    assert rep.repeated == sum(1 for a, b in zip(src, src[1:]) if a == b)
    in_span = [i for i in range(n) if g[0] <= t[i] <= g[-1]]
    assert rep.input_rows == len(in_span)
    assert rep.dropped == len(set(in_span) - set(src.tolist()))
    # conservation: every grid sample is a first use of a row or a repeat
    assert rep.output_samples == rep.repeated + len(set(src.tolist()))
    if 2.0 ** k > rate * 1.5:
        assert rep.dropped == 0 and rep.repeated > 0        # up-sampling repeats, drops nothing
    if 2.0 ** k * 1.5 < rate and jitter == 0:
        assert rep.dropped > 0                              # down-sampling drops rows
    assert rep.gaps == [] and rep.rate_changes == []


def test_rate_change_and_gap_reported() -> None:
    t = np.concatenate([np.arange(0, 10, 0.01), 10 + np.arange(0, 20, 0.1)])
    t = np.delete(t, np.nonzero((t > 15.05) & (t < 15.65))[0])      # a 0.7 s gap in the 10 Hz part
    y = np.sin(t)
    g, out, rep = resample(t, {"y": y}, 7, "linear")
    assert len(rep.rate_changes) == 1
    rc = rep.rate_changes[0]
    assert rc.time_s == pytest.approx(9.99, abs=0.011)
    assert rc.from_hz == pytest.approx(100) and rc.to_hz == pytest.approx(10)
    assert len(rep.gaps) == 1 and rep.gaps[0].start_s == pytest.approx(15.0) and rep.gaps[0].periods == pytest.approx(7)
    assert "rate change" in rep.summary() and "gaps" in rep.summary()


def test_missing_values_and_outside_span() -> None:
    t = np.arange(10) * 0.1
    y = t.copy()
    y[4] = np.nan
    g, out, rep = resample(t, {"y": y}, 5, "linear", t_start=-0.5, t_end=1.5)
    assert rep.missing == {"y": 1}
    np.testing.assert_allclose(out["y"][(g >= 0) & (g <= 0.9)], g[(g >= 0) & (g <= 0.9)], atol=1e-12)
    assert rep.before_log == int(np.sum(g < 0)) and rep.after_log == int(np.sum(g > 0.9))
    assert np.all(out["y"][g < 0] == 0.0) and np.all(out["y"][g > 0.9] == 0.9)
    with pytest.raises(UserError, match="method"):
        resample(t, {"y": y}, 5, "cubic")
    with pytest.raises(UserError, match="strictly increasing"):
        resample(t[::-1], {"y": y}, 5)
    with pytest.raises(UserError, match="no multiple"):
        grid(0, 0.2, 0.7)


SHARED = __import__("pathlib").Path(__import__("os").environ.get("FWEMU_SHARED_FLIGHTS") or __import__("pathlib")
                                    .Path(__file__).resolve().parents[2].parent / "shared" / "flights")


@pytest.mark.skipif(not SHARED.is_dir(), reason="../shared/flights is absent")
def test_altosui_rate_change_found_where_the_log_slows() -> None:
    """Each AltosUI log switches from 100 to ~10 samples/s once after apogee; the report finds that one change at the
    start of the first long interval (independently: the first row after boost whose next interval is longer than 50 ms
    and whose next 20 intervals have a median above 50 ms), and hedy (100 samples/s throughout) has none."""
    from firmware_model.flights.readers import read_flight

    for path in sorted((SHARED / "altosui").glob("*.csv")):
        rec = read_flight(path)
        t = rec.time_s
        d = np.diff(t)
        first = next(i for i in range(d.size - 20) if t[i] > 0 and d[i] > 0.05 and np.median(d[i:i + 20]) > 0.05)
        _, _, rep = resample(t, {"p": rec.pressure_pa}, 7, "hold")
        assert len(rep.rate_changes) == 1, (path.name, rep.rate_changes)
        rc = rep.rate_changes[0]
        assert rc.from_hz == pytest.approx(100.0) and 8.0 <= rc.to_hz <= 12.5
        assert rc.time_s == t[first], (path.name, rc.time_s, t[first])
    hedy = read_flight(SHARED / "cats" / "hedy-baro.csv")
    assert resample(hedy.time_s, {"p": hedy.pressure_pa}, 7)[2].rate_changes == []
