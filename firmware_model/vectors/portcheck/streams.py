"""The streams check-port drives a port and the model with (hypothesis strategies of ``(adc, acc)`` pairs).

Three families, all for one build (its sample period, barometer kind and width, valid range and gates):

* :func:`flight_streams`: flights from a pad through a boost of 2..40 g to a burnout speed from 15 m/s
  (subsonic) to 800 m/s (Mach 2.3), quadratic drag, apogee and descent; the barometer through the standard
  atmosphere and the build's transfer function (ADC counts or pascals) with noise, a transonic pressure error of
  up to +-150 m between Mach 0.85 and 1.2, single-sample spikes (any register value), clipped at the ADC rails
  or the sensor's range; the accelerometer with noise, clipped at a drawn +-g rail and the register's.
* :func:`edge_family`: the deterministic edge streams of :mod:`firmware_model.model.streams` (every kind, a drawn
  length) and the hypothesis edge streams of :mod:`firmware_model.flights.strategies` (steps, ramps, alternations,
  rounding ties).
* :func:`extreme_streams`: runs of held values at the input registers' extremes and at the build's boundaries
  (0, 1, full scale, the valid range's ends and one past them, the pascal edges; accelerometer rails, 0, +-1,
  1 g), or any register value, each held 1..64 samples, and steps of exactly the barometer gate (the recursive
  program's rate gate) and one more.

Every family draws its length as an integer that shrinks toward short streams, and hypothesis shrinks the rest
(values toward the first of each list, flights toward the pad). Streams are int64 arrays of register values.
"""

from __future__ import annotations

import math

import numpy as np
from hypothesis import strategies as st

from firmware_model.flights.strategies import PASCAL_EDGES, edge_streams, pascal_streams
from firmware_model.model.streams import EDGE_KINDS, edge_stream, pascal_edge_stream
from firmware_model.spec.atmosphere import pressure_pa
from firmware_model.spec.config import BuildConfig

G0 = 9.80665
ACC_MIN, ACC_MAX = -32768, 32767
#: Longest stream a flight draws (samples).
FLIGHT_MAX_SAMPLES = 6000
#: Most runs of an extreme stream, and the longest run.
MAX_RUNS, MAX_HOLD = 48, 64


def register_range(cfg: BuildConfig) -> tuple[int, int]:
    """What the barometer register can hold (ADC: 0..2^bits-1; pascal: the int32 range)."""
    return cfg.baro_word_range


def baro_boundaries(cfg: BuildConfig, consts: object) -> list[int]:
    """Barometer words worth hitting on purpose for this build, inside the register's range."""
    lo, hi = register_range(cfg)
    bmin, bmax = int(consts.BARO_MIN), int(consts.BARO_MAX)  # type: ignore[attr-defined]  # consts is typed as object here (a FirmwareConstants)
    vals = [lo, lo + 1, hi - 1, hi, bmin - 1, bmin, bmin + 1, bmax - 1, bmax, bmax + 1, (bmin + bmax) // 2]
    if cfg.pascal:
        vals += list(PASCAL_EDGES)
    else:
        vals += [(hi + 1) // 2, hi // 2]
    return sorted({v for v in vals if lo <= v <= hi}, key=lambda v: (abs(v - (bmin + bmax) // 2), v))


def acc_boundaries(cfg: BuildConfig) -> list[int]:
    one_g = int(round(cfg.accel_counts_per_mps2 * G0))
    return [one_g, 0, 1, -1, ACC_MAX, ACC_MIN, ACC_MAX - 1, ACC_MIN + 1, -one_g, 2 * one_g]


def extreme_streams(cfg: BuildConfig, consts: object) -> st.SearchStrategy[tuple[np.ndarray, np.ndarray]]:
    """Runs of held register values at the extremes (module docstring)."""
    lo, hi = register_range(cfg)
    baro = st.one_of(st.sampled_from(baro_boundaries(cfg, consts)), st.integers(lo, hi))
    acc = st.one_of(st.sampled_from(acc_boundaries(cfg)), st.integers(ACC_MIN, ACC_MAX))
    gate = int(getattr(consts, "E_GATE", 0))
    deltas = [0, 1, -1]
    if 0 < gate < (1 << 20):
        deltas += [gate, -gate, gate + 1, -gate - 1]
    # a run: (absolute barometer word or None = previous + delta, delta, accelerometer, repetitions)
    run = st.tuples(st.one_of(baro, st.none()), st.sampled_from(deltas), acc, st.integers(1, MAX_HOLD))

    def build(runs: list[tuple[int | None, int, int, int]]) -> tuple[np.ndarray, np.ndarray]:
        adc: list[int] = []
        accs: list[int] = []
        prev = baro_boundaries(cfg, consts)[0]
        for b, d, a, reps in runs:
            v = prev + d if b is None else b
            v = min(hi, max(lo, v))
            adc += [v] * reps
            accs += [a] * reps
            prev = v
        return np.asarray(adc, dtype=np.int64), np.asarray(accs, dtype=np.int64)

    return st.lists(run, min_size=1, max_size=MAX_RUNS).map(build)


def edge_family(cfg: BuildConfig) -> st.SearchStrategy[tuple[np.ndarray, np.ndarray]]:
    """The edge streams (module docstring), with the accelerometer of the deterministic kind or a drawn one."""
    one_g = int(round(cfg.accel_counts_per_mps2 * G0))

    def fixed(kind_n: tuple[str, int]) -> tuple[np.ndarray, np.ndarray]:
        kind, n = kind_n
        s = pascal_edge_stream(kind, n, cfg.k) if cfg.pascal else edge_stream(kind, n, cfg.baro_bits, cfg.k)
        return s.adc.astype(np.int64), s.acc.astype(np.int64)

    det = st.tuples(st.sampled_from(EDGE_KINDS), st.integers(4, 400)).map(fixed)

    @st.composite
    def drawn(draw: st.DrawFn) -> tuple[np.ndarray, np.ndarray]:
        n = draw(st.integers(4, 256))
        if cfg.pascal:
            adc = draw(pascal_streams(min_len=n, max_len=n))
        else:
            adc = draw(edge_streams(bits=cfg.baro_bits, length=n, shifts=(max(5, cfg.shift),)))
        a = draw(st.one_of(st.just(one_g), st.sampled_from(acc_boundaries(cfg)), st.integers(ACC_MIN, ACC_MAX)))
        return np.asarray(adc, dtype=np.int64), np.full(len(adc), a, dtype=np.int64)

    return st.one_of(det, drawn())


def _trajectory(dt: float, n: int, pad_s: float, boost_g: float, v_burnout: float, drag: float,
                drogue_mps: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Altitude above the pad (m), velocity (m/s) and sensed specific force (m/s^2) at n samples of dt (Euler at
    dt/2)."""
    sub = 2
    h = v = 0.0
    burn_left = v_burnout / max(boost_g * G0, 1e-9)
    t = 0.0
    hs = np.empty(n)
    vs = np.empty(n)
    fs = np.empty(n)
    h_dt = dt / sub
    past_apogee = False
    for i in range(n):
        f = G0
        for _ in range(sub):
            if t < pad_s:
                a, f = 0.0, G0
            elif burn_left > 0:
                dragf = drag * v * abs(v)
                a = boost_g * G0 - G0 - dragf
                f = boost_g * G0 - dragf
                burn_left -= h_dt
            elif not past_apogee:
                dragf = drag * v * abs(v)
                a = -G0 - dragf
                f = -dragf
                if v + a * h_dt < 0:
                    past_apogee = True
            else:
                a = (-drogue_mps - v) * 2.0  # settles on the drogue's rate
                f = a + G0
            v += a * h_dt
            h += v * h_dt
            t += h_dt
            if h < 0 and past_apogee:
                h, v, a, f = 0.0, 0.0, 0.0, G0
        hs[i], vs[i], fs[i] = h, v, f
    return hs, vs, fs


def flight_streams(cfg: BuildConfig) -> st.SearchStrategy[tuple[np.ndarray, np.ndarray]]:
    """Simulated flights with sensor errors (module docstring)."""
    lo, hi = register_range(cfg)
    pa_per_count, pa_at_zero = cfg.baro_transfer

    @st.composite
    def flight(draw: st.DrawFn) -> tuple[np.ndarray, np.ndarray]:
        n = draw(st.integers(8, FLIGHT_MAX_SAMPLES))
        pad_s = draw(st.floats(0.0, 3.0))
        boost_g = draw(st.floats(2.0, 40.0))
        v_burnout = draw(st.one_of(st.floats(15.0, 340.0), st.floats(340.0, 800.0)))
        drag = draw(st.floats(0.0, 0.002))
        drogue = draw(st.floats(5.0, 40.0))
        site_m = draw(st.floats(0.0, 3000.0))
        seed = draw(st.integers(0, 2**32 - 1))
        baro_noise = draw(st.floats(0.0, 4.0))
        acc_noise = draw(st.floats(0.0, 20.0))
        trans_err_m = draw(st.floats(-150.0, 150.0))
        clip_g = draw(st.one_of(st.none(), st.sampled_from((3.0, 16.0, 24.0, 50.0))))
        spikes = draw(st.lists(st.tuples(st.integers(0, n - 1), st.one_of(st.integers(lo, hi),
                                                                          st.sampled_from((lo, hi)))), max_size=4))
        dt = cfg.dt
        h, v, f = _trajectory(dt, n, pad_s, boost_g, v_burnout, drag, drogue)
        rng = np.random.default_rng(seed)
        mach = np.abs(v) / 340.0
        err = np.where((mach > 0.85) & (mach < 1.2), trans_err_m, 0.0)
        p = np.asarray(pressure_pa(site_m + h - err), dtype=np.float64)
        if cfg.pascal:
            word = np.clip(np.rint(p + rng.normal(0.0, baro_noise, n)), 1000, 120000)
        else:
            counts = (pa_at_zero - p) / (cfg.baro_sign * pa_per_count)
            word = np.clip(np.rint(counts + rng.normal(0.0, baro_noise, n)), lo, hi)
        adc = word.astype(np.int64)
        for i, val in spikes:
            adc[i] = val
        acc_f = f * cfg.accel_counts_per_mps2 + rng.normal(0.0, acc_noise, n)
        if clip_g is not None:
            rail = clip_g * G0 * cfg.accel_counts_per_mps2
            acc_f = np.clip(acc_f, -rail, rail)
        acc = np.clip(np.rint(acc_f), ACC_MIN, ACC_MAX).astype(np.int64)
        if not math.isfinite(float(np.sum(acc_f))):  # pragma: no cover - draws are finite
            acc = np.zeros(n, np.int64)
        return adc, acc

    return flight()


def port_streams(cfg: BuildConfig, consts: object) -> st.SearchStrategy[tuple[np.ndarray, np.ndarray]]:
    """All three families; hypothesis shrinks toward the first (held extremes, the simplest to read)."""
    return st.one_of(extreme_streams(cfg, consts), edge_family(cfg), flight_streams(cfg))


FAMILIES = {"extremes": extreme_streams, "edges": lambda cfg, consts: edge_family(cfg),
            "flights": lambda cfg, consts: flight_streams(cfg)}

__all__ = ["FAMILIES", "edge_family", "extreme_streams", "flight_streams", "port_streams"]
